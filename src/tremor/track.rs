//! Tracking a control point in the organised point cloud, frame by frame.
//!
//! A control point is a camera pixel `(u, v)`, or a 3D point that [`pixel_of`] projects to one. In each cloud its 3D position is estimated from
//! the valid points of a small square neighbourhood: the per-axis median, then the mean of the
//! points within `outlier_k` robust standard deviations (1.4826 × MAD, at least 0.05 mm) of it,
//! so no single invalid or noisy pixel makes a spike. With fewer than `min_valid_fraction` of
//! the neighbourhood valid the frame is marked invalid; no value is invented.
//!
//! A followed point's position is read at its sub-pixel match by [`locate_subpixel`]: the same
//! robust neighbourhood, fitted as an affine function of the pixel offset, which also gives the
//! surface's slope there.
//!
//! Displacement is measured along a vertical axis (the camera's optical axis by default, a
//! fitted table normal, or a given vector) relative to the point's median position over the
//! analysed span.

use crate::triangulate::PointCloud;
use nalgebra::Vector3;

/// Settings of the neighbourhood estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackOptions {
    /// Half size of the square neighbourhood, pixels (3 → 7×7).
    pub radius_px: usize,
    pub min_valid_fraction: f64,
    pub outlier_k: f64,
}

impl Default for TrackOptions {
    fn default() -> Self {
        Self {
            radius_px: 3,
            min_valid_fraction: 0.5,
            outlier_k: 3.0,
        }
    }
}

pub(crate) fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// The robust 3D position (camera frame, mm) of the surface around pixel `(u, v)`, or `None`.
pub fn locate(cloud: &PointCloud, pixel: (f64, f64), options: &TrackOptions) -> Option<[f64; 3]> {
    let (cu, cv) = (pixel.0.round(), pixel.1.round());
    if cu < 0.0 || cv < 0.0 || cu >= cloud.width as f64 || cv >= cloud.height as f64 {
        return None;
    }
    let r = options.radius_px as isize;
    let (cu, cv) = (cu as isize, cv as isize);
    let mut points = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
    let mut slots = 0usize;
    for y in cv - r..=cv + r {
        for x in cu - r..=cu + r {
            if x < 0 || y < 0 || x >= cloud.width as isize || y >= cloud.height as isize {
                continue;
            }
            slots += 1;
            let p = cloud.point_in_camera_mm[y as usize * cloud.width + x as usize];
            if p[2].is_finite() {
                points.push([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]);
            }
        }
    }
    if slots == 0 || (points.len() as f64) < options.min_valid_fraction * slots as f64 {
        return None;
    }
    let mut centre = [0.0; 3];
    let mut scale = [0.0; 3];
    for axis in 0..3 {
        let mut v: Vec<f64> = points.iter().map(|p| p[axis]).collect();
        centre[axis] = median(&mut v);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - centre[axis]).abs()).collect();
        scale[axis] = (1.4826 * median(&mut dev)).max(0.05);
    }
    let inliers: Vec<&[f64; 3]> = points
        .iter()
        .filter(|p| (0..3).all(|a| (p[a] - centre[a]).abs() <= options.outlier_k * scale[a]))
        .collect();
    if inliers.is_empty() {
        return Some(centre);
    }
    let n = inliers.len() as f64;
    Some([0, 1, 2].map(|a| inliers.iter().map(|p| p[a]).sum::<f64>() / n))
}

/// The camera pixel of a control point picked as a 3D point (camera frame, mm), e.g. clicked in
/// the point cloud: from then on it is tracked like one picked in the image. `None` when the
/// point lies behind the camera or outside the image.
pub fn pixel_of(
    point_in_camera_mm: [f64; 3],
    camera: &crate::geometry::LensModel,
) -> Option<(f64, f64)> {
    let p = Vector3::from(point_in_camera_mm);
    camera.project(&p).filter(|&(u, v)| camera.contains(u, v))
}

/// The direction displacements are measured along.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VerticalAxis {
    /// The camera's optical axis (+z, away from the camera).
    OpticalAxis,
    /// A given direction in the camera frame (normalised when used).
    Explicit(Vector3<f64>),
}

impl VerticalAxis {
    pub fn unit(&self) -> Option<Vector3<f64>> {
        match self {
            VerticalAxis::OpticalAxis => Some(Vector3::z()),
            VerticalAxis::Explicit(v) => v.try_normalize(1e-12),
        }
    }
}

/// One tracked sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    pub time_s: f64,
    /// The window's last frame in the session.
    pub frame: usize,
    /// The camera pixel measured at: the control point's pixel, which moves with the skin
    /// when it follows it; `None` where the skin patch was lost.
    pub pixel: Option<(f64, f64)>,
    pub position_mm: Option<[f64; 3]>,
    /// The surface's 3D change per camera pixel along u and along v at `pixel`, camera frame,
    /// mm/px: kept for a followed point, whose position [`super::undo_window_mean`] moves along
    /// it; `None` at a fixed pixel, where nothing was measured, and once that step is done.
    pub slope_mm_per_px: Option<SurfaceSlope>,
}

/// A surface's slope at a pixel: its 3D change per pixel along u and along v, mm/px.
pub type SurfaceSlope = [[f64; 3]; 2];

impl TrackSample {
    /// The sample of a window where nothing was measured.
    pub fn missing(time_s: f64, frame: usize) -> Self {
        Self {
            time_s,
            frame,
            pixel: None,
            position_mm: None,
            slope_mm_per_px: None,
        }
    }
}

/// Displacements along `axis` relative to the median position of the valid samples, mm; `None`
/// where the sample is invalid.
pub fn displacements(samples: &[TrackSample], axis: &Vector3<f64>) -> Vec<Option<f64>> {
    let valid: Vec<[f64; 3]> = samples.iter().filter_map(|s| s.position_mm).collect();
    if valid.is_empty() {
        return vec![None; samples.len()];
    }
    let reference = [0, 1, 2].map(|a| median(&mut valid.iter().map(|p| p[a]).collect::<Vec<_>>()));
    samples
        .iter()
        .map(|s| {
            s.position_mm
                .map(|p| (0..3).map(|a| (p[a] - reference[a]) * axis[a]).sum())
        })
        .collect()
}
/// Why a track's samples have no position: counted so that a report can say which.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MissingSamples {
    pub total: usize,
    /// No pixel: a followed point whose skin was not found (its match too weak, or the window
    /// not decoded).
    pub not_found: usize,
    /// A pixel, but too little decoded depth around it.
    pub no_depth: usize,
}

impl MissingSamples {
    pub fn of(samples: &[TrackSample]) -> Self {
        samples.iter().fold(
            Self {
                total: samples.len(),
                ..Self::default()
            },
            |mut m, s| {
                match (s.pixel, s.position_mm) {
                    (None, _) => m.not_found += 1,
                    (Some(_), None) => m.no_depth += 1,
                    (Some(_), Some(_)) => {}
                }
                m
            },
        )
    }

    /// Share of the samples in `count`, per cent (0 without samples).
    pub fn percent(&self, count: usize) -> f64 {
        100.0 * count as f64 / self.total.max(1) as f64
    }

    /// What a report says of a followed point's missing samples, as `analyze` and the GUI's
    /// tremor panel print it.
    pub fn followed_summary(&self) -> String {
        format!(
            "the followed skin was not found in {:.0} % of the windows and had no depth in {:.0} %",
            self.percent(self.not_found),
            self.percent(self.no_depth)
        )
    }
}

/// The 3D position (camera frame, mm) of the surface at sub-pixel `pixel`, with its slope
/// there: the valid points of the `(2·radius + 1)²` neighbourhood, outliers removed as in
/// [`locate`], fitted by least squares as `p(u, v) = p₀ + p_u·Δu + p_v·Δv` and evaluated
/// at `pixel`: `(p₀, [p_u, p_v])` (the slope is zero where too few inliers leave the
/// neighbourhood's median as the position). `None` with fewer than `min_valid_fraction` of the
/// neighbourhood valid.
pub fn locate_subpixel(
    cloud: &PointCloud,
    pixel: (f64, f64),
    options: &TrackOptions,
) -> Option<([f64; 3], SurfaceSlope)> {
    let (cu, cv) = (pixel.0.round(), pixel.1.round());
    if cu < 0.0 || cv < 0.0 || cu >= cloud.width as f64 || cv >= cloud.height as f64 {
        return None;
    }
    let r = options.radius_px as i64;
    let mut points: Vec<([f64; 3], f64, f64)> = Vec::with_capacity(((2 * r + 1).pow(2)) as usize);
    let mut slots = 0usize;
    for y in cv as i64 - r..=cv as i64 + r {
        for x in cu as i64 - r..=cu as i64 + r {
            if x < 0 || y < 0 || x >= cloud.width as i64 || y >= cloud.height as i64 {
                continue;
            }
            slots += 1;
            let p = cloud.point_in_camera_mm[y as usize * cloud.width + x as usize];
            if p[2].is_finite() {
                points.push((
                    [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])],
                    x as f64 - pixel.0,
                    y as f64 - pixel.1,
                ));
            }
        }
    }
    if slots == 0 || (points.len() as f64) < options.min_valid_fraction * slots as f64 {
        return None;
    }
    let mut centre = [0.0; 3];
    let mut scale = [0.0; 3];
    for axis in 0..3 {
        let mut v: Vec<f64> = points.iter().map(|p| p.0[axis]).collect();
        centre[axis] = median(&mut v);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - centre[axis]).abs()).collect();
        scale[axis] = (1.4826 * median(&mut dev)).max(0.05);
    }
    let fit = |subset: &[&([f64; 3], f64, f64)]| -> Option<([f64; 3], SurfaceSlope)> {
        let mut normal = nalgebra::Matrix3::<f64>::zeros();
        let mut rhs = [nalgebra::Vector3::<f64>::zeros(); 3];
        for (p, du, dv) in subset {
            let b = nalgebra::Vector3::new(1.0, *du, *dv);
            normal += b * b.transpose();
            for axis in 0..3 {
                rhs[axis] += b * p[axis];
            }
        }
        let lu = normal.lu();
        let (mut out, mut slope) = ([0.0; 3], [[0.0; 3]; 2]);
        for axis in 0..3 {
            let c = lu.solve(&rhs[axis])?;
            out[axis] = c[0];
            slope[0][axis] = c[1];
            slope[1][axis] = c[2];
        }
        Some((out, slope))
    };
    let inliers: Vec<&([f64; 3], f64, f64)> = points
        .iter()
        .filter(|p| (0..3).all(|a| (p.0[a] - centre[a]).abs() <= options.outlier_k * scale[a]))
        .collect();
    let flat = (centre, [[0.0; 3]; 2]);
    if inliers.len() < 3 {
        return Some(flat);
    }
    fit(&inliers).or(Some(flat))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_samples_say_whether_the_skin_or_its_depth_was_missing() {
        let found = |position: Option<[f64; 3]>| TrackSample {
            pixel: Some((10.0, 20.0)),
            position_mm: position,
            ..TrackSample::missing(0.0, 0)
        };
        let samples = [
            found(Some([0.0, 0.0, 400.0])),
            found(None),
            TrackSample::missing(0.1, 1),
            TrackSample::missing(0.2, 2),
        ];
        let m = MissingSamples::of(&samples);
        assert_eq!((m.total, m.not_found, m.no_depth), (4, 2, 1));
        assert_eq!(m.percent(m.not_found), 50.0);
        assert_eq!(
            m.followed_summary(),
            "the followed skin was not found in 50 % of the windows and had no depth in 25 %"
        );
        assert_eq!(MissingSamples::of(&[]).percent(0), 0.0);
    }
}
