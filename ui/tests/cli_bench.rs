//! `tremorscan bench`: the table, the verdict, the binned sizes measured when the PC does not
//! keep up, and the machine-readable last line.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::tremorscan;

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn bench_prints_stages_and_a_parsable_last_line() {
    let out = tremorscan(&[
        "bench",
        "--width",
        "160",
        "--height",
        "100",
        "--seconds",
        "0.3",
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    for stage in [
        "solve (phasors)",
        "smooth (unit phasor)",
        "triangulate",
        "display hand-off",
    ] {
        assert!(stdout.contains(stage), "{stage} missing:\n{stdout}");
    }
    assert!(stdout.contains("frames/s sustainable"), "{stdout}");
    // Resident memory over the measured windows, for each path (Linux reports it).
    if cfg!(target_os = "linux") {
        for path in ["CPU", "GPU"] {
            let line = stdout
                .lines()
                .find(|l| l.starts_with(&format!("{path}: resident memory ")))
                .unwrap_or_else(|| panic!("no {path} memory line:\n{stdout}"));
            let megabytes: Vec<f64> = line
                .split_whitespace()
                .filter_map(|word| word.trim_matches(['(', ')', ';']).parse().ok())
                .collect();
            // After the warm-up, at the end, the growth, the windows, the peak.
            assert_eq!(megabytes.len(), 5, "{line}");
            let (start, end, growth, peak) =
                (megabytes[0], megabytes[1], megabytes[2], megabytes[4]);
            // The kernel's counters are approximate by some pages (see tests/resident_memory.rs).
            assert!(start > 1.0 && end > 1.0 && peak + 1.0 >= end, "{line}");
            assert!((end - start - growth).abs() < 0.11, "{line}");
        }
    }
    // Where the memory goes: what each stage holds, by holder.
    let held = stdout
        .lines()
        .find(|l| l.starts_with("CPU: held by the stages: decoder "))
        .unwrap_or_else(|| panic!("no line of what the stages hold:\n{stdout}"));
    for holder in ["triangulator's tables", "point cloud", "the test frames"] {
        assert!(held.contains(holder), "{holder} missing: {held}");
    }
    // The header names the instruction set the CPU kernels dispatched to.
    let kernels = tremorscan::decode::backend::kernel_instruction_set();
    assert!(
        stdout.contains(&format!("on the CPU ({kernels}, ")),
        "{stdout}"
    );
    // The CI machine has lavapipe: the GPU path runs there too.
    assert!(
        stdout.contains("GPU: ") && stdout.contains("decode thread"),
        "{stdout}"
    );
    // The GPU runs the motion model too, and its cost there is stated against its still window.
    assert!(
        stdout.contains("GPU, still window (no motion model)")
            && stdout.contains("the motion model costs"),
        "{stdout}"
    );
    // The GPU's own clock, or a plain statement that the adapter has none.
    assert!(
        stdout.contains("compute by the GPU's clock")
            || stdout.contains("no compute time by the GPU's clock"),
        "{stdout}"
    );
    let last = stdout.lines().last().unwrap();
    let values: Vec<(&str, f64)> = last
        .split_whitespace()
        .map(|kv| {
            let (k, v) = kv.split_once('=').unwrap();
            (k, v.parse().unwrap())
        })
        .collect();
    let keys: Vec<&str> = values.iter().map(|(k, _)| *k).collect();
    assert_eq!(
        keys,
        [
            "decode_ms_median",
            "triangulate_ms_median",
            "fps_sustainable"
        ]
    );
    let (decode, triangulate, fps) = (values[0].1, values[1].1, values[2].1);
    assert!(decode > 0.0 && triangulate > 0.0, "{last}");
    // The decode thread does at least decode and triangulation per window, so its median time
    // is at least each of their medians (a quantile of a pointwise larger series is larger; the
    // median of the sums need not exceed the sum of the medians).
    assert!(
        fps > 0.0 && fps <= 1e3 / decode.max(triangulate) * 1.001,
        "{last}"
    );
}

/// The frame rates of the binning lines: `(bin, width, height, fps, keeps up)`.
fn binning_lines(stdout: &str) -> Vec<(usize, usize, usize, f64, bool)> {
    stdout
        .lines()
        .filter_map(|l| l.strip_prefix("CPU with "))
        .map(|l| {
            // "2×2 binning (128×100): 4782.8 frames/s sustainable over 1248 windows; keeps up"
            let (bin, rest) = l.split_once('×').unwrap();
            let (size, rest) = rest.split_once("): ").unwrap();
            let (width, height) = size.split_once('(').unwrap().1.split_once('×').unwrap();
            let fps = rest.split_whitespace().next().unwrap().parse().unwrap();
            let verdict = rest.rsplit_once("; ").unwrap().1;
            (
                bin.parse().unwrap(),
                width.parse().unwrap(),
                height.parse().unwrap(),
                fps,
                verdict == "keeps up",
            )
        })
        .collect()
}

#[test]
fn bench_measures_binned_sizes_when_the_pc_does_not_keep_up() {
    // No PC decodes a million windows a second: every binning down to 64×64 is measured, in
    // order, and the check says that none keeps up.
    let out = tremorscan(&[
        "bench",
        "--width",
        "256",
        "--height",
        "200",
        "--seconds",
        "0.2",
        "--fps",
        "1000000",
        "--no-gpu",
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert!(
        stdout.contains("does NOT keep up with a 1000000 FPS camera at this size"),
        "{stdout}"
    );
    let lines = binning_lines(&stdout);
    // 4×4 would be 64×50, under the smallest size the check takes.
    let sizes: Vec<(usize, usize, usize)> = lines.iter().map(|l| (l.0, l.1, l.2)).collect();
    assert_eq!(sizes, [(2, 128, 100), (3, 85, 66)], "{stdout}");
    assert!(lines.iter().all(|l| l.3 > 0.0 && !l.4), "{stdout}");
    assert!(
        stdout.contains("CPU: no binning up to 3×3 keeps up with a 1000000 FPS camera"),
        "{stdout}"
    );
    assert!(
        stdout
            .lines()
            .last()
            .unwrap()
            .starts_with("decode_ms_median="),
        "{stdout}"
    );

    // A rate any PC sustains: the verdict says so and no binned size is measured.
    let out = tremorscan(&[
        "bench",
        "--width",
        "160",
        "--height",
        "100",
        "--seconds",
        "0.2",
        "--fps",
        "1",
        "--no-gpu",
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert!(
        stdout.contains("keeps up with a 1 FPS camera at this size"),
        "{stdout}"
    );
    assert!(binning_lines(&stdout).is_empty(), "{stdout}");
    assert!(!stdout.contains("no binning"), "{stdout}");
}

#[test]
fn bench_refuses_a_tiny_image_and_a_bad_duration() {
    let out = tremorscan(&[
        "bench",
        "--width",
        "10",
        "--height",
        "10",
        "--seconds",
        "0.1",
    ]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("too small"),
        "{}",
        text(&out.stderr)
    );
    let out = tremorscan(&["bench", "--seconds=-1"]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("--seconds"),
        "{}",
        text(&out.stderr)
    );
    for fps in ["0", "-5", "NaN"] {
        let out = tremorscan(&["bench", &format!("--fps={fps}")]);
        assert!(!out.status.success(), "--fps {fps}");
        assert!(
            text(&out.stderr).contains("is not a frame rate"),
            "{}",
            text(&out.stderr)
        );
    }
}
