//! The per-pixel kernel of one Gauss–Newton step of the motion model ([`super::motion`]): the
//! patch's `(u, κ)` from its summed evidence, the significance test, the acceleration
//! bookkeeping, and the correction of the pixel's phasors.
//!
//! **Two passes per block of [`BLOCK`] pixels.** Most of a scene is still: in the rig's
//! default window (a 2 mm tremor, 640×400) each step corrects 1.6 % of the pixels. A still
//! pixel that the step before left uncorrected needs no model at all: its phasors stay the
//! still solution, and the step only writes its evidence at rest (or, on the last step, its
//! unit phasor and reasons). The first pass (here) does that for every pixel of the block,
//! branch-free, so that it vectorises as stage 1 does; it solves each pixel's patch system,
//! takes the acceleration, and marks on the stack the pixels that move or were corrected
//! before, leaving their planes as they were. The second pass ([`super::motion_moving`])
//! gathers the marked pixels into arrays, runs the full model over them in one branch-free
//! loop, and copies them back. Both passes vectorise. They write the same values as the single
//! per-pixel loop they replaced, bit for bit (the arithmetic and its order are unchanged;
//! checked by hashing every output plane of ten consecutive windows of three trembling hands,
//! two swaying). That loop branched per pixel on the motion, none of it vectorised, and it
//! took about half of a motion window's time. What kept the compiler from vectorising, found
//! with LLVM's loop-vectorize remarks: `f32::clamp`'s check of its bounds (hence [`clamp`]),
//! a slicing helper left out of line (its lengths unknown, so every index checked), loops over
//! the three slots, and the filled count of the gathered arrays.

use super::fastmath::{sin_cos_phase, whole_to_flags};
use super::invalid;
use super::motion::{acceleration_onset, StepKind, MOTION_SIGNIFICANCE};
use super::motion_basis::MotionBasis;
use super::motion_evidence::{chebyshev3_of, evidence, inconsistent};
use super::motion_moving::{copy_pixel, correct_gathered, Gathered};

/// Pixels per block: the marks of a block sit on the stack between its two passes.
pub(super) const BLOCK: usize = 64;

/// What one Gauss–Newton step of [`correct_row`] needs.
pub(super) struct Step<'a> {
    pub(super) basis: &'a MotionBasis,
    pub(super) gain2: (f32, f32, f32),
    /// χ² limit times the noise variance.
    pub(super) limit: f32,
    pub(super) min_amplitude: f32,
    pub(super) kind: StepKind,
    /// The priors' information in the units of the evidence (`σ²/sd²`: the evidence is
    /// weighted by `1/var(e)` over the camera noise variance).
    pub(super) prior_u: f32,
    pub(super) prior_k: f32,
    /// `1/σ²` of the camera noise.
    pub(super) inv_noise2: f32,
    /// Write the corrected unit phasor and reasons (else the next step's evidence).
    pub(super) last: bool,
    /// `1/Δt` to the previous window with patch velocities (0: none, no acceleration).
    pub(super) inv_since: f32,
    /// The largest velocity change over that Δt taken as acceleration, px/s.
    pub(super) max_velocity_change: f32,
    /// The shift of the window's mean coordinate per unit of velocity change, s.
    pub(super) shift_per_velocity_change: f32,
    /// The weight of each pixel's brightness change measured from its lit offsets in the
    /// previous window and this one, beside its patch's (0: the patch's alone;
    /// [`super::MotionParams::offset_brightness_weight`], taken on the last step of a refining
    /// model when the previous window was the one just before).
    pub(super) offset_brightness_weight: f32,
}

/// One row (or one block of a row) of every plane a step reads and writes; every slice has the
/// same length. On the last step `uu`, `uk` and `kk` (the unit phasor's planes) receive the
/// unit phasor and the support.
pub(super) struct RowPlanes<'a> {
    pub(super) phase: [&'a mut [f32]; 3],
    pub(super) amp: [&'a mut [f32]; 3],
    pub(super) offset: [&'a mut [f32]; 3],
    pub(super) uu: &'a mut [f32],
    pub(super) uk: &'a mut [f32],
    pub(super) kk: &'a mut [f32],
    pub(super) ue: &'a mut [f32],
    pub(super) ke: &'a mut [f32],
    pub(super) count: &'a mut [f32],
    pub(super) flags: &'a mut [u16],
    pub(super) velocity: &'a mut [f32],
    pub(super) brightness: &'a mut [f32],
    pub(super) acceleration: &'a mut [f32],
    /// The previous window's patch velocities, replaced by this window's on the last step.
    pub(super) patch_velocity: &'a mut [f32],
    /// Whether the previous window's patch velocity was significant, replaced likewise.
    pub(super) patch_moving: &'a mut [u8],
    /// The previous window's sum of the pixel's lit offsets, replaced by this window's on the
    /// last step.
    pub(super) lit_sum: &'a mut [f32],
}

impl RowPlanes<'_> {
    /// Pixels `start..end` of every plane.
    #[inline(always)]
    fn block(&mut self, start: usize, end: usize) -> RowPlanes<'_> {
        let [p0, p1, p2] = &mut self.phase;
        let [a0, a1, a2] = &mut self.amp;
        let [o0, o1, o2] = &mut self.offset;
        RowPlanes {
            phase: [
                &mut p0[start..end],
                &mut p1[start..end],
                &mut p2[start..end],
            ],
            amp: [
                &mut a0[start..end],
                &mut a1[start..end],
                &mut a2[start..end],
            ],
            offset: [
                &mut o0[start..end],
                &mut o1[start..end],
                &mut o2[start..end],
            ],
            uu: &mut self.uu[start..end],
            uk: &mut self.uk[start..end],
            kk: &mut self.kk[start..end],
            ue: &mut self.ue[start..end],
            ke: &mut self.ke[start..end],
            count: &mut self.count[start..end],
            flags: &mut self.flags[start..end],
            velocity: &mut self.velocity[start..end],
            brightness: &mut self.brightness[start..end],
            acceleration: &mut self.acceleration[start..end],
            patch_velocity: &mut self.patch_velocity[start..end],
            patch_moving: &mut self.patch_moving[start..end],
            lit_sum: &mut self.lit_sum[start..end],
        }
    }
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub(super) fn correct_row(step: &Step<'_>, row: RowPlanes<'_>) {
    // The step's kind and whether it is the last are fixed for the row: each combination is
    // compiled as its own loop, without branches on them per pixel.
    match (step.kind == StepKind::Refine, step.last) {
        (false, false) => correct_row_as::<false, false>(step, row),
        (false, true) => correct_row_as::<false, true>(step, row),
        (true, false) => correct_row_as::<true, false>(step, row),
        (true, true) => correct_row_as::<true, true>(step, row),
    }
}

/// [`correct_row`] for a step that refines (`REFINE`, else from rest) and is the last (`LAST`).
///
/// The marked pixels of successive blocks go into one array of [`BLOCK`] entries, and the
/// full model runs when it is full (and once for the rest at the row's end), so that every run
/// works on a full array rather than on a block's few moving pixels. Gathering across blocks
/// changes nothing: the first pass of a block reads and writes only its own pixels, and never
/// a marked one, so a marked pixel waits unchanged until its run.
#[inline(always)]
fn correct_row_as<const REFINE: bool, const LAST: bool>(step: &Step<'_>, mut row: RowPlanes<'_>) {
    let w = row.flags.len();
    // One per row: the entries past the filled ones hold earlier pixels, worked on and never
    // copied back.
    let mut gathered = Gathered::default();
    let mut m = 0;
    let mut start = 0;
    while start < w {
        let end = (start + BLOCK).min(w);
        let mut marks = [0u8; BLOCK];
        let marks = &mut marks[..end - start];
        still_pass::<REFINE, LAST>(step, &mut row.block(start, end), marks);
        for (x, _) in marks.iter().enumerate().filter(|(_, &mark)| mark != 0) {
            if m == BLOCK {
                run_gathered(step, &mut gathered, m, &mut row);
                m = 0;
            }
            gathered.index[m] = start + x;
            copy_pixel(&row, start + x, &mut gathered.planes(), m);
            m += 1;
        }
        start = end;
    }
    if m > 0 {
        run_gathered(step, &mut gathered, m, &mut row);
    }
    if LAST {
        write_lit_sums(step.basis, &mut row);
    }
}

/// Each pixel's sum of its lit offsets in this window, the offsets as the last step left them
/// (without the fringe the motion leaked into them), for the next window's brightness change
/// ([`super::motion_moving`]). A loop of its own after the row's passes, which read the
/// previous window's sums: written inside the first pass, it kept that pass from vectorising
/// (the motion model's stage took 7.4 → 14 ms on the rig's default hand).
#[inline(always)]
fn write_lit_sums(basis: &MotionBasis, row: &mut RowPlanes<'_>) {
    // Σ_s lit_s = Σ_c (Σ_s unmix[s][c])·(o_c − bias_c), as `motion_moving` sums this window's.
    let (unmix, bias) = (&basis.unmix_of_slot, &basis.bias_gray);
    let column = |c: usize| unmix[0][c] + unmix[1][c] + unmix[2][c];
    let (w0, w1, w2) = (column(0), column(1), column(2));
    let (b0, b1, b2) = (bias[0], bias[1], bias[2]);
    let n = row.lit_sum.len();
    let [o0, o1, o2] = &row.offset;
    let (o0, o1, o2) = (&o0[..n], &o1[..n], &o2[..n]);
    for (x, sum) in row.lit_sum.iter_mut().enumerate() {
        *sum = w0 * (o0[x] - b0) + w1 * (o1[x] - b1) + w2 * (o2[x] - b2);
    }
}

/// The second pass over the first `m` gathered pixels, copied back to their places in `row`.
#[inline(always)]
pub(super) fn run_gathered(
    step: &Step<'_>,
    gathered: &mut Gathered,
    m: usize,
    row: &mut RowPlanes<'_>,
) {
    correct_gathered(step, gathered, m);
    let index = gathered.index;
    let planes = gathered.planes();
    for (j, &x) in index[..m].iter().enumerate() {
        copy_pixel(&planes, j, row, x);
    }
}

/// The patch's `(u, κ)`: the ridge-regularised weighted least squares of `e = D_u·u + D_κ·κ`
/// over its summed evidence, clamped to where the model is defined, and whether it was
/// solvable, within the brightness range and significant.
#[derive(Clone, Copy)]
pub(super) struct PatchStep {
    pub(super) u: f32,
    pub(super) kappa: f32,
    pub(super) solvable: bool,
    pub(super) bright_ok: bool,
    pub(super) moving: bool,
}

#[inline(always)]
pub(super) fn patch_step<const REFINE: bool>(
    step: &Step<'_>,
    row: &RowPlanes<'_>,
    x: usize,
) -> PatchStep {
    let basis = step.basis;
    let (a, b, c) = (
        row.uu[x] + step.prior_u,
        row.uk[x],
        row.kk[x] + step.prior_k,
    );
    let det = a * c - b * b;
    let (ru, rk) = (row.ue[x], row.ke[x]);
    let solvable = (det > 0.0) & (row.count[x] > 0.0);
    let (u0, k0) = if REFINE {
        (row.velocity[x], row.brightness[x])
    } else {
        (0.0, 0.0)
    };
    // The evidence is absolute: its solution is the patch's (u, κ), not a step.
    let (u_new, k_new) = if solvable {
        ((c * ru - b * rk) / det, (a * rk - b * ru) / det)
    } else {
        (u0, k0)
    };
    // Kept where the model is defined, so that the next step's slopes are the model's.
    let kappa_max = basis.max_brightness_rate;
    let u = clamp(u_new, basis.max_velocity);
    let kappa = clamp(k_new, kappa_max);
    // At every step the motion stays only where the patch's evidence shows it: its (u, κ)
    // differ from rest by more than the noise (a χ² of the estimate with two degrees of
    // freedom above `MOTION_SIGNIFICANCE`). Elsewhere (still surfaces, and the ends of the
    // projector's range, where the residual is blind to motion but the unit phase is not) the
    // still solution is kept, and the next step starts from rest. Testing only on the last
    // step let a first step's noise-driven correction pool into a significant-looking second
    // estimate: a still hand at σ = 2 then got 0.56 % wrong fringe orders.
    let significance = (a * u * u + 2.0 * b * u * kappa + c * kappa * kappa) * step.inv_noise2;
    PatchStep {
        u,
        kappa,
        solvable,
        bright_ok: k_new.abs() <= kappa_max,
        moving: significance > MOTION_SIGNIFICANCE,
    }
}

/// `v.clamp(-limit, limit)` (NaN stays NaN) without `clamp`'s check of its bounds, which
/// kept the loop from vectorising.
#[inline(always)]
pub(super) fn clamp(v: f32, limit: f32) -> f32 {
    let v = if v < -limit { -limit } else { v };
    if v > limit {
        limit
    } else {
        v
    }
}

#[inline(always)]
pub(super) fn bit(set: bool, value: u16) -> f32 {
    if set {
        f32::from(value)
    } else {
        0.0
    }
}

/// The first pass over a block: every pixel's patch step and (on the last step) acceleration;
/// the still pixels' outputs; `marks` set where the pixel moves or was corrected before, whose
/// other planes stay as they were for the second pass ([`super::motion_moving`]).
#[inline(always)]
fn still_pass<const REFINE: bool, const LAST: bool>(
    step: &Step<'_>,
    row: &mut RowPlanes<'_>,
    marks: &mut [u8],
) {
    let basis = step.basis;
    // Every plane cut to the block's length, so that indexing needs no checks and the loop
    // vectorises.
    let n = marks.len();
    let mut row = row.block(0, n);
    let row = &mut row;
    for x in 0..n {
        let p = patch_step::<REFINE>(step, row, x);
        if LAST {
            // The acceleration: the change of the patch's velocity since the previous window,
            // on a surface that moves now or moved then, where it shifts the coordinate by more
            // than the noise and one surface can make it ([`super::motion::remove_acceleration_shift`]).
            let du = p.u - row.patch_velocity[x];
            let accelerating = p.solvable
                & (p.moving | (row.patch_moving[x] != 0))
                & (step.inv_since > 0.0)
                & (du.abs() <= step.max_velocity_change);
            let onset = acceleration_onset(du.abs() * step.shift_per_velocity_change);
            row.acceleration[x] = if accelerating {
                du * step.inv_since * onset
            } else {
                0.0
            };
            row.patch_velocity[x] = if p.solvable { p.u } else { f32::NAN };
            row.patch_moving[x] = u8::from(p.moving);
        }
        let corrected_before = REFINE & ((row.velocity[x] != 0.0) | (row.brightness[x] != 0.0));
        let full = p.moving | corrected_before;
        marks[x] = u8::from(full);
        // The still pixel: its phasors are the still solution.
        let phases = [row.phase[0][x], row.phase[1][x], row.phase[2][x]];
        let amps = [row.amp[0][x], row.amp[1][x], row.amp[2][x]];
        let mut z = [(0.0, 0.0); 3];
        for slot in 0..3 {
            let (s, c) = sin_cos_phase(phases[slot]);
            z[slot] = (amps[slot] * c, amps[slot] * s);
        }
        let cheb = chebyshev3_of(z, phases, amps, step.gain2);
        let keep_if = |keep: f32, old: f32| if full { old } else { keep };
        row.velocity[x] = keep_if(0.0, row.velocity[x]);
        row.brightness[x] = keep_if(0.0, row.brightness[x]);
        if LAST {
            let min_amp = cheb.amplitude[0]
                .min(cheb.amplitude[1])
                .min(cheb.amplitude[2]);
            let low = min_amp.is_nan() | (min_amp < step.min_amplitude);
            let saturated = row.flags[x] & invalid::SATURATED != 0;
            let reason = bit(low, invalid::LOW_AMPLITUDE)
                + bit(saturated, invalid::SATURATED)
                + bit(inconsistent(&cheb, step.limit), invalid::DISAGREEMENT);
            let keep = if reason == 0.0 { 1.0 } else { 0.0 };
            row.acceleration[x] = keep_if(row.acceleration[x] * keep, row.acceleration[x]);
            row.kk[x] = keep_if(keep, row.kk[x]);
            row.uu[x] = keep_if(cheb.unit.0 * keep, row.uu[x]);
            row.uk[x] = keep_if(cheb.unit.1 * keep, row.uk[x]);
            row.flags[x] = if full {
                row.flags[x]
            } else {
                whole_to_flags(reason)
            };
        } else {
            // The next step's evidence, at rest. The flags still hold stage 1's signal reasons
            // alone.
            let offsets = [row.offset[0][x], row.offset[1][x], row.offset[2][x]];
            let keep = if row.flags[x] == 0 { 1.0 } else { 0.0 };
            let ev = evidence(basis, z, &cheb, offsets, keep, step.gain2);
            row.uu[x] = keep_if(ev.uu, row.uu[x]);
            row.uk[x] = keep_if(ev.uk, row.uk[x]);
            row.kk[x] = keep_if(ev.kk, row.kk[x]);
            row.ue[x] = keep_if(ev.ue, row.ue[x]);
            row.ke[x] = keep_if(ev.ke, row.ke[x]);
            row.count[x] = keep_if(keep, row.count[x]);
        }
    }
}

#[cfg(test)]
mod tests;
