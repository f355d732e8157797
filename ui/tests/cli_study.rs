//! A study end to end: `batch` over simulated sessions (two of them corrupt), resumed, sharded
//! and merged; its Motion-BIDS dataset checked by the official validator and its C3D files read
//! back by ezc3d; and the single-session exports.
//!
//! The validator (`bids-validator-deno`, PyPI) and ezc3d (PyPI) are independent tools that CI
//! installs (`.ci/run`). Without them, here, those checks say so and are skipped, except under
//! `CI=true`, where a missing tool fails the test.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{s, tremorscan};
use std::path::Path;
use std::process::Command;
use tremorscan::rig::{RigConfig, Scene};
use tremorscan::study::{read_table, StudyRow};

/// The index fingertip's pixel at rest on the 640×400 rig, as `U,V`.
fn fingertip() -> String {
    let config = RigConfig::paper(640, 400).unwrap();
    let tip = Scene::new(config.scene.clone()).at(0.0).points[0];
    let (u, v) = config.camera.project(&tip).unwrap();
    format!("{u:.1},{v:.1}")
}

fn ok(args: &[&str]) -> String {
    let out = tremorscan(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

/// Whether an external tool can be used; under CI it must be.
fn tool_available(name: &str, probe: &mut Command) -> bool {
    let there = probe.output().is_ok_and(|o| o.status.success());
    if !there {
        assert!(
            std::env::var("CI").is_err(),
            "{name} is missing, and CI installs it (.ci/run)"
        );
        eprintln!("{name} is not installed here: that check is skipped");
    }
    there
}

/// The study: three sessions from two subjects with saved control points, one without control
/// points, one whose session.json is not JSON and one with a damaged frame.
fn make_study(study: &Path) {
    let tip = fingertip();
    let sessions: [(&str, &str, &str, &str, &str); 4] = [
        ("P-001/rest-right", "P-001", "right", "rest", "5"),
        ("P-001/rest-left", "P-001", "left", "rest", "2"),
        ("P-002/posture", "P-002", "right", "posture, arms out", "8"),
        ("P-002/no-points", "P-002", "right", "rest", "2"),
    ];
    for (k, (dir, subject, hand, condition, amplitude)) in sessions.iter().enumerate() {
        let out = study.join(dir);
        let seed = (k + 1).to_string();
        let tip_point = format!("index tip={tip}");
        let mut args = vec![
            "simulate",
            "--out",
            s(&out),
            "--frames",
            "182",
            "--amplitude-mm",
            amplitude,
            "--seed",
            &seed,
            "--subject",
            subject,
            "--hand",
            hand,
            "--condition",
            condition,
        ];
        if *dir != "P-002/no-points" {
            args.extend([
                "--control-point",
                &tip_point,
                "--control-point",
                "wrist=450,190",
            ]);
        }
        ok(&args);
    }
    // A projector glitch: ten dark frames, so the windows over them have no code and the
    // points no position there (missing samples, to be written as missing).
    for k in 60..70 {
        let dark =
            tremorscan::frame::Frame::from_data(640, 400, 3, vec![8; 640 * 400 * 3]).unwrap();
        let file = study.join(format!("P-001/rest-right/frames/{k:06}.png"));
        tremorscan::session::frames::write_png(&file, &dark).unwrap();
    }
    // A session.json that is not JSON.
    let bad = study.join("P-003/broken-manifest");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("session.json"), "{ \"format\": ").unwrap();
    // A session whose frame 100 is a truncated PNG.
    let damaged = study.join("P-003/damaged-frame");
    ok(&[
        "simulate",
        "--out",
        s(&damaged),
        "--frames",
        "182",
        "--subject",
        "P-003",
        "--hand",
        "left",
        "--condition",
        "rest",
        "--control-point",
        &format!("tip={tip}"),
    ]);
    let frame = damaged.join("frames/000100.png");
    let bytes = std::fs::read(&frame).unwrap();
    std::fs::write(&frame, &bytes[..bytes.len() / 3]).unwrap();
}

fn rows_of(table: &Path) -> Vec<StudyRow> {
    read_table(table).unwrap()
}

#[test]
fn a_study_is_batched_resumed_sharded_and_exported() {
    let dir = common::scratch("study");
    let study = dir.join("study");
    make_study(&study);
    let results = dir.join("results");
    let bids = dir.join("bids");

    // First run: every session analysed, the two corrupt ones (and the one without control
    // points) reported, the command fails at the end and says how many.
    let first = tremorscan(&["batch", s(&study), "--out", s(&results), "--bids", s(&bids)]);
    let stderr = String::from_utf8_lossy(&first.stderr);
    assert!(!first.status.success());
    assert!(stderr.contains("3 of 6 sessions failed"), "{stderr}");
    let table = results.join("study.csv");
    let rows = rows_of(&table);
    let by_session =
        |name: &str| -> Vec<&StudyRow> { rows.iter().filter(|r| r.session == name).collect() };
    assert_eq!(
        rows.len(),
        3 * 2 + 3,
        "two points in three sessions, one row per failure"
    );
    for name in ["P-001/rest-right", "P-001/rest-left", "P-002/posture"] {
        let r = by_session(name);
        assert_eq!(r.len(), 2, "{name}");
        let tip = r[0];
        assert_eq!(tip.point, "index tip");
        assert!(tip.error.is_empty(), "{name}: {}", tip.error);
        let f = tip.peak_frequency_hz.unwrap();
        assert!((f - 5.3).abs() < 0.2, "{name}: peak {f} Hz");
        assert!(tip.valid_fraction.unwrap() > 0.9);
        assert!(tip.amplitude_peak_to_peak_mm.unwrap() > 1.0);
        assert_eq!(
            tip.software_version,
            format!("tremorscan {}", env!("CARGO_PKG_VERSION"))
        );
        assert!(tip.date.starts_with("20"), "{}", tip.date);
        let out = results.join("sessions").join(name);
        for file in ["analysis.json", "report.png", "trial.c3d", "rows.csv"] {
            assert!(out.join(file).is_file(), "{name}: {file}");
        }
    }
    let posture = by_session("P-002/posture")[0];
    assert_eq!(
        (posture.subject.as_str(), posture.hand.as_str()),
        ("P-002", "right")
    );
    assert_eq!(posture.condition, "posture, arms out");
    for (name, why) in [
        ("P-002/no-points", "no control points"),
        ("P-003/broken-manifest", "session.json"),
        ("P-003/damaged-frame", "000100.png"),
    ] {
        let r = by_session(name);
        assert_eq!(r.len(), 1, "{name}");
        assert!(r[0].error.contains(why), "{name}: {}", r[0].error);
        assert!(r[0].peak_frequency_hz.is_none() && r[0].amplitude_rms_mm.is_none());
        assert!(stderr.contains(name), "{stderr}");
    }
    // No temporary file is left anywhere.
    let leftovers = walk(&dir)
        .into_iter()
        .filter(|p| s(p).contains(".tmp"))
        .count();
    assert_eq!(leftovers, 0);

    // Second run: every session is up to date and skipped, and the table is the same.
    let first_table = std::fs::read_to_string(&table).unwrap();
    let second = tremorscan(&["batch", s(&study), "--out", s(&results), "--bids", s(&bids)]);
    let stdout = String::from_utf8_lossy(&second.stdout);
    assert!(stdout.contains("0 processed, 6 up to date"), "{stdout}");
    assert_eq!(std::fs::read_to_string(&table).unwrap(), first_table);
    // A session whose input changed is processed again.
    let manifest = study.join("P-001/rest-left/session.json");
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(&manifest, std::fs::read(&manifest).unwrap()).unwrap();
    let third = tremorscan(&["batch", s(&study), "--out", s(&results), "--bids", s(&bids)]);
    assert!(
        String::from_utf8_lossy(&third.stdout).contains("1 processed, 5 up to date"),
        "{}",
        String::from_utf8_lossy(&third.stdout)
    );

    // Shards as separate processes, merged: the same table as the single run.
    let sharded = dir.join("sharded");
    let merge = tremorscan(&["batch", "--merge", s(&sharded)]);
    assert!(!merge.status.success(), "nothing to merge yet");
    for shard in ["0/3", "1/3", "2/3"] {
        let out = tremorscan(&["batch", s(&study), "--out", s(&sharded), "--shard", shard]);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("(shard "), "{text}");
        if shard == "1/3" {
            let early = tremorscan(&["batch", "--merge", s(&sharded)]);
            let why = String::from_utf8_lossy(&early.stderr);
            assert!(!early.status.success() && why.contains("2/3"), "{why}");
        }
    }
    ok(&["batch", "--merge", s(&sharded)]);
    assert_eq!(
        std::fs::read_to_string(sharded.join("study.csv")).unwrap(),
        first_table
    );

    check_bids(&bids);
    check_c3d(&results, &bids);

    // The single-session exports.
    let session = study.join("P-001/rest-right");
    let c3d = dir.join("one.c3d");
    ok(&["export-c3d", s(&session), "--out", s(&c3d)]);
    assert_eq!(
        std::fs::read(&c3d).unwrap(),
        std::fs::read(results.join("sessions/P-001/rest-right/trial.c3d")).unwrap(),
        "export-c3d writes what batch writes"
    );
    let one_bids = dir.join("one-bids");
    ok(&["export-bids", s(&session), "--bids-root", s(&one_bids)]);
    ok(&["export-bids", s(&session), "--bids-root", s(&one_bids)]);
    let motion_dir = one_bids.join("sub-P001/motion");
    for run in [1, 2] {
        let f = format!("sub-P001_task-rest_tracksys-cps_acq-right_run-{run}_motion.tsv");
        assert!(motion_dir.join(f).is_file(), "run {run}");
    }
    let refused = tremorscan(&[
        "export-c3d",
        s(&study.join("P-002/no-points")),
        "--out",
        s(&c3d),
    ]);
    assert!(String::from_utf8_lossy(&refused.stderr).contains("no control points"));

    // A window sequence: one PLY and one depth TIFF per window from 50 to 53.
    let clouds = dir.join("clouds");
    let depths = dir.join("depths");
    ok(&[
        "export",
        s(&session),
        "--clouds",
        s(&clouds),
        "--depth-tiffs",
        s(&depths),
        "--from",
        "50",
        "--to",
        "53",
    ]);
    for f in 50..=53 {
        let ply = std::fs::read(clouds.join(format!("cloud-{f:06}.ply"))).unwrap();
        assert!(
            ply.starts_with(b"ply\n") && ply.len() > 100_000,
            "window {f}"
        );
        let (w, h, depth) =
            tremorscan::export::read_depth_tiff(&depths.join(format!("depth-{f:06}.tiff")))
                .unwrap();
        assert_eq!((w, h), (640, 400));
        let valid = depth.iter().filter(|d| d.is_finite()).count();
        assert!(valid > w * h / 2, "window {f}: {valid} valid");
    }
    assert_eq!(std::fs::read_dir(&clouds).unwrap().count(), 4);
    let bad = tremorscan(&["export", s(&session), "--clouds", s(&clouds), "--from", "1"]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--from 1"));
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut all = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            all.extend(walk(&p));
        } else {
            all.push(p);
        }
    }
    all
}

/// The official validator finds no error in the dataset.
fn check_bids(bids: &Path) {
    for f in ["dataset_description.json", "participants.tsv"] {
        assert!(bids.join(f).is_file(), "{f}");
    }
    let participants = std::fs::read_to_string(bids.join("participants.tsv")).unwrap();
    assert_eq!(participants, "participant_id\nsub-P001\nsub-P002\n");
    if !tool_available(
        "bids-validator-deno",
        Command::new("bids-validator-deno").arg("--version"),
    ) {
        return;
    }
    let out = Command::new("bids-validator-deno")
        .args(["--format", "json", "--max-rows", "-1", s(bids)])
        .output()
        .unwrap();
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "validator output is not JSON ({e}): {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let issues = report["issues"]["issues"].as_array().unwrap();
    let errors: Vec<&serde_json::Value> =
        issues.iter().filter(|i| i["severity"] == "error").collect();
    assert!(errors.is_empty(), "BIDS validator errors: {errors:#?}");
    let summary = &report["summary"];
    assert_eq!(
        summary["subjects"].as_array().unwrap().len(),
        2,
        "{summary}"
    );
}

/// ezc3d reads every sample of the C3D files back, equal to the BIDS motion files' samples.
fn check_c3d(results: &Path, bids: &Path) {
    if !tool_available(
        "python3 with ezc3d",
        Command::new("python3").args(["-c", "import ezc3d"]),
    ) {
        return;
    }
    let script = r#"
import sys, math, ezc3d
c3d_path, tsv_path = sys.argv[1], sys.argv[2]
c = ezc3d.c3d(c3d_path)
points = c["data"]["points"]
rows = [line.split("\t") for line in open(tsv_path).read().splitlines()]
assert c["parameters"]["POINT"]["UNITS"]["value"] == ["mm"], c["parameters"]["POINT"]["UNITS"]
assert points.shape[2] == len(rows), (points.shape, len(rows))
assert 3 * points.shape[1] == len(rows[0]), (points.shape, len(rows[0]))
missing = 0
for k, row in enumerate(rows):
    for m in range(points.shape[1]):
        for a in range(3):
            cell, value = row[3 * m + a], points[a, m, k]
            if cell == "n/a":
                assert math.isnan(value), (k, m, a, value)
                missing += 1
            else:
                assert abs(float(cell) - value) < 1e-3, (k, m, a, cell, value)
print(len(rows), points.shape[1], missing)
"#;
    for (session, stem) in [
        (
            "P-001/rest-right",
            "sub-P001/motion/sub-P001_task-rest_tracksys-cps_acq-right_run-1",
        ),
        (
            "P-002/posture",
            "sub-P002/motion/sub-P002_task-posturearmsout_tracksys-cps_acq-right_run-1",
        ),
    ] {
        let c3d = results.join("sessions").join(session).join("trial.c3d");
        let tsv = bids.join(format!("{stem}_motion.tsv"));
        let out = Command::new("python3")
            .args(["-c", script, s(&c3d), s(&tsv)])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{session}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let counts = String::from_utf8_lossy(&out.stdout);
        let counts: Vec<usize> = counts
            .split_whitespace()
            .map(|c| c.parse().unwrap())
            .collect();
        assert_eq!(&counts[..2], [180, 2], "{session}");
        if session == "P-001/rest-right" {
            // The dark frames' windows: both points missing in each.
            assert!(counts[2] >= 2 * 3 * 10, "{session}: {counts:?}");
        }
    }
}
