//! Where the motion sweep's moving skin is lost: the counted pixels of `tremorscan sweep
//! --motion` (same rig, same protocol as `rig::motion_eval`) tallied by the true turn of the
//! window's outer frames at the highest frequency, `θ = f·(x₂ − x₀)/2` (signed: positive is the
//! side where the three-step window is singular at π/3), with the share kept, the gross errors,
//! the RMS of the others, how often the coarse estimate was beyond rounding, and the flags of
//! the refused pixels (a pixel may carry several).
//!
//! `cargo run --release -p tremorscan --example motion_breakdown -- AMPLITUDE_MM [sway] [FRAMES]`
//!
//! Settings from the environment, for trying the decoder's parameters: `UNIT_DECAY` (the unit
//! phasor's filter), `TRANSPORT=1` (carry it along the fine phase), `MIN_SUPPORT`,
//! `MOTION_DECAY`, `MOVING_DECAY` (the moving pixels' wider average of the unit phasor,
//! `MotionParams::moving_unit_decay`; 0 turns it off), `OFFSET_BRIGHTNESS`
//! (`MotionParams::offset_brightness_weight`), `ADVECTED=1`
//! (`MotionParams::advected_brightness`), `FROM_REST=1` (`MotionParams::predicted_start`
//! off), `ITERATIONS`, `MOTION_BLOCK` (the motion model's evidence summed over blocks
//! of that many pixels square), `REACH` (the sums' reach scale, `DecodeParams::reach_scale`;
//! the decays are stated at 640 px wide), `EDGE_PHASE`, `EDGE_COLOUR` and `EDGE_CHROMA` (the
//! edge-aware filters' links, `SmoothingParams`), `MOTION_OFF=1` (the paper's still window),
//! `WIDTH` and `HEIGHT` (640×400 by default); for the rig, `SWAY_MM` and `ROLL_DEG` (the
//! parts of `sway`, 4 mm and 3° by default), `TEXTURE` (the skin's texture contrast), `PSF`
//! (the lens's σ, px) and `SUBSURFACE` (the skin's blur of the pattern, projector px).
//! The median time of the motion model's stage over the decoded windows goes to stderr.
//! `FROZEN=1` also decodes each compared window with the hand held still at its centre frame's
//! pose (the same patterns and noise draws) and prints that decode's figures over the same
//! pixels, and each bin's RMS held still: the floor the pixels' noise sets. `MODEL_ERRORS=1`
//! adds each bin's velocity and brightness change against the truth (slope and RMS over the kept
//! pixels; the true brightness change from the window's outer frames rendered under flat light),
//! and `NO_NOISE=1` renders without camera noise.
//! `STILL=1` also prints, per window, the share of every lit pixel refused for each flag.
//! `BY_OUTLINE=1` tallies by the distance to the nearest pixel that is not skin in one of the
//! window's frames instead of by turn, and `ALL_SKIN=1` counts the still skin too. The
//! `coarse ≥ ½` column is the share whose coarse coordinate (the smoothed unit phase) is half a
//! fringe period or more from the truth, where no rounding can find the right order.

use std::f32::consts::TAU;
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
    /// Counted pixels whose coarse coordinate is half a fringe period or more from the truth
    /// (or missing): no rounding can give them the right order.
    coarse_off: usize,
    flags: [usize; 9],
    /// With `FROZEN=1`: the held-still decode's squared error and count over the pixels both
    /// decodes kept within the gross limit.
    frozen_sum2_mm2: f64,
    frozen_n: usize,
    /// With `MODEL_ERRORS=1`: over the kept pixels, Σ model·truth, Σ truth² and Σ (model −
    /// truth)² of the velocity (px/s) and of the brightness change (1/s).
    u_sums: [f64; 3],
    k_sums: [f64; 3],
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
    let env_f64 = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<f64>().ok());
    let mut config = RigConfig::paper(size("WIDTH", 640), size("HEIGHT", 400))?;
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = amplitude_mm;
        if sway {
            t.sway_amplitude_mm = env_f64("SWAY_MM").unwrap_or(4.0);
            t.roll_amplitude_deg = env_f64("ROLL_DEG").unwrap_or(3.0);
        }
    }
    if std::env::var("NO_NOISE").is_ok() {
        config.noise = tremorscan::rig::NoiseModel::none();
    }
    if let Some(c) = env_f64("PSF") {
        config.camera_psf_sigma_px = c;
    }
    if let Some(c) = env_f64("SUBSURFACE") {
        config.subsurface_sigma_px = c;
    }
    if let Some(c) = env_f64("TEXTURE") {
        config.scene.skin_texture_contrast = c;
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
    if let Some(v) = env("EDGE_PHASE") {
        params.smoothing.edge_phase_rad = v;
    }
    if let Some(v) = env("EDGE_COLOUR") {
        params.smoothing.edge_colour_ratio = v;
    }
    if let Some(v) = env("EDGE_CHROMA") {
        params.smoothing.edge_chromaticity = v;
    }
    params.smoothing.transport = std::env::var("TRANSPORT").is_ok();
    if let Some(v) = env("MIN_SUPPORT") {
        params.smoothing.min_support = v;
    }
    if std::env::var("MOTION_OFF").is_ok() {
        params.motion = tremorscan::decode::MotionParams::off();
    }
    if let Some(v) = env("ITERATIONS") {
        params.motion.iterations = v as u32;
    }
    if let Some(v) = env("MOVING_DECAY") {
        params.motion.moving_unit_decay = (v > 0.0).then_some(v);
    }
    if std::env::var("FROM_REST").is_ok() {
        params.motion.predicted_start = false;
    }
    if std::env::var("ADVECTED").is_ok() {
        params.motion.advected_brightness = true;
    }
    if let Some(v) = env("OFFSET_BRIGHTNESS") {
        params.motion.offset_brightness_weight = v;
    }
    if let Some(v) = env("MOTION_BLOCK") {
        params.motion.block_px = v as u32;
    }
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truths: [GroundTruth; 3] = Default::default();
    let mut cloud = PointCloud::default();
    let mut bins = [Bin::default(); BINS];
    let by_outline = std::env::var("BY_OUTLINE").is_ok();
    let all_skin = std::env::var("ALL_SKIN").is_ok();
    let mut refused_windows = 0usize;
    let mut motion_ms: Vec<f64> = Vec::new();
    let frozen = std::env::var("FROZEN").is_ok();
    let mut frozen_cloud = PointCloud::default();
    let mut frozen_frame = rig.blank_frame();
    let mut frozen_stats = Frozen::default();
    for i in 0..frames {
        truths.rotate_left(1);
        rig.render(i, &mut frame, Some(&mut truths[2]))?;
        let out = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => out,
            _ => continue,
        };
        motion_ms.push(out.timings.motion_ms);
        // Every window, compared or not: a refused one also cuts the next one's links.
        if let Some(r) = &out.refused {
            refused_windows += 1;
            eprintln!("window ending at frame {i} refused: {r:?}");
        }
        if i < 2 || (i - 2) % 3 != 0 {
            continue;
        }
        triangulator.triangulate(out, &mut cloud)?;
        if frozen {
            // The same window with the hand held at its centre frame's pose: the same patterns
            // and noise draws, only the motion gone (a decoder of its own, without a past).
            let mut still_decoder =
                SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
            let centre_s = rig.frame_time_s(i - 1);
            for k in i - 2..=i {
                rig.render_pattern(k, rig.pattern_index(k), centre_s, &mut frozen_frame, None)?;
                frozen_frame.time_s = rig.frame_time_s(k);
                if let WindowOutcome::Decoded(o) = still_decoder.push(&frozen_frame)? {
                    triangulator.triangulate(o, &mut frozen_cloud)?;
                }
            }
        }
        let model_errors = std::env::var("MODEL_ERRORS").is_ok();
        let mut true_kappa = Vec::new();
        if model_errors {
            // The true brightness change of each pixel's lit light: the window's outer frames
            // rendered under flat white light.
            let mut flat = [rig.blank_frame(), rig.blank_frame(), rig.blank_frame()];
            for (j, f) in flat.iter_mut().enumerate() {
                let k = i - 2 + j as u64;
                rig.render_flat(k, [255, 255, 255], rig.frame_time_s(k), f, None)?;
            }
            let dt = (rig.frame_time_s(i) - rig.frame_time_s(i - 2)) as f32;
            let sum = |f: &tremorscan::frame::Frame, p: usize| -> f32 {
                (0..3).map(|c| f32::from(f.data[3 * p + c])).sum()
            };
            true_kappa = (0..frame.width * frame.height)
                .map(|p| (sum(&flat[2], p) - sum(&flat[0], p)) / (dt * sum(&flat[1], p)))
                .collect();
        }
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
                if hi - lo <= MOVING_MM && !all_skin {
                    continue;
                }
                let turn = f_max * (truths[2].coordinate_px[p] - truths[0].coordinate_px[p]) / 2.0;
                let k = ((turn / BIN_RAD).floor() + (BINS / 2) as f32).clamp(0.0, (BINS - 1) as f32)
                    as usize;
                let k = if by_outline {
                    outline_distance_px(&truths, x, y, m + 1..m + BINS)
                        .map_or(BINS - 1, |r| r - m - 1)
                } else {
                    k
                };
                let bin = &mut bins[k];
                bin.counted += 1;
                let coarse_periods = (out.coarse_px[p] - truths[1].coordinate_px[p]) * f_max / TAU;
                if coarse_periods.is_nan() || coarse_periods.abs() >= 0.5 {
                    bin.coarse_off += 1;
                }
                let z = cloud.point_in_camera_mm[p][2];
                if frozen {
                    let still_z = frozen_cloud.point_in_camera_mm[p][2];
                    frozen_stats.add(z, still_z, d[1]);
                    if (z - d[1]).abs() <= GROSS_MM && (still_z - d[1]).abs() <= GROSS_MM {
                        bin.frozen_sum2_mm2 += f64::from(still_z - d[1]).powi(2);
                        bin.frozen_n += 1;
                    }
                }
                if z.is_finite() && model_errors {
                    let dt = (rig.frame_time_s(i) - rig.frame_time_s(i - 2)) as f32;
                    let u_true = (truths[2].coordinate_px[p] - truths[0].coordinate_px[p]) / dt;
                    let pairs = [
                        (&mut bin.u_sums, out.velocity_px_per_s[p], u_true),
                        (&mut bin.k_sums, out.brightness_rate_per_s[p], true_kappa[p]),
                    ];
                    for (sums, model, truth) in pairs {
                        if truth.is_finite() {
                            sums[0] += f64::from(model * truth);
                            sums[1] += f64::from(truth * truth);
                            sums[2] += f64::from((model - truth).powi(2));
                        }
                    }
                }
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
    motion_ms.sort_by(f64::total_cmp);
    if let Some(median) = motion_ms.get(motion_ms.len() / 2) {
        eprintln!(
            "motion model: median {median:.2} ms over {} windows",
            motion_ms.len()
        );
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
        "{amplitude_mm} mm{}, {frames} frames, {total} moving px, {refused_windows} windows refused (decode::broken)",
        if sway { " with sway" } else { "" }
    );
    if frozen {
        frozen_stats.print();
    }
    let label = if by_outline {
        "px from outline"
    } else {
        "turn rad"
    };
    print!("| {label} | share | kept | gross | RMS mm | coarse ≥ ½ |");
    if frozen {
        print!(" held still RMS mm |");
    }
    let model_errors = std::env::var("MODEL_ERRORS").is_ok();
    if model_errors {
        print!(" u slope | u RMS px/s | κ slope | κ RMS /s |");
    }
    for (_, name) in FLAGS {
        print!(" {name} |");
    }
    println!();
    println!(
        "|---|---:|---:|---:|---:|---:|{}",
        "---:|".repeat(FLAGS.len() + usize::from(frozen) + 4 * usize::from(model_errors))
    );
    for (k, b) in bins.iter().enumerate() {
        if b.counted == 0 {
            continue;
        }
        let row = if by_outline {
            let r = k + OUTLINE_MARGIN_PX + 1;
            if k + 1 == BINS {
                format!("≥ {r}")
            } else {
                format!("{r}")
            }
        } else {
            let lo = (k as f32 - (BINS / 2) as f32) * BIN_RAD;
            format!("{lo:+.1}..{:+.1}", lo + BIN_RAD)
        };
        print!(
            "| {row} | {} % | {} % | {} % | {} | {} % |",
            share(b.counted, total, 2),
            share(b.valid, b.counted, 1),
            share(b.gross, b.counted, 2),
            rms(b.sum2_mm2, b.valid - b.gross),
            share(b.coarse_off, b.counted, 1)
        );
        if frozen {
            print!(" {} |", rms(b.frozen_sum2_mm2, b.frozen_n));
        }
        if model_errors {
            for sums in [b.u_sums, b.k_sums] {
                print!(
                    " {:.2} | {:.1} |",
                    sums[0] / sums[1],
                    (sums[2] / b.valid.max(1) as f64).sqrt()
                );
            }
        }
        for v in b.flags {
            print!(" {} |", share(v, b.counted, 1));
        }
        println!();
    }
    Ok(())
}

/// The moving decode beside the same window decoded with the hand held still at its centre
/// frame's pose (`FROZEN=1`), over the counted pixels: what the pixels' noise alone leaves.
#[derive(Default)]
struct Frozen {
    counted: usize,
    kept: usize,
    gross: usize,
    sum2_mm2: f64,
    /// Pixels kept within the gross limit by both decodes, and their squared errors in each.
    both: usize,
    both_moving_sum2_mm2: f64,
    both_held_sum2_mm2: f64,
}

impl Frozen {
    fn add(&mut self, moving_mm: f32, held_mm: f32, truth_mm: f32) {
        self.counted += 1;
        if !held_mm.is_finite() {
            return;
        }
        self.kept += 1;
        let held = f64::from(held_mm - truth_mm);
        let moving = f64::from(moving_mm - truth_mm);
        if held.abs() > f64::from(GROSS_MM) {
            self.gross += 1;
            return;
        }
        self.sum2_mm2 += held * held;
        if moving_mm.is_finite() && moving.abs() <= f64::from(GROSS_MM) {
            self.both += 1;
            self.both_moving_sum2_mm2 += moving * moving;
            self.both_held_sum2_mm2 += held * held;
        }
    }

    fn print(&self) {
        println!(
            "held still at the centre pose: kept {} %, gross {} % of kept, RMS {} mm; kept by both ({} px): moving RMS {} mm, held still RMS {} mm",
            share(self.kept, self.counted, 2),
            share(self.gross, self.kept, 3),
            rms(self.sum2_mm2, self.kept - self.gross),
            self.both,
            rms(self.both_moving_sum2_mm2, self.both),
            rms(self.both_held_sum2_mm2, self.both),
        );
    }
}

/// The Chebyshev distance from pixel `(x, y)` to the nearest pixel that is not skin in one of
/// the window's frames, searched over `radii` (the first radius whose square ring holds one),
/// or `None` beyond them.
fn outline_distance_px(
    truths: &[GroundTruth; 3],
    x: usize,
    y: usize,
    radii: std::ops::Range<usize>,
) -> Option<usize> {
    let (w, h) = (truths[0].width, truths[0].height);
    let skin = |xx: usize, yy: usize| {
        truths
            .iter()
            .all(|t| t.surface[yy * w + xx] == tremorscan::rig::truth::surface::SKIN)
    };
    radii.into_iter().find(|&r| {
        let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        (x0..=x1).any(|xx| !skin(xx, y0) || !skin(xx, y1))
            || (y0..=y1).any(|yy| !skin(x0, yy) || !skin(x1, yy))
    })
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
