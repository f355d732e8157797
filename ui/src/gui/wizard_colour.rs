//! The colour calibration wizard: place a white target, project and capture the ten Table 1
//! colours one by one with live exposure and saturation feedback, fit the cross-talk `A` and `b`
//! ([`calibrate_colour`]), show them with the residual and the warnings, then save or reject.
//!
//! On the virtual rig the target is the rig's white board (`rig::captures::colour_target`) and
//! each capture is rendered with the projector showing that colour; the exposure slider scales
//! the projector's gain, so too much exposure shows up as saturation exactly as on a camera.

use std::path::PathBuf;
use tremorscan::calibrate::colour::{calibrate_colour, ColourCalibration, ColourOptions, Roi};
use tremorscan::calibrate::file::ColourFile;
use tremorscan::calibrate::TABLE1_LEVELS;
use tremorscan::frame::Frame;
use tremorscan::rig::captures::colour_target;
use tremorscan::rig::{RigConfig, VirtualRig};

/// Room light while the colour captures are taken, gray levels on white.
const AMBIENT_GRAY: f64 = 10.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColourStep {
    PlaceTarget,
    Capture,
    Review,
}

/// Exposure feedback of one capture in the region of interest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    pub mean_rgb: [f64; 3],
    /// Share of samples with a channel at or above the saturation level.
    pub saturated: f64,
}

/// Mean level and saturated share of `frame` inside `roi`.
pub fn exposure_of(frame: &Frame, roi: Roi, saturation_level: u8) -> Exposure {
    let mut sum = [0.0f64; 3];
    let mut saturated = 0usize;
    let mut n = 0usize;
    for y in roi.y..(roi.y + roi.height).min(frame.height) {
        for x in roi.x..(roi.x + roi.width).min(frame.width) {
            let i = (y * frame.width + x) * frame.channels;
            let px = &frame.data[i..i + frame.channels];
            for c in 0..3 {
                sum[c] += f64::from(px[c.min(frame.channels - 1)]);
            }
            saturated += usize::from(px.iter().any(|&v| v >= saturation_level));
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    Exposure {
        mean_rgb: sum.map(|s| s / n),
        saturated: saturated as f64 / n,
    }
}

pub struct ColourWizard {
    pub step: ColourStep,
    config: RigConfig,
    /// Exposure relative to the nominal one (the rig's projector gain).
    pub exposure: f64,
    pub captures: Vec<Frame>,
    pub feedback: Vec<Exposure>,
    pub result: Option<Result<ColourCalibration, String>>,
    pub save_path: String,
    pub roi: Roi,
    /// Live feedback at the current exposure, before the next capture.
    pub live: Option<LiveExposure>,
}

/// What the camera sees now, at the exposure set: the next colour, and the worst saturation of
/// the three full-level colours (the ones that clip first).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveExposure {
    pub exposure: f64,
    pub next_capture: usize,
    pub next: Exposure,
    pub full_level_saturated: f64,
    computed: std::time::Instant,
}

impl ColourWizard {
    pub fn new(config: RigConfig, save_path: PathBuf) -> Self {
        let (w, h) = (config.camera.width, config.camera.height);
        let side = (w.min(h) / 10).max(4);
        Self {
            step: ColourStep::PlaceTarget,
            config,
            exposure: 1.0,
            captures: Vec::new(),
            feedback: Vec::new(),
            result: None,
            save_path: save_path.display().to_string(),
            roi: Roi {
                x: (w - side) / 2,
                y: (h - side) / 2,
                width: side,
                height: side,
            },
            live: None,
        }
    }

    /// The camera frame with the projector showing Table 1 colour `k` at the current exposure.
    fn render_colour(&self, k: usize) -> Result<Frame, String> {
        let levels = *TABLE1_LEVELS.get(k).ok_or("all ten colours are captured")?;
        let mut target = colour_target(&self.config, AMBIENT_GRAY).map_err(|e| e.to_string())?;
        target.projector_gain_gray *= self.exposure;
        let sequence = target.default_sequence().map_err(|e| e.to_string())?;
        let rig = VirtualRig::new(target, sequence).map_err(|e| e.to_string())?;
        let mut frame = rig.blank_frame();
        rig.render_flat(k as u64, levels, 0.0, &mut frame, None)
            .map_err(|e| e.to_string())?;
        Ok(frame)
    }

    /// Refreshes the live feedback when the exposure or the next colour changed (at most four
    /// times a second while the slider moves).
    pub fn update_live(&mut self) -> Result<(), String> {
        let k = self.captures.len();
        if k >= TABLE1_LEVELS.len() {
            self.live = None;
            return Ok(());
        }
        if let Some(l) = &self.live {
            let same = l.exposure == self.exposure && l.next_capture == k;
            if same || l.computed.elapsed() < std::time::Duration::from_millis(250) {
                return Ok(());
            }
        }
        let next = exposure_of(&self.render_colour(k)?, self.roi, 250);
        let mut full_level_saturated = 0.0f64;
        for (j, levels) in TABLE1_LEVELS.iter().enumerate() {
            if levels.contains(&255) {
                let e = exposure_of(&self.render_colour(j)?, self.roi, 250);
                full_level_saturated = full_level_saturated.max(e.saturated);
            }
        }
        self.live = Some(LiveExposure {
            exposure: self.exposure,
            next_capture: k,
            next,
            full_level_saturated,
            computed: std::time::Instant::now(),
        });
        Ok(())
    }

    fn options(&self) -> ColourOptions {
        ColourOptions {
            roi: self.roi,
            samples: 10_000,
            saturation_level: 250,
            seed: 1,
        }
    }

    /// Projects the next Table 1 colour and captures it.
    pub fn capture_next(&mut self) -> Result<(), String> {
        let frame = self.render_colour(self.captures.len())?;
        self.feedback.push(exposure_of(&frame, self.roi, 250));
        self.captures.push(frame);
        if self.captures.len() == TABLE1_LEVELS.len() {
            self.result =
                Some(calibrate_colour(&self.captures, &self.options()).map_err(|e| e.to_string()));
            self.step = ColourStep::Review;
        }
        Ok(())
    }

    /// Starts the captures over (e.g. after changing the exposure).
    pub fn restart_captures(&mut self) {
        self.captures.clear();
        self.feedback.clear();
        self.result = None;
        self.step = ColourStep::Capture;
    }

    /// Saves the accepted result; returns the path written.
    pub fn save(&self) -> Result<PathBuf, String> {
        let Some(Ok(result)) = &self.result else {
            return Err("there is no successful fit to save".to_string());
        };
        let path = save_target(&self.save_path)?;
        ColourFile::new(&result.cross_talk, result.residual_rms_gray)
            .save(&path)
            .map_err(|e| e.to_string())?;
        Ok(path)
    }
}

/// What the wizard asks the app to do.
#[derive(Debug, Clone, PartialEq)]
pub enum WizardOutcome {
    Open,
    Closed,
    /// A calibration file was saved: use it.
    Saved(PathBuf),
}

/// The path typed for a calibration file, with its folder created.
pub fn save_target(typed: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(typed.trim());
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    Ok(path)
}

/// Asks where to save a calibration file (JSON), starting from `current`.
pub fn choose_save_path(current: &str) -> Option<String> {
    let current = PathBuf::from(current.trim());
    let mut dialog = rfd::FileDialog::new()
        .set_title("Save the calibration")
        .add_filter("JSON", &["json"]);
    if let Some(dir) = current.parent().filter(|d| d.is_dir()) {
        dialog = dialog.set_directory(dir);
    }
    if let Some(name) = current.file_name() {
        dialog = dialog.set_file_name(name.to_string_lossy());
    }
    dialog.save_file().map(|p| p.display().to_string())
}

pub fn colour_wizard_ui(ui: &mut egui::Ui, w: &mut ColourWizard) -> WizardOutcome {
    let mut outcome = WizardOutcome::Open;
    match w.step {
        ColourStep::PlaceTarget => {
            ui.label("Step 1 of 3: place a flat white target where the hand will be, filling the middle of the camera image. Dim the room light.");
            if ui.button("Next: capture colours").clicked() {
                w.restart_captures();
            }
        }
        ColourStep::Capture => {
            ui.label(format!(
                "Step 2 of 3: the projector shows each of the ten Table 1 colours; capture each ({} of {} done).",
                w.captures.len(),
                TABLE1_LEVELS.len()
            ));
            ui.add_enabled(
                w.captures.is_empty(),
                egui::Slider::new(&mut w.exposure, 0.3..=2.0).text("exposure (relative)"),
            );
            if let Some(levels) = TABLE1_LEVELS.get(w.captures.len()) {
                ui.label(format!(
                    "next colour: projector levels R {} G {} B {}",
                    levels[0], levels[1], levels[2]
                ));
            }
            if let Err(e) = w.update_live() {
                w.result = Some(Err(e));
            }
            if let Some(l) = &w.live {
                let text = format!(
                    "live: mean R G B {:.1} {:.1} {:.1} · full-level colours saturated on {:.1} %",
                    l.next.mean_rgb[0],
                    l.next.mean_rgb[1],
                    l.next.mean_rgb[2],
                    100.0 * l.full_level_saturated
                );
                if l.full_level_saturated > 0.01 {
                    ui.colored_label(egui::Color32::RED, text + ": lower the exposure");
                } else {
                    ui.label(text);
                }
            }
            exposure_table_ui(ui, w);
            ui.horizontal(|ui| {
                if ui.button("Capture colour").clicked() {
                    if let Err(e) = w.capture_next() {
                        w.result = Some(Err(e));
                    }
                }
                if ui.button("Start over").clicked() {
                    w.restart_captures();
                }
            });
            if let Some(Err(e)) = &w.result {
                ui.colored_label(egui::Color32::RED, e);
            }
        }
        ColourStep::Review => {
            ui.label("Step 3 of 3: the fitted cross-talk c = A·p + b.");
            exposure_table_ui(ui, w);
            match &w.result {
                Some(Ok(r)) => {
                    let a = r.cross_talk.a;
                    egui::Grid::new("colour_fit").show(ui, |ui| {
                        for row in 0..3 {
                            ui.label(format!("A[{row}]"));
                            for col in 0..3 {
                                ui.monospace(format!("{:8.4}", a[(row, col)]));
                            }
                            ui.label(format!("b[{row}] = {:6.2}", r.cross_talk.b_gray[row]));
                            ui.end_row();
                        }
                    });
                    ui.label(format!(
                        "residual RMS {:.3} gray levels",
                        r.residual_rms_gray
                    ));
                    for warning in &r.warnings {
                        ui.colored_label(
                            egui::Color32::from_rgb(230, 150, 0),
                            format!("warning: {warning}"),
                        );
                    }
                    ui.horizontal(|ui| {
                        let l = ui.label("Save to");
                        ui.add(
                            egui::TextEdit::singleline(&mut w.save_path)
                                .desired_width(260.0)
                                .id_salt("colour_save_path"),
                        )
                        .labelled_by(l.id);
                        if ui.button("Choose…").clicked() {
                            if let Some(path) = choose_save_path(&w.save_path) {
                                w.save_path = path;
                            }
                        }
                    });
                    ui.horizontal(|ui| {
                        if ui.button("Save colour calibration").clicked() {
                            match w.save() {
                                Ok(path) => outcome = WizardOutcome::Saved(path),
                                Err(e) => w.result = Some(Err(e)),
                            }
                        }
                        if ui.button("Reject and start over").clicked() {
                            w.restart_captures();
                        }
                    });
                }
                Some(Err(e)) => {
                    ui.colored_label(egui::Color32::RED, format!("the fit failed: {e}"));
                    if ui.button("Start over").clicked() {
                        w.restart_captures();
                    }
                }
                None => {}
            }
        }
    }
    if ui.button("Close wizard").clicked() {
        outcome = WizardOutcome::Closed;
    }
    outcome
}

fn exposure_table_ui(ui: &mut egui::Ui, w: &ColourWizard) {
    if w.feedback.is_empty() {
        return;
    }
    egui::Grid::new("colour_exposure")
        .striped(true)
        .show(ui, |ui| {
            ui.strong("colour");
            ui.strong("mean R G B");
            ui.strong("saturated");
            ui.end_row();
            for (k, e) in w.feedback.iter().enumerate() {
                let l = TABLE1_LEVELS[k];
                ui.label(format!("{k}: ({}, {}, {})", l[0], l[1], l[2]));
                ui.monospace(format!(
                    "{:5.1} {:5.1} {:5.1}",
                    e.mean_rgb[0], e.mean_rgb[1], e.mean_rgb[2]
                ));
                let text = format!("{:.1} %", 100.0 * e.saturated);
                if e.saturated > 0.01 {
                    ui.colored_label(egui::Color32::RED, text + " lower the exposure");
                } else {
                    ui.label(text);
                }
                ui.end_row();
            }
        });
}
