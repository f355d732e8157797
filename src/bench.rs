//! The per-stage throughput check behind `tremorscan bench`: does this PC keep up with the camera?
//!
//! It renders a few frames of the virtual rig at the requested size once (on a thread of its
//! own, which takes the renderer's image with it when it ends; the rig is dropped: neither is
//! part of what the decode thread holds), then streams them, for the requested time, through
//! exactly the work the pipeline's decode thread does per frame: the
//! sliding-window decoder (the frame into the window, shared as the pipeline shares captured
//! frames, then solve, smoothing, unwrapping), the triangulation and the hand-off to the display
//! (the coordinates move out of the decoder without a copy), after a few warm-up windows. Each
//! stage is timed per window; the report gives median and 99th percentile and the window rate the
//! decode thread sustains (one window per camera frame), from the median of its total time, and
//! the process's resident memory after the warm-up and at the end (steady state: no growth).

use crate::color::CrossTalk;
use crate::decode::window::SharedFrame;
use crate::decode::{
    CpuBackend, DecodeBackend, DecodeError, DecodeParams, SlidingDecoder, WindowOutcome,
};
use crate::memory::ResidentMemory;
use crate::pattern::PatternSequence;
use crate::rig::{RigConfig, RigError, VirtualRig};
use crate::triangulate::{PointCloud, TriangulateError, Triangulator};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Frames rendered once and cycled: two full sequences, so windows see changing data.
const FRAMES: u64 = 6;
/// The largest image side the check accepts (a 8192×8192 window needs about 3 GB).
pub const MAX_SIDE: usize = 8192;
/// Windows decoded before timing starts: the first ones allocate and fault in the buffers.
const WARM_UP_WINDOWS: usize = 3;
/// The stage a backend with its own clock adds: its compute, transfers excluded.
pub const DEVICE_STAGE: &str = "device compute (GPU clock)";

/// Errors of the throughput check.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("image size {width}×{height} is too small; at least 64×64")]
    TooSmall { width: usize, height: usize },
    #[error("image size {width}×{height} is too large; at most {MAX_SIDE}×{MAX_SIDE}")]
    TooLarge { width: usize, height: usize },
    #[error("the run time must be positive and finite, got {0} s")]
    BadDuration(f64),
    #[error(transparent)]
    Rig(#[from] RigError),
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error(transparent)]
    Triangulate(#[from] TriangulateError),
    #[error("no window was decoded within the run time")]
    NoWindows,
    #[error("could not start the thread that renders the test frames: {0}")]
    RenderThread(std::io::Error),
    #[error("the thread that renders the test frames panicked")]
    RenderPanicked,
}

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchConfig {
    pub width: usize,
    pub height: usize,
    pub duration: Duration,
}

/// Median and 99th percentile of one stage, milliseconds.
#[derive(Debug, Clone, PartialEq)]
pub struct StageStats {
    pub name: &'static str,
    pub median_ms: f64,
    pub p99_ms: f64,
}

/// The result of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchReport {
    pub width: usize,
    pub height: usize,
    pub windows: usize,
    /// Worker threads the data-parallel stages used.
    pub threads: usize,
    /// What ran the decode.
    pub backend: String,
    /// Per stage, in pipeline order; the decode stages sum (up to timer overhead) to `decode`.
    /// A backend with its own clock adds [`DEVICE_STAGE`] last.
    pub stages: Vec<StageStats>,
    pub decode_ms_median: f64,
    pub triangulate_ms_median: f64,
    /// Windows per second the decode thread sustains: 1000 / median of its total per window.
    pub fps_sustainable: f64,
    /// Valid points of the last window.
    pub valid_points: usize,
    /// This process's resident memory after the warm-up windows and at the end of the run
    /// (steady state: they should be equal); `None` where the system does not report it.
    pub memory: Option<(ResidentMemory, ResidentMemory)>,
    /// What the stages hold on the heap at the end of the run.
    pub held: HeldMemory,
}

/// Heap bytes the stages hold, by holder: where the resident memory goes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HeldMemory {
    /// The decoder's output planes, its stages' scratch ([`crate::decode::DecodeOutput`]) and
    /// the frames it copied ([`SlidingDecoder::memory_bytes`]).
    pub decoder_bytes: usize,
    /// The triangulator's tables.
    pub triangulator_bytes: usize,
    /// The point cloud.
    pub cloud_bytes: usize,
    /// The test frames, shared with the decoder's window.
    pub frames_bytes: usize,
}

/// The `q`-quantile (0..=1) of `values` by nearest rank; `values` is sorted in place.
pub fn quantile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let rank = (q * values.len() as f64).ceil() as usize;
    values[rank.clamp(1, values.len()) - 1]
}

/// What the stages run on: the rig's pattern sequence and cross-talk, its frames (cycled,
/// shared as the pipeline shares captured frames) and the triangulator of its calibration.
pub struct BenchInputs {
    pub width: usize,
    pub height: usize,
    pub sequence: PatternSequence,
    pub cross_talk: CrossTalk,
    pub frames: Vec<SharedFrame>,
    pub triangulator: Triangulator,
}

/// Renders the test frames of the virtual rig at `width`×`height`. The rendering runs on a
/// thread of its own, so that the renderer's linear image (kept per thread, 55 MB at
/// 1920×1200) goes when the thread ends, and the rig (its rays, 28 MB) is dropped here: the
/// bench's resident memory is then the decode thread's, as with a camera.
pub fn prepare(width: usize, height: usize) -> Result<BenchInputs, BenchError> {
    if width < 64 || height < 64 {
        return Err(BenchError::TooSmall { width, height });
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(BenchError::TooLarge { width, height });
    }
    let rig_config = RigConfig::paper(width, height)?;
    let sequence = rig_config.default_sequence()?;
    let rig = VirtualRig::new(rig_config, sequence)?;
    let render = || {
        (0..FRAMES)
            .map(|i| {
                let mut frame = rig.blank_frame();
                rig.render(i, &mut frame, None)
                    .map(|()| Arc::new(frame) as SharedFrame)
            })
            .collect::<Result<Vec<SharedFrame>, RigError>>()
    };
    let frames = std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("bench-render".into())
            .spawn_scoped(scope, render)
            .map_err(BenchError::RenderThread)?
            .join()
            .map_err(|_| BenchError::RenderPanicked)?
            .map_err(BenchError::from)
    })?;
    let triangulator = Triangulator::new(rig.stereo_model())?;
    Ok(BenchInputs {
        width: rig.width(),
        height: rig.height(),
        sequence: rig.sequence,
        cross_talk: rig.config.cross_talk,
        frames,
        triangulator,
    })
}

/// Median and p99 of `samples` (sorted in place).
pub fn stage_stats(name: &'static str, samples: &mut [f64]) -> StageStats {
    StageStats {
        name,
        median_ms: quantile(samples, 0.5),
        p99_ms: quantile(samples, 0.99),
    }
}

/// Renders the frames and runs the stages for `config.duration`.
pub fn run(config: &BenchConfig) -> Result<BenchReport, BenchError> {
    let inputs = prepare(config.width, config.height)?;
    run_cpu(&inputs, config.duration)
}

/// Runs the decode thread's per-frame work on the CPU for `duration` (at least three windows).
pub fn run_cpu(inputs: &BenchInputs, duration: Duration) -> Result<BenchReport, BenchError> {
    run_with(
        inputs,
        duration,
        Box::new(CpuBackend),
        DecodeParams::default(),
    )
}

/// Runs the decode thread's per-frame work with the decode on `backend` with `params` for
/// `duration` (at
/// least three windows). A backend that does not time its stages reports the whole decode as
/// "solve (phasors)".
pub fn run_with(
    inputs: &BenchInputs,
    duration: Duration,
    backend: Box<dyn DecodeBackend>,
    params: DecodeParams,
) -> Result<BenchReport, BenchError> {
    let seconds = duration.as_secs_f64();
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(BenchError::BadDuration(seconds));
    }
    let BenchInputs {
        width,
        height,
        sequence,
        cross_talk,
        frames,
        triangulator,
    } = inputs;
    let (width, height) = (*width, *height);
    let mut decoder =
        SlidingDecoder::new(sequence.clone(), *cross_talk, params)?.with_backend(backend);
    let mut cloud = PointCloud::default();
    let mut display_coordinate: Vec<f32> = Vec::new();
    let names = [
        "frame into window",
        "solve (phasors)",
        "motion model",
        "smooth (unit phasor)",
        "unwrap + checks",
        "decode (total)",
        "triangulate",
        "display hand-off",
        "decode thread (total)",
    ];
    let mut samples: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    // The device's own compute time, from backends with a clock of their own (GPU timestamps).
    let mut device_samples: Vec<f64> = Vec::new();
    let mut index = 0usize;
    let mut warm_up = WARM_UP_WINDOWS;
    while warm_up > 0 {
        let frame = Arc::clone(&frames[index % frames.len()]);
        index += 1;
        if let WindowOutcome::Decoded(out) = decoder.push_shared(frame)? {
            triangulator.triangulate(out, &mut cloud)?;
            // The hand-off too: its first exchange leaves the decoder a buffer to allocate.
            decoder.take_coordinate(&mut display_coordinate);
            warm_up -= 1;
        }
    }
    let memory_after_warm_up = ResidentMemory::now();
    let started = Instant::now();
    let mut valid_points = 0;
    while started.elapsed() < duration || samples[0].len() < 3 {
        let frame = Arc::clone(&frames[index % frames.len()]);
        index += 1;
        let t0 = Instant::now();
        let out = match decoder.push_shared(frame)? {
            WindowOutcome::Decoded(out) => out,
            _ => continue,
        };
        let t1 = Instant::now();
        triangulator.triangulate(out, &mut cloud)?;
        let timings = out.timings;
        let t2 = Instant::now();
        // As the pipeline does: the camera frame is shared, the coordinates are moved out.
        decoder.take_coordinate(&mut display_coordinate);
        let t3 = Instant::now();
        let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
        let decode_ms = ms(t0, t1);
        device_samples.extend(timings.device_ms);
        let row = [
            decode_ms - timings.total_ms(),
            timings.solve_ms,
            timings.motion_ms,
            timings.smooth_ms,
            timings.unwrap_ms,
            decode_ms,
            ms(t1, t2),
            ms(t2, t3),
            ms(t0, t3),
        ];
        for (series, value) in samples.iter_mut().zip(row) {
            series.push(value);
        }
        valid_points = cloud.valid_count();
    }
    let memory_at_end = ResidentMemory::now();
    let held = HeldMemory {
        decoder_bytes: decoder.memory_bytes(),
        triangulator_bytes: triangulator.memory_bytes(),
        cloud_bytes: cloud.point_in_camera_mm.capacity() * std::mem::size_of::<[f32; 3]>()
            + cloud.colour_rgb.capacity() * std::mem::size_of::<[u8; 3]>()
            + cloud.fringe_amplitude.capacity() * std::mem::size_of::<f32>(),
        frames_bytes: frames
            .iter()
            .map(|frame| (**frame).borrow().data.capacity())
            .sum(),
    };
    let windows = samples[0].len();
    if windows == 0 {
        return Err(BenchError::NoWindows);
    }
    let mut stages: Vec<StageStats> = names
        .iter()
        .zip(&mut samples)
        .map(|(&name, series)| stage_stats(name, series))
        .collect();
    if !device_samples.is_empty() {
        stages.push(stage_stats(DEVICE_STAGE, &mut device_samples));
    }
    let median = |name: &str| {
        stages
            .iter()
            .find(|s| s.name == name)
            .map_or(f64::NAN, |s| s.median_ms)
    };
    let total = median("decode thread (total)");
    Ok(BenchReport {
        width,
        height,
        windows,
        threads: rayon::current_num_threads(),
        backend: decoder.backend_name(),
        decode_ms_median: median("decode (total)"),
        triangulate_ms_median: median("triangulate"),
        fps_sustainable: 1e3 / total,
        stages,
        valid_points,
        memory: memory_after_warm_up.zip(memory_at_end),
        held,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn quantiles_by_nearest_rank() {
        let mut v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(quantile(&mut v, 0.5), 50.0);
        assert_eq!(quantile(&mut v, 0.99), 99.0);
        assert_eq!(quantile(&mut v, 1.0), 100.0);
        assert_eq!(quantile(&mut [7.0], 0.99), 7.0);
        assert!(quantile(&mut [], 0.5).is_nan());
    }

    #[test]
    fn a_short_run_times_every_stage() {
        let report = run(&BenchConfig {
            width: 160,
            height: 100,
            duration: Duration::from_millis(200),
        })
        .unwrap();
        assert!(report.windows >= 3);
        // Frame in, solve, motion, smooth, unwrap, decode, triangulate, hand-off, thread total.
        assert_eq!(report.stages.len(), 9);
        for s in &report.stages {
            assert!(s.median_ms >= 0.0 && s.p99_ms >= s.median_ms, "{s:?}");
        }
        assert!(report.valid_points > 1000, "{}", report.valid_points);
        let total = report.stages[8].median_ms;
        assert_eq!(report.stages[8].name, "decode thread (total)");
        assert!((report.fps_sustainable - 1e3 / total).abs() < 1e-9);
        // Six RGB frames of 160×100; the decoder's planes are many times a frame.
        assert_eq!(report.held.frames_bytes, 6 * 160 * 100 * 3);
        assert!(report.held.decoder_bytes > 20 * 160 * 100);
        assert!(report.held.triangulator_bytes >= 8 * 160 * 100);
        assert_eq!(report.held.cloud_bytes, 19 * 160 * 100);
        let err = run(&BenchConfig {
            width: 32,
            height: 100,
            duration: Duration::from_millis(10),
        })
        .unwrap_err();
        assert!(err.to_string().contains("too small"), "{err}");
        let err = prepare(100_000, 100).err().unwrap();
        assert!(err.to_string().contains("too large"), "{err}");
    }
}
