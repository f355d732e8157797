//! Exact ground truth returned with every rendered frame.

use nalgebra::Vector3;

/// Surface seen at a pixel.
pub mod surface {
    pub const NONE: u8 = 0;
    pub const TABLE: u8 = 1;
    pub const SKIN: u8 = 2;
    pub const BOARD: u8 = 3;
}

/// Per-pixel truth and the true positions of the tracked surface points, at the frame's time.
#[derive(Debug, Clone, Default)]
pub struct GroundTruth {
    pub width: usize,
    pub height: usize,
    pub time_s: f64,
    /// Z of the surface point in the camera frame, mm; NaN where the ray hits nothing.
    pub depth_mm: Vec<f32>,
    /// Coded projector coordinate of the surface point, projector px; NaN where the point is in
    /// shadow or outside the projector's field.
    pub coordinate_px: Vec<f32>,
    /// [`surface`] code per pixel.
    pub surface: Vec<u8>,
    /// Tracked points (see [`crate::rig::POINT_NAMES`]), camera frame, mm.
    pub points_in_camera: Vec<Vector3<f64>>,
    /// Inner corners of the chessboard, row by row, camera frame, mm (empty without a board).
    pub board_corners_in_camera: Vec<Vector3<f64>>,
}

impl GroundTruth {
    /// Resizes the buffers for `width`×`height`, reusing their allocations.
    pub fn resize(&mut self, width: usize, height: usize) {
        let n = width * height;
        self.width = width;
        self.height = height;
        self.depth_mm.resize(n, f32::NAN);
        self.coordinate_px.resize(n, f32::NAN);
        self.surface.resize(n, surface::NONE);
    }
}
