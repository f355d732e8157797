//! The status bar (device, capture and decode rates, latency, drops per stage, recording state,
//! the newest message) and the message log. Every failure the app meets ends up here as a
//! sentence: pipeline events, files that could not be read or written, devices that failed.

use std::time::Instant;
use tremorscan::pipeline::{MetricsSnapshot, PipelineEvent};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Info,
    Error,
}

#[derive(Default)]
pub struct Messages {
    pub log: Vec<(Instant, Level, String)>,
    pub show_log: bool,
}

impl Messages {
    pub fn info(&mut self, text: impl Into<String>) {
        self.log.push((Instant::now(), Level::Info, text.into()));
    }

    pub fn error(&mut self, text: impl Into<String>) {
        self.log.push((Instant::now(), Level::Error, text.into()));
    }

    pub fn latest(&self) -> Option<&(Instant, Level, String)> {
        self.log.last()
    }

    /// Turns pipeline events into messages.
    pub fn pipeline_events(&mut self, events: Vec<PipelineEvent>) {
        for event in events {
            match event {
                PipelineEvent::SourceEnded { frames } => {
                    self.info(format!("the source ended after {frames} frames"));
                }
                PipelineEvent::SourceFailed(e) => self.error(format!("camera failed: {e}")),
                PipelineEvent::DecodeFailed(e) => self.error(format!("decode failed on a window: {e}")),
                PipelineEvent::RecordingOverrun { recorded } => self.error(format!(
                    "recording stopped: the disk could not keep up; the {recorded} frames recorded are readable"
                )),
                PipelineEvent::RecordingStopped(Ok(s)) => self.info(format!(
                    "recording finished: {} frames, {:.1} MB",
                    s.frames,
                    s.bytes as f64 / 1e6
                )),
                PipelineEvent::RecordingStopped(Err(e)) => self.error(format!(
                    "recording failed: {e}; the frames written before stay readable"
                )),
            }
        }
    }
}

/// What the status bar shows.
pub struct Status<'a> {
    pub device: &'a str,
    pub metrics: Option<&'a MetricsSnapshot>,
    pub tracker_dropped: u64,
    pub recording: Option<String>,
    /// The second screen's sync, when it is the projector.
    pub screen: Option<String>,
}

pub fn status_bar_ui(ui: &mut egui::Ui, status: &Status<'_>, messages: &mut Messages) {
    ui.horizontal(|ui| {
        ui.label(status.device);
        ui.separator();
        match status.metrics {
            Some(m) => {
                ui.label(format!("capture {:.1} FPS", m.capture_fps));
                ui.label(format!("decode {:.1} FPS", m.decode_fps));
                ui.label(format!(
                    "latency {:.1} / {:.1} ms (median / p99)",
                    m.latency_ms_median, m.latency_ms_p99
                ));
                let drops = format!(
                    "drops: source {}, decode {}, display {}, tracker {}, recorder {}",
                    m.source_lost,
                    m.decode_dropped,
                    m.display_overwritten,
                    status.tracker_dropped,
                    m.recorder_lost
                );
                ui.label(drops).on_hover_text(
                    "display drops are frames decoded faster than the window repaints; tracking still sees them",
                );
                if m.refused_windows > 0 {
                    ui.label(format!("refused windows {}", m.refused_windows))
                        .on_hover_text(
                            "windows whose frames broke the phase relation on most lit pixels (a corrupted frame): no points from them",
                        );
                }
            }
            None => {
                ui.label("no device running");
            }
        }
        ui.separator();
        if let Some(screen) = &status.screen {
            ui.label(screen);
            ui.separator();
        }
        match &status.recording {
            Some(r) => ui.colored_label(egui::Color32::RED, r),
            None => ui.label("not recording"),
        };
        ui.separator();
        if let Some((_, level, text)) = messages.latest() {
            let colour = match level {
                Level::Info => ui.visuals().text_color(),
                Level::Error => egui::Color32::from_rgb(255, 90, 90),
            };
            ui.colored_label(colour, text);
        }
        if !messages.log.is_empty() && ui.small_button("log").clicked() {
            messages.show_log = !messages.show_log;
        }
    });
}

pub fn message_log_ui(ctx: &egui::Context, messages: &mut Messages) {
    let mut open = messages.show_log;
    egui::Window::new("Messages")
        .open(&mut open)
        .show(ctx, |ui| {
            egui::ScrollArea::vertical()
                .stick_to_bottom(true)
                .show(ui, |ui| {
                    let start = messages.log.first().map(|m| m.0);
                    for (at, level, text) in &messages.log {
                        let t = start.map_or(0.0, |s| at.duration_since(s).as_secs_f64());
                        let prefix = if *level == Level::Error {
                            "error"
                        } else {
                            "info"
                        };
                        ui.label(format!("{t:7.1} s  {prefix}: {text}"));
                    }
                });
        });
    messages.show_log = open;
}
