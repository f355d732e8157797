//! Recording a trial: the form (subject, hand, condition, notes, countdown, duration or manual
//! stop, folder), the countdown, the recording with its progress, and the outcome. Every frame the
//! camera delivers during the recording is written (the pipeline's recorder never drops one
//! silently: if the disk cannot keep up the recording stops and says so, keeping what it wrote).
//! Stopping does not wait for the disk: the form shows "finishing" until the recorder reports
//! that every queued frame is written, then the outcome.

use super::source::Source;
use std::path::PathBuf;
use std::time::Instant;
use tremorscan::session::record::RecordingSummary;
use tremorscan::session::TrialJson;

/// Duration presets, seconds (0: stop by hand).
pub const DURATIONS_S: [f64; 4] = [5.0, 10.0, 30.0, 0.0];

#[derive(Debug, Clone, PartialEq)]
pub enum TrialState {
    Idle,
    Countdown {
        until: Instant,
    },
    Recording {
        started: Instant,
        dir: PathBuf,
        recorded_before: u64,
    },
    /// Stopped; the recorder is still writing the frames it holds.
    Finishing {
        dir: PathBuf,
    },
}

pub struct TrialForm {
    pub subject: String,
    pub hand: String,
    pub condition: String,
    pub notes: String,
    /// Seconds; 0 means stop by hand.
    pub duration_s: f64,
    pub countdown_s: f64,
    pub sessions_dir: String,
    pub state: TrialState,
    /// The last outcome, for the user to read.
    pub last_outcome: Option<String>,
}

impl TrialForm {
    pub fn new(sessions_dir: PathBuf, duration_s: f64, countdown_s: f64) -> Self {
        Self {
            subject: String::new(),
            hand: "right".to_string(),
            condition: "rest".to_string(),
            notes: String::new(),
            duration_s,
            countdown_s,
            sessions_dir: sessions_dir.display().to_string(),
            state: TrialState::Idle,
            last_outcome: None,
        }
    }

    fn trial(&self) -> TrialJson {
        TrialJson {
            subject_id: self.subject.trim().to_string(),
            hand: self.hand.clone(),
            condition: self.condition.trim().to_string(),
            operator_notes: self.notes.clone(),
            date: tremorscan::calibrate::file::utc_now_iso8601(),
            control_points: Vec::new(),
        }
    }

    /// A new folder under the sessions folder, named after the subject and the time.
    fn new_session_dir(&self) -> PathBuf {
        let stamp: String = tremorscan::calibrate::file::utc_now_iso8601()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect();
        let subject: String = self
            .subject
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let name = if subject.is_empty() {
            format!("trial-{stamp}")
        } else {
            format!("{subject}-{stamp}")
        };
        PathBuf::from(self.sessions_dir.trim()).join(name)
    }

    pub fn is_busy(&self) -> bool {
        self.state != TrialState::Idle
    }

    /// Advances the countdown and the timed stop; returns messages for the status bar.
    pub fn tick(&mut self, source: &Source, messages: &mut Vec<String>) {
        match &self.state {
            TrialState::Countdown { until } if Instant::now() >= *until => {
                self.begin(source, messages);
            }
            TrialState::Recording { started, .. }
                if self.duration_s > 0.0 && started.elapsed().as_secs_f64() >= self.duration_s =>
            {
                self.stop(source);
            }
            TrialState::Recording { dir, .. } if !source.pipeline.is_recording() => {
                // The recorder stopped by itself (disk full or too slow); its event says why.
                self.state = TrialState::Finishing { dir: dir.clone() };
            }
            _ => {}
        }
    }

    fn begin(&mut self, source: &Source, messages: &mut Vec<String>) {
        let Some(manifest) = source.recording_manifest.clone() else {
            messages.push("this device cannot record (a replay is already a recording)".into());
            self.state = TrialState::Idle;
            return;
        };
        let dir = self.new_session_dir();
        if let Some(parent) = dir.parent() {
            if let Err(e) = std::fs::create_dir_all(parent) {
                messages.push(format!("cannot create {}: {e}", parent.display()));
                self.state = TrialState::Idle;
                return;
            }
        }
        match source
            .pipeline
            .start_recording(&dir, manifest, self.trial())
        {
            Ok(()) => {
                self.state = TrialState::Recording {
                    started: Instant::now(),
                    dir,
                    recorded_before: source.pipeline.metrics().recorded,
                };
            }
            Err(e) => {
                messages.push(format!("recording did not start: {e}"));
                self.state = TrialState::Idle;
            }
        }
    }

    /// Stops a recording without waiting for the disk (the outcome comes with
    /// [`Self::recording_stopped`]), or cancels a countdown.
    pub fn stop(&mut self, source: &Source) {
        self.state = match std::mem::replace(&mut self.state, TrialState::Idle) {
            TrialState::Recording { dir, .. } => {
                source.pipeline.end_recording();
                TrialState::Finishing { dir }
            }
            other @ TrialState::Finishing { .. } => other,
            TrialState::Idle | TrialState::Countdown { .. } => TrialState::Idle,
        };
    }

    /// The recorder's report (the pipeline's `RecordingStopped` event): every frame it held is
    /// written, or why it failed.
    pub fn recording_stopped(&mut self, result: &Result<RecordingSummary, String>) {
        let dir = match &self.state {
            TrialState::Recording { dir, .. } | TrialState::Finishing { dir } => dir.clone(),
            _ => return,
        };
        self.last_outcome = Some(match result {
            Ok(s) => format!(
                "saved {} frames ({:.1} MB) to {}",
                s.frames,
                s.bytes as f64 / 1e6,
                dir.display()
            ),
            Err(e) => format!(
                "the recording failed: {e}; the frames written to {} stay readable",
                dir.display()
            ),
        });
        self.state = TrialState::Idle;
    }

    pub fn trial_ui(
        &mut self,
        ui: &mut egui::Ui,
        source: Option<&Source>,
        messages: &mut Vec<String>,
    ) {
        ui.heading("Trial");
        let can_record = source.is_some_and(|s| s.recording_manifest.is_some());
        ui.add_enabled_ui(!self.is_busy(), |ui| {
            egui::Grid::new("trial_form").num_columns(2).show(ui, |ui| {
                let l = ui.label("Subject id");
                ui.add(egui::TextEdit::singleline(&mut self.subject).id_salt("subject"))
                    .labelled_by(l.id);
                ui.end_row();
                ui.label("Hand");
                ui.horizontal(|ui| {
                    ui.selectable_value(&mut self.hand, "left".to_string(), "left");
                    ui.selectable_value(&mut self.hand, "right".to_string(), "right");
                });
                ui.end_row();
                let l = ui.label("Condition");
                ui.add(egui::TextEdit::singleline(&mut self.condition).id_salt("condition"))
                    .labelled_by(l.id);
                ui.end_row();
                let l = ui.label("Notes");
                ui.add(
                    egui::TextEdit::multiline(&mut self.notes)
                        .desired_rows(2)
                        .id_salt("notes"),
                )
                .labelled_by(l.id);
                ui.end_row();
                ui.label("Duration");
                ui.horizontal(|ui| {
                    for d in DURATIONS_S {
                        let label = if d > 0.0 {
                            format!("{d:.0} s")
                        } else {
                            "manual".to_string()
                        };
                        ui.selectable_value(&mut self.duration_s, d, label);
                    }
                });
                ui.end_row();
                ui.label("Countdown");
                ui.add(
                    egui::Slider::new(&mut self.countdown_s, 0.0..=10.0)
                        .suffix(" s")
                        .text("before recording"),
                );
                ui.end_row();
                let l = ui.label("Folder");
                ui.horizontal(|ui| {
                    ui.add(
                        egui::TextEdit::singleline(&mut self.sessions_dir)
                            .desired_width(150.0)
                            .id_salt("sessions_dir"),
                    )
                    .labelled_by(l.id);
                    if ui.button("Choose…").clicked() {
                        if let Some(dir) = rfd::FileDialog::new()
                            .set_title("Folder for recorded trials")
                            .pick_folder()
                        {
                            self.sessions_dir = dir.display().to_string();
                        }
                    }
                });
                ui.end_row();
            });
        });
        let Some(source) = source else {
            return;
        };
        match self.state.clone() {
            TrialState::Idle => {
                let button = ui.add_enabled(can_record, egui::Button::new("Record trial"));
                if !can_record {
                    button.on_disabled_hover_text(
                        "Recording needs a live device (the virtual rig or a camera)",
                    );
                } else if button.clicked() {
                    self.last_outcome = None;
                    if self.countdown_s > 0.0 {
                        self.state = TrialState::Countdown {
                            until: Instant::now()
                                + std::time::Duration::from_secs_f64(self.countdown_s),
                        };
                    } else {
                        self.begin(source, messages);
                    }
                }
            }
            TrialState::Countdown { until } => {
                let left = until
                    .saturating_duration_since(Instant::now())
                    .as_secs_f64();
                ui.label(
                    egui::RichText::new(format!("Recording starts in {:.0} s", left.ceil()))
                        .size(18.0),
                );
                if ui.button("Cancel").clicked() {
                    self.state = TrialState::Idle;
                }
            }
            TrialState::Recording {
                started,
                recorded_before,
                ..
            } => {
                let elapsed = started.elapsed().as_secs_f64();
                let frames = source
                    .pipeline
                    .metrics()
                    .recorded
                    .saturating_sub(recorded_before);
                let text = format!("REC {elapsed:.1} s · {frames} frames");
                if self.duration_s > 0.0 {
                    ui.add(egui::ProgressBar::new((elapsed / self.duration_s) as f32).text(text));
                } else {
                    ui.colored_label(egui::Color32::RED, text);
                }
                if ui.button("Stop recording").clicked() {
                    self.stop(source);
                }
            }
            TrialState::Finishing { dir } => {
                ui.horizontal(|ui| {
                    ui.spinner();
                    ui.label(format!(
                        "finishing: writing the last frames to {}",
                        dir.display()
                    ));
                });
            }
        }
        if let Some(outcome) = &self.last_outcome {
            ui.label(outcome);
        }
    }
}
