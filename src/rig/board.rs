//! A printed chessboard for geometric calibration, placed anywhere in front of the camera.
//!
//! Board frame: origin at the first inner corner, x along the corner columns, y along the rows,
//! the printed face in the plane z = 0 and +z pointing into the board, so that the identity pose
//! shows the printed face to the camera. Inner corner (i, j) lies at `(i·s, j·s, 0)`. The squares
//! span one square beyond the inner corners on every side, with a white margin of one more
//! square around them; the square whose lower corner is `(a·s, b·s)` is dark when `a + b` is
//! even.

use crate::geometry::Pose;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// A chessboard and where it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chessboard {
    /// Inner corners per row (along x) and per column (along y).
    pub inner_cols: usize,
    pub inner_rows: usize,
    pub square_mm: f64,
    /// `point_in_camera = R · point_in_board + t`.
    pub camera_from_board: Pose,
    pub dark_albedo: f64,
    pub light_albedo: f64,
}

impl Chessboard {
    /// A 9×6 inner-corner board of 20 mm squares, printed on matte paper, at `camera_from_board`.
    pub fn standard(camera_from_board: Pose) -> Self {
        Self {
            inner_cols: 9,
            inner_rows: 6,
            square_mm: 20.0,
            camera_from_board,
            dark_albedo: 0.06,
            light_albedo: 0.85,
        }
    }

    /// Inner corners in the camera frame, row by row (j outer, i inner), mm.
    pub fn corners_in_camera(&self) -> Vec<V3> {
        let mut corners = Vec::with_capacity(self.inner_cols * self.inner_rows);
        for j in 0..self.inner_rows {
            for i in 0..self.inner_cols {
                let p = V3::new(i as f64 * self.square_mm, j as f64 * self.square_mm, 0.0);
                corners.push(self.camera_from_board.transform(&p));
            }
        }
        corners
    }

    /// The board's normal in the camera frame, pointing out of the printed face.
    pub fn normal_in_camera(&self) -> V3 {
        -(self.camera_from_board.rotation * V3::z())
    }

    /// Hit distance and board-frame point of the ray `origin + t·dir`, if it meets the board.
    pub fn intersect(&self, origin: &V3, dir: &V3) -> Option<(f64, V3)> {
        let normal = self.normal_in_camera();
        let centre = self.camera_from_board.translation_mm;
        let denom = dir.dot(&normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (centre - origin).dot(&normal) / denom;
        if t <= 1e-6 {
            return None;
        }
        let in_board = self
            .camera_from_board
            .inverse()
            .transform(&(origin + dir * t));
        let s = self.square_mm;
        let (lo, hi_x, hi_y) = (
            -2.0 * s,
            (self.inner_cols + 1) as f64 * s,
            (self.inner_rows + 1) as f64 * s,
        );
        let inside =
            in_board.x >= lo && in_board.x <= hi_x && in_board.y >= lo && in_board.y <= hi_y;
        inside.then_some((t, in_board))
    }

    /// Board-frame point where the ray `origin + t·dir` meets the board's plane (edges ignored).
    pub fn intersect_plane(&self, origin: &V3, dir: &V3) -> Option<V3> {
        let normal = self.normal_in_camera();
        let denom = dir.dot(&normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (self.camera_from_board.translation_mm - origin).dot(&normal) / denom;
        Some(
            self.camera_from_board
                .inverse()
                .transform(&(origin + dir * t)),
        )
    }

    /// Albedo at a board-frame point (gray: the same on all channels).
    pub fn albedo(&self, in_board: &V3) -> f64 {
        let s = self.square_mm;
        let a = (in_board.x / s).floor();
        let b = (in_board.y / s).floor();
        // Squares run from one before the first inner corner to one after the last.
        let in_squares = a >= -1.0
            && b >= -1.0
            && a <= self.inner_cols as f64 - 1.0
            && b <= self.inner_rows as f64 - 1.0;
        if in_squares && (a + b).rem_euclid(2.0) == 0.0 {
            self.dark_albedo
        } else {
            self.light_albedo
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_sit_where_four_squares_meet() {
        let board = Chessboard::standard(Pose {
            rotation: nalgebra::Matrix3::identity(),
            translation_mm: V3::new(-80.0, -50.0, 400.0),
        });
        let corners = board.corners_in_camera();
        assert_eq!(corners.len(), 54);
        assert!((corners[10] - V3::new(-60.0, -30.0, 400.0)).norm() < 1e-9);
        // Around the corner (1, 1): diagonal squares alike, neighbours different.
        let at = |dx: f64, dy: f64| board.albedo(&V3::new(20.0 + dx, 20.0 + dy, 0.0));
        assert_eq!(at(1.0, 1.0), at(-1.0, -1.0));
        assert_eq!(at(1.0, -1.0), at(-1.0, 1.0));
        assert_ne!(at(1.0, 1.0), at(1.0, -1.0));
        // The margin is white.
        assert_eq!(board.albedo(&V3::new(-30.0, 40.0, 0.0)), board.light_albedo);
        let (t, p) = board
            .intersect(&V3::zeros(), &V3::new(-60.0, -30.0, 400.0).normalize())
            .unwrap();
        assert!((p - V3::new(20.0, 20.0, 0.0)).norm() < 1e-9 && t > 400.0);
        assert!(board.normal_in_camera().z < 0.0);
    }
}
