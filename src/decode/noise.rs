//! The camera noise a session shows, measured from its windows, so that the decode's noise
//! assumption ([`super::DecodeParams::camera_noise_gray`]) is the camera's and not a constant.
//!
//! Each well-lit pixel of a sparse grid (every [`GRID_STEP_PX`]-th pixel of every
//! [`GRID_STEP_PX`]-th row; not saturated, every frequency's amplitude at least
//! `min_amplitude`) gives one sample of a residual that is a known multiple of the noise
//! variance σ² of the decoder's observations:
//!
//! * **The window fit's residual**, when the window has more observations than unknowns
//!   (a multi-frequency sequence, CPS-gray with 9 images): `r = c − M·M⁺·c` is the projection
//!   of the noise onto the `d = observations − unknowns` dimensions the model cannot explain, so
//!   `|r|²` is σ² times a χ² variable of `d` degrees of freedom.
//! * **The Chebyshev residual**, when the fit has none (CPS-RGB, CPS-gray with 7 images): the
//!   angle `e = φ_0 − 2φ_1 + φ_2` vanishes on a still surface, with variance `v·σ²`, `v` from
//!   the amplitudes and the solver's noise gains, so `e²/v` is σ² times a χ² variable of one
//!   degree of freedom (as in [`super::motion_noise`], which does this per window on a decoded
//!   output).
//!
//! Each sample is divided by the median of its χ² law, so the median of all samples (pooled
//! over several windows) estimates σ². The median ignores the minority of pixels whose residual
//! is not noise (motion inside the window, mixed pixels at depth edges); a scene that moved
//! almost everywhere would raise the estimate, which only makes the decode's tests more
//! lenient by that much. For gray patterns seen by a colour camera the observation is the mean
//! of the three channels, and σ is that mean's noise.

use super::fastmath::atan2;
use super::motion::{chebyshev3, gain2};
use super::WindowSolver;
use crate::frame::Frame;
use std::borrow::Borrow;

/// Sampling step of the grid, px, in both directions.
pub const GRID_STEP_PX: usize = 7;
/// Fewest samples for an estimate.
pub const MIN_SAMPLES: usize = 200;

/// Which residual a window gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseResidual {
    /// The window fit's residual, with this many degrees of freedom.
    Fit { dof: usize },
    /// The Chebyshev residual of a CPS window.
    Chebyshev,
}

/// The residual `solver`'s windows give, or `None` when they give none (a window with no
/// redundant observation and no Chebyshev triple).
pub fn noise_residual(solver: &WindowSolver) -> Option<NoiseResidual> {
    let dof = solver.observations - solver.unknowns;
    let frequencies = &solver.frequencies;
    if dof > 0 {
        Some(NoiseResidual::Fit { dof })
    } else if frequencies.len() == 3
        && frequencies[0] >= 3
        && frequencies[1] + 1 == frequencies[0]
        && frequencies[2] + 2 == frequencies[0]
    {
        Some(NoiseResidual::Chebyshev)
    } else {
        None
    }
}

/// The median of a χ² variable with `dof` degrees of freedom: tabulated up to 8, beyond by
/// Wilson–Hilferty (within 0.1 % there).
fn chi2_median(dof: usize) -> f64 {
    const EXACT: [f64; 8] = [
        0.454_936, 1.386_294, 2.365_974, 3.356_694, 4.351_460, 5.348_121, 6.345_811, 7.344_121,
    ];
    match dof {
        1..=8 => EXACT[dof - 1],
        _ => {
            let k = dof as f64;
            k * (1.0 - 2.0 / (9.0 * k)).powi(3)
        }
    }
}

/// Appends to `samples` one noise sample (σ² units, see the module header) per well-lit grid
/// pixel of the window `frames` (oldest first, matching `solver.order`). Returns the residual
/// used, or `None` when the window gives none (nothing is appended).
pub fn window_noise_samples<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    min_amplitude: f32,
    saturation_level: u8,
    samples: &mut Vec<f32>,
) -> Option<NoiseResidual> {
    window_noise_samples_every(
        solver,
        frames,
        (min_amplitude, saturation_level),
        GRID_STEP_PX,
        samples,
    )
}

/// [`window_noise_samples`] on a grid of `step_px` (at least 1) instead of [`GRID_STEP_PX`].
pub fn window_noise_samples_every<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    (min_amplitude, saturation_level): (f32, u8),
    step_px: usize,
    samples: &mut Vec<f32>,
) -> Option<NoiseResidual> {
    let step_px = step_px.max(1);
    let residual = noise_residual(solver)?;
    let first: &Frame = frames.first()?.borrow();
    let (w, h) = (first.width, first.height);
    if frames.len() != solver.order.len()
        || frames
            .iter()
            .any(|f| f.borrow().check_shape(w, h, first.channels).is_err())
    {
        return None;
    }
    let (n_obs, n_u) = (solver.observations, solver.unknowns);
    let scale = match residual {
        NoiseResidual::Fit { dof } => (1.0 / chi2_median(dof)) as f32,
        NoiseResidual::Chebyshev => (1.0 / chi2_median(1)) as f32,
    };
    let g2 = (residual == NoiseResidual::Chebyshev).then(|| gain2(solver));
    let mut obs = vec![0.0f32; n_obs];
    let mut u = vec![0.0f32; n_u];
    let mut z = vec![(0.0f32, 0.0f32); solver.frequencies.len()];
    for y in (step_px / 2..h).step_by(step_px) {
        for x in (step_px / 2..w).step_by(step_px) {
            if !observe(solver, frames, y * w + x, saturation_level, &mut obs) {
                continue;
            }
            for (r, value) in u.iter_mut().enumerate() {
                let row = &solver.pinv[r * n_obs..(r + 1) * n_obs];
                *value = row.iter().zip(&obs).map(|(a, b)| a * b).sum();
            }
            for (f, zf) in z.iter_mut().enumerate() {
                let k = solver.cos_unknown(f);
                *zf = (u[k], u[k + 1]);
            }
            // A NaN amplitude counts as low.
            if z.iter()
                .any(|&(c, s)| c.hypot(s).is_nan() || c.hypot(s) < min_amplitude)
            {
                continue;
            }
            let sample = match residual {
                NoiseResidual::Fit { .. } => {
                    let mut r2 = 0.0f64;
                    for (o, &c) in obs.iter().enumerate() {
                        let row = &solver.design[o * n_u..(o + 1) * n_u];
                        let model: f64 = row.iter().zip(&u).map(|(m, &v)| m * f64::from(v)).sum();
                        r2 += (f64::from(c) - model).powi(2);
                    }
                    r2 as f32
                }
                NoiseResidual::Chebyshev => {
                    let Some(g2) = g2 else { continue };
                    let cheb = chebyshev3([z[0], z[1], z[2]], g2);
                    let e = atan2(cheb.t.1, cheb.t.0);
                    e * e / cheb.var_over_noise
                }
            };
            if sample.is_finite() {
                samples.push(sample * scale);
            }
        }
    }
    Some(residual)
}

/// Reads pixel `i`'s observations into `obs` as the decoder does (RGB planes, a gray camera's
/// value, or a colour camera's channel mean for gray patterns); false when one is saturated.
fn observe<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    i: usize,
    saturation_level: u8,
    obs: &mut [f32],
) -> bool {
    for (k, frame) in frames.iter().map(Borrow::borrow).enumerate() {
        let ch = frame.channels;
        let px = &frame.data[i * ch..(i + 1) * ch];
        if px.iter().any(|&v| v >= saturation_level) {
            return false;
        }
        if solver.channels == 3 {
            for (j, &v) in px.iter().enumerate() {
                obs[k * 3 + j] = f32::from(v);
            }
        } else {
            obs[k] = px.iter().map(|&v| f32::from(v)).sum::<f32>() / ch as f32;
        }
    }
    true
}

/// The noise level, gray levels, that `samples` show; `None` with fewer than [`MIN_SAMPLES`].
/// Reorders `samples`.
pub fn noise_from_samples(samples: &mut [f32]) -> Option<f32> {
    if samples.len() < MIN_SAMPLES {
        return None;
    }
    let mid = samples.len() / 2;
    let (_, median, _) = samples.select_nth_unstable_by(mid, f32::total_cmp);
    Some(median.sqrt())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;
    use crate::pattern::{multi_frequency, Axis, PatternSequence};
    use crate::rig::{NoiseModel, RigConfig, VirtualRig};

    /// The noise measured over the rig's first window of `seq` at camera noise `sigma`.
    fn measure(seq: PatternSequence, sigma: f64) -> (f32, NoiseResidual) {
        let mut config = RigConfig::paper(320, 200).unwrap();
        config.noise = NoiseModel::gaussian(sigma);
        let rig = VirtualRig::new(config, seq).unwrap();
        let len = rig.sequence.entries.len();
        let frames: Vec<_> = (0..len as u64)
            .map(|i| {
                let mut f = rig.blank_frame();
                rig.render(i, &mut f, None).unwrap();
                f
            })
            .collect();
        let order: Vec<usize> = (0..len).collect();
        let solver = WindowSolver::new(&rig.sequence, &order, &rig.config.cross_talk).unwrap();
        let mut samples = Vec::new();
        let kind = window_noise_samples(&solver, &frames, 4.0, 255, &mut samples).unwrap();
        (noise_from_samples(&mut samples).unwrap(), kind)
    }

    #[test]
    fn a_cps_window_gives_the_camera_noise() {
        // The 8-bit camera and the 6-bit projector add about a third of a gray level in
        // quadrature, so the estimate sits a little above σ; it must follow σ.
        for sigma in [2.0, 5.0] {
            let seq = RigConfig::paper(320, 200)
                .unwrap()
                .default_sequence()
                .unwrap();
            let (s, kind) = measure(seq, sigma);
            assert_eq!(kind, NoiseResidual::Chebyshev);
            assert!((f64::from(s) / sigma - 1.0).abs() < 0.15, "σ {sigma}: {s}");
        }
    }

    #[test]
    fn a_multi_frequency_window_gives_the_noise_of_its_observations() {
        // Gray patterns on the colour camera: the decoder's observation is the mean of three
        // channels with independent noise, σ/√3.
        for sigma in [3.0, 6.0] {
            let seq = multi_frequency(&[16, 1], 3, 912.0, Axis::Columns, 8).unwrap();
            let (s, kind) = measure(seq, sigma);
            assert_eq!(kind, NoiseResidual::Fit { dof: 1 });
            let expected = sigma / 3f64.sqrt();
            assert!(
                (f64::from(s) / expected - 1.0).abs() < 0.15,
                "σ {sigma}: {s} against {expected}"
            );
        }
    }

    #[test]
    fn too_few_samples_give_no_estimate() {
        let mut samples = vec![1.0; MIN_SAMPLES - 1];
        assert_eq!(noise_from_samples(&mut samples), None);
        samples.push(4.0);
        assert_eq!(noise_from_samples(&mut samples), Some(1.0));
    }

    #[test]
    fn the_chi2_median_is_close() {
        // Exact medians of 9 and 12 degrees of freedom, and 2 ln 2 for two.
        for (dof, exact) in [
            (2, 2.0 * std::f64::consts::LN_2),
            (9, 8.342_833),
            (12, 11.340_322),
        ] {
            assert!((chi2_median(dof) / exact - 1.0).abs() < 0.001, "{dof}");
        }
    }
}
