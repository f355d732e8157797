//! The tremor panel: per control point, the spectrum of its last five seconds (3–12 Hz band
//! shaded), the peak frequency, the amplitude, the clinical band label and the MDS-UPDRS
//! amplitude bin, from [`tremorscan::tremor::analyze`], the field's measures
//! ([`TremorReport::measures_line`]) and the coherence with every other point, on the series
//! the displacement plot shows. The figures are recomputed a few times a
//! second (a Welch spectrum of 600 samples takes well under a millisecond), not every frame,
//! so the numbers can be read.

use super::plot_ui::Series;
use egui::Color32;
use egui_plot::{Line, Plot, PlotPoints, Polygon};
use std::time::{Duration, Instant};
use tremorscan::tremor::coherence::{
    coherence_line, pair_coherences, PairCoherence, Series as CoherenceSeries,
};
use tremorscan::tremor::{analyze, AnalysisOptions, MissingSamples, TremorReport};

const REFRESH: Duration = Duration::from_millis(300);

/// The analysis of one point, or why there is none yet.
pub struct PointAnalysis {
    pub id: u64,
    pub name: String,
    pub colour: Color32,
    pub report: Result<TremorReport, String>,
    /// Where a followed point's samples went, when the skin was not found in some windows.
    pub missing_line: Option<String>,
    /// With each other point.
    pub coherence: Vec<PairCoherence>,
}

#[derive(Default)]
pub struct TremorPanel {
    computed: Option<Instant>,
    pub results: Vec<PointAnalysis>,
}

/// One line summary of a report, as shown and as exported.
pub fn summary(r: &TremorReport) -> String {
    match r.peak_frequency_hz {
        Some(f) => format!(
            "{f:.2} Hz · {:.2} mm peak-to-peak · {:.2} mm RMS",
            r.amplitude_peak_to_peak_mm, r.amplitude_rms_mm
        ),
        None => format!(
            "no tremor above the noise · {:.3} mm RMS in 3–12 Hz",
            r.amplitude_rms_mm
        ),
    }
}

/// Why a followed point's samples are missing, as shown under its missing figures.
pub fn missing_line(m: &MissingSamples) -> String {
    format!(
        "{} (a point a little way in from the fingertip's end follows better; or turn \
         \"Follow the skin\" off)",
        m.followed_summary()
    )
}

impl TremorPanel {
    /// Recomputes the figures when due (or when `force`d).
    pub fn update(&mut self, series: &[Series], options: &AnalysisOptions, force: bool) {
        if !force && self.computed.is_some_and(|t| t.elapsed() < REFRESH) {
            return;
        }
        self.computed = Some(Instant::now());
        let reports: Vec<Result<TremorReport, String>> = series
            .iter()
            .map(|s| analyze(&s.times_s, &s.displacement_mm, options).map_err(|e| e.to_string()))
            .collect();
        let named: Vec<(&str, CoherenceSeries<'_>, Option<f64>)> = series
            .iter()
            .zip(&reports)
            .map(|(s, r)| {
                let series = CoherenceSeries {
                    times_s: &s.times_s,
                    displacement_mm: &s.displacement_mm,
                };
                let peak = r.as_ref().ok().and_then(|r| r.peak_frequency_hz);
                (s.name.as_str(), series, peak)
            })
            .collect();
        let coherence = pair_coherences(&named);
        self.results = series
            .iter()
            .zip(reports)
            .zip(coherence)
            .map(|((s, report), coherence)| PointAnalysis {
                id: s.id,
                name: s.name.clone(),
                colour: s.colour,
                report,
                missing_line: s
                    .missing
                    .filter(|m| m.not_found > 0)
                    .map(|m| missing_line(&m)),
                coherence,
            })
            .collect();
    }

    pub fn tremor_panel_ui(&mut self, ui: &mut egui::Ui) {
        ui.heading("Tremor");
        if self.results.is_empty() {
            ui.label("Add a control point to see its spectrum.");
            return;
        }
        egui::ScrollArea::vertical().show(ui, |ui| {
            for point in &self.results {
                ui.colored_label(point.colour, egui::RichText::new(&point.name).strong());
                match &point.report {
                    // A missing figure says why (too few valid samples) rather than show 0 mm.
                    Err(why) if why.starts_with("figures missing") => {
                        ui.label(why);
                        if let Some(line) = &point.missing_line {
                            ui.label(line);
                        }
                    }
                    Err(why) => {
                        ui.label(format!("waiting for samples: {why}"));
                    }
                    Ok(r) => {
                        ui.label(summary(r));
                        let bands = if r.frequency_bands.is_empty() {
                            "—".to_string()
                        } else {
                            r.frequency_bands.join(", ")
                        };
                        ui.label(format!(
                            "band: {bands} · MDS-UPDRS amplitude {} · {:.0} % valid",
                            r.updrs_amplitude_bin,
                            100.0 * r.valid_fraction
                        ));
                        ui.label(r.measures_line());
                        if let Some(line) = coherence_line(&point.coherence) {
                            ui.label(line);
                        }
                        spectrum_plot_ui(ui, point.id, point.colour, r);
                    }
                }
                ui.separator();
            }
        });
    }
}

fn spectrum_plot_ui(ui: &mut egui::Ui, id: u64, colour: Color32, r: &TremorReport) {
    let points: Vec<[f64; 2]> = r
        .spectrum
        .frequency_hz
        .iter()
        .zip(&r.spectrum.density)
        .filter(|(f, _)| **f <= 20.0)
        .map(|(f, d)| [*f, *d])
        .collect();
    let top = points.iter().map(|p| p[1]).fold(1e-9, f64::max);
    Plot::new(("spectrum", id))
        .height(120.0)
        .x_axis_label("frequency (Hz)")
        .y_axis_label("PSD (mm²/Hz)")
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
        .include_x(0.0)
        .include_x(20.0)
        .include_y(0.0)
        .show(ui, |plot_ui| {
            plot_ui.polygon(
                Polygon::new(
                    "3–12 Hz",
                    PlotPoints::from(vec![[3.0, 0.0], [12.0, 0.0], [12.0, top], [3.0, top]]),
                )
                .fill_color(Color32::from_rgba_unmultiplied(120, 120, 200, 40))
                .stroke(egui::Stroke::NONE),
            );
            plot_ui.line(Line::new("PSD", PlotPoints::from(points)).color(colour));
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use tremorscan::tremor::TrackSample;

    #[test]
    fn a_followed_point_says_how_often_its_skin_was_not_found() {
        let mut samples = vec![TrackSample::missing(0.0, 0); 9];
        samples.push(TrackSample {
            pixel: Some((1.0, 2.0)),
            ..TrackSample::missing(0.1, 1)
        });
        let line = missing_line(&MissingSamples::of(&samples));
        assert!(
            line.starts_with(
                "the followed skin was not found in 90 % of the windows and had no depth in 10 %"
            ),
            "{line}"
        );
    }
}
