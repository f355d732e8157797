//! The geometric calibration wizard: give the board geometry, capture poses (each pose: the board
//! under room light, then both coding axes), watch a coverage map of where corners have been seen
//! in the camera and the projector, calibrate, read the per-view reprojection errors, drop views
//! and recompute, then save the calibration file.
//!
//! On the virtual rig each capture renders the rig's standard board at the next of twelve
//! operator-like poses ([`standard_poses`]); the wizard itself only sees the images, as it would
//! at a real rig.

use super::wizard_colour::WizardOutcome;
use egui::{Color32, Pos2, Rect, Sense, Stroke, Vec2};
use std::path::PathBuf;
use tremorscan::calibrate::geometric::{
    calibrate_geometric, GeometricCalibration, GeometricOptions, ViewObservation,
};
use tremorscan::calibrate::{observe_capture, BoardSpec, CalibrationFile, LocalFitOptions};
use tremorscan::rig::captures::{render_capture, standard_poses};
use tremorscan::rig::RigConfig;
use tremorscan::session::manifest::PatternJson;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GeometricStep {
    Board,
    Poses,
    Review,
}

pub struct GeometricWizard {
    pub step: GeometricStep,
    config: RigConfig,
    pub board: BoardSpec,
    /// Captured views (a failed capture is reported and not kept).
    pub views: Vec<ViewObservation>,
    pub dropped: Vec<bool>,
    pub result: Option<Result<GeometricCalibration, String>>,
    pub last_error: Option<String>,
    pub save_path: String,
    poses_taken: usize,
}

impl GeometricWizard {
    pub fn new(config: RigConfig, save_path: PathBuf) -> Self {
        Self {
            step: GeometricStep::Board,
            config,
            board: BoardSpec {
                cols: 9,
                rows: 6,
                square_mm: 20.0,
            },
            views: Vec::new(),
            dropped: Vec::new(),
            result: None,
            last_error: None,
            save_path: save_path.display().to_string(),
            poses_taken: 0,
        }
    }

    /// Captures the next pose (both axes) and finds the board in it.
    pub fn capture_pose(&mut self) -> Result<usize, String> {
        let poses = standard_poses();
        let board = poses[self.poses_taken % poses.len()];
        let view = self.poses_taken;
        self.poses_taken += 1;
        let (capture, _) =
            render_capture(&self.config, board, view as u64).map_err(|e| e.to_string())?;
        let seen = observe_capture(
            view,
            &capture,
            &self.board,
            self.config.cross_talk,
            &LocalFitOptions::default(),
        )
        .map_err(|e| format!("pose {}: {e}", view + 1))?;
        self.views.push(seen);
        self.dropped.push(false);
        Ok(self.views.len())
    }

    /// Calibrates from the views not dropped.
    pub fn calibrate(&mut self) {
        let options = GeometricOptions {
            excluded_views: (0..self.views.len()).filter(|&k| self.dropped[k]).collect(),
            ..GeometricOptions::default()
        };
        let camera = (self.config.camera.width, self.config.camera.height);
        let projector = (self.config.projector.width, self.config.projector.height);
        self.result = Some(
            calibrate_geometric(&self.board, &self.views, camera, projector, &options)
                .map_err(|e| e.to_string()),
        );
        self.step = GeometricStep::Review;
    }

    pub fn save(&self) -> Result<PathBuf, String> {
        let Some(Ok(c)) = &self.result else {
            return Err("there is no successful calibration to save".to_string());
        };
        let path = super::wizard_colour::save_target(&self.save_path)?;
        let pattern = self
            .config
            .default_sequence()
            .ok()
            .map(|s| PatternJson::from_sequence(&s));
        CalibrationFile::from_geometric(c, Some(&self.config.cross_talk), "virtual rig", pattern)
            .save(&path)
            .map_err(|e| e.to_string())?;
        Ok(path)
    }
}

/// Corners seen so far, drawn over a frame of `size`, scaled to `width` points.
fn coverage_ui(
    ui: &mut egui::Ui,
    title: &str,
    size: (usize, usize),
    corners: &[[f64; 2]],
    width: f32,
) {
    ui.vertical(|ui| {
        ui.label(title);
        let scale = width / size.0 as f32;
        let (rect, _) =
            ui.allocate_exact_size(Vec2::new(width, size.1 as f32 * scale), Sense::hover());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(30));
        // A 4×4 grid: a cell with no corner yet is where the next pose should put the board.
        for gx in 0..4 {
            for gy in 0..4 {
                let cell = Rect::from_min_size(
                    rect.min
                        + Vec2::new(
                            gx as f32 * rect.width() / 4.0,
                            gy as f32 * rect.height() / 4.0,
                        ),
                    Vec2::new(rect.width() / 4.0, rect.height() / 4.0),
                );
                let covered = corners.iter().any(|c| {
                    cell.contains(rect.min + Vec2::new(c[0] as f32 * scale, c[1] as f32 * scale))
                });
                if !covered {
                    painter.rect_stroke(
                        cell.shrink(1.0),
                        0.0,
                        Stroke::new(1.0, Color32::from_rgb(120, 60, 60)),
                        egui::StrokeKind::Inside,
                    );
                }
            }
        }
        for c in corners {
            painter.circle_filled(
                rect.min + Vec2::new(c[0] as f32 * scale, c[1] as f32 * scale),
                1.5,
                Color32::from_rgb(80, 220, 120),
            );
        }
        painter.rect_stroke(
            Rect::from_min_max(rect.min, Pos2::new(rect.max.x, rect.max.y)),
            0.0,
            Stroke::new(1.0, Color32::GRAY),
            egui::StrokeKind::Inside,
        );
    });
}

pub fn geometric_wizard_ui(ui: &mut egui::Ui, w: &mut GeometricWizard) -> WizardOutcome {
    let mut outcome = WizardOutcome::Open;
    match w.step {
        GeometricStep::Board => {
            ui.label("Step 1 of 3: the printed chessboard (count inner corners).");
            egui::Grid::new("board_geometry").show(ui, |ui| {
                let l = ui.label("inner corners across");
                ui.add(egui::DragValue::new(&mut w.board.cols).range(3..=30))
                    .labelled_by(l.id);
                ui.end_row();
                let l = ui.label("inner corners down");
                ui.add(egui::DragValue::new(&mut w.board.rows).range(3..=30))
                    .labelled_by(l.id);
                ui.end_row();
                let l = ui.label("square size");
                ui.add(
                    egui::DragValue::new(&mut w.board.square_mm)
                        .range(1.0..=200.0)
                        .suffix(" mm"),
                )
                .labelled_by(l.id);
                ui.end_row();
            });
            if ui.button("Next: capture poses").clicked() {
                w.step = GeometricStep::Poses;
            }
        }
        GeometricStep::Poses => {
            ui.label("Step 2 of 3: hold the board still for each pose; tilt it up to about 30° and move it so corners cover every cell of both maps. Each pose captures both axes.");
            let camera: Vec<[f64; 2]> = w.views.iter().flat_map(|v| v.camera_px.clone()).collect();
            let projector: Vec<[f64; 2]> = w
                .views
                .iter()
                .flat_map(|v| v.projector_px.iter().flatten().copied().collect::<Vec<_>>())
                .collect();
            ui.horizontal(|ui| {
                coverage_ui(
                    ui,
                    "camera",
                    (w.config.camera.width, w.config.camera.height),
                    &camera,
                    200.0,
                );
                coverage_ui(
                    ui,
                    "projector",
                    (w.config.projector.width, w.config.projector.height),
                    &projector,
                    160.0,
                );
            });
            ui.label(format!("{} poses captured", w.views.len()));
            ui.horizontal(|ui| {
                if ui.button("Capture pose").clicked() {
                    w.last_error = w.capture_pose().err();
                }
                let enough = w.views.len() >= tremorscan::calibrate::geometric::MIN_VIEWS;
                if ui
                    .add_enabled(enough, egui::Button::new("Calibrate"))
                    .clicked()
                {
                    w.calibrate();
                }
            });
            if let Some(e) = &w.last_error {
                ui.colored_label(Color32::RED, e);
            }
        }
        GeometricStep::Review => review_ui(ui, w, &mut outcome),
    }
    if ui.button("Close wizard").clicked() {
        outcome = WizardOutcome::Closed;
    }
    outcome
}

fn review_ui(ui: &mut egui::Ui, w: &mut GeometricWizard, outcome: &mut WizardOutcome) {
    ui.label("Step 3 of 3: per-view reprojection error. Untick a view to drop it, then recompute.");
    match &w.result {
        Some(Ok(c)) => {
            let by_view: Vec<_> = c.views.clone();
            egui::Grid::new("view_errors").striped(true).show(ui, |ui| {
                ui.strong("use");
                ui.strong("view");
                ui.strong("camera RMS px");
                ui.strong("projector RMS px");
                ui.end_row();
                for k in 0..w.views.len() {
                    let mut used = !w.dropped[k];
                    ui.checkbox(&mut used, "");
                    w.dropped[k] = !used;
                    ui.label(format!("{}", k + 1));
                    match by_view.iter().find(|v| v.view == k) {
                        Some(v) => {
                            ui.monospace(format!("{:.3}", v.camera_rms_px));
                            ui.monospace(format!("{:.3}", v.projector_rms_px));
                        }
                        None => {
                            ui.label("dropped");
                            ui.label("");
                        }
                    }
                    ui.end_row();
                }
            });
            ui.label(format!(
                "overall RMS: camera {:.3} px, projector {:.3} px · baseline {:.2} mm · camera f {:.1} px",
                c.camera_rms_px,
                c.projector_rms_px,
                c.baseline_mm(),
                c.camera.intrinsics.fx
            ));
        }
        Some(Err(e)) => {
            ui.colored_label(Color32::RED, format!("calibration refused: {e}"));
        }
        None => {}
    }
    ui.horizontal(|ui| {
        if ui.button("Recompute").clicked() {
            w.calibrate();
        }
        if ui.button("Capture more poses").clicked() {
            w.step = GeometricStep::Poses;
        }
    });
    if matches!(w.result, Some(Ok(_))) {
        ui.horizontal(|ui| {
            let l = ui.label("Save to");
            ui.add(
                egui::TextEdit::singleline(&mut w.save_path)
                    .desired_width(260.0)
                    .id_salt("geometric_save_path"),
            )
            .labelled_by(l.id);
            if ui.button("Choose…").clicked() {
                if let Some(path) = super::wizard_colour::choose_save_path(&w.save_path) {
                    w.save_path = path;
                }
            }
        });
        if ui.button("Save calibration").clicked() {
            match w.save() {
                Ok(path) => *outcome = WizardOutcome::Saved(path),
                Err(e) => w.last_error = Some(e),
            }
        }
    }
    if let Some(e) = &w.last_error {
        ui.colored_label(Color32::RED, e);
    }
}
