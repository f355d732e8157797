//! One session of a `batch` run: its rows of the study table and its outputs, or its error.
//!
//! The outputs go to `RESULTS/sessions/<the session's path in the study>/`: `analysis.json` and
//! `report.png` as `analyze` writes them, `trial.c3d` (the control points in the table frame),
//! with `--bids` the trial's Motion-BIDS files, and last `rows.csv`, the session's rows of the
//! study table. `rows.csv` marks the session done: a later run skips the session while that
//! file is newer than every file of the session, and reads its rows back. A failed session
//! writes only `rows.csv` (its error row), so it too is skipped until its inputs change or
//! `--force`; the error is the same until then.

use crate::export_cmd::ControlPoints;
use crate::point_analysis::{analyze_tracks, PointOutcome};
use crate::session_tracking::{track_session, Feedback};
use crate::unwrap_args::UnwrapArgs;
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tremorscan::decode::{frames_averaged, DecodeParams};
use tremorscan::export::bids::{self, BidsName};
use tremorscan::session::{Manifest, Session, TrialJson};
use tremorscan::study::{self, StudyRow};

/// What one worker is asked to do.
pub struct SessionJob<'a> {
    pub study: &'a Path,
    /// The session's folder relative to the study folder.
    pub relative: &'a Path,
    pub results: &'a Path,
    pub extra_points: &'a [(f64, f64)],
    pub unwrap: &'a UnwrapArgs,
    /// Follow the skin or keep fixed pixels.
    pub mode: tremorscan::tremor::PointMode,
    pub bids: Option<&'a Path>,
    /// The session's BIDS run number (`bids_runs`).
    pub bids_run: Option<u32>,
    pub force: bool,
    pub software_version: &'a str,
    /// Set on Ctrl-C: the session stops between frames and is not marked done.
    pub stop: &'a std::sync::atomic::AtomicBool,
}

/// What came of one session.
#[derive(Debug, Clone)]
pub struct SessionOutputs {
    pub rows: Vec<StudyRow>,
    /// Its outputs were up to date, so it was not processed again.
    pub skipped: bool,
    /// Why the session failed as a whole.
    pub error: Option<String>,
}

/// The folder a session's outputs go to.
pub fn outputs_dir(results: &Path, relative: &Path) -> PathBuf {
    results.join("sessions").join(relative)
}

/// Each session's BIDS run number: its rank, in study order, among the sessions with the same
/// subject, task and hand. The same in every shard, since every shard sees the whole list.
/// Sessions whose manifest cannot be read get none (they fail anyway).
pub fn bids_runs(study_dir: &Path, sessions: &[PathBuf]) -> BTreeMap<PathBuf, u32> {
    let mut counts: BTreeMap<(String, String, Option<String>), u32> = BTreeMap::new();
    let mut runs = BTreeMap::new();
    for relative in sessions {
        let path = study_dir.join(relative).join("session.json");
        let Ok(manifest) = tremorscan::jsonfile::read::<Manifest>(&path) else {
            continue;
        };
        let trial = manifest.trial.unwrap_or_default();
        let Ok(name) = BidsName::of(&trial, 1) else {
            continue;
        };
        let n = counts
            .entry((name.subject, name.task, name.acquisition))
            .or_insert(0);
        *n += 1;
        runs.insert(relative.clone(), *n);
    }
    runs
}

/// Processes one session (or reads back its rows when up to date). Never fails: a failure is
/// the session's error row.
pub fn process_session(job: &SessionJob<'_>) -> SessionOutputs {
    let dir = outputs_dir(job.results, job.relative);
    let rows_csv = dir.join("rows.csv");
    let session_dir = job.study.join(job.relative);
    if !job.force {
        if let Some(done) = up_to_date(job, &session_dir, &rows_csv) {
            return done;
        }
    }
    let (rows, error) = match analyse(job, &session_dir, &dir) {
        Ok(rows) => (rows, None),
        // Interrupted: nothing marks the session as done, so the next run does it.
        Err(_) if job.stop.load(std::sync::atomic::Ordering::Relaxed) => {
            return SessionOutputs {
                rows: Vec::new(),
                skipped: false,
                error: Some("interrupted".into()),
            };
        }
        Err(e) => {
            let why = format!("{e:#}");
            let trial = tremorscan::jsonfile::read::<Manifest>(&session_dir.join("session.json"))
                .ok()
                .and_then(|m| m.trial)
                .unwrap_or_default();
            let row = StudyRow {
                error: why.clone(),
                ..metadata_row(job, &trial)
            };
            (vec![row], Some(why))
        }
    };
    // The rows last: they mark the session as done. Failing to write them is the session's
    // error too (the table still gets the rows).
    let written = std::fs::create_dir_all(&dir)
        .map_err(anyhow::Error::from)
        .and_then(|()| study::write_table(&rows_csv, &rows).map_err(anyhow::Error::from));
    match written {
        Ok(()) => SessionOutputs {
            rows,
            skipped: false,
            error,
        },
        Err(e) => {
            let why = format!("writing {}: {e:#}", rows_csv.display());
            let rows = rows
                .into_iter()
                .map(|r| StudyRow {
                    error: if r.error.is_empty() {
                        why.clone()
                    } else {
                        r.error
                    },
                    ..r
                })
                .collect();
            SessionOutputs {
                rows,
                skipped: false,
                error: Some(why),
            }
        }
    }
}

/// The session's outputs when they are newer than its inputs: its rows, read back. A session
/// that failed needs only its rows; one that did not, with `--bids`, its BIDS motion file too.
fn up_to_date(job: &SessionJob<'_>, session_dir: &Path, rows_csv: &Path) -> Option<SessionOutputs> {
    if !study::is_fresh(session_dir, &[rows_csv.to_path_buf()]).ok()? {
        return None;
    }
    let rows = study::read_table(rows_csv).ok()?;
    let error = rows
        .iter()
        .find(|r| r.point.is_empty())
        .map(|r| r.error.clone());
    if error.is_none() {
        if let Some(root) = job.bids {
            let file = root.join(bids_motion_file(job)?);
            if !study::is_fresh(session_dir, &[file]).ok()? {
                return None;
            }
        }
    }
    Some(SessionOutputs {
        rows,
        skipped: true,
        error,
    })
}

/// The session's BIDS motion file, relative to the BIDS root, if it can have one.
fn bids_motion_file(job: &SessionJob<'_>) -> Option<PathBuf> {
    let manifest =
        tremorscan::jsonfile::read::<Manifest>(&job.study.join(job.relative).join("session.json"))
            .ok()?;
    let name = BidsName::of(&manifest.trial.unwrap_or_default(), job.bids_run?).ok()?;
    Some(
        name.folder()
            .join(format!("{}_motion.tsv", name.motion_stem())),
    )
}

/// The row's metadata columns for `trial`.
fn metadata_row(job: &SessionJob<'_>, trial: &TrialJson) -> StudyRow {
    StudyRow {
        session: job.relative.display().to_string(),
        subject: trial.subject_id.clone(),
        hand: trial.hand.clone(),
        condition: trial.condition.clone(),
        date: trial.date.clone(),
        operator_notes: trial.operator_notes.clone(),
        software_version: job.software_version.to_string(),
        ..StudyRow::default()
    }
}

/// Tracks, analyses and writes one session's outputs; returns its rows.
fn analyse(job: &SessionJob<'_>, session_dir: &Path, dir: &Path) -> Result<Vec<StudyRow>> {
    let session = Session::open(session_dir)?;
    let trial = session.manifest.trial.clone().unwrap_or_default();
    let ControlPoints { names, pixels } = ControlPoints::of(&trial, job.extra_points)?;
    let decoding = job
        .unwrap
        .session_decoding(&session, DecodeParams::default())?;
    let params = decoding.params;
    let tracked = track_session(
        &session,
        &pixels,
        job.mode,
        None,
        params,
        Feedback::Quiet { stop: job.stop },
    )?;
    let outcomes = analyze_tracks(
        frames_averaged(&session.sequence()?, &params),
        &tracked.tracks,
        &tracked.axis,
        &names,
        &pixels,
        tremorscan::tremor::DisplacementAxis::Vertical,
    )?;

    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let objects: Vec<serde_json::Value> = outcomes.iter().map(|o| o.json(&tracked.axis)).collect();
    tremorscan::jsonfile::write_atomic(&dir.join("analysis.json"), &objects)?;
    let figures: Vec<_> = outcomes.iter().map(PointOutcome::figure).collect();
    crate::report_png::write_report(&dir.join("report.png"), &figures)
        .with_context(|| format!("writing {}", dir.join("report.png").display()))?;
    let motion = tracked.motion(&names);
    tremorscan::export::c3d::write_c3d(&dir.join("trial.c3d"), &motion)?;
    if let Some(root) = job.bids {
        let run = job
            .bids_run
            .context("the session has no BIDS run number (its subject or condition is missing)")?;
        let name = BidsName::of(&trial, run).map_err(anyhow::Error::msg)?;
        bids::write_trial(root, &name, &trial, &motion, job.software_version)?;
    }

    Ok(outcomes
        .iter()
        .enumerate()
        .map(|(k, o)| point_row(job, &trial, k, o))
        .collect())
}

/// A point's row: its figures, or the reason they are missing.
fn point_row(job: &SessionJob<'_>, trial: &TrialJson, index: usize, o: &PointOutcome) -> StudyRow {
    let mut row = StudyRow {
        point: o.name.clone(),
        point_index: index,
        u: Some(o.pixel.0),
        v: Some(o.pixel.1),
        ..metadata_row(job, trial)
    };
    match &o.report {
        Ok(r) => {
            row.valid_fraction = Some(r.valid_fraction);
            row.longest_gap_s = Some(r.longest_gap_s);
            row.duration_s = Some(r.duration_s);
            row.peak_frequency_hz = r.peak_frequency_hz;
            row.amplitude_peak_to_peak_mm = Some(r.amplitude_peak_to_peak_mm);
            row.amplitude_rms_mm = Some(r.amplitude_rms_mm);
            row.band_power_3_12_mm2 = Some(r.band_power_mm2);
            row.band_power_4_6_mm2 = Some(r.narrow_band_power_mm2);
            row.occupancy = Some(r.occupancy);
            row.frequency_stability_hz = r.frequency_stability_hz;
            row.updrs_amplitude_bin = Some(r.updrs_amplitude_bin);
            row.tetras_amplitude_rating = r.tetras_amplitude_rating.to_string();
            row.tremor_stability_index_hz = r.tremor_stability_index_hz;
            row.half_power_bandwidth_hz = r.half_power_bandwidth_hz;
            row.harmonic_relative_power = r.harmonic_relative_power;
            row.spectrum_3d_peak_hz = o.spectrum_3d_peak_hz;
            row.frequency_bands = r.frequency_bands.join("; ");
        }
        Err(why) => {
            let valid = o.displacement_mm.iter().filter(|d| d.is_some()).count();
            row.valid_fraction = Some(valid as f64 / o.displacement_mm.len().max(1) as f64);
            row.error = why.clone();
        }
    }
    row
}
