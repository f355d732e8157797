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
//! **A step is kept only where it does not break the pixel.** A Gauss–Newton step is accepted
//! where it improves the fit; here the fit is the patch's, and a second step's patch velocity
//! can still be wrong for one of its pixels (a patch that straddles skin moving at different
//! speeds, as the sides of a swaying finger do). Where a pixel's first correction passed the
//! Chebyshev test and the second one fails it, the pixel keeps the first, redone at its
//! `(u, κ)`, rather than be refused. Only that case: choosing whichever of the two corrections
//! fits the pixel better everywhere kept 0.7 points more of the swaying hand but picked the
//! noise too (10 mm tremor RMS 0.165 → 0.174 mm, 20 mm gross errors 0.38 → 0.75 %). Measured
//! on the motion sweep (docs/accuracy.md, Motion, stop 51): the swaying hand keeps 0.2–0.4
//! points more of its moving skin, with the same gross errors; the optical-axis rows do not
//! change. The second step was losing 0.9 % of the moving skin that the first had kept (and
//! gaining 0.5 %), most of it to the Chebyshev test; with the rule it loses 0.6 %.
//!
//! **The pixel's own brightness change.** A patch's one `κ` is the model's weakest value:
//! brightness changes with the skin's turn against the projector, which differs from pixel to
//! pixel across a finger, and on the rig the patch's `κ` follows the true one with a slope of
//! 0.7–0.8 (its velocity is not the limit: with the true per-pixel velocity the moving skin is
//! measured no better; with the true per-pixel `κ` the swaying hand's RMS falls by a fifth to a
//! quarter). A second, independent measurement is in the offsets: each window's offset image
//! (the pattern's mean) is the pixel's lit light at the window's centre, once the fringe the motion
//! leaked into it is taken out, so consecutive windows give `κ = (L − L_prev)/(Δt·L)` per
//! pixel, `L` the sum of the slots' projector-lit offsets, half a frame late and disturbed by
//! what a wrong velocity leaks. On the last step (refining, after the window just before) each
//! moving pixel takes `(1 − w)·κ_patch + w·κ_offsets` with `w` =
//! [`super::MotionParams::offset_brightness_weight`] (0.4: the two estimates' measured errors
//! weigh 0.35–0.55 by inverse variance), this window's offsets taken without the leak of the
//! first step's correction. A measured change beyond the model's range (at an outline the pixel
//! may have seen another surface) or without a previous window is not taken. Measured on the
//! motion sweep (docs/accuracy.md, Motion, stop 52): every row keeps more of its moving skin
//! with no more gross errors, the swaying hand 97.2–98.3 % at 0.18–0.20 mm (stop 51: 96.9–98.0 %,
//! 0.20–0.21 mm), the 10 mm tremor 98.4 % at 0.160 mm (98.0 %, 0.165 mm).
//!
//! **Started from the window before** ([`super::MotionParams::predicted_start`],
//! `decode/motion_predict.rs`). The residual grows faster than the velocity on the side where
//! the three-step window turns singular (π/3 per frame), so two steps from rest fall short
//! there. After the window just before, a first step takes each pixel's patch velocity in that
//! window (where that patch moved) and corrects from it, and the configured steps refine: the
//! 20 mm tremor keeps 85.1 % of its moving skin where it kept 82.1 %, the swaying hand's RMS
//! falls by 1–2 %, for 0.5–3 ms more per 640×400 window (docs/accuracy.md, Motion, stop 54).
//!
//! **Opt-in: the brightness change carried with the image** ([`super::MotionParams::advected_brightness`],
//! `decode/motion_advect.rs`, CPU only). Where the patch's `κ` is off is mostly near outlines,
//! and not by the noise (without camera noise the swaying hand keeps most of its error): much
//! of the per-pixel variation is the skin's light sliding across the pixels, `κ(p) = κ₀ +
//! v·∇ln L(p)`. With it on, the last step also solves each patch for `v` and gives each moving
//! pixel the change its own lit gradient makes: the swaying hand's RMS falls by 8–9 % (0 mm
//! with sway 0.192 → 0.177 mm, 10 mm with sway 0.196 → 0.180 mm) and the optical-axis rows are
//! unchanged to 3 µm, for about 5–6 ms more per 640×400 window (docs/accuracy.md, Motion,
//! stop 53). It stays opt-in until the GPU does the same and its sums cost less.
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

use super::motion_advect::{apply_advection, sum_advection};
pub use super::motion_basis::{MotionBasis, MAX_TURN_RAD};
use super::motion_blocks::step_in_blocks;
use super::motion_correct::{correct_row, RowPlanes, Step};
pub(crate) use super::motion_evidence::{chebyshev3, evidence, gain2, inconsistent};
use super::motion_predict::correct_predicted_row;
use super::smooth::{smooth_apart, smooth_planes, Planes};
use super::{DecodeOutput, DecodeParams, WindowSolver};
use rayon::prelude::*;

/// Smallest `det(M + κN)` accepted: below it the correction amplifies the noise by more than
/// 2.5×.
pub(super) const MIN_DET: f32 = 0.4;
/// χ² (two degrees of freedom) of a patch's `(u, κ)` against rest above which the motion is
/// taken as real: exceeded by chance with probability 10⁻⁴. Against the noise the window shows
/// (`motion_noise`), a still hand at σ 2–4 keeps no velocity at this level (at 10⁻³, 78 pixels
/// at σ = 4: a patch or two by chance), and the noise sweep's robust rows with checks on are
/// those of 10⁻⁶ to every printed digit. The swaying hand's slow skin (the fingertip slides 0.5–0.8
/// projector px a frame) passes it where 10⁻⁶ left it uncorrected (docs/accuracy.md, Motion,
/// stop 50). The level 10⁻⁶ had been kept for corrupted frames, which the motion model takes
/// for motion; their windows are now refused whole (`broken`).
pub(super) const MOTION_SIGNIFICANCE: f32 = 18.4;
/// The prior of a patch's velocity and brightness change before its evidence: zero, with
/// these standard deviations (px/s and 1/s; a 20 mm tremor at 6 Hz peaks near 750 px/s on the
/// paper's rig, a finger's side swaying 4 mm near 40/s). A patch with little evidence (the
/// ends of the projector's range, where the Chebyshev residual cannot see motion) then stays
/// near rest instead of fitting its noise.
const PRIOR_VELOCITY_PX_PER_S: f32 = 400.0;
pub(super) const PRIOR_BRIGHTNESS_RATE_PER_S: f32 = 20.0;
/// Smallest shift of the window's mean coordinate from its centre coordinate (`a·mean(τ²)/2`,
/// projector px) from which the acceleration is applied in full (from half of it in part,
/// [`acceleration_onset`]): below it the correction is within the noise of the coordinate, and a
/// still surface keeps the still solution. (The velocity change
/// is not tested against its own noise: consecutive windows share two frames, so the noise of
/// the change is far below what two independent estimates would have, and at a 10 mm tremor a
/// χ² test at 10⁻⁶ kept the acceleration at 9 % of the moving skin, removing a fifth of the
/// bias instead of nine tenths.)
pub(super) const MIN_ACCELERATION_SHIFT_PX: f32 = 0.05;

/// The share of its acceleration a pixel takes, from the shift it makes (projector px): all
/// from [`MIN_ACCELERATION_SHIFT_PX`] up, none below half of it, in proportion between, so that
/// the coordinate has no step at the threshold. (With a hard threshold a shift that crossed it
/// by a rounding error moved the coordinate by the whole 0.05 px: the CPU and the GPU once
/// differed so on one pixel. On the 640×400 motion sweep's 2–20 mm rows the ramp changes no
/// printed figure; one from the threshold to twice it raised the 10 mm RMS by 2 µm.)
#[inline]
pub(super) fn acceleration_onset(shift_px: f32) -> f32 {
    let half = 0.5 * MIN_ACCELERATION_SHIFT_PX;
    ((shift_px - half) / half).clamp(0.0, 1.0)
}

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
    let decay = params.motion_decay_at(out.width);
    let constants = StepConstants::new(basis, noise_gray, previous_s);
    let step = Step {
        basis,
        gain2: gain2(solver),
        limit: params.max_disagreement_chi2 * params.camera_noise_gray.powi(2),
        min_amplitude: params.min_amplitude,
        kind,
        last,
        inv_noise2: constants.inv_noise2,
        prior_u: constants.prior_u,
        prior_k: constants.prior_k,
        inv_since: constants.inv_since,
        shift_per_velocity_change: constants.shift_per_velocity_change,
        max_velocity_change: constants.max_velocity_change,
        offset_brightness_weight: if kind == StepKind::Refine && last && previous_s.is_some() {
            params.motion.offset_brightness_weight
        } else {
            0.0
        },
    };
    let block = params.motion.block_size();
    if block > 1 {
        step_in_blocks(&step, decay, block, out);
        return;
    }
    // The brightness change carried with the image (opt-in): its sums before the step's.
    let advected = kind == StepKind::Refine && last && params.motion.advected_brightness;
    if advected {
        sum_advection(basis, out, decay);
    }
    if kind != StepKind::Predicted {
        smooth_planes(&mut Planes::of_unit_phasor(out), decay);
        // The evidence planes are taken out of the output while its scratch sums them.
        let n = out.width * out.height;
        let mut evidence = std::mem::take(&mut out.motion_evidence);
        let (e0, rest) = evidence.split_at_mut(n);
        let (e1, e2) = rest.split_at_mut(n);
        smooth_apart(out, [e0, e1, &mut e2[..n]], decay);
        out.motion_evidence = evidence;
    }
    if advected {
        apply_advection(&step, out);
    }
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
        .zip(out.lit_offset_sum.par_chunks_mut(w))
        .for_each(
            |(
                (
                    (
                        (
                            (
                                (
                                    (
                                        (
                                            (
                                                ((((((phase, amp), colour), re), im), support), ue),
                                                ke,
                                            ),
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
                ),
                lit_sum,
            )| {
                let correct = if step.kind == StepKind::Predicted {
                    correct_predicted_row
                } else {
                    correct_row
                };
                correct(
                    &step,
                    RowPlanes {
                        phase: split3(phase, w),
                        amp: split3(amp, w),
                        offset: split3(colour, w),
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
                        lit_sum,
                    },
                );
            },
        );
}

/// The time since the previous window of a stream when it was the one just before (a frame
/// interval earlier, within a quarter of one), else `None` (NaN times compare false): only
/// then do its patch velocities give an acceleration, and its coordinates references
/// ([`super::temporal`]).
pub fn consecutive_since(time_s: f64, previous_time_s: f64, frame_interval_s: f32) -> Option<f32> {
    let since_s = (time_s - previous_time_s) as f32;
    ((since_s - frame_interval_s).abs() < 0.25 * frame_interval_s).then_some(since_s)
}

/// The constants of a window's Gauss–Newton steps that depend on its noise and on the window
/// before it; the CPU's steps and the GPU's take the same.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepConstants {
    /// The priors' information in the units of the evidence (`σ²/sd²`).
    pub prior_u: f32,
    pub prior_k: f32,
    /// `1/σ²` of the noise the significance test uses.
    pub inv_noise2: f32,
    /// `1/Δt` to the previous window (0: none, no acceleration).
    pub inv_since: f32,
    /// The largest velocity change over that Δt taken as acceleration, px/s.
    pub max_velocity_change: f32,
    /// The shift of the window's mean coordinate per unit of velocity change, s.
    pub shift_per_velocity_change: f32,
}

impl StepConstants {
    /// For a window of `basis` whose significance test uses `noise_gray`, `previous_s` after
    /// the stream's previous window ([`consecutive_since`]).
    pub fn new(basis: &MotionBasis, noise_gray: f32, previous_s: Option<f32>) -> Self {
        Self {
            prior_u: (noise_gray / PRIOR_VELOCITY_PX_PER_S).powi(2),
            prior_k: (noise_gray / PRIOR_BRIGHTNESS_RATE_PER_S).powi(2),
            inv_noise2: noise_gray.powi(-2),
            inv_since: previous_s.map_or(0.0, |s| 1.0 / s),
            shift_per_velocity_change: previous_s.map_or(0.0, |s| 0.5 * basis.mean_tau2_s2 / s),
            max_velocity_change: previous_s.map_or(0.0, |s| {
                std::f32::consts::TAU * MAX_OSCILLATION_HZ * s * basis.max_velocity
            }),
        }
    }
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
    /// From rest, to the motion predicted from the previous window (`motion_predict`): only
    /// the pixels with a prediction, their sums written from it, unsmoothed.
    Predicted,
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

/// The first `w` values of each of the three planes of a row-planar row of `3·w` values.
pub(super) fn split3(row: &mut [f32], w: usize) -> [&mut [f32]; 3] {
    let (a, rest) = row.split_at_mut(w);
    let (b, c) = rest.split_at_mut(w);
    [&mut a[..w], &mut b[..w], &mut c[..w]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_acceleration_sets_in_without_a_step() {
        assert_eq!(acceleration_onset(0.0), 0.0);
        assert_eq!(acceleration_onset(0.5 * MIN_ACCELERATION_SHIFT_PX), 0.0);
        assert_eq!(acceleration_onset(MIN_ACCELERATION_SHIFT_PX), 1.0);
        assert_eq!(acceleration_onset(10.0), 1.0);
        // The shift the pixel takes, onset × shift, grows by no more than three times the step
        // (its slope, (2·shift − half)/half, is 3 at the threshold) on a fine grid through it:
        // no jump.
        let step_px = 1e-5;
        let mut previous = 0.0f32;
        for k in 0..20_000 {
            let shift = k as f32 * step_px;
            let taken = acceleration_onset(shift) * shift;
            assert!(taken >= previous, "{shift}");
            assert!(
                taken - previous <= 3.0 * step_px + 1e-6,
                "{shift}: {previous} → {taken}"
            );
            previous = taken;
        }
    }
}
