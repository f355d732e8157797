//! One camera ray's projector-distortion offset as a polynomial in the shown coordinate.
//!
//! Along a camera ray the coded coordinate the real (distorted) projector shows differs from the
//! ideal (undistorted) one by a smooth offset. [`RaySamples::along`] samples the shown coordinate
//! and the offset at [`TERMS`] Chebyshev nodes of inverse depth over [`FIT_DEPTH_RANGE_MM`];
//! [`DistortionFit`] interpolates them as a polynomial of degree [`FIT_DEGREE`] in the normalised
//! variable `t = (shown − x_mid)·inv_half_span`, which runs over [−1, 1] between the outermost
//! samples (Newton's divided differences, then the monomial form for Horner).

use crate::triangulate::StereoModel;
use nalgebra::Vector3;

/// Degree of the distortion polynomial.
pub const FIT_DEGREE: usize = 6;
/// Depth range over which the distortion polynomial interpolates, mm along the optical axis:
/// the rig's working volume with a margin. Outside it the polynomial extrapolates.
pub const FIT_DEPTH_RANGE_MM: (f64, f64) = (200.0, 1000.0);

pub(super) const TERMS: usize = FIT_DEGREE + 1;
/// Quantities per pixel: `x_mid`, `inv_half_span` and the coefficients.
pub(super) const QUANTITIES: usize = TERMS + 2;

/// The shown coordinate and its offset `shown − ideal` at the depth nodes along one ray,
/// projector px.
#[derive(Debug, Clone, Copy)]
pub(super) struct RaySamples {
    pub shown: [f64; TERMS],
    pub offset: [f64; TERMS],
    /// Whether the sample falls on the projector's image (a coordinate it can show).
    pub on_projector: [bool; TERMS],
}

impl RaySamples {
    /// The samples along ray `d` (`d.z = 1`); `None` where a node misses the projector.
    pub fn along(model: &StereoModel, d: &Vector3<f64>) -> Option<Self> {
        let k = &model.projector.intrinsics;
        let (near, far) = FIT_DEPTH_RANGE_MM;
        let (inv_a, inv_b) = (1.0 / far, 1.0 / near);
        let mut shown = [0.0; TERMS];
        let mut offset = [0.0; TERMS];
        let mut on_projector = [false; TERMS];
        for j in 0..TERMS {
            let node = ((2 * j + 1) as f64 * std::f64::consts::PI / (2 * TERMS) as f64).cos();
            let depth = 1.0 / (0.5 * (inv_a + inv_b) + 0.5 * (inv_b - inv_a) * node);
            let q = model.projector_from_camera.transform(&(d * depth));
            if q.z <= 1e-9 {
                return None;
            }
            let (u, v) = model.projector.project(&q)?;
            let x = model.axis.coordinate(u, v);
            let ideal = model
                .axis
                .coordinate(k.fx * q.x / q.z + k.cx, k.fy * q.y / q.z + k.cy);
            shown[j] = x;
            offset[j] = x - ideal;
            on_projector[j] = model.projector.contains(u, v);
        }
        Some(Self {
            shown,
            offset,
            on_projector,
        })
    }
}

/// The offset `shown − ideal` of the coded coordinate along one camera ray, as a polynomial in
/// `t = (shown − x_mid)·inv_half_span` (monomial coefficients, lowest first).
#[derive(Debug, Clone, Copy)]
pub(super) struct DistortionFit {
    pub x_mid: f64,
    pub inv_half_span: f64,
    pub coeff: [f64; TERMS],
}

impl DistortionFit {
    /// No fit: the ray leaves the projector's image (or the camera's model) in the volume.
    pub const MISSING: Self = Self {
        x_mid: f64::NAN,
        inv_half_span: f64::NAN,
        coeff: [f64::NAN; TERMS],
    };

    /// The polynomial through `samples`; missing where there are none or two coincide.
    pub fn through(samples: Option<&RaySamples>) -> Self {
        let Some(RaySamples {
            shown: xs,
            offset: ys,
            ..
        }) = samples.copied()
        else {
            return Self::MISSING;
        };
        let lowest = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let highest = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (x_mid, half_span) = (0.5 * (lowest + highest), 0.5 * (highest - lowest));
        if half_span.is_nan() || half_span <= 0.0 {
            return Self::MISSING;
        }
        let inv_half_span = 1.0 / half_span;
        match interpolate(&xs.map(|x| (x - x_mid) * inv_half_span), &ys) {
            Some(coeff) => Self {
                x_mid,
                inv_half_span,
                coeff,
            },
            None => Self::MISSING,
        }
    }

    #[cfg(test)]
    pub fn offset(&self, x: f64) -> f64 {
        let t = (x - self.x_mid) * self.inv_half_span;
        self.coeff.iter().rev().fold(0.0, |acc, &c| acc * t + c)
    }
}

/// A fit's quantities in the order the row planes hold them.
pub(super) fn quantities(fit: &DistortionFit) -> [f64; QUANTITIES] {
    let mut q = [0.0; QUANTITIES];
    q[0] = fit.x_mid;
    q[1] = fit.inv_half_span;
    q[2..].copy_from_slice(&fit.coeff);
    q
}

/// Monomial coefficients (lowest first) of the polynomial through `(xs, ys)`, by Newton's
/// divided differences; `None` when two nodes coincide.
fn interpolate(xs: &[f64; TERMS], ys: &[f64; TERMS]) -> Option<[f64; TERMS]> {
    let mut dd = *ys;
    for level in 1..TERMS {
        for i in (level..TERMS).rev() {
            let span = xs[i] - xs[i - level];
            if span.abs() < 1e-9 {
                return None;
            }
            dd[i] = (dd[i] - dd[i - 1]) / span;
        }
    }
    // Horner on the Newton form: p = dd0 + (x − x0)(dd1 + (x − x1)(dd2 + …)).
    let mut coeff = [0.0; TERMS];
    for i in (0..TERMS).rev() {
        // coeff ← coeff·(x − xs[i]) + dd[i]
        let mut next = [0.0; TERMS];
        for p in 0..TERMS {
            if p + 1 < TERMS {
                next[p + 1] += coeff[p];
            }
            next[p] -= coeff[p] * xs[i];
        }
        next[0] += dd[i];
        coeff = next;
    }
    Some(coeff)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn interpolation_reproduces_a_polynomial_of_its_degree() {
        let truth = |x: f64| 0.3 - 0.02 * x + 1e-4 * x * x - 3e-7 * x.powi(3) + 2e-10 * x.powi(4);
        let xs: [f64; TERMS] =
            std::array::from_fn(|i| -300.0 + 600.0 * i as f64 / FIT_DEGREE as f64 + (i * i) as f64);
        let coeff = interpolate(&xs, &xs.map(truth)).unwrap();
        let fit = DistortionFit {
            x_mid: 0.0,
            inv_half_span: 1.0,
            coeff,
        };
        for x in [-250.0, -10.0, 77.0, 260.0] {
            assert!((fit.offset(x) - truth(x)).abs() < 1e-12, "{x}");
        }
        let mut repeated = xs;
        repeated[2] = repeated[1];
        assert!(interpolate(&repeated, &[0.0; TERMS]).is_none());
    }
}
