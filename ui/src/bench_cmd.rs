//! `tremorscan bench`: does this PC keep up with the camera? Renders the virtual rig at the
//! camera's size, runs the decode thread's per-frame work for a few seconds and prints per-stage
//! median and p99, the sustainable frame rate, and one machine-readable line.

use crate::gpu_decode::{GpuContext, GpuDecoder};
use anyhow::{Context, Result};
use std::io::Write;
use std::time::{Duration, Instant};
use tremorscan::bench::{prepare, quantile, run_cpu, BenchInputs, BenchReport, StageStats};
use tremorscan::decode::{DecodeParams, WindowSolver};

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

/// GPU decode times per window, and what the decode thread sustains with them.
struct GpuFigures {
    adapter: String,
    decode: StageStats,
    windows: usize,
    fps_sustainable: f64,
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
        run_gpu(&inputs, duration, &report)
    };
    write_report(&mut out, &report, &gpu)?;
    Ok(())
}

/// Times the GPU decode (upload, the six shader stages, read-back) per window; the decode
/// thread then triangulates and copies for the display on the CPU as before.
fn run_gpu(inputs: &BenchInputs, duration: Duration, cpu: &BenchReport) -> Result<GpuFigures> {
    let ctx = GpuContext::new()?;
    let rig = &inputs.rig;
    let (w, h) = (rig.width(), rig.height());
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk)?;
    let n = rig
        .sequence
        .chebyshev_n()
        .context("the rig's sequence is not CPS")?;
    let mut decoder = GpuDecoder::new(&ctx, w, h, &solver, &DecodeParams::default(), n)?;
    // Windows starting on pattern 0: frames 0–2 and 3–5 of the six.
    let windows: Vec<[&tremorscan::frame::Frame; 3]> = inputs
        .frames
        .chunks_exact(3)
        .map(|c| [&c[0], &c[1], &c[2]])
        .collect();
    let (mut coordinate, mut invalid) = (Vec::new(), Vec::new());
    for window in &windows {
        decoder.decode(*window, &mut coordinate, &mut invalid)?;
    }
    let mut samples = Vec::new();
    let started = Instant::now();
    while started.elapsed() < duration || samples.len() < 3 {
        let t0 = Instant::now();
        decoder.decode(
            windows[samples.len() % windows.len()],
            &mut coordinate,
            &mut invalid,
        )?;
        samples.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let windows = samples.len();
    let median = quantile(&mut samples, 0.5);
    let stage = |name: &str| {
        cpu.stages
            .iter()
            .find(|s| s.name == name)
            .map_or(0.0, |s| s.median_ms)
    };
    Ok(GpuFigures {
        adapter: ctx.adapter,
        decode: StageStats {
            name: "GPU decode",
            median_ms: median,
            p99_ms: quantile(&mut samples, 0.99),
        },
        windows,
        fps_sustainable: 1e3 / (median + stage("triangulate") + stage("display copy")),
    })
}

fn write_report(
    out: &mut impl Write,
    r: &BenchReport,
    gpu: &Result<GpuFigures>,
) -> std::io::Result<()> {
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
    match gpu {
        Ok(g) => {
            writeln!(
                out,
                "GPU ({}): decode {:.2} ms median, {:.2} ms p99 over {} windows (upload, six stages, read-back)",
                g.adapter, g.decode.median_ms, g.decode.p99_ms, g.windows
            )?;
            writeln!(
                out,
                "GPU: {:.1} frames/s sustainable with triangulation and display copy on the CPU",
                g.fps_sustainable
            )?;
        }
        Err(e) => writeln!(out, "GPU: not measured: {e:#}")?,
    }
    writeln!(
        out,
        "decode_ms_median={:.3} triangulate_ms_median={:.3} fps_sustainable={:.2}",
        r.decode_ms_median, r.triangulate_ms_median, r.fps_sustainable
    )
}
