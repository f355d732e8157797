//! Where the noise sweep's lit pixels are lost: the still hand of `tremorscan sweep` (same rig,
//! seed and decode settings), decoded with the default decoder, its lit pixels (the truth's ray
//! meets a lit surface) tallied by their distance to the nearest edge of the truth (a pixel that
//! is unlit, or whose 4-neighbour is unlit, on another surface or more than 3 projector px away
//! in coordinate), with the share refused, the share valid but a fringe off, and the refused
//! pixels' flags. Then the lit pixels the motion model gave a velocity (a still hand should have
//! none), with their speeds and their signs by the fine phase's octant (a sign locked to the
//! fringe phase is a bias, not noise), and the share of right neighbours close enough in phase
//! to be connected.
//!
//! `cargo run --release -p tremorscan --example lit_breakdown -- [SIGMA…]` (default: 0 2)
//!
//! Settings from the environment: `WIDTH` and `HEIGHT` (640×400 by default), `REACH` (the
//! sums' reach scale), `UNIT_DECAY`, `MOTION_DECAY`, `STILL=1` (the motion model off), `PSF`
//! (the camera blur's σ, px) and `NO_CROSS=1` (a rig without colour cross-talk).

use std::collections::BTreeMap;
use tremorscan::decode::{DecodeOutput, DecodeParams, SlidingDecoder};
use tremorscan::rig::{GroundTruth, NoiseModel, RigConfig, VirtualRig};

fn size(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
/// Distances tallied one by one; farther ones share the last row.
const FAR_PX: usize = 5;
/// A valid pixel this far off the truth, projector px, has a wrong fringe order: a third of the
/// rig's finest period (28 px), far beyond the noise.
const FRINGE_OFF_PX: f32 = 10.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sigmas: Vec<f64> = match std::env::args().skip(1).map(|a| a.parse()).collect() {
        Ok(v) if !Vec::is_empty(&v) => v,
        Ok(_) => vec![0.0, 2.0],
        Err(e) => return Err(format!("a noise level is not a number: {e}").into()),
    };
    for sigma in sigmas {
        let (out, truth) = decode_still_hand(sigma)?;
        report(sigma, &out, &truth);
    }
    Ok(())
}

/// The sweep's still hand at noise `sigma`, decoded as the sweep decodes it (checks on).
fn decode_still_hand(
    sigma: f64,
) -> Result<(DecodeOutput, GroundTruth), Box<dyn std::error::Error>> {
    let mut config = RigConfig::paper(size("WIDTH", 640), size("HEIGHT", 400))?;
    config.noise = NoiseModel::gaussian(sigma);
    config.seed = 1;
    if let Some(v) = std::env::var("PSF").ok().and_then(|v| v.parse().ok()) {
        config.camera_psf_sigma_px = v;
    }
    if std::env::var("NO_CROSS").is_ok() {
        config.cross_talk = tremorscan::color::CrossTalk::identity();
    }
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = 0.0;
        t.hand_amplitude_mm = 0.0;
    }
    let seq = config.default_sequence()?;
    let rig = VirtualRig::new(config, seq)?;
    let mut params = DecodeParams {
        camera_noise_gray: (sigma as f32).max(1.0),
        ..DecodeParams::default()
    };
    let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f32>().ok());
    params.reach_scale = env("REACH");
    if let Some(v) = env("UNIT_DECAY") {
        params.smoothing.decay = v;
    }
    if let Some(v) = env("MOTION_DECAY") {
        params.motion.decay = v;
    }
    if std::env::var("STILL").is_ok() {
        params.motion = tremorscan::decode::MotionParams::off();
    }
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in 0..3 {
        rig.render(i, &mut frame, (i == 1).then_some(&mut truth))?;
        decoder.push(&frame)?;
    }
    let out = decoder.output().ok_or("the window did not decode")?.clone();
    Ok((out, truth))
}

/// Each pixel's distance to the nearest edge of the truth (8-connected steps), up to
/// [`FAR_PX`].
fn edge_distance(truth: &GroundTruth) -> Vec<usize> {
    let (w, h) = (truth.width, truth.height);
    let lit = |p: usize| truth.coordinate_px[p].is_finite();
    let neighbours = |p: usize, diagonal: bool| {
        let (x, y) = ((p % w) as i64, (p / w) as i64);
        let steps: &[(i64, i64)] = if diagonal {
            &[
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (1, -1),
                (-1, 1),
                (-1, -1),
            ]
        } else {
            &[(1, 0), (-1, 0), (0, 1), (0, -1)]
        };
        steps
            .iter()
            .map(move |(dx, dy)| (x + dx, y + dy))
            .filter(|&(xx, yy)| xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64)
            .map(|(xx, yy)| yy as usize * w + xx as usize)
            .collect::<Vec<_>>()
    };
    let mut distance: Vec<usize> = (0..w * h)
        .map(|p| {
            let edge = !lit(p)
                || neighbours(p, false).into_iter().any(|q| {
                    !lit(q)
                        || truth.surface[q] != truth.surface[p]
                        || (truth.coordinate_px[q] - truth.coordinate_px[p]).abs() > 3.0
                });
            if edge {
                0
            } else {
                FAR_PX
            }
        })
        .collect();
    for d in 1..FAR_PX {
        let next: Vec<usize> = (0..w * h)
            .map(|p| {
                let near = neighbours(p, true)
                    .into_iter()
                    .any(|q| distance[q] == d - 1);
                if distance[p] == FAR_PX && near {
                    d
                } else {
                    distance[p]
                }
            })
            .collect();
        distance = next;
    }
    distance
}

fn report(sigma: f64, out: &DecodeOutput, truth: &GroundTruth) {
    let distance = edge_distance(truth);
    let mut rows = [(0usize, 0usize); FAR_PX + 1];
    let mut wrong = [0usize; FAR_PX + 1];
    let mut flags: BTreeMap<u16, usize> = BTreeMap::new();
    let mut flags_inside: BTreeMap<u16, usize> = BTreeMap::new();
    for p in (0..truth.width * truth.height).filter(|&p| truth.coordinate_px[p].is_finite()) {
        let row = &mut rows[distance[p]];
        row.0 += 1;
        if out.invalid[p] == 0
            && (out.coordinate_px[p] - truth.coordinate_px[p]).abs() > FRINGE_OFF_PX
        {
            wrong[distance[p]] += 1;
        }
        if out.invalid[p] != 0 {
            row.1 += 1;
            *flags.entry(out.invalid[p]).or_default() += 1;
            if distance[p] > 2 {
                *flags_inside.entry(out.invalid[p]).or_default() += 1;
            }
        }
    }
    let share = |(lit, refused): (usize, usize)| 100.0 * refused as f64 / lit.max(1) as f64;
    let total = rows.iter().fold((0, 0), |a, r| (a.0 + r.0, a.1 + r.1));
    println!(
        "σ = {sigma}: {} lit, {:.2} % valid ({} refused)",
        total.0,
        100.0 - share(total),
        total.1
    );
    for (d, &row) in rows.iter().enumerate() {
        let far = if d == FAR_PX { "+" } else { "" };
        println!(
            "  {d}{far} px from an edge: {} lit, {:.2} % refused, {:.3} % a fringe off",
            row.0,
            share(row),
            share((row.0, wrong[d]))
        );
    }
    let inside = rows[3..].iter().fold((0, 0), |a, r| (a.0 + r.0, a.1 + r.1));
    println!(
        "  more than 2 px from an edge: {:.3} % valid",
        100.0 - share(inside)
    );
    let lit_px: Vec<usize> = (0..truth.width * truth.height)
        .filter(|&p| truth.coordinate_px[p].is_finite())
        .collect();
    let moving = lit_px
        .iter()
        .filter(|&&p| out.velocity_px_per_s.get(p).is_some_and(|v| *v != 0.0))
        .count();
    let mut speeds: Vec<f32> = lit_px
        .iter()
        .filter_map(|&p| out.velocity_px_per_s.get(p).copied())
        .filter(|v| *v != 0.0)
        .map(f32::abs)
        .collect();
    speeds.sort_by(f32::total_cmp);
    let q = |f: f64| {
        speeds
            .get((f * speeds.len() as f64) as usize)
            .copied()
            .unwrap_or(0.0)
    };
    println!(
        "  lit with a velocity: {moving} ({:.2} %), |u| px/s quartiles {:.1} {:.1} {:.1}, max {:.1}",
        100.0 * moving as f64 / lit_px.len().max(1) as f64,
        q(0.25),
        q(0.5),
        q(0.75),
        speeds.last().copied().unwrap_or(0.0)
    );
    let w = truth.width;
    let mut linked = [0usize; 3];
    let mut pairs = 0usize;
    for &p in &lit_px {
        if p % w + 1 >= w || !truth.coordinate_px[p + 1].is_finite() {
            continue;
        }
        pairs += 1;
        let y = p / w;
        for (f, l) in linked.iter_mut().enumerate() {
            let a = out.phase_rad[y * 3 * w + f * w + p % w];
            let b = out.phase_rad[y * 3 * w + f * w + p % w + 1];
            let d = (a - b).abs();
            if d.min(std::f32::consts::TAU - d) < 1.0 {
                *l += 1;
            }
        }
    }
    println!(
        "  right neighbours within 1 rad per slot: {:?} %",
        linked.map(|l| (1000.0 * l as f64 / pairs.max(1) as f64).round() / 10.0)
    );
    let mut by_phase = [(0usize, 0usize); 8];
    for &p in &lit_px {
        let u = out.velocity_px_per_s.get(p).copied().unwrap_or(0.0);
        if u == 0.0 {
            continue;
        }
        let phi = out.phase_rad[(p / w) * 3 * w + p % w].rem_euclid(std::f32::consts::TAU);
        let bin = ((phi / std::f32::consts::TAU * 8.0) as usize).min(7);
        if u > 0.0 {
            by_phase[bin].0 += 1;
        } else {
            by_phase[bin].1 += 1;
        }
    }
    println!("  velocities (+, −) by the fine phase's octant: {by_phase:?}");
    println!("  flags of the refused (all): {flags:?}");
    println!("  flags of the refused (more than 2 px from an edge): {flags_inside:?}");
}
