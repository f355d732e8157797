//! What the residuals of a refined calibration say: which observations are outliers, the RMS
//! reprojection error per view and device, and the one-sigma uncertainties of the main
//! parameters from the Jacobian at the solution.

use super::geometric::{Uncertainty, ViewError};
use super::refine::{Bundle, ViewData, DEVICE_PARAMS, EXTRINSICS_AT};
use super::CalibrationError;
use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::Vector3;

/// Removes observations whose reprojection error exceeds five robust standard deviations of
/// their device (and 1 px); a camera outlier removes the whole corner. Returns how many.
pub(crate) fn drop_outliers(full: &[f64], data: &mut [ViewData]) -> usize {
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

pub(crate) struct ErrorReport {
    pub views: Vec<ViewError>,
    pub camera_rms_px: f64,
    pub projector_rms_px: f64,
}

pub(crate) fn report_errors(bundle: &Bundle<'_>, used: &[usize]) -> ErrorReport {
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
pub(crate) fn uncertainty_of(bundle: &Bundle<'_>) -> Result<Uncertainty, CalibrationError> {
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
