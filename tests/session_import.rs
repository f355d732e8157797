//! `cps-session/1` import: a valid session opens as written, and every malformed manifest is
//! refused with an error that names the field or file.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use serde_json::{json, Value};
use tremorscan::frame::Frame;
use tremorscan::pattern::{cps_rgb, Axis, PatternEntry};
use tremorscan::session::frames::write_png;
use tremorscan::session::{Session, SessionEntry, SessionError};

/// A fresh session folder with an empty `frames/` folder.
fn scratch(name: &str) -> common::Scratch {
    let dir = common::scratch_dir(name);
    std::fs::create_dir_all(dir.join("frames")).unwrap();
    dir
}

/// The import form: three CPS-RGB entries, three 16×10 RGB frames.
fn valid_manifest() -> Value {
    json!({
        "format": "cps-session/1",
        "pattern": {"x_max": 912.0, "axis": "columns", "projector_bits": 6,
            "sequence": [
                {"red": {"m": 64, "shift_rad": 0.0}, "green": {"m": 63, "shift_rad": 0.0}, "blue": {"m": 65, "shift_rad": 0.0}},
                {"red": {"m": 64, "shift_rad": 2.0943951023931953}, "green": {"m": 63, "shift_rad": 2.0943951023931953}, "blue": {"m": 65, "shift_rad": 2.0943951023931953}},
                {"red": {"m": 64, "shift_rad": 4.1887902047863905}, "green": {"m": 63, "shift_rad": 4.1887902047863905}, "blue": {"m": 65, "shift_rad": 4.1887902047863905}}
            ]},
        "color": {"A": [[0.82, 0.11, 0.02], [0.22, 0.71, 0.08], [0.02, 0.14, 0.51]], "b": [6.0, 7.0, 9.0]},
        "camera": {"width": 16, "height": 10, "K": [[1625.0, 0.0, 8.0], [0.0, 1625.0, 5.0], [0.0, 0.0, 1.0]], "dist": [-0.08, 0.05, 0.0004, -0.0003, 0.0]},
        "projector": {"width": 912, "height": 1140, "K": [[1380.0, 0.0, 455.5], [0.0, 1380.0, 575.0], [0.0, 0.0, 1.0]], "dist": [0.03, -0.01, 0.0, 0.0, 0.0]},
        "extrinsics": {"R": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "t_mm": [-150.0, 0.0, 20.0]},
        "frames": [
            {"file": "frames/000000.png", "time_s": 0.0, "pattern_index": 0},
            {"file": "frames/000001.png", "time_s": 0.00826, "pattern_index": 1},
            {"file": "frames/000002.png", "time_s": 0.01653, "pattern_index": 2}
        ],
        "tool": "another lab's recorder, an extra key to be ignored"
    })
}

fn frame(width: usize, height: usize, channels: usize, seed: u8) -> Frame {
    let data = (0..width * height * channels)
        .map(|i| (i as u8).wrapping_mul(7).wrapping_add(seed))
        .collect();
    Frame::from_data(width, height, channels, data).unwrap()
}

/// Writes `manifest` and three 16×10 RGB frames; returns the folder.
fn session_with(name: &str, manifest: &Value) -> common::Scratch {
    let dir = scratch(name);
    for i in 0..3 {
        write_png(
            &dir.join(format!("frames/{i:06}.png")),
            &frame(16, 10, 3, i as u8),
        )
        .unwrap();
    }
    std::fs::write(
        dir.join("session.json"),
        serde_json::to_string_pretty(manifest).unwrap(),
    )
    .unwrap();
    dir
}

fn open_error(name: &str, edit: impl FnOnce(&mut Value)) -> String {
    let mut manifest = valid_manifest();
    edit(&mut manifest);
    let dir = session_with(name, &manifest);
    let err = Session::open(&dir).unwrap_err().to_string();
    let _ = std::fs::remove_dir_all(&dir);
    err
}

#[test]
fn the_import_form_opens_with_every_part_checked() {
    let dir = session_with("valid", &valid_manifest());
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.frame_count(), 3);
    assert_eq!(
        session.sequence().unwrap(),
        cps_rgb(65, 912.0, Axis::Columns, 6).unwrap()
    );
    let model = session.stereo_model().unwrap();
    assert_eq!(model.camera.intrinsics.fx, 1625.0);
    assert_eq!(model.projector.distortion.k1, 0.03);
    assert_eq!(model.projector_from_camera.translation_mm.x, -150.0);
    assert_eq!(session.cross_talk().unwrap().unwrap().b_gray.z, 9.0);
    let f = session.load_frame(1).unwrap();
    assert_eq!(
        (f.width, f.height, f.channels, f.pattern_index),
        (16, 10, 3, 1)
    );
    assert_eq!(
        f.data,
        frame(16, 10, 3, 1).data,
        "PNG round trip is lossless"
    );
    assert_eq!(f.time_s, 0.00826);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gray_and_bmp_frames_load() {
    let dir = session_with("gray-bmp", &valid_manifest());
    let gray = frame(16, 10, 1, 3);
    image::save_buffer(
        dir.join("frames/000001.bmp"),
        &gray.data,
        16,
        10,
        image::ColorType::L8,
    )
    .unwrap();
    let mut manifest = valid_manifest();
    manifest["frames"][1]["file"] = json!("frames/000001.bmp");
    std::fs::write(dir.join("session.json"), manifest.to_string()).unwrap();
    let session = Session::open(&dir).unwrap();
    let f = session.load_frame(1).unwrap();
    // BMP stores gray as 8-bit palette or expanded RGB; either way the levels survive.
    let levels: Vec<u8> = f.data.iter().step_by(f.channels).copied().collect();
    assert_eq!(levels, gray.data);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn calibration_entries_constant_and_both_axes() {
    let mut manifest = valid_manifest();
    manifest["pattern"]["sequence"][0] = json!({"constant": [85, 0, 0]});
    manifest["pattern"]["sequence"][2] =
        json!({"axis": "rows", "x_max": 1140.0, "gray": {"m": 81, "shift_rad": 0.0}});
    manifest.as_object_mut().unwrap().remove("color");
    manifest["camera"].as_object_mut().unwrap().remove("K");
    manifest["camera"].as_object_mut().unwrap().remove("dist");
    manifest.as_object_mut().unwrap().remove("extrinsics");
    let dir = session_with("calibration", &manifest);
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.entries[0], SessionEntry::Constant([85.0, 0.0, 0.0]));
    match session.entries[2] {
        SessionEntry::Coding { axis, x_max, entry } => {
            assert_eq!((axis, x_max), (Axis::Rows, 1140.0));
            assert!(matches!(entry, PatternEntry::Gray(_)));
        }
        other => panic!("{other:?}"),
    }
    // What a calibration session may lack is asked for by name when needed.
    assert!(session
        .camera()
        .unwrap_err()
        .to_string()
        .contains("camera.K: is missing"));
    assert!(session
        .projector_from_camera()
        .unwrap_err()
        .to_string()
        .contains("extrinsics: is missing"));
    assert!(session.sequence().is_err(), "not a measurement sequence");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn wrong_format_tag() {
    let e = open_error("format", |m| m["format"] = json!("cps-session/2"));
    assert!(
        e.contains("\"cps-session/2\"") && e.contains("cps-session/1"),
        "{e}"
    );
}

#[test]
fn missing_key() {
    let e = open_error("missing", |m| {
        m["pattern"]
            .as_object_mut()
            .unwrap()
            .remove("projector_bits");
    });
    assert!(e.contains("pattern") && e.contains("projector_bits"), "{e}");
}

#[test]
fn wrong_type() {
    let e = open_error("type", |m| m["camera"]["width"] = json!("960"));
    assert!(e.contains("camera.width"), "{e}");
}

#[test]
fn unknown_axis() {
    let e = open_error("axis", |m| m["pattern"]["axis"] = json!("radial"));
    assert!(e.contains("pattern.axis"), "{e}");
}

#[test]
fn entry_mixing_gray_and_colour() {
    let e = open_error("mixed", |m| {
        m["pattern"]["sequence"][1]["gray"] = json!({"m": 3, "shift_rad": 0.0});
    });
    assert!(e.contains("pattern.sequence[1]"), "{e}");
}

#[test]
fn entry_missing_a_channel() {
    let e = open_error("channel", |m| {
        m["pattern"]["sequence"][2]
            .as_object_mut()
            .unwrap()
            .remove("blue");
    });
    assert!(e.contains("pattern.sequence[2]"), "{e}");
}

#[test]
fn constant_level_out_of_range() {
    let e = open_error("constant", |m| {
        m["pattern"]["sequence"][0] = json!({"constant": [300, 0, 0]});
    });
    assert!(e.contains("pattern.sequence[0].constant"), "{e}");
}

#[test]
fn bad_bit_depth() {
    let e = open_error("bits", |m| m["pattern"]["projector_bits"] = json!(12));
    assert!(e.contains("pattern.projector_bits"), "{e}");
}

#[test]
fn pattern_index_out_of_range() {
    let e = open_error("index", |m| m["frames"][2]["pattern_index"] = json!(3));
    assert!(e.contains("frames[2].pattern_index"), "{e}");
}

#[test]
fn missing_frame_file() {
    let e = open_error("nofile", |m| {
        m["frames"][1]["file"] = json!("frames/000009.png")
    });
    assert!(e.contains("000009.png") && e.contains("missing"), "{e}");
}

#[test]
fn camera_matrix_with_skew_or_wrong_shape() {
    let e = open_error("skew", |m| m["camera"]["K"][0][1] = json!(0.5));
    assert!(e.contains("camera.K"), "{e}");
    let e = open_error("shape", |m| {
        m["camera"]["K"] = json!([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    });
    assert!(e.contains("camera.K"), "{e}");
}

#[test]
fn distortion_of_the_wrong_length() {
    let e = open_error("dist", |m| m["projector"]["dist"] = json!([0.1, 0.2, 0.3]));
    assert!(e.contains("projector.dist") && e.contains("4 or 5"), "{e}");
}

#[test]
fn extrinsic_rotation_that_is_not_a_rotation() {
    let e = open_error("rotation", |m| m["extrinsics"]["R"][0][0] = json!(2.0));
    assert!(
        e.contains("extrinsics.R") && e.contains("not a rotation"),
        "{e}"
    );
}

#[test]
fn singular_colour_matrix() {
    let e = open_error("colour", |m| {
        m["color"]["A"] = json!([[1, 1, 1], [1, 1, 1], [1, 1, 1]])
    });
    assert!(e.contains("color.A") && e.contains("singular"), "{e}");
}

#[test]
fn not_json_at_all() {
    let dir = scratch("notjson");
    std::fs::write(dir.join("session.json"), "format: cps-session/1").unwrap();
    let e = Session::open(&dir).unwrap_err();
    assert!(matches!(e, SessionError::Json(_)), "{e:?}");
    let _ = std::fs::remove_dir_all(&dir);
    let e = Session::open(&dir).unwrap_err();
    assert!(e.to_string().contains("session.json"), "{e}");
}

#[test]
fn frame_of_the_wrong_size_or_depth() {
    let dir = session_with("size", &valid_manifest());
    write_png(&dir.join("frames/000002.png"), &frame(17, 10, 3, 0)).unwrap();
    let session = Session::open(&dir).unwrap();
    let e = session.load_frame(2).unwrap_err().to_string();
    assert!(
        e.contains("000002.png") && e.contains("17×10") && e.contains("16×10"),
        "{e}"
    );
    // 16-bit gray.
    image::save_buffer(
        dir.join("frames/000001.png"),
        &[0u8; 16 * 10 * 2],
        16,
        10,
        image::ColorType::L16,
    )
    .unwrap();
    let e = session.load_frame(1).unwrap_err().to_string();
    assert!(e.contains("000001.png") && e.contains("8-bit"), "{e}");
    // Not an image.
    std::fs::write(dir.join("frames/000000.png"), b"not a png").unwrap();
    let e = session.load_frame(0).unwrap_err().to_string();
    assert!(e.contains("000000.png"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
