//! The figures of `docs/accuracy.md`'s "Following the skin" tables: a control point placed on
//! one of the rig's named surface points (0 index fingertip, 1 middle fingertip, …), tracked
//! through `FRAMES` frames at 640×400 following the skin (as `track` and `analyze` give it, and
//! as matched before the decode window's mean is undone) and at its fixed pixel, against the
//! material point: valid share, 3D RMS and maximum distance, and the peak frequency and
//! peak-to-peak along each series' principal axis beside the truth's.
//!
//! `cargo run --release -p tremorscan --example skin_tracking -- FRAMES POINT [still|HZ]`: the
//! issue's hand (finger flexion 3 mm, sway 4 mm, roll 5°, 4.2 Hz, or at HZ), or a still hand.
//! `FLEX_MM`, `SWAY_MM` and `ROLL_DEG` in the environment change the moving hand's flexion,
//! sway and roll (the motion sweep's fingertip: `FLEX_MM=10 SWAY_MM=0 ROLL_DEG=0`).

use tremorscan::decode::{frames_averaged, DecodeParams};
use tremorscan::rig::skin_eval::{skin_tracking, TrackAgainstTruth};
use tremorscan::rig::{RigConfig, Tremor, VirtualRig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: skin_tracking FRAMES POINT [still|HZ]";
    let frames: u64 = args.next().ok_or(usage)?.parse()?;
    let point: usize = args.next().ok_or(usage)?.parse()?;
    let last = args.next();
    let still = last.as_deref() == Some("still");
    let hz: f64 = match last.as_deref() {
        Some(text) if !still => text.parse()?,
        _ => 4.2,
    };
    let mut config = RigConfig::paper(640, 400)?;
    config.scene.hand = Some(if still {
        Tremor::flexion(4.2, 0.0, 0.0)
    } else {
        let env = |name: &str, default: f64| {
            std::env::var(name)
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(default)
        };
        Tremor {
            sway_amplitude_mm: env("SWAY_MM", 4.0),
            roll_amplitude_deg: env("ROLL_DEG", 5.0),
            ..Tremor::flexion(hz, env("FLEX_MM", 3.0), 0.3)
        }
    });
    let sequence = config.default_sequence()?;
    let rig = VirtualRig::new(config, sequence)?;
    let params = DecodeParams::default();
    let r = skin_tracking(&rig, params, frames, point)?;
    let window_frames = frames_averaged(&rig.sequence, &params);
    println!("point {point} placed at {:?}, {frames} frames", r.placed_at);
    println!(
        "| mode | valid | 3D RMS mm | max mm | peak Hz (truth) | peak-to-peak mm (truth) | error |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, track) in [
        ("follows the skin", &r.follow),
        ("follows the skin, window mean kept", &r.follow_window_mean),
        ("fixed pixel", &r.fixed),
    ] {
        row(name, track, window_frames);
    }
    if still {
        println!(
            "drift of the followed point, last second against the first: {}",
            drift(&r.follow)
        );
    }
    Ok(())
}

fn row(name: &str, track: &TrackAgainstTruth, window_frames: usize) {
    let errors = track.errors_mm();
    let max = errors.iter().copied().fold(0.0, f64::max);
    let rms = track
        .rms_mm()
        .map_or("—".to_string(), |v| format!("{v:.3}"));
    let figures = match track.principal_figures(window_frames) {
        (Ok(m), Ok(t)) => {
            let hz = |r: &tremorscan::tremor::TremorReport| {
                r.peak_frequency_hz
                    .map_or("none".to_string(), |f| format!("{f:.3}"))
            };
            // A relative error against a still truth (0 mm) is no figure: say so.
            let error = if t.amplitude_peak_to_peak_mm > 0.0 {
                let ratio = m.amplitude_peak_to_peak_mm / t.amplitude_peak_to_peak_mm;
                format!("{:+.2} %", 100.0 * (ratio - 1.0))
            } else {
                "— (truth still)".to_string()
            };
            format!(
                "{} ({}) | {:.3} ({:.3}) | {error}",
                hz(&m),
                hz(&t),
                m.amplitude_peak_to_peak_mm,
                t.amplitude_peak_to_peak_mm,
            )
        }
        (m, t) => format!("{:?} | {:?} |", m.err(), t.err()),
    };
    println!(
        "| {name} | {:.1} % | {rms} | {max:.3} | {figures} |",
        100.0 * track.valid_share()
    );
}

/// Distance between the mean positions of the first and the last second (121 windows), mm.
fn drift(track: &TrackAgainstTruth) -> String {
    let positions: Vec<[f64; 3]> = track.samples.iter().filter_map(|s| s.position_mm).collect();
    if positions.len() < 2 * 121 {
        return "too few valid samples".to_string();
    }
    let mean = |part: &[[f64; 3]]| {
        [0, 1, 2].map(|a| part.iter().map(|p| p[a]).sum::<f64>() / part.len() as f64)
    };
    let (first, last) = (
        mean(&positions[..121]),
        mean(&positions[positions.len() - 121..]),
    );
    let d = (0..3)
        .map(|a| (last[a] - first[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    format!("{d:.4} mm")
}
