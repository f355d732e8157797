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
//! surface. Across a depth edge they extrapolate two different surfaces. Along either axis a
//! pixel is marked [`invalid::MIXED`] when
//!
//! * both sides have two valid pixels, their extrapolations disagree, and the pixel's own
//!   coordinate either agrees with neither (it lies between the two surfaces) or agrees with one
//!   but its neighbour on the other side disagrees with that surface carried one step on (it is
//!   the last pixel before the edge, the one the blur mixes most, or one that took the far
//!   surface's coordinate); or
//! * only one side has two valid pixels and the pixel's coordinate disagrees with that side's
//!   extrapolation, or its fringe amplitude (summed over the frequencies) is below
//!   [`MIN_AMPLITUDE_RATIO`] of the amplitude two pixels into that side: it borders pixels
//!   without a code, and is either off the surface it touches or lit only by the blur of that
//!   surface's light (a pixel of a cast shadow next to a finger's outline, whose code is the
//!   finger's), or the other side's pixels two and three steps away, across a one-pixel gap,
//!   extrapolate to another surface (the gap is the edge, and the pixel touches it).
//!
//! The test runs twice: once on every pixel, then, with the first pass's marks applied, on the
//! valid pixels beside them, which may now border pixels without a code and take the one-sided
//! test. That second look catches a one-pixel sliver (a gap between two fingers, seeing the
//! table in shadow) lit only by the blur of the surfaces on either side: their codes agree, so
//! the sliver passes the first pass, and the first pass refuses the last pixel of each surface.
//! With the wider coarse average of [`super::SmoothingParams::transport`] two such pixels on
//! the still hand's table at σ = 2 decoded, 2.4 mm off.
//!
//! So at a depth edge whose coordinate step exceeds the limit the two pixels touching the edge
//! are refused, and any in between; the pixels one step further in, which agree with their own
//! surface, are kept. Refusing every pixel whose sides disagree (two each side of the edge)
//! made up as few points but cost 0.75 points of the moving skin's coverage at a 10 mm tremor,
//! at the edges between fingers, for nothing: those pixels were right.
//!
//! "Disagree" means by more than the larger of [`super::DecodeParams::mixed_limit_px`] (1.5
//! projector px, below the step of a 2 mm depth error at the rig's distance, 1.8 px) and
//! [`NOISE_SIGMAS`] standard deviations of the compared difference, predicted from the
//! coordinate's noise `σ_x² = σ²/Σ (f_i·a_i/g_i)²` over the frequency slots (amplitude `a_i`,
//! noise gain `g_i`, camera noise `σ`: the configured level or the higher one the window's
//! Chebyshev residuals show, [`super::motion_noise`]), taken at its median over a grid of valid
//! pixels. A pixel's own amplitude would not do: mixing two fringes lowers it, and with it the
//! very pixels to refuse would be excused as noisy. On a well-lit surface at σ = 2 the noise
//! term is about 0.7 px and the fixed limit rules; on dark skin or a noisier camera the noise
//! term takes over, so that noise is not taken for an edge (at σ = 4 on the rig a fixed 1.5 px
//! refused 5 % of the lit pixels).
//!
//! Almost every pixel has four valid neighbours on each axis that agree within the fixed limit;
//! a branch-free pass over whole rows (`candidates`) clears those, and the rules above run on
//! the rest. The stage runs on the host after every backend, on the final coordinates and
//! flags, so the CPU and GPU decoders mark the same pixels.

use super::{invalid, motion_noise, DecodeOutput, DecodeParams, WindowSolver};
use rayon::prelude::*;

/// Standard deviations of the predicted noise a disagreement must exceed.
pub const NOISE_SIGMAS: f32 = 5.0;

/// A pixel bordering pixels without a code whose summed fringe amplitude is below this share of
/// the amplitude two pixels into its valid side is lit by the blur of that side's light. With
/// the lens's blur `σ` and a straight edge half a pixel from the pixel's centre, the share is
/// `Φ(−0.5/s)/Φ(1.5/s)` (`s² = σ² + 1/12`, the pixel's footprint): 0.16 for the rig's default
/// σ = 0.4 px and 0.34 for a soft σ = 1 px lens, against 0.84 and 0.69 for the last pixel of
/// the lit surface.
pub const MIN_AMPLITUDE_RATIO: f32 = 0.5;

/// What the per-pixel test reads: coordinates, flags and summed amplitudes of the window, and
/// its limits.
#[derive(Clone, Copy)]
struct Planes<'a> {
    coord: &'a [f32],
    flags: &'a [u16],
    amplitude: &'a [f32],
    limit_px: f32,
    /// The typical variance of one pixel's coordinate, px².
    var_px2: f32,
}

impl Planes<'_> {
    /// Whether `difference`, whose variance is `k` times a pixel's, is a disagreement. A NaN
    /// variance (no valid pixel to take it from) never hides one.
    #[inline]
    fn beyond(&self, difference: f32, k: f32) -> bool {
        let noise_px2 = NOISE_SIGMAS * NOISE_SIGMAS * k * self.var_px2;
        difference.abs() > self.limit_px
            && (noise_px2.is_nan() || difference * difference > noise_px2)
    }

    /// The linear extrapolation to a pixel from its neighbours one and two steps away on one
    /// side (variance 5 pixels'), or `None` when either is invalid or outside the image.
    #[inline]
    fn extrapolate(&self, near: Option<usize>, far: Option<usize>) -> Option<f32> {
        let (near, far) = (near?, far?);
        (self.flags[near] == 0 && self.flags[far] == 0)
            .then(|| 2.0 * self.coord[near] - self.coord[far])
    }

    /// The extrapolation to a pixel across a one-pixel gap: its neighbour one step away on a
    /// side is invalid, those two and three steps away valid (variance 13 pixels').
    #[inline]
    fn across_gap(&self, side: [Option<usize>; 3]) -> Option<f32> {
        let (gap, near, far) = (side[0]?, side[1]?, side[2]?);
        (self.flags[gap] != 0 && self.flags[near] == 0 && self.flags[far] == 0)
            .then(|| 3.0 * self.coord[near] - 2.0 * self.coord[far])
    }

    /// Whether pixel `p` is mixed along one axis: `before` and `after` hold the pixels one, two
    /// and three steps away on each side.
    #[inline]
    fn mixed(&self, p: usize, before: [Option<usize>; 3], after: [Option<usize>; 3]) -> bool {
        let c = self.coord[p];
        let left = self.extrapolate(before[0], before[1]);
        let right = self.extrapolate(after[0], after[1]);
        match (left, right, before[0], after[0]) {
            (Some(l), Some(r), Some(b), Some(a)) => {
                if !self.beyond(l - r, 10.0) {
                    return false;
                }
                // The neighbour `next`, against the surface through `prev` and `p`.
                let steps_off = |prev: usize, next: usize| {
                    self.beyond(self.coord[next] - (2.0 * c - self.coord[prev]), 6.0)
                };
                match (!self.beyond(c - l, 6.0), !self.beyond(c - r, 6.0)) {
                    (false, false) => true,
                    (true, false) => steps_off(b, a),
                    (false, true) => steps_off(a, b),
                    (true, true) => false,
                }
            }
            (Some(s), None, ..) => self.one_sided(p, s, before[1], after),
            (None, Some(s), ..) => self.one_sided(p, s, after[1], before),
            _ => false,
        }
    }

    /// The test of a pixel with two valid pixels on one side only: `s` is that side's
    /// extrapolation, `inner` its pixel two steps away, `other` the other side's pixels.
    #[inline]
    fn one_sided(&self, p: usize, s: f32, inner: Option<usize>, other: [Option<usize>; 3]) -> bool {
        let off_its_side = self.beyond(self.coord[p] - s, 6.0);
        let edge_across_gap = self
            .across_gap(other)
            .is_some_and(|g| self.beyond(g - s, 18.0));
        let dim =
            inner.is_some_and(|q| self.amplitude[p] < MIN_AMPLITUDE_RATIO * self.amplitude[q]);
        off_its_side || edge_across_gap || dim
    }
}

/// Sets `row` (row `y`) to 1 where a pixel needs the general test and 0 where the fast path
/// clears it: a pixel at least two pixels from the image's border whose four neighbours on
/// each axis are valid and extrapolate to it within the fixed limit along both axes (the noise
/// term only raises the limit, so neither axis can mark it). Branch-free over whole rows, so
/// that it vectorises; on the rig it leaves about one pixel in twenty to the general test.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn candidates(planes: &Planes<'_>, y: usize, w: usize, h: usize, row: &mut [u8]) {
    row.fill(1);
    if y < 2 || y + 2 >= h || w < 5 {
        return;
    }
    let line = |k: usize| {
        let start = (y + k - 2) * w;
        (
            &planes.coord[start..start + w],
            &planes.flags[start..start + w],
        )
    };
    let [(c0, f0), (c1, f1), (c2, f2), (c3, f3), (c4, f4)] = [0, 1, 2, 3, 4].map(line);
    let limit = planes.limit_px;
    let n = w - 4;
    let out = &mut row[2..2 + n];
    for x in 0..n {
        let flags = (f2[x] | f2[x + 1] | f2[x + 3] | f2[x + 4])
            | (f0[x + 2] | f1[x + 2] | f3[x + 2] | f4[x + 2]);
        let horizontal = (2.0 * c2[x + 1] - c2[x]) - (2.0 * c2[x + 3] - c2[x + 4]);
        let vertical = (2.0 * c1[x + 2] - c0[x + 2]) - (2.0 * c3[x + 2] - c4[x + 2]);
        let clear = (flags == 0) & (horizontal.abs() <= limit) & (vertical.abs() <= limit);
        out[x] = u8::from(!clear);
    }
}

/// The median, over a grid of valid pixels, of the variance of a pixel's combined coordinate
/// for camera noise `noise_gray`, px² (NaN with no valid pixel on the grid).
fn typical_variance(
    solver: &WindowSolver,
    out: &DecodeOutput,
    noise_gray: f32,
    scratch: &mut Vec<f32>,
) -> f32 {
    let (w, h, nf) = (out.width, out.height, out.frequencies);
    let weight: Vec<f32> = (0..nf)
        .map(|i| {
            let f = solver.frequency_rad_per_px[i] / solver.noise_gain[i];
            f * f
        })
        .collect();
    let step = motion_noise::GRID_STEP_PX;
    scratch.clear();
    for y in (step / 2..h).step_by(step) {
        let amp = &out.amplitude[y * w * nf..(y + 1) * w * nf];
        for x in (step / 2..w).step_by(step) {
            if out.invalid[y * w + x] != 0 {
                continue;
            }
            let total: f32 = (0..nf).map(|i| weight[i] * amp[i * w + x].powi(2)).sum();
            let var = noise_gray * noise_gray / total;
            if var.is_finite() {
                scratch.push(var);
            }
        }
    }
    if scratch.is_empty() {
        return f32::NAN;
    }
    let mid = scratch.len() / 2;
    *scratch.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// Writes each pixel's fringe amplitude summed over the frequencies into `summed`.
fn summed_amplitude(out: &DecodeOutput, summed: &mut [f32]) {
    let (w, nf) = (out.width, out.frequencies);
    summed
        .par_chunks_mut(w)
        .zip(out.amplitude.par_chunks(w * nf))
        .for_each(|(row, amp)| {
            let mut planes = amp.chunks_exact(w);
            match planes.next() {
                Some(first) => row.copy_from_slice(first),
                None => row.fill(0.0),
            }
            for plane in planes {
                for (total, a) in row.iter_mut().zip(plane) {
                    *total += a;
                }
            }
        });
}

/// Marks the mixed pixels of `out` (see the module header); a `mixed_limit_px` that is not
/// positive disables the stage.
pub fn flag_mixed_pixels(solver: &WindowSolver, params: &DecodeParams, out: &mut DecodeOutput) {
    let mut scratch = std::mem::take(&mut out.noise_scratch);
    let measured = motion_noise::residual_noise_gray(solver, out, &mut scratch);
    out.noise_scratch = scratch;
    flag_mixed_pixels_with_noise(solver, params, measured, out);
}

/// [`flag_mixed_pixels`] with the noise level the window's final phases show already measured
/// (`measured_noise_gray`, as [`motion_noise::residual_noise_gray`] measures it): a backend that
/// does not hand its phases back (the GPU decode) measures it where they are.
pub fn flag_mixed_pixels_with_noise(
    solver: &WindowSolver,
    params: &DecodeParams,
    measured_noise_gray: Option<f32>,
    out: &mut DecodeOutput,
) {
    let limit_px = params.mixed_limit_px;
    if limit_px.is_nan() || limit_px <= 0.0 {
        return;
    }
    let (w, h) = (out.width, out.height);
    let mut scratch = std::mem::take(&mut out.noise_scratch);
    let noise_gray =
        motion_noise::significance_noise_gray(measured_noise_gray, params.camera_noise_gray);
    let var_px2 = typical_variance(solver, out, noise_gray, &mut scratch);
    out.noise_scratch = scratch;
    let mut amplitude = std::mem::take(&mut out.smooth_tmp);
    amplitude.resize(amplitude.len().max(w * h), 0.0);
    summed_amplitude(out, &mut amplitude[..w * h]);
    let amplitude_plane = &amplitude[..w * h];
    // First every pixel the fast path does not clear; then, with those marks applied, the
    // valid pixels beside them once more.
    for pass in [Pass::First, Pass::BesideMarks] {
        let planes = Planes {
            coord: &out.coordinate_px,
            flags: &out.invalid,
            amplitude: amplitude_plane,
            limit_px,
            var_px2,
        };
        let marks = &mut out.jump;
        marks.clear();
        marks.resize(w * h, 0);
        let any = marks
            .par_chunks_mut(w)
            .enumerate()
            .map(|(y, row)| mark_row(&planes, pass, y, w, h, row))
            .reduce(|| false, |a, b| a || b);
        if !any {
            break;
        }
        apply_marks(out);
    }
    out.smooth_tmp = amplitude;
}

/// Which pixels a pass of the mixed test examines.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Every valid pixel the fast path ([`candidates`]) does not clear.
    First,
    /// Every valid pixel with a neighbour the first pass marked: where that neighbour was one
    /// of its two pixels on a side, the pixel now borders pixels without a code on that side
    /// and takes the one-sided test. A one-pixel sliver of surface between two marked pixels
    /// (a gap between two fingers seen through the blur of both) passes the first pass, whose
    /// extrapolations from either side agree, and is refused here when the blur alone lights it.
    BesideMarks,
}

/// Writes the marks of one row of `pass` into `row` (row `y`); whether it marked any.
fn mark_row(planes: &Planes<'_>, pass: Pass, y: usize, w: usize, h: usize, row: &mut [u8]) -> bool {
    let flags = planes.flags;
    match pass {
        Pass::First => candidates(planes, y, w, h, row),
        Pass::BesideMarks => beside_marks(flags, y, w, h, row),
    }
    keep_valid(row, &flags[y * w..(y + 1) * w]);
    let up = |k: usize| y.checked_sub(k).map(|yy| yy * w);
    let down = |k: usize| (y + k < h).then(|| (y + k) * w);
    let mut any = false;
    // Most of a row is cleared: whole runs of [`SKIP_RUN`] empty marks are stepped over.
    for (run, marks) in row.chunks_mut(SKIP_RUN).enumerate() {
        // An OR over the run, with no early exit, so that it vectorises.
        if marks.iter().fold(0, |any, &m| any | m) == 0 {
            continue;
        }
        for (i, mark) in marks.iter_mut().enumerate() {
            if *mark == 0 {
                continue;
            }
            let x = run * SKIP_RUN + i;
            let p = y * w + x;
            let left = |k: usize| x.checked_sub(k).map(|xx| y * w + xx);
            let right = |k: usize| (x + k < w).then(|| p + k);
            let column = |row: Option<usize>| row.map(|r| r + x);
            let horizontal = planes.mixed(p, [1, 2, 3].map(left), [1, 2, 3].map(right));
            let vertical = planes.mixed(
                p,
                [1, 2, 3].map(|k| column(up(k))),
                [1, 2, 3].map(|k| column(down(k))),
            );
            *mark = u8::from(horizontal || vertical);
            any |= horizontal || vertical;
        }
    }
    any
}

/// Marks a run of the general test's loop steps over when none is set.
const SKIP_RUN: usize = 32;

/// Clears the marks of pixels that are already invalid: only valid pixels are tested. A loop
/// of its own, without branches, so that it vectorises.
fn keep_valid(row: &mut [u8], flags: &[u16]) {
    for (mark, &f) in row.iter_mut().zip(flags) {
        *mark &= u8::from(f == 0);
    }
}

/// Sets `row` (row `y`) to 1 where a pixel has a 4-neighbour marked [`invalid::MIXED`], else 0.
/// Branch-free over whole rows, so that it vectorises: the second look runs on every row.
fn beside_marks(flags: &[u16], y: usize, w: usize, h: usize, row: &mut [u8]) {
    let line = |yy: usize| &flags[yy * w..(yy + 1) * w];
    let own = line(y);
    let mixed = |f: u16| f & invalid::MIXED;
    let vertical = |row: &mut [u8], other: &[u16]| {
        for (mark, &f) in row.iter_mut().zip(other) {
            *mark |= u8::from(mixed(f) != 0);
        }
    };
    row.fill(0);
    if y > 0 {
        vertical(row, line(y - 1));
    }
    if y + 1 < h {
        vertical(row, line(y + 1));
    }
    if w > 1 {
        for (mark, pair) in row[1..].iter_mut().zip(own.windows(2)) {
            *mark |= u8::from(mixed(pair[0]) != 0);
        }
        for (mark, pair) in row[..w - 1].iter_mut().zip(own.windows(2)) {
            *mark |= u8::from(mixed(pair[1]) != 0);
        }
    }
}

/// Sets [`invalid::MIXED`] and a NaN coordinate where `out.jump` holds a mark.
fn apply_marks(out: &mut DecodeOutput) {
    let w = out.width;
    out.invalid
        .par_chunks_mut(w)
        .zip(out.coordinate_px.par_chunks_mut(w))
        .zip(out.jump.par_chunks(w))
        .for_each(|((flags, coord), marks)| {
            for ((flag, c), &mark) in flags.iter_mut().zip(coord).zip(marks) {
                if mark != 0 {
                    *flag |= invalid::MIXED;
                    *c = f32::NAN;
                }
            }
        });
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
    fn the_pixels_touching_a_depth_step_are_marked() {
        // A step of 18 px (about 20 mm) between columns 9 and 10: the two pixels touching it;
        // columns 8 and 11 agree with their own surfaces and are kept.
        let mut out = output(
            20,
            8,
            |x, _| if x < 10 { x as f32 } else { 18.0 + x as f32 },
        );
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), [9, 10].into_iter().collect());
        // A mixed pixel at column 9, two thirds of the way: it and the two touching it.
        let mut out = output(20, 8, |x, _| match x {
            0..=8 => x as f32,
            9 => 21.0,
            _ => 18.0 + x as f32,
        });
        flag(&mut out, 1.5);
        assert!(out.coordinate_px[9].is_nan());
        assert_eq!(columns(&out), (8..=10).collect());
        // A pixel that took the far surface's coordinate (column 9 on the right's surface):
        // it and its neighbour on the near side, across the jump.
        let mut out = output(20, 8, |x, _| if x < 9 { x as f32 } else { 18.0 + x as f32 });
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), [8, 9].into_iter().collect());
        // A step below the limit is a surface.
        let mut out = output(20, 8, |x, _| if x < 10 { x as f32 } else { 1.2 + x as f32 });
        flag(&mut out, 1.5);
        assert!(columns(&out).is_empty());
    }

    /// Marks columns `from..` of every row of `out` invalid.
    fn invalid_from(out: &mut DecodeOutput, from: usize) {
        let w = out.width;
        for (p, flag) in out.invalid.iter_mut().enumerate() {
            if p % w >= from {
                *flag = invalid::DISAGREEMENT;
            }
        }
    }

    #[test]
    fn a_pixel_bordering_invalid_ones_is_checked_against_its_side() {
        // Column 5 decoded to the far surface; columns 6.. invalid. Column 5 is off its left
        // side's extrapolation; column 4 (no right side) and column 3 (whose right side runs
        // through 5) agree with their surface and are kept.
        let mut out = output(12, 6, |x, _| if x == 5 { 25.0 } else { x as f32 });
        invalid_from(&mut out, 6);
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), [5].into_iter().collect());
    }

    #[test]
    fn a_pixel_lit_only_by_the_blur_is_refused() {
        // Column 5 borders invalid pixels (a shadow) and has the coordinate of its surface,
        // but a third of the fringe amplitude two pixels in: the blur's light, not its own.
        let dim = |amplitude: f32| {
            let mut out = output(12, 6, |x, _| x as f32);
            invalid_from(&mut out, 6);
            let (w, nf) = (out.width, out.frequencies);
            for y in 0..out.height {
                for i in 0..nf {
                    out.amplitude[y * nf * w + i * w + 5] = amplitude;
                }
            }
            flag(&mut out, 1.5);
            columns(&out)
        };
        assert_eq!(dim(30.0), [5].into_iter().collect());
        // The last pixel of a lit surface keeps most of its light.
        assert!(dim(70.0).is_empty());
    }

    #[test]
    fn an_edge_across_a_one_pixel_gap_refuses_the_pixels_beside_the_gap() {
        // Column 5 invalid between two surfaces 25 px apart: columns 4 and 6 each touch the
        // other surface through the blur.
        let mut out = output(12, 6, |x, _| if x < 5 { x as f32 } else { 25.0 + x as f32 });
        for y in 0..6 {
            out.invalid[y * 12 + 5] = invalid::UNWRAP_MARGIN;
        }
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), [4, 6].into_iter().collect());
        // One invalid pixel on a smooth surface is no edge.
        let mut out = output(12, 6, |x, _| x as f32);
        for y in 0..6 {
            out.invalid[y * 12 + 5] = invalid::UNWRAP_MARGIN;
        }
        flag(&mut out, 1.5);
        assert!(columns(&out).is_empty());
    }

    #[test]
    fn a_noisy_coordinate_needs_a_larger_disagreement() {
        // A 3 px step: an edge at amplitude 100, noise at amplitude 2 (σ_x ≈ 0.7 px, so five
        // standard deviations of the extrapolations' difference exceed 3 px).
        let step = |x: usize, _| if x < 10 { 0.0 } else { 3.0 };
        let mut out = output(20, 8, step);
        flag(&mut out, 1.5);
        assert_eq!(columns(&out), [9, 10].into_iter().collect());
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
