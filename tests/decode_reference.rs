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
///
/// The mixed-pixel stage reads the neighbours' coordinates and validity, so a pixel that flips
/// at a threshold can flip the marks of its neighbours: the planes are compared without it, and
/// the stage is then run on both and compared on its own ([`same_mixed_marks`]).
fn compare(rig: &VirtualRig, frames: &[Frame], params: DecodeParams) {
    let params = DecodeParams {
        motion: MotionParams::off(),
        mixed_limit_px: 0.0,
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
    let edges = depth_edges(&solver, &params, &reference);
    let (mut coord_err, mut both, mut differs) = (0f32, 0usize, 0usize);
    for (p, (&a, &b)) in fast
        .coordinate_px
        .iter()
        .zip(&reference.coordinate_px)
        .enumerate()
    {
        if (fast.invalid[p] == 0) != (reference.invalid[p] == 0) {
            differs += 1;
            borderline(&solver, &params, &reference, p, fast.invalid[p], edges[p]);
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
    same_mixed_marks(&solver, &params, &mut fast, &mut reference);
}

/// Runs the mixed-pixel stage on both outputs. The marks must agree but for the odd pixel, and
/// a pixel marked on one path only must lie within two pixels of one that both paths mark (a
/// depth edge) or of one whose validity differed before the stage (a borderline case, whose
/// neighbours' extrapolations then differ).
fn same_mixed_marks(
    solver: &WindowSolver,
    params: &DecodeParams,
    fast: &mut DecodeOutput,
    reference: &mut DecodeOutput,
) {
    use tremorscan::decode::{edges::flag_mixed_pixels, invalid};
    let params = DecodeParams {
        mixed_limit_px: DecodeParams::default().mixed_limit_px,
        ..*params
    };
    let before: Vec<bool> = (fast.invalid.iter().zip(&reference.invalid))
        .map(|(&a, &b)| (a == 0) != (b == 0))
        .collect();
    flag_mixed_pixels(solver, &params, fast);
    flag_mixed_pixels(solver, &params, reference);
    let (w, h) = (fast.width, fast.height);
    let mixed = |out: &DecodeOutput, p: usize| out.invalid[p] & invalid::MIXED != 0;
    let both = |x: usize, y: usize| {
        let p = y * w + x;
        (mixed(fast, p) && mixed(reference, p)) || before[p]
    };
    let (mut marked, mut differs) = (0usize, 0usize);
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            marked += usize::from(mixed(reference, p));
            if mixed(fast, p) == mixed(reference, p) {
                continue;
            }
            differs += 1;
            let near_edge = (y.saturating_sub(2)..(y + 3).min(h))
                .any(|yy| (x.saturating_sub(2)..(x + 3).min(w)).any(|xx| both(xx, yy)));
            assert!(near_edge, "pixel ({x}, {y}) marked mixed on one path only");
        }
    }
    eprintln!("mixed: {marked} marked, {differs} differ");
    assert!(marked > 0, "the hand's outline has mixed pixels");
    assert!(differs * 1000 <= w * h, "mixed marks differ on {differs}");
}

/// Per pixel: whether it lies at a depth edge of `reference`: within three pixels of one that
/// the mixed-pixel stage marks there (it marks the pixels touching the edge, so this is four
/// pixels from the edge itself, about the reach of the smoothing's links across it).
fn depth_edges(
    solver: &WindowSolver,
    params: &DecodeParams,
    reference: &DecodeOutput,
) -> Vec<bool> {
    use tremorscan::decode::{edges::flag_mixed_pixels, invalid};
    let mut marked = reference.clone();
    let params = DecodeParams {
        mixed_limit_px: DecodeParams::default().mixed_limit_px,
        ..*params
    };
    flag_mixed_pixels(solver, &params, &mut marked);
    let (w, h) = (marked.width, marked.height);
    let mixed = |x: usize, y: usize| marked.invalid[y * w + x] & invalid::MIXED != 0;
    (0..w * h)
        .map(|p| {
            let (x, y) = (p % w, p / w);
            (y.saturating_sub(3)..(y + 4).min(h))
                .any(|yy| (x.saturating_sub(3)..(x + 4).min(w)).any(|xx| mixed(xx, yy)))
        })
        .collect()
}

/// A pixel valid on one path and not on the other must sit on a threshold: the two paths differ
/// by rounding only. At a depth edge the support of the robust coarse estimate may also flip:
/// the edge-aware filter links two neighbours by a threshold on their phase difference, which
/// the two surfaces' pixels straddle. The per-pixel (paper) coarse coordinate goes through `acos`, whose slope
/// grows without bound near the ends of the range, so there 1e-5 rad of phase rounding moves it
/// by up to about 0.1 px, and the eq. 8 rounding residual by up to 0.1/14 ≈ 0.007 of a period.
fn borderline(
    solver: &WindowSolver,
    params: &DecodeParams,
    reference: &DecodeOutput,
    p: usize,
    fast_reason: u16,
    at_depth_edge: bool,
) {
    use tremorscan::decode::invalid;
    let changed = fast_reason ^ reference.invalid[p];
    let mut allowed = invalid::UNWRAP_MARGIN | invalid::ORDER_JUMP;
    if at_depth_edge {
        allowed |= invalid::LOW_SUPPORT;
    }
    assert_eq!(
        changed & !allowed,
        0,
        "pixel {p}: reasons {fast_reason} (fast) and {} (reference)",
        reference.invalid[p]
    );
    // Where the support flipped, the filter linked different neighbours on the two paths, so
    // the coarse estimates differ and the rounding margin may flip anywhere.
    if changed & invalid::UNWRAP_MARGIN != 0 && changed & invalid::LOW_SUPPORT == 0 {
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
