//! Colour calibration against the virtual rig's known cross-talk.
#![allow(clippy::unwrap_used, reason = "tests")]

use nalgebra::Vector3;
use tremorscan::calibrate::{calibrate_colour, ColourOptions, ColourWarning, Roi};
use tremorscan::frame::Frame;
use tremorscan::rig::captures::{colour_target, render_colour_captures};
use tremorscan::rig::{NoiseModel, RigConfig, VirtualRig};

const W: usize = 320;
const H: usize = 200;
/// A 24×24 px region at the image centre: about 22 mm of the target, over which Lambert shading
/// and falloff change by well under 1 %, symmetric about the centre.
const ROI: Roi = Roi {
    x: W / 2 - 12,
    y: H / 2 - 12,
    width: 24,
    height: 24,
};

/// The rig looking at a white target, with the projector gain chosen so that one projector level
/// gives `A` gray levels at the region's centre: then the calibration must return the rig's `A`.
fn white_target_rig(noise: NoiseModel) -> VirtualRig {
    let mut config = RigConfig::paper(W, H).unwrap();
    config.noise = noise;
    let config = colour_target(&config, 3.0).unwrap();
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

fn captures(rig: &VirtualRig) -> Vec<Frame> {
    render_colour_captures(&rig.config).unwrap()
}

fn options() -> ColourOptions {
    ColourOptions {
        roi: ROI,
        samples: 10_000,
        saturation_level: 250,
        seed: 7,
    }
}

#[test]
fn recovers_the_rigs_cross_talk_at_default_noise() {
    let rig = white_target_rig(NoiseModel::default());
    let result = calibrate_colour(&captures(&rig), &options()).unwrap();
    let known = rig.config.cross_talk;
    let a = result.cross_talk.a;
    for i in 0..3 {
        for j in 0..3 {
            // Brief: each entry within 0.01. Noise contributes about 10⁻³ (576 pixels of
            // σ ≈ 1.2 gray against 70–210 gray of signal), shading across the region less.
            assert!(
                (a[(i, j)] - known.a[(i, j)]).abs() < 0.01,
                "A[{i}][{j}] = {} vs {}",
                a[(i, j)],
                known.a[(i, j)]
            );
        }
    }
    // b includes the ambient light on the white target. The mean of 576 pixels with σ ≈ 0.85 gray
    // has a standard error of 0.035 gray; allow four of them.
    let expected_b = known.b_gray + Vector3::repeat(rig.config.ambient_gray);
    assert!(
        (result.cross_talk.b_gray - expected_b).amax() < 0.15,
        "{:?}",
        result.cross_talk.b_gray
    );
    // The residual is the camera noise (σ about 0.8–1.6 gray with shot noise) and quantisation.
    assert!(
        result.residual_rms_gray < 2.0,
        "{}",
        result.residual_rms_gray
    );
    assert!(result.warnings.is_empty(), "{:?}", result.warnings);
}

#[test]
fn saturated_and_dark_captures_are_reported() {
    let mut rig = white_target_rig(NoiseModel::default());
    // A little too much light: full red (0.82·255·1.15 + 9 ≈ 249.5 gray) crosses the 250 guard
    // on about half of the samples.
    rig.config.projector_gain_gray *= 1.15;
    let result = calibrate_colour(&captures(&rig), &options()).unwrap();
    assert!(
        result
            .warnings
            .iter()
            .any(|w| matches!(w, ColourWarning::Saturated { capture: 7, .. })),
        "{:?}",
        result.warnings
    );
    // Far too much: full red clips everywhere, which leaves nothing to fit.
    let mut rig = white_target_rig(NoiseModel::default());
    rig.config.projector_gain_gray *= 1.6;
    assert_eq!(
        calibrate_colour(&captures(&rig), &options()).unwrap_err(),
        tremorscan::calibrate::CalibrationError::NoUsableSamples { capture: 7 }
    );
    // Far too little light: every colour stays within a few gray levels of black.
    let mut rig = white_target_rig(NoiseModel::default());
    rig.config.projector_gain_gray *= 0.02;
    let result = calibrate_colour(&captures(&rig), &options()).unwrap();
    assert!(
        result
            .warnings
            .iter()
            .any(|w| matches!(w, ColourWarning::TooDark { .. })),
        "{:?}",
        result.warnings
    );
}

#[test]
fn bad_input_is_refused_with_a_clear_error() {
    let rig = white_target_rig(NoiseModel::default());
    let frames = captures(&rig);
    let err = calibrate_colour(&frames[..9], &options()).unwrap_err();
    assert!(err.to_string().contains("needs the 10 captures"), "{err}");
    let mut outside = options();
    outside.roi.x = W - 10;
    let err = calibrate_colour(&frames, &outside).unwrap_err();
    assert!(err.to_string().contains("does not lie inside"), "{err}");
    let mut mixed = frames.clone();
    mixed[4] = Frame::new(W / 2, H / 2, 3).unwrap();
    assert!(calibrate_colour(&mixed, &options()).is_err());
}

#[test]
fn a_matrix_far_from_diagonal_is_flagged() {
    let mut rig = white_target_rig(NoiseModel::default());
    // A camera whose green channel sees mostly the projector's red.
    rig.config.cross_talk.a =
        nalgebra::Matrix3::new(0.5, 0.1, 0.02, 0.6, 0.3, 0.08, 0.02, 0.14, 0.51);
    let result = calibrate_colour(&captures(&rig), &options()).unwrap();
    assert!(result
        .warnings
        .contains(&ColourWarning::NotDiagonallyDominant));
    assert!((result.cross_talk.a[(1, 0)] - 0.6).abs() < 0.01);
}
