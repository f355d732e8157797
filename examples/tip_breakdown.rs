//! Why the swaying fingertip loses samples: the sweep's fingertip trial (the index fingertip's
//! pixel at rest, `rig::tremor_eval`), window by window. For each window it counts the valid
//! pixels of the tracker's 7×7 neighbourhood (`tremor::locate` needs half of them) and finds
//! the nearest pixel, within 15 px, that is not skin in one of the window's three frames (the
//! outline's distance, Chebyshev). It prints a table of windows and failures by that distance.
//! For each failing window (or only the window ending at frame `ONLY`) it also prints a map: 12 rows by 13
//! columns from 3 px above and 6 px left of the control point. Each cell is
//! `S FLAGS:ERR`: S is in how many of the three frames the pixel was skin, FLAGS its invalid
//! bits, ERR its coarse coordinate's error in fringe periods against the truth at the window's
//! centre frame.
//!
//! `cargo run --release -p tremorscan --example tip_breakdown -- AMPLITUDE_MM [FRAMES]`
//!
//! The hand sways 4 mm and rolls 3° (`SWAY_MM`, `ROLL_DEG`); `PSF`, `SUBSURFACE` and
//! `TEXTURE` set the rig's lens blur, subsurface blur and skin texture. For the decoder:
//! `UNIT_DECAY`, `MOVING_DECAY` (0 turns the wide average off), `EDGE_PHASE`, `EDGE_COLOUR`
//! and `EDGE_CHROMA`, as in `motion_breakdown`. `QUIET=1` prints the summary only.

use std::collections::BTreeMap;
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::rig::truth::surface;
use tremorscan::rig::{GroundTruth, RigConfig, Scene, VirtualRig};

/// The tracker's neighbourhood: 7×7 (`TrackOptions::default`).
const RADIUS_PX: usize = 3;
/// How far the outline is looked for.
const SEARCH_PX: usize = 15;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: tip_breakdown AMPLITUDE_MM [FRAMES]";
    let amplitude_mm: f64 = args.next().ok_or(usage)?.parse()?;
    let frames: u64 = args.next().map_or(Ok(363), |a| a.parse())?;
    let env_f64 = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
    let env_f32 = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f32>().ok());
    let mut config = RigConfig::paper(640, 400)?;
    let hand = config.scene.hand.as_mut().ok_or("the rig has no hand")?;
    hand.tip_amplitude_mm = amplitude_mm;
    hand.sway_amplitude_mm = env_f64("SWAY_MM").unwrap_or(4.0);
    hand.roll_amplitude_deg = env_f64("ROLL_DEG").unwrap_or(3.0);
    if let Some(v) = env_f64("PSF") {
        config.camera_psf_sigma_px = v;
    }
    if let Some(v) = env_f64("SUBSURFACE") {
        config.subsurface_sigma_px = v;
    }
    if let Some(v) = env_f64("TEXTURE") {
        config.scene.skin_texture_contrast = v;
    }
    let mut params = DecodeParams::default();
    if let Some(v) = env_f32("UNIT_DECAY") {
        params.smoothing.decay = v;
    }
    if let Some(v) = env_f32("MOVING_DECAY") {
        params.motion.moving_unit_decay = (v > 0.0).then_some(v);
    }
    if let Some(v) = env_f32("EDGE_PHASE") {
        params.smoothing.edge_phase_rad = v;
    }
    if let Some(v) = env_f32("EDGE_COLOUR") {
        params.smoothing.edge_colour_ratio = v;
    }
    if let Some(v) = env_f32("EDGE_CHROMA") {
        params.smoothing.edge_chromaticity = v;
    }
    let quiet = std::env::var("QUIET").is_ok();
    let only: Option<u64> = std::env::var("ONLY").ok().and_then(|v| v.parse().ok());

    let seq = config.default_sequence()?;
    let rig = VirtualRig::new(config, seq)?;
    let tip = *Scene::new(rig.config.scene.clone())
        .at(0.0)
        .points
        .first()
        .ok_or("the hand has no fingertip")?;
    let (u, v) = rig
        .config
        .camera
        .project(&tip)
        .ok_or("the fingertip is not seen")?;
    let (cu, cv) = (u.round() as usize, v.round() as usize);
    let (w, h) = (rig.width(), rig.height());
    if cu < SEARCH_PX || cv < SEARCH_PX || cu + SEARCH_PX >= w || cv + SEARCH_PX >= h {
        return Err("the fingertip is too near the image's border".into());
    }
    let period_px = std::f32::consts::TAU
        / rig
            .sequence
            .distinct_frequencies()
            .first()
            .map(|&m| rig.sequence.frequency(m) as f32)
            .ok_or("no frequency")?;
    println!("control point ({u:.1}, {v:.1}), finest period {period_px:.2} projector px");

    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truths: [GroundTruth; 3] = Default::default();
    // Outline distance → (windows, failing windows).
    let mut by_distance: BTreeMap<usize, (usize, usize)> = BTreeMap::new();
    for i in 0..frames {
        rig.render(i, &mut frame, Some(&mut truths[(i % 3) as usize]))?;
        let WindowOutcome::Decoded(out) = decoder.push(&frame)? else {
            continue;
        };
        // The window's centre frame.
        let centre = &truths[((i + 2) % 3) as usize];
        let near =
            |r: usize| (cv - r..=cv + r).flat_map(move |y| (cu - r..=cu + r).map(move |x| (x, y)));
        let valid = near(RADIUS_PX)
            .filter(|&(x, y)| out.invalid[y * w + x] == 0)
            .count();
        let outline_px = near(SEARCH_PX)
            .filter(|&(x, y)| truths.iter().any(|t| t.surface[y * w + x] != surface::SKIN))
            .map(|(x, y)| x.abs_diff(cu).max(y.abs_diff(cv)))
            .min()
            .unwrap_or(usize::MAX);
        let failing = 2 * valid < (2 * RADIUS_PX + 1).pow(2);
        let entry = by_distance.entry(outline_px).or_default();
        entry.0 += 1;
        entry.1 += usize::from(failing);
        let shown = match only {
            Some(k) => k == i,
            None => failing,
        };
        if quiet || !shown {
            continue;
        }
        println!(
            "window ending at frame {i}: {valid} of 49 valid, outline at {} px",
            distance(outline_px)
        );
        for y in cv - 3..=cv + 8 {
            let mut line = String::new();
            for x in cu - 6..=cu + 6 {
                let j = y * w + x;
                let skin = truths
                    .iter()
                    .filter(|t| t.surface[j] == surface::SKIN)
                    .count();
                let err = (out.coarse_px[j] - centre.coordinate_px[j]) / period_px;
                line += &format!(" {skin}{:>4}:{err:+.1}", out.invalid[j]);
            }
            println!("{line}");
        }
    }
    println!("| outline px | windows | failing |");
    println!("|---:|---:|---:|");
    for (&d, (n, bad)) in &by_distance {
        println!("| {} | {n} | {bad} |", distance(d));
    }
    let total: usize = by_distance.values().map(|e| e.1).sum();
    println!("{total} failing windows");
    Ok(())
}

/// An outline distance as printed: beyond the search, "> 15".
fn distance(px: usize) -> String {
    if px == usize::MAX {
        format!("> {SEARCH_PX}")
    } else {
        px.to_string()
    }
}
