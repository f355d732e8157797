//! One control point's tremor figures, as `analyze`, `batch` and the GUI's report give them:
//! the displacement along the chosen axis, the figures (or why they are missing), the
//! principal axis of the 3D motion, the summed 3-axis spectrum's peak and the coherence with
//! every other point ([`tremorscan::tremor::coherence`]); and the JSON object each point gets.

use anyhow::{Context, Result};
use nalgebra::Vector3;
use serde_json::json;
use tremorscan::tremor::coherence::{pair_coherences, PairCoherence, Series};
use tremorscan::tremor::{
    analyze, displacements, principal_axis, summed_spectrum_peak, AnalysisOptions,
    DisplacementAxis, TrackSample, TremorError, TremorReport,
};

/// The JSON object of one point's tremor figures.
pub fn report_json(pixel: (f64, f64), r: &TremorReport, axis: &Vector3<f64>) -> serde_json::Value {
    json!({
        "pixel": [pixel.0, pixel.1],
        "valid_fraction": r.valid_fraction,
        "longest_gap_s": r.longest_gap_s,
        "duration_s": r.duration_s,
        "peak_frequency_hz": r.peak_frequency_hz,
        "peaks_hz": r.peaks_hz,
        "amplitude_peak_to_peak_mm": r.amplitude_peak_to_peak_mm,
        "amplitude_peak_to_peak_cm": r.amplitude_peak_to_peak_mm / 10.0,
        "amplitude_rms_mm": r.amplitude_rms_mm,
        "band_power_3_12": r.band_power_mm2,
        "band_power_4_6": r.narrow_band_power_mm2,
        "occupancy": r.occupancy,
        "frequency_stability": r.frequency_stability_hz,
        "updrs_amplitude_bin": r.updrs_amplitude_bin,
        "tetras_amplitude_rating": r.tetras_amplitude_rating,
        "tremor_stability_index_hz": r.tremor_stability_index_hz,
        "half_power_bandwidth_hz": r.half_power_bandwidth_hz,
        "harmonic_relative_power": r.harmonic_relative_power,
        "frequency_bands": r.frequency_bands,
        "vertical_axis": [axis.x, axis.y, axis.z],
        "spectrum": {
            "frequency_hz": r.spectrum.frequency_hz,
            "psd_mm2_per_hz": r.spectrum.density,
        },
    })
}

/// One control point's analysis.
pub struct PointOutcome {
    pub name: String,
    pub pixel: (f64, f64),
    pub times_s: Vec<f64>,
    /// Along `axis`.
    pub displacement_mm: Vec<Option<f64>>,
    /// Which axis the displacement and figures are along, and its unit vector (camera frame).
    pub axis_name: &'static str,
    pub axis: Vector3<f64>,
    /// The principal axis of the band-passed 3D motion (`None`: too little measured).
    pub principal_axis: Option<Vector3<f64>>,
    /// The peak of the summed 3-axis spectrum, Hz.
    pub spectrum_3d_peak_hz: Option<f64>,
    /// Coherence with each other point.
    pub coherence: Vec<PairCoherence>,
    /// The figures, or why they are missing (too little was measured).
    pub report: Result<TremorReport, String>,
}

impl PointOutcome {
    /// The JSON object `analyze` writes for this point; `vertical` is the vertical axis.
    pub fn json(&self, vertical: &Vector3<f64>) -> serde_json::Value {
        let (u, v) = self.pixel;
        let mut object = match &self.report {
            Ok(r) => report_json(self.pixel, r, vertical),
            Err(why) => json!({ "pixel": [u, v], "figures_missing": why }),
        };
        let vector = |a: &Vector3<f64>| json!([a.x, a.y, a.z]);
        object["name"] = json!(self.name);
        object["displacement_axis"] = json!({ "name": self.axis_name, "unit": vector(&self.axis) });
        object["principal_axis"] = self.principal_axis.as_ref().map_or(json!(null), vector);
        object["spectrum_3d_peak_hz"] = json!(self.spectrum_3d_peak_hz);
        object["coherence"] = self
            .coherence
            .iter()
            .map(|c| json!({ "with": c.with, "at_peak": c.at_peak, "mean_2_12_hz": c.band_mean }))
            .collect();
        object
    }

    /// The point's panel in the report figure.
    pub fn figure(&self) -> crate::report_png::PointFigure {
        crate::report_png::PointFigure {
            label: self.name.clone(),
            times_s: self.times_s.clone(),
            displacement_mm: self.displacement_mm.clone(),
            report: self.report.clone(),
            coherence: self.coherence.clone(),
        }
    }
}

/// The tremor figures of every tracked point (`tracks`, one sample per window) along `axis`; `vertical` is the vertical axis, `window_frames`
/// the frames the decode averages (`decode::frames_averaged`), whose gain the analysis undoes.
/// A point with too little measured gets the reason instead of figures; any other analysis
/// failure is an error naming the point.
pub fn analyze_tracks(
    window_frames: usize,
    tracks: &[Vec<TrackSample>],
    vertical: &Vector3<f64>,
    names: &[String],
    pixels: &[(f64, f64)],
    axis: DisplacementAxis,
) -> Result<Vec<PointOutcome>> {
    let options = AnalysisOptions {
        window_frames,
        ..AnalysisOptions::default()
    };
    let mut outcomes = Vec::new();
    for ((track, name), &pixel) in tracks.iter().zip(names).zip(pixels) {
        let times_s: Vec<f64> = track.iter().map(|s| s.time_s).collect();
        let principal = principal_axis(track, options.band_hz);
        let unit = match axis {
            DisplacementAxis::Principal => principal,
            other => other.unit(vertical, track, &options),
        };
        let (displacement_mm, report) = match unit {
            Some(unit) => {
                let d = displacements(track, &unit);
                let report = match analyze(&times_s, &d, &options) {
                    Ok(r) => Ok(r),
                    // Too little was measured at this point: say so, keep the others' figures.
                    Err(e @ TremorError::TooFewValid { .. }) => Err(e.to_string()),
                    Err(e) => return Err(e).with_context(|| format!("point `{name}`")),
                };
                (d, report)
            }
            None => (
                vec![None; track.len()],
                Err("figures missing: too little was measured for a principal axis".to_string()),
            ),
        };
        outcomes.push(PointOutcome {
            name: name.clone(),
            pixel,
            times_s,
            displacement_mm,
            axis_name: axis.name(),
            axis: unit.unwrap_or(*vertical),
            principal_axis: principal,
            spectrum_3d_peak_hz: summed_spectrum_peak(track, &options),
            coherence: Vec::new(),
            report,
        });
    }
    // Coherence of every pair, on the displacements each point's figures use.
    let series: Vec<(&str, Series<'_>, Option<f64>)> = outcomes
        .iter()
        .map(|o| {
            let peak = o.report.as_ref().ok().and_then(|r| r.peak_frequency_hz);
            let series = Series {
                times_s: &o.times_s,
                displacement_mm: &o.displacement_mm,
            };
            (o.name.as_str(), series, peak)
        })
        .collect();
    let pairs = pair_coherences(&series);
    for (o, c) in outcomes.iter_mut().zip(pairs) {
        o.coherence = c;
    }
    Ok(outcomes)
}
