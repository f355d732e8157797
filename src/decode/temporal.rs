//! Stage 4b (motion model only): fringe-order consistency of each pixel with its own recent past.
//!
//! The spatial check of [`super::consistency`] only sees a wrong fringe order where it borders
//! connected pixels with the right one. Under motion a whole patch can take the wrong order
//! together, ringed by pixels the other checks already rejected: on the rig's fingertip in a
//! 2 mm tremor with lateral sway, where the velocity is too small for the model's significance
//! test yet moves the still solution's coarse estimate by half a period, a 7×7 patch around the
//! tip came out 29 px (30 mm) off, coherent and valid, in 5 of 361 windows.
//!
//! Time gives a neighbour that no ring of invalid pixels can hide. The model marks a pixel
//! [`invalid::MOTION`] once, by its estimate, a frame turns its finest phase by more than
//! [`super::motion::MAX_TURN_RAD`], i.e. once its coordinate moves by more than
//! `MAX_TURN_RAD/(2π)` of a fringe period per frame (0.16 period, 4.5 px on the paper's rig). So
//! between windows one frame apart a kept pixel moves by at most that step, and within
//! [`MAX_AGE_WINDOWS`] windows by at most two steps (0.32 period), while a wrong fringe order
//! moves it by a whole period more. A pixel whose coordinate moved by a non-zero whole number
//! of periods, give or take a step per window, since the coordinate it last had where valid at
//! most two windows ago took a wrong order now or then; which one cannot be told, so it is
//! marked [`invalid::ORDER_JUMP`] and keeps its reference (a wrong depth is worse than a
//! missing one). A new surface (a finger arriving over the table) moves the coordinate by an
//! arbitrary amount and passes unless that happens to be near a whole number of periods. After
//! two windows the reference is too old to tell the cases apart and the pixel is accepted
//! again.
//!
//! **The cost.** Where a wrong order lasts more than two windows it becomes the reference, and
//! the right order after it is refused for up to two windows. Measured on the rig over 38
//! windows (2 mm tremor with sway): of the pixels this check marks, 31,588 were a fringe off
//! and 29,152 were right against a reference a fringe off; moving skin valid 87.1 → 83.2 %,
//! more than 2 mm off 2.8 → 0.86 %. At a 10 mm tremor without sway: 96.2 → 95.5 % and
//! 0.76 → 0.35 %. Comparing with the previous window only kept more (84.6 %, 95.7 %) and
//! refused fewer wrong orders (1.3 %, 0.45 %).
//!
//! **The same references settle uncertain roundings** ([`settle_margin_from_recent`], run
//! before the check). Under motion the spatial coarse estimate (the smoothed unit phase) is
//! the weak link: the motion model's small per-frequency errors reach the unit phase `n`-fold,
//! and on swaying skin it lands in the rounding margin (0.3 to 0.5 of a period from the fine
//! solution, [`invalid::UNWRAP_MARGIN`]) on 9.2 % of the moving skin at a 10 mm tremor, against
//! 3.5 % without sway; measured on the rig, the coarse error of those pixels has a median of
//! 11.6 px, their fine phases 0.3 px. The pixel's reference, moved on by its patch's velocity
//! over the frames since, is an independent estimate of the same coordinate that is off by
//! less than a pixel where the reference is right. Where it unwraps to the same fringe orders
//! as the spatial estimate's nearest, inside the margin, the two agree and the pixel is kept;
//! where it picks another order nothing is decided. Replayed on the skin's margin pixels with
//! a reference over 13 windows of that tremor (the reference moved on by its own velocity):
//! 26,223 settled right and 404 wrong, nearly all of those from a reference that was itself a
//! fringe off; letting the reference overrule the spatial estimate would have settled 11,989
//! more right and 3,016 more wrong. Moving skin kept (`tremorscan sweep --motion`): 95.6 →
//! 97.6 % at 10 mm, 85.9 → 90.6 % with sway.
//!
//! **The references follow the skin.** A reference is the pixel's last valid coordinate carried
//! forward by its patch's velocity (where the model found the patch moving; else it stays) over
//! every window since, so the check and the settling compare with where the pixel should be
//! now, not where it was. Within one window the difference is at most a step, but a pixel
//! invalid for a window on fast skin had drifted up to two steps from a standing reference,
//! close to the check's tolerance. Measured with `tremorscan sweep --motion`'s protocol (moving
//! skin, valid / more than 2 mm off), standing → carried: 10 mm 97.57 / 0.356 % → 97.57 /
//! 0.338 %, 20 mm 77.31 / 1.57 % → 77.21 / 1.38 %, 10 mm with sway 90.63 / 0.79 % → 90.64 /
//! 0.77 %. Most of what stays wrong has no reference at all: at 10 mm, before this change, 848
//! of the 1030 wrong pixels were invalid for the two windows before (232 of them in the
//! stream's first window, which has no references).
//! Keeping carried references longer trades coverage for fewer wrong orders, since a lasting
//! wrong reference then refuses the right order for longer: 3, 4 and 6 windows gave 97.06 /
//! 0.287 % (4) and 96.52 / 0.296 % (6) at 10 mm, 89.85 / 0.77 % (3) and 89.40 / 0.70 % (4)
//! with sway; two is kept.
//!
//! Only consecutive windows of one stream are compared (the window the check last ran on, one
//! frame interval earlier, by the time stamp kept with the references); any other window
//! starts afresh.

use super::motion::consecutive_since;
use super::unwrap::CpsMaps;
use super::{invalid, DecodeOutput};
use rayon::prelude::*;

/// How many windows back a pixel's last valid coordinate still serves as its reference.
pub const MAX_AGE_WINDOWS: u8 = 2;

/// Marks the pixels whose coordinate moved by a whole number of fringe periods (`period_px`),
/// give or take `max_step_px` per window of age, from their reference carried forward by the
/// patch velocity, then makes every valid pixel its own reference and carries the others'
/// forward. Only a window one frame interval (`frame_interval_s`, within a quarter of one)
/// after the last window this check ran on is tested.
pub(crate) fn flag_temporal_jumps(
    out: &mut DecodeOutput,
    period_px: f32,
    max_step_px: f32,
    frame_interval_s: f32,
) {
    let consecutive = consecutive_since(out.time_s, out.recent_time_s, frame_interval_s).is_some();
    out.recent_time_s = out.time_s;
    let w = out.width;
    let limits = Limits {
        period_px,
        inv_period: 1.0 / period_px,
        max_step_px,
        frame_interval_s,
    };
    out.invalid
        .par_chunks_mut(w)
        .zip(out.coordinate_px.par_chunks_mut(w))
        .zip(out.recent_coordinate_px.par_chunks_mut(w))
        .zip(out.recent_age_windows.par_chunks_mut(w))
        .zip(out.patch_velocity_px_per_s.par_chunks(w))
        .zip(out.patch_moving.par_chunks(w))
        .for_each(|(((((flags, coord), recent), age), velocity), moving)| {
            let reference = Reference {
                coordinate_px: recent,
                age_windows: age,
                velocity_px_per_s: velocity,
                moving,
            };
            row_temporal_jumps(flags, coord, reference, limits, consecutive);
        });
}

/// Keeps the pixels whose only fault is the rounding margin when their own recent past agrees:
/// the spatial coarse coordinate lies between 0.3 and 0.5 of a period from the fine solution,
/// so its fringe order is uncertain, and the reference coordinate (valid at most
/// [`MAX_AGE_WINDOWS`] windows ago, carried forward since), moved on by the patch's velocity
/// over this frame interval, unwraps to the same order at every frequency well inside the
/// margin (`max_residual`). Two independent estimates then pick the same order. With
/// `two_averages` (stage 2 ran both, [`super::smooth_moving`]), a pixel refused because the
/// narrow and wide averages contradicted each other is also settled where the past picks the
/// wide one's orders; the first `width·height` values of `out.motion_evidence` hold its coarse
/// coordinate then. Runs before [`flag_temporal_jumps`], on the same references, and only on a
/// window one frame interval after the last one checked.
pub(crate) fn settle_margin_from_recent(
    out: &mut DecodeOutput,
    cps: &CpsMaps,
    max_residual: f32,
    frame_interval_s: f32,
    two_averages: bool,
) {
    if consecutive_since(out.time_s, out.recent_time_s, frame_interval_s).is_none() {
        return;
    }
    let w = out.width;
    // Stage 2's other estimate: the wide average's coarse coordinate where the two contradicted
    // each other (NaN elsewhere), or none at all.
    let none = [f32::NAN];
    let (wide_px, wide_row) = if two_averages {
        (&out.motion_evidence[..w * out.height], w)
    } else {
        (&none[..], 0)
    };
    let settle = Settle {
        cps: *cps,
        max_residual,
        frame_interval_s,
    };
    out.invalid
        .par_chunks_mut(w)
        .zip(out.coordinate_px.par_chunks_mut(w))
        .zip(out.coarse_px.par_chunks(w))
        .zip(out.phase_rad.par_chunks(3 * w))
        .zip(out.amplitude.par_chunks(3 * w))
        .zip(out.recent_coordinate_px.par_chunks(w))
        .zip(out.recent_age_windows.par_chunks(w))
        .zip(out.patch_velocity_px_per_s.par_chunks(w))
        .zip(out.patch_moving.par_chunks(w))
        .enumerate()
        .for_each(
            |(
                y,
                ((((((((flags, coord), coarse), phase), amp), recent), age), velocity), moving),
            )| {
                let wide = &wide_px[y * wide_row..];
                for x in 0..flags.len() {
                    if flags[x] != invalid::UNWRAP_MARGIN {
                        continue;
                    }
                    let older = age[x].saturating_add(1);
                    if older > MAX_AGE_WINDOWS || !recent[x].is_finite() {
                        continue;
                    }
                    let u = patch_velocity(velocity[x], moving[x]);
                    let phases = [phase[x], phase[w + x], phase[2 * w + x]];
                    let amps = [amp[x], amp[w + x], amp[2 * w + x]];
                    let other = if wide_row == 0 { f32::NAN } else { wide[x] };
                    let agreed = settle
                        .agreed(coarse[x], recent[x], u, phases, amps)
                        .or_else(|| {
                            let other = other.is_finite().then_some(other)?;
                            settle.agreed(other, recent[x], u, phases, amps)
                        });
                    if let Some(c) = agreed {
                        flags[x] = 0;
                        coord[x] = c;
                    }
                }
            },
        );
}

#[derive(Clone, Copy)]
struct Settle {
    cps: CpsMaps,
    max_residual: f32,
    frame_interval_s: f32,
}

impl Settle {
    /// The coordinate unwrapped from the spatial coarse coordinate `coarse` when the reference
    /// `recent` (carried to the previous window), moved on at `u` px/s over one frame interval,
    /// unwraps to the same orders within the margin.
    fn agreed(
        &self,
        coarse: f32,
        recent: f32,
        u: f32,
        phases: [f32; 3],
        amps: [f32; 3],
    ) -> Option<f32> {
        let predicted = recent + u * self.frame_interval_s;
        let spatial = self.cps.unwrap(coarse, phases, amps);
        let temporal = self.cps.unwrap(predicted, phases, amps);
        // Other orders move the combination by about a period; the same orders give the same
        // arithmetic.
        let same_orders = (spatial.combined - temporal.combined).abs() < 0.5;
        (same_orders && temporal.residual <= self.max_residual).then_some(spatial.combined)
    }
}

#[derive(Clone, Copy)]
struct Limits {
    period_px: f32,
    inv_period: f32,
    max_step_px: f32,
    frame_interval_s: f32,
}

/// One row of the references, and the patch velocity that carries them forward.
struct Reference<'a> {
    coordinate_px: &'a mut [f32],
    age_windows: &'a mut [u8],
    velocity_px_per_s: &'a [f32],
    moving: &'a [u8],
}

/// The patch's velocity where the motion model kept it (significant and defined), else rest.
#[inline(always)]
fn patch_velocity(velocity_px_per_s: f32, moving: u8) -> f32 {
    if (moving != 0) & velocity_px_per_s.is_finite() {
        velocity_px_per_s
    } else {
        0.0
    }
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn row_temporal_jumps(
    flags: &mut [u16],
    coord: &mut [f32],
    reference: Reference<'_>,
    limits: Limits,
    consecutive: bool,
) {
    let n = flags.len();
    let coord = &mut coord[..n];
    let (recent, age) = (
        &mut reference.coordinate_px[..n],
        &mut reference.age_windows[..n],
    );
    let (velocity, moving) = (&reference.velocity_px_per_s[..n], &reference.moving[..n]);
    for x in 0..n {
        let older = if consecutive {
            age[x].saturating_add(1)
        } else {
            u8::MAX
        };
        let c = coord[x];
        // The reference carried over this frame interval by the patch's velocity.
        let predicted =
            recent[x] + patch_velocity(velocity[x], moving[x]) * limits.frame_interval_s;
        let moved = c - predicted;
        let periods = (moved * limits.inv_period).round();
        let off = (moved - periods * limits.period_px).abs();
        // NaN on either side compares false: nothing to test.
        let jumped = (older <= MAX_AGE_WINDOWS)
            & (periods != 0.0)
            & (off <= f32::from(older) * limits.max_step_px);
        let keep = c.is_finite() & !jumped;
        flags[x] |= u16::from(jumped) * invalid::ORDER_JUMP;
        // Selects rather than conditional stores, so the loop vectorises.
        coord[x] = if jumped { f32::NAN } else { c };
        recent[x] = if keep { c } else { predicted };
        age[x] = if keep { 0 } else { older };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};
    use std::f32::consts::TAU;

    fn output(w: usize) -> DecodeOutput {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        DecodeOutput::new(w, 1, &solver)
    }

    const INTERVAL_S: f32 = 1.0 / 121.0;

    /// Decodes one "window" `frames` frame intervals after the previous one: sets the time and
    /// the coordinates, clears the flags, runs the check.
    fn window(out: &mut DecodeOutput, coords: &[f32], frames: u32) -> Vec<bool> {
        out.time_s += f64::from(frames) * f64::from(INTERVAL_S);
        out.coordinate_px.copy_from_slice(coords);
        out.invalid.fill(0);
        flag_temporal_jumps(out, 28.0, 4.5, INTERVAL_S);
        out.invalid
            .iter()
            .map(|f| f & invalid::ORDER_JUMP != 0)
            .collect()
    }

    #[test]
    fn a_fringe_jump_in_time_is_marked_and_motion_is_not() {
        let nan = f32::NAN;
        let mut out = output(5);
        // Pixel 0 moves 4 px a window; pixel 1 is a fringe off in the third window; pixel 2 is
        // invalid in between and a fringe off; pixel 3 is a new surface (the coordinate changes
        // by a fraction of a period); pixel 4 stays a fringe off.
        let windows: [[f32; 5]; 5] = [
            [100.0, 100.0, 100.0, 100.0, 100.0],
            [104.0, 101.0, nan, 100.0, 100.0],
            [108.0, 130.0, 129.0, 115.0, 128.0],
            [112.0, 103.0, 103.0, 115.0, 128.0],
            [116.0, 104.0, 104.0, 115.0, 128.0],
        ];
        let marked: Vec<Vec<bool>> = windows.iter().map(|c| window(&mut out, c, 1)).collect();
        let column = |x: usize| marked.iter().map(|m| m[x]).collect::<Vec<_>>();
        assert_eq!(column(0), [false; 5]);
        assert_eq!(column(1), [false, false, true, false, false]);
        assert_eq!(column(2), [false, false, true, false, false]);
        assert_eq!(column(3), [false; 5]);
        // A lasting jump is refused for two windows, then accepted.
        assert_eq!(column(4), [false, false, true, true, false]);
        assert!(out.coordinate_px.iter().all(|c| c.is_finite()));
    }

    #[test]
    fn a_reference_follows_its_patch_through_the_windows_its_pixel_is_invalid() {
        let nan = f32::NAN;
        let mut out = output(3);
        // Pixels 0 and 1 lie on a patch moving 4.4 px a frame, pixel 2 on a still one. All are
        // invalid in the second window; in the third pixel 1 comes back a fringe off.
        let step_px = 4.4f32;
        out.patch_velocity_px_per_s.fill(step_px / INTERVAL_S);
        out.patch_moving.copy_from_slice(&[1, 1, 0]);
        window(&mut out, &[100.0, 100.0, 100.0], 1);
        assert_eq!(window(&mut out, &[nan, nan, nan], 1), [false; 3]);
        // Carried one frame by the patch's velocity; the still patch's stays.
        let carried = 100.0 + step_px;
        assert!((out.recent_coordinate_px[0] - carried).abs() < 1e-3);
        assert!((out.recent_coordinate_px[1] - carried).abs() < 1e-3);
        assert_eq!(out.recent_coordinate_px[2], 100.0);
        assert_eq!(out.recent_age_windows[..], [1, 1, 1]);
        let now = 100.0 + 2.0 * step_px;
        let marked = window(&mut out, &[now, now + 28.0, 100.5], 1);
        assert_eq!(marked, [false, true, false]);
        assert_eq!(out.recent_coordinate_px[0], now);
        assert!((out.recent_coordinate_px[1] - now).abs() < 1e-3);
    }

    /// The rig's CPS-RGB solver, its unwrap maps and the finest period (projector px).
    fn maps() -> (WindowSolver, CpsMaps, f32) {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        let f = &solver.frequency_rad_per_px;
        let cps = CpsMaps::new(f, &solver.noise_gain);
        let period = TAU / f[0];
        (solver, cps, period)
    }

    #[test]
    fn the_recent_past_settles_an_uncertain_rounding_only_when_it_agrees() {
        let (solver, cps, period) = maps();
        let f = &solver.frequency_rad_per_px;
        let w = 4;
        let mut out = DecodeOutput::new(w, 1, &solver);
        // The previous window: every pixel valid at 100 px.
        window(&mut out, &[100.0; 4], 1);
        // This one, a frame later: every pixel moved to 104 px (the patch at 484 px/s), its
        // spatial coarse coordinate 0.4 of a period above (pixels 0, 2, 3) or 0.6 above (1,
        // nearer the next order).
        out.time_s += f64::from(INTERVAL_S);
        let truth = 104.0f32;
        for slot in 0..3 {
            let phase = (f[slot] * truth).rem_euclid(TAU);
            out.phase_rad[slot * w..(slot + 1) * w].fill(phase);
            out.amplitude[slot * w..(slot + 1) * w].fill(50.0);
        }
        out.patch_velocity_px_per_s.fill(484.0);
        out.patch_moving.fill(1);
        let coarse = [0.4, 0.6, 0.4, 0.4].map(|k| truth + k * period);
        out.coarse_px.copy_from_slice(&coarse);
        out.coordinate_px.fill(f32::NAN);
        out.invalid.fill(invalid::UNWRAP_MARGIN);
        // Pixel 2 has another fault too; pixel 3's reference is too old.
        out.invalid[2] |= invalid::DISAGREEMENT;
        out.recent_age_windows[3] = MAX_AGE_WINDOWS;
        settle_margin_from_recent(&mut out, &cps, 0.3, INTERVAL_S, false);
        assert_eq!(out.invalid[0], 0);
        assert!(
            (out.coordinate_px[0] - truth).abs() < 1e-3,
            "{:?}",
            out.coordinate_px
        );
        for x in 1..4 {
            assert_ne!(out.invalid[x], 0, "pixel {x}");
            assert!(out.coordinate_px[x].is_nan(), "pixel {x}");
        }
        // A window that does not follow the last one is left alone.
        out.time_s += 3.0 * f64::from(INTERVAL_S);
        out.invalid[0] = invalid::UNWRAP_MARGIN;
        out.coordinate_px[0] = f32::NAN;
        settle_margin_from_recent(&mut out, &cps, 0.3, INTERVAL_S, false);
        assert_eq!(out.invalid[0], invalid::UNWRAP_MARGIN);
    }

    #[test]
    fn where_the_two_averages_contradicted_the_recent_past_may_side_with_either() {
        let (solver, cps, period) = maps();
        let f = &solver.frequency_rad_per_px;
        let w = 3;
        let truth = 104.0f32;
        // Each pixel's narrow and wide coarse coordinates, in periods from the truth: the wide
        // one right (0), the narrow one right (1), both a period off (2).
        let cases = [(1.0, 0.1), (0.1, 1.0), (1.0, -1.0)];
        let settled = |two_averages: bool| {
            let mut out = DecodeOutput::new(w, 1, &solver);
            window(&mut out, &[truth; 3], 1);
            out.time_s += f64::from(INTERVAL_S);
            for slot in 0..3 {
                let phase = (f[slot] * truth).rem_euclid(TAU);
                out.phase_rad[slot * w..(slot + 1) * w].fill(phase);
                out.amplitude[slot * w..(slot + 1) * w].fill(50.0);
            }
            for (x, &(narrow, wide)) in cases.iter().enumerate() {
                out.coarse_px[x] = truth + narrow * period;
                out.motion_evidence[x] = truth + wide * period;
            }
            out.coordinate_px.fill(f32::NAN);
            out.invalid.fill(invalid::UNWRAP_MARGIN);
            settle_margin_from_recent(&mut out, &cps, 0.3, INTERVAL_S, two_averages);
            let right = |x: usize| (out.coordinate_px[x] - truth).abs() < 1e-3;
            (0..w)
                .map(|x| out.invalid[x] == 0 && right(x))
                .collect::<Vec<_>>()
        };
        assert_eq!(settled(true), [true, true, false]);
        // Without a second average the first pixel has only its narrow one.
        assert_eq!(settled(false), [false, true, false]);
    }

    #[test]
    fn a_window_after_a_gap_is_not_compared() {
        let mut out = output(2);
        window(&mut out, &[100.0, 100.0], 1);
        assert_eq!(window(&mut out, &[128.0, 100.0], 3), [false, false]);
        // ... and it becomes the reference for the next one.
        assert_eq!(window(&mut out, &[100.0, 101.0], 1), [true, false]);
    }
}
