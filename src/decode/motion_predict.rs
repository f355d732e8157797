//! The motion model's first step, started from the stream's window just before.
//!
//! **Why.** The Gauss–Newton steps of [`super::motion`] start from rest, and the Chebyshev
//! residual they linearise grows faster than the velocity on the side where the three-step
//! window turns singular (a turn of π/3 per frame at the highest frequency, where the fringe
//! moves half a period a frame). There two steps fall short: at a 20 mm tremor the skin turning
//! 0.6–0.8 rad a frame kept 18 % of its pixels after two steps, 71 % after three and 89 % after
//! four (`motion_breakdown`, `ITERATIONS`). The window just before shares two of this window's
//! frames, and where the motion is fastest it is also steadiest (the tremor's acceleration is
//! zero at its peak velocity), so its patch velocity is a starting point most of the way there.
//!
//! **How.** The first step takes each pixel's patch velocity from the previous window, where
//! that patch moved (significant and solved), as its patch solution: the sums the step solves
//! are written as evidence of that velocity so strong that the patch solve returns it
//! ([`PREDICTION_WEIGHT`]), and the step runs without its edge-aware sums, over those pixels
//! only. It corrects each there and writes the evidence linearised there; the configured steps
//! then refine from it as from any step, each testing its patch's velocity against rest.
//! Every other pixel keeps the still solution and stage 1's evidence at rest, so a window with
//! nothing predicted decodes as from rest, bit for bit (the rig's still hand has a few chance
//! patches moving, whose pixels and neighbours differ: `tests/motion_predicted_start.rs`). A
//! stream's first window and one after a drop start from rest.
//!
//! **What was measured** (docs/accuracy.md, Motion, stop 54). The previous window's
//! acceleration (carrying the velocity on by `a·Δt`) and its brightness change as well moved
//! the 20 mm row by 0.2 points of coverage and the swaying rows by 0.1 points and 2 µm; they are
//! left out, so that the GPU, whose planes keep what a pixel refused after the motion step had,
//! starts from the same values.

use super::motion_correct::{run_gathered, RowPlanes, Step, BLOCK};
use super::motion_moving::{copy_pixel, Gathered};

/// The weight of the written evidence (in the units of the evidence, `1/σ²` per pixel): far
/// above the priors and any patch's sums, so that the patch solve returns the prediction to
/// within rounding, and its significance test passes wherever the prediction is not rest.
pub const PREDICTION_WEIGHT: f32 = 1.0e9;

/// The velocity a pixel starts from: its patch velocity in the previous window where that
/// patch moved (significant and solved), else none.
#[inline(always)]
pub(super) fn predicted_velocity(patch_velocity: f32, patch_moving: u8) -> Option<f32> {
    (patch_moving != 0 && patch_velocity.is_finite() && patch_velocity != 0.0)
        .then_some(patch_velocity)
}

/// The step's sums `(uu, uk, kk, ue, ke, count)` that are evidence of velocity `u` and no
/// brightness change, so strong that the patch solve returns them.
pub(super) fn sums_of(u: f32) -> [f32; 6] {
    [
        PREDICTION_WEIGHT,
        0.0,
        PREDICTION_WEIGHT,
        PREDICTION_WEIGHT * u,
        0.0,
        1.0,
    ]
}

/// The predicted step over one row (`step` from rest, not the last): every pixel with a
/// predicted velocity gets its sums written and the full model there (gathered, as the steps'
/// second pass runs it), which leaves its correction and its evidence there for the next step;
/// every other pixel keeps stage 1's evidence at rest and no motion, as a step from rest that
/// found it still would leave it.
pub(super) fn correct_predicted_row(step: &Step<'_>, mut row: RowPlanes<'_>) {
    let w = row.flags.len();
    let mut gathered = Gathered::default();
    let mut m = 0;
    for x in 0..w {
        let Some(u) = predicted_velocity(row.patch_velocity[x], row.patch_moving[x]) else {
            row.velocity[x] = 0.0;
            row.brightness[x] = 0.0;
            continue;
        };
        [
            row.uu[x],
            row.uk[x],
            row.kk[x],
            row.ue[x],
            row.ke[x],
            row.count[x],
        ] = sums_of(u);
        if m == BLOCK {
            run_gathered(step, &mut gathered, m, &mut row);
            m = 0;
        }
        gathered.index[m] = x;
        copy_pixel(&row, x, &mut gathered.planes(), m);
        m += 1;
    }
    if m > 0 {
        run_gathered(step, &mut gathered, m, &mut row);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_written_sums_solve_to_the_previous_windows_moving_patches() {
        // (patch velocity, moving) → the velocity the step starts from.
        let cases = [
            (312.5, 1, Some(312.5)),
            (f32::NAN, 1, None),
            (250.0, 0, None),
            (-97.25, 1, Some(-97.25)),
            (0.0, 1, None),
        ];
        // The patch solve of the step (`motion_correct::patch_step`) with the priors of a
        // window whose noise is 1 gray level (the largest they get: σ²/sd², sd 400 px/s and
        // 20/s), and its significance test at a noise of 100 gray levels.
        let (prior_u, prior_k) = (1.0 / 400f32.powi(2), 1.0 / 20f32.powi(2));
        for (patch_u, moving, expected) in cases {
            assert_eq!(predicted_velocity(patch_u, moving), expected, "{patch_u}");
            let Some(expected) = expected else { continue };
            let [uu, uk, kk, ue, ke, count] = sums_of(expected);
            let (a, b, c) = (uu + prior_u, uk, kk + prior_k);
            let det = a * c - b * b;
            assert!(det > 0.0 && count > 0.0, "{patch_u}: solvable");
            let (u, kappa) = ((c * ue - b * ke) / det, (a * ke - b * ue) / det);
            assert!(
                (u - expected).abs() <= 1e-5 * expected.abs(),
                "{patch_u}: {u}"
            );
            assert_eq!(kappa, 0.0, "{patch_u}");
            let significance = (a * u * u + 2.0 * b * u * kappa + c * kappa * kappa) / 1e4;
            assert!(
                significance > crate::decode::motion::MOTION_SIGNIFICANCE,
                "{patch_u}"
            );
        }
    }
}
