//! Projector–camera calibration from views of a printed chessboard.
//!
//! Per view: the corners in the ambient-light image ([`super::corners`]), and the projector
//! coordinates at each corner from the decoded column and row maps by the robust local fit
//! ([`super::local_fit`]), which makes the projector a second camera that "sees" the corners.
//! Then for all views: Zhang's closed form for both devices ([`super::zhang`]), the stereo
//! extrinsics as the rotation-averaged `projector_from_board · board_from_camera` of the views,
//! and one joint Levenberg–Marquardt refinement ([`super::refine`]). Observations further than
//! five robust standard deviations (and at least 1 px) from the first solution are dropped and the
//! refinement repeated once. The report has per-view and overall RMS reprojection errors and
//! one-sigma uncertainties of the main parameters from the Jacobian at the solution, and the
//! calibration is refused when those show that the poses did not determine it.

use super::corners::{find_board_corners, BoardSpec};
use super::local_fit::{fit_coordinate, LocalFitOptions};
use super::refine::{
    device_from_params, device_to_params, pose_from_params, pose_to_params, Bundle, ViewData,
    DEVICE_PARAMS, EXTRINSICS_AT, VIEWS_AT,
};
use super::residuals::{drop_outliers, report_errors, uncertainty_of};
use super::zhang::{homography, intrinsics_from_homographies, pose_from_homography};
use super::{CalibrationError, Device};
use crate::geometry::{Distortion, LensModel, Pose};
use levenberg_marquardt::LevenbergMarquardt;
use nalgebra::{Matrix3, Vector3};

/// What one calibration view saw: the corners in the camera (board order) and, where the
/// decoded maps allowed, the projector coordinates of the same corners.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewObservation {
    pub camera_px: Vec<[f64; 2]>,
    pub projector_px: Vec<Option<[f64; 2]>>,
}

/// Finds the board in `ambient_gray` and reads the projector column and row at every corner
/// from the decoded maps (row-major, NaN where invalid, all `width`×`height`).
#[allow(
    clippy::too_many_arguments,
    reason = "a view is three images of one size plus the board"
)]
pub fn observe_view(
    view: usize,
    ambient_gray: &[u8],
    column_map_px: &[f32],
    row_map_px: &[f32],
    width: usize,
    height: usize,
    board: &BoardSpec,
    fit: &LocalFitOptions,
) -> Result<ViewObservation, CalibrationError> {
    let camera_px = find_board_corners(ambient_gray, width, height, board, view)?;
    let projector_px: Vec<Option<[f64; 2]>> = camera_px
        .iter()
        .map(|&[u, v]| {
            let column = fit_coordinate(column_map_px, width, height, (u, v), fit).ok()?;
            let row = fit_coordinate(row_map_px, width, height, (u, v), fit).ok()?;
            Some([column.value_px, row.value_px])
        })
        .collect();
    let decoded = projector_px.iter().flatten().count();
    if 2 * decoded < camera_px.len() {
        return Err(CalibrationError::ProjectorNotDecoded {
            view,
            decoded,
            expected: camera_px.len(),
        });
    }
    Ok(ViewObservation {
        camera_px,
        projector_px,
    })
}

/// Settings of the geometric calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct GeometricOptions {
    /// Views left out (indices into the views passed in), e.g. those the user dropped.
    pub excluded_views: Vec<usize>,
    /// Estimate the sixth-order radial term `k3` (otherwise fixed at 0, as is usual for lenses
    /// of moderate field).
    pub estimate_k3: bool,
    /// Largest accepted one-sigma uncertainty of a focal length, relative.
    pub max_focal_uncertainty: f64,
}

impl Default for GeometricOptions {
    fn default() -> Self {
        Self {
            excluded_views: Vec::new(),
            estimate_k3: false,
            max_focal_uncertainty: 0.01,
        }
    }
}

/// Reprojection errors of one view, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewError {
    pub view: usize,
    pub camera_rms_px: f64,
    pub projector_rms_px: f64,
    pub projector_corners: usize,
}

/// One-sigma uncertainties from the Jacobian at the solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncertainty {
    /// fx, fy, cx, cy of the camera, pixels.
    pub camera: [f64; 4],
    pub projector: [f64; 4],
    pub baseline_mm: f64,
}

/// The result of a geometric calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct GeometricCalibration {
    pub camera: LensModel,
    pub projector: LensModel,
    /// `point_in_projector = R · point_in_camera + t`.
    pub projector_from_camera: Pose,
    /// Per used view, in the order given.
    pub views: Vec<ViewError>,
    pub camera_from_board: Vec<Pose>,
    pub camera_rms_px: f64,
    pub projector_rms_px: f64,
    pub uncertainty: Uncertainty,
    /// Observations dropped as outliers after the first refinement.
    pub dropped_observations: usize,
}

impl GeometricCalibration {
    /// Distance between the camera and projector centres, mm.
    pub fn baseline_mm(&self) -> f64 {
        self.projector_from_camera.inverse().translation_mm.norm()
    }
}

/// Views needed at the least.
pub const MIN_VIEWS: usize = 3;

/// Calibrates camera and projector from the observations of `board` in several views.
pub fn calibrate_geometric(
    board: &BoardSpec,
    observations: &[ViewObservation],
    camera_size: (usize, usize),
    projector_size: (usize, usize),
    options: &GeometricOptions,
) -> Result<GeometricCalibration, CalibrationError> {
    if let Some(&view) = options
        .excluded_views
        .iter()
        .find(|&&v| v >= observations.len())
    {
        return Err(CalibrationError::NoSuchView {
            view,
            count: observations.len(),
        });
    }
    let used: Vec<usize> = (0..observations.len())
        .filter(|v| !options.excluded_views.contains(v))
        .collect();
    if used.len() < MIN_VIEWS {
        return Err(CalibrationError::TooFewViews {
            got: used.len(),
            needed: MIN_VIEWS,
        });
    }
    let board_mm = board.corners_on_board_mm();
    let mut data = Vec::with_capacity(used.len());
    for &v in &used {
        let o = &observations[v];
        if o.camera_px.len() != board_mm.len() || o.projector_px.len() != board_mm.len() {
            return Err(CalibrationError::CornersNotFound {
                view: v,
                found: o.camera_px.len(),
                expected: board_mm.len(),
            });
        }
        data.push(ViewData {
            board_mm: board_mm.clone(),
            camera_px: o.camera_px.clone(),
            projector_px: o.projector_px.clone(),
        });
    }
    let mut full = initial_parameters(&data, &used, camera_size, projector_size)?;
    let free: Vec<usize> = (0..full.len())
        .filter(|&i| options.estimate_k3 || (i != 8 && i != DEVICE_PARAMS + 8))
        .collect();
    full = minimise(&full, &free, &data)?;
    let dropped = drop_outliers(&full, &mut data);
    if dropped > 0 {
        full = minimise(&full, &free, &data)?;
    }
    let bundle = Bundle {
        full: full.clone(),
        free: free.clone(),
        views: &data,
    };
    let uncertainty = uncertainty_of(&bundle)?;
    let camera = device_from_params(&full[..DEVICE_PARAMS], camera_size.0, camera_size.1);
    let projector = device_from_params(
        &full[DEVICE_PARAMS..EXTRINSICS_AT],
        projector_size.0,
        projector_size.1,
    );
    for (device, sigma, lens) in [
        (Device::Camera, &uncertainty.camera, &camera),
        (Device::Projector, &uncertainty.projector, &projector),
    ] {
        let worst = (sigma[0] / lens.intrinsics.fx).max(sigma[1] / lens.intrinsics.fy);
        if worst.is_nan() || worst > options.max_focal_uncertainty {
            return Err(CalibrationError::DegeneratePoses {
                device,
                why: format!(
                    "the focal length is only known to ±{:.2} % (one sigma); add views with \
                     more varied tilt and distance",
                    100.0 * worst
                ),
            });
        }
    }
    let report = report_errors(&bundle, &used);
    let camera_from_board = (0..data.len())
        .map(|v| pose_from_params(&full[VIEWS_AT + 6 * v..VIEWS_AT + 6 * v + 6]))
        .collect();
    Ok(GeometricCalibration {
        camera,
        projector,
        projector_from_camera: pose_from_params(&full[EXTRINSICS_AT..VIEWS_AT]),
        camera_rms_px: report.camera_rms_px,
        projector_rms_px: report.projector_rms_px,
        views: report.views,
        camera_from_board,
        uncertainty,
        dropped_observations: dropped,
    })
}

/// Zhang's closed form for both devices, then the averaged extrinsics.
fn initial_parameters(
    data: &[ViewData],
    used: &[usize],
    camera_size: (usize, usize),
    projector_size: (usize, usize),
) -> Result<Vec<f64>, CalibrationError> {
    let mut camera_h = Vec::with_capacity(data.len());
    let mut projector_h = Vec::with_capacity(data.len());
    for (view, &index) in data.iter().zip(used) {
        let h = homography(&view.board_mm, &view.camera_px).ok_or(
            CalibrationError::DegeneratePoses {
                device: Device::Camera,
                why: format!("view {index}: the corners do not define a homography"),
            },
        )?;
        camera_h.push(h);
        let (board, seen): (Vec<[f64; 2]>, Vec<[f64; 2]>) = view
            .board_mm
            .iter()
            .zip(&view.projector_px)
            .filter_map(|(b, p)| p.map(|p| (*b, p)))
            .unzip();
        let h = homography(&board, &seen).ok_or(CalibrationError::DegeneratePoses {
            device: Device::Projector,
            why: format!("view {index}: the decoded corners do not define a homography"),
        })?;
        projector_h.push(h);
    }
    let k_camera =
        intrinsics_from_homographies(&camera_h, camera_size.0, camera_size.1, Device::Camera)?;
    let k_projector = intrinsics_from_homographies(
        &projector_h,
        projector_size.0,
        projector_size.1,
        Device::Projector,
    )?;
    let mut full = Vec::with_capacity(VIEWS_AT + 6 * data.len());
    let lens = |intrinsics, (width, height)| LensModel {
        width,
        height,
        intrinsics,
        distortion: Distortion::default(),
    };
    full.extend(device_to_params(&lens(k_camera, camera_size)));
    full.extend(device_to_params(&lens(k_projector, projector_size)));
    let mut rotation_sum = Matrix3::zeros();
    let mut translations = Vec::with_capacity(data.len());
    let mut camera_poses = Vec::with_capacity(data.len());
    for (hc, hp) in camera_h.iter().zip(&projector_h) {
        let singular = || CalibrationError::Singular;
        let camera_from_board = pose_from_homography(&k_camera, hc).ok_or_else(singular)?;
        let projector_from_board = pose_from_homography(&k_projector, hp).ok_or_else(singular)?;
        let r = projector_from_board.rotation * camera_from_board.rotation.transpose();
        rotation_sum += r;
        translations
            .push(projector_from_board.translation_mm - r * camera_from_board.translation_mm);
        camera_poses.push(camera_from_board);
    }
    let svd = rotation_sum.svd(true, true);
    let (u, v_t) = (
        svd.u.ok_or(CalibrationError::Singular)?,
        svd.v_t.ok_or(CalibrationError::Singular)?,
    );
    let mut rotation = u * v_t;
    if rotation.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        rotation = u * v_t;
    }
    let median = |k: usize| {
        let mut values: Vec<f64> = translations.iter().map(|t| t[k]).collect();
        values.sort_by(f64::total_cmp);
        values[values.len() / 2]
    };
    let extrinsics = Pose {
        rotation,
        translation_mm: Vector3::new(median(0), median(1), median(2)),
    };
    full.extend(pose_to_params(&extrinsics));
    for pose in &camera_poses {
        full.extend(pose_to_params(pose));
    }
    Ok(full)
}

fn minimise(full: &[f64], free: &[usize], data: &[ViewData]) -> Result<Vec<f64>, CalibrationError> {
    let bundle = Bundle {
        full: full.to_vec(),
        free: free.to_vec(),
        views: data,
    };
    let (solved, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(bundle);
    if !report.termination.was_successful() {
        return Err(CalibrationError::RefinementFailed(format!(
            "{:?}",
            report.termination
        )));
    }
    Ok(solved.full)
}
