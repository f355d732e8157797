//! Stage 3: coarse coordinate, unwrapping (eq. 8), combination and validity.
//!
//! * Coarse coordinate `x_c` in projector px, by method:
//!   - (a) per pixel, paper eqs. 13–15: `C = (c0 + c2)/(2c1)` if `|c1| ≥ |s1|`, else
//!     `(s0 + s2)/(2s1)`, with `c_i, s_i` the unit-normalised cos/sin of frequency slot i, then
//!     `x_c = arccos(C)/f_1`;
//!   - (b) from the smoothed unit phasor: `x_c = angle(w̄)/f_1`;
//!   - (c) temporal: start from the lowest frequency (m ≤ 2, no ambiguity) and refine upwards.
//! * Each wrapped phase `φ_i` unwraps as `k_i = round((x_c·f_i − φ_i)/2π)`,
//!   `x_i = (2π·k_i + φ_i)/f_i`. The distance of the rounded argument from its integer is the
//!   rounding margin; near 0.5 the fringe order is a coin toss and the pixel is marked invalid.
//! * CPS maps are combined with weights `amplitude²`: the phase noise of a frequency is inversely
//!   proportional to its amplitude, so this is the inverse-variance weighting.
//! * The three CPS periods differ by only about 1 %, so a wrong fringe order moves all three maps
//!   almost together and the disagreement test catches little; the rounding margin and the
//!   support test carry most of the protection. A wrong depth is worse than a missing one.

use super::smooth::unit_angle;
use super::{invalid, DecodeOutput, DecodeParams, UnwrapMethod, WindowSolver, BAND_ROWS};
use rayon::prelude::*;
use std::f32::consts::{PI, TAU};

/// Runs stage 3 over the whole image.
pub(crate) fn unwrap_and_combine(
    solver: &WindowSolver,
    params: &DecodeParams,
    chebyshev_n: Option<u32>,
    out: &mut DecodeOutput,
) {
    let w = out.width;
    let nf = out.frequencies;
    let band_px = BAND_ROWS * w;
    let f = &solver.frequency_rad_per_px;
    // x_max = m·π / f_m for any slot.
    let x_max = solver.frequencies[0] as f32 * PI / f[0];
    let f1 = chebyshev_n.map_or(0.0, |n| f[0] / n as f32);
    let method = params.unwrap;
    out.coordinate_px
        .par_chunks_mut(band_px)
        .zip(out.coarse_px.par_chunks_mut(band_px))
        .zip(out.invalid.par_chunks_mut(band_px))
        .zip(out.phase_rad.par_chunks(band_px * nf))
        .zip(out.amplitude.par_chunks(band_px * nf))
        .zip(out.unit_re.par_chunks(band_px))
        .zip(out.unit_im.par_chunks(band_px))
        .zip(out.support.par_chunks(band_px))
        .for_each(|(((((((coord, coarse), flags), phase), amp), re), im), support)| {
            for i in 0..flags.len() {
                let (r, x) = (i / w, i % w);
                let ph = |s: usize| phase[(r * nf + s) * w + x];
                let am = |s: usize| amp[(r * nf + s) * w + x];
                let mut reason = flags[i];
                let (xc, value) = match method {
                    UnwrapMethod::Temporal => temporal(nf, f, &ph, params, &mut reason),
                    UnwrapMethod::ChebyshevPerPixel | UnwrapMethod::ChebyshevRobust => {
                        let xc = if method == UnwrapMethod::ChebyshevRobust {
                            if support[i] < params.smoothing.min_support {
                                reason |= invalid::LOW_SUPPORT;
                            }
                            unit_angle(re[i], im[i]) / f1
                        } else {
                            paper_coarse(ph(0), ph(1), ph(2)) / f1
                        };
                        (xc, chebyshev_combine(xc, f, &ph, &am, params, &mut reason))
                    }
                };
                if !(-0.5..x_max).contains(&value) {
                    reason |= invalid::OUT_OF_RANGE;
                }
                coarse[i] = xc;
                flags[i] = reason;
                coord[i] = if reason == 0 { value } else { f32::NAN };
            }
        });
}

/// The paper's per-pixel unit phase `f_1·x̂` (eqs. 13–15), in `[0, π]`.
#[inline]
pub fn paper_coarse(phase0: f32, phase1: f32, phase2: f32) -> f32 {
    let (s0, c0) = phase0.sin_cos();
    let (s1, c1) = phase1.sin_cos();
    let (s2, c2) = phase2.sin_cos();
    let cos_f1x = if c1.abs() >= s1.abs() {
        (c0 + c2) / (2.0 * c1)
    } else {
        (s0 + s2) / (2.0 * s1)
    };
    cos_f1x.clamp(-1.0, 1.0).acos()
}

/// Unwraps `phase` (rad, `[0, 2π)`) of frequency `f` with coarse coordinate `xc`; returns the
/// unwrapped coordinate and the rounding residual in `[0, 0.5]`.
#[inline]
pub fn unwrap_one(xc: f32, phase: f32, f: f32) -> (f32, f32) {
    let arg = (xc * f - phase) / TAU;
    let k = arg.round();
    ((TAU * k + phase) / f, (arg - k).abs())
}

fn chebyshev_combine(
    xc: f32,
    f: &[f32],
    ph: &dyn Fn(usize) -> f32,
    am: &dyn Fn(usize) -> f32,
    params: &DecodeParams,
    reason: &mut u8,
) -> f32 {
    let mut xs = [0f32; 3];
    let mut weights = [0f32; 3];
    let mut worst_residual = 0f32;
    for s in 0..3 {
        let (xi, residual) = unwrap_one(xc, ph(s), f[s]);
        xs[s] = xi;
        weights[s] = am(s) * am(s);
        worst_residual = worst_residual.max(residual);
    }
    let total: f32 = weights.iter().sum();
    let combined = if total > 0.0 {
        xs.iter().zip(&weights).map(|(x, w)| x * w).sum::<f32>() / total
    } else {
        xs[0]
    };
    if worst_residual > params.max_rounding_residual {
        *reason |= invalid::UNWRAP_MARGIN;
    }
    let spread = xs.iter().map(|x| (x - combined).abs()).fold(0.0, f32::max);
    if spread > params.max_disagreement_px {
        *reason |= invalid::DISAGREEMENT;
    }
    combined
}

/// Eq. 8 from the lowest frequency upwards; slots are in descending frequency order.
fn temporal(
    nf: usize,
    f: &[f32],
    ph: &dyn Fn(usize) -> f32,
    params: &DecodeParams,
    reason: &mut u8,
) -> (f32, f32) {
    let lowest = nf - 1;
    let xc = ph(lowest) / f[lowest];
    let mut x = xc;
    for s in (0..lowest).rev() {
        let (xi, residual) = unwrap_one(x, ph(s), f[s]);
        if residual > params.max_rounding_residual {
            *reason |= invalid::UNWRAP_MARGIN;
        }
        x = xi;
    }
    (xc, x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_formula_recovers_unit_phase() {
        let (x_max, n) = (912.0f32, 65u32);
        let f = |m: u32| m as f32 * PI / x_max;
        for &x in &[3.0f32, 100.0, 455.5, 700.25, 905.0] {
            let phase = |m: u32| (f(m) * x).rem_euclid(TAU);
            let got = paper_coarse(phase(n), phase(n - 1), phase(n - 2)) / f(1);
            assert!((got - x).abs() < 0.05, "{x} → {got}");
        }
    }

    #[test]
    fn unwrap_one_rounds_to_the_nearest_order() {
        let f = 65.0 * PI / 912.0;
        let x = 500.3f32;
        let phase = (f * x).rem_euclid(TAU);
        let (xi, res) = unwrap_one(x + 9.0, phase, f);
        assert!((xi - x).abs() < 1e-3 && res < 0.33);
        let (xi, _) = unwrap_one(x + 15.0, phase, f);
        assert!((xi - x - 2.0 * 912.0 / 65.0).abs() < 1e-3, "one period off: {xi}");
    }
}
