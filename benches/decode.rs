//! Decode, triangulation and virtual-rig benchmarks at 640×400 and the paper's 1920×1200.
//!
//! `cargo bench -p tremorscan --bench decode`. Figures go to `docs/benchmarks.md`.
#![allow(clippy::unwrap_used, reason = "benchmark setup")]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::time::Duration;
use tremorscan::decode::{
    decode_window, DecodeOutput, DecodeParams, MotionParams, UnwrapMethod, WindowSolver,
};
use tremorscan::frame::Frame;
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan::triangulate::{PointCloud, Triangulator};

const SIZES: [(usize, usize); 2] = [(640, 400), (1920, 1200)];

fn rig(width: usize, height: usize) -> VirtualRig {
    let config = RigConfig::paper(width, height).unwrap();
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

/// The rig's frames 0, 1, 2: one window.
fn first_window(rig: &VirtualRig) -> Vec<Frame> {
    (0..3)
        .map(|i| {
            let mut f = rig.blank_frame();
            rig.render(i, &mut f, None).unwrap();
            f
        })
        .collect()
}

fn bench_decode(c: &mut Criterion) {
    let mut group = c.benchmark_group("decode_cps_rgb_window");
    group
        .sample_size(30)
        .measurement_time(Duration::from_secs(8));
    for (w, h) in SIZES {
        let rig = rig(w, h);
        let frames = first_window(&rig);
        let refs: Vec<&Frame> = frames.iter().collect();
        let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
        let mut out = DecodeOutput::new(w, h, &solver);
        // The robust decode with its motion model (the default), the same without it (the
        // paper's still window: the motion model's cost is the difference), and per pixel.
        for (name, method, motion) in [
            (
                "robust",
                UnwrapMethod::ChebyshevRobust,
                MotionParams::default(),
            ),
            (
                "robust_still",
                UnwrapMethod::ChebyshevRobust,
                MotionParams::off(),
            ),
            (
                "per_pixel",
                UnwrapMethod::ChebyshevPerPixel,
                MotionParams::default(),
            ),
        ] {
            let params = DecodeParams {
                unwrap: method,
                motion,
                ..DecodeParams::default()
            };
            group.bench_with_input(BenchmarkId::new(name, format!("{w}x{h}")), &(), |b, ()| {
                b.iter(|| decode_window(&solver, &refs, &params, Some(65), &mut out).unwrap());
            });
        }
    }
    group.finish();
}

/// The fast decoder against the straightforward per-pixel 9×9 solve (`decode::reference`), the
/// comparison table of `docs/benchmarks.md`. The equality of their results is tested in
/// `tests/decode_reference.rs`.
fn bench_reference(c: &mut Criterion) {
    use tremorscan::decode::reference::decode_window_reference;
    let mut group = c.benchmark_group("fast_vs_reference");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    for (w, h) in SIZES {
        let rig = rig(w, h);
        let frames = first_window(&rig);
        let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
        let mut out = DecodeOutput::new(w, h, &solver);
        let params = DecodeParams::default();
        let size = format!("{w}x{h}");
        group.bench_with_input(BenchmarkId::new("fast", &size), &(), |b, ()| {
            b.iter(|| decode_window(&solver, &frames, &params, Some(65), &mut out).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("reference", &size), &(), |b, ()| {
            b.iter(|| {
                decode_window_reference(&solver, &frames, &params, Some(65), &mut out).unwrap()
            });
        });
        // Stage 1 alone: the part the reference does differently.
        let mut last = (0.0, 0.0);
        for _ in 0..3 {
            decode_window(&solver, &frames, &params, Some(65), &mut out).unwrap();
            let fast = out.timings.solve_ms;
            decode_window_reference(&solver, &frames, &params, Some(65), &mut out).unwrap();
            last = (fast, out.timings.solve_ms);
        }
        println!(
            "fast_vs_reference/{size}: solve stage {:.2} ms (fast) vs {:.1} ms (reference)",
            last.0, last.1
        );
    }
    group.finish();
}

fn bench_rig(c: &mut Criterion) {
    let mut group = c.benchmark_group("virtual_rig_render");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    for (w, h) in SIZES {
        // The rig's default camera (with the lens's blur), and without the blur: its cost.
        for (name, psf_sigma_px) in [("lens_blur", None), ("no_blur", Some(0.0))] {
            let mut config = RigConfig::paper(w, h).unwrap();
            if let Some(sigma) = psf_sigma_px {
                config.camera_psf_sigma_px = sigma;
            }
            let seq = config.default_sequence().unwrap();
            let rig = VirtualRig::new(config, seq).unwrap();
            let mut frame = rig.blank_frame();
            let mut index = 0u64;
            group.bench_function(BenchmarkId::new(name, format!("{w}x{h}")), |b| {
                b.iter(|| {
                    index += 1;
                    rig.render(index, &mut frame, None).unwrap();
                });
            });
        }
    }
    group.finish();
}

/// Stage 5 alone, the mixed pixels at depth edges (`decode::edges`), on the decoded first
/// window: each iteration marks a fresh copy of the output.
fn bench_mixed_pixels(c: &mut Criterion) {
    let mut group = c.benchmark_group("mixed_pixel_stage");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(6));
    for (w, h) in SIZES {
        let rig = rig(w, h);
        let frames = first_window(&rig);
        let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
        let mut decoded = DecodeOutput::new(w, h, &solver);
        let unmarked = DecodeParams {
            mixed_limit_px: 0.0,
            ..DecodeParams::default()
        };
        decode_window(&solver, &frames, &unmarked, Some(65), &mut decoded).unwrap();
        let params = DecodeParams::default();
        group.bench_function(BenchmarkId::from_parameter(format!("{w}x{h}")), |b| {
            b.iter_batched_ref(
                || decoded.clone(),
                |out| tremorscan::decode::edges::flag_mixed_pixels(&solver, &params, out),
                criterion::BatchSize::LargeInput,
            );
        });
    }
    group.finish();
}

fn bench_triangulate(c: &mut Criterion) {
    let mut group = c.benchmark_group("triangulate");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(6));
    for (w, h) in SIZES {
        let rig = rig(w, h);
        let mut decoder = tremorscan::decode::SlidingDecoder::new(
            rig.sequence.clone(),
            rig.config.cross_talk,
            DecodeParams::default(),
        )
        .unwrap();
        let mut frame = rig.blank_frame();
        for i in 0..3 {
            rig.render(i, &mut frame, None).unwrap();
            decoder.push(&frame).unwrap();
        }
        let decoded = decoder.output().unwrap();
        let triangulator = Triangulator::new(rig.stereo_model()).unwrap();
        let mut cloud = PointCloud::default();
        group.bench_function(BenchmarkId::from_parameter(format!("{w}x{h}")), |b| {
            b.iter(|| triangulator.triangulate(decoded, &mut cloud).unwrap());
        });
    }
    group.finish();
}

/// Bayer demosaicing of a 1920×1200 frame (the capture thread's cost with a Bayer camera).
fn bench_demosaic(c: &mut Criterion) {
    use tremorscan::device::bayer::{demosaic_bilinear, demosaic_reference, BayerPattern};
    let mut group = c.benchmark_group("demosaic_1920x1200");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(6));
    let (w, h) = (1920, 1200);
    let raw: Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
    let mut rgb = Vec::new();
    group.bench_function("fast", |b| {
        b.iter(|| demosaic_bilinear(&raw, w, h, BayerPattern::Bg, &mut rgb).unwrap());
    });
    group.bench_function("reference", |b| {
        b.iter(|| demosaic_reference(&raw, w, h, BayerPattern::Bg, &mut rgb).unwrap());
    });
    group.finish();
}

criterion_group!(reference_comparison, bench_reference);
criterion_group!(
    benches,
    bench_decode,
    bench_triangulate,
    bench_rig,
    bench_mixed_pixels,
    bench_demosaic
);
criterion_main!(benches, reference_comparison);
