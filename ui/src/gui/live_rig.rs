//! A real rig: a camera (GenICam, feature `genicam`) with a second screen as the projector.
//!
//! Starting takes a few seconds and never blocks the window:
//!
//! ```text
//! begin ─► screen shows the flash code ─┬─► "screen-sync" thread grabs frames (arrival, brightness)
//!          (viewport, every pass)       └─► flash over: thread returns the camera and samples
//!       ─► estimate_delay ─► SyncedCamera ─► Pipeline (real time) ─► Source; screen shows patterns
//! ```
//!
//! A camera that does not see the screen, a missing calibration or a missing camera ends the
//! start with a message; the window keeps running without a device.

use super::projector_screen::ProjectorScreen;
use super::settings::Settings;
use super::source::{live_pipeline_config, sequence_of, Source};
use crate::gpu_decode::{start_pipeline, DecoderChoice};
use anyhow::{anyhow, Context, Result};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, PoisonError};
use std::thread::JoinHandle;
use tremorscan::calibrate::file::{CalibrationFile, ColourFile};
use tremorscan::color::CrossTalk;
use tremorscan::device::screen_sync::{estimate_delay, host_time_s, DelayEstimate};
use tremorscan::device::synced_camera::{SyncMode, SyncStats, SyncedCamera};
use tremorscan::device::Camera;
use tremorscan::frame::Frame;
use tremorscan::pattern::PatternSequence;
use tremorscan::session::Manifest;
use tremorscan::tremor::LiveTracker;
use tremorscan::triangulate::StereoModel;

/// Longest display + camera delay searched for, s.
const MAX_DELAY_S: f64 = 0.25;
/// Jitter allowance around each exposure, s (a frame handed to a compositor lands within about
/// a millisecond of its refresh).
const GUARD_S: f64 = 1.0e-3;

/// Everything a real rig needs besides the camera: from the calibration files.
pub struct RigParts {
    pub sequence: PatternSequence,
    pub cross_talk: CrossTalk,
    pub stereo: StereoModel,
    pub manifest: Manifest,
    /// Projector (screen) image size, pixels.
    pub projector_size: (usize, usize),
    pub exposure_s: f64,
    /// Where the decode runs.
    pub decoder: DecoderChoice,
}

impl RigParts {
    /// From the settings' calibration files (both required for a real rig).
    pub fn from_settings(settings: &Settings, exposure_s: f64) -> Result<Self> {
        let geometric = settings.calibration_file.as_ref().ok_or_else(|| {
            anyhow!("a real rig needs its geometric calibration: choose a calibration file in Settings (the geometric wizard or `tremorscan import-calibration` makes one)")
        })?;
        let colour = settings.colour_file.as_ref().ok_or_else(|| {
            anyhow!("a real rig needs its colour calibration: choose a colour file in Settings (the colour wizard makes one)")
        })?;
        let (_, calibration) = CalibrationFile::load(geometric)
            .with_context(|| format!("calibration {}", geometric.display()))?;
        let (_, cross_talk) = ColourFile::load(colour)
            .with_context(|| format!("colour calibration {}", colour.display()))?;
        let projector_size = (calibration.projector.width, calibration.projector.height);
        let sequence = sequence_of(settings, projector_size)?;
        let stereo = StereoModel {
            camera: calibration.camera,
            projector: calibration.projector,
            projector_from_camera: calibration.projector_from_camera,
            axis: sequence.axis,
        };
        let manifest = Manifest::for_rig(&sequence, &cross_talk, &stereo);
        Ok(Self {
            sequence,
            cross_talk,
            stereo,
            manifest,
            projector_size,
            exposure_s,
            decoder: settings.decoder,
        })
    }
}

/// How the screen runs and frames are labelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenPlan {
    pub monitor: usize,
    pub hold_refreshes: u32,
    pub sync: SyncMode,
    /// Pack images for a LightCrafter's video input at this bit depth.
    pub packed_bits: Option<u8>,
}

impl ScreenPlan {
    /// A plain screen: a free-running camera, each pattern held `hold_refreshes`.
    pub fn second_screen(monitor: usize, hold_refreshes: u32) -> Self {
        Self {
            monitor,
            hold_refreshes,
            sync: SyncMode::FreeRunning,
            packed_bits: None,
        }
    }

    /// A LightCrafter on the screen output: one packed image per refresh, the camera triggered
    /// by the projector once per image.
    pub fn lightcrafter(monitor: usize, bits: u8) -> Self {
        Self {
            monitor,
            hold_refreshes: 1,
            sync: SyncMode::Triggered { pattern_count: 3 },
            packed_bits: Some(bits),
        }
    }
}

type SyncResult = std::result::Result<(Box<dyn Camera>, Vec<(f64, f64)>), String>;

enum RigState {
    Syncing {
        flash_over: Arc<AtomicBool>,
        thread: Option<JoinHandle<SyncResult>>,
    },
    Running {
        stats: Arc<SyncStats>,
        delay: DelayEstimate,
        since: std::time::Instant,
    },
    Stopped,
}

pub struct LiveRig {
    pub screen: ProjectorScreen,
    parts: Option<RigParts>,
    sync: SyncMode,
    state: RigState,
}

impl LiveRig {
    /// Starts the sync of `camera` with a screen showing `parts.sequence` as `plan` says.
    pub fn begin(camera: Box<dyn Camera>, parts: RigParts, plan: ScreenPlan) -> Result<Self> {
        let screen = ProjectorScreen::new(
            &parts.sequence,
            parts.projector_size,
            plan.monitor,
            plan.hold_refreshes,
            plan.packed_bits,
        )?;
        let flash_over = Arc::new(AtomicBool::new(false));
        let over = Arc::clone(&flash_over);
        let thread = std::thread::Builder::new()
            .name("screen-sync".to_string())
            .spawn(move || watch_flash(camera, &over))
            .context("starting the screen-sync thread")?;
        Ok(Self {
            screen,
            parts: Some(parts),
            sync: plan.sync,
            state: RigState::Syncing {
                flash_over,
                thread: Some(thread),
            },
        })
    }

    /// One pass: shows the screen and moves the start along. Returns the running source once
    /// synced, or why the start failed.
    pub fn drive(&mut self, ctx: &egui::Context, tracker: LiveTracker) -> Option<Result<Source>> {
        self.screen.viewport_ui(ctx);
        let RigState::Syncing { flash_over, thread } = &mut self.state else {
            return None;
        };
        if self.screen.flash_done() {
            flash_over.store(true, Ordering::SeqCst);
        }
        if !thread.as_ref().is_some_and(JoinHandle::is_finished) {
            return None;
        }
        let joined = thread.take().map(|t| {
            t.join()
                .unwrap_or_else(|_| Err("the screen-sync thread failed".into()))
        });
        let result = self.finish(joined, tracker);
        if result.is_err() {
            self.state = RigState::Stopped;
        }
        Some(result)
    }

    fn finish(&mut self, joined: Option<SyncResult>, tracker: LiveTracker) -> Result<Source> {
        let (camera, samples) = joined
            .ok_or_else(|| anyhow!("the sync ended twice"))?
            .map_err(|e| anyhow!(e))?;
        let parts = self
            .parts
            .take()
            .ok_or_else(|| anyhow!("the rig started twice"))?;
        let delay = {
            let schedule = self
                .screen
                .schedule
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            estimate_delay(&schedule, &samples, parts.exposure_s, MAX_DELAY_S)
                .context("measuring the screen's delay")?
        };
        let camera_fps = camera.fps();
        let synced = SyncedCamera::new(
            camera,
            Arc::clone(&self.screen.schedule),
            self.sync,
            delay,
            parts.exposure_s,
            GUARD_S,
        );
        let stats = synced.stats();
        self.screen.show_patterns();
        let (pipeline, _) = start_pipeline(
            parts.decoder,
            Box::new(synced),
            parts.sequence,
            parts.cross_talk,
            parts.stereo,
            live_pipeline_config(),
        )
        .context("starting the camera pipeline")?;
        self.state = RigState::Running {
            stats,
            delay,
            since: std::time::Instant::now(),
        };
        Source::with_pipeline(
            pipeline,
            Some(parts.manifest),
            None,
            None,
            camera_fps,
            tracker,
        )
    }

    /// The sync's state for the status bar, honest about the rate achieved.
    pub fn status_line(&self) -> String {
        match &self.state {
            RigState::Syncing { .. } => {
                "second screen: measuring the delay (flash code on screen)…".to_string()
            }
            RigState::Running {
                stats,
                delay,
                since,
            } => {
                // Measured rates since the patterns started, not the camera's nominal one.
                let delivered = stats.delivered.load(Ordering::Relaxed);
                let uncertain = stats.uncertain.load(Ordering::Relaxed);
                let elapsed_s = since.elapsed().as_secs_f64().max(1e-3);
                let phase = match self.sync {
                    SyncMode::FreeRunning => "",
                    SyncMode::Triggered { .. } if stats.locked.load(Ordering::Relaxed) => {
                        "phase locked, "
                    }
                    SyncMode::Triggered { .. } => "finding the phase, ",
                };
                format!(
                    "second screen: {phase}delay {:.1} ± {:.1} ms, {:.1} of {:.1} FPS kept, {} uncertain frames dropped, patterns {:.1}/s",
                    delay.delay_s * 1e3,
                    delay.uncertainty_s * 1e3,
                    delivered as f64 / elapsed_s,
                    (delivered + uncertain) as f64 / elapsed_s,
                    uncertain,
                    self.screen.pattern_rate_hz()
                )
            }
            RigState::Stopped => "second screen: stopped".to_string(),
        }
    }
}

impl Drop for LiveRig {
    fn drop(&mut self) {
        // A sync in progress: let its thread hand the camera back and end.
        if let RigState::Syncing { flash_over, .. } = &self.state {
            flash_over.store(true, Ordering::SeqCst);
        }
    }
}

/// The "screen-sync" thread: grabs frames until the flash code is over, noting each frame's
/// arrival (host time) and mean brightness, then hands the camera back.
fn watch_flash(mut camera: Box<dyn Camera>, over: &AtomicBool) -> SyncResult {
    let mut samples = Vec::new();
    let mut frame = Frame::empty();
    while !over.load(Ordering::SeqCst) {
        match camera.grab(&mut frame) {
            Ok(_) => {
                let arrival = host_time_s();
                let sum: u64 = frame.data.iter().map(|&v| u64::from(v)).sum();
                let mean = sum as f64 / frame.data.len().max(1) as f64 / 255.0;
                samples.push((arrival, mean));
            }
            Err(tremorscan::device::DeviceError::Idle) => {}
            Err(e) => return Err(format!("the camera failed while syncing: {e}")),
        }
    }
    Ok((camera, samples))
}
