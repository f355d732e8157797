//! JSON files on disk: reading with the path of the field that does not fit (`camera.K[2]`),
//! and writing through a temporary file and a rename, so that a reader never sees half a file.

use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Errors of reading or writing a JSON file.
#[derive(Debug, thiserror::Error)]
pub enum JsonFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: field `{field}`: {message}")]
    Parse {
        path: PathBuf,
        field: String,
        message: String,
    },
}

/// Reads `path` into `T`.
pub fn read<T: DeserializeOwned>(path: &Path) -> Result<T, JsonFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| JsonFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut de = serde_json::Deserializer::from_str(&text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| JsonFileError::Parse {
        path: path.to_path_buf(),
        field: e.path().to_string(),
        message: e.inner().to_string(),
    })
}

/// Writes `value` as pretty JSON to `path` (via `path` + `.tmp` and a rename).
pub fn write_atomic<T: Serialize>(path: &Path, value: &T) -> Result<(), JsonFileError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| JsonFileError::Parse {
        path: path.to_path_buf(),
        field: String::new(),
        message: e.to_string(),
    })?;
    write_bytes_atomic(path, text.as_bytes())
}

/// Writes `bytes` to `path` via `path` + `.tmp` and a rename, so that a reader (or a run that
/// was interrupted) never sees half a file.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), JsonFileError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| JsonFileError::Io { path: p, source }
    };
    std::fs::write(&tmp, bytes).map_err(io(&tmp))?;
    std::fs::rename(&tmp, path).map_err(io(path))
}
