//! The calibration file (`cps-calibration/1`, JSON, see `docs/formats.md`): camera, projector,
//! extrinsics and colour in the same shapes as a session manifest, plus the date, the RMS
//! errors and the rig and pattern identity, and the colour file. Loading checks every field and names the one it
//! rejects; it never panics.

use super::geometric::GeometricCalibration;
use crate::color::CrossTalk;
use crate::geometry::{LensModel, Pose};
use crate::jsonfile::{self, JsonFileError};
use crate::session::manifest::{ColorJson, ExtrinsicsJson, FieldError, LensJson, PatternJson};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const CALIBRATION_FORMAT: &str = "cps-calibration/1";

/// Errors of reading and writing calibration files.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error(transparent)]
    Json(#[from] JsonFileError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: \"format\" is \"{found}\", expected \"{CALIBRATION_FORMAT}\"")]
    Format { path: PathBuf, found: String },
    #[error("{path}: {source}")]
    Field { path: PathBuf, source: FieldError },
    #[error("{path}: line {line}: {why}")]
    OpenCv {
        path: PathBuf,
        line: usize,
        why: String,
    },
    #[error("{path}: {why}")]
    OpenCvContent { path: PathBuf, why: String },
}

/// RMS reprojection errors, pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RmsJson {
    pub camera_px: f64,
    pub projector_px: f64,
    #[serde(default)]
    pub views: Vec<ViewRmsJson>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewRmsJson {
    pub view: usize,
    pub camera_px: f64,
    pub projector_px: f64,
}

/// The file as written on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    pub format: String,
    /// UTC date and time of the calibration, ISO 8601.
    pub created_utc: String,
    /// Free text naming the rig (camera and projector models, serials).
    #[serde(default)]
    pub rig: String,
    /// The pattern the rig was calibrated with, if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pattern: Option<PatternJson>,
    pub camera: LensJson,
    pub projector: LensJson,
    pub extrinsics: ExtrinsicsJson,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<ColorJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms: Option<RmsJson>,
}

/// A checked calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub camera: LensModel,
    pub projector: LensModel,
    pub projector_from_camera: Pose,
    pub cross_talk: Option<CrossTalk>,
}

impl CalibrationFile {
    /// The file for a geometric calibration, with the colour calibration if there is one.
    pub fn from_geometric(
        calib: &GeometricCalibration,
        cross_talk: Option<&CrossTalk>,
        rig: &str,
        pattern: Option<PatternJson>,
    ) -> Self {
        Self {
            format: CALIBRATION_FORMAT.to_string(),
            created_utc: utc_now_iso8601(),
            rig: rig.to_string(),
            pattern,
            camera: LensJson::from_lens(&calib.camera),
            projector: LensJson::from_lens(&calib.projector),
            extrinsics: ExtrinsicsJson::from_pose(&calib.projector_from_camera),
            color: cross_talk.map(ColorJson::from_cross_talk),
            rms: Some(RmsJson {
                camera_px: calib.camera_rms_px,
                projector_px: calib.projector_rms_px,
                views: calib
                    .views
                    .iter()
                    .map(|v| ViewRmsJson {
                        view: v.view,
                        camera_px: v.camera_rms_px,
                        projector_px: v.projector_rms_px,
                    })
                    .collect(),
            }),
        }
    }

    /// Reads and checks a calibration file.
    pub fn load(path: &Path) -> Result<(Self, Calibration), FileError> {
        let file: Self = read_json(path)?;
        if file.format != CALIBRATION_FORMAT {
            return Err(FileError::Format {
                path: path.to_path_buf(),
                found: file.format,
            });
        }
        let calibration = file.check().map_err(|source| FileError::Field {
            path: path.to_path_buf(),
            source,
        })?;
        Ok((file, calibration))
    }

    /// The checked calibration.
    pub fn check(&self) -> Result<Calibration, FieldError> {
        Ok(Calibration {
            camera: self.camera.to_lens("camera")?,
            projector: self.projector.to_lens("projector")?,
            projector_from_camera: self.extrinsics.to_pose("extrinsics")?,
            cross_talk: self
                .color
                .as_ref()
                .map(|c| c.to_cross_talk("color"))
                .transpose()?,
        })
    }

    /// Writes the file (to a temporary name, then renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), FileError> {
        write_json(path, self)
    }
}

/// The colour calibration file written by `tremorscan calibrate-color`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColourFile {
    #[serde(rename = "A")]
    pub a: [[f64; 3]; 3],
    pub b: [f64; 3],
    /// RMS of `c − (A·p + b)` over the samples, gray levels.
    pub rms_residual: f64,
}

impl ColourFile {
    pub fn new(cross_talk: &CrossTalk, rms_residual: f64) -> Self {
        let json = ColorJson::from_cross_talk(cross_talk);
        Self {
            a: json.a,
            b: json.b,
            rms_residual,
        }
    }

    /// Reads a colour file and checks its cross-talk.
    pub fn load(path: &Path) -> Result<(Self, CrossTalk), FileError> {
        let file: Self = read_json(path)?;
        let cross_talk = ColorJson {
            a: file.a,
            b: file.b,
        }
        .to_cross_talk("")
        .map_err(|source| FileError::Field {
            path: path.to_path_buf(),
            source,
        })?;
        Ok((file, cross_talk))
    }

    pub fn save(&self, path: &Path) -> Result<(), FileError> {
        write_json(path, self)
    }
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, FileError> {
    Ok(jsonfile::read(path)?)
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), FileError> {
    Ok(jsonfile::write_atomic(path, value)?)
}
/// The current UTC time as `YYYY-MM-DDTHH:MM:SSZ` (civil date from days since 1970, after
/// Howard Hinnant's well-known algorithm).
pub fn utc_now_iso8601() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}
