//! `tremorscan sweep --motion` end to end at a small size: both tables, every row, and a refused
//! amplitude.
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
fn the_motion_sweep_prints_the_skin_and_the_fingertip_tables() {
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
    // Two tables × (no sway, sway) × (still, motion).
    assert_eq!(rows.len(), 8, "{stdout}");
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
    for row in rows[4..].iter().filter(|r| r.contains("motion model")) {
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
