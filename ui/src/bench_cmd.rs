//! `tremorscan bench`: does this PC keep up with the camera? Renders the virtual rig at the
//! camera's size, runs the decode thread's per-frame work for a few seconds and prints per-stage
//! median and p99, the sustainable frame rate, and one machine-readable line.
//!
//! When the CPU path does not keep up, the check goes on to measure the camera's binned sizes
//! (2×2, 3×3, 4×4: the image sizes of a camera binned that way, the camera's *Binning* in
//! Settings) until one keeps up, so that the lab learns what this PC can do, not only what it
//! cannot.

use crate::gpu_decode::{GpuBackend, GpuContext};
use anyhow::{Context, Result};
use std::io::Write;
use std::time::Duration;
use tremorscan::bench::{prepare, run_cpu, run_with, BenchInputs, BenchReport, DEVICE_STAGE};
use tremorscan::decode::{CpuBackend, DecodeParams, MotionParams};

/// Binning factors measured, in this order, when the requested size does not keep up.
const BINNINGS: [usize; 3] = [2, 3, 4];
/// Seconds each binned size is measured at most (it only has to answer yes or no).
const BINNED_SECONDS: f64 = 3.0;

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
    /// The camera's frame rate the decode must sustain, frames per second.
    #[arg(long, default_value_t = 121.0)]
    pub fps: f64,
    /// Skip the GPU decode.
    #[arg(long)]
    pub no_gpu: bool,
}

pub fn run_bench(args: &BenchArgs) -> Result<()> {
    if !(args.fps.is_finite() && args.fps > 0.0) {
        anyhow::bail!("--fps {} is not a frame rate", args.fps);
    }
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
    write_cpu_report(&mut out, &report, args.fps)?;
    // The same windows decoded as the paper's still window: what the motion model costs.
    let still = DecodeParams {
        motion: MotionParams::off(),
        ..DecodeParams::default()
    };
    let still_report = run_with(&inputs, duration, Box::new(CpuBackend), still)
        .context("the CPU benchmark of the still window failed")?;
    writeln!(
        out,
        "CPU, still window (no motion model): decode {:.2} ms median per window, {:.1} frames/s \
         sustainable; the motion model costs {:.2}× its decode",
        still_report.decode_ms_median,
        still_report.fps_sustainable,
        report.decode_ms_median / still_report.decode_ms_median
    )?;
    write_still_stages(&mut out, &still_report)?;
    if report.fps_sustainable < args.fps {
        let binned_duration = duration.min(Duration::from_secs_f64(BINNED_SECONDS));
        find_binning(&mut out, args, binned_duration)?;
    }
    let gpu = if args.no_gpu {
        Err(anyhow::anyhow!("skipped (--no-gpu)"))
    } else {
        run_gpu(&inputs, duration, DecodeParams::default())
    };
    write_gpu_report(&mut out, &gpu)?;
    if let Ok(g) = &gpu {
        // The GPU's still window in the same process: what the model costs there.
        let still_gpu = run_gpu(&inputs, duration, still)
            .context("the GPU benchmark of the still window failed")?;
        writeln!(
            out,
            "GPU, still window (no motion model): decode {:.2} ms median per window; the motion \
             model costs {:.2}× its decode",
            still_gpu.decode_ms_median,
            g.decode_ms_median / still_gpu.decode_ms_median
        )?;
    }
    writeln!(
        out,
        "decode_ms_median={:.3} triangulate_ms_median={:.3} fps_sustainable={:.2}",
        report.decode_ms_median, report.triangulate_ms_median, report.fps_sustainable
    )?;
    Ok(())
}

/// The still window's stages beside the motion model's table: where the model's cost lies.
fn write_still_stages(out: &mut impl Write, still: &BenchReport) -> Result<()> {
    let stages: Vec<String> = still
        .stages
        .iter()
        .filter(|s| s.median_ms > 0.0)
        .map(|s| format!("{} {:.2}", s.name, s.median_ms))
        .collect();
    writeln!(out, "  its stages, median ms: {}", stages.join(", "))?;
    Ok(())
}

/// Measures the CPU path at the binned sizes of the requested one, smallest binning first, and
/// stops at the first that keeps up with `args.fps`. Sizes under 64×64 are not tried.
fn find_binning(out: &mut impl Write, args: &BenchArgs, duration: Duration) -> Result<()> {
    let mut largest_tried = None;
    for bin in BINNINGS {
        let (width, height) = (args.width / bin, args.height / bin);
        if width < 64 || height < 64 {
            break;
        }
        largest_tried = Some(bin);
        let inputs = prepare(width, height)
            .with_context(|| format!("could not prepare the test frames at {width}×{height}"))?;
        let report = run_cpu(&inputs, duration)
            .with_context(|| format!("the CPU benchmark at {width}×{height} failed"))?;
        let keeps_up = report.fps_sustainable >= args.fps;
        writeln!(
            out,
            "CPU with {bin}×{bin} binning ({width}×{height}): {:.1} frames/s sustainable over {} windows; {}",
            report.fps_sustainable,
            report.windows,
            if keeps_up { "keeps up" } else { "does NOT keep up" }
        )?;
        if keeps_up {
            return Ok(());
        }
    }
    match largest_tried {
        Some(max) => writeln!(
            out,
            "CPU: no binning up to {max}×{max} keeps up with a {} FPS camera on this PC",
            args.fps
        )?,
        None => writeln!(
            out,
            "CPU: no binned size of {}×{} is 64×64 or larger, so none was measured",
            args.width, args.height
        )?,
    }
    Ok(())
}

/// Runs the same per-frame work with the decode on the GPU (wgpu's preferred adapter, software
/// ones included) with `params` (the motion model with the default ones): upload of the new
/// frame, the shader's stages in two submissions (the window's noise is read back between
/// them), read-back, the mixed-pixel stage on the host; triangulation and the display hand-off
/// stay on the CPU.
fn run_gpu(inputs: &BenchInputs, duration: Duration, params: DecodeParams) -> Result<BenchReport> {
    let ctx = GpuContext::new()?;
    let backend = GpuBackend::new(ctx, &inputs.sequence, &params)?;
    Ok(run_with(inputs, duration, Box::new(backend), params)?)
}

/// The CPU path's table, verdict against `camera_fps` and memory.
fn write_cpu_report(out: &mut impl Write, r: &BenchReport, camera_fps: f64) -> std::io::Result<()> {
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
    let verdict = if r.fps_sustainable >= camera_fps {
        "keeps up with"
    } else {
        "does NOT keep up with"
    };
    writeln!(
        out,
        "CPU: {:.1} frames/s sustainable; this PC {verdict} a {camera_fps} FPS camera at this size",
        r.fps_sustainable
    )?;
    memory_line(out, "CPU", r)
}

/// The GPU path's figures, or why it was not measured.
fn write_gpu_report(out: &mut impl Write, gpu: &Result<BenchReport>) -> std::io::Result<()> {
    match gpu {
        Ok(g) => {
            let stage = |name: &str| g.stages.iter().find(|s| s.name == name);
            if let Some(d) = stage("decode (total)") {
                writeln!(
                    out,
                    "{}: decode {:.2} ms median, {:.2} ms p99 over {} windows (upload of the new frame, the stages, read-back, mixed pixels on the host)",
                    g.backend, d.median_ms, d.p99_ms, g.windows
                )?;
            }
            match stage(DEVICE_STAGE) {
                Some(d) => writeln!(
                    out,
                    "GPU: compute by the GPU's clock {:.2} ms median, {:.2} ms p99 (the compute passes, no transfers)",
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
    Ok(())
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
    }?;
    let held = &r.held;
    writeln!(
        out,
        "{path}: held by the stages: decoder {:.1} MB, triangulator's tables {:.1} MB, point cloud {:.1} MB, the test frames {:.1} MB",
        mb(held.decoder_bytes as u64),
        mb(held.triangulator_bytes as u64),
        mb(held.cloud_bytes as u64),
        mb(held.frames_bytes as u64)
    )
}
