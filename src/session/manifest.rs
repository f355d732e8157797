//! The JSON shapes of `session.json` (`cps-session/1`, see `docs/formats.md`) and their checked
//! conversion into library types. Every check names the field it rejects, as a path such as
//! `camera.K[2]` or `pattern.sequence[4].red.m`.
//!
//! Unknown keys are ignored (serde's default), so other tools may add their own.

use crate::color::CrossTalk;
use crate::geometry::{Distortion, Intrinsics, LensModel, Pose};
use crate::pattern::{Axis, ChannelCode, PatternEntry};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The format tag of a session manifest.
pub const SESSION_FORMAT: &str = "cps-session/1";

/// A whole manifest, as written on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub pattern: PatternJson,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<ColorJson>,
    pub camera: LensJson,
    pub projector: LensJson,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extrinsics: Option<ExtrinsicsJson>,
    /// Listed frames (image files). A live recording lists none and names its container in
    /// `recording` instead.
    #[serde(default)]
    pub frames: Vec<FrameJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<RecordingJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trial: Option<TrialJson>,
    /// The camera's noise, gray levels (standard deviation per sample), when the recording
    /// states it; otherwise the decode measures it from the frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_noise_gray: Option<f64>,
}

impl Manifest {
    /// The manifest of a rig: its sequence, colour cross-talk and calibrated geometry, no frames.
    pub fn for_rig(
        sequence: &crate::pattern::PatternSequence,
        cross_talk: &CrossTalk,
        stereo: &crate::triangulate::StereoModel,
    ) -> Self {
        Self {
            format: SESSION_FORMAT.to_string(),
            pattern: PatternJson::from_sequence(sequence),
            color: Some(ColorJson::from_cross_talk(cross_talk)),
            camera: LensJson::from_lens(&stereo.camera),
            projector: LensJson::from_lens(&stereo.projector),
            extrinsics: Some(ExtrinsicsJson::from_pose(&stereo.projector_from_camera)),
            frames: Vec::new(),
            recording: None,
            trial: None,
            camera_noise_gray: None,
        }
    }
}

/// The container a live recording wrote its frames to (`frames.cpsr`, see `container`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingJson {
    pub file: String,
}

/// What a clinical trial recorded: who, which hand, under what condition, and the control points.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrialJson {
    #[serde(default)]
    pub subject_id: String,
    /// `left` or `right` (free text is kept as given).
    #[serde(default)]
    pub hand: String,
    /// E.g. `rest`, `posture`, `medication off`.
    #[serde(default)]
    pub condition: String,
    #[serde(default)]
    pub operator_notes: String,
    /// When the trial was recorded: RFC 3339 in UTC (`2026-12-03T11:30:05Z`), or empty when
    /// unknown.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub date: String,
    #[serde(default)]
    pub control_points: Vec<ControlPointJson>,
}

/// A control point, by the camera pixel it started at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlPointJson {
    pub name: String,
    pub u: f64,
    pub v: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatternJson {
    pub x_max: f64,
    pub axis: AxisJson,
    pub projector_bits: u32,
    pub sequence: Vec<EntryJson>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisJson {
    Columns,
    Rows,
    Diagonal,
}

impl From<AxisJson> for Axis {
    fn from(a: AxisJson) -> Self {
        match a {
            AxisJson::Columns => Axis::Columns,
            AxisJson::Rows => Axis::Rows,
            AxisJson::Diagonal => Axis::Diagonal,
        }
    }
}

impl From<Axis> for AxisJson {
    fn from(a: Axis) -> Self {
        match a {
            Axis::Columns => AxisJson::Columns,
            Axis::Rows => AxisJson::Rows,
            Axis::Diagonal => AxisJson::Diagonal,
        }
    }
}

/// One projected image: a gray or an RGB coding entry, or a constant colour. A coding entry may
/// override the pattern's axis and `x_max` (calibration captures code both axes in one session).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EntryJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gray: Option<ChannelJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub red: Option<ChannelJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub green: Option<ChannelJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blue: Option<ChannelJson>,
    /// Projector levels 0–255 of R, G and B, held over the whole image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constant: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<AxisJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_max: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ChannelJson {
    pub m: u32,
    pub shift_rad: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LensJson {
    pub width: usize,
    pub height: usize,
    #[serde(rename = "K", default, skip_serializing_if = "Option::is_none")]
    pub k: Option<[[f64; 3]; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dist: Option<Vec<f64>>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExtrinsicsJson {
    #[serde(rename = "R")]
    pub r: [[f64; 3]; 3],
    pub t_mm: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColorJson {
    #[serde(rename = "A")]
    pub a: [[f64; 3]; 3],
    pub b: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameJson {
    pub file: String,
    pub time_s: f64,
    pub pattern_index: usize,
}

/// A rejected field: its path and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {why}")]
pub struct FieldError {
    pub field: String,
    pub why: String,
}

fn reject(field: impl Into<String>, why: impl Into<String>) -> FieldError {
    FieldError {
        field: field.into(),
        why: why.into(),
    }
}

fn finite(field: &str, values: impl IntoIterator<Item = f64>) -> Result<(), FieldError> {
    if values.into_iter().all(f64::is_finite) {
        Ok(())
    } else {
        Err(reject(field, "holds a value that is not a finite number"))
    }
}

impl LensJson {
    pub fn from_lens(lens: &LensModel) -> Self {
        let (k, d) = (&lens.intrinsics, &lens.distortion);
        Self {
            width: lens.width,
            height: lens.height,
            k: Some([[k.fx, 0.0, k.cx], [0.0, k.fy, k.cy], [0.0, 0.0, 1.0]]),
            dist: Some(vec![d.k1, d.k2, d.p1, d.p2, d.k3]),
        }
    }

    /// The lens model; `name` is the field's path (`camera`, `projector`).
    pub fn to_lens(&self, name: &str) -> Result<LensModel, FieldError> {
        if self.width == 0 || self.height == 0 {
            return Err(reject(
                format!("{name}.width"),
                format!("size {}×{} is empty", self.width, self.height),
            ));
        }
        let k = self
            .k
            .ok_or_else(|| reject(format!("{name}.K"), "is missing"))?;
        finite(&format!("{name}.K"), k.iter().flatten().copied())?;
        if k[0][1] != 0.0 || k[1][0] != 0.0 || k[2] != [0.0, 0.0, 1.0] {
            return Err(reject(
                format!("{name}.K"),
                "must be [[fx,0,cx],[0,fy,cy],[0,0,1]] (no skew)",
            ));
        }
        if k[0][0] <= 0.0 || k[1][1] <= 0.0 {
            return Err(reject(
                format!("{name}.K"),
                "focal lengths fx and fy must be positive",
            ));
        }
        let dist = self
            .dist
            .as_ref()
            .ok_or_else(|| reject(format!("{name}.dist"), "is missing"))?;
        finite(&format!("{name}.dist"), dist.iter().copied())?;
        let d = match dist.as_slice() {
            [k1, k2, p1, p2] => [*k1, *k2, *p1, *p2, 0.0],
            [k1, k2, p1, p2, k3] => [*k1, *k2, *p1, *p2, *k3],
            other => {
                return Err(reject(
                    format!("{name}.dist"),
                    format!(
                        "needs 4 or 5 coefficients (k1, k2, p1, p2[, k3]), got {}",
                        other.len()
                    ),
                ))
            }
        };
        Ok(LensModel {
            width: self.width,
            height: self.height,
            intrinsics: Intrinsics {
                fx: k[0][0],
                fy: k[1][1],
                cx: k[0][2],
                cy: k[1][2],
            },
            distortion: Distortion {
                k1: d[0],
                k2: d[1],
                p1: d[2],
                p2: d[3],
                k3: d[4],
            },
        })
    }
}

impl ExtrinsicsJson {
    pub fn from_pose(pose: &Pose) -> Self {
        let r = &pose.rotation;
        let t = &pose.translation_mm;
        Self {
            r: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            t_mm: [t.x, t.y, t.z],
        }
    }

    /// `projector_from_camera`; R must be a rotation to 1e-6.
    pub fn to_pose(&self, name: &str) -> Result<Pose, FieldError> {
        finite(&format!("{name}.R"), self.r.iter().flatten().copied())?;
        finite(&format!("{name}.t_mm"), self.t_mm)?;
        let r = Matrix3::from_fn(|i, j| self.r[i][j]);
        let off = (r * r.transpose() - Matrix3::identity()).abs().max();
        if off > 1e-6 || r.determinant() < 0.0 {
            return Err(reject(
                format!("{name}.R"),
                format!(
                    "is not a rotation (RRᵀ differs from I by {off:.1e}, det {:.3})",
                    r.determinant()
                ),
            ));
        }
        Ok(Pose {
            rotation: r,
            translation_mm: Vector3::from(self.t_mm),
        })
    }
}

impl ColorJson {
    pub fn from_cross_talk(c: &CrossTalk) -> Self {
        Self {
            a: [
                [c.a[(0, 0)], c.a[(0, 1)], c.a[(0, 2)]],
                [c.a[(1, 0)], c.a[(1, 1)], c.a[(1, 2)]],
                [c.a[(2, 0)], c.a[(2, 1)], c.a[(2, 2)]],
            ],
            b: [c.b_gray.x, c.b_gray.y, c.b_gray.z],
        }
    }

    pub fn to_cross_talk(&self, name: &str) -> Result<CrossTalk, FieldError> {
        let field = |key: &str| {
            if name.is_empty() {
                key.to_string()
            } else {
                format!("{name}.{key}")
            }
        };
        finite(&field("A"), self.a.iter().flatten().copied())?;
        finite(&field("b"), self.b)?;
        let a = Matrix3::from_fn(|i, j| self.a[i][j]);
        if a.determinant().abs() < 1e-9 {
            return Err(reject(field("A"), "is singular"));
        }
        Ok(CrossTalk {
            a,
            b_gray: Vector3::from(self.b),
        })
    }
}

/// A checked sequence entry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SessionEntry {
    /// A coding pattern along `axis` with range `x_max`.
    Coding {
        axis: Axis,
        x_max: f64,
        entry: PatternEntry,
    },
    /// Constant projector levels (0–255) of R, G and B.
    Constant([f64; 3]),
}

impl SessionEntry {
    /// Every entry of a coding sequence.
    pub fn coding_entries(sequence: &crate::pattern::PatternSequence) -> Vec<SessionEntry> {
        sequence
            .entries
            .iter()
            .map(|&entry| SessionEntry::Coding {
                axis: sequence.axis,
                x_max: sequence.x_max,
                entry,
            })
            .collect()
    }
}

impl PatternJson {
    /// The pattern section of a session that projects `sequence` (and nothing else).
    pub fn from_sequence(sequence: &crate::pattern::PatternSequence) -> Self {
        Self {
            x_max: sequence.x_max,
            axis: sequence.axis.into(),
            projector_bits: sequence.projector_bits,
            sequence: SessionEntry::coding_entries(sequence)
                .iter()
                .map(|e| EntryJson::from_entry(e, sequence.axis, sequence.x_max))
                .collect(),
        }
    }
}

impl EntryJson {
    pub fn from_entry(entry: &SessionEntry, pattern_axis: Axis, pattern_x_max: f64) -> Self {
        let code = |c: ChannelCode| ChannelJson {
            m: c.m,
            shift_rad: c.shift_rad,
        };
        match *entry {
            SessionEntry::Constant(levels) => Self {
                constant: Some(levels),
                ..Self::default()
            },
            SessionEntry::Coding { axis, x_max, entry } => {
                let mut json = Self {
                    axis: (axis != pattern_axis).then_some(axis.into()),
                    x_max: (x_max != pattern_x_max).then_some(x_max),
                    ..Self::default()
                };
                match entry {
                    PatternEntry::Gray(g) => json.gray = Some(code(g)),
                    PatternEntry::Rgb { red, green, blue } => {
                        json.red = Some(code(red));
                        json.green = Some(code(green));
                        json.blue = Some(code(blue));
                    }
                }
                json
            }
        }
    }

    /// The checked entry at `pattern.sequence[index]`.
    pub fn to_entry(
        &self,
        index: usize,
        pattern: &PatternJson,
    ) -> Result<SessionEntry, FieldError> {
        let field = format!("pattern.sequence[{index}]");
        let code = |c: &ChannelJson, channel: &str| {
            if c.shift_rad.is_finite() {
                Ok(ChannelCode::new(c.m, c.shift_rad))
            } else {
                Err(reject(
                    format!("{field}.{channel}.shift_rad"),
                    "is not a finite number",
                ))
            }
        };
        let rgb = [&self.red, &self.green, &self.blue];
        let coding = match (&self.gray, rgb, &self.constant) {
            (None, [None, None, None], Some(levels)) => {
                if levels.iter().any(|l| !(0.0..=255.0).contains(l)) {
                    return Err(reject(format!("{field}.constant"), "levels must lie in 0–255"));
                }
                return Ok(SessionEntry::Constant(*levels));
            }
            (Some(g), [None, None, None], None) => PatternEntry::Gray(code(g, "gray")?),
            (None, [Some(r), Some(g), Some(b)], None) => PatternEntry::Rgb {
                red: code(r, "red")?,
                green: code(g, "green")?,
                blue: code(b, "blue")?,
            },
            _ => {
                return Err(reject(
                    field,
                    "needs exactly one of: \"gray\"; all of \"red\", \"green\", \"blue\"; or \"constant\"",
                ))
            }
        };
        let x_max = self.x_max.unwrap_or(pattern.x_max);
        if !(x_max.is_finite() && x_max > 0.0) {
            return Err(reject(
                format!("{field}.x_max"),
                format!("must be positive, got {x_max}"),
            ));
        }
        Ok(SessionEntry::Coding {
            axis: self.axis.unwrap_or(pattern.axis).into(),
            x_max,
            entry: coding,
        })
    }
}
