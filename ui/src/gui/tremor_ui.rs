//! The tremor panel: per control point, the spectrum of its last five seconds (3–12 Hz band
//! shaded), the peak frequency, the amplitude, the clinical band label and the MDS-UPDRS
//! amplitude bin, from [`tremorscan::tremor::analyze`]. The figures are recomputed a few times a
//! second (a Welch spectrum of 600 samples takes well under a millisecond), not every frame,
//! so the numbers can be read.

use super::plot_ui::Series;
use egui::Color32;
use egui_plot::{Line, Plot, PlotPoints, Polygon};
use std::time::{Duration, Instant};
use tremorscan::tremor::{analyze, AnalysisOptions, TremorReport};

const REFRESH: Duration = Duration::from_millis(300);

/// The analysis of one point, or why there is none yet.
pub type PointAnalysis = (u64, String, Color32, Result<TremorReport, String>);

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

impl TremorPanel {
    /// Recomputes the figures when due (or when `force`d).
    pub fn update(&mut self, series: &[Series], options: &AnalysisOptions, force: bool) {
        if !force && self.computed.is_some_and(|t| t.elapsed() < REFRESH) {
            return;
        }
        self.computed = Some(Instant::now());
        self.results = series
            .iter()
            .map(|s| {
                let r = analyze(&s.times_s, &s.displacement_mm, options).map_err(|e| e.to_string());
                (s.id, s.name.clone(), s.colour, r)
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
            for (id, name, colour, result) in &self.results {
                ui.colored_label(*colour, egui::RichText::new(name).strong());
                match result {
                    // A missing figure says why (too few valid samples) rather than show 0 mm.
                    Err(why) if why.starts_with("figures missing") => {
                        ui.label(why);
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
                        spectrum_plot_ui(ui, *id, *colour, r);
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
