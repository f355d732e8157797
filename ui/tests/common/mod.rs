//! Shared helpers of the command-line tests: run the binary, scratch folders.
#![allow(
    dead_code,
    unused_imports,
    reason = "each test binary uses a different subset of the helpers"
)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs `tremorscan` with `args` and returns what it did.
pub fn tremorscan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tremorscan"))
        .args(args)
        .output()
        .unwrap()
}

#[path = "../../../tests/common/scratch.rs"]
mod scratch;
pub use scratch::{scratch, scratch_dir, Scratch};

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
