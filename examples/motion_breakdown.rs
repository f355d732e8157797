//! Where the motion sweep's moving skin is lost: the counted pixels of `tremorscan sweep
//! --motion` (same rig, same protocol as `rig::motion_eval`) tallied by the true turn of the
//! window's outer frames at the highest frequency, `θ = f·(x₂ − x₀)/2` (signed: positive is the
//! side where the three-step window is singular at π/3), with the share kept, the gross errors,
//! the RMS of the others and the flags of the refused pixels (a pixel may carry several).
//!
//! `cargo run --release -p tremorscan --example motion_breakdown -- AMPLITUDE_MM [sway] [FRAMES]`
//!
//! Settings from the environment, for trying the decoder's parameters: `UNIT_DECAY` (the unit
//! phasor's filter), `TRANSPORT=1` (carry it along the fine phase), `MIN_SUPPORT`,
//! `MOTION_DECAY`, `ITERATIONS`, `MOTION_BLOCK` (the motion model's evidence summed over blocks
//! of that many pixels square), `REACH` (the sums' reach scale, `DecodeParams::reach_scale`;
//! the decays are stated at 640 px wide), `WIDTH` and `HEIGHT` (640×400 by default); `STILL=1` also
//! prints, per window, the share of every lit pixel refused for each flag.

use tremorscan::decode::{invalid, DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::rig::motion_eval::{GROSS_MM, MOVING_MM, OUTLINE_MARGIN_PX};
use tremorscan::rig::{GroundTruth, RigConfig, VirtualRig};
use tremorscan::triangulate::{PointCloud, Triangulator};

const FLAGS: [(u16, &str); 9] = [
    (invalid::LOW_AMPLITUDE, "amplitude"),
    (invalid::SATURATED, "saturated"),
    (invalid::UNWRAP_MARGIN, "margin"),
    (invalid::DISAGREEMENT, "disagree"),
    (invalid::LOW_SUPPORT, "support"),
    (invalid::OUT_OF_RANGE, "range"),
    (invalid::ORDER_JUMP, "jump"),
    (invalid::MOTION, "motion"),
    (invalid::MIXED, "mixed"),
];
const BIN_RAD: f32 = 0.2;
const BINS: usize = 18;

#[derive(Default, Clone, Copy)]
struct Bin {
    counted: usize,
    valid: usize,
    gross: usize,
    sum2_mm2: f64,
    flags: [usize; 9],
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: motion_breakdown AMPLITUDE_MM [sway] [FRAMES]";
    let amplitude_mm: f64 = args.next().ok_or(usage)?.parse()?;
    let rest: Vec<String> = args.collect();
    let sway = rest.iter().any(|a| a == "sway");
    let frames: u64 = rest.iter().find_map(|a| a.parse().ok()).unwrap_or(40);
    let size = |name: &str, default: usize| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let mut config = RigConfig::paper(size("WIDTH", 640), size("HEIGHT", 400))?;
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = amplitude_mm;
        if sway {
            t.sway_amplitude_mm = 4.0;
            t.roll_amplitude_deg = 3.0;
        }
    }
    let seq = config.default_sequence()?;
    let rig = VirtualRig::new(config, seq)?;
    let f_max = rig
        .sequence
        .distinct_frequencies()
        .first()
        .map(|&m| rig.sequence.frequency(m) as f32)
        .ok_or("no frequency")?;
    let triangulator = Triangulator::new(rig.stereo_model())?;
    let mut params = DecodeParams::default();
    let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f32>().ok());
    if let Some(v) = env("UNIT_DECAY") {
        params.smoothing.decay = v;
    }
    if let Some(v) = env("MOTION_DECAY") {
        params.motion.decay = v;
    }
    params.reach_scale = env("REACH");
    params.smoothing.transport = std::env::var("TRANSPORT").is_ok();
    if let Some(v) = env("MIN_SUPPORT") {
        params.smoothing.min_support = v;
    }
    if let Some(v) = env("ITERATIONS") {
        params.motion.iterations = v as u32;
    }
    if let Some(v) = env("MOTION_BLOCK") {
        params.motion.block_px = v as u32;
    }
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truths: [GroundTruth; 3] = Default::default();
    let mut cloud = PointCloud::default();
    let mut bins = [Bin::default(); BINS];
    for i in 0..frames {
        truths.rotate_left(1);
        rig.render(i, &mut frame, Some(&mut truths[2]))?;
        let out = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => out,
            _ => continue,
        };
        if i < 2 || (i - 2) % 3 != 0 {
            continue;
        }
        triangulator.triangulate(out, &mut cloud)?;
        if std::env::var("STILL").is_ok() {
            // Every lit pixel of the centre frame, whatever it shows: the flags of the refused.
            let mut lit = 0usize;
            let mut refused = [0usize; 9];
            for (p, &c) in truths[1].coordinate_px.iter().enumerate() {
                if !c.is_finite() {
                    continue;
                }
                lit += 1;
                for (j, (bit, _)) in FLAGS.iter().enumerate() {
                    if out.invalid[p] & bit != 0 {
                        refused[j] += 1;
                    }
                }
            }
            let shares: Vec<String> = FLAGS
                .iter()
                .zip(refused)
                .map(|((_, name), r)| format!("{name} {:.2}", 100.0 * r as f64 / lit as f64))
                .collect();
            println!("window {i}: lit {lit}: {}", shares.join(", "));
        }
        let (w, h) = (truths[0].width, truths[0].height);
        let m = OUTLINE_MARGIN_PX;
        for y in m..h - m {
            for x in m..w - m {
                let p = y * w + x;
                let skin = (y - m..=y + m).all(|yy| {
                    (x - m..=x + m).all(|xx| {
                        truths.iter().all(|t| {
                            t.surface[yy * w + xx] == tremorscan::rig::truth::surface::SKIN
                        })
                    })
                });
                if !skin {
                    continue;
                }
                let d = [0, 1, 2].map(|k| truths[k].depth_mm[p]);
                let lo = d.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = d.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                if hi - lo <= MOVING_MM {
                    continue;
                }
                let turn = f_max * (truths[2].coordinate_px[p] - truths[0].coordinate_px[p]) / 2.0;
                let k = ((turn / BIN_RAD).floor() + (BINS / 2) as f32).clamp(0.0, (BINS - 1) as f32)
                    as usize;
                let bin = &mut bins[k];
                bin.counted += 1;
                let z = cloud.point_in_camera_mm[p][2];
                if z.is_finite() {
                    bin.valid += 1;
                    if (z - d[1]).abs() > GROSS_MM {
                        bin.gross += 1;
                    } else {
                        bin.sum2_mm2 += f64::from(z - d[1]).powi(2);
                    }
                } else {
                    for (j, (bit, _)) in FLAGS.iter().enumerate() {
                        if out.invalid[p] & bit != 0 {
                            bin.flags[j] += 1;
                        }
                    }
                }
            }
        }
    }
    let total: usize = bins.iter().map(|b| b.counted).sum();
    let valid: usize = bins.iter().map(|b| b.valid).sum();
    let gross: usize = bins.iter().map(|b| b.gross).sum();
    let sum2: f64 = bins.iter().map(|b| b.sum2_mm2).sum();
    println!(
        "kept {} %, gross {} % of kept, RMS {} mm",
        share(valid, total, 2),
        share(gross, valid, 3),
        rms(sum2, valid - gross)
    );
    println!(
        "{amplitude_mm} mm{}, {frames} frames, {total} moving px",
        if sway { " with sway" } else { "" }
    );
    print!("| turn rad | share | kept | gross | RMS mm |");
    for (_, name) in FLAGS {
        print!(" {name} |");
    }
    println!();
    println!("|---|---:|---:|---:|---:|{}", "---:|".repeat(FLAGS.len()));
    for (k, b) in bins.iter().enumerate() {
        if b.counted == 0 {
            continue;
        }
        let lo = (k as f32 - (BINS / 2) as f32) * BIN_RAD;
        print!(
            "| {lo:+.1}..{:+.1} | {} % | {} % | {} % | {} |",
            lo + BIN_RAD,
            share(b.counted, total, 2),
            share(b.valid, b.counted, 1),
            share(b.gross, b.counted, 2),
            rms(b.sum2_mm2, b.valid - b.gross)
        );
        for v in b.flags {
            print!(" {} |", share(v, b.counted, 1));
        }
        println!();
    }
    Ok(())
}

/// `part` as a percentage of `whole` with `digits` decimals, or "–" when `whole` is empty.
fn share(part: usize, whole: usize, digits: usize) -> String {
    if whole == 0 {
        return "–".into();
    }
    format!("{:.digits$}", 100.0 * part as f64 / whole as f64)
}

/// The RMS of `n` squared errors summing to `sum2`, mm, or "–" when there are none.
fn rms(sum2: f64, n: usize) -> String {
    if n == 0 {
        return "–".into();
    }
    format!("{:.3}", (sum2 / n as f64).sqrt())
}
