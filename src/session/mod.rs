//! Sessions in the `cps-session/1` folder format (`docs/formats.md`): a `session.json`
//! manifest and the frames as image files. Measurement sessions carry the full calibration;
//! calibration sessions may leave out what the calibration produces (`color`, `K`, `dist`,
//! `extrinsics`), and the accessors that need them say which field is missing.
//!
//! [`Session::open`] reads and checks the manifest and that every frame file exists; frames
//! are read one at a time with [`Session::load_frame`]. [`write_session`] writes the folder.

pub mod container;
pub mod decoding;
pub mod frames;
pub mod manifest;
pub mod record;

pub use decoding::{NoiseSource, SessionDecoding};
pub use manifest::{Manifest, SessionEntry, TrialJson, SESSION_FORMAT};
pub use record::Recorder;

use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::geometry::{LensModel, Pose};
use crate::jsonfile::{self, JsonFileError};
use crate::pattern::{Axis, PatternError, PatternSequence};
use crate::triangulate::StereoModel;
use manifest::{EntryJson, FieldError, FrameJson};
use std::path::{Path, PathBuf};

/// Errors of reading or writing a session.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Json(#[from] JsonFileError),
    #[error("{path}: \"format\" is \"{found}\", expected \"{SESSION_FORMAT}\"")]
    Format { path: PathBuf, found: String },
    #[error("session.json: {0}")]
    Field(#[from] FieldError),
    #[error("session.json: {field}: {source}")]
    Pattern { field: String, source: PatternError },
    #[error("frame file {file} is missing")]
    MissingFrame { file: PathBuf },
    #[error("frame file {file} {why}")]
    FrameImage { file: PathBuf, why: String },
    #[error(
        "frame file {file} is {width}×{height}, the camera is {expected_width}×{expected_height}"
    )]
    FrameSize {
        file: PathBuf,
        width: usize,
        height: usize,
        expected_width: usize,
        expected_height: usize,
    },
    #[error("{path}: {source}")]
    Container {
        path: PathBuf,
        source: container::ContainerError,
    },
    #[error("frame {index} does not exist (the session has {count} frames)")]
    NoSuchFrame { index: usize, count: usize },
    #[error(transparent)]
    Decode(#[from] crate::decode::DecodeError),
}

/// An opened session.
#[derive(Debug, Clone)]
pub struct Session {
    pub dir: PathBuf,
    pub manifest: Manifest,
    /// The checked sequence entries.
    pub entries: Vec<SessionEntry>,
    /// For a live recording: its container and the complete records found in it.
    pub container: Option<ContainerFrames>,
}

/// The frames of a recording container.
#[derive(Debug, Clone)]
pub struct ContainerFrames {
    pub path: PathBuf,
    pub records: Vec<container::RecordInfo>,
    /// Why the scan stopped early, if the recording was cut off (crash, full disk).
    pub cut_off: Option<String>,
}

impl Session {
    /// Reads `dir/session.json`, checks it and checks that every frame file exists.
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, SessionError> {
        let dir = dir.as_ref().to_path_buf();
        let path = dir.join("session.json");
        let mut manifest: Manifest = jsonfile::read(&path)?;
        let container = match &manifest.recording {
            Some(recording) => {
                let cpath = dir.join(&recording.file);
                let mut file = std::fs::File::open(&cpath).map_err(|source| SessionError::Io {
                    path: cpath.clone(),
                    source,
                })?;
                let index =
                    container::scan(&mut file).map_err(|source| SessionError::Container {
                        path: cpath.clone(),
                        source,
                    })?;
                manifest.frames = index
                    .records
                    .iter()
                    .map(|r| FrameJson {
                        file: recording.file.clone(),
                        time_s: r.time_s,
                        pattern_index: r.pattern_index,
                    })
                    .collect();
                Some(ContainerFrames {
                    path: cpath,
                    records: index.records,
                    cut_off: index.cut_off,
                })
            }
            None => None,
        };
        if manifest.format != SESSION_FORMAT {
            return Err(SessionError::Format {
                path,
                found: manifest.format,
            });
        }
        let p = &manifest.pattern;
        if !(p.x_max.is_finite() && p.x_max > 0.0) {
            return Err(FieldError {
                field: "pattern.x_max".into(),
                why: format!("must be positive, got {}", p.x_max),
            }
            .into());
        }
        if !(1..=8).contains(&p.projector_bits) {
            return Err(FieldError {
                field: "pattern.projector_bits".into(),
                why: format!("must lie in 1..=8, got {}", p.projector_bits),
            }
            .into());
        }
        if p.sequence.is_empty() {
            return Err(FieldError {
                field: "pattern.sequence".into(),
                why: "is empty".into(),
            }
            .into());
        }
        let entries = p
            .sequence
            .iter()
            .enumerate()
            .map(|(i, e)| e.to_entry(i, p))
            .collect::<Result<Vec<_>, _>>()?;
        for (i, f) in manifest.frames.iter().enumerate() {
            if f.pattern_index >= entries.len() {
                return Err(FieldError {
                    field: format!("frames[{i}].pattern_index"),
                    why: format!(
                        "is {}, but pattern.sequence has {} entries",
                        f.pattern_index,
                        entries.len()
                    ),
                }
                .into());
            }
            if !f.time_s.is_finite() {
                return Err(FieldError {
                    field: format!("frames[{i}].time_s"),
                    why: "is not a finite number".into(),
                }
                .into());
            }
            let file = dir.join(&f.file);
            if !file.is_file() {
                return Err(SessionError::MissingFrame { file });
            }
        }
        if let Some(noise) = manifest.camera_noise_gray {
            if !(noise.is_finite() && noise > 0.0) {
                return Err(FieldError {
                    field: "camera_noise_gray".into(),
                    why: format!("must be a positive number of gray levels, got {noise}"),
                }
                .into());
            }
        }
        for (name, lens) in [
            ("camera", &manifest.camera),
            ("projector", &manifest.projector),
        ] {
            if lens.width == 0 || lens.height == 0 {
                return Err(FieldError {
                    field: format!("{name}.width"),
                    why: format!("size {}×{} is empty", lens.width, lens.height),
                }
                .into());
            }
        }
        let session = Self {
            dir,
            manifest,
            entries,
            container,
        };
        // Whatever calibration is present must be valid, even where it is optional.
        if session.manifest.camera.k.is_some() || session.manifest.camera.dist.is_some() {
            session.camera()?;
        }
        if session.manifest.projector.k.is_some() || session.manifest.projector.dist.is_some() {
            session.projector()?;
        }
        if session.manifest.extrinsics.is_some() {
            session.projector_from_camera()?;
        }
        session.cross_talk()?;
        Ok(session)
    }

    pub fn frame_count(&self) -> usize {
        self.manifest.frames.len()
    }

    /// Frames per second from the frame times; the nominal 121 when fewer than two frames or
    /// no time span say otherwise.
    pub fn frame_rate_hz(&self) -> f64 {
        let frames = &self.manifest.frames;
        match (frames.first(), frames.last()) {
            (Some(a), Some(b)) if b.time_s > a.time_s => {
                (frames.len() - 1) as f64 / (b.time_s - a.time_s)
            }
            _ => 121.0,
        }
    }

    pub fn camera_size(&self) -> (usize, usize) {
        (self.manifest.camera.width, self.manifest.camera.height)
    }

    pub fn projector_size(&self) -> (usize, usize) {
        (
            self.manifest.projector.width,
            self.manifest.projector.height,
        )
    }

    pub fn camera(&self) -> Result<LensModel, SessionError> {
        Ok(self.manifest.camera.to_lens("camera")?)
    }

    pub fn projector(&self) -> Result<LensModel, SessionError> {
        Ok(self.manifest.projector.to_lens("projector")?)
    }

    pub fn projector_from_camera(&self) -> Result<Pose, SessionError> {
        let e = self.manifest.extrinsics.as_ref().ok_or(FieldError {
            field: "extrinsics".into(),
            why: "is missing".into(),
        })?;
        Ok(e.to_pose("extrinsics")?)
    }

    /// The colour cross-talk, if the session has one.
    pub fn cross_talk(&self) -> Result<Option<CrossTalk>, SessionError> {
        Ok(self
            .manifest
            .color
            .as_ref()
            .map(|c| c.to_cross_talk("color"))
            .transpose()?)
    }

    /// The coding entries along `axis`, as a sequence, with the session index of each.
    pub fn coding_sequence(
        &self,
        axis: Axis,
    ) -> Result<(PatternSequence, Vec<usize>), SessionError> {
        let mut entries = Vec::new();
        let mut indices = Vec::new();
        let mut x_max = None;
        for (i, e) in self.entries.iter().enumerate() {
            if let SessionEntry::Coding {
                axis: a,
                x_max: x,
                entry,
            } = *e
            {
                if a != axis {
                    continue;
                }
                if x_max.is_some_and(|m| m != x) {
                    return Err(FieldError {
                        field: format!("pattern.sequence[{i}].x_max"),
                        why: format!("differs from the other {axis:?} entries"),
                    }
                    .into());
                }
                x_max = Some(x);
                entries.push(entry);
                indices.push(i);
            }
        }
        let sequence = PatternSequence {
            x_max: x_max.unwrap_or(self.manifest.pattern.x_max),
            axis,
            projector_bits: self.manifest.pattern.projector_bits,
            entries,
        };
        sequence
            .validate()
            .map_err(|source| SessionError::Pattern {
                field: format!("pattern.sequence ({axis:?} entries)"),
                source,
            })?;
        Ok((sequence, indices))
    }

    /// The measurement sequence: every entry must code the pattern's own axis.
    pub fn sequence(&self) -> Result<PatternSequence, SessionError> {
        let axis: Axis = self.manifest.pattern.axis.into();
        let (sequence, indices) = self.coding_sequence(axis)?;
        if indices.len() != self.entries.len() {
            return Err(FieldError {
                field: "pattern.sequence".into(),
                why: format!(
                    "holds constant or other-axis entries; a measurement session codes {axis:?} only"
                ),
            }
            .into());
        }
        Ok(sequence)
    }

    /// Everything the triangulator needs.
    pub fn stereo_model(&self) -> Result<StereoModel, SessionError> {
        Ok(StereoModel {
            camera: self.camera()?,
            projector: self.projector()?,
            projector_from_camera: self.projector_from_camera()?,
            axis: self.manifest.pattern.axis.into(),
        })
    }

    /// Reads frame `index`, with its time and pattern index from the manifest.
    pub fn load_frame(&self, index: usize) -> Result<Frame, SessionError> {
        let entry = self
            .manifest
            .frames
            .get(index)
            .ok_or(SessionError::NoSuchFrame {
                index,
                count: self.frame_count(),
            })?;
        let mut frame = match &self.container {
            Some(c) => self.container_frame(c, index)?,
            None => frames::read_frame(&self.dir.join(&entry.file), self.camera_size())?,
        };
        frame.time_s = entry.time_s;
        frame.pattern_index = entry.pattern_index;
        Ok(frame)
    }
}

impl Session {
    /// Replaces the trial metadata (subject, notes, control points) and rewrites `session.json`
    /// atomically; the frames are untouched.
    pub fn save_trial(&mut self, trial: TrialJson) -> Result<(), SessionError> {
        let mut manifest = self.manifest.clone();
        manifest.trial = Some(trial.clone());
        if manifest.recording.is_some() {
            // A recording's frames live in its container, not in the manifest.
            manifest.frames.clear();
        }
        jsonfile::write_atomic(&self.dir.join("session.json"), &manifest)?;
        self.manifest.trial = Some(trial);
        Ok(())
    }

    fn container_frame(&self, c: &ContainerFrames, index: usize) -> Result<Frame, SessionError> {
        let err = |source| SessionError::Container {
            path: c.path.clone(),
            source,
        };
        let info = c.records.get(index).ok_or(SessionError::NoSuchFrame {
            index,
            count: c.records.len(),
        })?;
        let mut file = std::fs::File::open(&c.path).map_err(|source| SessionError::Io {
            path: c.path.clone(),
            source,
        })?;
        let frame = container::read_frame(&mut file, index, info).map_err(err)?;
        let (w, h) = self.camera_size();
        if (frame.width, frame.height) != (w, h) {
            return Err(SessionError::FrameSize {
                file: c.path.join(format!("#{index}")),
                width: frame.width,
                height: frame.height,
                expected_width: w,
                expected_height: h,
            });
        }
        Ok(frame)
    }
}

/// Writes a session folder: each frame as `frames/NNNNNN.png`, then `session.json` (written to a
/// temporary name and renamed, so a reader never sees half a manifest). `manifest.frames` is
/// replaced by the frames written.
pub fn write_session(
    dir: &Path,
    mut manifest: Manifest,
    frames: &[Frame],
) -> Result<(), SessionError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SessionError::Io { path, source }
    };
    let frames_dir = dir.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(io(&frames_dir))?;
    manifest.frames.clear();
    for (i, frame) in frames.iter().enumerate() {
        let file = format!("frames/{i:06}.png");
        frames::write_png(&dir.join(&file), frame)?;
        manifest.frames.push(FrameJson {
            file,
            time_s: frame.time_s,
            pattern_index: frame.pattern_index,
        });
    }
    Ok(jsonfile::write_atomic(
        &dir.join("session.json"),
        &manifest,
    )?)
}

/// The manifest entries of `entries` within a pattern section of `axis` and `x_max`.
pub fn entries_json(entries: &[SessionEntry], axis: Axis, x_max: f64) -> Vec<EntryJson> {
    entries
        .iter()
        .map(|e| EntryJson::from_entry(e, axis, x_max))
        .collect()
}
