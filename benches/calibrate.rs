//! Calibration benchmarks: finding the chessboard in one view (960×600 and 1920×1200), observing
//! a whole capture (decoding both axes and the local fits), and the joint refinement of twelve
//! views. Calibration is not real-time; these tell how long an operator waits.
//!
//! `cargo bench -p tremorscan --bench calibrate`. Figures go to `docs/benchmarks.md`.
#![allow(clippy::unwrap_used, reason = "benchmark setup")]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::time::Duration;
use tremorscan::calibrate::{
    calibrate_geometric, find_board_corners, gray_of, observe_capture, BoardSpec, GeometricOptions,
    LocalFitOptions,
};
use tremorscan::rig::captures::{render_capture, standard_poses};
use tremorscan::rig::RigConfig;

const BOARD: BoardSpec = BoardSpec {
    cols: 9,
    rows: 6,
    square_mm: 20.0,
};

fn bench_views(c: &mut Criterion) {
    let mut group = c.benchmark_group("calibration_view");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(6));
    for (w, h) in [(960, 600), (1920, 1200)] {
        let config = RigConfig::paper(w, h).unwrap();
        let (capture, _) = render_capture(&config, standard_poses()[1], 1).unwrap();
        let gray = gray_of(&capture.ambient);
        group.bench_function(BenchmarkId::new("find_corners", format!("{w}x{h}")), |b| {
            b.iter(|| find_board_corners(&gray, w, h, &BOARD, 0).unwrap())
        });
        group.bench_function(
            BenchmarkId::new("observe_capture", format!("{w}x{h}")),
            |b| {
                b.iter(|| {
                    observe_capture(
                        0,
                        &capture,
                        &BOARD,
                        config.cross_talk,
                        &LocalFitOptions::default(),
                    )
                    .unwrap()
                })
            },
        );
    }
    group.finish();
}

fn bench_refine(c: &mut Criterion) {
    let config = RigConfig::paper(960, 600).unwrap();
    let observations: Vec<_> = standard_poses()
        .into_iter()
        .enumerate()
        .map(|(k, board)| {
            let (capture, _) = render_capture(&config, board, k as u64).unwrap();
            observe_capture(
                k,
                &capture,
                &BOARD,
                config.cross_talk,
                &LocalFitOptions::default(),
            )
            .unwrap()
        })
        .collect();
    let mut group = c.benchmark_group("calibration_solve");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(6));
    group.bench_function("zhang_and_lm_12_views", |b| {
        b.iter(|| {
            calibrate_geometric(
                &BOARD,
                &observations,
                (960, 600),
                (912, 1140),
                &GeometricOptions::default(),
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_views, bench_refine);
criterion_main!(benches);
