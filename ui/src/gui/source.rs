//! The running measurement behind the window: a pipeline on the chosen device and a tracker
//! thread that measures every control point in every cloud.
//!
//! ```text
//! device ─► Pipeline ("capture", "decode") ─┬─► latest cloud (display, newest wins)
//!                                           └─► consumer queue ─► "tracker" ─► LiveTracker (Mutex)
//! ```
//!
//! The tracker runs on its own named thread so a slow window (software rendering draws a few
//! frames a second) never costs a tracked sample: the consumer queue holds a few clouds (the
//! tracker needs well under a millisecond for each) and counts what it drops, shown in the
//! status bar.

use super::settings::{DeviceChoice, Settings};
use crate::gpu_decode::start_pipeline;
use anyhow::{Context, Result};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use tremorscan::calibrate::file::{CalibrationFile, ColourFile};
use tremorscan::device::{Pacing, PlaybackCamera, PlaybackControl, VirtualCamera};
use tremorscan::pattern::{cps_rgb, Axis, PatternSequence};
use tremorscan::pipeline::{CloudFrame, DecodePolicy, Pipeline, PipelineConfig, PipelineEvent};
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan::session::{Manifest, Session, SessionDecoding};
use tremorscan::tremor::LiveTracker;

/// Seconds of displacement history kept per control point.
pub const HISTORY_S: f64 = 5.0;

/// Clouds waiting for the tracker at most. Tracking takes well under a millisecond per cloud, so
/// the queue only fills while the window holds the tracker's lock; each cloud can be 60 MB at
/// 1920×1200, so it stays short.
const TRACKER_QUEUE: usize = 8;

/// What is measuring.
pub struct Source {
    pub pipeline: Pipeline,
    pub tracker: Arc<Mutex<LiveTracker>>,
    tracker_thread: Option<JoinHandle<()>>,
    /// The manifest a recording from this source starts from (live devices only).
    pub recording_manifest: Option<Manifest>,
    /// Replay controls, for a replayed session.
    pub playback: Option<Arc<PlaybackControl>>,
    /// The replayed session (control points are saved into it).
    pub session: Option<Session>,
    /// The newest cloud shown.
    pub latest: Option<Arc<CloudFrame>>,
    pub nominal_fps: f64,
    /// How a replayed session is decoded (method and noise, with where each comes from).
    pub decode_note: Option<String>,
}

/// The CPS-RGB sequence the settings ask for, on a projector of `projector_size`.
pub fn sequence_of(settings: &Settings, projector_size: (usize, usize)) -> Result<PatternSequence> {
    let (axis, x_max) = if settings.code_columns {
        (Axis::Columns, projector_size.0 as f64)
    } else {
        (Axis::Rows, projector_size.1 as f64)
    };
    cps_rgb(settings.fringe_count, x_max, axis, settings.projector_bits)
        .context("pattern parameters")
}

/// The virtual rig the settings describe.
pub fn virtual_rig(settings: &Settings) -> Result<VirtualRig> {
    let mut config =
        RigConfig::paper(settings.rig_width, settings.rig_height).context("virtual rig size")?;
    if let Some(tremor) = config.scene.hand.as_mut() {
        // A hand-edited settings file may hold anything: negative or non-finite values are
        // refused with the field's name.
        for (name, value) in [
            ("rig_tip_amplitude_mm", settings.rig_tip_amplitude_mm),
            ("rig_sway_mm", settings.rig_sway_mm),
            ("rig_roll_deg", settings.rig_roll_deg),
        ] {
            anyhow::ensure!(
                value.is_finite() && value >= 0.0,
                "virtual hand: {name} = {value} is not a peak amplitude (≥ 0)"
            );
        }
        tremor.tip_amplitude_mm = settings.rig_tip_amplitude_mm;
        tremor.sway_amplitude_mm = settings.rig_sway_mm;
        tremor.roll_amplitude_deg = settings.rig_roll_deg;
    }
    let sequence = sequence_of(settings, (config.projector.width, config.projector.height))?;
    VirtualRig::new(config, sequence).context("virtual rig")
}

/// The pipeline of a real camera: real time (the newest frame wins, drops are counted), with the
/// tracker's queue.
pub fn live_pipeline_config() -> PipelineConfig {
    PipelineConfig {
        decode_policy: DecodePolicy::RealTime,
        consumer_queue: TRACKER_QUEUE,
        ..PipelineConfig::default()
    }
}

impl Source {
    /// Starts the device of `settings` with its tracker, keeping the points of `tracker`.
    pub fn start(settings: &Settings, tracker: LiveTracker) -> Result<Self> {
        // Simulated and recorded sources have no real time to keep: capture waits for decode, so
        // every window is decoded and the tremor is sampled at the full scene rate (a slower PC
        // plays them in slow motion, shown by the status bar's rates). A real camera uses
        // `DecodePolicy::RealTime`.
        // One frame waiting is enough to keep capture and decode both busy; more only adds latency.
        let mut config = PipelineConfig {
            decode_policy: DecodePolicy::Lossless,
            decode_queue: 1,
            consumer_queue: TRACKER_QUEUE,
            decode_params: settings.decode_params(),
            ..PipelineConfig::default()
        };
        let mut decode_note = None;
        let (pipeline, recording_manifest, playback, session, nominal_fps) = match &settings.device
        {
            DeviceChoice::VirtualRig => {
                let rig = virtual_rig(settings)?;
                let mut cross_talk = rig.config.cross_talk;
                let mut stereo = rig.stereo_model();
                if let Some(path) = &settings.colour_file {
                    cross_talk = ColourFile::load(path)
                        .with_context(|| format!("colour calibration {}", path.display()))?
                        .1;
                }
                if let Some(path) = &settings.calibration_file {
                    let (_, c) = CalibrationFile::load(path)
                        .with_context(|| format!("calibration {}", path.display()))?;
                    stereo.camera = c.camera;
                    stereo.projector = c.projector;
                    stereo.projector_from_camera = c.projector_from_camera;
                }
                let mut manifest = rig.session_manifest();
                manifest.color = Some(tremorscan::session::manifest::ColorJson::from_cross_talk(
                    &cross_talk,
                ));
                let fps = rig.config.fps;
                let sequence = rig.sequence.clone();
                let camera = VirtualCamera::new(rig, Pacing::Recorded);
                let (pipeline, _) = start_pipeline(
                    settings.decoder,
                    Box::new(camera),
                    sequence,
                    cross_talk,
                    stereo,
                    config,
                )
                .context("starting the virtual rig")?;
                (pipeline, Some(manifest), None, None, fps)
            }
            DeviceChoice::Replay { session } => {
                let opened = Session::open(session)
                    .with_context(|| format!("opening session {}", session.display()))?;
                let sequence = opened.sequence()?;
                // A replay follows the session: the Settings' method where the sequence takes
                // it, else the sequence's own; the camera noise the session states or shows.
                let requested =
                    Some(settings.unwrap.method()).filter(|m| m.check(&sequence).is_ok());
                let decoding = SessionDecoding::new(&opened, requested, config.decode_params)
                    .with_context(|| format!("choosing how to decode {}", session.display()))?;
                config.decode_params = decoding.params;
                decode_note = Some(format!("replay: {}", decoding.describe()));
                let cross_talk = opened
                    .cross_talk()?
                    .unwrap_or_else(tremorscan::color::CrossTalk::identity);
                let stereo = opened.stereo_model()?;
                let kept = opened.clone();
                let (camera, control) = PlaybackCamera::new(opened);
                let fps = tremorscan::device::Camera::fps(&camera);
                let (pipeline, _) = start_pipeline(
                    settings.decoder,
                    Box::new(camera),
                    sequence,
                    cross_talk,
                    stereo,
                    config,
                )
                .context("starting the replay")?;
                (pipeline, None, Some(control), Some(kept), fps)
            }
            DeviceChoice::Camera { .. } => {
                anyhow::bail!(
                    "a camera starts through the live rig (it syncs with the screen first)"
                )
            }
        };
        let mut source = Self::with_pipeline(
            pipeline,
            recording_manifest,
            playback,
            session,
            nominal_fps,
            tracker,
        )?;
        source.decode_note = decode_note;
        Ok(source)
    }

    /// A running pipeline with its tracker thread.
    pub fn with_pipeline(
        pipeline: Pipeline,
        recording_manifest: Option<Manifest>,
        playback: Option<Arc<PlaybackControl>>,
        session: Option<Session>,
        nominal_fps: f64,
        mut tracker: LiveTracker,
    ) -> Result<Self> {
        tracker.analysis.window_frames = pipeline.frames_averaged();
        let tracker = Arc::new(Mutex::new(tracker));
        let tracker_thread = match pipeline.consumer_queue() {
            Some(queue) => {
                let tracker = Arc::clone(&tracker);
                Some(
                    std::thread::Builder::new()
                        .name("tracker".to_string())
                        .spawn(move || {
                            while let Some(cloud) = queue.pop() {
                                tracker
                                    .lock()
                                    .unwrap_or_else(PoisonError::into_inner)
                                    .update(&cloud.cloud, cloud.window_end as usize);
                            }
                        })
                        .context("starting the tracker thread")?,
                )
            }
            None => None,
        };
        Ok(Self {
            pipeline,
            tracker,
            tracker_thread,
            recording_manifest,
            playback,
            session,
            latest: None,
            nominal_fps,
            decode_note: None,
        })
    }

    /// Takes the newest cloud, if a new one arrived; returns whether it did.
    pub fn poll(&mut self) -> bool {
        match self.pipeline.latest() {
            Some(cloud) => {
                self.latest = Some(cloud);
                true
            }
            None => false,
        }
    }

    /// Locks the tracker (a poisoned lock only means the tracker thread panicked mid-update;
    /// the histories are still usable).
    pub fn tracker(&self) -> std::sync::MutexGuard<'_, LiveTracker> {
        self.tracker.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Stops everything (a recording still being written is finished first) and hands back the
    /// tracker (its points carry over to the next source) and the last events.
    pub fn stop(mut self) -> (LiveTracker, Vec<PipelineEvent>) {
        // Stopping the pipeline joins its threads and closes the consumer queue.
        let (_, events) = self.pipeline.stop_with_events();
        if let Some(t) = self.tracker_thread.take() {
            let _ = t.join();
        }
        let tracker = self.tracker.lock().unwrap_or_else(PoisonError::into_inner);
        (tracker.clone(), events)
    }
}
