//! Motion-BIDS: a trial's control-point trajectories as a BIDS motion recording, in a dataset
//! that BIDS tools (and the official validator) read.
//!
//! One trial is written as (the spec's `motion` datatype, BIDS 1.10):
//!
//! ```text
//! sub-<subject>/motion/sub-<subject>_task-<task>_tracksys-cps[_acq-<hand>]_run-<n>_motion.tsv
//!                                                                        …_channels.tsv
//!                                                                        …_motion.json
//! sub-<subject>/motion/sub-<subject>_task-<task>[_acq-<hand>]_run-<n>_events.tsv
//! ```
//!
//! - `_motion.tsv` has no header: a row per sample, three columns (x, y, z, mm) per control
//!   point, `n/a` where the point was not measured.
//! - `_channels.tsv` names each column: `name`, `component` (x, y, z), `type` (POS),
//!   `tracked_point` (the control point's name), `units` (mm), `reference_frame`.
//! - `_motion.json` holds the sampling rate (the camera's), the effective rate, the counts and
//!   the tracking system; `_events.tsv` one event spanning the trial with its condition.
//!
//! Labels come from the trial metadata: subject id → `sub`, condition → `task`, hand → `acq`,
//! each made BIDS-safe by keeping ASCII letters and digits only (`P-017` → `P017`). A trial
//! without a subject id or condition is refused, since BIDS needs both. The top-level files
//! (`dataset_description.json`, `participants.tsv`, `README`) are written by
//! [`write_dataset_files`]. Every file is written atomically.

use super::motion::TrialMotion;
use super::{write_atomic, ExportError};
use crate::session::TrialJson;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The BIDS version the files follow.
pub const BIDS_VERSION: &str = "1.10.0";
/// The `tracksys` label of this scanner.
pub const TRACKSYS: &str = "cps";

/// A BIDS label: the ASCII letters and digits of `text`, in order.
pub fn bids_label(text: &str) -> String {
    text.chars().filter(char::is_ascii_alphanumeric).collect()
}

/// The entities of one trial's files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BidsName {
    pub subject: String,
    pub task: String,
    /// The hand, when the trial says which.
    pub acquisition: Option<String>,
    pub run: u32,
}

impl BidsName {
    /// The entities of `trial`'s files with run `run`; `Err` naming what is missing.
    pub fn of(trial: &TrialJson, run: u32) -> Result<Self, String> {
        let subject = bids_label(&trial.subject_id);
        if subject.is_empty() {
            return Err(format!(
                "the trial's subject id `{}` has no letters or digits, and BIDS needs a subject label",
                trial.subject_id
            ));
        }
        let task = bids_label(&trial.condition);
        if task.is_empty() {
            return Err(format!(
                "the trial's condition `{}` has no letters or digits, and BIDS needs a task label",
                trial.condition
            ));
        }
        let acquisition = Some(bids_label(&trial.hand)).filter(|a| !a.is_empty());
        Ok(Self {
            subject,
            task,
            acquisition,
            run,
        })
    }

    fn acq(&self) -> String {
        self.acquisition
            .as_ref()
            .map_or(String::new(), |a| format!("_acq-{a}"))
    }

    /// The folder the trial's files go in, relative to the dataset's root.
    pub fn folder(&self) -> PathBuf {
        PathBuf::from(format!("sub-{}", self.subject)).join("motion")
    }

    /// The stem of the motion files (`…_tracksys-cps…_run-n`).
    pub fn motion_stem(&self) -> String {
        format!(
            "sub-{}_task-{}_tracksys-{TRACKSYS}{}_run-{}",
            self.subject,
            self.task,
            self.acq(),
            self.run
        )
    }

    /// The stem of the events file (no `tracksys`: events belong to the trial).
    pub fn events_stem(&self) -> String {
        format!(
            "sub-{}_task-{}{}_run-{}",
            self.subject,
            self.task,
            self.acq(),
            self.run
        )
    }
}

/// The run number for `trial` under `root`: the lowest one whose motion file is not there yet.
pub fn next_free_run(root: &Path, trial: &TrialJson) -> Result<u32, String> {
    let mut run = 1;
    loop {
        let name = BidsName::of(trial, run)?;
        let file = root
            .join(name.folder())
            .join(format!("{}_motion.tsv", name.motion_stem()));
        if !file.exists() {
            return Ok(run);
        }
        run += 1;
    }
}

fn tsv_number(v: f64) -> String {
    format!("{v:.4}")
}

/// Writes one trial's motion, channels, sidecar and events files under `root`; returns the
/// motion TSV's path. `software_version` goes into the sidecar.
pub fn write_trial(
    root: &Path,
    name: &BidsName,
    trial: &TrialJson,
    motion: &TrialMotion,
    software_version: &str,
) -> Result<PathBuf, ExportError> {
    let folder = root.join(name.folder());
    let format_error = |why: String| ExportError::Format {
        path: folder.clone(),
        why,
    };
    motion.check().map_err(format_error)?;
    if motion.samples() == 0 {
        return Err(format_error("the trial has no samples".into()));
    }
    std::fs::create_dir_all(&folder).map_err(super::io_error(&folder))?;
    let stem = name.motion_stem();

    let mut rows = String::new();
    for k in 0..motion.samples() {
        let cells: Vec<String> = motion
            .points
            .iter()
            .flat_map(|p| match p.positions_mm[k] {
                Some(xyz) => xyz.map(tsv_number).to_vec(),
                None => vec!["n/a".to_string(); 3],
            })
            .collect();
        rows.push_str(&cells.join("\t"));
        rows.push('\n');
    }
    let motion_tsv = folder.join(format!("{stem}_motion.tsv"));
    write_atomic(&motion_tsv, rows.as_bytes())?;

    let mut channels =
        String::from("name\tcomponent\ttype\ttracked_point\tunits\treference_frame\n");
    for p in &motion.points {
        let point = p.name.replace(['\t', '\n', '\r'], " ");
        let label = bids_label(&p.name);
        for axis in ["x", "y", "z"] {
            channels.push_str(&format!(
                "{label}_{axis}\t{axis}\tPOS\t{point}\tmm\t{}\n",
                motion.frame.name()
            ));
        }
    }
    write_atomic(
        &folder.join(format!("{stem}_channels.tsv")),
        channels.as_bytes(),
    )?;

    let n = motion.points.len();
    let effective_hz = match (motion.times_s.first(), motion.times_s.last()) {
        (Some(a), Some(b)) if motion.samples() > 1 && b > a => {
            (motion.samples() - 1) as f64 / (b - a)
        }
        _ => motion.sampling_hz,
    };
    // The rate as the session's time stamps give it, to a microhertz (121.00000000000001 is
    // 121).
    let round = |hz: f64| (hz * 1e6).round() / 1e6;
    let mut sidecar = serde_json::json!({
        "TaskName": name.task,
        "TaskDescription": trial.condition,
        "SamplingFrequency": round(motion.sampling_hz),
        "SamplingFrequencyEffective": round(effective_hz),
        "RecordingType": "continuous",
        "RecordingDuration": motion.duration_s(),
        "TrackingSystemName": "tremorscan Chebyshev Phase Shifting structured light",
        "Manufacturer": "tremorscan",
        "SoftwareVersions": software_version,
        "MotionChannelCount": 3 * n,
        "POSChannelCount": 3 * n,
        "TrackedPointsCount": n,
        "MissingValues": "n/a",
    });
    if !trial.operator_notes.trim().is_empty() {
        sidecar["SubjectArtefactDescription"] = serde_json::json!(trial.operator_notes);
    }
    let sidecar_path = folder.join(format!("{stem}_motion.json"));
    let text = serde_json::to_string_pretty(&sidecar).map_err(|e| ExportError::Format {
        path: sidecar_path.clone(),
        why: e.to_string(),
    })?;
    write_atomic(&sidecar_path, text.as_bytes())?;

    let trial_type = if trial.condition.trim().is_empty() {
        "trial".to_string()
    } else {
        trial.condition.replace(['\t', '\n', '\r'], " ")
    };
    let events = format!(
        "onset\tduration\ttrial_type\n{}\t{}\t{trial_type}\n",
        tsv_number(0.0),
        tsv_number(motion.duration_s())
    );
    write_atomic(
        &folder.join(format!("{}_events.tsv", name.events_stem())),
        events.as_bytes(),
    )?;
    Ok(motion_tsv)
}

/// Writes (or rewrites) `dataset_description.json`, `README` and `participants.tsv` under
/// `root`. `participants.tsv` lists the subjects already in it and `subjects` (BIDS labels
/// without `sub-`), sorted.
pub fn write_dataset_files(
    root: &Path,
    subjects: &[String],
    software_version: &str,
) -> Result<(), ExportError> {
    std::fs::create_dir_all(root).map_err(super::io_error(root))?;
    let description = serde_json::json!({
        "Name": "tremorscan study",
        "BIDSVersion": BIDS_VERSION,
        "DatasetType": "raw",
        "GeneratedBy": [{ "Name": "tremorscan", "Version": software_version }],
    });
    let path = root.join("dataset_description.json");
    let text = serde_json::to_string_pretty(&description).map_err(|e| ExportError::Format {
        path: path.clone(),
        why: e.to_string(),
    })?;
    write_atomic(&path, text.as_bytes())?;
    let readme = "Control-point trajectories of hand tremor trials, measured by tremorscan \
                  (Chebyshev Phase Shifting structured light, one 3D position per camera frame).\n";
    write_atomic(&root.join("README"), readme.as_bytes())?;

    let participants = root.join("participants.tsv");
    let mut all: BTreeSet<String> = BTreeSet::new();
    if let Ok(text) = std::fs::read_to_string(&participants) {
        for line in text.lines().skip(1) {
            if let Some(id) = line.split('\t').next().and_then(|c| c.strip_prefix("sub-")) {
                all.insert(id.to_string());
            }
        }
    }
    all.extend(subjects.iter().cloned());
    let mut out = String::from("participant_id\n");
    for s in all {
        out.push_str(&format!("sub-{s}\n"));
    }
    write_atomic(&participants, out.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_keep_letters_and_digits_only() {
        assert_eq!(bids_label("P-017"), "P017");
        assert_eq!(bids_label("rest, medication off"), "restmedicationoff");
        assert_eq!(bids_label("--"), "");
    }

    #[test]
    fn a_trial_without_subject_or_condition_is_refused_by_name() {
        let mut trial = TrialJson {
            subject_id: "P-1".into(),
            condition: "rest".into(),
            hand: "left".into(),
            ..TrialJson::default()
        };
        let name = BidsName::of(&trial, 2).expect("a name");
        assert_eq!(
            name.motion_stem(),
            "sub-P1_task-rest_tracksys-cps_acq-left_run-2"
        );
        assert_eq!(name.events_stem(), "sub-P1_task-rest_acq-left_run-2");
        trial.condition = " ".into();
        assert!(BidsName::of(&trial, 1)
            .expect_err("no task")
            .contains("condition"));
        trial.condition = "rest".into();
        trial.subject_id = String::new();
        assert!(BidsName::of(&trial, 1)
            .expect_err("no subject")
            .contains("subject"));
    }

    #[test]
    fn a_trial_is_written_with_missing_samples_as_n_a_and_a_channel_per_axis() {
        use crate::export::{MotionFrame, PointTrack};
        let dir = tempfile::tempdir().expect("temp dir");
        let trial = TrialJson {
            subject_id: "P-7".into(),
            condition: "rest".into(),
            operator_notes: "moved at 1 s".into(),
            ..TrialJson::default()
        };
        let motion = TrialMotion {
            sampling_hz: 121.0,
            times_s: vec![0.0, 1.0 / 121.0, 2.0 / 121.0],
            points: vec![PointTrack {
                name: "index tip".into(),
                positions_mm: vec![Some([1.0, 2.0, 3.0]), None, Some([1.5, 2.5, -3.25])],
            }],
            frame: MotionFrame::Table,
        };
        let run = next_free_run(dir.path(), &trial).expect("run");
        assert_eq!(run, 1);
        let name = BidsName::of(&trial, run).expect("name");
        let tsv = write_trial(dir.path(), &name, &trial, &motion, "test").expect("written");
        assert_eq!(
            std::fs::read_to_string(&tsv).expect("tsv"),
            "1.0000\t2.0000\t3.0000\nn/a\tn/a\tn/a\n1.5000\t2.5000\t-3.2500\n"
        );
        let folder = dir.path().join("sub-P7/motion");
        let channels = std::fs::read_to_string(
            folder.join("sub-P7_task-rest_tracksys-cps_run-1_channels.tsv"),
        )
        .expect("channels");
        assert_eq!(channels.lines().count(), 4);
        assert!(channels.contains("indextip_z\tz\tPOS\tindex tip\tmm\ttable"));
        let sidecar: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(
                folder.join("sub-P7_task-rest_tracksys-cps_run-1_motion.json"),
            )
            .expect("sidecar"),
        )
        .expect("json");
        assert_eq!(sidecar["SamplingFrequency"], 121.0);
        assert_eq!(sidecar["POSChannelCount"], 3);
        assert_eq!(sidecar["SubjectArtefactDescription"], "moved at 1 s");
        assert!(folder.join("sub-P7_task-rest_run-1_events.tsv").is_file());
        // The next trial of the same subject and task takes run 2.
        assert_eq!(next_free_run(dir.path(), &trial).expect("run"), 2);
        write_dataset_files(dir.path(), &["P7".into()], "test").expect("top level");
        write_dataset_files(dir.path(), &["P1".into()], "test").expect("top level again");
        assert_eq!(
            std::fs::read_to_string(dir.path().join("participants.tsv")).expect("tsv"),
            "participant_id\nsub-P1\nsub-P7\n"
        );
    }
}
