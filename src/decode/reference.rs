//! The straightforward decoder the fast path is measured and tested against.
//!
//! Stage 1 done the obvious way: for every pixel, one after another, gather the window's
//! observations, solve the window's linear system `M·u = c` (paper eqs. 4 / 22) by LU
//! decomposition in f64 (least squares through the normal equations when the window has more
//! observations than unknowns), and derive phases with libm's `atan2`, amplitudes with `hypot`,
//! the unit phasor and the flags in f64. Stages 2–4 are the shared ones. No precomputed
//! pseudo-inverse, no SIMD, no threads: the baseline of the comparison in `docs/benchmarks.md`,
//! and the ground for the test that the fast path computes the same thing. It decodes with the
//! still model whatever `params.motion` says: compare it with the fast path at
//! [`super::MotionModel::Off`].

use super::{check_window, finish_window, invalid, DecodeError, DecodeOutput, DecodeParams};
use super::{UnwrapMethod, WindowSolver};
use crate::frame::Frame;
use nalgebra::{DMatrix, DVector};
use std::borrow::Borrow;
use std::f64::consts::TAU;
use std::time::Instant;

/// Decodes one window like [`super::decode_window`], with the per-pixel solve of this module.
pub fn decode_window_reference<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    chebyshev_n: Option<u32>,
    out: &mut DecodeOutput,
) -> Result<(), DecodeError> {
    check_window(solver, frames, params, chebyshev_n, out)?;
    let started = Instant::now();
    let (n_obs, n_u) = (solver.observations, solver.unknowns);
    let m = DMatrix::from_row_slice(n_obs, n_u, &solver.design);
    let mt = m.transpose();
    let chebyshev = params.unwrap != UnwrapMethod::Temporal && solver.frequencies.len() == 3;
    let (w, h) = (out.width, out.height);
    let (nf, nc) = (out.frequencies, out.channels);
    let mut c = DVector::<f64>::zeros(n_obs);
    for y in 0..h {
        for x in 0..w {
            let mut highest = 0u8;
            for (k, frame) in frames.iter().map(Borrow::borrow).enumerate() {
                let p = (y * w + x) * frame.channels;
                let px = &frame.data[p..p + frame.channels];
                highest = highest.max(px.iter().copied().max().unwrap_or(0));
                if nc == frame.channels {
                    for j in 0..nc {
                        c[k * nc + j] = f64::from(px[j]);
                    }
                } else {
                    // Gray patterns seen by a colour camera: the channel mean.
                    c[k] = px.iter().map(|&v| f64::from(v)).sum::<f64>() / px.len() as f64;
                }
            }
            let u = if n_obs == n_u {
                m.clone().lu().solve(&c)
            } else {
                (&mt * &m).lu().solve(&(&mt * &c))
            };
            // A singular system leaves the pixel without signal: zero amplitudes, flagged low.
            let u = u.unwrap_or_else(|| DVector::zeros(n_u));
            let at = |planes: usize, plane: usize| (y * planes + plane) * w + x;
            for j in 0..nc {
                out.colour[at(nc, j)] = u[j] as f32;
            }
            let mut min_amp = f64::INFINITY;
            let z: Vec<(f64, f64)> = (0..nf)
                .map(|f| (u[solver.cos_unknown(f)], u[solver.cos_unknown(f) + 1]))
                .collect();
            for (f, &(cu, sv)) in z.iter().enumerate() {
                out.phase_rad[at(nf, f)] = sv.atan2(cu).rem_euclid(TAU) as f32;
                let amp = cu.hypot(sv);
                out.amplitude[at(nf, f)] = amp as f32;
                min_amp = min_amp.min(amp);
            }
            let (mut re, mut im, mut odd) = (0.0, 0.0, false);
            if chebyshev {
                let [(c0, s0), (c1, s1), (c2, s2)] = [z[0], z[1], z[2]];
                // z0·conj(z1) and z1·conj(z2), and the agreement of the two (see `phasor`).
                let (pr, pi) = (c0 * c1 + s0 * s1, s0 * c1 - c0 * s1);
                let (qr, qi) = (c1 * c2 + s1 * s2, s1 * c2 - c1 * s2);
                re = pr + qr;
                im = pi + qi;
                let (tr, ti) = (pr * qr + pi * qi, pi * qr - pr * qi);
                let sin2 = ti * ti / (tr * tr + ti * ti);
                let g: Vec<f64> = solver.noise_gain.iter().map(|&g| f64::from(g)).collect();
                let var_over_noise = g[0] * g[0] / (c0 * c0 + s0 * s0)
                    + 4.0 * g[1] * g[1] / (c1 * c1 + s1 * s1)
                    + g[2] * g[2] / (c2 * c2 + s2 * s2);
                let noise2 = f64::from(params.camera_noise_gray).powi(2);
                let limit = f64::from(params.max_disagreement_chi2) * noise2;
                odd = tr < 0.0 || sin2 > limit * var_over_noise;
            }
            let mut reason = 0;
            if min_amp.is_nan() || min_amp < f64::from(params.min_amplitude) {
                reason |= invalid::LOW_AMPLITUDE;
            }
            if highest >= params.saturation_level {
                reason |= invalid::SATURATED;
            }
            if odd {
                reason |= invalid::DISAGREEMENT;
            }
            let p = y * w + x;
            out.invalid[p] = reason;
            let keep = if reason == 0 { 1.0 } else { 0.0 };
            out.support[p] = keep as f32;
            out.unit_re[p] = (re * keep) as f32;
            out.unit_im[p] = (im * keep) as f32;
        }
    }
    finish_window(solver, params, chebyshev_n, None, started, out);
    Ok(())
}
