//! A real GenICam device: aravis's fake GigE Vision camera, running in this process on loopback
//! (the same GVCP/GVSP protocol stack a real camera speaks). Discovery, configuration, streaming
//! and pulling the camera out mid-stream, also during a recording.
//!
//! Runs with `--features genicam` (CI installs libaravis-dev). The fake camera listens on the
//! GigE Vision port of 127.0.0.1, so the tests take turns.
#![cfg(feature = "genicam")]
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tremorscan::device::bayer::BayerPattern;
use tremorscan::device::genicam::{
    list_cameras, GenicamCamera, GenicamError, GenicamSettings, PixelChoice, TriggerChoice,
};
use tremorscan::device::{Camera, DeviceError};
use tremorscan::frame::Frame;
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig, PipelineEvent};
use tremorscan::session::{Session, TrialJson};

/// One fake camera at a time: they all listen on 127.0.0.1's GVCP port.
static LOOPBACK: Mutex<()> = Mutex::new(());

struct FakeCamera {
    fake: Option<aravis::GvFakeCamera>,
    id: String,
    _turn: MutexGuard<'static, ()>,
}

impl FakeCamera {
    /// Starts a fake camera and waits until discovery lists it.
    fn start(serial: &str) -> Self {
        let turn = LOOPBACK.lock().unwrap_or_else(|p| p.into_inner());
        let fake = aravis::GvFakeCamera::new(Some("127.0.0.1"), Some(serial));
        let id = format!("Aravis-Fake-{serial}");
        let deadline = Instant::now() + Duration::from_secs(10);
        while !list_cameras().iter().any(|c| c.id == id) {
            assert!(
                Instant::now() < deadline,
                "the fake camera {id} never appeared"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        Self {
            fake: Some(fake),
            id,
            _turn: turn,
        }
    }

    /// Pulls the cable: the fake camera stops answering.
    fn unplug(&mut self) {
        self.fake = None;
    }
}

fn grab_ok(camera: &mut GenicamCamera, frame: &mut Frame) -> u64 {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        match camera.grab(frame) {
            Ok(g) => return g.sequence_number,
            Err(DeviceError::Idle) if Instant::now() < deadline => continue,
            Err(e) => panic!("grab failed: {e}"),
        }
    }
}

#[test]
fn discovery_lists_the_camera_and_a_wrong_id_names_what_is_there() {
    let fake = FakeCamera::start("TSD1");
    let info = list_cameras()
        .into_iter()
        .find(|c| c.id == fake.id)
        .unwrap();
    assert_eq!(info.protocol, "GigEVision");
    assert_eq!(info.address, "127.0.0.1");
    match GenicamCamera::open("Basler-acA1920-155uc-0000", &GenicamSettings::default()) {
        Err(GenicamError::NoCamera(id, found)) => {
            assert_eq!(id, "Basler-acA1920-155uc-0000");
            assert!(found.contains(&fake.id), "{found}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("opened a camera that is not there"),
    }
}

#[test]
fn settings_reach_the_camera_and_frames_have_the_region_size() {
    let fake = FakeCamera::start("TSC1");
    let settings = GenicamSettings {
        pixel: PixelChoice::Auto,
        exposure_micros: Some(5000.0),
        gain_db: Some(2.0),
        region: Some([64, 32, 320, 200]),
        frame_rate_hz: Some(50.0),
        ..GenicamSettings::default()
    };
    let mut camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    let back = camera.readback().unwrap();
    assert_eq!(back.region, [64, 32, 320, 200]);
    assert_eq!(back.exposure_micros, 5000.0);
    assert_eq!(back.gain_db, 2.0);
    assert!((back.frame_rate_hz - 50.0).abs() < 0.01, "{back:?}");
    assert_eq!(back.trigger_mode, "Off");
    assert_eq!(camera.size(), (320, 200));
    let mut frame = Frame::empty();
    grab_ok(&mut camera, &mut frame);
    assert_eq!((frame.width, frame.height, frame.channels), (320, 200, 3));
    assert_eq!(frame.data.len(), 320 * 200 * 3);
    drop(camera);

    // A line the camera does not have is refused with the ones it has.
    let wrong = GenicamSettings {
        trigger: TriggerChoice::Hardware {
            line: "Line7".to_string(),
        },
        ..settings.clone()
    };
    let offered = match GenicamCamera::open(&fake.id, &wrong) {
        Err(GenicamError::NoTriggerLine { line, offered, .. }) => {
            assert_eq!(line, "Line7");
            offered
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("accepted a line the camera lacks"),
    };
    // Hardware trigger on: the camera says so, and without edges on the line no frame comes.
    let line = offered.into_iter().find(|l| l.starts_with("Line")).unwrap();
    let triggered = GenicamSettings {
        trigger: TriggerChoice::Hardware { line },
        ..settings
    };
    let mut camera = GenicamCamera::open(&fake.id, &triggered).unwrap();
    assert_eq!(camera.readback().unwrap().trigger_mode, "On");
    assert!(matches!(camera.grab(&mut frame), Err(DeviceError::Idle)));
}

#[test]
fn streaming_numbers_times_and_cycles_patterns_and_a_bayer_stream_is_demosaiced() {
    let fake = FakeCamera::start("TSS1");
    let settings = GenicamSettings {
        frame_rate_hz: Some(100.0),
        region: Some([0, 0, 256, 160]),
        pattern_offset: 1,
        ..GenicamSettings::default()
    };
    let mut camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    let mut frame = Frame::empty();
    // A second program (here: a second open) cannot take the camera while it streams.
    match GenicamCamera::open(&fake.id, &settings) {
        Err(GenicamError::Busy { detail, .. }) => assert!(detail.contains("another program")),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("opened a camera in use"),
    }
    let mut stamps = Vec::new();
    let mut host_s = Vec::new();
    let started = Instant::now();
    // Incomplete buffers, counted after each grab. Two frames can rightly arrive without
    // some of their packets, both near the start: the one the camera is sending when the stream
    // starts (seen as block 65401, the fake camera's first, in 4 of about 110 runs on a 2-core
    // machine), and the one in flight when the first grab gives a buffer back to the pool the
    // busy check let fill (popped after the 16 queued ones; seen once in CI as one incomplete
    // buffer counted after the first grab).
    let mut incomplete_after = Vec::new();
    for _ in 0..50 {
        let k = grab_ok(&mut camera, &mut frame);
        incomplete_after.push(camera.incomplete_buffers());
        assert_eq!(frame.pattern_index, ((k + 1) % 3) as usize);
        if let Some(&(k0, t0)) = stamps.last() {
            assert!(k > k0, "frame numbers go forward");
            assert!(frame.time_s >= t0, "camera time goes forward");
        }
        stamps.push((k, frame.time_s));
        host_s.push(started.elapsed().as_secs_f64());
    }
    // Camera time stamps are in seconds: they advance as the host's clock does. The first grabs
    // empty the pool of 16 buffers the camera filled while the busy check above ran (about 6 s
    // here, the frames after them dropped and seen as a gap in the numbers); from then on each
    // frame's host-minus-camera offset is its delivery delay plus a constant. Scheduling only
    // ever adds delay, so the smallest offset among frames 20..30 and among frames 40..50 both
    // sit near the constant, and they agree to within 5 % of the span between them (measured:
    // under 0.2 ms in 0.2 s, with four busy loops on two cores). A stamp in milliseconds or in
    // ticks would drift by about the whole span.
    let offsets: Vec<f64> = stamps.iter().zip(&host_s).map(|(s, h)| h - s.1).collect();
    let least = |o: &[f64]| o.iter().copied().fold(f64::INFINITY, f64::min);
    let span_s = stamps[45].1 - stamps[25].1;
    let drift_s = least(&offsets[40..]) - least(&offsets[20..30]);
    assert!(span_s > 0.1, "20 frames in {span_s} s");
    assert!(
        drift_s.abs() < 0.05 * span_s,
        "camera time drifts {drift_s} s from the host's over {span_s} s"
    );
    // The camera is never faster than the 10 ms period asked for. It can be slower: on a loaded
    // CI machine the fake camera's mean period was 11.2 ms.
    let (first, last) = (stamps[0], stamps[stamps.len() - 1]);
    let period = (last.1 - first.1) / (last.0 - first.0) as f64;
    assert!(period > 0.0095, "mean period {period} s");
    // At most those two frames are lost, both among the first 20 grabs (the pool's 16, the
    // frame that resumed the stream, a margin); once streaming, loopback loses nothing.
    let lost_at_start = incomplete_after[19];
    assert!(
        lost_at_start <= 2,
        "{lost_at_start} frames lost at the start: {incomplete_after:?}"
    );
    assert_eq!(
        camera.incomplete_buffers(),
        lost_at_start,
        "frames lost once streaming (incomplete count after each grab: {incomplete_after:?})"
    );
    // The fake camera draws a pattern, not a flat field.
    let (min, max) = frame
        .data
        .iter()
        .fold((255u8, 0u8), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(max > min + 50, "{min}..{max}");
    drop(camera);

    let bayer = GenicamSettings {
        pixel: PixelChoice::Bayer(BayerPattern::Bg),
        ..settings
    };
    match GenicamCamera::open(&fake.id, &bayer) {
        Ok(mut camera) => {
            assert_eq!(camera.readback().unwrap().pixel_format, "BayerBG8");
            grab_ok(&mut camera, &mut frame);
            assert_eq!(frame.data.len(), 256 * 160 * 3);
        }
        // A camera without that format says what it offers.
        Err(GenicamError::NoColourFormat { offered, .. }) => assert!(!offered.is_empty()),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn pulling_the_camera_out_ends_a_recording_that_keeps_its_frames() {
    let mut fake = FakeCamera::start("TSU1");
    let rig = common::rig(320, 200);
    let settings = GenicamSettings {
        frame_rate_hz: Some(60.0),
        region: Some([0, 0, 320, 200]),
        ..GenicamSettings::default()
    };
    let camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    let config = PipelineConfig {
        decode_policy: DecodePolicy::RealTime,
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
    let dir = common::scratch("genicam-unplug");
    pipeline
        .start_recording(&dir, rig.session_manifest(), TrialJson::default())
        .unwrap();
    // Record a while, then pull the cable.
    let deadline = Instant::now() + Duration::from_secs(20);
    while pipeline.metrics().recorded < 20 {
        assert!(Instant::now() < deadline, "nothing recorded");
        std::thread::sleep(Duration::from_millis(20));
    }
    fake.unplug();
    assert!(
        pipeline.wait_for_end(Duration::from_secs(30)),
        "the pipeline did not notice the camera was gone"
    );
    let events = pipeline.events();
    let failure = events
        .iter()
        .find_map(|e| match e {
            PipelineEvent::SourceFailed(why) => Some(why.clone()),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no failure reported: {events:?}"));
    assert!(failure.contains("unplugged"), "{failure}");
    let summary = pipeline.stop_recording().unwrap().unwrap();
    let m = pipeline.stop();
    assert_eq!(m.recorder_lost, 0, "{m}");
    assert!(summary.frames >= 20);
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.frame_count() as u64, summary.frames);
    let last = session.load_frame(session.frame_count() - 1).unwrap();
    assert_eq!((last.width, last.height), (320, 200));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Share of GigE Vision data packets the fake camera drops: a 256×160 RGB8 frame spans about 85
/// packets, so none arrives whole (aravis's resend requests meet the same loss).
const LOST: f64 = 0.5;

#[test]
fn a_link_that_loses_the_packets_is_reported_as_too_slow() {
    let fake = FakeCamera::start("TSL1");
    let settings = GenicamSettings {
        frame_rate_hz: Some(50.0),
        region: Some([0, 0, 256, 160]),
        ..GenicamSettings::default()
    };
    let mut camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    let mut frame = Frame::empty();
    grab_ok(&mut camera, &mut frame);
    // Half the packets lost from now on: frames arrive, never whole.
    fake.fake.as_ref().unwrap().set_gvsp_lost_ratio(LOST);
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        match camera.grab(&mut frame) {
            Err(DeviceError::Link(why)) => {
                assert!(why.contains("incomplete"), "{why}");
                break;
            }
            Ok(_) | Err(DeviceError::Idle) => {
                assert!(Instant::now() < deadline, "no link error after 30 s");
            }
            Err(e) => panic!("wrong error: {e}"),
        }
    }
    assert!(camera.incomplete_buffers() >= 30);
}

#[test]
fn binning_reaches_the_camera_and_a_factor_it_cannot_do_is_refused() {
    let fake = FakeCamera::start("TSCB");
    let settings = GenicamSettings {
        binning: Some(2),
        region: Some([0, 0, 256, 160]),
        ..GenicamSettings::default()
    };
    let mut camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    let back = camera.readback().unwrap();
    assert_eq!(back.binning, Some((2, 2)), "{back:?}");
    assert_eq!(back.region, [0, 0, 256, 160]);
    let mut frame = Frame::empty();
    grab_ok(&mut camera, &mut frame);
    assert_eq!((frame.width, frame.height), (256, 160));
    drop(camera);

    // 1×1 sets binning back; the camera reports it.
    let settings = GenicamSettings {
        binning: Some(1),
        ..GenicamSettings::default()
    };
    let camera = GenicamCamera::open(&fake.id, &settings).unwrap();
    assert_eq!(camera.readback().unwrap().binning, Some((1, 1)));
    drop(camera);

    // Beyond the camera's range (the fake camera bins 1 to 16): refused, saying what it can do.
    let settings = GenicamSettings {
        binning: Some(64),
        ..GenicamSettings::default()
    };
    match GenicamCamera::open(&fake.id, &settings) {
        Err(GenicamError::NoBinning {
            binning: 64,
            detail,
            ..
        }) => assert!(detail.contains("1 to 16"), "{detail}"),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("opened with a binning the camera cannot do"),
    }
}
