//! The displacement plot: every control point's displacement over the last five seconds along
//! the chosen axis (the optical axis, each point's principal axis of motion, or camera x, y,
//! z), every sample drawn (about 600 per point at 121 FPS; nothing is decimated), gaps left
//! open where a point was not measured. Live it follows the newest sample; paused it freezes
//! the series so they can be zoomed, dragged and hovered. The tremor panel analyses the same
//! series.

use egui::Color32;
use egui_plot::{Legend, Line, Plot, PlotPoints};
use nalgebra::Vector3;
use tremorscan::tremor::{displacements, DisplacementAxis, LiveTracker, MissingSamples, PointMode};

/// The axes the plot offers, with their labels.
const AXES: [(DisplacementAxis, &str); 5] = [
    (DisplacementAxis::Vertical, "vertical (optical axis)"),
    (DisplacementAxis::Principal, "principal axis of each point"),
    (DisplacementAxis::X, "camera x"),
    (DisplacementAxis::Y, "camera y"),
    (DisplacementAxis::Z, "camera z"),
];

/// One point's series at one instant.
#[derive(Debug, Clone)]
pub struct Series {
    pub id: u64,
    pub name: String,
    pub colour: Color32,
    pub times_s: Vec<f64>,
    pub displacement_mm: Vec<Option<f64>>,
    pub pixel: (f64, f64),
    /// Why samples are missing, for a point that follows the skin (`None` at a fixed pixel).
    pub missing: Option<MissingSamples>,
}

/// The series of every point in `tracker`, displacement along `axis` (the vertical is the
/// optical axis; a point too sparse for a principal axis has no displacement).
pub fn snapshot(
    tracker: &LiveTracker,
    axis: DisplacementAxis,
    colour: &mut impl FnMut(u64) -> Color32,
) -> Vec<Series> {
    let follows = tracker.mode() == PointMode::FollowSkin;
    tracker
        .points
        .iter()
        .map(|p| {
            let samples = p.history(tracker.analysis.window_frames);
            let times_s = samples.iter().map(|s| s.time_s).collect();
            let displacement_mm = match axis.unit(&Vector3::z(), &samples, &tracker.analysis) {
                Some(unit) => displacements(&samples, &unit),
                None => vec![None; samples.len()],
            };
            Series {
                id: p.id,
                name: p.name.clone(),
                colour: colour(p.id),
                times_s,
                displacement_mm,
                pixel: p.pixel,
                missing: follows.then(|| MissingSamples::of(&samples)),
            }
        })
        .collect()
}

/// Splits a series into runs of measured samples, as plot points.
pub fn segments(times_s: &[f64], values: &[Option<f64>]) -> Vec<Vec<[f64; 2]>> {
    let mut out: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut run: Vec<[f64; 2]> = Vec::new();
    for (t, v) in times_s.iter().zip(values) {
        match v {
            Some(v) => run.push([*t, *v]),
            None if !run.is_empty() => out.push(std::mem::take(&mut run)),
            None => {}
        }
    }
    if !run.is_empty() {
        out.push(run);
    }
    out
}

#[derive(Default)]
pub struct DisplacementPlot {
    /// Frozen series while paused.
    paused: Option<Vec<Series>>,
    /// The axis the displacements are taken along.
    pub axis: DisplacementAxis,
}

impl DisplacementPlot {
    pub fn is_paused(&self) -> bool {
        self.paused.is_some()
    }

    pub fn displacement_plot_ui(&mut self, ui: &mut egui::Ui, live: &[Series]) {
        ui.horizontal(|ui| {
            let heading = ui.strong("Displacement along");
            let label = AXES
                .iter()
                .find(|(a, _)| *a == self.axis)
                .map_or("", |(_, l)| l);
            egui::ComboBox::from_id_salt("displacement_axis")
                .selected_text(label)
                .show_ui(ui, |ui| {
                    for (axis, label) in AXES {
                        ui.selectable_value(&mut self.axis, axis, label);
                    }
                })
                .response
                .labelled_by(heading.id);
            let label = if self.is_paused() {
                "Resume plot"
            } else {
                "Pause plot"
            };
            if ui.button(label).clicked() {
                self.paused = match self.paused {
                    Some(_) => None,
                    None => Some(live.to_vec()),
                };
            }
            if self.is_paused() {
                ui.label("paused: drag to pan, scroll to zoom, double-click to fit");
            }
        });
        let series = self.paused.as_deref().unwrap_or(live);
        let newest = series
            .iter()
            .filter_map(|s| s.times_s.last().copied())
            .fold(f64::NEG_INFINITY, f64::max);
        let mut plot = Plot::new("displacement")
            .legend(Legend::default())
            .x_axis_label("time (s)")
            .y_axis_label("displacement (mm)")
            .include_y(-1.0)
            .include_y(1.0);
        if !self.is_paused() {
            plot = plot.allow_drag(false).allow_zoom(false).allow_scroll(false);
            if newest.is_finite() {
                plot = plot
                    .include_x(newest - super::source::HISTORY_S)
                    .include_x(newest)
                    .auto_bounds(egui::Vec2b::new(true, true));
            }
        }
        plot.show(ui, |plot_ui| {
            for s in series {
                // Runs of one point share its name, so the legend has one entry per point.
                for run in segments(&s.times_s, &s.displacement_mm) {
                    plot_ui.line(
                        Line::new(s.name.clone(), PlotPoints::from(run))
                            .color(s.colour)
                            .width(1.5),
                    );
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_split_the_series_and_every_sample_is_kept() {
        let t: Vec<f64> = (0..8).map(f64::from).collect();
        let v = [
            Some(1.0),
            Some(2.0),
            None,
            None,
            Some(3.0),
            None,
            Some(4.0),
            Some(5.0),
        ];
        let s = segments(&t, &v);
        assert_eq!(
            s,
            vec![
                vec![[0.0, 1.0], [1.0, 2.0]],
                vec![[4.0, 3.0]],
                vec![[6.0, 4.0], [7.0, 5.0]]
            ]
        );
        let long: Vec<Option<f64>> = (0..605).map(|i| Some(f64::from(i))).collect();
        let lt: Vec<f64> = (0..605).map(f64::from).collect();
        assert_eq!(segments(&lt, &long)[0].len(), 605);
    }
}
