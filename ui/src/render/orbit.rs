//! The 3D view's camera: an orbit around a target point in the rig's camera frame (mm; x right,
//! y down, z away from the camera), with pan, zoom, a reset to the rig camera's own viewpoint
//! ("top": the rig looks down on the hand) and a side view. Also the projection of points to
//! the screen for picking and for drawing control-point markers, with the same matrix the shader
//! uses, so what is clicked is what is drawn.

use nalgebra::{Matrix4, Point3, Vector3};

/// Preset viewpoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewPreset {
    /// From the rig camera, looking down on the hand.
    Top,
    /// From the side (+x), looking across: depth and vertical motion show best.
    Side,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub target_mm: Vector3<f32>,
    pub distance_mm: f32,
    /// Turn about the vertical (image y) axis, radians.
    pub yaw_rad: f32,
    /// Tilt about the horizontal (image x) axis, radians.
    pub pitch_rad: f32,
    pub fov_y_rad: f32,
}

impl OrbitCamera {
    /// Looking at `target_mm` from the `preset` direction, `distance_mm` away.
    pub fn new(preset: ViewPreset, target_mm: Vector3<f32>, distance_mm: f32) -> Self {
        let yaw_rad = match preset {
            ViewPreset::Top => 0.0,
            ViewPreset::Side => -std::f32::consts::FRAC_PI_2,
        };
        Self {
            target_mm,
            distance_mm,
            yaw_rad,
            pitch_rad: 0.0,
            fov_y_rad: 40f32.to_radians(),
        }
    }

    /// Unit vector from the eye towards the target.
    fn forward(&self) -> Vector3<f32> {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        Vector3::new(sy * cp, sp, cy * cp)
    }

    /// Up on screen: image "up" is −y in the camera frame.
    fn up(&self) -> Vector3<f32> {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        Vector3::new(sy * sp, -cp, cy * sp)
    }

    pub fn eye_mm(&self) -> Vector3<f32> {
        self.target_mm - self.forward() * self.distance_mm
    }

    /// World → clip space for wgpu (depth in [0, 1]) at `aspect` = width / height.
    pub fn clip_from_world(&self, aspect: f32) -> Matrix4<f32> {
        let eye = self.eye_mm();
        let view = Matrix4::look_at_rh(
            &Point3::from(eye),
            &Point3::from(self.target_mm),
            &self.up(),
        );
        let near = (self.distance_mm * 0.05).max(1.0);
        let far = self.distance_mm * 10.0 + 2000.0;
        let projection = Matrix4::new_perspective(aspect.max(1e-3), self.fov_y_rad, near, far);
        // nalgebra's projection gives depth in [−1, 1] (OpenGL); wgpu wants [0, 1].
        #[rustfmt::skip]
        let depth_to_unit = Matrix4::new(
            1.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0,
            0.0, 0.0, 0.5, 0.5,
            0.0, 0.0, 0.0, 1.0,
        );
        depth_to_unit * projection * view
    }

    /// Turns the view by a pointer drag of `(dx, dy)` points.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw_rad -= dx * 0.008;
        self.pitch_rad = (self.pitch_rad + dy * 0.008).clamp(-1.5, 1.5);
    }

    /// Moves the target by a drag of `(dx, dy)` points in a view `height_points` tall.
    pub fn pan(&mut self, dx: f32, dy: f32, height_points: f32) {
        let mm_per_point =
            2.0 * self.distance_mm * (self.fov_y_rad / 2.0).tan() / height_points.max(1.0);
        let right = self.forward().cross(&self.up()).normalize();
        // Screen right is −(forward × up) in this right-handed frame with up = −y.
        self.target_mm += (-right * dx + self.up() * dy) * mm_per_point;
    }

    /// Zooms by `factor` (> 1 moves closer).
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance_mm = (self.distance_mm / factor).clamp(20.0, 20_000.0);
        }
    }
}

/// A point projected to the screen: position in points within the view, and depth in [0, 1].
pub fn project(
    clip_from_world: &Matrix4<f32>,
    point_mm: [f32; 3],
    view_size_points: [f32; 2],
) -> Option<([f32; 2], f32)> {
    let p = clip_from_world * nalgebra::Vector4::new(point_mm[0], point_mm[1], point_mm[2], 1.0);
    if p.w <= 1e-6 {
        return None;
    }
    let (x, y, z) = (p.x / p.w, p.y / p.w, p.z / p.w);
    if !(0.0..=1.0).contains(&z) {
        return None;
    }
    Some((
        [
            (x + 1.0) * 0.5 * view_size_points[0],
            (1.0 - y) * 0.5 * view_size_points[1],
        ],
        z,
    ))
}

/// The slot of the organised cloud whose point is drawn nearest to `at` (points, within
/// `radius` points), preferring the nearest to the viewer among close candidates.
pub fn pick(
    clip_from_world: &Matrix4<f32>,
    points_mm: &[[f32; 3]],
    view_size_points: [f32; 2],
    at: [f32; 2],
    radius: f32,
) -> Option<usize> {
    let mut best: Option<(usize, f32)> = None;
    for (i, p) in points_mm.iter().enumerate() {
        if !p[2].is_finite() {
            continue;
        }
        let Some((s, depth)) = project(clip_from_world, *p, view_size_points) else {
            continue;
        };
        let d2 = (s[0] - at[0]).powi(2) + (s[1] - at[1]).powi(2);
        if d2 > radius * radius {
            continue;
        }
        // Screen distance first, depth breaks near-ties (within a pixel).
        let score = d2.sqrt().floor() + depth;
        if best.is_none_or(|(_, b)| score < b) {
            best = Some((i, score));
        }
    }
    best.map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_top_view_sees_the_target_at_the_centre_and_image_axes_as_the_camera_does() {
        let cam = OrbitCamera::new(ViewPreset::Top, Vector3::new(0.0, 0.0, 500.0), 500.0);
        let m = cam.clip_from_world(1.0);
        let (centre, depth) = project(&m, [0.0, 0.0, 500.0], [100.0, 100.0]).expect("visible");
        assert!((centre[0] - 50.0).abs() < 1e-3 && (centre[1] - 50.0).abs() < 1e-3);
        assert!(depth > 0.0 && depth < 1.0);
        // +x is right and +y is down on screen, as in the camera image.
        let (right, _) = project(&m, [10.0, 0.0, 500.0], [100.0, 100.0]).expect("visible");
        let (down, _) = project(&m, [0.0, 10.0, 500.0], [100.0, 100.0]).expect("visible");
        assert!(right[0] > 50.0 && (right[1] - 50.0).abs() < 1e-3);
        assert!(down[1] > 50.0 && (down[0] - 50.0).abs() < 1e-3);
        // Nearer points have smaller depth.
        let (_, near) = project(&m, [0.0, 0.0, 400.0], [100.0, 100.0]).expect("visible");
        assert!(near < depth);
    }

    #[test]
    fn the_side_view_shows_depth_across_the_screen() {
        let cam = OrbitCamera::new(ViewPreset::Side, Vector3::new(0.0, 0.0, 500.0), 500.0);
        let m = cam.clip_from_world(1.0);
        let (a, _) = project(&m, [0.0, 0.0, 450.0], [100.0, 100.0]).expect("visible");
        let (b, _) = project(&m, [0.0, 0.0, 550.0], [100.0, 100.0]).expect("visible");
        assert!(
            (a[0] - b[0]).abs() > 10.0,
            "depth is horizontal: {a:?} {b:?}"
        );
    }

    #[test]
    fn picking_prefers_the_point_under_the_pointer_then_the_nearer_one() {
        let cam = OrbitCamera::new(ViewPreset::Top, Vector3::new(0.0, 0.0, 500.0), 500.0);
        let m = cam.clip_from_world(1.0);
        let points = [
            [f32::NAN; 3],
            [0.0, 0.0, 600.0],
            [0.0, 0.0, 500.0],
            [40.0, 0.0, 500.0],
        ];
        assert_eq!(
            pick(&m, &points, [100.0, 100.0], [50.0, 50.0], 5.0),
            Some(2)
        );
        assert_eq!(pick(&m, &points, [100.0, 100.0], [5.0, 5.0], 5.0), None);
    }

    #[test]
    fn zoom_and_orbit_stay_in_range() {
        let mut cam = OrbitCamera::new(ViewPreset::Top, Vector3::zeros(), 500.0);
        cam.zoom(1e9);
        assert_eq!(cam.distance_mm, 20.0);
        cam.zoom(f32::NAN);
        assert_eq!(cam.distance_mm, 20.0);
        cam.orbit(0.0, 1e6);
        assert_eq!(cam.pitch_rad, 1.5);
    }
}
