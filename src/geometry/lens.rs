//! Pinhole lens model with OpenCV-convention distortion (k1, k2, p1, p2, k3).
//!
//! A point `(X, Y, Z)` in the device frame (mm, z forward) projects to normalised coordinates
//! `(x, y) = (X/Z, Y/Z)`, is distorted radially and tangentially, then mapped to pixels by the
//! intrinsics. Undistortion inverts the distortion by fixed-point iteration, which converges for the
//! moderate distortion of machine-vision lenses and projectors.

use super::GeometryError;
use nalgebra::Vector3;

/// OpenCV-convention distortion coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// Distorts normalised coordinates.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Inverts [`Distortion::distort`] by fixed-point iteration.
    pub fn undistort(&self, xd: f64, yd: f64) -> Result<(f64, f64), GeometryError> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let (dx, dy) = self.distort(x, y);
            let (ex, ey) = (dx - xd, dy - yd);
            x -= ex;
            y -= ey;
            if ex.abs() < 1e-13 && ey.abs() < 1e-13 {
                return Ok((x, y));
            }
        }
        let (dx, dy) = self.distort(x, y);
        if (dx - xd).abs() < 1e-9 && (dy - yd).abs() < 1e-9 {
            Ok((x, y))
        } else {
            Err(GeometryError::UndistortDiverged { xd, yd })
        }
    }
}

/// Focal lengths and principal point in pixels (pixel centres at integers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// A camera or projector: image size, intrinsics and distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensModel {
    pub width: usize,
    pub height: usize,
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
}

impl LensModel {
    /// Projects `point` (device frame, mm) to pixel coordinates; `None` behind the lens.
    #[inline]
    pub fn project(&self, point: &Vector3<f64>) -> Option<(f64, f64)> {
        if point.z <= 1e-9 {
            return None;
        }
        let (xd, yd) = self
            .distortion
            .distort(point.x / point.z, point.y / point.z);
        let k = &self.intrinsics;
        Some((k.fx * xd + k.cx, k.fy * yd + k.cy))
    }

    /// The unit ray through pixel `(u, v)` in the device frame.
    pub fn ray(&self, u: f64, v: f64) -> Result<Vector3<f64>, GeometryError> {
        let k = &self.intrinsics;
        let (x, y) = self
            .distortion
            .undistort((u - k.cx) / k.fx, (v - k.cy) / k.fy)?;
        Ok(Vector3::new(x, y, 1.0).normalize())
    }

    /// Whether pixel coordinates `(u, v)` fall on the sensor (pixel centres at integers).
    #[inline]
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= -0.5 && v >= -0.5 && u < self.width as f64 - 0.5 && v < self.height as f64 - 0.5
    }

    /// The same lens on a sensor binned to `width`×`height` (intrinsics scaled, distortion kept).
    pub fn resized(&self, width: usize, height: usize) -> Result<Self, GeometryError> {
        if width == 0 || height == 0 {
            return Err(GeometryError::EmptySize { width, height });
        }
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let k = &self.intrinsics;
        Ok(Self {
            width,
            height,
            intrinsics: Intrinsics {
                fx: k.fx * sx,
                fy: k.fy * sy,
                cx: (k.cx + 0.5) * sx - 0.5,
                cy: (k.cy + 0.5) * sy - 0.5,
            },
            distortion: self.distortion,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> LensModel {
        LensModel {
            width: 1920,
            height: 1200,
            intrinsics: Intrinsics {
                fx: 3200.0,
                fy: 3190.0,
                cx: 955.0,
                cy: 604.0,
            },
            distortion: Distortion {
                k1: -0.09,
                k2: 0.04,
                p1: 0.0007,
                p2: -0.0004,
                k3: -0.01,
            },
        }
    }

    #[test]
    fn ray_and_project_are_inverse() {
        let lens = lens();
        for &(u, v) in &[
            (0.0, 0.0),
            (1919.0, 1199.0),
            (955.0, 604.0),
            (300.5, 1000.25),
        ] {
            let ray = lens.ray(u, v).unwrap();
            let (pu, pv) = lens.project(&(ray * 480.0)).unwrap();
            assert!(
                (pu - u).abs() < 1e-6 && (pv - v).abs() < 1e-6,
                "{u},{v} → {pu},{pv}"
            );
        }
    }

    #[test]
    fn resize_keeps_the_field_of_view() {
        let lens = lens();
        let small = lens.resized(640, 400).unwrap();
        let p = Vector3::new(40.0, -25.0, 500.0);
        let (u, v) = lens.project(&p).unwrap();
        let (us, vs) = small.project(&p).unwrap();
        assert!(((u + 0.5) / 3.0 - 0.5 - us).abs() < 1e-9);
        assert!(((v + 0.5) / 3.0 - 0.5 - vs).abs() < 1e-9);
        assert!(lens.resized(0, 10).is_err());
        assert!(lens.project(&Vector3::new(1.0, 1.0, -5.0)).is_none());
    }
}
