//! Live recording: frames recorded into a session come back bit for bit with their metadata;
//! a recording cut off mid-frame stays readable up to its last complete frame.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{rig, scratch};

use tremorscan::frame::Frame;
use tremorscan::rig::VirtualRig;
use tremorscan::session::manifest::ControlPointJson;
use tremorscan::session::{Manifest, Recorder, Session, TrialJson};

fn manifest(rig: &VirtualRig) -> Manifest {
    rig.session_manifest()
}

fn trial() -> TrialJson {
    TrialJson {
        subject_id: "P-017".into(),
        hand: "right".into(),
        condition: "rest, medication off".into(),
        operator_notes: "slight movement at 2 s".into(),
        date: "2026-12-03T09:15:00Z".into(),
        control_points: vec![ControlPointJson {
            name: "index tip".into(),
            u: 80.5,
            v: 40.0,
        }],
    }
}

fn frames(rig: &VirtualRig, n: u64) -> Vec<Frame> {
    common::rendered(rig, 0..n)
}

#[test]
fn a_recording_reads_back_bit_for_bit_with_its_trial() {
    let rig = rig(160, 100);
    let dir = scratch("roundtrip");
    let recorded = frames(&rig, 9);
    let mut recorder = Recorder::create(&dir, manifest(&rig), trial()).unwrap();
    for f in &recorded {
        recorder.write_frame(f).unwrap();
    }
    let summary = recorder.finish().unwrap();
    assert_eq!(summary.frames, 9);
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.frame_count(), 9);
    assert_eq!(session.manifest.trial, Some(trial()));
    assert!(session.container.as_ref().unwrap().cut_off.is_none());
    for (i, f) in recorded.iter().enumerate() {
        assert_eq!(&session.load_frame(i).unwrap(), f);
    }
    assert_eq!(session.sequence().unwrap(), rig.sequence);
    // Never larger than the raw frames plus a 48-byte header each (noisy frames are stored).
    assert!(summary.bytes <= 8 + 9 * (160 * 100 * 3 + 48), "{summary:?}");
    // Control points set in replay are saved with the session; the frames stay as they were.
    let mut session = session;
    let mut t = trial();
    t.control_points.push(ControlPointJson {
        name: "thumb".into(),
        u: 30.0,
        v: 60.0,
    });
    session.save_trial(t.clone()).unwrap();
    let reopened = Session::open(&dir).unwrap();
    assert_eq!(reopened.manifest.trial, Some(t));
    assert_eq!(reopened.frame_count(), 9);
    assert_eq!(&reopened.load_frame(8).unwrap(), &recorded[8]);
    // A second recording into the same folder is refused.
    assert!(Recorder::create(&dir, manifest(&rig), trial()).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_recording_cut_off_mid_frame_keeps_every_complete_frame() {
    let rig = rig(160, 100);
    let dir = scratch("crash");
    let recorded = frames(&rig, 6);
    let mut recorder = Recorder::create(&dir, manifest(&rig), trial()).unwrap();
    for f in &recorded {
        recorder.write_frame(f).unwrap();
    }
    recorder.finish().unwrap();
    // The process died while the sixth frame was being written: cut the file inside it.
    let path = dir.join("frames.cpsr");
    let len = std::fs::metadata(&path).unwrap().len();
    let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.set_len(len - 100).unwrap();
    drop(file);
    let session = Session::open(&dir).unwrap();
    assert_eq!(session.frame_count(), 5);
    let cut = session.container.as_ref().unwrap().cut_off.clone().unwrap();
    assert!(cut.contains("frame 5"), "{cut}");
    for (i, f) in recorded.iter().take(5).enumerate() {
        assert_eq!(&session.load_frame(i).unwrap(), f);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_frame_of_the_wrong_size_is_refused_and_the_recording_goes_on() {
    let rig = rig(160, 100);
    let dir = scratch("size");
    let mut recorder = Recorder::create(&dir, manifest(&rig), trial()).unwrap();
    let good = frames(&rig, 2);
    recorder.write_frame(&good[0]).unwrap();
    let wrong = Frame::new(80, 50, 3).unwrap();
    let e = recorder.write_frame(&wrong).unwrap_err().to_string();
    assert!(e.contains("80×50") && e.contains("160×100"), "{e}");
    recorder.write_frame(&good[1]).unwrap();
    recorder.finish().unwrap();
    assert_eq!(Session::open(&dir).unwrap().frame_count(), 2);
    let _ = std::fs::remove_dir_all(&dir);
}
