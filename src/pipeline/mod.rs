//! The live pipeline on named threads:
//!
//! ```text
//! camera ──► "capture" ──StageQueue (newest, or lossless)──► "decode" (sliding window + triangulate)
//!               │                                                 ├──► LatestSlot  (display: newest wins)
//!               │                                                 └──► StageQueue (consumers: tracker)
//!               └──bounded channel (1 s of frames)──► "recorder" ──► frames.cpsr
//! ```
//!
//! - Capture reuses a small pool of frames (`Arc`s whose other holders have let go), stamps each
//!   with the instant it arrived, and counts frames the source lost (gaps in its numbering).
//! - Decode and triangulation share one thread: a decoder output is 188 MB at 1920×1200, handing it
//!   on would need a pool of them, and both stages already spread over all cores through rayon,
//!   in a worker pool of their own ("decode-worker-N"; the thread "decode" hands its loop to the
//!   pool, so the loop runs on one of these workers and takes part in the parallel work of each
//!   stage). In the process-wide pool they queued behind any other parallel work, such as the
//!   virtual rig rendering the next frame on the capture thread: recording the rig at 640×400
//!   for 10 s, the decode got 60 of 333 frames decoded (the others dropped, or in windows broken
//!   by drops); in its own pool, 288 of 290.
//!   Real time, the decode queue keeps the newest frames and counts drops; a replay for analysis
//!   uses [`DecodePolicy::Lossless`] and makes capture wait instead.
//! - Recording never drops silently: when the recorder's queue is full (the disk cannot keep up)
//!   the recording stops at once with [`PipelineEvent::RecordingOverrun`], the frames written
//!   stay readable, and the frames it could not take are counted.
//! - Metrics ([`metrics`]) cover every stage; events report ends and failures as messages.

pub mod metrics;
pub mod queue;

pub use metrics::{Metrics, MetricsSnapshot};
pub use queue::{LatestSlot, StageQueue};

use crate::color::CrossTalk;
use crate::decode::{CpuBackend, DecodeBackend, DecodeParams, SlidingDecoder};
use crate::device::{Camera, DeviceError};
use crate::frame::Frame;
use crate::pattern::PatternSequence;
use crate::session::record::RecordingSummary;
use crate::session::{Manifest, Recorder, SessionError, TrialJson};
use crate::triangulate::{PointCloud, StereoModel, Triangulator};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Errors of starting or controlling the pipeline.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Decode(#[from] crate::decode::DecodeError),
    #[error(transparent)]
    Triangulate(#[from] crate::triangulate::TriangulateError),
    #[error(transparent)]
    Session(#[from] SessionError),
    #[error("could not start the {name} thread: {source}")]
    Thread {
        name: &'static str,
        source: std::io::Error,
    },
    #[error("could not start the decode workers: {0}")]
    Workers(#[from] rayon::ThreadPoolBuildError),
    #[error("a recording is already running")]
    AlreadyRecording,
    #[error("the camera delivers {got:?}, the calibration is for {expected:?}")]
    SizeMismatch {
        got: (usize, usize),
        expected: (usize, usize),
    },
}

/// What the decode stage does when it falls behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodePolicy {
    /// Keep the newest frames, drop (and count) the oldest waiting ones.
    RealTime,
    /// Make capture wait: nothing is dropped (replays for analysis).
    Lossless,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineConfig {
    pub decode_policy: DecodePolicy,
    /// Frames waiting for decode at most.
    pub decode_queue: usize,
    /// Frames waiting for the disk at most before a recording is declared overrun.
    pub recorder_queue: usize,
    /// Clouds kept for [`Pipeline::next_for_consumer`] (0: no consumer queue). Each holds a
    /// full cloud (44 MB at 1920×1200), so keep it small; beyond it the oldest are dropped.
    pub consumer_queue: usize,
    /// Publish every result to the display slot ([`Pipeline::latest`]); headless runs turn it
    /// off so no display drops are counted.
    pub display: bool,
    pub decode_params: DecodeParams,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            decode_policy: DecodePolicy::RealTime,
            decode_queue: 3,
            recorder_queue: 121,
            consumer_queue: 0,
            display: true,
            decode_params: DecodeParams::default(),
        }
    }
}

/// A captured frame with the instant it arrived.
#[derive(Debug, Clone)]
pub struct CapturedFrame {
    pub frame: Frame,
    pub sequence_number: u64,
    pub arrived: Instant,
}

/// The decoder keeps captured frames in its window without copying them.
impl std::borrow::Borrow<Frame> for CapturedFrame {
    fn borrow(&self) -> &Frame {
        &self.frame
    }
}

/// One decoded, triangulated window.
#[derive(Debug, Clone)]
pub struct CloudFrame {
    pub cloud: PointCloud,
    /// The window's last camera frame as captured (for the live image), shared with capture
    /// rather than copied, when the pipeline publishes to a display; otherwise `None`.
    pub camera: Option<Arc<CapturedFrame>>,
    /// Projector coordinate per pixel, projector px, NaN where invalid (the unwrapped phase
    /// in projector units), when publishing to a display; otherwise empty.
    pub projector_px: Vec<f32>,
    /// Source number of the window's last frame.
    pub window_end: u64,
    /// From the arrival of the window's last frame to publication.
    pub latency: Duration,
}

/// Something the user should hear about.
#[derive(Debug, Clone, PartialEq)]
pub enum PipelineEvent {
    SourceEnded {
        frames: u64,
    },
    SourceFailed(String),
    DecodeFailed(String),
    /// The disk could not keep up: the recording stopped after `recorded` frames.
    RecordingOverrun {
        recorded: u64,
    },
    /// A recording ended (stopped, overrun or failed): what it holds, or why it failed.
    RecordingStopped(Result<RecordingSummary, String>),
}

struct RecorderLink {
    sender: SyncSender<Arc<CapturedFrame>>,
    handle: JoinHandle<Result<RecordingSummary, SessionError>>,
}

/// State shared by the threads and the handle.
struct Shared {
    stop: AtomicBool,
    metrics: Metrics,
    latest: LatestSlot<Arc<CloudFrame>>,
    consumers: Option<Arc<StageQueue<Arc<CloudFrame>>>>,
    recorder: Mutex<Option<RecorderLink>>,
    /// Recorders stopped by an overrun, still writing what they hold.
    draining: Mutex<Vec<JoinHandle<Result<RecordingSummary, SessionError>>>>,
    events: Mutex<Vec<PipelineEvent>>,
    /// What runs the decode; the decode thread updates it when a backend changes (a GPU that
    /// failed hands over to the CPU).
    decoder_name: Mutex<String>,
}

impl Shared {
    fn event(&self, e: PipelineEvent) {
        self.events
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(e);
    }
}

/// A running pipeline.
pub struct Pipeline {
    shared: Arc<Shared>,
    config: PipelineConfig,
    threads: Vec<JoinHandle<()>>,
    camera_name: String,
    frames_averaged: usize,
}

mod stages;

impl Pipeline {
    /// Starts capture and decode for `camera`, which shows `sequence` through a rig of
    /// `stereo` calibration and `cross_talk`; the decode runs on the CPU.
    pub fn start(
        camera: Box<dyn Camera>,
        sequence: PatternSequence,
        cross_talk: CrossTalk,
        stereo: StereoModel,
        config: PipelineConfig,
    ) -> Result<Self, PipelineError> {
        Self::start_with_backend(
            camera,
            sequence,
            cross_talk,
            stereo,
            config,
            Box::new(CpuBackend),
        )
    }

    /// [`Pipeline::start`] with the decode on `backend` (a GPU).
    pub fn start_with_backend(
        camera: Box<dyn Camera>,
        sequence: PatternSequence,
        cross_talk: CrossTalk,
        stereo: StereoModel,
        config: PipelineConfig,
        backend: Box<dyn DecodeBackend>,
    ) -> Result<Self, PipelineError> {
        let expected = (stereo.camera.width, stereo.camera.height);
        if camera.size() != expected {
            return Err(PipelineError::SizeMismatch {
                got: camera.size(),
                expected,
            });
        }
        let camera_name = camera.name();
        let frames_averaged = crate::decode::frames_averaged(&sequence, &config.decode_params);
        // A window must not span a lost frame: the scene moves between them.
        let window = sequence.entries.len() as f64;
        let max_span_s = (window - 0.5) / camera.fps().max(1e-3);
        let decoder = SlidingDecoder::new(sequence, cross_talk, config.decode_params)?
            .with_max_span(max_span_s)
            .with_backend(backend);
        let workers = rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("decode-worker-{i}"))
            .build()?;
        let triangulator = workers.install(|| Triangulator::new(stereo))?;
        // Named inside the pool: the CPU backend counts the threads it runs on.
        let (decoder, decoder_name) = workers.install(move || {
            let name = decoder.backend_name();
            (decoder, name)
        });
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            metrics: Metrics::default(),
            latest: LatestSlot::default(),
            consumers: (config.consumer_queue > 0)
                .then(|| Arc::new(StageQueue::new(config.consumer_queue))),
            recorder: Mutex::new(None),
            draining: Mutex::new(Vec::new()),
            events: Mutex::new(Vec::new()),
            decoder_name: Mutex::new(decoder_name),
        });
        let decode_queue = Arc::new(StageQueue::new(config.decode_queue));
        let spawn = |name: &'static str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.to_string())
                .spawn(f)
                .map_err(|source| PipelineError::Thread { name, source })
        };
        let decode = {
            let (shared, queue) = (Arc::clone(&shared), Arc::clone(&decode_queue));
            spawn(
                "decode",
                Box::new(move || {
                    workers.install(|| {
                        stages::decode_loop(
                            &shared,
                            &queue,
                            decoder,
                            &triangulator,
                            config.display,
                        );
                    });
                }),
            )?
        };
        let capture = {
            let (shared, queue) = (Arc::clone(&shared), Arc::clone(&decode_queue));
            let policy = config.decode_policy;
            spawn(
                "capture",
                Box::new(move || stages::capture_loop(&shared, &queue, camera, policy)),
            )
        };
        let capture = match capture {
            Ok(capture) => capture,
            Err(e) => {
                // Let the decode thread see the end instead of waiting for frames forever.
                decode_queue.close();
                let _ = decode.join();
                return Err(e);
            }
        };
        Ok(Self {
            shared,
            config,
            threads: vec![capture, decode],
            camera_name,
            frames_averaged,
        })
    }

    pub fn camera_name(&self) -> &str {
        &self.camera_name
    }

    /// How many frames each decoded coordinate averages ([`crate::decode::frames_averaged`]),
    /// for the tremor analysis of what this pipeline measures.
    pub fn frames_averaged(&self) -> usize {
        self.frames_averaged
    }

    /// What runs the decode now ("CPU (AVX-512, 2 threads)", or the GPU's name).
    pub fn decoder_name(&self) -> String {
        self.shared
            .decoder_name
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    pub fn metrics(&self) -> MetricsSnapshot {
        self.shared.metrics.snapshot()
    }

    /// The newest cloud not yet taken, for a display.
    pub fn latest(&self) -> Option<Arc<CloudFrame>> {
        self.shared.latest.take()
    }

    /// Every cloud, in order, for a consumer such as the tracker, waiting for the next; `None`
    /// when the pipeline has ended or was started without a consumer queue. Beyond
    /// `consumer_queue` waiting clouds the oldest are dropped ([`Self::consumer_dropped`]).
    pub fn next_for_consumer(&self) -> Option<Arc<CloudFrame>> {
        self.shared.consumers.as_ref()?.pop()
    }

    pub fn consumer_dropped(&self) -> u64 {
        self.shared.consumers.as_ref().map_or(0, |q| q.dropped())
    }

    /// The consumer queue itself, for a consumer on its own thread (the GUI's tracker): it
    /// outlives the pipeline handle and ends (`pop` gives `None`) when the pipeline stops.
    pub fn consumer_queue(&self) -> Option<Arc<StageQueue<Arc<CloudFrame>>>> {
        self.shared.consumers.clone()
    }

    /// Drains the events so far.
    pub fn events(&self) -> Vec<PipelineEvent> {
        std::mem::take(
            &mut *self
                .shared
                .events
                .lock()
                .unwrap_or_else(PoisonError::into_inner),
        )
    }

    /// Whether the capture and decode threads still run.
    pub fn is_running(&self) -> bool {
        self.threads.iter().any(|t| !t.is_finished())
    }

    /// Starts recording every captured frame into a new session folder `dir`.
    pub fn start_recording(
        &self,
        dir: &Path,
        manifest: Manifest,
        trial: TrialJson,
    ) -> Result<(), PipelineError> {
        let mut slot = self
            .shared
            .recorder
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if slot.is_some() {
            return Err(PipelineError::AlreadyRecording);
        }
        let recorder = Recorder::create(dir, manifest, trial)?;
        let (sender, receiver) = sync_channel::<Arc<CapturedFrame>>(self.config.recorder_queue);
        let shared = Arc::clone(&self.shared);
        let handle = std::thread::Builder::new()
            .name("recorder".to_string())
            .spawn(move || stages::record_loop(&shared, recorder, &receiver))
            .map_err(|source| PipelineError::Thread {
                name: "recorder",
                source,
            })?;
        *slot = Some(RecorderLink { sender, handle });
        Ok(())
    }

    /// Stops the recording (if any), waiting for every queued frame to be written. The result
    /// is also reported as [`PipelineEvent::RecordingStopped`].
    pub fn stop_recording(&self) -> Option<Result<RecordingSummary, String>> {
        let link = self
            .shared
            .recorder
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take()?;
        Some(stages::finish_recording(link))
    }

    /// Ends the recording without waiting for the disk: the recorder writes every frame it
    /// holds on its own thread and reports the outcome as [`PipelineEvent::RecordingStopped`]
    /// (a GUI stays responsive meanwhile). Returns whether a recording was running.
    pub fn end_recording(&self) -> bool {
        let link = self
            .shared
            .recorder
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        match link {
            Some(link) => {
                stash(&self.shared, link);
                true
            }
            None => false,
        }
    }

    pub fn is_recording(&self) -> bool {
        self.shared
            .recorder
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .is_some()
    }

    /// Waits until the source ends (a replay) or `timeout` passes; true if it ended.
    pub fn wait_for_end(&self, timeout: Duration) -> bool {
        let start = Instant::now();
        while self.is_running() {
            if start.elapsed() > timeout {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        true
    }

    /// Stops capture, lets decode finish what is queued, ends any recording, joins every thread.
    pub fn stop(mut self) -> MetricsSnapshot {
        self.shutdown();
        self.metrics()
    }

    /// Like [`Self::stop`], and also hands back the events not yet taken: the outcome of a
    /// recording that was still being written is among them.
    pub fn stop_with_events(mut self) -> (MetricsSnapshot, Vec<PipelineEvent>) {
        self.shutdown();
        (self.metrics(), self.events())
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            if t.join().is_err() {
                self.shared.event(PipelineEvent::DecodeFailed(
                    "a pipeline thread panicked".to_string(),
                ));
            }
        }
        self.stop_recording();
        let draining = std::mem::take(
            &mut *self
                .shared
                .draining
                .lock()
                .unwrap_or_else(PoisonError::into_inner),
        );
        for handle in draining {
            // Its result was reported as an event by the recorder thread itself.
            let _ = handle.join();
        }
        if let Some(c) = &self.shared.consumers {
            c.close();
        }
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Whether a device error ends the stream normally.
fn is_end(e: &DeviceError) -> bool {
    matches!(e, DeviceError::EndOfStream { .. })
}

/// Tries to hand a frame to the recorder; on overrun or a dead recorder the recording stops.
fn offer_to_recorder(shared: &Shared, frame: &Arc<CapturedFrame>) {
    let mut slot = shared
        .recorder
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    let Some(link) = slot.as_ref() else {
        return;
    };
    match link.sender.try_send(Arc::clone(frame)) {
        Ok(()) => {}
        Err(TrySendError::Full(_)) => {
            // The disk cannot keep up: stop now, let the recorder write what it holds.
            shared.metrics.recorder_lost(1);
            if let Some(link) = slot.take() {
                shared.event(PipelineEvent::RecordingOverrun {
                    recorded: shared.metrics.snapshot().recorded,
                });
                stash(shared, link);
            }
        }
        Err(TrySendError::Disconnected(_)) => {
            // The recorder stopped on an error (it reported it).
            shared.metrics.recorder_lost(1);
            if let Some(link) = slot.take() {
                stash(shared, link);
            }
        }
    }
}

/// Closes a recorder's queue and keeps its thread to be joined later, so capture never waits
/// for the disk.
fn stash(shared: &Shared, link: RecorderLink) {
    let RecorderLink { sender, handle } = link;
    drop(sender);
    shared
        .draining
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .push(handle);
}
