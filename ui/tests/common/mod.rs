//! Shared helpers of the command-line tests: run the binary, scratch folders.
#![allow(
    dead_code,
    reason = "each test binary uses a different subset of the helpers"
)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `tremorscan` with `args` and returns what it did.
pub fn tremorscan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .args(args)
        .output()
        .unwrap()
}

/// A fresh path under the system's temporary folder, unique to this test process and `name`
/// (anything left there by an earlier run is removed; the folder itself is not created).
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tremorscan-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
