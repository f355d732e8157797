//! `track` and `analyze` end to end on a simulated trembling hand.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use std::process::Command;
use tremorscan::rig::{RigConfig, Scene};

#[test]
fn track_and_analyze_a_simulated_tremor() {
    let dir = common::scratch("tremor");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_tremorscan"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    let d = dir.to_str().unwrap();
    run(&["simulate", "--out", d, "--frames", "242"]);
    // The index fingertip's pixel at rest.
    let config = RigConfig::paper(640, 400).unwrap();
    let tip = Scene::new(config.scene.clone()).at(0.0).points[0];
    let (u, v) = config.camera.project(&tip).unwrap();
    let point = format!("{:.1},{:.1}", u, v);
    let csv = dir.join("track.csv");
    run(&[
        "track",
        d,
        "--point",
        &point,
        "--point",
        "100,350",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "time_s,frame,point,u,v,x_mm,y_mm,z_mm,displacement_mm,valid"
    );
    assert_eq!(
        lines.len(),
        1 + 2 * 240,
        "one row per decoded window and point"
    );
    assert!(lines[1].ends_with(",1"), "{}", lines[1]);
    // The same fingertip picked as a 3D point (as clicked in the cloud) tracks the same surface.
    let tip_mm = format!("{},{},{}", tip.x, tip.y, tip.z);
    let csv3 = dir.join("track3d.csv");
    run(&[
        "track",
        d,
        "--point-mm",
        &tip_mm,
        "--csv",
        csv3.to_str().unwrap(),
    ]);
    let text3 = std::fs::read_to_string(&csv3).unwrap();
    let z = |line: &str| line.split(',').nth(7).unwrap().to_string();
    let rows3: Vec<&str> = text3.lines().skip(1).collect();
    assert_eq!(rows3.len(), 240);
    for (a, b) in rows3.iter().zip(lines.iter().skip(1)) {
        assert_eq!(z(a), z(b), "{a} vs {b}");
    }
    let json = dir.join("tremor.json");
    let stdout = run(&[
        "analyze",
        d,
        "--point",
        &point,
        "--vertical",
        "table",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(stdout.contains("MDS-UPDRS amplitude bin 1"), "{stdout}");
    let value: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let p = &value[0];
    let f = p["peak_frequency_hz"].as_f64().unwrap();
    assert!((f - 5.3).abs() < 0.05, "{f}");
    assert!(p["valid_fraction"].as_f64().unwrap() > 0.95);
    assert!(p["amplitude_peak_to_peak_mm"].as_f64().unwrap() > 3.0);
    let spectrum = &p["spectrum"];
    assert_eq!(
        spectrum["frequency_hz"].as_array().unwrap().len(),
        spectrum["psd_mm2_per_hz"].as_array().unwrap().len()
    );
    for key in [
        "band_power_3_12",
        "band_power_4_6",
        "occupancy",
        "frequency_stability",
        "updrs_amplitude_bin",
        "amplitude_rms_mm",
        "pixel",
    ] {
        assert!(!p[key].is_null(), "{key}");
    }
    // A point off the image is refused in one line.
    let out = Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .args([
            "analyze",
            d,
            "--point",
            "5000,1",
            "--json",
            json.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("outside"));
    let _ = std::fs::remove_dir_all(&dir);
}
