//! The motion model's steps started from the stream's previous window
//! (`MotionParams::predicted_start`, `decode/motion_predict.rs`) against steps from rest, on
//! the rig's truth: the fast skin of a large tremor, the swaying hand, and a still hand.
//!
//! Each case decodes frames 0..14 (windows ending at frames 2, 5, 8, 11) with both settings
//! and compares them with the truth as `tremorscan sweep --motion` does
//! ([`tremorscan::rig::motion_eval`]); the sweep's 13 windows per row are in docs/accuracy.md.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use tremorscan::decode::DecodeParams;
use tremorscan::rig::motion_eval::{evaluate_motion, MotionAccuracy};
use tremorscan::rig::VirtualRig;

fn rig(amplitude_mm: f64, sway_mm: f64, roll_deg: f64) -> VirtualRig {
    common::trembling_hand(amplitude_mm, sway_mm, roll_deg)
}

fn from_rest() -> DecodeParams {
    let mut params = DecodeParams::default();
    params.motion.predicted_start = false;
    params
}

/// From rest, then predicted (the default), over the same windows of `rig`.
fn both(rig: &VirtualRig) -> (MotionAccuracy, MotionAccuracy) {
    let a = evaluate_motion(rig, from_rest(), 14, 3).unwrap();
    let b = evaluate_motion(rig, DecodeParams::default(), 14, 3).unwrap();
    eprintln!("from rest: {a:?}\npredicted: {b:?}");
    (a, b)
}

#[test]
fn a_twenty_millimetre_tremor_keeps_more_of_its_fastest_skin() {
    // Where the skin turns 0.6–0.8 rad a frame, two steps from rest fall short of its velocity
    // (decode/motion_predict.rs). Over these four windows (the first has no window before it):
    // 87.02 %, 0.41 % and 0.251 mm against 86.03 %, 0.43 % and 0.253 mm.
    let (rest, predicted) = both(&rig(20.0, 0.0, 0.0));
    let (a, b) = (&rest.moving, &predicted.moving);
    assert!(
        b.coverage().unwrap() >= a.coverage().unwrap() + 0.005,
        "coverage {:?} against {:?}",
        b.coverage(),
        a.coverage()
    );
    assert!(b.gross_rate().unwrap() <= a.gross_rate().unwrap() + 5e-4);
    assert!(b.rms_mm().unwrap() <= a.rms_mm().unwrap());
}

#[test]
fn a_swaying_hand_loses_nothing_by_starting_from_the_window_before() {
    // A 10 mm tremor swaying 4 mm. Over these four windows: 96.71 %, 0.18 % and 0.189 mm
    // against 96.72 %, 0.21 % and 0.193 mm.
    let (rest, predicted) = both(&rig(10.0, 4.0, 3.0));
    let (a, b) = (&rest.moving, &predicted.moving);
    assert!(b.coverage().unwrap() >= a.coverage().unwrap() - 1e-3);
    assert!(b.gross_rate().unwrap() <= a.gross_rate().unwrap() + 5e-4);
    assert!(b.rms_mm().unwrap() <= 1.01 * a.rms_mm().unwrap());
}

#[test]
fn a_still_hand_decodes_as_from_rest() {
    // A still hand's patches do not move (but for the significance test's chance hits), so its
    // windows start from rest either way and every pixel whose patch stayed still comes out as
    // from rest (measured over six windows: 4 pixel-windows moving, 3 others differing, by
    // 9.2·10⁻⁵ px at most, of 1,468,300 valid).
    let rig = rig(0.0, 0.0, 0.0);
    let c = common::still_pixels_compared(&rig, from_rest(), DecodeParams::default(), 8);
    let (moving, differing, valid) = (c.moving, c.differing, c.valid);
    assert!(valid > 1_000_000, "{valid}");
    assert!(moving <= 20, "{moving}");
    assert!(differing <= 20, "{differing}");
}
