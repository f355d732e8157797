//! Stage 5: mixed pixels at depth edges.
//!
//! A real lens blurs, so a camera pixel on the outline of a finger over the table sees the
//! fringes of both surfaces. Its phasors are sums of two that code different projector
//! coordinates; where one surface dominates, the Chebyshev relation still nearly holds and the
//! pixel decodes to a coordinate between the two, or to the far surface's, and passes every
//! per-pixel test. On the rig with the camera's blur ([`crate::rig::optics`]) such pixels were
//! 0.09 % of the valid ones at 960×600, all on the outline, up to 20 mm off.
//!
//! What gives them away is their neighbourhood: on one surface the coordinate is smooth, so the
//! two pixels on either side of a pixel, along a row or a column, extrapolate linearly to the
//! same value at the pixel (`2·x(p−1) − x(p−2)` and `2·x(p+1) − x(p+2)`), however steep the
//! surface. Across a depth edge they extrapolate two different surfaces. A pixel is marked
//! [`invalid::MIXED`] when, along either axis,
//!
//! * both sides have two valid pixels and their extrapolations differ by more than the limit
//!   (the pixel sits between two neighbourhoods that disagree), or
//! * only one side has, and the pixel's own coordinate differs from that side's extrapolation by
//!   more than the limit (it borders invalid pixels and disagrees with the surface it touches).
//!
//! The first rule marks the two pixels on each side of every depth edge whose coordinate step is
//! larger than the limit: they are the ones the blur mixes. The limit is the larger of
//! [`super::DecodeParams::mixed_limit_px`] (1.5 projector px, below the step of a 2 mm depth
//! error at the rig's distance, 1.8 px) and [`NOISE_SIGMAS`] standard deviations of the
//! compared difference, predicted per pixel from the coordinate's noise: `σ_x² = σ²/Σ (f_i·a_i/g_i)²`
//! over the frequency slots (amplitude `a_i`, noise gain `g_i`, camera noise `σ`: the configured
//! level or the higher one the window's Chebyshev residuals show, [`super::motion_noise`]). On a
//! well-lit surface at σ = 2 the noise term is about 0.7 px and the fixed limit rules; on dark
//! skin or a noisier camera the noise term takes over, so that noise is not taken for an edge
//! (at σ = 4 on the rig a fixed 1.5 px refused 5 % of the lit pixels).
//!
//! The stage runs on the host after every backend, on the final coordinates and flags, so the
//! CPU and GPU decoders mark the same pixels.

use super::{invalid, motion_noise, DecodeOutput, DecodeParams, WindowSolver};
use rayon::prelude::*;

/// Standard deviations of the predicted noise a disagreement must exceed.
pub const NOISE_SIGMAS: f32 = 5.0;

/// The linear extrapolation to a pixel from its valid neighbours at one and two steps on one
/// side, with its variance, or `None` when either is invalid or outside the image.
#[inline]
fn extrapolate(
    coord: &[f32],
    var: &[f32],
    flags: &[u16],
    near: Option<usize>,
    far: Option<usize>,
) -> Option<(f32, f32)> {
    let (near, far) = (near?, far?);
    (flags[near] == 0 && flags[far] == 0)
        .then(|| (2.0 * coord[near] - coord[far], 4.0 * var[near] + var[far]))
}

/// Whether pixel `p` disagrees with its neighbourhood along one axis: `before` and `after`
/// hold the pixels one and two steps away on each side.
#[inline]
fn disagrees(
    (coord, var, flags): (&[f32], &[f32], &[u16]),
    p: usize,
    before: [Option<usize>; 2],
    after: [Option<usize>; 2],
    limit_px: f32,
) -> bool {
    let left = extrapolate(coord, var, flags, before[0], before[1]);
    let right = extrapolate(coord, var, flags, after[0], after[1]);
    let beyond = |difference: f32, variance: f32| {
        let sigmas = NOISE_SIGMAS * NOISE_SIGMAS * variance;
        // NaN variance (no amplitude) never hides a difference.
        difference.abs() > limit_px && !(difference * difference <= sigmas)
    };
    match (left, right) {
        (Some((l, vl)), Some((r, vr))) => beyond(l - r, vl + vr),
        (Some((s, vs)), None) | (None, Some((s, vs))) => beyond(coord[p] - s, vs + var[p]),
        (None, None) => false,
    }
}

/// Writes into `var` (one value per pixel) the variance of each pixel's combined coordinate,
/// px², for camera noise `noise_gray`.
fn coordinate_variance(
    solver: &WindowSolver,
    out: &DecodeOutput,
    noise_gray: f32,
    var: &mut [f32],
) {
    let (w, nf) = (out.width, out.frequencies);
    let weight: Vec<f32> = (0..nf)
        .map(|i| {
            let f = solver.frequency_rad_per_px[i] / solver.noise_gain[i];
            f * f
        })
        .collect();
    let noise2 = noise_gray * noise_gray;
    var.par_chunks_mut(w)
        .zip(out.amplitude.par_chunks(w * nf))
        .for_each(|(row, amp)| {
            for (x, v) in row.iter_mut().enumerate() {
                let total: f32 = (0..nf).map(|i| weight[i] * amp[i * w + x].powi(2)).sum();
                *v = noise2 / total;
            }
        });
}

/// Marks the mixed pixels of `out` (see the module header); a `mixed_limit_px` that is not
/// positive disables the stage.
pub fn flag_mixed_pixels(solver: &WindowSolver, params: &DecodeParams, out: &mut DecodeOutput) {
    let limit_px = params.mixed_limit_px;
    if !(limit_px > 0.0) {
        return;
    }
    let (w, h) = (out.width, out.height);
    let mut scratch = std::mem::take(&mut out.noise_scratch);
    let measured = motion_noise::residual_noise_gray(solver, out, &mut scratch);
    out.noise_scratch = scratch;
    let noise_gray = measured.map_or(params.camera_noise_gray, |m| {
        m.max(params.camera_noise_gray)
    });
    let mut var = std::mem::take(&mut out.smooth_tmp);
    var.resize(var.len().max(w * h), 0.0);
    coordinate_variance(solver, out, noise_gray, &mut var[..w * h]);
    // One typical variance for the window: the median over a grid of valid pixels. A pixel's
    // own amplitude would not do: mixing two fringes lowers it, and with it the very pixels to
    // refuse would be excused as noisy.
    let mut scratch = std::mem::take(&mut out.noise_scratch);
    scratch.clear();
    for y in (motion_noise::GRID_STEP_PX / 2..h).step_by(motion_noise::GRID_STEP_PX) {
        for x in (motion_noise::GRID_STEP_PX / 2..w).step_by(motion_noise::GRID_STEP_PX) {
            let p = y * w + x;
            if out.invalid[p] == 0 && var[p].is_finite() {
                scratch.push(var[p]);
            }
        }
    }
    let typical = if scratch.is_empty() {
        0.0
    } else {
        let mid = scratch.len() / 2;
        *scratch.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    out.noise_scratch = scratch;
    var[..w * h].fill(typical);
    let planes = (&out.coordinate_px[..], &var[..w * h], &out.invalid[..]);
    let marks = &mut out.jump;
    marks.clear();
    marks.resize(w * h, 0);
    marks.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let up = |k: usize| y.checked_sub(k).map(|yy| yy * w);
        let down = |k: usize| (y + k < h).then(|| (y + k) * w);
        for (x, mark) in row.iter_mut().enumerate() {
            let p = y * w + x;
            if planes.2[p] != 0 {
                continue;
            }
            let left = |k: usize| x.checked_sub(k).map(|xx| y * w + xx);
            let right = |k: usize| (x + k < w).then(|| p + k);
            let column = |row: Option<usize>| row.map(|r| r + x);
            let horizontal = disagrees(
                planes,
                p,
                [left(1), left(2)],
                [right(1), right(2)],
                limit_px,
            );
            let vertical = disagrees(
                planes,
                p,
                [column(up(1)), column(up(2))],
                [column(down(1)), column(down(2))],
                limit_px,
            );
            *mark = u8::from(horizontal || vertical);
        }
    });
    out.smooth_tmp = var;
    for ((flag, c), &mark) in out
        .invalid
        .iter_mut()
        .zip(out.coordinate_px.iter_mut())
        .zip(out.jump.iter())
    {
        if mark != 0 {
            *flag |= invalid::MIXED;
            *c = f32::NAN;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::rig::RigConfig;

    fn solver() -> WindowSolver {
        let config = RigConfig::paper(64, 40).expect("rig");
        let seq = config.default_sequence().expect("sequence");
        WindowSolver::new(&seq, &[0, 1, 2], &config.cross_talk).expect("solver")
    }

    /// An output of `w × h` valid, well-lit pixels whose coordinate is `f(x, y)`.
    fn output(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> DecodeOutput {
        let mut out = DecodeOutput::new(w, h, &solver());
        for y in 0..h {
            for x in 0..w {
                out.coordinate_px[y * w + x] = f(x, y);
            }
        }
        out.amplitude.fill(100.0);
        out.invalid.fill(0);
        out
    }

    fn flag(out: &mut DecodeOutput, limit_px: f32) {
        let params = DecodeParams {
            mixed_limit_px: limit_px,
            ..DecodeParams::default()
        };
        flag_mixed_pixels(&solver(), &params, out);
    }

    fn marked(out: &DecodeOutput) -> Vec<(usize, usize)> {
        (0..out.width * out.height)
            .filter(|&p| out.invalid[p] & invalid::MIXED != 0)
            .map(|p| (p % out.width, p / out.width))
            .collect()
    }

    #[test]
    fn a_steep_smooth_surface_is_not_an_edge() {
        // 6 px per pixel along x, a gentle curve along y: nothing to mark.
        let mut out = output(20, 12, |x, y| 6.0 * x as f32 + 0.02 * (y * y) as f32);
        flag(&mut out, 1.5);
        assert!(marked(&out).is_empty());
    }

    fn columns(out: &DecodeOutput) -> std::collections::BTreeSet<usize> {
        marked(out).iter().map(|&(x, _)| x).collect()
    }

    #[test]
    fn the_two_pixels_each_side_of_a_depth_step_are_marked() {
        // A step of 18 px (about 20 mm) between columns 9 and 10.
        let mut out = output(
            20,
            8,
            |x, _| if x < 10 { x as f32 } else { 18.0 + x as f32 },
        );
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), (8..=11).collect());
        // A mixed pixel at column 9, two thirds of the way: it and its neighbours.
        let mut out = output(20, 8, |x, _| match x {
            0..=8 => x as f32,
            9 => 21.0,
            _ => 18.0 + x as f32,
        });
        flag(&mut out, 1.5);
        assert!(out.coordinate_px[9].is_nan());
        assert_eq!(columns(&out), (7..=11).collect());
        // A step below the limit is a surface.
        let mut out = output(20, 8, |x, _| if x < 10 { x as f32 } else { 1.2 + x as f32 });
        flag(&mut out, 1.5);
        assert!(columns(&out).is_empty());
    }

    #[test]
    fn a_pixel_bordering_invalid_ones_is_checked_against_its_side() {
        // Column 5 decoded to the far surface; columns 6.. invalid.
        let mut out = output(12, 6, |x, _| if x == 5 { 25.0 } else { x as f32 });
        for y in 0..6 {
            for x in 6..12 {
                out.invalid[y * 12 + x] = invalid::DISAGREEMENT;
            }
        }
        flag(&mut out, 1.5);
        // Column 5 against its left side. Column 4 has no right side (5, 6), and agrees with
        // its left; column 3 lies between 1–2 and the extrapolation through 4 and 5.
        assert_eq!(columns(&out), [3, 5].into_iter().collect());
    }

    #[test]
    fn a_noisy_coordinate_needs_a_larger_disagreement() {
        // A 3 px step: an edge at amplitude 100, noise at amplitude 2 (σ_x ≈ 0.7 px, so five
        // standard deviations of the extrapolations' difference exceed 3 px).
        let step = |x: usize, _| if x < 10 { 0.0 } else { 3.0 };
        let mut out = output(20, 8, step);
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), (8..=11).collect());
        let mut out = output(20, 8, step);
        out.amplitude.fill(2.0);
        flag(&mut out, 1.5);
        assert!(columns(&out).is_empty());
    }

    #[test]
    fn a_limit_of_zero_disables_the_stage() {
        let mut out = output(12, 6, |x, _| if x < 6 { 0.0 } else { 30.0 });
        flag(&mut out, 0.0);
        assert!(marked(&out).is_empty());
    }
}
