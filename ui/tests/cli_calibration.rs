//! End to end through the binary: simulate calibration sessions, calibrate colour and geometry
//! from them, and check the file written against the virtual rig; then the failure paths.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{s, scratch, tremorscan};

use std::path::Path;
use tremorscan::calibrate::{CalibrationFile, ColourFile};
use tremorscan::rig::RigConfig;

fn views(dir: &Path, n: usize) -> Vec<String> {
    (0..n)
        .map(|k| {
            dir.join(format!("view-{k:02}"))
                .to_str()
                .unwrap()
                .to_string()
        })
        .collect()
}

#[test]
fn simulate_then_calibrate_colour_and_geometry() {
    let dir = scratch("e2e");
    let out = tremorscan(&[
        "simulate-calibration",
        "--out",
        s(&dir),
        "--width",
        "640",
        "--height",
        "400",
        "--views",
        "6",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let color = dir.join("color.json");
    let out = tremorscan(&[
        "calibrate-color",
        s(&dir.join("colour")),
        "--out",
        s(&color),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("verdict: GOOD"));
    let (_, cross_talk) = ColourFile::load(&color).unwrap();
    let truth = RigConfig::paper(640, 400).unwrap();
    // The colour target's gain makes one projector level worth A gray levels at the centre;
    // measured within 0.003 of the rig's A at the default noise.
    assert!((cross_talk.a - truth.cross_talk.a).abs().max() < 0.01);

    let calib = dir.join("calib.json");
    let mut args = vec!["calibrate-geometric".to_string()];
    args.extend(views(&dir, 6));
    for a in [
        "--board",
        "9x6",
        "--square-mm",
        "20",
        "--color",
        s(&color),
        "--out",
        s(&calib),
    ] {
        args.push(a.to_string());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = tremorscan(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("verdict: GOOD"), "{stdout}");
    let (file, found) = CalibrationFile::load(&calib).unwrap();
    // Six views at 640×400 (fewer than the library test's twelve at 960×600): measured focal
    // errors 0.01–0.07 %, baseline 0.14 mm.
    for (f, t) in [
        (found.camera.intrinsics, truth.camera.intrinsics),
        (found.projector.intrinsics, truth.projector.intrinsics),
    ] {
        assert!((f.fx / t.fx - 1.0).abs() < 0.005 && (f.fy / t.fy - 1.0).abs() < 0.005);
    }
    let baseline = |p: &tremorscan::geometry::Pose| p.inverse().translation_mm.norm();
    assert!(
        (baseline(&found.projector_from_camera) - baseline(&truth.projector_from_camera)).abs()
            < 0.5
    );
    let rms = file.rms.unwrap();
    assert!(rms.camera_px < 0.3 && rms.projector_px < 0.3);
    assert_eq!(rms.views.len(), 6);
    assert_eq!(found.cross_talk, Some(cross_talk));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn failures_exit_non_zero_with_one_line() {
    let dir = scratch("fail");
    let out = tremorscan(&[
        "simulate-calibration",
        "--out",
        s(&dir),
        "--width",
        "320",
        "--height",
        "200",
        "--views",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Two views are not enough.
    let mut args = vec!["calibrate-geometric".to_string()];
    args.extend(views(&dir, 2));
    for a in [
        "--board",
        "9x6",
        "--square-mm",
        "20",
        "--out",
        s(&dir.join("c.json")),
    ] {
        args.push(a.to_string());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = tremorscan(&args);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(!dir.join("c.json").exists(), "no file written on failure");
    // A folder that is no session.
    let out = tremorscan(&["calibrate-color", s(&dir), "--out", s(&dir.join("x.json"))]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("session.json"), "{stderr}");
    // A bad board argument.
    let out = tremorscan(&[
        "calibrate-geometric",
        s(&dir.join("view-00")),
        "--board",
        "nine",
        "--square-mm",
        "20",
        "--out",
        s(&dir.join("y.json")),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("COLSxROWS"));
    let _ = std::fs::remove_dir_all(&dir);
}
