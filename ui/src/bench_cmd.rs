//! `tremorscan bench`: does this PC keep up with the camera? Renders the virtual rig at the
//! camera's size, runs the decode thread's per-frame work for a few seconds and prints per-stage
//! median and p99, the sustainable frame rate, and one machine-readable line.

use anyhow::{Context, Result};
use std::io::Write;
use std::time::Duration;
use tremorscan::bench::{run, BenchConfig, BenchReport};

/// The camera's frame rate the check compares against.
const CAMERA_FPS: f64 = 121.0;

/// Options of `tremorscan bench`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchArgs {
    /// Image width, camera pixels.
    #[arg(long, default_value_t = 1920)]
    pub width: usize,
    /// Image height, camera pixels.
    #[arg(long, default_value_t = 1200)]
    pub height: usize,
    /// How long to measure, seconds (after rendering the test frames).
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
}

pub fn run_bench(args: &BenchArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "rendering test frames of the virtual rig at {}×{}…",
        args.width, args.height
    )?;
    out.flush()?;
    let duration = Duration::try_from_secs_f64(args.seconds)
        .with_context(|| format!("--seconds {} is not a duration", args.seconds))?;
    let report = run(&BenchConfig {
        width: args.width,
        height: args.height,
        duration,
    })
    .context("the benchmark failed")?;
    write_report(&mut out, &report)?;
    Ok(())
}

fn write_report(out: &mut impl Write, r: &BenchReport) -> std::io::Result<()> {
    writeln!(
        out,
        "{} windows at {}×{} on {} threads, {} valid points per window",
        r.windows, r.width, r.height, r.threads, r.valid_points
    )?;
    writeln!(out, "{:<24} {:>10} {:>10}", "stage", "median ms", "p99 ms")?;
    for s in &r.stages {
        writeln!(
            out,
            "{:<24} {:>10.2} {:>10.2}",
            s.name, s.median_ms, s.p99_ms
        )?;
    }
    let verdict = if r.fps_sustainable >= CAMERA_FPS {
        "keeps up with"
    } else {
        "does NOT keep up with"
    };
    writeln!(
        out,
        "CPU: {:.1} frames/s sustainable; this PC {verdict} a {CAMERA_FPS} FPS camera at this size",
        r.fps_sustainable
    )?;
    writeln!(out, "GPU: not measured; this build has no GPU decode path")?;
    writeln!(
        out,
        "decode_ms_median={:.3} triangulate_ms_median={:.3} fps_sustainable={:.2}",
        r.decode_ms_median, r.triangulate_ms_median, r.fps_sustainable
    )
}
