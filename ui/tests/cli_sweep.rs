//! `tremorscan sweep` end to end at a small size: the noise table's columns mean what they
//! say; `--motion`: the three tables, every row, and a refused amplitude.
#![allow(clippy::unwrap_used, reason = "tests")]

use std::process::Command;

fn sweep(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .arg("sweep")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_motion_sweep_prints_the_skin_the_fingertip_and_the_followed_tables() {
    let out = sweep(&[
        "--motion",
        "--width",
        "320",
        "--height",
        "200",
        "--amplitudes-mm",
        "5",
        "--frames",
        "4",
        "--tip-frames",
        "130",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("| 5 mm |"))
        .collect();
    // Two tables × (no sway, sway) × (still, motion), then the followed point's table ×
    // (no sway, sway).
    assert_eq!(rows.len(), 10, "{stdout}");
    assert!(
        stdout.contains("Index fingertip followed on the skin"),
        "{stdout}"
    );
    assert!(
        stdout.contains("Index fingertip's pixel, 130 frames"),
        "{stdout}"
    );
    assert!(
        stdout.contains("| valid | peak Hz (truth) | peak-to-peak mm (truth) |"),
        "{stdout}"
    );
    // Every fingertip row of the motion model has figures with the truth beside them, here
    // within a few per cent and the same bin.
    // The followed point's rows (motion model only) have their figures in the same columns.
    let fingertip_rows = rows[4..8].iter().filter(|r| r.contains("motion model"));
    for row in fingertip_rows.chain(&rows[8..]) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let error: f64 = cells[7].trim_end_matches(" %").parse().unwrap();
        assert!(error.abs() < 10.0, "{row}");
        let bins: Vec<&str> = cells[8]
            .split([' ', '(', ')'])
            .filter(|s| !s.is_empty())
            .collect();
        assert_eq!(bins[0], bins[1], "{row}");
    }

    let out = sweep(&["--motion", "--amplitudes-mm=-1"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("is not a displacement"), "{stderr}");
}

#[test]
fn the_noise_sweep_with_checks_off_shows_what_the_unwrapping_alone_does() {
    // "Checks off" keeps the signal checks only (docs/accuracy.md, Set-up): at σ = 2 the paper's
    // per-pixel formula then keeps nearly every lit pixel and puts a wrong fringe order on about
    // a third of them (320×200: 99.39 % kept, 31 % wrong). With the mixed-pixel stage left on,
    // that column kept 25.6 % (its scattered wrong orders read as depth edges) and hid most of
    // the formula's failure.
    let out = sweep(&["--width", "320", "--height", "200", "--sigmas", "2"]);
    assert!(out.status.success(), "{out:?}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let row = |method: &str, checks: &str| -> Vec<f64> {
        let line = stdout
            .lines()
            .find(|l| l.contains(method) && l.contains(&format!("| {checks} |")))
            .unwrap_or_else(|| panic!("no {method} {checks} row in {stdout}"));
        line.split('|')
            .filter_map(|c| c.trim().parse().ok())
            .collect()
    };
    // σ, valid %, errors %, RMS.
    let paper_off = row("per-pixel", "off");
    assert!(paper_off[1] > 99.0 && paper_off[2] > 20.0, "{paper_off:?}");
    let robust_on = row("robust", "on");
    assert!(robust_on[1] > 90.0 && robust_on[2] == 0.0, "{robust_on:?}");
}
