//! The camera noise the motion model's significance test uses: the configured level, or the
//! level the window's own Chebyshev residuals show when that is higher.
//!
//! The motion model keeps a patch's velocity only where it differs from rest by more than the
//! noise ([`super::motion`]). That test is only as good as its noise level: told σ = 2 gray
//! levels on a camera at σ = 4, it took noise for motion on a still hand and left 7,277 wrong
//! fringe orders in a 640×400 window (`tests/accuracy.rs`). The still window's checks are far
//! less sensitive to the level, so an operator's setting that is too low went unnoticed.
//!
//! On a still pixel the Chebyshev residual `e = φ_0 − 2φ_1 + φ_2` is normal with variance
//! `v·σ²`, `v` known from the amplitudes ([`super::motion_evidence::Chebyshev3::var_over_noise`]), so
//! `e²/v` is `σ²` times a χ² variable of one degree of freedom, whose median is 0.455. The
//! median of `e²/v` over a grid of the window's pixels with a valid signal, divided by 0.455,
//! estimates `σ²`. Most of a scene is still, and the median ignores the moving minority (a
//! hand whose moving skin covered half the sampled pixels would raise the estimate, which only
//! makes the test stricter). The grid takes every [`GRID_STEP_PX`]-th pixel of every
//! [`GRID_STEP_PX`]-th row, about 1/50 of the window.

use super::fastmath::{atan2, sin_cos_phase};
use super::motion::{chebyshev3, gain2};
use super::{DecodeOutput, WindowSolver};

/// Sampling step of the grid, px, in both directions.
pub const GRID_STEP_PX: usize = 7;
/// Median of a χ² variable with one degree of freedom.
const CHI2_1_MEDIAN: f32 = 0.4549;
/// Fewest sampled pixels for an estimate; with fewer the configured level stands.
const MIN_SAMPLES: usize = 64;

/// The noise level, gray levels, that the window's stage-1 phases and amplitudes in `out` show,
/// or `None` with too few pixels to tell. `scratch` is reused between windows.
pub fn residual_noise_gray(
    solver: &WindowSolver,
    out: &DecodeOutput,
    scratch: &mut Vec<f32>,
) -> Option<f32> {
    if out.frequencies != 3 {
        return None;
    }
    let g2 = gain2(solver);
    let w = out.width;
    scratch.clear();
    for y in (GRID_STEP_PX / 2..out.height).step_by(GRID_STEP_PX) {
        for x in (GRID_STEP_PX / 2..w).step_by(GRID_STEP_PX) {
            if out.invalid[y * w + x] != 0 {
                continue;
            }
            let z: [(f32, f32); 3] = std::array::from_fn(|slot| {
                let (s, c) = sin_cos_phase(out.phase_at(slot, x, y));
                let a = out.amplitude_at(slot, x, y);
                (a * c, a * s)
            });
            let cheb = chebyshev3(z, g2);
            let e = atan2(cheb.t.1, cheb.t.0);
            let scaled = e * e / cheb.var_over_noise;
            if scaled.is_finite() {
                scratch.push(scaled);
            }
        }
    }
    noise_from_scaled_residuals(scratch)
}

/// The noise level, gray levels, that the grid's scaled residuals `e²/v` show (finite values
/// only, in any order; reordered here), or `None` with fewer than [`MIN_SAMPLES`]. The GPU
/// decode gathers the same values on the device and finishes here.
pub fn noise_from_scaled_residuals(scaled: &mut [f32]) -> Option<f32> {
    if scaled.len() < MIN_SAMPLES {
        return None;
    }
    let mid = scaled.len() / 2;
    let (_, median, _) = scaled.select_nth_unstable_by(mid, f32::total_cmp);
    Some((*median / CHI2_1_MEDIAN).sqrt())
}

/// The noise the significance test uses: the level the window shows (`measured`), or the
/// `configured` one where that is higher or nothing was measured.
pub fn significance_noise_gray(measured: Option<f32>, configured: f32) -> f32 {
    measured.map_or(configured, |m| m.max(configured))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;
    use crate::decode::{phasor, DecodeParams};
    use crate::rig::{NoiseModel, RigConfig, VirtualRig};

    /// Stage 1 of the rig's first window at camera noise `sigma`, then the estimate.
    fn estimate(sigma: f64) -> f32 {
        let mut config = RigConfig::paper(320, 200).unwrap();
        config.noise = NoiseModel::gaussian(sigma);
        if let Some(hand) = config.scene.hand.as_mut() {
            hand.tip_amplitude_mm = 0.0;
            hand.hand_amplitude_mm = 0.0;
        }
        let seq = config.default_sequence().unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        let frames: Vec<_> = (0..3)
            .map(|i| {
                let mut f = rig.blank_frame();
                rig.render(i, &mut f, None).unwrap();
                f
            })
            .collect();
        let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
        let mut out = DecodeOutput::new(320, 200, &solver);
        let params = DecodeParams::default();
        // With the motion model stage 1 flags signal reasons alone, not the residual.
        let basis = crate::decode::motion_basis(&solver, &frames, &params);
        assert!(basis.is_some());
        phasor::solve_phasors(&solver, &frames, &params, true, basis.as_ref(), &mut out);
        residual_noise_gray(&solver, &out, &mut Vec::new()).unwrap()
    }

    #[test]
    fn the_residuals_give_the_camera_noise() {
        // The 8-bit camera and the 6-bit projector add about a third of a gray level in
        // quadrature, so the estimate sits a little above σ; it must follow σ, not a setting.
        for sigma in [2.0, 4.0, 6.0] {
            let s = estimate(sigma);
            println!("σ = {sigma}: estimated {s:.3}");
            assert!((f64::from(s) / sigma - 1.0).abs() < 0.15, "σ {sigma}: {s}");
        }
    }

    #[test]
    fn too_few_pixels_give_no_estimate() {
        let config = RigConfig::paper(320, 200).unwrap();
        let seq = config.default_sequence().unwrap();
        let solver = WindowSolver::new(&seq, &[0, 1, 2], &config.cross_talk).unwrap();
        let mut out = DecodeOutput::new(320, 200, &solver);
        // Every pixel refused by stage 1.
        out.invalid.fill(crate::decode::invalid::LOW_AMPLITUDE);
        assert_eq!(residual_noise_gray(&solver, &out, &mut Vec::new()), None);
    }
}
