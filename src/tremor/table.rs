//! The table the hand rests on: its plane, fitted robustly in an organised cloud, and the table
//! frame that exports give positions in.
//!
//! The plane is a least-squares fit through a grid of valid points (at most about 20,000),
//! refitted twice without the points more than 3 robust standard deviations (1.4826 × MAD, at
//! least 0.05 mm) off it, which drops the hand. Its normal points away from the camera.
//!
//! The table frame has its origin where the camera's optical axis meets the plane, `z` up (out of
//! the table, towards the camera), `x` the camera's `x` axis projected onto the table and `y =
//! z × x`, so it is right-handed and a hand moved along the camera's image rows moves along `x`.

use super::track::median;
use crate::triangulate::PointCloud;
use nalgebra::{Matrix3, Vector3};

/// A plane in the camera frame: `normal · (p − point_mm) = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TablePlane {
    /// Unit normal, pointing away from the camera (`z > 0`).
    pub normal: Vector3<f64>,
    /// A point of the plane (the inliers' centroid), camera frame, mm.
    pub point_mm: Vector3<f64>,
}

/// The dominant plane of `cloud` (the table). `None` with fewer than 10 points to fit.
pub fn fit_table_plane(cloud: &PointCloud) -> Option<TablePlane> {
    let step = ((cloud.width * cloud.height) / 20_000).max(1);
    let mut points: Vec<Vector3<f64>> = cloud
        .point_in_camera_mm
        .iter()
        .step_by(step)
        .filter(|p| p[2].is_finite())
        .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        .collect();
    let mut plane = None;
    for _ in 0..3 {
        if points.len() < 10 {
            return None;
        }
        let centroid = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        let mut cov = Matrix3::zeros();
        for p in &points {
            let d = p - centroid;
            cov += d * d.transpose();
        }
        let eig = cov.symmetric_eigen();
        let (k, _) = eig
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let mut normal = eig.eigenvectors.column(k).into_owned();
        if normal.z < 0.0 {
            normal = -normal;
        }
        let dist: Vec<f64> = points
            .iter()
            .map(|p| (p - centroid).dot(&normal).abs())
            .collect();
        let scale = (1.4826 * median(&mut dist.clone())).max(0.05);
        points = points
            .into_iter()
            .zip(dist)
            .filter(|(_, d)| *d <= 3.0 * scale)
            .map(|(p, _)| p)
            .collect();
        plane = Some(TablePlane {
            normal,
            point_mm: centroid,
        });
    }
    plane
}

/// Normal of the dominant plane of `cloud` (the table), pointing away from the camera; `None`
/// with too few points. See [`fit_table_plane`].
pub fn fit_table_normal(cloud: &PointCloud) -> Option<Vector3<f64>> {
    fit_table_plane(cloud).map(|p| p.normal)
}

/// The rigid transform from the camera frame to the table frame (module header).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableFrame {
    /// Rows: the table's `x`, `y`, `z` axes in camera coordinates.
    pub table_from_camera_rotation: Matrix3<f64>,
    /// The table frame's origin, camera frame, mm.
    pub origin_in_camera_mm: Vector3<f64>,
}

impl TableFrame {
    /// The frame on `plane`; `None` when the optical axis runs parallel to the table (no origin)
    /// or the camera's `x` axis is along the normal.
    pub fn on(plane: &TablePlane) -> Option<Self> {
        let up = -plane.normal;
        // The optical axis (0, 0, t) meets the plane where normal · ((0,0,t) − p) = 0.
        if plane.normal.z.abs() < 1e-6 {
            return None;
        }
        let t = plane.normal.dot(&plane.point_mm) / plane.normal.z;
        let origin = Vector3::new(0.0, 0.0, t);
        let x = (Vector3::x() - up * up.dot(&Vector3::x())).try_normalize(1e-9)?;
        let y = up.cross(&x);
        Some(Self {
            table_from_camera_rotation: Matrix3::from_rows(&[
                x.transpose(),
                y.transpose(),
                up.transpose(),
            ]),
            origin_in_camera_mm: origin,
        })
    }

    /// The point `p` (camera frame, mm) in the table frame, mm.
    pub fn table_from_camera(&self, p: [f64; 3]) -> [f64; 3] {
        let q = self.table_from_camera_rotation * (Vector3::from(p) - self.origin_in_camera_mm);
        [q.x, q.y, q.z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_frame_puts_the_plane_at_height_zero_with_z_towards_the_camera() {
        // A table tilted 20° about the camera's x axis, 600 mm away on the optical axis.
        let a = 20f64.to_radians();
        let normal = Vector3::new(0.0, -a.sin(), a.cos());
        let plane = TablePlane {
            normal,
            point_mm: Vector3::new(30.0, 0.0, 600.0) + Vector3::new(0.0, a.cos(), a.sin()) * 50.0,
        };
        let frame = TableFrame::on(&plane).expect("a frame");
        // Points of the plane have height 0; the camera is above the table.
        let on_plane = plane.point_mm + Vector3::new(1.0, 0.0, 0.0) * 40.0;
        let q = frame.table_from_camera([on_plane.x, on_plane.y, on_plane.z]);
        assert!(q[2].abs() < 1e-9, "{q:?}");
        assert!(frame.table_from_camera([0.0, 0.0, 0.0])[2] > 500.0);
        // The origin is on the optical axis, and a move along the camera's x is along x.
        let o = frame.origin_in_camera_mm;
        assert!(o.x.abs() < 1e-9 && o.y.abs() < 1e-9);
        assert!(frame
            .table_from_camera([o.x, o.y, o.z])
            .iter()
            .all(|c| c.abs() < 1e-9));
        let step = frame.table_from_camera([o.x + 10.0, o.y, o.z]);
        assert!((step[0] - 10.0).abs() < 1e-9 && step[1].abs() < 1e-9);
        // Rigid: distances are kept.
        let r = frame.table_from_camera_rotation;
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-12);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_table_seen_edge_on_has_no_frame() {
        let plane = TablePlane {
            normal: Vector3::new(0.0, 1.0, 0.0),
            point_mm: Vector3::new(0.0, 50.0, 500.0),
        };
        assert!(TableFrame::on(&plane).is_none());
    }
}
