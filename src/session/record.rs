//! Live recording of a session: `session.json` first (pattern, calibration, trial metadata and
//! the container's name), then every frame appended to `frames.cpsr` as it arrives. Nothing needs
//! to be rewritten at the end, so a recording stopped by a crash or a full disk is a valid
//! session up to its last complete frame ([`Session::open`](super::Session::open) reads it).
//!
//! [`Recorder::finish`] flushes and syncs; [`Recorder::set_trial`] rewrites the manifest (atomic
//! rename) when the control points or notes change after the recording.

use super::container::{ContainerError, ContainerWriter};
use super::manifest::{Manifest, RecordingJson, TrialJson};
use super::SessionError;
use crate::frame::Frame;
use crate::jsonfile;
use std::fs::File;
use std::path::{Path, PathBuf};

/// Name of the container inside the session folder.
pub const CONTAINER_FILE: &str = "frames.cpsr";

/// Writes one recording.
pub struct Recorder {
    dir: PathBuf,
    manifest: Manifest,
    /// Unbuffered: each record goes to the kernel in one write as soon as it is built, so a
    /// crash of this process loses no frame that `write_frame` accepted.
    writer: ContainerWriter<File>,
}

/// What a finished recording holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordingSummary {
    pub frames: u64,
    pub bytes: u64,
}

impl Recorder {
    /// Creates `dir` (which must not hold a session yet) and starts recording. `manifest`
    /// supplies the pattern, sizes and calibration; its frame list is ignored.
    pub fn create(
        dir: &Path,
        mut manifest: Manifest,
        trial: TrialJson,
    ) -> Result<Self, SessionError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| SessionError::Io { path, source }
        };
        let manifest_path = dir.join("session.json");
        if manifest_path.exists() {
            return Err(SessionError::Io {
                path: manifest_path,
                source: std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "a session is already recorded here",
                ),
            });
        }
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let container_path = dir.join(CONTAINER_FILE);
        let file = File::create(&container_path).map_err(io(&container_path))?;
        let writer = ContainerWriter::new(file).map_err(|source| SessionError::Container {
            path: container_path.clone(),
            source,
        })?;
        manifest.frames.clear();
        manifest.recording = Some(RecordingJson {
            file: CONTAINER_FILE.to_string(),
        });
        manifest.trial = Some(trial);
        jsonfile::write_atomic(&manifest_path, &manifest)?;
        Ok(Self {
            dir: dir.to_path_buf(),
            manifest,
            writer,
        })
    }

    /// Appends a frame. A frame of the wrong size is refused; a write error (disk full) is
    /// returned at once, and every frame before it stays readable.
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), SessionError> {
        let (w, h) = (self.manifest.camera.width, self.manifest.camera.height);
        if (frame.width, frame.height) != (w, h) {
            return Err(SessionError::FrameSize {
                file: self.dir.join(CONTAINER_FILE),
                width: frame.width,
                height: frame.height,
                expected_width: w,
                expected_height: h,
            });
        }
        self.writer
            .write_frame(frame)
            .map_err(|source| self.container_error(source))
    }

    pub fn frames(&self) -> u64 {
        self.writer.frames()
    }

    pub fn bytes(&self) -> u64 {
        self.writer.bytes()
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Replaces the trial metadata (e.g. control points set after recording).
    pub fn set_trial(&mut self, trial: TrialJson) -> Result<(), SessionError> {
        self.manifest.trial = Some(trial);
        Ok(jsonfile::write_atomic(
            &self.dir.join("session.json"),
            &self.manifest,
        )?)
    }

    /// Flushes and syncs the container.
    pub fn finish(mut self) -> Result<RecordingSummary, SessionError> {
        self.writer
            .flush()
            .map_err(|source| self.container_error(source))?;
        let summary = RecordingSummary {
            frames: self.writer.frames(),
            bytes: self.writer.bytes(),
        };
        let path = self.dir.join(CONTAINER_FILE);
        let file = self.writer.into_inner();
        file.sync_all()
            .map_err(|source| SessionError::Io { path, source })?;
        Ok(summary)
    }

    fn container_error(&self, source: ContainerError) -> SessionError {
        SessionError::Container {
            path: self.dir.join(CONTAINER_FILE),
            source,
        }
    }
}
