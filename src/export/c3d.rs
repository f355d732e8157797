//! C3D (the biomechanics standard that Visual3D, Mokka and OpenSim's importers read): a trial's
//! control points as markers, one frame per sample, in mm.
//!
//! Layout (C3D user guide, c3d.org; Intel byte order, 512-byte blocks):
//!
//! - **Header** (block 1): parameters start at block 2 (`0x50` key), the marker count, frames
//!   1 to N, `POINT:SCALE` = −1 (negative: the data are 32-bit floats), the data's first block and
//!   the frame rate. No analog channels.
//! - **Parameters** (blocks 2…): groups `POINT` (`USED`, `SCALE`, `RATE`, `DATA_START`, `FRAMES`,
//!   `UNITS` = `mm`, `LABELS` the control points' names made unique, `DESCRIPTIONS` the frame the
//!   positions are in), `ANALOG` (`USED` = 0, `RATE`) and `MANUFACTURER`. Each record's offset
//!   points at the next one; the last record's offset is 0.
//! - **Data**: per frame, per marker, `x y z` and a fourth word: 0.0 for a measured sample, −1.0
//!   (negative: "invalid" in every C3D reader) for one that was not; its coordinates are 0.
//!
//! Why not `c3dio` for writing: its 0.8.0 writer leaves out the description-length byte of
//! group records, writes 0 as the parameter section's first byte and no `POINT:RATE`,
//! `POINT:SCALE` or `POINT:DATA_START`, and cannot write a negative fourth word in the float
//! format, so ezc3d refuses its files and a missing sample would read as a marker at the origin.
//! `c3dio` is still used, in the tests, as a reader of what this writes; ezc3d reads it too
//! (`tests/study_exports.rs`). The file is written to a temporary name and renamed.

use super::motion::TrialMotion;
use super::{write_atomic, ExportError};
use std::path::Path;

const BLOCK: usize = 512;

/// One parameter's value.
enum Value<'a> {
    Int(i16),
    Float(f32),
    /// A string, as a 1-D character array.
    Text(&'a str),
    /// Strings of one length (padded with spaces), as a 2-D character array.
    Texts(&'a [String]),
}

/// The parameter section's records, written in order.
struct Parameters {
    bytes: Vec<u8>,
    /// Where the last record's offset field is, to write 0 there at the end.
    last_offset_at: Option<usize>,
}

impl Parameters {
    fn new() -> Self {
        // First byte: the first record starts right after these 4 bytes (byte 1 of 512); then
        // the key, the block count (set at the end) and the processor (84: Intel).
        Self {
            bytes: vec![1, 0x50, 0, 84],
            last_offset_at: None,
        }
    }

    fn record(&mut self, name: &str, id: i8, body: &[u8], description: &str) {
        let description = &description.as_bytes()[..description.len().min(127)];
        self.bytes.push(name.len() as u8);
        self.bytes.push(id as u8);
        self.bytes.extend(name.as_bytes());
        let offset_at = self.bytes.len();
        // From the offset field to the next record: itself, the body, the description.
        let offset = 2 + body.len() + 1 + description.len();
        self.bytes.extend((offset as u16).to_le_bytes());
        self.bytes.extend(body);
        self.bytes.push(description.len() as u8);
        self.bytes.extend(description);
        self.last_offset_at = Some(offset_at);
    }

    fn group(&mut self, name: &str, id: i8, description: &str) {
        self.record(name, -id, &[], description);
    }

    fn parameter(&mut self, group: i8, name: &str, value: Value<'_>) {
        let mut body = Vec::new();
        match value {
            Value::Int(v) => {
                body.extend([2, 0]);
                body.extend(v.to_le_bytes());
            }
            Value::Float(v) => {
                body.extend([4, 0]);
                body.extend(v.to_le_bytes());
            }
            Value::Text(s) => {
                body.extend([0xFF, 1, s.len() as u8]);
                body.extend(s.as_bytes());
            }
            Value::Texts(list) => {
                let width = list.iter().map(String::len).max().unwrap_or(1).max(1);
                body.extend([0xFF, 2, width as u8, list.len() as u8]);
                for s in list {
                    body.extend(format!("{s:<width$}").as_bytes());
                }
            }
        }
        self.record(name, group, &body, "");
    }

    /// The section padded to whole blocks, the last record's offset 0.
    fn finish(mut self) -> Vec<u8> {
        if let Some(at) = self.last_offset_at {
            self.bytes[at..at + 2].copy_from_slice(&[0, 0]);
        }
        let blocks = self.bytes.len().div_ceil(BLOCK);
        self.bytes[2] = blocks as u8;
        self.bytes.resize(blocks * BLOCK, 0);
        self.bytes
    }
}

/// Text for a C3D character parameter: printable ASCII only, at most `max` characters.
fn ascii(text: &str, max: usize) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c
            } else {
                '_'
            }
        })
        .take(max)
        .collect()
}

/// The markers' labels: each control point's name (or `P<k>`), unique, at most 30 characters.
fn unique_labels(motion: &TrialMotion) -> Vec<String> {
    let mut labels: Vec<String> = Vec::new();
    for (k, p) in motion.points.iter().enumerate() {
        let base: String = p
            .name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .take(24)
            .collect();
        let base = if base.is_empty() {
            format!("P{k}")
        } else {
            base
        };
        let mut label = base.clone();
        let mut n = 2;
        while labels.contains(&label) {
            label = format!("{base}_{n}");
            n += 1;
        }
        labels.push(label);
    }
    labels
}

/// Writes `motion` as a C3D file at `path`. Returns the number of frames written.
pub fn write_c3d(path: &Path, motion: &TrialMotion) -> Result<usize, ExportError> {
    let format_error = |why: String| ExportError::Format {
        path: path.to_path_buf(),
        why,
    };
    motion.check().map_err(format_error)?;
    let frames = motion.samples();
    let markers = motion.points.len();
    if frames == 0 {
        return Err(format_error("the trial has no samples".into()));
    }
    if frames > usize::from(u16::MAX) {
        return Err(format_error(format!(
            "{frames} frames: a C3D header counts at most {} (9 minutes at 121 Hz)",
            u16::MAX
        )));
    }
    if markers > 255 {
        return Err(format_error(format!(
            "{markers} control points: at most 255 fit a C3D label list"
        )));
    }
    let rate = motion.sampling_hz as f32;
    let labels = unique_labels(motion);
    let descriptions = vec![ascii(motion.frame.description(), 127); markers];

    // The parameter section's size does not depend on DATA_START's value, so build it once
    // to learn its length, then with the right value.
    let section = |data_start: u16| {
        let mut p = Parameters::new();
        p.group("POINT", 1, "3D points");
        p.group("ANALOG", 2, "analog channels (none)");
        p.group("MANUFACTURER", 3, "software that wrote the file");
        p.parameter(1, "USED", Value::Int(markers as i16));
        p.parameter(1, "SCALE", Value::Float(-1.0));
        p.parameter(1, "RATE", Value::Float(rate));
        p.parameter(1, "DATA_START", Value::Int(data_start as i16));
        // Stored as 16 bits and read as unsigned by C3D readers.
        p.parameter(1, "FRAMES", Value::Int(frames as u16 as i16));
        p.parameter(1, "UNITS", Value::Text("mm"));
        p.parameter(1, "LABELS", Value::Texts(&labels));
        p.parameter(1, "DESCRIPTIONS", Value::Texts(&descriptions));
        p.parameter(2, "USED", Value::Int(0));
        p.parameter(2, "RATE", Value::Float(rate));
        p.parameter(3, "COMPANY", Value::Text("tremorscan"));
        p.parameter(3, "SOFTWARE", Value::Text("tremorscan"));
        p.parameter(3, "VERSION_LABEL", Value::Text(env!("CARGO_PKG_VERSION")));
        p.finish()
    };
    let blocks = section(0).len() / BLOCK;
    let data_start = 2 + blocks;
    let parameters = section(data_start as u16);

    let mut header = vec![0u8; BLOCK];
    let mut word = |index: usize, bytes: &[u8]| {
        header[2 * index..2 * index + bytes.len()].copy_from_slice(bytes);
    };
    word(0, &[2, 0x50]);
    word(1, &(markers as u16).to_le_bytes());
    word(2, &0u16.to_le_bytes());
    word(3, &1u16.to_le_bytes());
    word(4, &(frames as u16).to_le_bytes());
    word(5, &0u16.to_le_bytes());
    word(6, &(-1.0f32).to_le_bytes());
    word(8, &(data_start as u16).to_le_bytes());
    word(9, &0u16.to_le_bytes());
    word(10, &rate.to_le_bytes());

    let mut bytes = header;
    bytes.extend(parameters);
    debug_assert_eq!(bytes.len(), (data_start - 1) * BLOCK);
    bytes.reserve(frames * markers * 16 + BLOCK);
    for k in 0..frames {
        for p in &motion.points {
            let (xyz, residual) = match p.positions_mm[k] {
                Some(xyz) => (xyz.map(|v| v as f32), 0.0f32),
                None => ([0.0; 3], -1.0),
            };
            for v in xyz {
                bytes.extend(v.to_le_bytes());
            }
            bytes.extend(residual.to_le_bytes());
        }
    }
    bytes.resize(bytes.len().div_ceil(BLOCK) * BLOCK, 0);
    write_atomic(path, &bytes)?;
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::{MotionFrame, PointTrack};
    use c3dio::prelude::C3d;

    fn motion() -> TrialMotion {
        TrialMotion {
            sampling_hz: 121.0,
            times_s: (0..50).map(|k| k as f64 / 121.0).collect(),
            points: ["index tip", "index tip", "wrist"]
                .iter()
                .enumerate()
                .map(|(m, name)| PointTrack {
                    name: (*name).into(),
                    positions_mm: (0..50)
                        .map(|k| {
                            (k % 7 != m)
                                .then(|| [k as f64 * 0.5, -(m as f64) * 10.0, 600.25 + k as f64])
                        })
                        .collect(),
                })
                .collect(),
            frame: MotionFrame::Table,
        }
    }

    #[test]
    fn an_independent_reader_reads_back_every_sample_and_the_missing_ones_as_missing() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("trial.c3d");
        let m = motion();
        assert_eq!(write_c3d(&path, &m).expect("written"), 50);
        let back = C3d::load_path(path.clone()).expect("c3dio reads it back");
        assert_eq!(back.points.labels, ["index_tip", "index_tip_2", "wrist"]);
        assert_eq!(back.points.rows(), 50);
        assert_eq!(back.points.units, ['m', 'm', ' ', ' ']);
        assert!((back.points.frame_rate - 121.0).abs() < 1e-4);
        let mut missing = 0;
        for k in 0..50 {
            for (j, p) in m.points.iter().enumerate() {
                let marker = back.points[k][j];
                match p.positions_mm[k] {
                    Some(xyz) => {
                        for a in 0..3 {
                            assert_eq!(marker[a], xyz[a] as f32, "frame {k} marker {j}");
                        }
                        assert!(marker.residual >= 0.0);
                    }
                    None => {
                        missing += 1;
                        assert!(marker.residual < 0.0, "frame {k} marker {j}: {marker:?}");
                    }
                }
            }
        }
        assert!(missing > 10);
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    #[test]
    fn an_empty_or_inconsistent_trial_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut empty = motion();
        empty.times_s.clear();
        for p in &mut empty.points {
            p.positions_mm.clear();
        }
        assert!(write_c3d(&dir.path().join("t.c3d"), &empty).is_err());
        let mut short = motion();
        short.points[1].positions_mm.pop();
        let e = write_c3d(&dir.path().join("t.c3d"), &short).expect_err("refused");
        assert!(e.to_string().contains("index tip"), "{e}");
    }
}
