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
    // A second point on the back of the hand.
    let back = Scene::new(config.scene.clone()).at(0.0).points[5];
    let (bu, bv) = config.camera.project(&back).unwrap();
    let back_point = format!("{bu:.1},{bv:.1}");
    let csv = dir.join("track.csv");
    run(&[
        "track",
        d,
        "--point",
        &point,
        "--point",
        &back_point,
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
    // By default the point follows the skin: its u,v are where the material point it was
    // placed on is seen at each sample's time, within a pixel.
    let scene = Scene::new(config.scene.clone());
    let mut followed = 0;
    for row in lines
        .iter()
        .skip(1)
        .filter(|l| l.split(',').nth(2) == Some("0"))
    {
        let cells: Vec<&str> = row.split(',').collect();
        if cells[9] != "1" {
            continue;
        }
        let t: f64 = cells[0].parse().unwrap();
        let (pu, pv): (f64, f64) = (cells[3].parse().unwrap(), cells[4].parse().unwrap());
        let (tu, tv) = config.camera.project(&scene.at(t).points[0]).unwrap();
        assert!(
            (pu - tu).hypot(pv - tv) < 1.0,
            "{row}: the material point is at {tu:.2},{tv:.2}"
        );
        followed += 1;
    }
    assert!(followed > 228, "{followed} of 240 samples valid");
    // The same fingertip picked as a 3D point (as clicked in the cloud) tracks the same surface
    // at a fixed pixel.
    let fixed = |args: &[&str], name: &str| {
        let path = dir.join(name);
        let mut all = vec!["track", d, "--fixed-pixel", "--csv", path.to_str().unwrap()];
        all.extend_from_slice(args);
        run(&all);
        std::fs::read_to_string(&path).unwrap()
    };
    let tip_mm = format!("{},{},{}", tip.x, tip.y, tip.z);
    let text3 = fixed(&["--point-mm", &tip_mm], "track3d.csv");
    let text2 = fixed(&["--point", &point], "track2d.csv");
    let z = |line: &str| line.split(',').nth(7).unwrap().to_string();
    let rows3: Vec<&str> = text3.lines().skip(1).collect();
    assert_eq!(rows3.len(), 240);
    for (a, b) in rows3.iter().zip(text2.lines().skip(1)) {
        assert_eq!(z(a), z(b), "{a} vs {b}");
    }
    let json = dir.join("tremor.json");
    let stdout = run(&[
        "analyze",
        d,
        "--point",
        &point,
        "--point",
        &back_point,
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
        "tetras_amplitude_rating",
        "tremor_stability_index_hz",
        "half_power_bandwidth_hz",
        "harmonic_relative_power",
        "principal_axis",
        "spectrum_3d_peak_hz",
    ] {
        assert!(!p[key].is_null(), "{key}");
    }
    assert_eq!(p["tetras_amplitude_rating"], "1–1.5");
    assert_eq!(p["displacement_axis"]["name"], "vertical");
    let peak_3d = p["spectrum_3d_peak_hz"].as_f64().unwrap();
    assert!((peak_3d - 5.3).abs() < 0.1, "{peak_3d}");
    // The fingertip flexes about its knuckle, mostly along the optical axis.
    let principal = p["principal_axis"].as_array().unwrap();
    assert!(principal[2].as_f64().unwrap() > 0.9, "{principal:?}");
    // The back of the hand rises and falls with the index finger (the rig's whole-hand
    // motion is in phase with it): the two points are coherent at the tremor's peak.
    let c = &p["coherence"][0];
    assert_eq!(c["with"], value[1]["name"]);
    assert!(c["at_peak"].as_f64().unwrap() > 0.8, "{c}");
    // Along the principal axis the peak-to-peak is at least the vertical one.
    let json_p = dir.join("tremor-principal.json");
    run(&[
        "analyze",
        d,
        "--point",
        &point,
        "--axis",
        "principal",
        "--json",
        json_p.to_str().unwrap(),
    ]);
    let principal_run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_p).unwrap()).unwrap();
    let q = &principal_run[0];
    assert_eq!(q["displacement_axis"]["name"], "principal");
    assert!(
        q["amplitude_peak_to_peak_mm"].as_f64().unwrap()
            >= 0.99 * p["amplitude_peak_to_peak_mm"].as_f64().unwrap(),
        "{} against {}",
        q["amplitude_peak_to_peak_mm"],
        p["amplitude_peak_to_peak_mm"]
    );
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
