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
use super::settings::{DeviceChoice, Settings};
use super::source::{live_pipeline_config, sequence_of, Source};
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
use tremorscan::pipeline::Pipeline;
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
        })
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
        camera_fps: f64,
    },
    Stopped,
}

pub struct LiveRig {
    pub screen: ProjectorScreen,
    parts: Option<RigParts>,
    state: RigState,
}

/// Opens the camera of `choice`.
#[cfg(feature = "genicam")]
pub fn open_camera(choice: &DeviceChoice) -> Result<Box<dyn Camera>> {
    use tremorscan::device::genicam::{list_cameras, GenicamCamera, GenicamSettings};
    let DeviceChoice::Camera {
        camera_id,
        exposure_micros,
        ..
    } = choice
    else {
        return Err(anyhow!("not a camera device"));
    };
    let id = if camera_id.trim().is_empty() {
        list_cameras()
            .first()
            .map(|c| c.id.clone())
            .ok_or_else(|| anyhow!("no GenICam camera found: check its cable and power"))?
    } else {
        camera_id.trim().to_string()
    };
    let settings = GenicamSettings {
        exposure_micros: Some(*exposure_micros),
        ..GenicamSettings::default()
    };
    Ok(Box::new(GenicamCamera::open(&id, &settings)?))
}

/// Without the `genicam` feature there is no camera to open.
#[cfg(not(feature = "genicam"))]
pub fn open_camera(_choice: &DeviceChoice) -> Result<Box<dyn Camera>> {
    Err(anyhow!(
        "this build has no GenICam camera support: build with `--features genicam` (the .deb has it)"
    ))
}

impl LiveRig {
    /// Starts the sync of `camera` with a screen on `monitor` showing `parts.sequence`.
    pub fn begin(
        camera: Box<dyn Camera>,
        parts: RigParts,
        monitor: usize,
        hold_refreshes: u32,
    ) -> Result<Self> {
        let screen = ProjectorScreen::new(
            &parts.sequence,
            parts.projector_size,
            monitor,
            hold_refreshes,
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
            SyncMode::FreeRunning,
            delay,
            parts.exposure_s,
            GUARD_S,
        );
        let stats = synced.stats();
        self.screen.show_patterns();
        let pipeline = Pipeline::start(
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
            camera_fps,
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
                camera_fps,
            } => {
                let delivered = stats.delivered.load(Ordering::Relaxed);
                let uncertain = stats.uncertain.load(Ordering::Relaxed);
                let kept = delivered as f64 / (delivered + uncertain).max(1) as f64;
                format!(
                    "second screen: delay {:.1} ± {:.1} ms, {:.1} of {:.1} FPS kept, {} uncertain frames dropped, patterns {:.1}/s",
                    delay.delay_s * 1e3,
                    delay.uncertainty_s * 1e3,
                    kept * camera_fps,
                    camera_fps,
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

/// Starts the rig of `settings` (a camera device).
pub fn begin_from_settings(settings: &Settings) -> Result<LiveRig> {
    let DeviceChoice::Camera {
        exposure_micros,
        monitor,
        hold_refreshes,
        ..
    } = &settings.device
    else {
        return Err(anyhow!("the device is not a camera"));
    };
    let parts = RigParts::from_settings(settings, exposure_micros * 1e-6)?;
    let camera = open_camera(&settings.device)?;
    if camera.size() != (parts.stereo.camera.width, parts.stereo.camera.height) {
        return Err(anyhow!(
            "the camera delivers {}×{} but the calibration is for {}×{}",
            camera.size().0,
            camera.size().1,
            parts.stereo.camera.width,
            parts.stereo.camera.height
        ));
    }
    LiveRig::begin(camera, parts, *monitor, *hold_refreshes)
}
