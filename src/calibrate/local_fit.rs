//! The projector coordinate at a sub-pixel camera position (a chessboard corner), from the dense
//! decoded map around it by a robust local regression.
//!
//! Around the position `(u₀, v₀)` every valid map value within `radius_px` enters a weighted
//! least-squares fit of the quadratic surface
//!
//! ```text
//! x(u, v) = c0 + c1·du + c2·dv + c3·du² + c4·du·dv + c5·dv²,   du = u − u₀, dv = v − v₀
//! ```
//!
//! with Gaussian weights of `sigma_px`. After each fit, values further than `outlier_k` robust
//! standard deviations (1.4826 × the median absolute residual, at least `min_scale_px`) are
//! dropped and the fit repeated, so a few wrong-fringe pixels cannot move the result. The answer
//! is `c0`. This is a plain local polynomial regression, not a local homography.

use super::CalibrationError;
use nalgebra::{SMatrix, SVector};

/// Settings of the local fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFitOptions {
    pub radius_px: usize,
    pub sigma_px: f64,
    pub min_points: usize,
    pub outlier_k: f64,
    pub min_scale_px: f64,
    pub iterations: usize,
}

impl Default for LocalFitOptions {
    fn default() -> Self {
        Self {
            radius_px: 6,
            sigma_px: 4.0,
            min_points: 20,
            outlier_k: 4.0,
            min_scale_px: 0.05,
            iterations: 3,
        }
    }
}

/// The fitted coordinate and how well the surface fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFit {
    pub value_px: f64,
    /// Weighted RMS residual of the points kept, projector px.
    pub residual_rms_px: f64,
    pub points_used: usize,
}

/// Fits the coordinate of `map` (row-major `width`×`height`, NaN where invalid) at `at`.
pub fn fit_coordinate(
    map: &[f32],
    width: usize,
    height: usize,
    at: (f64, f64),
    options: &LocalFitOptions,
) -> Result<LocalFit, CalibrationError> {
    let (u0, v0) = at;
    let r = options.radius_px as f64;
    let inside = |lo: f64, hi: f64, size: usize| -> Option<(usize, usize)> {
        let first = lo.ceil().max(0.0);
        let last = hi.floor().min(size as f64 - 1.0);
        (first <= last).then_some((first as usize, last as usize))
    };
    let (Some((x0, x1)), Some((y0, y1))) = (
        inside(u0 - r, u0 + r, width),
        inside(v0 - r, v0 + r, height),
    ) else {
        return Err(CalibrationError::TooFewPoints {
            u: u0,
            v: v0,
            found: 0,
            needed: options.min_points,
        });
    };
    // (du, dv, value, weight)
    let mut points = Vec::with_capacity((x1 - x0 + 1) * (y1 - y0 + 1));
    for y in y0..=y1 {
        for x in x0..=x1 {
            let value = map.get(y * width + x).copied().unwrap_or(f32::NAN);
            let (du, dv) = (x as f64 - u0, y as f64 - v0);
            let d2 = du * du + dv * dv;
            if value.is_finite() && d2 <= r * r {
                let weight = (-0.5 * d2 / (options.sigma_px * options.sigma_px)).exp();
                points.push((du, dv, f64::from(value), weight));
            }
        }
    }
    let mut keep = vec![true; points.len()];
    let mut result = None;
    for _ in 0..options.iterations.max(1) {
        let used = keep.iter().filter(|&&k| k).count();
        if used < options.min_points {
            return Err(CalibrationError::TooFewPoints {
                u: u0,
                v: v0,
                found: used,
                needed: options.min_points,
            });
        }
        let mut normal = SMatrix::<f64, 6, 6>::zeros();
        let mut rhs = SVector::<f64, 6>::zeros();
        for (&(du, dv, value, weight), _) in points.iter().zip(&keep).filter(|(_, &k)| k) {
            let basis = SVector::<f64, 6>::from([1.0, du, dv, du * du, du * dv, dv * dv]);
            normal += basis * basis.transpose() * weight;
            rhs += basis * (value * weight);
        }
        let coeffs = normal.try_inverse().ok_or(CalibrationError::Singular)? * rhs;
        let residual = |&(du, dv, value, _): &(f64, f64, f64, f64)| {
            let basis = SVector::<f64, 6>::from([1.0, du, dv, du * du, du * dv, dv * dv]);
            value - basis.dot(&coeffs)
        };
        let mut abs: Vec<f64> = points
            .iter()
            .zip(&keep)
            .filter(|(_, &k)| k)
            .map(|(p, _)| residual(p).abs())
            .collect();
        abs.sort_by(f64::total_cmp);
        let median = abs[abs.len() / 2];
        let scale = (1.4826 * median).max(options.min_scale_px);
        let (mut sum_w, mut sum_wr2) = (0.0, 0.0);
        for (p, k) in points.iter().zip(&keep) {
            if *k {
                let r = residual(p);
                sum_w += p.3;
                sum_wr2 += p.3 * r * r;
            }
        }
        result = Some(LocalFit {
            value_px: coeffs[0],
            residual_rms_px: (sum_wr2 / sum_w).sqrt(),
            points_used: used,
        });
        let mut changed = false;
        for (p, k) in points.iter().zip(keep.iter_mut()) {
            let outlier = residual(p).abs() > options.outlier_k * scale;
            if *k && outlier {
                *k = false;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    result.ok_or(CalibrationError::Singular)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(width: usize, height: usize) -> Vec<f32> {
        let mut map = vec![f32::NAN; width * height];
        let mut state = 99u64;
        let mut noise = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            // Uniform in ±0.17: σ = 0.1 px.
            ((state >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 0.346
        };
        for y in 0..height {
            for x in 0..width {
                let (u, v) = (x as f64, y as f64);
                let value = 300.0 + 1.3 * u + 0.2 * v + 0.001 * u * u - 0.0005 * u * v;
                map[y * width + x] = (value + noise()) as f32;
            }
        }
        map
    }

    #[test]
    fn recovers_a_smooth_map_despite_outliers_and_holes() {
        let (w, h) = (60, 40);
        let mut map = synthetic(w, h);
        // Wrong fringe orders (one period off) and invalid pixels near the corner.
        for &(x, y) in &[(30, 20), (31, 20), (29, 22), (33, 18), (27, 21)] {
            map[y * w + x] += 28.06;
        }
        for &(x, y) in &[(30, 21), (28, 19), (32, 23)] {
            map[y * w + x] = f32::NAN;
        }
        let at = (30.37, 20.61);
        let truth = 300.0 + 1.3 * at.0 + 0.2 * at.1 + 0.001 * at.0 * at.0 - 0.0005 * at.0 * at.1;
        let fit = fit_coordinate(&map, w, h, at, &LocalFitOptions::default()).unwrap();
        // About 110 points of σ = 0.1 px, Gaussian weighted: the standard error of c0 is near
        // 0.02 px; allow three of them.
        assert!((fit.value_px - truth).abs() < 0.06, "{fit:?} vs {truth}");
        assert!(fit.residual_rms_px < 0.2, "{fit:?}");
        assert!(fit.points_used < 113, "outliers must be dropped: {fit:?}");
    }

    #[test]
    fn too_few_points_is_an_error() {
        let (w, h) = (30, 30);
        let mut map = synthetic(w, h);
        for v in map.iter_mut().skip(w * 10) {
            *v = f32::NAN;
        }
        let err =
            fit_coordinate(&map, w, h, (15.0, 20.0), &LocalFitOptions::default()).unwrap_err();
        assert!(
            matches!(err, CalibrationError::TooFewPoints { .. }),
            "{err}"
        );
        let err =
            fit_coordinate(&map, w, h, (-50.0, 5.0), &LocalFitOptions::default()).unwrap_err();
        assert!(err.to_string().contains("(-50.0, 5.0)"), "{err}");
    }
}
