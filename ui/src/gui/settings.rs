//! Settings that persist between runs: the device, the virtual rig's image size, the pattern
//! parameters, the unwrapping method and where the decode runs, the trial defaults and the folders last used. Stored as
//! JSON in `$XDG_CONFIG_HOME/tremorscan/settings.json` (or `~/.config/…`), written atomically
//! when the app closes or a setting changes. An unreadable file is reported and replaced by
//! defaults; it is never a reason not to start.

use crate::gpu_decode::DecoderChoice;
use crate::unwrap_args::CoarseAverageArg;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tremorscan::decode::{DecodeParams, UnwrapMethod};

/// Where frames come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum DeviceChoice {
    VirtualRig,
    Replay {
        session: PathBuf,
    },
    /// A GenICam camera (feature `genicam`) with a second screen as the projector, synced in
    /// software. Needs the rig's calibration files.
    Camera {
        /// Aravis device id; empty: the first camera found.
        camera_id: String,
        exposure_micros: f64,
        /// Monitor of the projector screen, in the system's order (0 is usually the main one).
        monitor: usize,
        /// Screen refreshes each pattern stays.
        hold_refreshes: u32,
        /// What projects: a plain screen, or a LightCrafter 4500 fed by that screen output.
        #[serde(default)]
        projector: ProjectorKind,
        /// The camera's binning, the same factor across and down (1: none). 2 leaves a quarter
        /// of the pixels to decode (`tremorscan bench` says which factor this PC needs); the
        /// calibration must be made at the same binning.
        #[serde(default = "no_binning")]
        binning: u32,
    },
}

fn no_binning() -> u32 {
    1
}

/// The projector of a camera rig.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectorKind {
    /// Any screen; the camera runs free and frames are labelled by time.
    #[default]
    SecondScreen,
    /// A LightCrafter 4500 (feature `lightcrafter`) on that video output: programmed over USB for
    /// CPS-RGB at 6 bits, it triggers the camera once per image (wire its trigger out 1 to the
    /// camera's Line1); the screen output carries one packed image per refresh.
    LightCrafter,
}

impl DeviceChoice {
    /// The camera device with its defaults: 5 ms exposure, the second monitor, 2 refreshes per
    /// pattern (30 patterns/s on a 60 Hz screen).
    pub fn default_camera() -> Self {
        DeviceChoice::Camera {
            camera_id: String::new(),
            exposure_micros: 5000.0,
            monitor: 1,
            hold_refreshes: 2,
            projector: ProjectorKind::SecondScreen,
            binning: 1,
        }
    }
}

/// Unwrapping method, as stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnwrapChoice {
    PerPixel,
    Robust,
}

impl UnwrapChoice {
    pub fn method(self) -> UnwrapMethod {
        match self {
            UnwrapChoice::PerPixel => UnwrapMethod::ChebyshevPerPixel,
            UnwrapChoice::Robust => UnwrapMethod::ChebyshevRobust,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    pub device: DeviceChoice,
    /// Virtual rig camera image, pixels.
    pub rig_width: usize,
    pub rig_height: usize,
    /// The virtual hand's tremor: peak fingertip flexion along the optical axis, mm; peak
    /// sideways sway of the whole hand, mm; peak roll about the forearm, degrees.
    pub rig_tip_amplitude_mm: f64,
    pub rig_sway_mm: f64,
    pub rig_roll_deg: f64,
    /// Highest fringe count n of the CPS-RGB sequence (n, n−1, n−2).
    pub fringe_count: u32,
    /// Coded projector axis: columns (true) or rows.
    pub code_columns: bool,
    /// Projector bit depth per channel.
    pub projector_bits: u32,
    pub unwrap: UnwrapChoice,
    /// How the robust unwrap averages the coarse phase (`--coarse-average`).
    pub coarse_average: CoarseAverageArg,
    /// Where the decode runs: a hardware GPU when there is one (`auto`), the CPU, or the GPU.
    pub decoder: DecoderChoice,
    /// Folder new trials are recorded into.
    pub sessions_dir: PathBuf,
    pub trial_seconds: f64,
    pub countdown_seconds: f64,
    /// Where the last export went.
    pub export_dir: PathBuf,
    /// Calibration files in use (none: the rig's own exact calibration).
    pub calibration_file: Option<PathBuf>,
    pub colour_file: Option<PathBuf>,
    /// Point size in the 3D view, pixels.
    pub point_size_px: f32,
}

fn home() -> PathBuf {
    std::env::var_os("HOME").map_or_else(|| PathBuf::from("."), PathBuf::from)
}

impl Settings {
    /// How these settings decode: the unwrap method and the coarse average chosen, the rest as
    /// the library's defaults (a replay then follows its session, `session::decoding`).
    pub fn decode_params(&self) -> DecodeParams {
        DecodeParams {
            unwrap: self.unwrap.method(),
            smoothing: self.coarse_average.smoothing(),
            ..DecodeParams::default()
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            device: DeviceChoice::VirtualRig,
            rig_width: 640,
            rig_height: 400,
            rig_tip_amplitude_mm: 2.0,
            rig_sway_mm: 0.0,
            rig_roll_deg: 0.0,
            fringe_count: 65,
            code_columns: true,
            projector_bits: 6,
            unwrap: UnwrapChoice::Robust,
            coarse_average: CoarseAverageArg::Plain,
            decoder: DecoderChoice::Auto,
            sessions_dir: home().join("tremorscan-sessions"),
            trial_seconds: 10.0,
            countdown_seconds: 3.0,
            export_dir: home().join("tremorscan-exports"),
            calibration_file: None,
            colour_file: None,
            point_size_px: 2.0,
        }
    }
}

/// The settings file's default location.
pub fn default_path() -> PathBuf {
    let config = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .unwrap_or_else(|| home().join(".config"));
    config.join("tremorscan").join("settings.json")
}

/// Loads settings from `path`: defaults when it does not exist, defaults and a message when it
/// cannot be read.
pub fn load(path: &Path) -> (Settings, Option<String>) {
    match std::fs::read_to_string(path) {
        Ok(text) => match serde_json::from_str::<Settings>(&text) {
            Ok(s) => (s, None),
            Err(e) => (
                Settings::default(),
                Some(format!(
                    "settings file {} is unreadable ({e}); using defaults",
                    path.display()
                )),
            ),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => (Settings::default(), None),
        Err(e) => (
            Settings::default(),
            Some(format!(
                "cannot read settings file {} ({e}); using defaults",
                path.display()
            )),
        ),
    }
}

/// Saves settings to `path`, creating its folder.
pub fn save(path: &Path, settings: &Settings) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    tremorscan::jsonfile::write_atomic(path, settings).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_round_trip_and_a_bad_file_falls_back_to_defaults() {
        let dir = std::env::temp_dir().join(format!("tremorscan-settings-{}", std::process::id()));
        let path = dir.join("settings.json");
        let mut s = Settings {
            device: DeviceChoice::Replay {
                session: PathBuf::from("/data/trial-1"),
            },
            ..Settings::default()
        };
        s.trial_seconds = 30.0;
        save(&path, &s).expect("save");
        assert_eq!(load(&path), (s, None));
        std::fs::write(&path, "{ not json").expect("write");
        let (loaded, message) = load(&path);
        assert_eq!(loaded, Settings::default());
        assert!(message.is_some_and(|m| m.contains("unreadable")));
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn camera_binning_round_trips_and_files_from_before_it_load_without_binning() {
        let dir = std::env::temp_dir().join(format!("tremorscan-binning-{}", std::process::id()));
        let path = dir.join("settings.json");
        let mut camera = DeviceChoice::default_camera();
        if let DeviceChoice::Camera { binning, .. } = &mut camera {
            assert_eq!(*binning, 1, "no binning by default");
            *binning = 2;
        }
        let s = Settings {
            device: camera,
            ..Settings::default()
        };
        save(&path, &s).expect("save");
        assert_eq!(load(&path), (s.clone(), None));
        // The same file as an earlier version wrote it: no "binning" key.
        let mut json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
        let removed = remove_key(&mut json, "binning");
        assert!(removed, "the file has a binning key: {json}");
        std::fs::write(&path, json.to_string()).expect("write");
        let (loaded, message) = load(&path);
        assert_eq!(message, None);
        assert!(
            matches!(loaded.device, DeviceChoice::Camera { binning: 1, .. }),
            "{:?}",
            loaded.device
        );
        let _ = std::fs::remove_dir_all(dir);
    }

    /// Removes `key` wherever it occurs in `value`; whether it was there.
    fn remove_key(value: &mut serde_json::Value, key: &str) -> bool {
        match value {
            serde_json::Value::Object(map) => {
                let here = map.remove(key).is_some();
                map.values_mut()
                    .fold(here, |found, v| remove_key(v, key) | found)
            }
            serde_json::Value::Array(items) => items
                .iter_mut()
                .fold(false, |found, v| remove_key(v, key) | found),
            _ => false,
        }
    }
}
