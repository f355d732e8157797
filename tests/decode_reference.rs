//! The fast decoder computes what the straightforward per-pixel 9×9 solve computes
//! (`decode::reference`), on the virtual rig's frames with camera noise.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use std::f32::consts::TAU;
use tremorscan::decode::reference::decode_window_reference;
use tremorscan::decode::{
    decode_window, DecodeOutput, DecodeParams, MotionParams, UnwrapMethod, WindowSolver,
};
use tremorscan::frame::Frame;
use tremorscan::pattern::{cps_gray, Axis, CpsGrayVariant, PatternSequence};
use tremorscan::rig::{RigConfig, VirtualRig};

fn frames(rig: &VirtualRig, first: u64) -> Vec<Frame> {
    let len = rig.sequence.entries.len() as u64;
    common::rendered(rig, first..first + len)
}

/// Decodes `frames` both ways and compares every output plane. The reference is the still
/// model, so both decode without the motion model.
fn compare(rig: &VirtualRig, frames: &[Frame], params: DecodeParams) {
    let params = DecodeParams {
        motion: MotionParams::off(),
        ..params
    };
    let order: Vec<usize> = frames.iter().map(|f| f.pattern_index).collect();
    let solver = WindowSolver::new(&rig.sequence, &order, &rig.config.cross_talk).unwrap();
    let n = rig.sequence.chebyshev_n();
    let (w, h) = (frames[0].width, frames[0].height);
    let mut fast = DecodeOutput::new(w, h, &solver);
    let mut reference = DecodeOutput::new(w, h, &solver);
    decode_window(&solver, frames, &params, n, &mut fast).unwrap();
    decode_window_reference(&solver, frames, &params, n, &mut reference).unwrap();
    // Stage 1, on pixels with signal: the fast path rounds the solve to f32 (relative 1e-6 of
    // values up to a few hundred gray levels) and uses a polynomial atan2 (error ≤ 1e-5 rad).
    let (mut phase_err, mut amp_err, mut colour_err) = (0f32, 0f32, 0f32);
    for i in 0..fast.phase_rad.len() {
        let (a, b) = (fast.amplitude[i], reference.amplitude[i]);
        if b < params.min_amplitude {
            continue;
        }
        let d = (fast.phase_rad[i] - reference.phase_rad[i]).abs();
        phase_err = phase_err.max(d.min(TAU - d));
        amp_err = amp_err.max((a - b).abs() / b);
    }
    for (a, b) in fast.colour.iter().zip(&reference.colour) {
        colour_err = colour_err.max((a - b).abs());
    }
    // The final coordinate where both are valid, and how often validity differs.
    let (mut coord_err, mut both, mut differs) = (0f32, 0usize, 0usize);
    for (p, (&a, &b)) in fast
        .coordinate_px
        .iter()
        .zip(&reference.coordinate_px)
        .enumerate()
    {
        if (fast.invalid[p] == 0) != (reference.invalid[p] == 0) {
            differs += 1;
            borderline(&solver, &params, &reference, p, fast.invalid[p]);
        } else if fast.invalid[p] == 0 {
            coord_err = coord_err.max((a - b).abs());
            both += 1;
        }
    }
    eprintln!(
        "{w}×{h} {:?}: phase {phase_err:.1e} rad, amplitude {amp_err:.1e} rel, colour \
         {colour_err:.1e} gray, coordinate {coord_err:.1e} px on {both} pixels, validity differs \
         on {differs}",
        params.unwrap
    );
    assert!(phase_err < 5e-5, "phase differs by {phase_err} rad");
    assert!(amp_err < 1e-4, "amplitude differs by {amp_err} (relative)");
    assert!(
        colour_err < 1e-3,
        "colour differs by {colour_err} gray levels"
    );
    // 1e-5 rad on the finest phase (0.22 rad/px) is 5e-5 px; 1e-3 px is the bound.
    assert!(coord_err < 1e-3, "coordinate differs by {coord_err} px");
    assert!(both > w * h / 4, "only {both} valid pixels");
    // Each pixel whose validity differs was checked to be a borderline case above; a
    // systematic difference would flip far more than one pixel in a thousand.
    assert!(
        differs * 1000 <= w * h,
        "validity differs on {differs} pixels"
    );
}

/// A pixel valid on one path and not on the other must sit on a threshold: the two paths differ
/// by rounding only. The per-pixel (paper) coarse coordinate goes through `acos`, whose slope
/// grows without bound near the ends of the range, so there 1e-5 rad of phase rounding moves it
/// by up to about 0.1 px, and the eq. 8 rounding residual by up to 0.1/14 ≈ 0.007 of a period.
fn borderline(
    solver: &WindowSolver,
    params: &DecodeParams,
    reference: &DecodeOutput,
    p: usize,
    fast_reason: u8,
) {
    use tremorscan::decode::invalid;
    let changed = fast_reason ^ reference.invalid[p];
    assert_eq!(
        changed & !(invalid::UNWRAP_MARGIN | invalid::ORDER_JUMP),
        0,
        "pixel {p}: reasons {fast_reason} (fast) and {} (reference)",
        reference.invalid[p]
    );
    if changed & invalid::UNWRAP_MARGIN != 0 {
        let (w, x, y) = (reference.width, p % reference.width, p / reference.width);
        let xc = reference.coarse_px[p];
        let residual = (0..3)
            .map(|f| {
                let arg = (xc * solver.frequency_rad_per_px[f] - reference.phase_at(f, x, y)) / TAU;
                (arg - arg.round()).abs()
            })
            .fold(0f32, f32::max);
        assert!(
            (residual - params.max_rounding_residual).abs() < 0.01,
            "pixel {p} (row width {w}): rounding residual {residual} is not at the threshold"
        );
    }
}

#[test]
fn fast_cps_rgb_decode_equals_the_per_pixel_solve() {
    let config = RigConfig::paper(320, 200).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    for method in [
        UnwrapMethod::ChebyshevRobust,
        UnwrapMethod::ChebyshevPerPixel,
    ] {
        let params = DecodeParams {
            unwrap: method,
            ..DecodeParams::default()
        };
        compare(&rig, &frames(&rig, 0), params);
    }
    // A rotated window (frames 1, 2, 0 of the sequence).
    compare(&rig, &frames(&rig, 1), DecodeParams::default());
}

#[test]
fn fast_gray_decode_equals_the_per_pixel_solve() {
    let config = RigConfig::paper(320, 200).unwrap();
    let seq: PatternSequence =
        cps_gray(65, CpsGrayVariant::Minimal7, 912.0, Axis::Columns, 8).unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    compare(&rig, &frames(&rig, 0), DecodeParams::default());
}
