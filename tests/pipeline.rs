//! The threaded pipeline: a lossless replay decodes every window; a real-time one that cannot keep
//! up drops and counts; recording keeps every frame, and an overrun stops it loudly with what was
//! written intact.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{rig, scratch};

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tremorscan::device::{Camera, DeviceError, Grabbed, Pacing, ReplayCamera};
use tremorscan::frame::Frame;
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig, PipelineEvent};
use tremorscan::rig::VirtualRig;
use tremorscan::session::{write_session, Manifest, Session, TrialJson};

fn manifest(rig: &VirtualRig) -> Manifest {
    rig.session_manifest()
}

fn rendered(rig: &VirtualRig, n: u64) -> Vec<Frame> {
    common::rendered(rig, 0..n)
}

/// Frames from memory after `go` is set, `interval` apart (zero: as fast as asked for).
struct MemoryCamera {
    frames: Vec<Frame>,
    repeat: usize,
    next: usize,
    go: Arc<AtomicBool>,
    interval: Duration,
}

impl Camera for MemoryCamera {
    fn name(&self) -> String {
        "memory".into()
    }
    fn size(&self) -> (usize, usize) {
        (self.frames[0].width, self.frames[0].height)
    }
    fn fps(&self) -> f64 {
        121.0
    }
    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        while !self.go.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(1));
        }
        if self.next >= self.frames.len() * self.repeat {
            return Err(DeviceError::EndOfStream {
                frames: self.next as u64,
            });
        }
        std::thread::sleep(self.interval);
        let src = &self.frames[self.next % self.frames.len()];
        frame.clone_from(src);
        // Keep time and pattern running across repeats.
        frame.time_s = self.next as f64 / 121.0;
        frame.pattern_index = self.next % 3;
        self.next += 1;
        Ok(Grabbed {
            sequence_number: self.next as u64 - 1,
        })
    }
}

/// A lossless pipeline over `frames` shown `repeat` times, held until `go` is set.
fn lossless_pipeline(
    rig: &VirtualRig,
    frames: &[Frame],
    repeat: usize,
) -> (Pipeline, Arc<AtomicBool>) {
    lossless_pipeline_with(
        rig,
        frames,
        repeat,
        PipelineConfig::default().consumer_queue,
    )
}

/// [`lossless_pipeline`] with a queue of `consumer_queue` results for a consumer.
fn lossless_pipeline_with(
    rig: &VirtualRig,
    frames: &[Frame],
    repeat: usize,
    consumer_queue: usize,
) -> (Pipeline, Arc<AtomicBool>) {
    let go = Arc::new(AtomicBool::new(false));
    let camera = MemoryCamera {
        frames: frames.to_vec(),
        repeat,
        next: 0,
        go: Arc::clone(&go),
        interval: Duration::ZERO,
    };
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        consumer_queue,
        ..PipelineConfig::default()
    };
    let pipeline = Pipeline::start(
        Box::new(camera),
        rig.sequence.clone(),
        rig.config.cross_talk,
        rig.stereo_model(),
        config,
    )
    .unwrap();
    (pipeline, go)
}

#[test]
fn a_lossless_replay_decodes_every_window() {
    let rig = rig(320, 200);
    let dir = scratch("replay");
    write_session(&dir, manifest(&rig), &rendered(&rig, 12)).unwrap();
    let session = Session::open(&dir).unwrap();
    let (seq, cross, stereo) = (
        session.sequence().unwrap(),
        session.cross_talk().unwrap().unwrap(),
        session.stereo_model().unwrap(),
    );
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        consumer_queue: 16,
        ..PipelineConfig::default()
    };
    let camera = ReplayCamera::new(session, Pacing::AsFastAsPossible);
    let pipeline = Pipeline::start(Box::new(camera), seq, cross, stereo, config).unwrap();
    assert!(pipeline.wait_for_end(Duration::from_secs(30)));
    let mut ends = Vec::new();

    while let Some(cloud) = pipeline.next_for_consumer() {
        // At 320×200 a fringe period spans about 11 camera pixels; the hand scene decodes
        // over most of the image (measured 95.5–95.7 %).
        assert!(
            cloud.cloud.valid_count() * 4 > 320 * 200 * 3,
            "{}",
            cloud.cloud.valid_count()
        );

        assert!(cloud.latency > Duration::ZERO);
        ends.push(cloud.window_end);
    }
    assert_eq!(ends, (2..12).collect::<Vec<u64>>());
    let events = pipeline.events();
    assert!(
        events.contains(&PipelineEvent::SourceEnded { frames: 12 }),
        "{events:?}"
    );
    let m = pipeline.stop();
    assert_eq!(
        (
            m.captured,
            m.decoded,
            m.decode_dropped,
            m.unsolvable_windows
        ),
        (12, 10, 0, 0)
    );
    assert!(m.latency_ms_median > 0.0 && m.latency_ms_p99 >= m.latency_ms_median);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn windows_refused_for_a_corrupted_frame_are_counted_and_give_no_points() {
    let rig = rig(320, 200);
    let mut frames = rendered(&rig, 12);
    frames[6] = common::corrupted_red(&rig, 6);
    let (pipeline, go) = lossless_pipeline_with(&rig, &frames, 1, 16);
    go.store(true, Ordering::SeqCst);
    assert!(pipeline.wait_for_end(Duration::from_secs(30)));
    let mut empty = Vec::new();
    while let Some(cloud) = pipeline.next_for_consumer() {
        let valid = cloud.cloud.valid_count();
        if valid == 0 {
            empty.push(cloud.window_end);
        } else {
            assert!(valid * 4 > 320 * 200 * 3, "{}: {valid}", cloud.window_end);
        }
    }
    // The three windows that hold frame 6.
    assert_eq!(empty, [6, 7, 8]);
    let m = pipeline.stop();
    assert_eq!((m.decoded, m.refused_windows), (10, 3));
    assert!(m.to_string().contains("3 refused"), "{m}");
}

#[test]
fn a_real_time_stage_that_falls_behind_drops_and_counts() {
    let rig = rig(320, 200);
    let go = Arc::new(AtomicBool::new(true));
    let camera = MemoryCamera {
        frames: rendered(&rig, 3),
        repeat: 100,
        next: 0,
        go,
        // 2000 frames/s for 150 ms: faster than a 320×200 window decodes (~3 ms), and long
        // enough for the decoder to run many windows.
        interval: Duration::from_micros(500),
    };
    // The default real-time queue keeps the newest three frames: consecutive ones, so some
    // windows still decode while most frames are dropped.
    let config = PipelineConfig::default();
    let pipeline = Pipeline::start(
        Box::new(camera),
        rig.sequence.clone(),
        rig.config.cross_talk,
        rig.stereo_model(),
        config,
    )
    .unwrap();
    assert!(pipeline.wait_for_end(Duration::from_secs(60)));
    let m = pipeline.stop();
    assert_eq!(m.captured, 300);
    // Memory frames arrive far faster than a 320×200 window decodes.
    assert!(m.decode_dropped > 0, "{m}");
    assert!(m.decoded > 0, "{m}");
    // Every frame is accounted for: dropped, or handed to the decoder (which decodes it, refuses
    // a window spanning a dropped frame, or is still filling its first window).
    let handed = m.captured - m.decode_dropped;
    assert!(m.decoded + m.unsolvable_windows <= handed, "{m}");
    assert!(
        m.unsolvable_windows > 0,
        "windows across dropped frames are refused: {m}"
    );
}

#[test]
fn recording_keeps_every_frame_and_an_overrun_stops_it_loudly() {
    // Part 1: a recording that keeps up holds every captured frame, bit for bit.
    let small = rig(160, 100);
    let frames = rendered(&small, 6);
    let (pipeline, go) = lossless_pipeline(&small, &frames, 5);
    let dir = scratch("record");
    pipeline
        .start_recording(&dir, manifest(&small), TrialJson::default())
        .unwrap();
    go.store(true, Ordering::SeqCst);
    assert!(pipeline.wait_for_end(Duration::from_secs(30)));
    let summary = pipeline.stop_recording().unwrap().unwrap();
    assert_eq!(summary.frames, 30);
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.frame_count(), 30);
    assert_eq!(session.load_frame(7).unwrap().data, frames[1].data);
    let m = pipeline.stop();
    assert_eq!((m.recorded, m.recorder_lost), (30, 0));

    // Part 2: full-size frames arriving far faster than the disk writes them, with a queue
    // of 2: the recording stops at once, says so, and what it wrote reads back.
    let big = rig(1920, 1200);
    let go = Arc::new(AtomicBool::new(false));
    let camera = MemoryCamera {
        frames: rendered(&big, 3),
        repeat: 20,
        next: 0,
        go: Arc::clone(&go),
        interval: Duration::ZERO,
    };
    let config = PipelineConfig {
        decode_policy: DecodePolicy::RealTime,
        recorder_queue: 2,
        ..PipelineConfig::default()
    };
    let pipeline = Pipeline::start(
        Box::new(camera),
        big.sequence.clone(),
        big.config.cross_talk,
        big.stereo_model(),
        config,
    )
    .unwrap();
    let dir2 = scratch("overrun");
    pipeline
        .start_recording(&dir2, manifest(&big), TrialJson::default())
        .unwrap();
    go.store(true, Ordering::SeqCst);
    assert!(pipeline.wait_for_end(Duration::from_secs(120)));
    let events = pipeline.events();
    assert!(
        events
            .iter()
            .any(|e| matches!(e, PipelineEvent::RecordingOverrun { .. })),
        "{events:?}"
    );
    assert!(!pipeline.is_recording());
    let m = pipeline.stop();
    assert!(m.recorder_lost >= 1, "{m}");
    let session = Session::open(&dir2).unwrap();
    assert!(session.frame_count() >= 1 && (session.frame_count() as u64) < m.captured);
    assert_eq!(session.frame_count() as u64, m.recorded, "{m}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

#[test]
fn devices_pace_and_end_as_asked() {
    use std::time::Instant;
    use tremorscan::device::VirtualCamera;
    // The virtual rig as a camera: the rig's own frames, numbered, ending at its limit.
    let r = rig(160, 100);
    let expected = rendered(&r, 4);
    let mut camera = VirtualCamera::new(r, Pacing::AsFastAsPossible).with_limit(4);
    let mut frame = Frame::new(1, 1, 3).unwrap();
    for (i, want) in expected.iter().enumerate() {
        let grabbed = camera.grab(&mut frame).unwrap();
        assert_eq!(grabbed.sequence_number, i as u64);
        assert_eq!(&frame, want);
    }
    assert!(matches!(
        camera.grab(&mut frame),
        Err(DeviceError::EndOfStream { frames: 4 })
    ));
    // A replay at the recorded rate takes the recorded time (12 frames at 121 FPS: 91 ms).
    let r = rig(160, 100);
    let dir = scratch("paced");
    write_session(&dir, manifest(&r), &rendered(&r, 12)).unwrap();
    let mut replay = ReplayCamera::new(Session::open(&dir).unwrap(), Pacing::Recorded);
    let start = Instant::now();
    for _ in 0..12 {
        replay.grab(&mut frame).unwrap();
    }
    let wall = start.elapsed().as_secs_f64();
    assert!(wall >= 11.0 / 121.0 - 1e-3, "{wall} s");
    assert!((replay.fps() - 121.0).abs() < 1e-6);
    assert!(matches!(
        replay.grab(&mut frame),
        Err(DeviceError::EndOfStream { frames: 12 })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ending_a_recording_without_waiting_still_writes_every_frame_and_reports_it() {
    let small = rig(160, 100);
    let frames = rendered(&small, 6);
    let (pipeline, go) = lossless_pipeline(&small, &frames, 4);
    let dir = scratch("end-recording");
    pipeline
        .start_recording(&dir, manifest(&small), TrialJson::default())
        .unwrap();
    go.store(true, Ordering::SeqCst);
    assert!(pipeline.wait_for_end(Duration::from_secs(30)));
    assert!(pipeline.end_recording());
    assert!(!pipeline.is_recording());
    assert!(!pipeline.end_recording(), "nothing left to end");
    // The outcome arrives as an event once the recorder has written what it held.
    let start = std::time::Instant::now();
    let summary = loop {
        let stopped = pipeline.events().into_iter().find_map(|e| match e {
            PipelineEvent::RecordingStopped(r) => Some(r),
            _ => None,
        });
        if let Some(r) = stopped {
            break r.unwrap();
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no RecordingStopped event"
        );
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!(summary.frames, 24);
    assert_eq!(Session::open(&dir).unwrap().frame_count(), 24);
    let m = pipeline.stop();
    assert_eq!((m.recorded, m.recorder_lost), (24, 0));
}
