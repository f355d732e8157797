//! The study table, `study.csv`: a row per session and control point with the trial metadata,
//! every tremor figure, the valid share, the software version and an error column. A session that
//! failed has one row, with the error and empty figures; a point whose figures are missing (too
//! little measured) has its row with the reason in `error` and empty figures, never zeros.
//!
//! Rows are written with the `csv` crate (quoting as RFC 4180), sorted by session and then by the
//! point's order in the session, and atomically (a temporary name and a rename). A shard writes
//! `study-shard-I-of-N.csv`; [`merge_tables`] joins a complete set of those into `study.csv` and
//! refuses an incomplete or mixed set, naming what is missing.

use super::{io_error, StudyError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The study table's file name in the results folder.
pub const TABLE_FILE: &str = "study.csv";

/// One row of the study table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct StudyRow {
    /// The session folder, relative to the study folder.
    pub session: String,
    pub subject: String,
    pub hand: String,
    pub condition: String,
    pub date: String,
    pub operator_notes: String,
    /// The control point's name (empty on a session's error row).
    pub point: String,
    /// The order of the point in its session (0 on an error row).
    pub point_index: usize,
    pub u: Option<f64>,
    pub v: Option<f64>,
    pub valid_fraction: Option<f64>,
    pub longest_gap_s: Option<f64>,
    pub duration_s: Option<f64>,
    pub peak_frequency_hz: Option<f64>,
    pub amplitude_peak_to_peak_mm: Option<f64>,
    pub amplitude_rms_mm: Option<f64>,
    pub band_power_3_12_mm2: Option<f64>,
    pub band_power_4_6_mm2: Option<f64>,
    pub occupancy: Option<f64>,
    pub frequency_stability_hz: Option<f64>,
    pub updrs_amplitude_bin: Option<u8>,
    /// The TETRAS amplitude rating (`tremor::measures`; empty without figures).
    pub tetras_amplitude_rating: String,
    pub tremor_stability_index_hz: Option<f64>,
    pub half_power_bandwidth_hz: Option<f64>,
    pub harmonic_relative_power: Option<f64>,
    /// The peak of the three coordinates' summed spectrum.
    pub spectrum_3d_peak_hz: Option<f64>,
    /// The clinical band labels, joined with `; `.
    pub frequency_bands: String,
    pub software_version: String,
    /// Why the session or the point has no figures; empty when it has them.
    pub error: String,
}

/// The name of shard `index` of `count`'s table.
pub fn shard_table_name(index: usize, count: usize) -> String {
    format!("study-shard-{index}-of-{count}.csv")
}

/// Writes `rows` (sorted by session and point) to `path`, atomically.
pub fn write_table(path: &Path, rows: &[StudyRow]) -> Result<(), StudyError> {
    let mut sorted = rows.to_vec();
    sorted.sort_by(|a, b| {
        a.session
            .cmp(&b.session)
            .then(a.point_index.cmp(&b.point_index))
    });
    let table_error = |e: &dyn std::fmt::Display| StudyError::Table {
        path: path.to_path_buf(),
        why: e.to_string(),
    };
    // The header is written by hand, so an empty table has it too.
    let mut writer = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(Vec::new());
    writer
        .write_record(table_columns())
        .map_err(|e| table_error(&e))?;
    for row in &sorted {
        writer.serialize(row).map_err(|e| table_error(&e))?;
    }
    let bytes = writer.into_inner().map_err(|e| table_error(&e))?;
    crate::jsonfile::write_bytes_atomic(path, &bytes).map_err(|e| StudyError::Table {
        path: path.to_path_buf(),
        why: e.to_string(),
    })
}

/// The table's column names, in order.
pub fn table_columns() -> Vec<&'static str> {
    vec![
        "session",
        "subject",
        "hand",
        "condition",
        "date",
        "operator_notes",
        "point",
        "point_index",
        "u",
        "v",
        "valid_fraction",
        "longest_gap_s",
        "duration_s",
        "peak_frequency_hz",
        "amplitude_peak_to_peak_mm",
        "amplitude_rms_mm",
        "band_power_3_12_mm2",
        "band_power_4_6_mm2",
        "occupancy",
        "frequency_stability_hz",
        "updrs_amplitude_bin",
        "tetras_amplitude_rating",
        "tremor_stability_index_hz",
        "half_power_bandwidth_hz",
        "harmonic_relative_power",
        "spectrum_3d_peak_hz",
        "frequency_bands",
        "software_version",
        "error",
    ]
}

/// Reads a study table written by [`write_table`].
pub fn read_table(path: &Path) -> Result<Vec<StudyRow>, StudyError> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut reader = csv::Reader::from_reader(file);
    let header = reader
        .headers()
        .map_err(|e| StudyError::Table {
            path: path.to_path_buf(),
            why: e.to_string(),
        })?
        .clone();
    if header.iter().collect::<Vec<_>>() != table_columns() {
        return Err(StudyError::Table {
            path: path.to_path_buf(),
            why: "not a tremorscan study table (its columns differ)".into(),
        });
    }
    reader
        .deserialize()
        .enumerate()
        .map(|(k, row)| {
            row.map_err(|e| StudyError::Table {
                path: path.to_path_buf(),
                why: format!("row {}: {e}", k + 1),
            })
        })
        .collect()
}

/// Joins the shard tables in `results` into `study.csv` there. Every shard of one count must be
/// present, and no session may appear in two shards. Returns the number of rows.
pub fn merge_tables(results: &Path) -> Result<usize, StudyError> {
    let mut shards: Vec<(usize, usize, PathBuf)> = Vec::new();
    for entry in std::fs::read_dir(results).map_err(io_error(results))? {
        let entry = entry.map_err(io_error(results))?;
        let name = entry.file_name().to_string_lossy().to_string();
        let Some(rest) = name
            .strip_prefix("study-shard-")
            .and_then(|r| r.strip_suffix(".csv"))
        else {
            continue;
        };
        let parsed = rest
            .split_once("-of-")
            .and_then(|(i, n)| Some((i.parse::<usize>().ok()?, n.parse::<usize>().ok()?)));
        match parsed {
            Some((i, n)) if i < n => shards.push((i, n, entry.path())),
            _ => {
                return Err(StudyError::Merge(format!(
                    "{}: not a shard table name (study-shard-I-of-N.csv)",
                    entry.path().display()
                )))
            }
        }
    }
    let Some(&(_, count, _)) = shards.first() else {
        return Err(StudyError::Merge(format!(
            "{}: no shard tables (study-shard-I-of-N.csv) to merge",
            results.display()
        )));
    };
    if let Some((_, other, _)) = shards.iter().find(|s| s.1 != count) {
        return Err(StudyError::Merge(format!(
            "{}: shard tables of {count} and of {other} parts are mixed; remove the old ones",
            results.display()
        )));
    }
    let missing: Vec<String> = (0..count)
        .filter(|i| !shards.iter().any(|s| s.0 == *i))
        .map(|i| format!("{i}/{count}"))
        .collect();
    if !missing.is_empty() {
        return Err(StudyError::Merge(format!(
            "{}: shard(s) {} have not finished (no table yet); nothing was merged",
            results.display(),
            missing.join(", ")
        )));
    }
    let mut rows = Vec::new();
    let mut seen: std::collections::BTreeMap<String, usize> = Default::default();
    shards.sort();
    for (i, _, path) in &shards {
        for row in read_table(path)? {
            if let Some(j) = seen.get(&row.session).filter(|j| *j != i) {
                return Err(StudyError::Merge(format!(
                    "session {} is in shards {j} and {i}",
                    row.session
                )));
            }
            seen.insert(row.session.clone(), *i);
            rows.push(row);
        }
    }
    write_table(&results.join(TABLE_FILE), &rows)?;
    Ok(rows.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(session: &str, point_index: usize) -> StudyRow {
        StudyRow {
            session: session.into(),
            subject: "P-1".into(),
            condition: "rest, \"off\"".into(),
            point: format!("p{point_index}"),
            point_index,
            peak_frequency_hz: Some(5.25),
            updrs_amplitude_bin: Some(2),
            ..StudyRow::default()
        }
    }

    #[test]
    fn a_table_round_trips_sorted_with_empty_cells_for_missing_figures() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join(TABLE_FILE);
        let mut failed = row("a", 0);
        failed.error = "frames.cpsr: record 3 is damaged".into();
        failed.peak_frequency_hz = None;
        failed.updrs_amplitude_bin = None;
        let rows = vec![row("b", 1), row("b", 0), failed.clone()];
        write_table(&path, &rows).expect("written");
        let back = read_table(&path).expect("read");
        assert_eq!(back, vec![failed, row("b", 0), row("b", 1)]);
        let text = std::fs::read_to_string(&path).expect("text");
        assert!(text.starts_with(&table_columns().join(",")));
        // The missing figures are empty cells, not zeros.
        assert!(text.lines().nth(1).expect("row").contains(",,"));
        write_table(&path, &[]).expect("empty");
        assert!(read_table(&path).expect("read").is_empty());
    }

    #[test]
    fn shards_merge_only_when_all_are_there() {
        let dir = tempfile::tempdir().expect("temp dir");
        write_table(&dir.path().join(shard_table_name(0, 2)), &[row("a", 0)]).expect("0");
        let e = merge_tables(dir.path()).expect_err("shard 1 missing");
        assert!(e.to_string().contains("1/2"), "{e}");
        assert!(!dir.path().join(TABLE_FILE).exists());
        write_table(&dir.path().join(shard_table_name(1, 2)), &[row("b", 0)]).expect("1");
        assert_eq!(merge_tables(dir.path()).expect("merged"), 2);
        let merged = read_table(&dir.path().join(TABLE_FILE)).expect("read");
        assert_eq!(merged, vec![row("a", 0), row("b", 0)]);
        write_table(&dir.path().join(shard_table_name(0, 3)), &[row("c", 0)]).expect("stale");
        assert!(merge_tables(dir.path()).is_err());
    }
}
