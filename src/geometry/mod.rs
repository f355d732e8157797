//! Geometry: lens models and rigid transforms between the camera and projector frames.
//!
//! Frames are named in variables: `point_in_camera`, `point_in_projector`. All lengths are in
//! millimetres. A [`Pose`] named `projector_from_camera` maps `point_in_camera` to
//! `point_in_projector = R · point_in_camera + t`.

pub mod lens;

pub use lens::{Distortion, Intrinsics, LensModel};

use nalgebra::{Matrix3, Rotation3, Vector3};

/// Errors of the geometry module.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GeometryError {
    #[error("undistortion did not converge at normalised point ({xd:.4}, {yd:.4}); the distortion coefficients are too strong")]
    UndistortDiverged { xd: f64, yd: f64 },
    #[error("image size {width}×{height} is empty")]
    EmptySize { width: usize, height: usize },
}

/// A rigid transform `point_in_to = rotation · point_in_from + translation_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Matrix3<f64>,
    pub translation_mm: Vector3<f64>,
}

impl Pose {
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::zeros(),
        }
    }

    #[inline]
    pub fn transform(&self, point: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * point + self.translation_mm
    }

    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation_mm: -(rt * self.translation_mm),
        }
    }

    /// A device placed at `centre_in_world` whose optical (+z) axis looks at `target_in_world`, with
    /// its +x axis kept as close as possible to the world's +x. Returns `device_from_world`.
    pub fn look_at(centre_in_world: Vector3<f64>, target_in_world: Vector3<f64>) -> Self {
        let z = (target_in_world - centre_in_world).normalize();
        let y = z.cross(&Vector3::x()).normalize();
        let x = y.cross(&z);
        // Rows are the device axes expressed in the world frame.
        let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let rotation = Rotation3::from_matrix(&rotation).into_inner();
        Self {
            rotation,
            translation_mm: -(rotation * centre_in_world),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_puts_target_on_axis() {
        let centre = Vector3::new(150.0, 0.0, 20.0);
        let target = Vector3::new(0.0, 0.0, 480.0);
        let pose = Pose::look_at(centre, target);
        let t = pose.transform(&target);
        assert!(t.x.abs() < 1e-9 && t.y.abs() < 1e-9 && t.z > 0.0);
        assert!(pose.transform(&centre).norm() < 1e-9);
        let back = pose.inverse().transform(&t);
        assert!((back - target).norm() < 1e-9);
        assert!((pose.rotation.determinant() - 1.0).abs() < 1e-12);
    }
}
