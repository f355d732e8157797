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
//! * CPS maps are combined by inverse variance, weighted by amplitude: map i has noise
//!   `σ_i = σ_cam·g_i / (a_i·f_i)`, with `a_i` its amplitude and `g_i` the noise gain of the
//!   solver's rows for that frequency (cross-talk unmixing amplifies some channels), so its weight
//!   is `(a_i·f_i / g_i)²`.
//! * Disagreement between the maps is tested against that noise: `χ² = Σ (x_i − x̄)² / σ_i²`
//!   with two degrees of freedom. The three CPS periods differ by only about 1 %, so a wrong
//!   fringe order moves the maps apart by only 0.4–0.9 px: invisible on dark pixels, but many σ on
//!   well-lit ones, and motion inside the window, which corrupts the frequencies differently,
//!   shows up the same way. The rounding margin, support and order-jump tests carry the rest.
//!   A wrong depth is worse than a missing one.

use super::fastmath::whole_to_flags;
use super::smooth::unit_angle;
use super::{invalid, DecodeOutput, DecodeParams, UnwrapMethod, WindowSolver};
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
    let f = &solver.frequency_rad_per_px;
    // x_max = m·π / f_m for any slot.
    let x_max = solver.frequencies[0] as f32 * PI / f[0];
    let f1 = chebyshev_n.map_or(0.0, |n| f[0] / n as f32);
    let consts = Consts {
        w,
        nf,
        f1,
        x_max,
        params: *params,
        f,
        gain: &solver.noise_gain,
    };
    out.coordinate_px
        .par_chunks_mut(w)
        .zip(out.coarse_px.par_chunks_mut(w))
        .zip(out.invalid.par_chunks_mut(w))
        .zip(out.phase_rad.par_chunks(w * nf))
        .zip(out.amplitude.par_chunks(w * nf))
        .zip(out.unit_re.par_chunks(w))
        .zip(out.unit_im.par_chunks(w))
        .zip(out.support.par_chunks(w))
        // Free after smoothing: one row of it per row of the image.
        .zip(out.smooth_tmp.par_chunks_mut(w))
        .for_each(
            |((((((((coord, coarse), flags), phase), amp), re), im), support), scratch)| {
                let row = Row {
                    scratch,
                    coord,
                    coarse,
                    flags,
                    phase,
                    amp,
                    re,
                    im,
                    support,
                };
                match consts.params.unwrap {
                    UnwrapMethod::Temporal => temporal_row(&consts, row),
                    UnwrapMethod::ChebyshevPerPixel | UnwrapMethod::ChebyshevRobust => {
                        chebyshev_row(&consts, row);
                    }
                }
            },
        );
}

struct Consts<'a> {
    w: usize,
    nf: usize,
    f1: f32,
    x_max: f32,
    params: DecodeParams,
    f: &'a [f32],
    gain: &'a [f32],
}

struct Row<'a> {
    /// One row of scratch.
    scratch: &'a mut [f32],
    coord: &'a mut [f32],
    coarse: &'a mut [f32],
    flags: &'a mut [u16],
    phase: &'a [f32],
    amp: &'a [f32],
    re: &'a [f32],
    im: &'a [f32],
    support: &'a [f32],
}

/// Round to nearest for |v| < 2²²: adding and removing 1.5·2²³ leaves the integer part, and
/// compiles to two additions instead of a libm call.
#[inline]
fn round_fast(v: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0;
    (v + MAGIC) - MAGIC
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn chebyshev_row(c: &Consts<'_>, row: Row<'_>) {
    let w = c.w;
    let p = &c.params;
    let robust = p.unwrap == UnwrapMethod::ChebyshevRobust;
    // Every slice exactly `w` long: no bounds checks in the loops, which then vectorise.
    let (ph0, ph1, ph2) = (
        &row.phase[..w],
        &row.phase[w..2 * w],
        &row.phase[2 * w..3 * w],
    );
    let (am0, am1, am2) = (&row.amp[..w], &row.amp[w..2 * w], &row.amp[2 * w..3 * w]);
    let (coarse, coord, flags) = (
        &mut row.coarse[..w],
        &mut row.coord[..w],
        &mut row.flags[..w],
    );
    // New reason bits as f32 sums of distinct powers of two, merged into the byte flags last.
    let added = &mut row.scratch[..w];
    let inv_f1 = 1.0 / c.f1;
    let bit = |set: bool, value: u16| if set { f32::from(value) } else { 0.0 };
    // The coarse coordinate first, in a loop of its own so the main loop has no calls.
    if robust {
        let (re, im, support) = (&row.re[..w], &row.im[..w], &row.support[..w]);
        let min_support = p.smoothing.min_support;
        for x in 0..w {
            coarse[x] = unit_angle(re[x], im[x]) * inv_f1;
            added[x] = bit(support[x] < min_support, invalid::LOW_SUPPORT);
        }
    } else {
        for x in 0..w {
            coarse[x] = paper_coarse(ph0[x], ph1[x], ph2[x]) * inv_f1;
            added[x] = 0.0;
        }
    }
    let cps = CpsMaps::new(c.f, c.gain);
    let inv_noise2 = 1.0 / (p.camera_noise_gray * p.camera_noise_gray);
    for x in 0..w {
        let u = cps.unwrap(
            coarse[x],
            [ph0[x], ph1[x], ph2[x]],
            [am0[x], am1[x], am2[x]],
        );
        added[x] += bit(u.residual > p.max_rounding_residual, invalid::UNWRAP_MARGIN)
            + bit(
                u.weighted_spread * inv_noise2 > p.max_disagreement_chi2,
                invalid::DISAGREEMENT,
            )
            + bit(
                !(-0.5..c.x_max).contains(&u.combined),
                invalid::OUT_OF_RANGE,
            );
        coord[x] = u.combined;
    }
    for x in 0..w {
        let reason = flags[x] | whole_to_flags(added[x]);
        flags[x] = reason;
        if reason != 0 {
            coord[x] = f32::NAN;
        }
    }
}

/// Eq. 8 for the three CPS frequencies and their inverse-variance combination.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CpsMaps {
    f: [f32; 3],
    /// `(f/g)²` per slot: times the amplitude squared, the map's inverse variance over the
    /// camera noise variance (g: the solver's noise gain of the slot).
    weight: [f32; 3],
}

/// One pixel's three maps unwrapped from one coarse coordinate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unwrapped {
    /// The maps combined by inverse variance, projector px.
    pub combined: f32,
    /// The largest rounding residual of the three, `[0, 0.5]`.
    pub residual: f32,
    /// `Σ w_i·(x_i − x̄)²` before division by the camera noise variance: times `1/σ²` it is
    /// the disagreement's χ².
    pub weighted_spread: f32,
}

impl CpsMaps {
    /// The maps of `f` (rad per projector px, slots n, n−1, n−2) with noise gains `gain`.
    pub(crate) fn new(f: &[f32], gain: &[f32]) -> Self {
        let f = [f[0], f[1], f[2]];
        let weight = [0, 1, 2].map(|i| (f[i] / gain[i]).powi(2));
        Self { f, weight }
    }

    /// Unwraps the wrapped `phase` of each slot around the coarse coordinate `xc` and combines
    /// them, weighting each map by `(a·f/g)²`.
    #[inline(always)]
    pub(crate) fn unwrap(&self, xc: f32, phase: [f32; 3], amplitude: [f32; 3]) -> Unwrapped {
        let (x0, r0) = unwrap_one(xc, phase[0], self.f[0]);
        let (x1, r1) = unwrap_one(xc, phase[1], self.f[1]);
        let (x2, r2) = unwrap_one(xc, phase[2], self.f[2]);
        let w0 = self.weight[0] * amplitude[0] * amplitude[0];
        let w1 = self.weight[1] * amplitude[1] * amplitude[1];
        let w2 = self.weight[2] * amplitude[2] * amplitude[2];
        let total = w0 + w1 + w2;
        // A zero total only happens on pixels already flagged for low amplitude.
        let combined = if total > 0.0 {
            (x0 * w0 + x1 * w1 + x2 * w2) / total
        } else {
            x0
        };
        let (d0, d1, d2) = (x0 - combined, x1 - combined, x2 - combined);
        Unwrapped {
            combined,
            residual: r0.max(r1).max(r2),
            weighted_spread: w0 * d0 * d0 + w1 * d1 * d1 + w2 * d2 * d2,
        }
    }
}

/// Eq. 8 from the lowest frequency upwards; slots are in descending frequency order.
fn temporal_row(c: &Consts<'_>, row: Row<'_>) {
    let w = c.w;
    let lowest = c.nf - 1;
    for x in 0..w {
        let mut reason = row.flags[x];
        let xc = row.phase[lowest * w + x] / c.f[lowest];
        let mut value = xc;
        for s in (0..lowest).rev() {
            let (xi, residual) = unwrap_one(value, row.phase[s * w + x], c.f[s]);
            if residual > c.params.max_rounding_residual {
                reason |= invalid::UNWRAP_MARGIN;
            }
            value = xi;
        }
        if !(-0.5..c.x_max).contains(&value) {
            reason |= invalid::OUT_OF_RANGE;
        }
        row.coarse[x] = xc;
        row.flags[x] = reason;
        row.coord[x] = if reason == 0 { value } else { f32::NAN };
    }
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
    const INV_TAU: f32 = 1.0 / TAU;
    let arg = (xc * f - phase) * INV_TAU;
    let k = round_fast(arg);
    ((TAU * k + phase) / f, (arg - k).abs())
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
        assert!(
            (xi - x - 2.0 * 912.0 / 65.0).abs() < 1e-3,
            "one period off: {xi}"
        );
    }
}
