//! `tremorscan bench`: does this PC keep up with the camera? Renders the virtual rig at the
//! camera's size, runs the decode thread's per-frame work for a few seconds and prints per-stage
//! median and p99, the sustainable frame rate, and one machine-readable line.

use crate::gpu_decode::{GpuBackend, GpuContext};
use anyhow::{Context, Result};
use std::io::Write;
use std::time::Duration;
use tremorscan::bench::{prepare, run_cpu, run_with, BenchInputs, BenchReport, DEVICE_STAGE};
use tremorscan::decode::DecodeParams;

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
    /// How long to measure each path, seconds (after rendering the test frames).
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Skip the GPU decode.
    #[arg(long)]
    pub no_gpu: bool,
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
    let inputs = prepare(args.width, args.height).context("could not prepare the test frames")?;
    let report = run_cpu(&inputs, duration).context("the CPU benchmark failed")?;
    let gpu = if args.no_gpu {
        Err(anyhow::anyhow!("skipped (--no-gpu)"))
    } else {
        run_gpu(&inputs, duration)
    };
    write_report(&mut out, &report, &gpu)?;
    Ok(())
}

/// Runs the same per-frame work with the decode on the GPU (wgpu's preferred adapter, software
/// ones included): upload of the new frame, the six shader stages, read-back; triangulation and
/// the display hand-off stay on the CPU.
fn run_gpu(inputs: &BenchInputs, duration: Duration) -> Result<BenchReport> {
    let ctx = GpuContext::new()?;
    let backend = GpuBackend::new(ctx, &inputs.rig.sequence, &DecodeParams::default())?;
    Ok(run_with(inputs, duration, Box::new(backend))?)
}

fn write_report(
    out: &mut impl Write,
    r: &BenchReport,
    gpu: &Result<BenchReport>,
) -> std::io::Result<()> {
    writeln!(
        out,
        "{} windows at {}×{} on the {}, {} valid points per window",
        r.windows, r.width, r.height, r.backend, r.valid_points
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
    memory_line(out, "CPU", r)?;
    match gpu {
        Ok(g) => {
            let stage = |name: &str| g.stages.iter().find(|s| s.name == name);
            if let Some(d) = stage("decode (total)") {
                writeln!(
                    out,
                    "{}: decode {:.2} ms median, {:.2} ms p99 over {} windows (upload of the new frame, six stages, read-back)",
                    g.backend, d.median_ms, d.p99_ms, g.windows
                )?;
            }
            match stage(DEVICE_STAGE) {
                Some(d) => writeln!(
                    out,
                    "GPU: compute by the GPU's clock {:.2} ms median, {:.2} ms p99 (the six stages, no transfers)",
                    d.median_ms, d.p99_ms
                )?,
                None => writeln!(
                    out,
                    "GPU: no compute time by the GPU's clock (a software adapter, or no timestamp queries)"
                )?,
            }
            if let Some(t) = stage("decode thread (total)") {
                writeln!(
                    out,
                    "GPU: decode thread {:.2} ms median, {:.2} ms p99 with triangulation ({:.2} ms) and display hand-off on the CPU: {:.1} frames/s sustainable",
                    t.median_ms, t.p99_ms, g.triangulate_ms_median, g.fps_sustainable
                )?;
            }
            memory_line(out, "GPU", g)?;
        }
        Err(e) => writeln!(out, "GPU: not measured: {e:#}")?,
    }
    writeln!(
        out,
        "decode_ms_median={:.3} triangulate_ms_median={:.3} fps_sustainable={:.2}",
        r.decode_ms_median, r.triangulate_ms_median, r.fps_sustainable
    )
}

/// The process's resident memory over the measured windows of `r`: steady state means no growth.
fn memory_line(out: &mut impl Write, path: &str, r: &BenchReport) -> std::io::Result<()> {
    let mb = |bytes: u64| bytes as f64 / 1e6;
    match r.memory {
        Some((start, end)) => writeln!(
            out,
            "{path}: resident memory {:.1} MB after the warm-up, {:.1} MB at the end ({:+.1} MB over {} windows); peak of the process so far {:.1} MB",
            mb(start.resident_bytes),
            mb(end.resident_bytes),
            mb(end.resident_bytes) - mb(start.resident_bytes),
            r.windows,
            mb(end.peak_bytes)
        ),
        None => writeln!(out, "{path}: resident memory not reported by this system"),
    }
}
