//! `tremorscan sweep --motion`: how the decoder copes with moving fingertips, as Markdown tables.
//!
//! For each peak fingertip amplitude the trembling hand is rendered at the rig's default noise,
//! once with the fingers flexing along the optical axis only and once with lateral sway added
//! (the whole hand swaying sideways and rolling about the forearm). The same frames are decoded
//! by the still model (the paper's window, motion ignored) and by the motion model, and compared
//! with the truth by [`tremorscan::rig::motion_eval`]: coverage, gross errors and RMS of the
//! moving skin, RMS of the still skin. A second table gives, for the same rigs, what `tremorscan
//! analyze --fixed-pixel` reports at the index fingertip's pixel over a 3 s trial against the
//! truth there ([`tremorscan::rig::tremor_eval`]), or why it reports no figure. A third gives
//! what `analyze` reports by default, the control point following the skin it was placed on
//! ([`tremorscan::rig::skin_eval`]), against the material point: the motion model only, as it
//! is the decoder such a trial runs.

use crate::sweep::SweepArgs;
use anyhow::{ensure, Context, Result};
use tremorscan::decode::{frames_averaged, DecodeParams, MotionParams};
use tremorscan::rig::motion_eval::{evaluate_motion, MotionAccuracy, GROSS_MM};
use tremorscan::rig::skin_eval::skin_tracking;
use tremorscan::rig::tremor_eval::{fingertip_tremor, FingertipTremor};
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan::tremor::{TremorError, TremorReport};

/// Lateral sway of the "with sway" rows: peak sideways displacement, mm, and peak roll about
/// the forearm, degrees.
pub const SWAY_MM: f64 = 4.0;
pub const ROLL_DEG: f64 = 3.0;

/// The rig of one row.
pub fn motion_rig(
    width: usize,
    height: usize,
    amplitude_mm: f64,
    sway: bool,
    seed: u64,
) -> Result<VirtualRig> {
    let mut config = RigConfig::paper(width, height)?;
    config.seed = seed;
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = amplitude_mm;
        if sway {
            t.sway_amplitude_mm = SWAY_MM;
            t.roll_amplitude_deg = ROLL_DEG;
        }
    }
    let seq = config.default_sequence()?;
    Ok(VirtualRig::new(config, seq)?)
}

fn percent(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{:.2} %", 100.0 * v))
}

fn mm(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{v:.3} mm"))
}

pub fn run(args: &SweepArgs) -> Result<()> {
    ensure!(args.frames >= 3, "--frames must be at least 3 (one window)");
    for &a in &args.amplitudes_mm {
        ensure!(
            a.is_finite() && a >= 0.0,
            "amplitude {a} mm is not a displacement"
        );
    }
    println!(
        "{}×{}, {} frames per row, every third window; moving: true depth changes > 0.5 mm in \
         the window; gross: > {GROSS_MM} mm off; pixels ≥ 2 px inside the skin's outline",
        args.width, args.height, args.frames
    );
    println!();
    println!(
        "| peak amplitude | lateral sway | decoder | moving px | coverage | gross | RMS | still: \
         coverage | still: RMS |"
    );
    println!("|---:|---|---|---:|---:|---:|---:|---:|---:|");
    for sway in [false, true] {
        for &amplitude_mm in &args.amplitudes_mm {
            let rig = motion_rig(args.width, args.height, amplitude_mm, sway, args.seed)?;
            for (name, params) in decoders(args) {
                let acc: MotionAccuracy = evaluate_motion(&rig, params, args.frames, 3)
                    .with_context(|| format!("amplitude {amplitude_mm} mm, {name}"))?;
                println!(
                    "| {amplitude_mm} mm | {} | {name} | {} | {} | {} | {} | {} | {} |",
                    sway_label(sway),
                    acc.moving.counted,
                    percent(acc.moving.coverage()),
                    percent(acc.moving.gross_rate()),
                    mm(acc.moving.rms_mm()),
                    percent(acc.still.coverage()),
                    mm(acc.still.rms_mm()),
                );
            }
        }
    }
    if args.tip_frames > 0 {
        fingertip_table(args)?;
        followed_table(args)?;
    }
    Ok(())
}

/// The decoders the sweep compares; the motion model with the settings `args` names.
fn decoders(args: &SweepArgs) -> [(&'static str, DecodeParams); 2] {
    [
        ("still model", MotionParams::off()),
        (
            "motion model",
            MotionParams {
                advected_brightness: args.advected_brightness,
                predicted_start: !args.from_rest,
                ..MotionParams::default()
            },
        ),
    ]
    .map(|(name, motion)| {
        (
            name,
            DecodeParams {
                motion,
                ..DecodeParams::default()
            },
        )
    })
}

fn sway_label(sway: bool) -> String {
    if sway {
        format!("{SWAY_MM} mm, {ROLL_DEG}°")
    } else {
        "none".into()
    }
}

/// The fingertip trials: measured figures beside the truth at the same pixel.
fn fingertip_table(args: &SweepArgs) -> Result<()> {
    println!();
    println!(
        "Index fingertip's pixel, {} frames ({:.1} s), displacement along the optical axis; \
         truth: the skin seen along the pixel's ray",
        args.tip_frames,
        args.tip_frames as f64 / 121.0
    );
    println!();
    println!(
        "| peak amplitude | lateral sway | decoder | valid | peak Hz (truth) | peak-to-peak mm \
         (truth) | error | MDS-UPDRS bin (truth) |"
    );
    println!("|---:|---|---|---:|---:|---:|---:|---:|");
    for sway in [false, true] {
        for &amplitude_mm in &args.amplitudes_mm {
            let rig = motion_rig(args.width, args.height, amplitude_mm, sway, args.seed)?;
            for (name, params) in decoders(args) {
                let tip = fingertip_tremor(&rig, params, args.tip_frames)
                    .with_context(|| format!("fingertip, amplitude {amplitude_mm} mm, {name}"))?;
                println!(
                    "| {amplitude_mm} mm | {} | {name} | {} |",
                    sway_label(sway),
                    fingertip_cells(&tip)
                );
            }
        }
    }
    Ok(())
}

/// The fingertip trials as a control point that follows the skin measures them, against the
/// material point it was placed on (figures along each series' principal axis).
fn followed_table(args: &SweepArgs) -> Result<()> {
    println!();
    println!(
        "Index fingertip followed on the skin (the default of `analyze`), motion model, {} frames; truth: the material point the point was placed on",
        args.tip_frames
    );
    println!();
    println!(
        "| peak amplitude | lateral sway | valid | 3D RMS from the material point | peak Hz (truth) | peak-to-peak mm (truth) | error | MDS-UPDRS bin (truth) |"
    );
    println!("|---:|---|---:|---:|---:|---:|---:|---:|");
    let [_, (_, params)] = decoders(args);
    for sway in [false, true] {
        for &amplitude_mm in &args.amplitudes_mm {
            let rig = motion_rig(args.width, args.height, amplitude_mm, sway, args.seed)?;
            let track = skin_tracking(&rig, params, args.tip_frames, 0)
                .with_context(|| format!("followed fingertip, amplitude {amplitude_mm} mm"))?
                .follow;
            let (measured, truth) =
                track.principal_figures(frames_averaged(&rig.sequence, &params));
            let figures = match (&measured, &truth) {
                (Ok(m), Ok(t)) => format!(
                    "{} ({}) | {:.2} ({:.2}) | {} | {} ({})",
                    hz(m),
                    hz(t),
                    m.amplitude_peak_to_peak_mm,
                    t.amplitude_peak_to_peak_mm,
                    relative_error(m, t),
                    m.updrs_amplitude_bin,
                    t.updrs_amplitude_bin,
                ),
                (Err(e), _) => format!("{} | – | – | –", missing(e)),
                (Ok(_), Err(e)) => format!("no truth: {} | – | – | –", missing(e)),
            };
            println!(
                "| {amplitude_mm} mm | {} | {:.1} % | {} | {figures} |",
                sway_label(sway),
                100.0 * track.valid_share(),
                mm(track.rms_mm()),
            );
        }
    }
    Ok(())
}

/// A report's peak frequency, Hz, or "none".
fn hz(r: &TremorReport) -> String {
    r.peak_frequency_hz
        .map_or("none".into(), |f| format!("{f:.3}"))
}

/// The measured peak-to-peak against the truth's, or "–" against a still truth.
fn relative_error(measured: &TremorReport, truth: &TremorReport) -> String {
    if truth.amplitude_peak_to_peak_mm > 0.0 {
        let ratio = measured.amplitude_peak_to_peak_mm / truth.amplitude_peak_to_peak_mm;
        format!("{:+.1} %", 100.0 * (ratio - 1.0))
    } else {
        "–".into()
    }
}

/// One row's figures: each measured figure with the truth's in brackets, or why it is missing.
fn fingertip_cells(tip: &FingertipTremor) -> String {
    let truth = |f: &dyn Fn(&TremorReport) -> String| {
        tip.truth
            .as_ref()
            .map_or_else(|_| "no truth".to_string(), f)
    };
    match &tip.measured {
        Ok(m) => format!(
            "{:.1} % | {} ({}) | {:.2} ({}) | {} | {} ({})",
            100.0 * m.valid_fraction,
            hz(m),
            truth(&hz),
            m.amplitude_peak_to_peak_mm,
            truth(&|t| format!("{:.2}", t.amplitude_peak_to_peak_mm)),
            tip.peak_to_peak_error()
                .map_or("–".into(), |e| format!("{:+.1} %", 100.0 * e)),
            m.updrs_amplitude_bin,
            truth(&|t| t.updrs_amplitude_bin.to_string()),
        ),
        Err(e) => format!(
            "{} | – ({}) | – ({}) | – | – ({})",
            missing(e),
            truth(&hz),
            truth(&|t| format!("{:.2}", t.amplitude_peak_to_peak_mm)),
            truth(&|t| t.updrs_amplitude_bin.to_string()),
        ),
    }
}

/// Why a figure is missing, short enough for a table cell.
fn missing(e: &TremorError) -> String {
    match e {
        TremorError::TooFewValid { why } => format!("figures missing: {why}"),
        other => other.to_string(),
    }
}
