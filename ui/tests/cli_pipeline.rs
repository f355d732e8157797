//! Record a trial through the live pipeline, kill the process mid-recording, and replay what
//! it left: every complete frame is there.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use std::process::Command;
use std::time::{Duration, Instant};
use tremorscan::session::Session;

#[test]
fn record_interrupt_then_replay() {
    let dir = common::scratch("rec");
    let mut child = Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .args(["record", "--out", dir.to_str().unwrap(), "--seconds", "120"])
        .args([
            "--width",
            "320",
            "--height",
            "200",
            "--subject",
            "T-1",
            "--hand",
            "left",
        ])
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until a few frames are on disk, then kill it as a crash would (SIGKILL: no
    // clean-up runs).
    let container = dir.join("frames.cpsr");
    let start = Instant::now();
    while std::fs::metadata(&container).map_or(0, |m| m.len()) < 2_000_000 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "nothing recorded"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let session = Session::open(&dir).unwrap();
    let frames = session.frame_count();
    assert!(frames >= 3, "{frames} frames");
    assert_eq!(session.manifest.trial.as_ref().unwrap().subject_id, "T-1");
    for i in 0..frames {
        let f = session.load_frame(i).unwrap();
        assert_eq!(f.pattern_index, i % 3);
    }
    // The default decoder, then the CPU and the GPU (lavapipe on the CI machine) named.
    for (decoder, runs_on) in [
        (None, "decode: "),
        (Some("cpu"), "decode: CPU"),
        (Some("gpu"), "decode: GPU"),
    ] {
        let mut args = vec!["replay", dir.to_str().unwrap()];
        if let Some(d) = decoder {
            args.extend(["--decoder", d]);
        }
        // Every decoder with the default decode, the motion model with it.
        let out = Command::new(env!("CARGO_BIN_EXE_tremorscan"))
            .args(&args)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains(runs_on), "{stdout}");
        assert!(
            stdout.contains(&format!(
                "replayed {frames} frames into {} windows",
                frames - 2
            )),
            "{stdout}"
        );
        // The closing metrics line carries the process's resident memory where Linux reports it.
        if cfg!(target_os = "linux") {
            assert!(
                stdout
                    .lines()
                    .any(|l| l.starts_with("capture ") && l.contains(" | resident ")),
                "{stdout}"
            );
        }
    }
    // The paper's still window on the GPU too.
    let out = Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .args([
            "replay",
            dir.to_str().unwrap(),
            "--decoder",
            "gpu",
            "--motion",
            "off",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("decode: GPU"),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
