//! Studies: many sessions processed as one. This module finds the sessions under a study folder
//! ([`find_sessions`]), splits them into deterministic shards for a cluster's array job
//! ([`shard`]), tells whether a session's outputs are newer than its inputs ([`is_fresh`]), and
//! reads, writes and merges the study table ([`table`]).
//!
//! A session is a folder holding `session.json`; the search does not descend into a session
//! (its frames and truth folders hold no sessions). Sessions are listed by their path relative
//! to the study folder, sorted, so every process that looks at the same study sees the same list
//! and shard `I/N` is the same set everywhere: the sessions whose index in that list is `I` modulo
//! `N` (round robin, so shards get a similar mix of long and short trials).

pub mod table;

pub use table::{merge_tables, read_table, write_table, StudyRow, TABLE_FILE};

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Errors of study handling.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {why}")]
    Table { path: PathBuf, why: String },
    #[error("shard `{0}`: expected I/N with 0 ≤ I < N, e.g. 3/10")]
    Shard(String),
    #[error("{0}")]
    Merge(String),
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> StudyError {
    let path = path.to_path_buf();
    move |source| StudyError::Io { path, source }
}

/// Every session folder under `root` (itself included), as paths relative to `root`, sorted.
pub fn find_sessions(root: &Path) -> Result<Vec<PathBuf>, StudyError> {
    let meta = std::fs::metadata(root).map_err(io_error(root))?;
    if !meta.is_dir() {
        return Err(StudyError::Io {
            path: root.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a folder"),
        });
    }
    let mut found = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        if dir.join("session.json").is_file() {
            let relative = dir.strip_prefix(root).unwrap_or(&dir).to_path_buf();
            found.push(relative);
            continue;
        }
        for entry in std::fs::read_dir(&dir).map_err(io_error(&dir))? {
            let entry = entry.map_err(io_error(&dir))?;
            // Symbolic links are not followed, so a link cannot make the search loop.
            if entry.file_type().map_err(io_error(&entry.path()))?.is_dir() {
                stack.push(entry.path());
            }
        }
    }
    found.sort();
    Ok(found)
}

/// A part of a study: shard `index` of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = StudyError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || StudyError::Shard(text.to_string());
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The sessions of `shard` among `sessions` (in the order [`find_sessions`] gives).
pub fn shard(sessions: &[PathBuf], shard: Shard) -> Vec<PathBuf> {
    sessions
        .iter()
        .enumerate()
        .filter(|(k, _)| k % shard.count == shard.index)
        .map(|(_, p)| p.clone())
        .collect()
}

/// The newest modification time of the files under `dir` (recursively), if any.
pub fn newest_modification(dir: &Path) -> Result<Option<SystemTime>, StudyError> {
    let mut newest: Option<SystemTime> = None;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).map_err(io_error(&d))? {
            let entry = entry.map_err(io_error(&d))?;
            let meta = entry.metadata().map_err(io_error(&entry.path()))?;
            if meta.is_dir() {
                stack.push(entry.path());
            } else {
                let t = meta.modified().map_err(io_error(&entry.path()))?;
                newest = Some(newest.map_or(t, |n| n.max(t)));
            }
        }
    }
    Ok(newest)
}

/// Whether every file of `outputs` exists and is newer than every file under `session`.
pub fn is_fresh(session: &Path, outputs: &[PathBuf]) -> Result<bool, StudyError> {
    let Some(input) = newest_modification(session)? else {
        return Ok(false);
    };
    for out in outputs {
        match std::fs::metadata(out).and_then(|m| m.modified()) {
            Ok(t) if t > input => {}
            _ => return Ok(false),
        }
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sessions_are_found_sorted_without_descending_into_one() {
        let dir = tempfile::tempdir().expect("temp dir");
        for s in ["b/s2", "a/s1", "a/s1/frames/nested", "c", "a/empty"] {
            std::fs::create_dir_all(dir.path().join(s)).expect("mkdir");
        }
        for s in ["b/s2", "a/s1", "a/s1/frames/nested", "c"] {
            std::fs::write(dir.path().join(s).join("session.json"), "{}").expect("write");
        }
        let found = find_sessions(dir.path()).expect("found");
        let names: Vec<String> = found.iter().map(|p| p.display().to_string()).collect();
        assert_eq!(names, ["a/s1", "b/s2", "c"]);
        assert!(find_sessions(&dir.path().join("missing")).is_err());
    }

    #[test]
    fn shards_partition_the_sessions() {
        let sessions: Vec<PathBuf> = (0..11).map(|k| PathBuf::from(format!("s{k:02}"))).collect();
        let mut all: Vec<PathBuf> = (0..4)
            .flat_map(|i| shard(&sessions, Shard { index: i, count: 4 }))
            .collect();
        all.sort();
        assert_eq!(all, sessions);
        assert_eq!(shard(&sessions, "1/4".parse().expect("shard")).len(), 3);
        for bad in ["4/4", "1", "a/3", "0/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn outputs_older_than_an_input_are_not_fresh() {
        let dir = tempfile::tempdir().expect("temp dir");
        let session = dir.path().join("s");
        std::fs::create_dir_all(session.join("frames")).expect("mkdir");
        std::fs::write(session.join("frames/0.png"), "x").expect("write");
        let out = dir.path().join("out.json");
        assert!(!is_fresh(&session, std::slice::from_ref(&out)).expect("checked"));
        std::thread::sleep(std::time::Duration::from_millis(20));
        std::fs::write(&out, "{}").expect("write");
        assert!(is_fresh(&session, std::slice::from_ref(&out)).expect("checked"));
        std::thread::sleep(std::time::Duration::from_millis(20));
        std::fs::write(session.join("frames/0.png"), "y").expect("write");
        assert!(!is_fresh(&session, &[out]).expect("checked"));
    }
}
