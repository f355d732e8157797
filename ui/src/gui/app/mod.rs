//! The main window: it owns the running [`Source`], the views and the panels, and lays them out.
//! Each frame it takes the newest cloud, copies the tracked points once (so no panel holds the
//! tracker's lock while it draws), lets every panel draw and collect the user's edits, then
//! applies the edits to the tracker in one place.

mod menus;

use super::camera_view::CameraView;
use super::cloud_view::CloudView;
use super::exports::{self, ExportKind};
use super::live_rig::{self, LiveRig};
use super::plot_ui::{self, DisplacementPlot};
use super::points::{self, PointColours, PointEdit};
use super::settings::{self, DeviceChoice, Settings};
use super::source::{Source, HISTORY_S};
use super::status_ui::{self, Messages, Status};
use super::tremor_ui::TremorPanel;
use super::trial_ui::{TrialForm, TrialState};
use super::wizard_colour::ColourWizard;
use super::wizard_geometric::GeometricWizard;
use std::path::PathBuf;
use std::sync::{mpsc, Arc};
use tremorscan::tremor::LiveTracker;

pub struct TremorApp {
    pub settings: Settings,
    /// Where settings persist (None: not persisted, as in tests).
    settings_path: Option<PathBuf>,
    pub source: Option<Source>,
    /// A real camera with the second screen, while it syncs and runs.
    pub live_rig: Option<LiveRig>,
    /// The tracker while no source runs (keeps the points).
    spare_tracker: LiveTracker,
    pub colours: PointColours,
    camera_view: CameraView,
    pub cloud_view: CloudView,
    pub plot: DisplacementPlot,
    pub tremor: TremorPanel,
    pub trial: TrialForm,
    pub messages: Messages,
    pub colour_wizard: Option<ColourWizard>,
    pub geometric_wizard: Option<GeometricWizard>,
    pub show_settings: bool,
    pub settings_draft: Settings,
    /// Typed replay folder (the dialog fills it too).
    pub replay_path: String,
    screenshot_results: (mpsc::Sender<String>, mpsc::Receiver<String>),
}

impl TremorApp {
    /// The app with `settings`, drawing its 3D view with wgpu when `has_renderer`.
    pub fn new(settings: Settings, settings_path: Option<PathBuf>, has_renderer: bool) -> Self {
        let trial = TrialForm::new(
            settings.sessions_dir.clone(),
            settings.trial_seconds,
            settings.countdown_seconds,
        );
        let mut app = Self {
            cloud_view: CloudView::new(has_renderer, settings.point_size_px),
            settings_draft: settings.clone(),
            replay_path: match &settings.device {
                DeviceChoice::Replay { session } => session.display().to_string(),
                DeviceChoice::VirtualRig | DeviceChoice::Camera { .. } => String::new(),
            },
            settings,
            settings_path,
            source: None,
            live_rig: None,
            spare_tracker: LiveTracker::new(HISTORY_S),
            colours: PointColours::default(),
            camera_view: CameraView::default(),
            plot: DisplacementPlot::default(),
            tremor: TremorPanel::default(),
            trial,
            messages: Messages::default(),
            colour_wizard: None,
            geometric_wizard: None,
            show_settings: false,
            screenshot_results: mpsc::channel(),
        };
        app.restart_source();
        app
    }

    /// (Re)starts the device of the current settings, carrying the control points over.
    pub fn restart_source(&mut self) {
        self.stop_source();
        if matches!(self.settings.device, DeviceChoice::Camera { .. }) {
            match super::rig_devices::begin_from_settings(&self.settings) {
                Ok(rig) => {
                    self.messages
                        .info("camera open; measuring the screen's delay with a flash code");
                    self.live_rig = Some(rig);
                }
                Err(e) => self.messages.error(format!("{e:#}")),
            }
            self.persist();
            return;
        }
        let mut tracker = self.spare_tracker.clone();
        tracker.clear_history();
        match Source::start(&self.settings, tracker) {
            Ok(source) => {
                if let Some(session) = &source.session {
                    let saved = session
                        .manifest
                        .trial
                        .as_ref()
                        .map(|t| t.control_points.clone())
                        .unwrap_or_default();
                    let mut tracker = source.tracker();
                    if tracker.points.is_empty() {
                        for p in saved {
                            tracker.add(p.name, (p.u, p.v));
                        }
                    }
                }
                self.messages.info(format!(
                    "started {}; decoding on {}",
                    source.pipeline.camera_name(),
                    source.pipeline.decoder_name()
                ));
                if let Some(note) = &source.decode_note {
                    self.messages.info(note.clone());
                }
                self.cloud_view.camera = None;
                self.source = Some(source);
            }
            Err(e) => self.messages.error(format!("{e:#}")),
        }
        self.persist();
    }

    /// Stops the running source and live rig, keeping the control points.
    fn stop_source(&mut self) {
        if let Some(old) = self.source.take() {
            self.trial.stop(&old);
            let (tracker, events) = old.stop();
            self.spare_tracker = tracker;
            self.handle_events(events);
        }
        self.live_rig = None;
    }

    /// Starts a live rig on an already opened camera (tests inject a camera here).
    pub fn start_live_rig(
        &mut self,
        camera: Box<dyn tremorscan::device::Camera>,
        parts: live_rig::RigParts,
        plan: live_rig::ScreenPlan,
    ) {
        self.stop_source();
        match LiveRig::begin(camera, parts, plan) {
            Ok(rig) => self.live_rig = Some(rig),
            Err(e) => self.messages.error(format!("{e:#}")),
        }
    }

    /// One pass of the live rig: its screen, and its source once synced.
    fn drive_live_rig(&mut self, ctx: &egui::Context) {
        let Some(rig) = &mut self.live_rig else {
            return;
        };
        let mut tracker = self.spare_tracker.clone();
        tracker.clear_history();
        match rig.drive(ctx, tracker) {
            Some(Ok(source)) => {
                self.messages.info(rig.status_line());
                self.source = Some(source);
            }
            Some(Err(e)) => {
                self.messages.error(format!("{e:#}"));
                self.live_rig = None;
            }
            None => {}
        }
    }

    /// Writes the settings file, if this app persists settings.
    pub fn persist(&mut self) {
        self.settings.point_size_px = self.cloud_view.point_size_px;
        self.settings.trial_seconds = self.trial.duration_s;
        self.settings.countdown_seconds = self.trial.countdown_s;
        self.settings.sessions_dir = PathBuf::from(self.trial.sessions_dir.trim());
        if let Some(path) = &self.settings_path {
            if let Err(e) = settings::save(path, &self.settings) {
                self.messages.error(e);
            }
        }
    }

    /// Opens a saved session for replay.
    pub fn open_replay(&mut self, session: PathBuf) {
        self.replay_path = session.display().to_string();
        self.settings.device = DeviceChoice::Replay { session };
        self.restart_source();
    }

    pub fn use_virtual_rig(&mut self) {
        self.settings.device = DeviceChoice::VirtualRig;
        self.restart_source();
    }

    /// A copy of the tracked points (the tracker thread keeps running meanwhile).
    pub fn tracker_copy(&self) -> LiveTracker {
        match &self.source {
            Some(s) => s.tracker().clone(),
            None => self.spare_tracker.clone(),
        }
    }

    /// Hands pipeline events to the trial (a recording's outcome) and the message log.
    fn handle_events(&mut self, events: Vec<tremorscan::pipeline::PipelineEvent>) {
        for e in &events {
            if let tremorscan::pipeline::PipelineEvent::RecordingStopped(result) = e {
                self.trial.recording_stopped(result);
            }
        }
        self.messages.pipeline_events(events);
    }

    /// Applies the point edits of this frame.
    pub fn apply_edits(&mut self, edits: Vec<PointEdit>) {
        for edit in edits {
            match &self.source {
                Some(s) => {
                    points::apply(&mut s.tracker(), &mut self.colours, edit);
                }
                None => {
                    points::apply(&mut self.spare_tracker, &mut self.colours, edit);
                }
            }
        }
    }

    /// Exports to a known path (the dialog's answer, or a test's).
    pub fn export_to(&mut self, kind: ExportKind, path: PathBuf, ctx: &egui::Context) {
        let latest = self.source.as_ref().and_then(|s| s.latest.clone());
        let result = match kind {
            ExportKind::CloudPly => exports::export_cloud(&path, latest.as_deref()),
            ExportKind::TrackCsv => exports::export_track(&path, &self.tracker_copy()),
            ExportKind::ReportPng => exports::export_report(&path, &self.tracker_copy()),
            ExportKind::Screenshot => {
                let sender = self.screenshot_results.0.clone();
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
                    egui::ScreenshotCallback::new(move |image: Arc<egui::ColorImage>| {
                        let text = exports::save_screenshot(&path, &image)
                            .unwrap_or_else(|e| format!("error: {e:#}"));
                        let _ = sender.send(text);
                    }),
                ));
                return;
            }
        };
        match result {
            Ok(text) => self.messages.info(text),
            Err(e) => self.messages.error(format!("{e:#}")),
        }
    }

    /// One frame of the whole window.
    pub fn frame_ui(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let events = match &mut self.source {
            Some(source) => {
                source.poll();
                source.pipeline.events()
            }
            None => Vec::new(),
        };
        self.handle_events(events);
        self.drive_live_rig(&ctx);
        if let Some(source) = &self.source {
            let mut notes = Vec::new();
            self.trial.tick(source, &mut notes);
            for n in notes {
                self.messages.error(n);
            }
        }
        while let Ok(text) = self.screenshot_results.1.try_recv() {
            if text.starts_with("error:") {
                self.messages.error(text);
            } else {
                self.messages.info(text);
            }
        }
        let tracker = self.tracker_copy();
        let series = plot_ui::snapshot(&tracker, self.plot.axis, &mut |id| self.colours.colour(id));
        self.tremor.update(&series, &tracker.analysis, false);
        let latest = self.source.as_ref().and_then(|s| s.latest.clone());
        let mut edits = Vec::new();

        egui::Panel::top("toolbar").show(ui, |ui| self.toolbar_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| {
            let metrics = self.source.as_ref().map(|s| s.pipeline.metrics());
            let recording = match &self.trial.state {
                TrialState::Recording { dir, started, .. } => Some(format!(
                    "REC {:.1} s to {}",
                    started.elapsed().as_secs_f64(),
                    dir.display()
                )),
                TrialState::Countdown { .. } => Some("recording soon (countdown)".to_string()),
                TrialState::Finishing { .. } => Some("finishing the recording".to_string()),
                TrialState::Idle => None,
            };
            let device = self.source.as_ref().map_or("no device".to_string(), |s| {
                format!(
                    "{} · decode on {}",
                    s.pipeline.camera_name(),
                    s.pipeline.decoder_name()
                )
            });
            let status = Status {
                device: &device,
                metrics: metrics.as_ref(),
                tracker_dropped: self
                    .source
                    .as_ref()
                    .map_or(0, |s| s.pipeline.consumer_dropped()),
                recording,
                screen: self.live_rig.as_ref().map(LiveRig::status_line),
            };
            status_ui::status_bar_ui(ui, &status, &mut self.messages);
        });
        egui::Panel::bottom("plot")
            .resizable(true)
            .default_size(230.0)
            .show(ui, |ui| {
                self.plot.displacement_plot_ui(ui, &series);
            });
        egui::Panel::left("side")
            .resizable(true)
            .default_size(340.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    points::points_list_ui(ui, &tracker, &mut self.colours, &mut edits);
                    ui.separator();
                    let mut notes = Vec::new();
                    self.trial.trial_ui(ui, self.source.as_ref(), &mut notes);
                    for n in notes {
                        self.messages.error(n);
                    }
                    if let Some(source) = &mut self.source {
                        if source.playback.is_some() {
                            ui.separator();
                            if let Some(text) = super::replay_ui::replay_ui(ui, source) {
                                self.messages.info(text);
                            }
                        }
                    }
                });
            });
        egui::Panel::right("tremor")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                self.tremor.tremor_panel_ui(ui);
            });
        egui::CentralPanel::default().show(ui, |ui| {
            if self.source.is_none() {
                ui.colored_label(egui::Color32::from_rgb(255, 90, 90), "No device is running. See the message in the status bar; choose the virtual rig or open a session.");
            }
            ui.columns(2, |cols| {
                self.camera_view.camera_view_ui(&mut cols[0], latest.as_deref(), &tracker, &mut self.colours, &mut edits);
                self.cloud_view.cloud_view_ui(&mut cols[1], latest.as_deref(), &tracker, &mut self.colours, &mut edits);
            });
        });
        self.apply_edits(edits);
        self.wizards_ui(&ctx);
        super::settings_ui::settings_window_ui(&ctx, self);
        status_ui::message_log_ui(&ctx, &mut self.messages);
        // About 30 repaints a second: the pipeline is polled, not waited on (software rendering
        // would otherwise take the cores that decode needs).
        ctx.request_repaint_after(std::time::Duration::from_millis(33));
    }
}

impl eframe::App for TremorApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.frame_ui(ui);
    }

    fn on_exit(&mut self) {
        if let Some(source) = &self.source {
            self.trial.stop(source);
        }
        self.persist();
        // Stopping the pipeline waits for the recorder: every queued frame is written before the
        // app exits.
        if let Some(source) = self.source.take() {
            let (_, events) = source.stop();
            self.handle_events(events);
        }
    }
}
