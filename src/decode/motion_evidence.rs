//! The per-pixel side of the motion model ([`super::motion`]): the Chebyshev quantities of a
//! pixel's three phasors (phases, amplitudes, the unit phasor and the residual
//! `φ_0 − 2φ_1 + φ_2`, with its variance from the amplitudes), and the evidence the pixel gives
//! its patch's velocity and brightness change: the five terms of the weighted normal equations
//! of `e ≈ D_u·u + D_κ·κ`, written in absolute terms at the `(u, κ)` the pixel was corrected
//! with. Stage 1 ([`super::phasor`]) writes them at rest, each Gauss–Newton step again after its
//! correction, and the noise estimate ([`super::motion_noise`]) reads the residuals.

use super::fastmath::{atan2, phase_0_tau};
use super::motion_basis::MotionBasis;
use super::WindowSolver;

/// The per-pixel Chebyshev quantities of three phasors (slots 0, 1, 2 = frequencies n, n−1,
/// n−2), shared by stage 1 and the motion correction.
#[derive(Clone, Copy)]
pub(crate) struct Chebyshev3 {
    pub phase: [f32; 3],
    pub amplitude: [f32; 3],
    /// The unit phasor `z_0·z̄_1 + z_1·z̄_2`.
    pub unit: (f32, f32),
    /// `t = (z_0·z̄_1)·conj(z_1·z̄_2)`, whose angle is `φ_0 − 2φ_1 + φ_2`.
    pub t: (f32, f32),
    /// The variance of that angle over the camera noise variance.
    pub var_over_noise: f32,
}

/// Phases, amplitudes, unit phasor and the Chebyshev residual of `z`; `gain2` holds the squared
/// noise gains `(g_0², 4·g_1², g_2²)`.
#[inline(always)]
pub(crate) fn chebyshev3(z: [(f32, f32); 3], gain2: (f32, f32, f32)) -> Chebyshev3 {
    let [(c0, s0), (c1, s1), (c2, s2)] = z;
    let (a0, a1, a2) = (c0 * c0 + s0 * s0, c1 * c1 + s1 * s1, c2 * c2 + s2 * s2);
    let phase = [
        phase_0_tau(s0, c0),
        phase_0_tau(s1, c1),
        phase_0_tau(s2, c2),
    ];
    chebyshev3_of(z, phase, [a0.sqrt(), a1.sqrt(), a2.sqrt()], gain2)
}

/// [`chebyshev3`] of phasors `z` whose phases and amplitudes are already known (a pixel the
/// step leaves as it was): no arctangents or roots.
#[inline(always)]
pub(super) fn chebyshev3_of(
    z: [(f32, f32); 3],
    phase: [f32; 3],
    amplitude: [f32; 3],
    gain2: (f32, f32, f32),
) -> Chebyshev3 {
    let [(c0, s0), (c1, s1), (c2, s2)] = z;
    let [a0, a1, a2] = amplitude.map(|a| a * a);
    // p = z0·conj(z1) and q = z1·conj(z2) both estimate a0·a1·e^{i f1 x} (eq. 13 and its sine
    // form); the unit phasor is their sum.
    let (pr, pi) = (c0 * c1 + s0 * s1, s0 * c1 - c0 * s1);
    let (qr, qi) = (c1 * c2 + s1 * s2, s1 * c2 - c1 * s2);
    Chebyshev3 {
        phase,
        amplitude,
        unit: (pr + qr, pi + qi),
        t: (pr * qr + pi * qi, pi * qr - pr * qi),
        var_over_noise: gain2.0 / a0 + gain2.1 / a1 + gain2.2 / a2,
    }
}

/// Whether the Chebyshev residual of `c` exceeds `limit` (χ² times the noise variance): the two
/// Chebyshev equations disagree. Tested on sin² of the angle, no atan2.
#[inline(always)]
pub(crate) fn inconsistent(c: &Chebyshev3, limit: f32) -> bool {
    let (tr, ti) = c.t;
    let sin2 = ti * ti / (tr * tr + ti * ti);
    (tr < 0.0) | (sin2 > limit * c.var_over_noise)
}

/// [`inconsistent`] for phasors `z` whose phases and amplitudes are not needed: the residual
/// from their products and the variance from their squared amplitudes, no arctangents or roots.
#[inline(always)]
pub(super) fn disagrees(z: [(f32, f32); 3], gain2: (f32, f32, f32), limit: f32) -> bool {
    let [(c0, s0), (c1, s1), (c2, s2)] = z;
    let (pr, pi) = (c0 * c1 + s0 * s1, s0 * c1 - c0 * s1);
    let (qr, qi) = (c1 * c2 + s1 * s2, s1 * c2 - c1 * s2);
    let (tr, ti) = (pr * qr + pi * qi, pi * qr - pr * qi);
    let var_over_noise = gain2.0 / (c0 * c0 + s0 * s0)
        + gain2.1 / (c1 * c1 + s1 * s1)
        + gain2.2 / (c2 * c2 + s2 * s2);
    let sin2 = ti * ti / (tr * tr + ti * ti);
    // A NaN (a zero phasor) disagrees.
    !((tr >= 0.0) & (sin2 <= limit * var_over_noise))
}

/// The squared noise gains of `solver`'s slots, as [`chebyshev3`] takes them.
pub(crate) fn gain2(solver: &WindowSolver) -> (f32, f32, f32) {
    let g = &solver.noise_gain;
    (g[0] * g[0], 4.0 * g[1] * g[1], g[2] * g[2])
}

/// One pixel's evidence for its patch's `(u, κ)`: the five terms of the normal equations.
#[derive(Clone, Copy)]
pub(crate) struct Evidence {
    pub uu: f32,
    pub uk: f32,
    pub kk: f32,
    pub ue: f32,
    pub ke: f32,
}

impl Evidence {
    const NONE: Self = Self {
        uu: 0.0,
        uk: 0.0,
        kk: 0.0,
        ue: 0.0,
        ke: 0.0,
    };
}

/// The evidence of a still pixel (stage 1, and a step's pixels at rest) with phasors `z`, their
/// Chebyshev quantities `c` and camera offsets `offsets`, less what the pixel's own noise (at
/// the basis's noise level; `gain2` as [`chebyshev3`] takes it) adds on average
/// ([`MotionBasis::noise_bias`]); none where `keep` is 0 or the weights are not finite.
#[inline(always)]
pub(crate) fn evidence(
    basis: &MotionBasis,
    z: [(f32, f32); 3],
    c: &Chebyshev3,
    offsets: [f32; 3],
    keep: f32,
    gain2: (f32, f32, f32),
) -> Evidence {
    let noise2 = basis.bias_noise2;
    let lit = basis.lit_offsets(offsets);
    let dz = basis.slopes_at_rest(z, lit);
    let mut ev = evidence_with(z, dz, c, keep, (0.0, 0.0));
    let (bu, bk) = basis.noise_bias(z, lit, gain2);
    let w = noise2 * keep / c.var_over_noise;
    let (bu, bk) = (w * bu, w * bk);
    if bu.is_finite() & bk.is_finite() {
        ev.ue -= bu;
        ev.ke -= bk;
    }
    ev
}

/// The evidence of a pixel whose phasors `z`, corrected at `(u, κ) = at`, move by `dz` per
/// unit of `u` and `κ`. It is in absolute terms, `e + D_u·u + D_κ·κ` against `(D_u, D_κ)`, so
/// that pixels linearised at different velocities pool into one estimate of their patch's.
#[inline(always)]
pub(super) fn evidence_with(
    z: [(f32, f32); 3],
    dz: [[(f32, f32); 2]; 3],
    c: &Chebyshev3,
    keep: f32,
    at: (f32, f32),
) -> Evidence {
    let (du, dk) = MotionBasis::residual_slopes(z, dz);
    let e = atan2(c.t.1, c.t.0) + du * at.0 + dk * at.1;
    let w = keep / c.var_over_noise;
    let ok = w.is_finite() & du.is_finite() & dk.is_finite() & (keep > 0.0);
    if ok {
        Evidence {
            uu: w * du * du,
            uk: w * du * dk,
            kk: w * dk * dk,
            ue: w * du * e,
            ke: w * dk * e,
        }
    } else {
        Evidence::NONE
    }
}
