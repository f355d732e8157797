//! Closed-form initial calibration from views of a planar board (Zhang, "A flexible new
//! technique for camera calibration", 2000): one homography per view, the intrinsics from the
//! image of the absolute conic, then each view's pose. Lens distortion is left at zero here; the
//! joint refinement ([`super::refine`]) estimates it.
//!
//! Image coordinates are normalised (centred on the image and scaled by its half size) before
//! any linear algebra, so the 6×6 conic system stays well conditioned; the intrinsics are mapped
//! back to pixels at the end.

use super::{CalibrationError, Device};
use crate::geometry::{Intrinsics, Pose};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// The homography `image ~ H · (x, y, 1)` from board millimetres to image pixels, by the
/// normalised direct linear transform over all point pairs.
pub fn homography(board_mm: &[[f64; 2]], image_px: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    if board_mm.len() != image_px.len() || board_mm.len() < 4 {
        return None;
    }
    let tb = normaliser(board_mm)?;
    let ti = normaliser(image_px)?;
    let mut a = DMatrix::<f64>::zeros(2 * board_mm.len(), 9);
    for (k, (b, i)) in board_mm.iter().zip(image_px).enumerate() {
        let p = tb * Vector3::new(b[0], b[1], 1.0);
        let q = ti * Vector3::new(i[0], i[1], 1.0);
        let (x, y, u, v) = (p.x / p.z, p.y / p.z, q.x / q.z, q.y / q.z);
        let rows = [
            [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u],
            [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v],
        ];
        for (r, row) in rows.iter().enumerate() {
            for (c, value) in row.iter().enumerate() {
                a[(2 * k + r, c)] = *value;
            }
        }
    }
    let h = smallest_right_singular_vector(&a)?;
    let hn = Matrix3::from_row_slice(h.as_slice());
    let full = ti.try_inverse()? * hn * tb;
    let scale = full[(2, 2)];
    (scale.abs() > 1e-15).then(|| full / scale)
}

/// Hartley's normalisation: centroid to the origin, mean distance √2.
fn normaliser(points: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean_dist = points
        .iter()
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .sum::<f64>()
        / n;
    if mean_dist <= 1e-12 {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    Some(Matrix3::new(
        s,
        0.0,
        -s * cx,
        0.0,
        s,
        -s * cy,
        0.0,
        0.0,
        1.0,
    ))
}

fn smallest_right_singular_vector(a: &DMatrix<f64>) -> Option<nalgebra::DVector<f64>> {
    // The eigenvector of AᵀA of the smallest eigenvalue (A has at most a few hundred rows).
    let ata = a.transpose() * a;
    let eig = ata.symmetric_eigen();
    let (k, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))?;
    Some(eig.eigenvectors.column(k).into_owned())
}

/// Intrinsics (zero skew) of a device of `width`×`height` pixels from the homographies of its
/// views. Needs at least two views whose board orientations differ; fails with
/// [`CalibrationError::DegeneratePoses`] when the views do not determine the focal lengths.
pub fn intrinsics_from_homographies(
    homographies: &[Matrix3<f64>],
    width: usize,
    height: usize,
    device: Device,
) -> Result<Intrinsics, CalibrationError> {
    let degenerate = |why: &str| CalibrationError::DegeneratePoses {
        device,
        why: why.to_string(),
    };
    if homographies.len() < 2 {
        return Err(degenerate("fewer than two views"));
    }
    let half = 0.5 * (width.max(height) as f64);
    let to_normalised = Matrix3::new(
        1.0 / half,
        0.0,
        -0.5 * width as f64 / half,
        0.0,
        1.0 / half,
        -0.5 * height as f64 / half,
        0.0,
        0.0,
        1.0,
    );
    // Two rows per view (Zhang's eq. 8) and one zero-skew row.
    let mut v = DMatrix::<f64>::zeros(2 * homographies.len() + 1, 6);
    for (k, h) in homographies.iter().enumerate() {
        // Only the first two columns enter the constraints; scale them to unit size so every
        // view weighs the same whatever its distance.
        let h = to_normalised * h;
        let h = h / (h.column(0).norm_squared() + h.column(1).norm_squared()).sqrt();
        let row = |i: usize, j: usize| {
            let (a, b) = (h.column(i), h.column(j));
            [
                a[0] * b[0],
                a[0] * b[1] + a[1] * b[0],
                a[1] * b[1],
                a[2] * b[0] + a[0] * b[2],
                a[2] * b[1] + a[1] * b[2],
                a[2] * b[2],
            ]
        };
        let (v12, v11, v22) = (row(0, 1), row(0, 0), row(1, 1));
        for c in 0..6 {
            v[(2 * k, c)] = v12[c];
            v[(2 * k + 1, c)] = v11[c] - v22[c];
        }
    }
    v[(2 * homographies.len(), 1)] = 1.0;
    // The conic is a one-dimensional null space. Parallel boards (any number of them) leave it
    // two or more dimensional: the second-smallest singular value then vanishes too.
    let singular = v.clone().svd(false, false).singular_values;
    let mut sorted: Vec<f64> = singular.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    if sorted.len() < 6 || sorted[1] < 1e-3 * sorted[5] {
        return Err(degenerate(
            "the board orientations are too alike to determine the focal length; tilt the board \
             differently between views",
        ));
    }
    let b = smallest_right_singular_vector(&v).ok_or_else(|| degenerate("no conic"))?;
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    if den.abs() < 1e-300 || b11.abs() < 1e-300 {
        return Err(degenerate("singular conic"));
    }
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let (fx2, fy2) = (lambda / b11, lambda * b11 / den);
    if fx2 <= 0.0 || fy2 <= 0.0 || !fx2.is_finite() || !fy2.is_finite() {
        return Err(degenerate("no real focal length fits the views"));
    }
    let (fx, fy) = (fx2.sqrt(), fy2.sqrt());
    let u0 = -b13 * fx2 / lambda;
    // Back from normalised to pixel units.
    Ok(Intrinsics {
        fx: fx * half,
        fy: fy * half,
        cx: u0 * half + 0.5 * width as f64,
        cy: v0 * half + 0.5 * height as f64,
    })
}

/// The board pose `camera_from_board` of one view from its homography and the intrinsics.
pub fn pose_from_homography(k: &Intrinsics, h: &Matrix3<f64>) -> Option<Pose> {
    let k_inv = Matrix3::new(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0).try_inverse()?;
    let m = k_inv * h;
    let mut lambda = 1.0 / m.column(0).norm();
    if (m.column(2) * lambda).z < 0.0 {
        // The board lies in front of the device.
        lambda = -lambda;
    }
    let r1 = m.column(0) * lambda;
    let r2 = m.column(1) * lambda;
    let r3 = r1.cross(&r2);
    let t = m.column(2) * lambda;
    let approx = Matrix3::from_columns(&[r1, r2, r3]);
    let svd = approx.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut rotation = u * v_t;
    if rotation.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        rotation = u * v_t;
    }
    Some(Pose {
        rotation,
        translation_mm: t,
    })
}
