//! Scratch folders of the tests: each is a fresh temporary folder, removed when the test passes
//! and kept (its path printed) when the test fails, so that a failure's files can be inspected
//! and a passing run leaves nothing behind.
//!
//! Shared by the core crate's and the app crate's tests (`#[path]`-included by the latter).

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A path inside a fresh temporary folder; the temporary folder goes when this is dropped,
/// unless the thread is panicking (a failing test).
pub struct Scratch {
    path: PathBuf,
    root: Option<tempfile::TempDir>,
}

/// A path named `name` that does not exist yet, inside a fresh temporary folder.
pub fn scratch(name: &str) -> Scratch {
    let root = tempfile::Builder::new()
        .prefix(&format!("tremorscan-{name}-"))
        .tempdir()
        .expect("a temporary folder for the test");
    Scratch {
        path: root.path().join(name),
        root: Some(root),
    }
}

/// Like [`scratch`], with the folder created.
pub fn scratch_dir(name: &str) -> Scratch {
    let dir = scratch(name);
    std::fs::create_dir_all(&dir.path).expect("the test's scratch folder");
    dir
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            if let Some(root) = self.root.take() {
                eprintln!(
                    "the failed test's files are kept in {}",
                    root.keep().display()
                );
            }
        }
    }
}
