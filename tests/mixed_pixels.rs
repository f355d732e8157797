//! No point is made up at a depth edge: with the camera's optical blur the rig's pixels on a
//! finger's outline mix two surfaces, and the decoder must refuse them (`invalid::MIXED`)
//! without losing the surface away from the outline. The protocol and its figures:
//! `src/rig/edge_eval.rs`, `docs/accuracy.md`.
#![allow(clippy::unwrap_used, reason = "tests")]

use tremorscan::decode::DecodeParams;
use tremorscan::rig::edge_eval::{evaluate_edges, EdgeAccuracy};
use tremorscan::rig::{RigConfig, VirtualRig};

/// The still hand at 960×600 with the rig's default blur, decoded with `params`.
fn still_hand(params: DecodeParams) -> EdgeAccuracy {
    let mut config = RigConfig::paper(960, 600).unwrap();
    assert!(
        config.camera_psf_sigma_px > 0.0,
        "the blur is on by default"
    );
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = 0.0;
        t.hand_amplitude_mm = 0.0;
    }
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    evaluate_edges(&rig, params, 0).unwrap()
}

#[test]
fn mixed_pixels_at_depth_edges_are_refused() {
    let without = still_hand(DecodeParams {
        mixed_limit_px: 0.0,
        ..DecodeParams::default()
    });
    let with = still_hand(DecodeParams::default());
    for (name, a) in [("without the check", &without), ("with it", &with)] {
        println!(
            "{name}: {} valid, {} more than 2 mm off ({:.4} %, {} on the outline); lit pixels off \
             the outline valid {:.3} %, their RMS {:.4} mm",
            a.valid,
            a.gross,
            100.0 * a.gross_rate().unwrap(),
            a.gross_on_outline,
            100.0 * a.interior_coverage().unwrap(),
            a.interior_rms_mm().unwrap()
        );
    }
    // Without the check the blur makes up points on the outline, and only there (measured:
    // 472, 0.085 % of the valid pixels): the case must show the defect.
    assert!(without.gross_rate().unwrap() > 5e-4, "{without:?}");
    assert_eq!(without.gross, without.gross_on_outline, "{without:?}");
    // The targets (measured: 0.012 %, 99.995 %, 0.0785 mm against 0.0785 mm).
    assert!(with.gross_rate().unwrap() <= 5e-4, "{with:?}");
    assert!(with.interior_coverage().unwrap() >= 0.98, "{with:?}");
    // The interior is untouched: the check refuses pixels on the outline, and off it only
    // the odd noisy one (measured: 99.998 → 99.995 % valid, the RMS the same to 0.1 µm).
    let (a, b) = (
        without.interior_rms_mm().unwrap(),
        with.interior_rms_mm().unwrap(),
    );
    assert!((b / a - 1.0).abs() < 0.01, "interior RMS {a} → {b} mm");
    let lost = without.interior_coverage().unwrap() - with.interior_coverage().unwrap();
    assert!(lost < 2e-4, "{without:?} → {with:?}");
}
