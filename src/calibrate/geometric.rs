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

/// Removes observations whose reprojection error exceeds five robust standard deviations of
/// their device (and 1 px); a camera outlier removes the whole corner. Returns how many.
fn drop_outliers(full: &[f64], data: &mut [ViewData]) -> usize {
    let bundle = Bundle {
        full: full.to_vec(),
        free: Vec::new(),
        views: data,
    };
    let per_view = corner_errors(&bundle);
    let threshold = |errors: Vec<f64>| {
        let mut e = errors;
        e.sort_by(f64::total_cmp);
        let median = e.get(e.len() / 2).copied().unwrap_or(0.0);
        (5.0 * 1.4826 * median).max(1.0)
    };
    let camera_limit = threshold(per_view.iter().flat_map(|v| v.0.clone()).collect());
    let projector_limit = threshold(
        per_view
            .iter()
            .flat_map(|v| v.1.iter().flatten().copied().collect::<Vec<_>>())
            .collect(),
    );
    let mut dropped = 0;
    for (view, (camera, projector)) in data.iter_mut().zip(per_view) {
        for (slot, e) in view.projector_px.iter_mut().zip(&projector) {
            if e.is_some_and(|e| e > projector_limit) {
                *slot = None;
                dropped += 1;
            }
        }
        let keep: Vec<bool> = camera.iter().map(|&e| e <= camera_limit).collect();
        dropped += keep.iter().filter(|&&k| !k).count();
        let mut k = keep.iter();
        view.board_mm.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        view.camera_px.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        view.projector_px.retain(|_| *k.next().unwrap_or(&true));
    }
    dropped
}

/// Per view: the camera error of every corner and the projector error where decoded, px.
type CornerErrors = Vec<(Vec<f64>, Vec<Option<f64>>)>;

fn corner_errors(bundle: &Bundle<'_>) -> CornerErrors {
    let mut residuals = Vec::with_capacity(bundle.residual_count());
    bundle.residuals_of(&bundle.full, &mut residuals);
    let mut r = residuals.chunks_exact(2).map(|p| p[0].hypot(p[1]));
    bundle
        .views
        .iter()
        .map(|view| {
            let camera: Vec<f64> = view.camera_px.iter().map_while(|_| r.next()).collect();
            let projector = view
                .projector_px
                .iter()
                .map(|p| p.and_then(|_| r.next()))
                .collect();
            (camera, projector)
        })
        .collect()
}

struct ErrorReport {
    views: Vec<ViewError>,
    camera_rms_px: f64,
    projector_rms_px: f64,
}

fn report_errors(bundle: &Bundle<'_>, used: &[usize]) -> ErrorReport {
    let rms = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt();
    let (mut all_camera, mut all_projector) = (Vec::new(), Vec::new());
    let views = corner_errors(bundle)
        .into_iter()
        .zip(used)
        .map(|((camera, projector), &view)| {
            let projector: Vec<f64> = projector.into_iter().flatten().collect();
            all_camera.extend_from_slice(&camera);
            all_projector.extend_from_slice(&projector);
            ViewError {
                view,
                camera_rms_px: rms(&camera),
                projector_rms_px: rms(&projector),
                projector_corners: projector.len(),
            }
        })
        .collect();
    ErrorReport {
        views,
        camera_rms_px: rms(&all_camera),
        projector_rms_px: rms(&all_projector),
    }
}

/// One-sigma uncertainties: the covariance σ²·(JᵀJ)⁻¹ with σ² the residual variance per
/// degree of freedom, and the baseline's variance propagated through its gradient.
fn uncertainty_of(bundle: &Bundle<'_>) -> Result<Uncertainty, CalibrationError> {
    use levenberg_marquardt::LeastSquaresProblem;
    let jacobian = bundle.jacobian().ok_or(CalibrationError::Singular)?;
    let residuals = bundle.residuals().ok_or(CalibrationError::Singular)?;
    let dof = residuals.len().saturating_sub(bundle.free.len()).max(1);
    let variance = residuals.norm_squared() / dof as f64;
    let covariance = (jacobian.transpose() * &jacobian)
        .try_inverse()
        .ok_or(CalibrationError::Singular)?
        * variance;
    let sigma_of = |full_index: usize| {
        bundle
            .free
            .iter()
            .position(|&i| i == full_index)
            .map_or(0.0, |c| covariance[(c, c)].max(0.0).sqrt())
    };
    // Baseline = ‖−Rᵀt‖ = ‖t‖: its gradient is t/‖t‖ on the translation entries.
    let t = Vector3::new(
        bundle.full[EXTRINSICS_AT + 3],
        bundle.full[EXTRINSICS_AT + 4],
        bundle.full[EXTRINSICS_AT + 5],
    );
    let g = t / t.norm().max(1e-12);
    let mut baseline_variance = 0.0;
    for a in 0..3 {
        for b in 0..3 {
            let (ia, ib) = (
                bundle.free.iter().position(|&i| i == EXTRINSICS_AT + 3 + a),
                bundle.free.iter().position(|&i| i == EXTRINSICS_AT + 3 + b),
            );
            if let (Some(ia), Some(ib)) = (ia, ib) {
                baseline_variance += g[a] * g[b] * covariance[(ia, ib)];
            }
        }
    }
    Ok(Uncertainty {
        camera: [sigma_of(0), sigma_of(1), sigma_of(2), sigma_of(3)],
        projector: [
            sigma_of(DEVICE_PARAMS),
            sigma_of(DEVICE_PARAMS + 1),
            sigma_of(DEVICE_PARAMS + 2),
            sigma_of(DEVICE_PARAMS + 3),
        ],
        baseline_mm: baseline_variance.max(0.0).sqrt(),
    })
}
