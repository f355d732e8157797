//! Tremor in 3D: the axis a point's tremor runs along, and the spectrum of its whole motion.
//!
//! - **Principal axis**: each coordinate of the point's 3D track is put on a uniform grid
//!   ([`resample`]), detrended and band-passed to the tremor band; the axis is the eigenvector
//!   of the largest eigenvalue of the 3×3 covariance of the measured samples (principal
//!   component analysis of the band-passed motion). Its sign is chosen so that its largest
//!   component is positive, so the same motion always gives the same vector.
//! - **Summed 3-axis spectrum**: the Welch densities of the three detrended coordinates,
//!   added (mm²/Hz), which does not depend on any axis; its peak is the highest bin in the band.
//! - **Displacement axis** ([`DisplacementAxis`]): which direction the clinical figures are
//!   computed along: the vertical (today's default), the principal axis, or a camera axis.
//!
//! Too few measured samples give `None`, never an axis fitted to gaps.

use super::analysis::{AnalysisOptions, MIN_VALID_FRACTION};
use super::spectrum::{band_pass, detrend_linear, resample, welch};
use super::track::TrackSample;
use nalgebra::{Matrix3, Vector3};

/// The direction the displacement figures are computed along.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DisplacementAxis {
    /// The vertical axis (the optical axis, a given vector or the table normal).
    #[default]
    Vertical,
    /// The principal axis of the point's band-passed 3D motion.
    Principal,
    /// Camera x, y or z.
    X,
    Y,
    Z,
}

impl DisplacementAxis {
    /// The unit vector for a point with this `track`, given the `vertical` unit axis; `None`
    /// for the principal axis of a track too sparse to have one.
    pub fn unit(
        self,
        vertical: &Vector3<f64>,
        track: &[TrackSample],
        options: &AnalysisOptions,
    ) -> Option<Vector3<f64>> {
        match self {
            DisplacementAxis::Vertical => Some(*vertical),
            DisplacementAxis::Principal => principal_axis(track, options.band_hz),
            DisplacementAxis::X => Some(Vector3::x()),
            DisplacementAxis::Y => Some(Vector3::y()),
            DisplacementAxis::Z => Some(Vector3::z()),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            DisplacementAxis::Vertical => "vertical",
            DisplacementAxis::Principal => "principal",
            DisplacementAxis::X => "x",
            DisplacementAxis::Y => "y",
            DisplacementAxis::Z => "z",
        }
    }
}

/// The three coordinates of `track` on a uniform grid, detrended, with the grid's rate and
/// which samples were measured; `None` when less than half was measured.
fn coordinates(track: &[TrackSample]) -> Option<([Vec<f64>; 3], f64, Vec<bool>)> {
    let times: Vec<f64> = track.iter().map(|s| s.time_s).collect();
    let mut axes: [Vec<f64>; 3] = Default::default();
    let (mut rate_hz, mut measured) = (0.0, Vec::new());
    for (a, out) in axes.iter_mut().enumerate() {
        let values: Vec<Option<f64>> = track.iter().map(|s| s.position_mm.map(|p| p[a])).collect();
        let series = resample(&times, &values)?;
        if series.valid_fraction < MIN_VALID_FRACTION {
            return None;
        }
        let mut x = series.values;
        detrend_linear(&mut x);
        *out = x;
        rate_hz = series.rate_hz;
        measured = series.measured;
    }
    Some((axes, rate_hz, measured))
}

/// The principal axis of the track's motion in `band_hz`, camera frame, unit.
pub fn principal_axis(track: &[TrackSample], band_hz: (f64, f64)) -> Option<Vector3<f64>> {
    let (axes, rate_hz, measured) = coordinates(track)?;
    let passed: Vec<Vec<f64>> = axes
        .iter()
        .map(|x| band_pass(x, rate_hz, band_hz.0, band_hz.1))
        .collect();
    let mut covariance = Matrix3::<f64>::zeros();
    let mut n = 0usize;
    for (i, m) in measured.iter().enumerate() {
        if *m {
            let v = Vector3::new(passed[0][i], passed[1][i], passed[2][i]);
            covariance += v * v.transpose();
            n += 1;
        }
    }
    if n < 8 || covariance.trace() <= 0.0 {
        return None;
    }
    let eigen = covariance.symmetric_eigen();
    let k = eigen.eigenvalues.imax();
    let axis = eigen.eigenvectors.column(k).into_owned();
    let largest = axis
        .iter()
        .copied()
        .fold(0.0f64, |m, c| if c.abs() > m.abs() { c } else { m });
    Some(if largest < 0.0 { -axis } else { axis })
}

/// The peak of the summed 3-axis spectrum in the analysis band, Hz.
pub fn summed_spectrum_peak(track: &[TrackSample], options: &AnalysisOptions) -> Option<f64> {
    let (axes, rate_hz, _) = coordinates(track)?;
    let segment = ((options.segment_s * rate_hz).round() as usize).min(axes[0].len());
    let nfft = (8 * segment).next_power_of_two();
    let spectra: Vec<_> = axes
        .iter()
        .map(|x| welch(x, rate_hz, segment, nfft))
        .collect::<Option<_>>()?;
    let (lo, hi) = options.band_hz;
    spectra[0]
        .frequency_hz
        .iter()
        .enumerate()
        .filter(|(_, f)| **f >= lo && **f <= hi)
        .map(|(k, f)| (*f, spectra.iter().map(|s| s.density[k]).sum::<f64>()))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|(_, d)| *d > 0.0)
        .map(|(f, _)| f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn track(direction: Vector3<f64>, f_hz: f64, drop_every: usize) -> Vec<TrackSample> {
        (0..363)
            .map(|i| {
                let t = i as f64 / 121.0;
                let p = Vector3::new(10.0, -5.0, 480.0)
                    + direction * 3.0 * (TAU * f_hz * t).sin()
                    // Slow drift and a smaller motion across: not the principal axis.
                    + Vector3::new(0.2 * t, 0.0, 0.0)
                    + direction.cross(&Vector3::x()).normalize() * 0.4 * (TAU * f_hz * t + 1.0).sin();
                TrackSample {
                    position_mm: (drop_every == 0 || i % drop_every != 0).then_some([p.x, p.y, p.z]),
                    ..TrackSample::missing(t, i)
                }
            })
            .collect()
    }

    #[test]
    fn the_principal_axis_is_the_tremor_direction() {
        let direction = Vector3::new(0.3, -0.8, 0.52).normalize();
        let options = AnalysisOptions::default();
        let axis = principal_axis(&track(direction, 5.0, 7), options.band_hz).unwrap();
        assert!(axis.dot(&direction).abs() > 0.995, "{axis:?}");
        // The sign convention: largest component positive.
        assert!(axis.y.abs() > axis.x.abs() && axis.y > 0.0, "{axis:?}");
        let peak = summed_spectrum_peak(&track(direction, 5.0, 7), &options).unwrap();
        assert!((peak - 5.0).abs() < 0.1, "{peak}");
        let v = DisplacementAxis::Principal
            .unit(&Vector3::z(), &track(direction, 5.0, 0), &options)
            .unwrap();
        assert!(v.dot(&direction).abs() > 0.995);
    }

    #[test]
    fn a_sparse_track_has_no_axis() {
        let sparse: Vec<TrackSample> = track(Vector3::z(), 5.0, 0)
            .into_iter()
            .enumerate()
            .map(|(i, s)| TrackSample {
                position_mm: if i % 3 == 0 { s.position_mm } else { None },
                ..s
            })
            .collect();
        assert_eq!(principal_axis(&sparse, (3.0, 12.0)), None);
        assert_eq!(
            summed_spectrum_peak(&sparse, &AnalysisOptions::default()),
            None
        );
    }
}
