//! Motion inside the window: one velocity per pixel, shared by the three CPS frequencies.
//!
//! The paper's window (§7) assumes a still scene for its 2/121 s. A fingertip in a 10 mm tremor
//! moves by several projector pixels in that time, and every frequency's phase turns with it:
//! `φ_f(t) = φ_f(t_c) + f_f·u·(t − t_c)`, with `u` the pixel's coordinate velocity (projector
//! px/s) and `f_f` the frequency in rad per projector px. All three channels code the same
//! coordinate, so `u` is one unknown per pixel.
//!
//! **What the still solve returns under motion.** Frame `k` of a channel samples
//! `o + d_kᵀ·R(g·τ_k)·z`, with `z = (U, V)` the phasor at the window's centre time, `d_k =
//! (cos θ_k, −sin θ_k)` the frame's pattern shift, `τ_k = t_k − t_c`, `g = f_f·u` and `R` a
//! rotation. The still closed form (rows `L_k`) therefore returns `ẑ = M(g)·z` with
//! `M(g) = Σ_k L_k·d_kᵀ·(cos(gτ_k)·I + sin(gτ_k)·J)`, a 2×2 matrix that is the identity at
//! `g = 0` (J is the quarter turn). For shifts 0, 2π/3, 4π/3 at times −Δ, 0, Δ it adds a
//! ripple of `g·Δ/√3·sin(2φ + …)` to each phase: a different error per frequency, which breaks
//! the Chebyshev relation `φ_0 − 2φ_1 + φ_2 = 0` and, beyond a few millimetres of tremor, the
//! fringe orders.
//!
//! **Brightness changes too.** A surface that moves turns against the projector and its shading
//! changes: on the sides of a finger swaying sideways by 4 mm, by a third per frame. Every
//! sample of the pixel's projector-lit light scales by `1 + κ·τ_k` (κ per second, shared by
//! the channels and by offset and fringe alike), which adds `κ·(N(g)·z + ō_f·v)` to the still
//! solution, with `N(g) = Σ_k τ_k·L_k·d_kᵀ·R(gτ_k)`, `v = Σ_k τ_k·L_k` and `ō_f` the slot's
//! projector-lit offset (the offset image unmixed, less the cross-talk bias `b`). Its phase
//! error follows the fringe once per period (the velocity's twice), and with offsets near the
//! fringe amplitude it is the larger of the two. So the model has two unknowns per patch,
//! `u` and `κ`.
//!
//! **Estimating u and κ** (a generalised phase shift with per-pixel shifts, solved by one
//! Gauss–Newton step from the still solution, in the spirit of the per-pixel shift estimation
//! of motion-induced error compensation, e.g. Liu et al., Opt. Express 26 (2018) 12632). The
//! Chebyshev residual `e = angle(z_0·z̄_1·conj(z_1·z̄_2)) = φ_0 − 2φ_1 + φ_2` needs no
//! unwrapping, is zero for a still pixel whatever its coordinate, and under motion is, to first
//! order, `e ≈ D_u·u + D_κ·κ` with `D_u = Σ_f w_f·f_f·(ẑ × M'(0)·ẑ)/|ẑ|²`,
//! `D_κ = Σ_f w_f·(ẑ × (N(0)·ẑ + ō_f·v))/|ẑ|²` and `w = (1, −2, 1)`. One pixel's `e` is
//! noisy and its slopes oscillate with the fringes (differently: twice and once per period),
//! but `u` and `κ` are smooth along a surface, so stage 1 writes the five sums of the normal
//! equations (`W·D_u²`, `W·D_u·D_κ`, `W·D_κ²`, `W·D_u·e`, `W·D_κ·e`, with `W = 1/var(e)` from
//! the amplitudes), the edge-aware filter of [`super::smooth`] sums them over each pixel's
//! connected neighbourhood, and the 2×2 system gives the patch's weighted least-squares `u` and
//! `κ`. Further steps repeat this on the corrected phasors, undoing the previous correction
//! with the forward model before applying the new one. Each pixel's evidence is written in
//! absolute terms, `e + D_u·u + D_κ·κ` at the `(u, κ)` it was corrected with, so the patch
//! solves for its velocity rather than pooling steps taken from different starting points
//! (pooled steps let a pixel that started at rest drag its fast neighbours back towards it).
//! Measured on the rig at a 10 mm tremor: 94.4 % of the moving skin kept with 0.97 % gross
//! errors, against 90.8 % and 1.6 % with pooled steps.
//!
//! **What was tried and dropped.** The velocity predicted per pixel from the two previous
//! windows' coordinates (the sliding window's own motion), as the steps' starting point: under
//! motion the decoded coordinates carry errors of a few tenths of a pixel, so only about 70 %
//! of those predictions came within 60 px/s of the truth, and started there the steps kept
//! 82 % of the moving skin at 10 mm, 10 % of it more than a projector pixel off.
//!
//! **Correcting.** Each frequency's phasor is then
//! `z = (M(g) + κ·N(g))⁻¹·(ẑ − κ·ō_f·v)` with `g = f_f·u`, exactly for the model, and the
//! offset image loses the fringe that motion leaks into it (`Σ_k O_k·d_kᵀ·R(gτ_k)·z` per slot,
//! mixed into the camera channels); the phases, amplitudes, the unit phasor and the Chebyshev check are computed
//! again from the corrected phasors, so [`super::invalid::DISAGREEMENT`] (and the χ² test of
//! stage 3) test the motion model's residual rather than stillness. A pixel whose frame rotates
//! by more than [`MAX_TURN_RAD`] within the window, whose `M` is near singular or whose light
//! changes too fast is marked [`super::invalid::MOTION`]: the model does not explain it.
//!
//! **Acceleration.** Where the tremor turns back the velocity changes fast and the three-step
//! solve returns the frames' mean coordinate rather than the centre's; the shift, `a·mean(τ²)/2`,
//! is the same at every frequency and so invisible to the Chebyshev residual. The last step
//! takes `a` from the change of the patch's velocity since the previous window of the same
//! stream (kept in the output between windows), and [`remove_acceleration_shift`] moves the
//! coordinate back to the centre time. A window with no previous one (a single decode, a drop)
//! keeps the shift.
//!
//! Only CPS-RGB windows (three frames, factored solve) take the model; other sequences decode
//! as before.

use super::fastmath::{sin_cos_phase, sin_cos_small, whole_to_byte};
use super::motion_basis::apply;
pub use super::motion_basis::{MotionBasis, MAX_TURN_RAD};
pub(crate) use super::motion_evidence::{chebyshev3, evidence, gain2, inconsistent};
use super::motion_evidence::{chebyshev3_of, evidence_with};
use super::smooth::{smooth_planes, Planes};
use super::{invalid, DecodeOutput, DecodeParams, WindowSolver};
use rayon::prelude::*;

/// Smallest `det(M + κN)` accepted: below it the correction amplifies the noise by more than
/// 2.5×.
const MIN_DET: f32 = 0.4;
/// χ² (two degrees of freedom) of a patch's `(u, κ)` against rest above which the motion is
/// taken as real: exceeded by chance with probability 10⁻⁶. At 10⁻⁴ (18.4) a still hand at
/// σ = 2 kept 55 pixels with motion and 12 wrong fringe orders; at 10⁻⁶ none, for 0.1 % of the
/// moving skin at a 10 mm tremor.
const MOTION_SIGNIFICANCE: f32 = 27.6;
/// The prior of a patch's velocity and brightness change before its evidence: zero, with
/// these standard deviations (px/s and 1/s; a 20 mm tremor at 6 Hz peaks near 750 px/s on the
/// paper's rig, a finger's side swaying 4 mm near 40/s). A patch with little evidence (the
/// ends of the projector's range, where the Chebyshev residual cannot see motion) then stays
/// near rest instead of fitting its noise.
const PRIOR_VELOCITY_PX_PER_S: f32 = 400.0;
const PRIOR_BRIGHTNESS_RATE_PER_S: f32 = 20.0;
/// Smallest shift of the window's mean coordinate from its centre coordinate (`a·mean(τ²)/2`,
/// projector px) for which the acceleration is applied: below it the correction is within the
/// noise of the coordinate, and a still surface keeps the still solution. (The velocity change
/// is not tested against its own noise: consecutive windows share two frames, so the noise of
/// the change is far below what two independent estimates would have, and at a 10 mm tremor a
/// χ² test at 10⁻⁶ kept the acceleration at 9 % of the moving skin, removing a fifth of the
/// bias instead of nine tenths.)
const MIN_ACCELERATION_SHIFT_PX: f32 = 0.05;
/// The fastest oscillation whose acceleration the model takes, Hz: a change of velocity
/// between windows larger than a sinusoid at this frequency and the model's largest velocity
/// can make is not motion of one surface (at an outline the pixel saw another surface in the
/// previous window), and the pixel gets no acceleration.
const MAX_OSCILLATION_HZ: f32 = 8.0;

/// Sums the evidence over each pixel's connected patch (two passes of the edge-aware filter),
/// then corrects the phasors: one Gauss–Newton step. Stage 1 (or the previous step) left the
/// evidence in `unit_re`, `unit_im`, `support` (`uu`, `uk`, `kk`) and `motion_evidence`
/// (`ue`, `ke`, count). The last step also takes the acceleration from the patch velocities
/// of the window `previous_s` seconds before, when there is one.
#[allow(
    clippy::too_many_arguments,
    reason = "the step's inputs are distinct: the window, its noise, and where the step stands"
)]
pub(crate) fn motion_step(
    solver: &WindowSolver,
    params: &DecodeParams,
    noise_gray: f32,
    basis: &MotionBasis,
    kind: StepKind,
    last: bool,
    previous_s: Option<f32>,
    out: &mut DecodeOutput,
) {
    let decay = params.motion.decay;
    {
        smooth_planes(&mut Planes::of_unit_phasor(out), decay);
        let n = out.width * out.height;
        let (e0, rest) = out.motion_evidence.split_at_mut(n);
        let (e1, e2) = rest.split_at_mut(n);
        let mut planes = Planes {
            planes: [e0, e1, e2],
            w: out.width,
            h: out.height,
            connect: &out.connect,
            tmp: &mut out.smooth_tmp,
            band_scratch: &mut out.band_scratch,
            band_scratch_len: out.band_scratch_len,
            vertical_state: &mut out.vertical_state,
        };
        smooth_planes(&mut planes, decay);
    }
    let step = Step {
        basis,
        gain2: gain2(solver),
        limit: params.max_disagreement_chi2 * params.camera_noise_gray.powi(2),
        min_amplitude: params.min_amplitude,
        kind,
        last,
        inv_noise2: noise_gray.powi(-2),
        prior_u: (noise_gray / PRIOR_VELOCITY_PX_PER_S).powi(2),
        prior_k: (noise_gray / PRIOR_BRIGHTNESS_RATE_PER_S).powi(2),
        inv_since: previous_s.map_or(0.0, |s| 1.0 / s),
        shift_per_velocity_change: previous_s.map_or(0.0, |s| 0.5 * basis.mean_tau2_s2 / s),
        max_velocity_change: previous_s.map_or(0.0, |s| {
            std::f32::consts::TAU * MAX_OSCILLATION_HZ * s * basis.max_velocity
        }),
    };
    let w = out.width;
    let n = w * out.height;
    let (ev0, rest) = out.motion_evidence.split_at_mut(n);
    let (ev1, ev2) = rest.split_at_mut(n);
    out.phase_rad
        .par_chunks_mut(3 * w)
        .zip(out.amplitude.par_chunks_mut(3 * w))
        .zip(out.colour.par_chunks_mut(3 * w))
        .zip(out.unit_re.par_chunks_mut(w))
        .zip(out.unit_im.par_chunks_mut(w))
        .zip(out.support.par_chunks_mut(w))
        .zip(ev0.par_chunks_mut(w))
        .zip(ev1.par_chunks_mut(w))
        .zip(ev2.par_chunks_mut(w))
        .zip(out.invalid.par_chunks_mut(w))
        .zip(out.velocity_px_per_s.par_chunks_mut(w))
        .zip(out.brightness_rate_per_s.par_chunks_mut(w))
        .zip(out.acceleration_px_per_s2.par_chunks_mut(w))
        .zip(out.patch_velocity_px_per_s.par_chunks_mut(w))
        .zip(out.patch_moving.par_chunks_mut(w))
        .for_each(
            |(
                (
                    (
                        (
                            (
                                (
                                    (
                                        (((((((phase, amp), colour), re), im), support), ue), ke),
                                        count,
                                    ),
                                    flags,
                                ),
                                velocity,
                            ),
                            brightness,
                        ),
                        acceleration,
                    ),
                    patch_velocity,
                ),
                patch_moving,
            )| {
                correct_row(
                    &step,
                    RowPlanes {
                        phase,
                        amp,
                        colour,
                        uu: re,
                        uk: im,
                        kk: support,
                        ue,
                        ke,
                        count,
                        flags,
                        velocity,
                        brightness,
                        acceleration,
                        patch_velocity,
                        patch_moving,
                    },
                );
            },
        );
}

/// Where a step starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StepKind {
    /// From rest: the phase planes hold the still solution; the step solves the patch's
    /// evidence for `(u, κ)`.
    FromRest,
    /// From the previous step: the phase planes hold its correction at the values in the
    /// velocity and brightness planes, which it undoes before solving the patch's evidence.
    Refine,
}

/// What one Gauss–Newton step of [`correct_row`] needs.
struct Step<'a> {
    basis: &'a MotionBasis,
    gain2: (f32, f32, f32),
    /// χ² limit times the noise variance.
    limit: f32,
    min_amplitude: f32,
    kind: StepKind,
    /// The priors' information in the units of the evidence (`σ²/sd²`: the evidence is
    /// weighted by `1/var(e)` over the camera noise variance).
    prior_u: f32,
    prior_k: f32,
    /// `1/σ²` of the camera noise.
    inv_noise2: f32,
    /// Write the corrected unit phasor and reasons (else the next step's evidence).
    last: bool,
    /// `1/Δt` to the previous window with patch velocities (0: none, no acceleration).
    inv_since: f32,
    /// The largest velocity change over that Δt taken as acceleration, px/s.
    max_velocity_change: f32,
    /// The shift of the window's mean coordinate per unit of velocity change, s.
    shift_per_velocity_change: f32,
}

/// One row of every plane a step reads and writes. On the last step `uu`, `uk` and `kk` (the
/// unit phasor's planes) receive the unit phasor and the support.
struct RowPlanes<'a> {
    phase: &'a mut [f32],
    amp: &'a mut [f32],
    colour: &'a mut [f32],
    uu: &'a mut [f32],
    uk: &'a mut [f32],
    kk: &'a mut [f32],
    ue: &'a mut [f32],
    ke: &'a mut [f32],
    count: &'a mut [f32],
    flags: &'a mut [u8],
    velocity: &'a mut [f32],
    brightness: &'a mut [f32],
    acceleration: &'a mut [f32],
    /// The previous window's patch velocities, replaced by this window's on the last step.
    patch_velocity: &'a mut [f32],
    /// Whether the previous window's patch velocity was significant, replaced likewise.
    patch_moving: &'a mut [u8],
}

/// The first `w` values of the three planes of a row-planar row of `3·w` values.
#[inline(always)]
fn split3(row: &mut [f32], w: usize) -> [&mut [f32]; 3] {
    let (a, rest) = row.split_at_mut(w);
    let (b, c) = rest.split_at_mut(w);
    [a, b, &mut c[..w]]
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn correct_row(step: &Step<'_>, row: RowPlanes<'_>) {
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
#[inline(always)]
fn correct_row_as<const REFINE: bool, const LAST: bool>(step: &Step<'_>, row: RowPlanes<'_>) {
    let basis = step.basis;
    let w = row.flags.len();
    let [ph0, ph1, ph2] = split3(row.phase, w);
    let [am0, am1, am2] = split3(row.amp, w);
    let [co0, co1, co2] = split3(row.colour, w);
    // Every plane cut to the row's width up front, so that indexing by `x` needs no checks.
    let (uu, uk, kk) = (&mut row.uu[..w], &mut row.uk[..w], &mut row.kk[..w]);
    let (ue, ke, count) = (&mut row.ue[..w], &mut row.ke[..w], &mut row.count[..w]);
    let (flags, velocity) = (&mut row.flags[..w], &mut row.velocity[..w]);
    let brightness = &mut row.brightness[..w];
    let acceleration = &mut row.acceleration[..w];
    let patch_velocity = &mut row.patch_velocity[..w];
    let patch_moving = &mut row.patch_moving[..w];
    let bit = |set: bool, value: u8| if set { f32::from(value) } else { 0.0 };
    let kappa_max = basis.max_brightness_rate;
    for x in 0..w {
        // The patch's step: the ridge-regularised weighted least squares of e = D_u·u + D_κ·κ.
        let (a, b, c) = (uu[x] + step.prior_u, uk[x], kk[x] + step.prior_k);
        let det = a * c - b * b;
        let (ru, rk) = (ue[x], ke[x]);
        let solvable = (det > 0.0) & (count[x] > 0.0);
        let (u0, k0) = if REFINE {
            (velocity[x], brightness[x])
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
        let u = u_new.clamp(-basis.max_velocity, basis.max_velocity);
        let kappa = k_new.clamp(-kappa_max, kappa_max);
        let bright_ok = k_new.abs() <= kappa_max;
        let phases = [ph0[x], ph1[x], ph2[x]];
        let amps = [am0[x], am1[x], am2[x]];
        let offsets = [co0[x], co1[x], co2[x]];
        let lit = basis.lit_offsets(offsets);
        // At every step the motion stays only where the patch's evidence shows it: its (u, κ)
        // differ from rest by more than the noise (a χ² of the estimate with two degrees of
        // freedom above `MOTION_SIGNIFICANCE`). Elsewhere (still surfaces, and the ends of the
        // projector's range, where the residual is blind to motion but the unit phase is not)
        // the still solution is kept, and the next step starts from rest. Testing only on the
        // last step let a first step's noise-driven correction pool into a significant-looking
        // second estimate: a still hand at σ = 2 then got 0.56 % wrong fringe orders.
        let significance = (a * u * u + 2.0 * b * u * kappa + c * kappa * kappa) * step.inv_noise2;
        let moving = significance > MOTION_SIGNIFICANCE;
        if LAST {
            // The acceleration: the change of the patch's velocity since the previous window,
            // on a surface that moves now or moved then, where it shifts the coordinate by more
            // than the noise and one surface can make it ([`remove_acceleration_shift`]).
            let du = u - patch_velocity[x];
            let accelerating = solvable
                & (moving | (patch_moving[x] != 0))
                & (step.inv_since > 0.0)
                & (du.abs() <= step.max_velocity_change)
                & (du.abs() * step.shift_per_velocity_change >= MIN_ACCELERATION_SHIFT_PX);
            acceleration[x] = if accelerating {
                du * step.inv_since
            } else {
                0.0
            };
            patch_velocity[x] = if solvable { u } else { f32::NAN };
            patch_moving[x] = u8::from(moving);
        }
        let (u, kappa) = if moving { (u, kappa) } else { (0.0, 0.0) };
        // Undo the previous correction, if any; correct only where the patch moves.
        let corrected_before = REFINE & ((u0 != 0.0) | (k0 != 0.0));
        let mut within = bright_ok | !moving;
        let mut worst_det = if moving { f32::INFINITY } else { 1.0 };
        let (vx, vy) = basis.v;
        let mut dz = [[(0.0, 0.0); 2]; 3];
        let mut still = [(0.0, 0.0); 3];
        // A plain loop: an `array::from_fn` closure here stayed out of line (perf: 55 %).
        let mut z = [(0.0, 0.0); 3];
        for slot in 0..3 {
            let (s, c) = sin_cos_phase(phases[slot]);
            let mut seen = (amps[slot] * c, amps[slot] * s);
            let f = basis.f_rad_per_px[slot];
            if corrected_before {
                // What the still solve saw: the previous correction undone.
                let (x, y) = apply(&basis.response(f * u0, k0).0, seen);
                seen = (x + k0 * lit[slot] * vx, y + k0 * lit[slot] * vy);
            }
            still[slot] = seen;
            z[slot] = seen;
            if moving {
                let model = basis.linearised(f * u, kappa);
                within &= model.within;
                worst_det = worst_det.min(model.det);
                let lit_term = (kappa * lit[slot] * vx, kappa * lit[slot] * vy);
                let zs = apply(&model.inverse, (seen.0 - lit_term.0, seen.1 - lit_term.1));
                dz[slot] = model.slopes(zs, f, lit[slot], basis.v);
                z[slot] = zs;
            }
        }
        velocity[x] = u;
        brightness[x] = kappa;
        // A pixel the step leaves as it was (still, and not corrected before: most of a scene)
        // keeps its phases and amplitudes, without recomputing them.
        let changed = moving | corrected_before;
        let cheb = if changed {
            let cheb = chebyshev3(z, step.gain2);
            ph0[x] = cheb.phase[0];
            ph1[x] = cheb.phase[1];
            ph2[x] = cheb.phase[2];
            am0[x] = cheb.amplitude[0];
            am1[x] = cheb.amplitude[1];
            am2[x] = cheb.amplitude[2];
            cheb
        } else {
            chebyshev3_of(z, phases, amps, step.gain2)
        };
        if !LAST {
            // The next step's evidence, from the corrected phasors. The flags still hold stage
            // 1's signal reasons alone.
            let keep = if flags[x] == 0 { 1.0 } else { 0.0 };
            let dz = if moving {
                dz
            } else {
                basis.slopes_at_rest(still, lit)
            };
            let ev = evidence_with(z, dz, &cheb, keep, (u, kappa));
            uu[x] = ev.uu;
            uk[x] = ev.uk;
            kk[x] = ev.kk;
            ue[x] = ev.ue;
            ke[x] = ev.ke;
            count[x] = keep;
            continue;
        }
        // The offset image without the fringe that the motion leaked into it.
        let mut leak = [0.0; 3];
        for slot in (0..3).filter(|_| moving) {
            let g = basis.f_rad_per_px[slot] * u;
            let mut r = 0.0;
            for k in 0..3 {
                let (s, cs) =
                    sin_cos_small((g * basis.tau_s[k]).clamp(-MAX_TURN_RAD, MAX_TURN_RAD));
                let (dx, dy) = basis.d[k];
                let scale = 1.0 + kappa * basis.tau_s[k];
                // d_kᵀ·R(gτ_k)·z, scaled by the frame's brightness, less the still d_kᵀ·z
                // (which the offset row cancels).
                let turned = (dx * cs + dy * s, -dx * s + dy * cs);
                r += basis.offset_row[k]
                    * (scale * cross_dot(turned, z[slot]) - cross_dot(basis.d[k], z[slot]));
            }
            leak[slot] = r;
        }
        co0[x] = offsets[0] - dot3(basis.mix_of_slot_row(0), leak);
        co1[x] = offsets[1] - dot3(basis.mix_of_slot_row(1), leak);
        co2[x] = offsets[2] - dot3(basis.mix_of_slot_row(2), leak);
        let min_amp = cheb.amplitude[0]
            .min(cheb.amplitude[1])
            .min(cheb.amplitude[2]);
        let low = min_amp.is_nan() | (min_amp < step.min_amplitude);
        let unexplained = !within | (worst_det < MIN_DET);
        let saturated = flags[x] & invalid::SATURATED != 0;
        let reason = bit(low, invalid::LOW_AMPLITUDE)
            + bit(saturated, invalid::SATURATED)
            + bit(inconsistent(&cheb, step.limit), invalid::DISAGREEMENT)
            + bit(unexplained, invalid::MOTION);
        let keep = if reason == 0.0 { 1.0 } else { 0.0 };
        // Only a valid pixel's motion is reported.
        velocity[x] = u * keep;
        brightness[x] = kappa * keep;
        acceleration[x] *= keep;
        kk[x] = keep;
        uu[x] = cheb.unit.0 * keep;
        uk[x] = cheb.unit.1 * keep;
        flags[x] = whole_to_byte(reason);
    }
}

/// Moves each valid pixel's coordinate from the window's mean to its centre time.
///
/// Under an acceleration `a` the coordinate is `x_c + u·τ + a·τ²/2`, and the three-step solve
/// (with or without the linear model) returns the phase of the frames' mean coordinate, `x_c +
/// a·mean(τ²)/2`, at every frequency alike: the Chebyshev residual cannot see it, and it is a
/// shift of the depth, largest where the tremor turns back. Measured on the rig at a 10 mm
/// tremor, the decoded coordinate of moving skin was off by 1.01 times that shift (0.115 px
/// RMS of a 0.168 px error). `a` comes from the patch velocities of consecutive windows
/// (stored by the last step), not from the window itself: its ripple on the phases is a third
/// of the shift and orthogonal to the velocity's, too weak to estimate per patch. Correcting
/// the phasors for it as well (turns `u·τ + a·τ²/2` in `M`) gave the same shift but lost 0.45
/// points of the moving skin at 10 mm to the rounding margin, so only the coordinate moves.
pub(crate) fn remove_acceleration_shift(basis: &MotionBasis, out: &mut DecodeOutput) {
    let half_mean_tau2 = 0.5 * basis.mean_tau2_s2;
    out.coordinate_px
        .par_iter_mut()
        .zip(out.acceleration_px_per_s2.par_iter())
        .for_each(|(x, a)| *x -= a * half_mean_tau2);
}

/// `aᵀ·b` of two 2-vectors.
#[inline(always)]
fn cross_dot(a: (f32, f32), b: (f32, f32)) -> f32 {
    a.0 * b.0 + a.1 * b.1
}

#[inline(always)]
fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
