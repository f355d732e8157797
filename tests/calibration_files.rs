//! Calibration files: the JSON file round-trips, malformed files name the field, and OpenCV
//! FileStorage files (YAML and XML) import to the same calibration.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use serde_json::{json, Value};
use tremorscan::calibrate::{import_opencv, CalibrationFile, ColourFile, CALIBRATION_FORMAT};
use tremorscan::rig::RigConfig;
use tremorscan::session::manifest::{ColorJson, ExtrinsicsJson, LensJson};

fn rig_file() -> CalibrationFile {
    let c = RigConfig::paper(960, 600).unwrap();
    CalibrationFile {
        format: CALIBRATION_FORMAT.to_string(),
        created_utc: "2026-11-24T02:30:00Z".to_string(),
        rig: "virtual paper rig".to_string(),
        pattern: None,
        camera: LensJson::from_lens(&c.camera),
        projector: LensJson::from_lens(&c.projector),
        extrinsics: ExtrinsicsJson::from_pose(&c.projector_from_camera),
        color: Some(ColorJson::from_cross_talk(&c.cross_talk)),
        rms: None,
    }
}

#[test]
fn the_calibration_file_round_trips() {
    let dir = scratch("roundtrip");
    let path = dir.join("calib.json");
    let file = rig_file();
    file.save(&path).unwrap();
    let (loaded, calib) = CalibrationFile::load(&path).unwrap();
    assert_eq!(loaded, file);
    let c = RigConfig::paper(960, 600).unwrap();
    assert_eq!(calib.camera, c.camera);
    assert_eq!(calib.projector, c.projector);
    assert!(
        (calib.projector_from_camera.rotation - c.projector_from_camera.rotation)
            .abs()
            .max()
            < 1e-15
    );
    assert_eq!(calib.cross_talk, Some(c.cross_talk));
    let _ = std::fs::remove_dir_all(&dir);
}

fn load_error(name: &str, edit: impl FnOnce(&mut Value)) -> String {
    let dir = scratch(name);
    let path = dir.join("calib.json");
    let mut value = serde_json::to_value(rig_file()).unwrap();
    edit(&mut value);
    std::fs::write(&path, value.to_string()).unwrap();
    let e = CalibrationFile::load(&path).unwrap_err().to_string();
    let _ = std::fs::remove_dir_all(&dir);
    e
}

#[test]
fn malformed_calibration_files_name_the_field() {
    let e = load_error("noextr", |v| {
        v.as_object_mut().unwrap().remove("extrinsics");
    });
    assert!(e.contains("extrinsics"), "{e}");
    let e = load_error("format", |v| v["format"] = json!("something-else"));
    assert!(e.contains("cps-calibration/1"), "{e}");
    let e = load_error("rot", |v| v["extrinsics"]["R"][1][1] = json!(-1.0));
    assert!(e.contains("extrinsics.R"), "{e}");
    let e = load_error("fx", |v| v["projector"]["K"][0][0] = json!(-5.0));
    assert!(e.contains("projector.K") && e.contains("positive"), "{e}");
    let e = load_error("nan", |v| v["camera"]["dist"] = json!([0.1, "x", 0.0, 0.0]));
    assert!(e.contains("camera.dist"), "{e}");
    let e = load_error("size", |v| v["camera"]["width"] = json!(0));
    assert!(e.contains("camera.width"), "{e}");
}

#[test]
fn the_colour_file_round_trips_and_checks_a() {
    let dir = scratch("colour");
    let path = dir.join("color.json");
    let c = RigConfig::paper(64, 40).unwrap().cross_talk;
    ColourFile::new(&c, 1.25).save(&path).unwrap();
    let (file, loaded) = ColourFile::load(&path).unwrap();
    assert_eq!(loaded, c);
    assert_eq!(file.rms_residual, 1.25);
    std::fs::write(
        &path,
        r#"{"A": [[0,0,0],[0,0,0],[0,0,0]], "b": [1,2,3], "rms_residual": 0}"#,
    )
    .unwrap();
    let e = ColourFile::load(&path).unwrap_err().to_string();
    assert!(e.contains("A") && e.contains("singular"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The rig's calibration as OpenCV would write it (`%g`-like formatting, 1×5 distortion).
fn opencv_yaml(c: &RigConfig) -> String {
    let k = |l: &tremorscan::geometry::LensModel| {
        let i = l.intrinsics;
        format!(
            "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {:e}, 0., {:e}, 0., {:e},\n       {:e}, 0., 0., 1. ]\n",
            i.fx, i.cx, i.fy, i.cy
        )
    };
    let d = |l: &tremorscan::geometry::LensModel| {
        let d = l.distortion;
        format!(
            "!!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ {:e}, {:e}, {:e}, {:e}, {:e} ]\n",
            d.k1, d.k2, d.p1, d.p2, d.k3
        )
    };
    let r = c.projector_from_camera.rotation;
    let t = c.projector_from_camera.translation_mm;
    let rows: Vec<String> = (0..9).map(|i| format!("{:e}", r[(i / 3, i % 3)])).collect();
    format!(
        "%YAML:1.0\n---\nKc: {}kc: {}Kp: {}kp: {}Rp: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {} ]\nTp: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ {:e}, {:e}, {:e} ]\ncam_error: 0.05\n",
        k(&c.camera),
        d(&c.camera),
        k(&c.projector),
        d(&c.projector),
        rows.join(", "),
        t.x,
        t.y,
        t.z
    )
}

#[test]
fn opencv_yaml_imports_the_same_calibration() {
    let c = RigConfig::paper(960, 600).unwrap();
    let dir = scratch("yaml");
    let path = dir.join("calibration.yml");
    std::fs::write(&path, opencv_yaml(&c)).unwrap();
    let calib = import_opencv(&path, (960, 600), (912, 1140)).unwrap();
    assert_eq!(calib.camera, c.camera);
    assert_eq!(calib.projector, c.projector);
    assert!(
        (calib.projector_from_camera.rotation - c.projector_from_camera.rotation)
            .abs()
            .max()
            < 1e-12
    );
    assert!(
        (calib.projector_from_camera.translation_mm - c.projector_from_camera.translation_mm)
            .norm()
            < 1e-9
    );
    // A missing matrix is named with the alternatives looked for.
    let text = opencv_yaml(&c).replace("Kp:", "Kq:");
    std::fs::write(&path, text).unwrap();
    let e = import_opencv(&path, (960, 600), (912, 1140))
        .unwrap_err()
        .to_string();
    assert!(e.contains("Kp or proj_K or K2"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn opencv_xml_imports_with_other_names() {
    let c = RigConfig::paper(960, 600).unwrap();
    let m = |name: &str, rows: usize, cols: usize, data: &[f64]| {
        let values: Vec<String> = data.iter().map(|v| format!("{v:e}")).collect();
        format!(
            "<{name} type_id=\"opencv-matrix\">\n  <rows>{rows}</rows>\n  <cols>{cols}</cols>\n  <dt>d</dt>\n  <data>\n    {}</data></{name}>\n",
            values.join(" ")
        )
    };
    let k = |l: &tremorscan::geometry::LensModel| {
        let i = l.intrinsics;
        [i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0]
    };
    let d = |l: &tremorscan::geometry::LensModel| {
        let d = l.distortion;
        [d.k1, d.k2, d.p1, d.p2]
    };
    let r = c.projector_from_camera.rotation;
    let r: Vec<f64> = (0..9).map(|i| r[(i / 3, i % 3)]).collect();
    let t = c.projector_from_camera.translation_mm;
    let xml = format!(
        "<?xml version=\"1.0\"?>\n<opencv_storage>\n{}{}{}{}{}{}<stereo_error>0.1</stereo_error>\n</opencv_storage>\n",
        m("cam_K", 3, 3, &k(&c.camera)),
        m("cam_kc", 1, 4, &d(&c.camera)),
        m("proj_K", 3, 3, &k(&c.projector)),
        m("proj_kc", 4, 1, &d(&c.projector)),
        m("R", 3, 3, &r),
        m("T", 3, 1, &[t.x, t.y, t.z]),
    );
    let dir = scratch("xml");
    let path = dir.join("calibration.xml");
    std::fs::write(&path, xml).unwrap();
    let calib = import_opencv(&path, (960, 600), (912, 1140)).unwrap();
    assert_eq!(calib.camera.intrinsics, c.camera.intrinsics);
    assert_eq!(calib.projector.distortion.k2, c.projector.distortion.k2);
    assert_eq!(calib.camera.distortion.k3, 0.0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fresh, existing scratch folder.
fn scratch(name: &str) -> common::Scratch {
    common::scratch_dir(&format!("calfile-{name}"))
}
