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
//! ([`PREDICTION_WEIGHT`]), and the step runs without its edge-aware sums. It corrects the pixel
//! there and writes the evidence linearised there; the configured steps then refine from it as
//! from any step, each testing its patch's velocity against rest. Elsewhere (a still patch, a
//! stream's first window, a window after a drop) the first step leaves the still solution and
//! writes the evidence at rest, as stage 1 did.
//!
//! **What was measured** (docs/accuracy.md, Motion, stop 54). The previous window's
//! acceleration (carrying the velocity on by `a·Δt`) and its brightness change as well moved
//! the 20 mm row by 0.2 points of coverage and the swaying rows by 0.1 points and 2 µm; they are
//! left out, so that the GPU, whose planes keep what a pixel refused after the motion step had,
//! starts from the same values.

use super::DecodeOutput;
use rayon::prelude::*;

/// The weight of the written evidence (in the units of the evidence, `1/σ²` per pixel): far
/// above the priors and any patch's sums, so that the patch solve returns the prediction to
/// within rounding, and its significance test passes wherever the prediction is not rest.
pub const PREDICTION_WEIGHT: f32 = 1.0e9;

/// Writes into the step's sums (`unit_re`, `unit_im`, `support` and `motion_evidence`) the
/// evidence of each pixel's predicted velocity: its patch velocity in the previous window where
/// that patch moved, else rest, and no brightness change.
pub(crate) fn predicted_sums(out: &mut DecodeOutput) {
    let n = out.width * out.height;
    let (ue, rest) = out.motion_evidence.split_at_mut(n);
    let (ke, count) = rest.split_at_mut(n);
    out.unit_re
        .par_iter_mut()
        .zip(out.unit_im.par_iter_mut())
        .zip(out.support.par_iter_mut())
        .zip(ue.par_iter_mut())
        .zip(ke.par_iter_mut())
        .zip(count[..n].par_iter_mut())
        .zip(out.patch_velocity_px_per_s.par_iter())
        .zip(out.patch_moving.par_iter())
        .for_each(
            |(((((((uu, uk), kk), ue), ke), count), &patch_u), &moving)| {
                let u = if moving != 0 && patch_u.is_finite() {
                    patch_u
                } else {
                    0.0
                };
                *uu = PREDICTION_WEIGHT;
                *uk = 0.0;
                *kk = PREDICTION_WEIGHT;
                *ue = PREDICTION_WEIGHT * u;
                *ke = 0.0;
                *count = 1.0;
            },
        );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    #[test]
    fn the_written_sums_solve_to_the_previous_windows_moving_patches() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let cross_talk = crate::color::CrossTalk::paper();
        let solver = WindowSolver::new(&seq, &[0, 1, 2], &cross_talk).unwrap();
        let mut out = DecodeOutput::new(5, 1, &solver);
        out.patch_velocity_px_per_s = vec![312.5, f32::NAN, 250.0, -97.25, 40.0];
        out.patch_moving = vec![1, 1, 0, 1, 1];
        out.unit_re.fill(f32::NAN);
        predicted_sums(&mut out);
        // The patch solve of the step (`motion_correct::patch_step`) with the priors of a
        // window whose noise is 1 gray level (the largest they get: σ²/sd², sd 400 px/s and
        // 20/s) and the significance test it applies.
        let (prior_u, prior_k) = (1.0 / 400f32.powi(2), 1.0 / 20f32.powi(2));
        let n = out.width;
        for (x, expected) in [312.5, 0.0, 0.0, -97.25, 40.0].into_iter().enumerate() {
            let (a, b, c) = (
                out.unit_re[x] + prior_u,
                out.unit_im[x],
                out.support[x] + prior_k,
            );
            let (ru, rk, count) = (
                out.motion_evidence[x],
                out.motion_evidence[n + x],
                out.motion_evidence[2 * n + x],
            );
            let det = a * c - b * b;
            assert!(det > 0.0 && count > 0.0, "pixel {x}: solvable");
            let (u, kappa) = ((c * ru - b * rk) / det, (a * rk - b * ru) / det);
            assert!(
                (u - expected).abs() <= 1e-5 * expected.abs(),
                "pixel {x}: {u}"
            );
            assert_eq!(kappa, 0.0, "pixel {x}");
            // Moving wherever the prediction is not rest, at any noise the windows show (the
            // significance is χ² over σ², here at σ = 100 gray levels).
            let significance = (a * u * u + 2.0 * b * u * kappa + c * kappa * kappa) / 1e4;
            assert_eq!(
                significance > crate::decode::motion::MOTION_SIGNIFICANCE,
                expected != 0.0,
                "pixel {x}"
            );
        }
    }
}
