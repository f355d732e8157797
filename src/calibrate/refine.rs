//! Joint Levenberg–Marquardt refinement of a projector–camera calibration: both devices'
//! intrinsics and distortion, the stereo extrinsics and every board pose, minimising the
//! reprojection error of all corners in the camera and in the projector at once.
//!
//! The minimiser is the `levenberg-marquardt` crate (MINPACK's algorithm on nalgebra). The
//! Jacobian is taken by central differences: with a few dozen views the problem has well under
//! 200 parameters and a few thousand residuals, so the ~2·n residual evaluations per iteration
//! cost a few milliseconds, and no hand-derived derivative of the distortion model can be wrong.
//!
//! Parameter vector (all `f64`):
//! `[camera fx fy cx cy k1 k2 p1 p2 k3 | projector (same 9) | extrinsics rx ry rz tx ty tz |
//!   per view: rx ry rz tx ty tz]`, rotations as axis·angle. Fixed entries (e.g. `k3`) are left
//! out of the vector the minimiser sees.

use crate::geometry::{Distortion, Intrinsics, LensModel, Pose};
use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::{DMatrix, DVector, Dyn, Owned, Rotation3, Vector3};

/// Parameters per device (fx fy cx cy k1 k2 p1 p2 k3).
pub const DEVICE_PARAMS: usize = 9;
/// Offset of the extrinsics in the full vector.
pub const EXTRINSICS_AT: usize = 2 * DEVICE_PARAMS;
/// Offset of the first view's pose.
pub const VIEWS_AT: usize = EXTRINSICS_AT + 6;

/// One view's corners: board position, camera observation and (where decoded) projector
/// observation.
#[derive(Debug, Clone)]
pub struct ViewData {
    pub board_mm: Vec<[f64; 2]>,
    pub camera_px: Vec<[f64; 2]>,
    pub projector_px: Vec<Option<[f64; 2]>>,
}

/// The least-squares problem: full parameter vector, which entries are free, and the data.
pub struct Bundle<'a> {
    pub full: Vec<f64>,
    pub free: Vec<usize>,
    pub views: &'a [ViewData],
}

pub fn device_to_params(lens: &LensModel) -> [f64; DEVICE_PARAMS] {
    let (k, d) = (&lens.intrinsics, &lens.distortion);
    [k.fx, k.fy, k.cx, k.cy, d.k1, d.k2, d.p1, d.p2, d.k3]
}

pub fn device_from_params(p: &[f64], width: usize, height: usize) -> LensModel {
    LensModel {
        width,
        height,
        intrinsics: Intrinsics {
            fx: p[0],
            fy: p[1],
            cx: p[2],
            cy: p[3],
        },
        distortion: Distortion {
            k1: p[4],
            k2: p[5],
            p1: p[6],
            p2: p[7],
            k3: p[8],
        },
    }
}

pub fn pose_to_params(pose: &Pose) -> [f64; 6] {
    let r = Rotation3::from_matrix(&pose.rotation).scaled_axis();
    let t = pose.translation_mm;
    [r.x, r.y, r.z, t.x, t.y, t.z]
}

pub fn pose_from_params(p: &[f64]) -> Pose {
    Pose {
        rotation: Rotation3::new(Vector3::new(p[0], p[1], p[2])).into_inner(),
        translation_mm: Vector3::new(p[3], p[4], p[5]),
    }
}

/// Pixel position of a device-frame point; points behind the device are pushed to a tiny
/// positive depth, which yields a large residual rather than a missing one.
fn project(p: &[f64], point: &Vector3<f64>) -> [f64; 2] {
    let z = point.z.max(1e-6);
    let (x, y) = (point.x / z, point.y / z);
    let r2 = x * x + y * y;
    let radial = 1.0 + r2 * (p[4] + r2 * (p[5] + r2 * p[8]));
    let xd = x * radial + 2.0 * p[6] * x * y + p[7] * (r2 + 2.0 * x * x);
    let yd = y * radial + p[6] * (r2 + 2.0 * y * y) + 2.0 * p[7] * x * y;
    [p[0] * xd + p[2], p[1] * yd + p[3]]
}

impl Bundle<'_> {
    /// Number of residuals: two per camera corner and two per decoded projector corner.
    pub fn residual_count(&self) -> usize {
        self.views
            .iter()
            .map(|v| 2 * v.camera_px.len() + 2 * v.projector_px.iter().flatten().count())
            .sum()
    }

    /// Residuals (observed − predicted) of the full vector `full`, view by view: first the
    /// camera corners, then the decoded projector corners.
    pub fn residuals_of(&self, full: &[f64], out: &mut Vec<f64>) {
        out.clear();
        let camera = &full[..DEVICE_PARAMS];
        let projector = &full[DEVICE_PARAMS..EXTRINSICS_AT];
        let extrinsics = pose_from_params(&full[EXTRINSICS_AT..VIEWS_AT]);
        for (v, view) in self.views.iter().enumerate() {
            let pose = pose_from_params(&full[VIEWS_AT + 6 * v..VIEWS_AT + 6 * v + 6]);
            let in_camera: Vec<Vector3<f64>> = view
                .board_mm
                .iter()
                .map(|b| pose.transform(&Vector3::new(b[0], b[1], 0.0)))
                .collect();
            for (p, seen) in in_camera.iter().zip(&view.camera_px) {
                let q = project(camera, p);
                out.extend([seen[0] - q[0], seen[1] - q[1]]);
            }
            for (p, seen) in in_camera.iter().zip(&view.projector_px) {
                if let Some(seen) = seen {
                    let q = project(projector, &extrinsics.transform(p));
                    out.extend([seen[0] - q[0], seen[1] - q[1]]);
                }
            }
        }
    }

    fn with_free(&self, x: &DVector<f64>) -> Vec<f64> {
        let mut full = self.full.clone();
        for (&i, &value) in self.free.iter().zip(x.iter()) {
            full[i] = value;
        }
        full
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Bundle<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.full = self.with_free(x);
    }

    fn params(&self) -> DVector<f64> {
        DVector::from_iterator(self.free.len(), self.free.iter().map(|&i| self.full[i]))
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let mut out = Vec::with_capacity(self.residual_count());
        self.residuals_of(&self.full, &mut out);
        // The minimiser minimises ½‖r‖²; its sign convention does not matter.
        Some(DVector::from_vec(out))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let m = self.residual_count();
        let mut jacobian = DMatrix::<f64>::zeros(m, self.free.len());
        let (mut plus, mut minus) = (Vec::with_capacity(m), Vec::with_capacity(m));
        let mut full = self.full.clone();
        for (column, &i) in self.free.iter().enumerate() {
            let value = full[i];
            let step = 1e-6 * value.abs().max(1.0);
            full[i] = value + step;
            self.residuals_of(&full, &mut plus);
            full[i] = value - step;
            self.residuals_of(&full, &mut minus);
            full[i] = value;
            for (row, (a, b)) in plus.iter().zip(&minus).enumerate() {
                // r = observed − predicted, so ∂r/∂p = −∂predicted/∂p; LM uses ∂r/∂p.
                jacobian[(row, column)] = (a - b) / (2.0 * step);
            }
        }
        Some(jacobian)
    }
}
