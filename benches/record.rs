//! Sustained write rate of live recording: frames of the virtual rig (noise included) written
//! through `session::Recorder` to a file in the system's temporary folder, then synced. Prints a
//! table; figures go to `docs/benchmarks.md`.
//!
//! `cargo bench -p tremorscan --bench record [-- SECONDS]` (default 3 s of frames per size).
#![allow(clippy::unwrap_used, reason = "benchmark setup")]

use std::time::Instant;
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan::session::{Manifest, Recorder, TrialJson};

fn manifest(rig: &VirtualRig) -> Manifest {
    rig.session_manifest()
}

fn main() {
    let seconds: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(3.0);
    println!("| size | frames | MB written | ratio | wall s (incl. sync) | frames/s | MB/s | keeps 121 FPS |");
    println!("|---|---:|---:|---:|---:|---:|---:|---|");
    for (w, h) in [(640, 400), (1920, 1200)] {
        let config = RigConfig::paper(w, h).unwrap();
        let seq = config.default_sequence().unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        // Six distinct frames (two pattern cycles), written round robin.
        let frames: Vec<_> = (0..6)
            .map(|i| {
                let mut f = rig.blank_frame();
                rig.render(i, &mut f, None).unwrap();
                f
            })
            .collect();
        let n = (seconds * 121.0).round() as usize;
        let dir = std::env::temp_dir().join(format!(
            "tremorscan-bench-record-{}-{w}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        let start = Instant::now();
        let mut recorder = Recorder::create(&dir, manifest(&rig), TrialJson::default()).unwrap();
        for i in 0..n {
            let mut f = frames[i % frames.len()].clone();
            f.time_s = i as f64 / 121.0;
            recorder.write_frame(&f).unwrap();
        }
        let summary = recorder.finish().unwrap();
        let wall = start.elapsed().as_secs_f64();
        let raw = (n * w * h * 3) as f64;
        let fps = n as f64 / wall;
        println!(
            "| {w}×{h} | {n} | {:.0} | {:.3} | {wall:.2} | {fps:.0} | {:.0} | {} |",
            summary.bytes as f64 / 1e6,
            summary.bytes as f64 / raw,
            summary.bytes as f64 / 1e6 / wall,
            if fps >= 121.0 { "yes" } else { "no" }
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
