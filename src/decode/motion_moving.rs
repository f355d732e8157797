//! The second pass of a motion step ([`super::motion_correct`]): the full model on the pixels
//! of a row that move or were corrected by the step before, [`BLOCK`] at a time. They are
//! gathered into arrays on the stack, the model runs over every entry in two loops with no
//! branches (each choice is computed both ways and one selected), so that they vectorise, and
//! the marked entries are copied back. The first loop corrects each slot's phasor, the second
//! finishes the pixel from the corrected phasors; as a single loop LLVM's cost model kept it
//! scalar (see [`correct_gathered`]).
//!
//! Per pixel: undo the previous step's correction (`(M(g₀) + κ₀N(g₀))·z + κ₀·ō·v`), correct
//! with the patch's `(u, κ)` (`z = (M(g) + κN(g))⁻¹·(ẑ − κ·ō·v)` per slot, [`super::motion`]),
//! then write the next step's evidence, or on the last step the phases, amplitudes, unit
//! phasor, the offsets without the fringe the motion leaked into them, and the reasons.

use super::fastmath::{sin_cos_phase, sin_cos_small, whole_to_flags};
use super::invalid;
use super::motion::{StepKind, MIN_DET};
use super::motion_basis::{apply, MotionBasis, MAX_TURN_RAD};
use super::motion_correct::{bit, clamp, patch_step, PatchStep, RowPlanes, Step, BLOCK};
use super::motion_evidence::{chebyshev3, disagrees, evidence_with, inconsistent};

/// Marked pixels of a row, gathered into arrays, so that the full model runs over them in one
/// branch-free loop that vectorises; `index` says where in the row each came from. The
/// entries past the filled ones hold zeros or earlier pixels: the model runs on
/// them too (every value is finite or a harmless NaN) and their results are not copied back.
pub(super) struct Gathered {
    pub(super) index: [usize; BLOCK],
    phase: [[f32; BLOCK]; 3],
    amp: [[f32; BLOCK]; 3],
    offset: [[f32; BLOCK]; 3],
    /// `uu`, `uk`, `kk`, `ue`, `ke` and `count`.
    evidence: [[f32; BLOCK]; 6],
    flags: [u16; BLOCK],
    velocity: [f32; BLOCK],
    brightness: [f32; BLOCK],
    acceleration: [f32; BLOCK],
    /// Not read by the full model (the first pass took the acceleration): never copied.
    patch_velocity: [f32; BLOCK],
    patch_moving: [u8; BLOCK],
    lit_sum: [f32; BLOCK],
}

impl Default for Gathered {
    fn default() -> Self {
        Self {
            index: [0; BLOCK],
            phase: [[0.0; BLOCK]; 3],
            amp: [[0.0; BLOCK]; 3],
            offset: [[0.0; BLOCK]; 3],
            evidence: [[0.0; BLOCK]; 6],
            flags: [0; BLOCK],
            velocity: [0.0; BLOCK],
            brightness: [0.0; BLOCK],
            acceleration: [0.0; BLOCK],
            patch_velocity: [0.0; BLOCK],
            patch_moving: [0; BLOCK],
            lit_sum: [0.0; BLOCK],
        }
    }
}

impl Gathered {
    #[inline(always)]
    pub(super) fn planes(&mut self) -> RowPlanes<'_> {
        let [p0, p1, p2] = &mut self.phase;
        let [a0, a1, a2] = &mut self.amp;
        let [o0, o1, o2] = &mut self.offset;
        let [uu, uk, kk, ue, ke, count] = &mut self.evidence;
        RowPlanes {
            phase: [p0, p1, p2],
            amp: [a0, a1, a2],
            offset: [o0, o1, o2],
            uu,
            uk,
            kk,
            ue,
            ke,
            count,
            flags: &mut self.flags,
            velocity: &mut self.velocity,
            brightness: &mut self.brightness,
            acceleration: &mut self.acceleration,
            patch_velocity: &mut self.patch_velocity,
            patch_moving: &mut self.patch_moving,
            lit_sum: &mut self.lit_sum,
        }
    }
}

/// Copies pixel `i` of `from` to pixel `j` of `to`: every plane the full model reads or writes.
#[inline(always)]
pub(super) fn copy_pixel(from: &RowPlanes<'_>, i: usize, to: &mut RowPlanes<'_>, j: usize) {
    for slot in 0..3 {
        to.phase[slot][j] = from.phase[slot][i];
        to.amp[slot][j] = from.amp[slot][i];
        to.offset[slot][j] = from.offset[slot][i];
    }
    to.uu[j] = from.uu[i];
    to.uk[j] = from.uk[i];
    to.kk[j] = from.kk[i];
    to.ue[j] = from.ue[i];
    to.ke[j] = from.ke[i];
    to.count[j] = from.count[i];
    to.flags[j] = from.flags[i];
    to.velocity[j] = from.velocity[i];
    to.brightness[j] = from.brightness[i];
    to.acceleration[j] = from.acceleration[i];
    to.lit_sum[j] = from.lit_sum[i];
}

/// The second pass over a block's gathered pixels: a function of its own, whose planes the
/// compiler knows do not alias, so that the loops vectorise.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub(super) fn correct_gathered(step: &Step<'_>, gathered: &mut Gathered, filled: usize) {
    match (step.kind == StepKind::Refine, step.last) {
        (false, false) => correct_gathered_as::<false, false>(step, gathered, filled),
        (false, true) => correct_gathered_as::<false, true>(step, gathered, filled),
        (true, false) => correct_gathered_as::<true, false>(step, gathered, filled),
        (true, true) => correct_gathered_as::<true, true>(step, gathered, filled),
    }
}

/// [`correct_gathered`] for one kind of step, in two loops over every entry (filled or not:
/// the rest are not copied back). A fixed count lets the compiler see that the arrays do not
/// overlap (with the filled count it asked for more run-time overlap checks than it makes, and
/// stayed scalar). As one loop, LLVM's cost model judged the whole model not worth vectorising
/// (its loop-vectorize remarks: "vectorization is not beneficial"), and 83 % of the pass ran
/// on scalar or 4-wide instructions; split where the slots' corrections are done, both halves
/// vectorise.
#[inline(always)]
fn correct_gathered_as<const REFINE: bool, const LAST: bool>(
    step: &Step<'_>,
    gathered: &mut Gathered,
    filled: usize,
) {
    let mut corrected = Corrected::default();
    {
        let planes = gathered.planes();
        // Over the filled entries only (on a scene that hardly moves a run holds a few).
        let mut measured = [f32::NAN; BLOCK];
        if REFINE && step.offset_brightness_weight > 0.0 {
            for (j, rate) in measured.iter_mut().enumerate().take(filled.min(BLOCK)) {
                *rate = brightness_from_offsets(step, &planes, j);
            }
        }
        for j in 0..BLOCK {
            correct_slots::<REFINE>(step, &planes, j, measured[j], &mut corrected);
        }
    }
    let mut planes = gathered.planes();
    for j in 0..BLOCK {
        finish_pixel::<LAST>(step, &mut planes, j, &corrected);
    }
}

/// What the first loop of [`correct_gathered_as`] leaves for the second, per entry: the patch's
/// `(u, κ)` (0 where it does not move) and each slot's [`SlotCorrection`].
struct Corrected {
    u: [f32; BLOCK],
    kappa: [f32; BLOCK],
    moving: [bool; BLOCK],
    bright_ok: [bool; BLOCK],
    /// Per slot: the still phasor, the corrected one, and its slopes in `u` and `κ`.
    still: [[[f32; BLOCK]; 2]; 3],
    z: [[[f32; BLOCK]; 2]; 3],
    dz: [[[f32; BLOCK]; 4]; 3],
    within: [[bool; BLOCK]; 3],
    det: [[f32; BLOCK]; 3],
}

impl Default for Corrected {
    fn default() -> Self {
        Self {
            u: [0.0; BLOCK],
            kappa: [0.0; BLOCK],
            moving: [false; BLOCK],
            bright_ok: [false; BLOCK],
            still: [[[0.0; BLOCK]; 2]; 3],
            z: [[[0.0; BLOCK]; 2]; 3],
            dz: [[[0.0; BLOCK]; 4]; 3],
            within: [[false; BLOCK]; 3],
            det: [[0.0; BLOCK]; 3],
        }
    }
}

impl Corrected {
    #[inline(always)]
    fn set_slot(&mut self, slot: usize, j: usize, c: &SlotCorrection) {
        self.still[slot][0][j] = c.still.0;
        self.still[slot][1][j] = c.still.1;
        self.z[slot][0][j] = c.z.0;
        self.z[slot][1][j] = c.z.1;
        self.dz[slot][0][j] = c.dz[0].0;
        self.dz[slot][1][j] = c.dz[0].1;
        self.dz[slot][2][j] = c.dz[1].0;
        self.dz[slot][3][j] = c.dz[1].1;
        self.within[slot][j] = c.within;
        self.det[slot][j] = c.det;
    }

    #[inline(always)]
    fn slot(&self, slot: usize, j: usize) -> SlotCorrection {
        SlotCorrection {
            still: (self.still[slot][0][j], self.still[slot][1][j]),
            z: (self.z[slot][0][j], self.z[slot][1][j]),
            dz: [
                (self.dz[slot][0][j], self.dz[slot][1][j]),
                (self.dz[slot][2][j], self.dz[slot][3][j]),
            ],
            within: self.within[slot][j],
            det: self.det[slot][j],
        }
    }
}

/// The first half of the model for one pixel that moves or was corrected by the step before:
/// the patch's `(u, κ)`, and each slot's phasor with the previous correction undone and the
/// new one applied. The acceleration was taken by the first pass.
#[inline(always)]
fn correct_slots<const REFINE: bool>(
    step: &Step<'_>,
    row: &RowPlanes<'_>,
    x: usize,
    measured_kappa: f32,
    out: &mut Corrected,
) {
    let basis = step.basis;
    let PatchStep {
        u,
        kappa,
        bright_ok,
        moving,
        ..
    } = patch_step::<REFINE>(step, row, x);
    let (u0, k0) = if REFINE {
        (row.velocity[x], row.brightness[x])
    } else {
        (0.0, 0.0)
    };
    let phases = [row.phase[0][x], row.phase[1][x], row.phase[2][x]];
    let amps = [row.amp[0][x], row.amp[1][x], row.amp[2][x]];
    let offsets = [row.offset[0][x], row.offset[1][x], row.offset[2][x]];
    let lit = basis.lit_offsets(offsets);
    // Undo the previous correction, if any; correct only where the patch moves.
    let corrected_before = REFINE & ((u0 != 0.0) | (k0 != 0.0));
    let kappa = if REFINE && !measured_kappa.is_nan() {
        let w = step.offset_brightness_weight;
        (1.0 - w) * kappa + w * measured_kappa
    } else {
        kappa
    };
    let (u, kappa) = if moving { (u, kappa) } else { (0.0, 0.0) };
    // Each slot written out rather than looped over, so that the loop over the gathered pixels
    // (which this is inlined into) has no inner loop and vectorises.
    let before = (corrected_before, u0, k0);
    let now = (moving, u, kappa);
    let slot0 = correct_slot::<REFINE>(basis, 0, (phases[0], amps[0], lit[0]), before, now);
    let slot1 = correct_slot::<REFINE>(basis, 1, (phases[1], amps[1], lit[1]), before, now);
    let slot2 = correct_slot::<REFINE>(basis, 2, (phases[2], amps[2], lit[2]), before, now);
    if !REFINE {
        out.set_slot(0, x, &slot0);
        out.set_slot(1, x, &slot1);
        out.set_slot(2, x, &slot2);
        out.u[x] = u;
        out.kappa[x] = kappa;
        out.moving[x] = moving;
        out.bright_ok[x] = bright_ok;
        return;
    }
    // A step that breaks a consistent correction is refused for this pixel
    // ([`super::motion`], "A step is kept only where it does not break the pixel"): it keeps
    // the previous step's correction, redone at `(u0, κ0)`.
    let then = (corrected_before, u0, k0);
    let kept0 = correct_slot::<REFINE>(basis, 0, (phases[0], amps[0], lit[0]), before, then);
    let kept1 = correct_slot::<REFINE>(basis, 1, (phases[1], amps[1], lit[1]), before, then);
    let kept2 = correct_slot::<REFINE>(basis, 2, (phases[2], amps[2], lit[2]), before, then);
    let keep_previous = corrected_before
        & disagrees([slot0.z, slot1.z, slot2.z], step.gain2, step.limit)
        & !disagrees([kept0.z, kept1.z, kept2.z], step.gain2, step.limit);
    out.set_slot(0, x, &SlotCorrection::select(keep_previous, kept0, slot0));
    out.set_slot(1, x, &SlotCorrection::select(keep_previous, kept1, slot1));
    out.set_slot(2, x, &SlotCorrection::select(keep_previous, kept2, slot2));
    out.u[x] = if keep_previous { u0 } else { u };
    out.kappa[x] = if keep_previous { k0 } else { kappa };
    // The previous brightness change was clamped to the model's range when it was applied.
    out.moving[x] = moving | keep_previous;
    out.bright_ok[x] = bright_ok | keep_previous;
}

/// The pixel's brightness change from its lit offsets in the previous window and in this one
/// (`(L − L_prev)/(Δt·L)`, per second), this window's without the fringe the previous step's
/// correction `(u0, κ0)` says motion leaked into them; NaN where the step takes none (a weight
/// of 0), a sum is not positive, or the change is beyond the model's range (at an outline the
/// pixel may have seen another surface then).
///
/// Written out without loops, closures over arrays or `f32::clamp`, so that its loop
/// vectorises: with [`leak_of_slot`] and [`MotionBasis::lit_offsets`] it ran scalar, and the
/// gathered pass took six times as long.
#[inline(always)]
fn brightness_from_offsets(step: &Step<'_>, row: &RowPlanes<'_>, x: usize) -> f32 {
    let now = lit_sum_without_leak(
        step.basis,
        (row.velocity[x], row.brightness[x]),
        [row.phase[0][x], row.phase[1][x], row.phase[2][x]],
        [row.amp[0][x], row.amp[1][x], row.amp[2][x]],
        [row.offset[0][x], row.offset[1][x], row.offset[2][x]],
    );
    let before = row.lit_sum[x];
    let rate = (now - before) * step.inv_since / now;
    let taken = (step.offset_brightness_weight > 0.0)
        & (step.inv_since > 0.0)
        & (before > 0.0)
        & (now > 0.0)
        & (rate.abs() <= step.basis.max_brightness_rate);
    if taken {
        rate
    } else {
        f32::NAN
    }
}

/// The sum of a pixel's projector-lit offsets (`Σ_c (Σ_s unmix[s][c])·(o_c − bias_c)`) without
/// the fringe that the previous step's correction `(u0, κ0)` says motion leaked into them (none
/// where it was not corrected): its lit light at the window's centre.
#[inline(always)]
pub(super) fn lit_sum_without_leak(
    basis: &MotionBasis,
    (u0, k0): (f32, f32),
    phase: [f32; 3],
    amp: [f32; 3],
    offset: [f32; 3],
) -> f32 {
    let corrected_before = (u0 != 0.0) | (k0 != 0.0);
    let leak0 = leak_at(basis, 0, (u0, k0), (phase[0], amp[0]));
    let leak1 = leak_at(basis, 1, (u0, k0), (phase[1], amp[1]));
    let leak2 = leak_at(basis, 2, (u0, k0), (phase[2], amp[2]));
    let (leak0, leak1, leak2) = if corrected_before {
        (leak0, leak1, leak2)
    } else {
        (0.0, 0.0, 0.0)
    };
    // Each camera channel's offset without the leaked fringe, less the cross-talk bias; the
    // lit offsets' sum is Σ_c (Σ_s unmix[s][c])·that.
    let (mix, unmix, bias) = (&basis.mix_of_slot, &basis.unmix_of_slot, &basis.bias_gray);
    let channel = |c: usize| {
        offset[c] - (mix[0][c] * leak0 + mix[1][c] * leak1 + mix[2][c] * leak2) - bias[c]
    };
    let (c0, c1, c2) = (channel(0), channel(1), channel(2));
    (unmix[0][0] + unmix[1][0] + unmix[2][0]) * c0
        + (unmix[0][1] + unmix[1][1] + unmix[2][1]) * c1
        + (unmix[0][2] + unmix[1][2] + unmix[2][2]) * c2
}

/// [`leak_of_slot`] of slot `slot` at `(u, κ)` for the phasor of `(phase, amp)`, its three
/// frames written out.
#[inline(always)]
fn leak_at(
    basis: &MotionBasis,
    slot: usize,
    (u, kappa): (f32, f32),
    (phase, amp): (f32, f32),
) -> f32 {
    let (s, c) = sin_cos_phase(phase);
    let z = (amp * c, amp * s);
    let g = basis.f_rad_per_px[slot] * u;
    let frame = |k: usize| {
        let tau = basis.tau_s[k];
        let (sn, cs) = sin_cos_small(clamp(g * tau, MAX_TURN_RAD));
        let (dx, dy) = basis.d[k];
        let turned = (dx * cs + dy * sn, -dx * sn + dy * cs);
        basis.offset_row[k] * ((1.0 + kappa * tau) * dot2(turned, z) - dot2(basis.d[k], z))
    };
    frame(0) + frame(1) + frame(2)
}

/// The second half, for the same pixel: write the next step's evidence or (on the last step)
/// the unit phasor, the offsets without the fringe the motion leaked into them, and the
/// reasons.
#[inline(always)]
fn finish_pixel<const LAST: bool>(
    step: &Step<'_>,
    row: &mut RowPlanes<'_>,
    x: usize,
    corrected: &Corrected,
) {
    let basis = step.basis;
    let (u, kappa) = (corrected.u[x], corrected.kappa[x]);
    let (moving, bright_ok) = (corrected.moving[x], corrected.bright_ok[x]);
    let offsets = [row.offset[0][x], row.offset[1][x], row.offset[2][x]];
    let lit = basis.lit_offsets(offsets);
    let slots = [
        corrected.slot(0, x),
        corrected.slot(1, x),
        corrected.slot(2, x),
    ];
    let within = (bright_ok | !moving)
        & (slots[0].within | !moving)
        & (slots[1].within | !moving)
        & (slots[2].within | !moving);
    let worst_det = if moving {
        f32::INFINITY
            .min(slots[0].det)
            .min(slots[1].det)
            .min(slots[2].det)
    } else {
        1.0
    };
    let still = [slots[0].still, slots[1].still, slots[2].still];
    let z = [slots[0].z, slots[1].z, slots[2].z];
    let dz = [slots[0].dz, slots[1].dz, slots[2].dz];
    row.velocity[x] = u;
    row.brightness[x] = kappa;
    // Every marked pixel moves now or was corrected before: its phases change.
    let cheb = chebyshev3(z, step.gain2);
    for slot in 0..3 {
        row.phase[slot][x] = cheb.phase[slot];
        row.amp[slot][x] = cheb.amplitude[slot];
    }
    if !LAST {
        // The next step's evidence, from the corrected phasors. The flags still hold stage
        // 1's signal reasons alone.
        let keep = if row.flags[x] == 0 { 1.0 } else { 0.0 };
        let at_rest = basis.slopes_at_rest(still, lit);
        let dz: [[(f32, f32); 2]; 3] = std::array::from_fn(|slot| {
            [
                select2(moving, dz[slot][0], at_rest[slot][0]),
                select2(moving, dz[slot][1], at_rest[slot][1]),
            ]
        });
        let ev = evidence_with(z, dz, &cheb, keep, (u, kappa));
        row.uu[x] = ev.uu;
        row.uk[x] = ev.uk;
        row.kk[x] = ev.kk;
        row.ue[x] = ev.ue;
        row.ke[x] = ev.ke;
        row.count[x] = keep;
        return;
    }
    // The offset image without the fringe that the motion leaked into it.
    let leak = [
        leak_of_slot(basis, 0, (moving, u, kappa), z[0]),
        leak_of_slot(basis, 1, (moving, u, kappa), z[1]),
        leak_of_slot(basis, 2, (moving, u, kappa), z[2]),
    ];
    for slot in 0..3 {
        row.offset[slot][x] = offsets[slot] - dot3(basis.mix_of_slot_row(slot), leak);
    }
    let min_amp = cheb.amplitude[0]
        .min(cheb.amplitude[1])
        .min(cheb.amplitude[2]);
    let low = min_amp.is_nan() | (min_amp < step.min_amplitude);
    let unexplained = !within | (worst_det < MIN_DET);
    let saturated = row.flags[x] & invalid::SATURATED != 0;
    let reason = bit(low, invalid::LOW_AMPLITUDE)
        + bit(saturated, invalid::SATURATED)
        + bit(inconsistent(&cheb, step.limit), invalid::DISAGREEMENT)
        + bit(unexplained, invalid::MOTION);
    let keep = if reason == 0.0 { 1.0 } else { 0.0 };
    // Only a valid pixel's motion is reported.
    row.velocity[x] = u * keep;
    row.brightness[x] = kappa * keep;
    row.acceleration[x] *= keep;
    row.kk[x] = keep;
    row.uu[x] = cheb.unit.0 * keep;
    row.uk[x] = cheb.unit.1 * keep;
    row.flags[x] = whole_to_flags(reason);
}

/// One slot of [`correct_slots`]: its phasor as the still solve saw it, corrected, and how the
/// correction moves with `u` and `κ`, with the model's determinant and range.
#[derive(Clone, Copy)]
struct SlotCorrection {
    still: (f32, f32),
    z: (f32, f32),
    dz: [(f32, f32); 2],
    within: bool,
    det: f32,
}

impl SlotCorrection {
    /// `a` if `choose`, else `b`, field by field: no branches.
    #[inline(always)]
    fn select(choose: bool, a: Self, b: Self) -> Self {
        Self {
            still: select2(choose, a.still, b.still),
            z: select2(choose, a.z, b.z),
            dz: [
                select2(choose, a.dz[0], b.dz[0]),
                select2(choose, a.dz[1], b.dz[1]),
            ],
            within: if choose { a.within } else { b.within },
            det: if choose { a.det } else { b.det },
        }
    }
}

/// Slot `slot` with phase, amplitude and lit offset `(phase, amp, lit)`, corrected before at
/// `(u0, κ0)` where `corrected_before`, and now at `(u, κ)` where `moving`. Both sides of each
/// choice are computed and one is selected: no branches.
#[inline(always)]
fn correct_slot<const REFINE: bool>(
    basis: &MotionBasis,
    slot: usize,
    (phase, amp, lit): (f32, f32, f32),
    (corrected_before, u0, k0): (bool, f32, f32),
    (moving, u, kappa): (bool, f32, f32),
) -> SlotCorrection {
    let (vx, vy) = basis.v;
    let (s, c) = sin_cos_phase(phase);
    let mut seen = (amp * c, amp * s);
    let f = basis.f_rad_per_px[slot];
    if REFINE {
        // What the still solve saw: the previous correction undone.
        let (x, y) = apply(&basis.response(f * u0, k0).0, seen);
        let undone = (x + k0 * lit * vx, y + k0 * lit * vy);
        seen = select2(corrected_before, undone, seen);
    }
    let model = basis.linearised(f * u, kappa);
    let lit_term = (kappa * lit * vx, kappa * lit * vy);
    let zs = apply(&model.inverse, (seen.0 - lit_term.0, seen.1 - lit_term.1));
    let slopes = model.slopes(zs, f, lit, basis.v);
    let none = (0.0, 0.0);
    SlotCorrection {
        still: seen,
        z: select2(moving, zs, seen),
        dz: [
            select2(moving, slopes[0], none),
            select2(moving, slopes[1], none),
        ],
        within: model.within,
        det: model.det,
    }
}

/// The fringe that motion at `(u, κ)` leaked into slot `slot`'s offset (0 where not `moving`):
/// `Σ_k O_k·(s_k·d_kᵀ·R(gτ_k)·z − d_kᵀ·z)`, the frame's brightness scale `s_k` and the still
/// `d_kᵀ·z`, which the offset row cancels.
#[inline(always)]
fn leak_of_slot(
    basis: &MotionBasis,
    slot: usize,
    (moving, u, kappa): (bool, f32, f32),
    z: (f32, f32),
) -> f32 {
    let g = basis.f_rad_per_px[slot] * u;
    let mut r = 0.0;
    for k in 0..3 {
        let (s, cs) = sin_cos_small((g * basis.tau_s[k]).clamp(-MAX_TURN_RAD, MAX_TURN_RAD));
        let (dx, dy) = basis.d[k];
        let scale = 1.0 + kappa * basis.tau_s[k];
        let turned = (dx * cs + dy * s, -dx * s + dy * cs);
        r += basis.offset_row[k] * (scale * dot2(turned, z) - dot2(basis.d[k], z));
    }
    if moving {
        r
    } else {
        0.0
    }
}

/// `a` if `choose`, else `b`.
#[inline(always)]
fn select2(choose: bool, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    (
        if choose { a.0 } else { b.0 },
        if choose { a.1 } else { b.1 },
    )
}

/// `aᵀ·b` of two 2-vectors.
#[inline(always)]
fn dot2(a: (f32, f32), b: (f32, f32)) -> f32 {
    a.0 * b.0 + a.1 * b.1
}

#[inline(always)]
fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
