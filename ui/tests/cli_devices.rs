//! `tremorscan devices` and `tremorscan lightcrafter`: what the build can drive, the CPS timing
//! plan, and clear errors where a feature or a device is missing.

#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::tremorscan;

#[test]
fn devices_lists_cameras_and_projectors_without_failing() {
    let out = tremorscan(&["devices"]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("cameras (GenICam"), "{text}");
    assert!(text.contains("DLP LightCrafter 4500:"), "{text}");
    assert!(text.contains("second screen"), "{text}");
}

#[test]
fn the_lightcrafter_plan_is_six_bits_at_121_fps_and_too_fast_is_an_error() {
    let out = tremorscan(&["lightcrafter", "--dry-run"]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("6-bit patterns of 2500 µs, 7500 µs of light per image, 8264 µs per image"),
        "{text}"
    );
    let out = tremorscan(&["lightcrafter", "--fps", "121", "--bits", "8", "--dry-run"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("lower the bit depth or the frame rate"),
        "{err}"
    );
    // Programming needs the feature and the device; either way the answer is one error line.
    let out = tremorscan(&["lightcrafter"]);
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with("error: "), "{err}");
        assert!(err.contains("LightCrafter"), "{err}");
    }
}
