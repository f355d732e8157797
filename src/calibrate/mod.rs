//! Calibration of the projector–camera rig: colour (cross-talk, paper §5.3) and geometric
//! (intrinsics, distortion and extrinsics of camera and projector from chessboard views).
//!
//! Geometric calibration runs `corners` (find the board) → `local_fit` (projector coordinates
//! at the corners) → `zhang` (closed-form start) → `refine` (joint Levenberg–Marquardt), tied
//! together by `geometric`.

pub mod capture;
pub mod colour;
pub mod corners;
pub mod file;
pub mod geometric;
pub mod local_fit;
pub mod opencv;
pub mod refine;
mod residuals;
pub mod zhang;

pub use capture::{coordinate_map, observe_capture, CalibrationCapture};
pub use colour::{
    calibrate_colour, ColourCalibration, ColourOptions, ColourWarning, Roi, TABLE1_LEVELS,
};
pub use corners::{find_board_corners, gray_of, BoardSpec};
pub use file::{Calibration, CalibrationFile, ColourFile, FileError, CALIBRATION_FORMAT};
pub use geometric::{
    calibrate_geometric, observe_view, GeometricCalibration, GeometricOptions, Uncertainty,
    ViewError, ViewObservation, MIN_VIEWS,
};
pub use local_fit::{fit_coordinate, LocalFit, LocalFitOptions};
pub use opencv::import_opencv;

use crate::frame::FrameError;

/// Which device of the rig a calibration message is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Device {
    Camera,
    Projector,
}

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Device::Camera => "camera",
            Device::Projector => "projector",
        })
    }
}

/// Errors of calibration.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CalibrationError {
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("colour calibration needs the {expected} captures of Table 1, got {got}")]
    CaptureCount { expected: usize, got: usize },
    #[error("region of interest {roi:?} does not lie inside the {width}×{height} image")]
    RoiOutside {
        roi: Roi,
        width: usize,
        height: usize,
    },
    #[error("capture {capture} has no usable (unsaturated) sample in the region of interest")]
    NoUsableSamples { capture: usize },
    #[error("the samples do not determine the fit (singular system)")]
    Singular,
    #[error("a chessboard needs at least 2×2 inner corners, got {cols}×{rows}")]
    BadBoard { cols: usize, rows: usize },
    #[error("view {view}: found {found} of the board's {expected} inner corners; the whole board must be visible and sharp")]
    CornersNotFound {
        view: usize,
        found: usize,
        expected: usize,
    },
    #[error("view {view}: the projector coordinates were decoded at only {decoded} of {expected} corners; keep the whole board inside the projected area, dim the room light for the pattern captures, and decode with the rig's colour calibration")]
    ProjectorNotDecoded {
        view: usize,
        decoded: usize,
        expected: usize,
    },
    #[error("{got} usable views, geometric calibration needs at least {needed}")]
    TooFewViews { got: usize, needed: usize },
    #[error("view {view} does not exist ({count} views)")]
    NoSuchView { view: usize, count: usize },
    #[error("degenerate board poses for the {device}: {why}")]
    DegeneratePoses { device: Device, why: String },
    #[error("view {view}: the pattern frames do not decode")]
    Decode {
        view: usize,
        source: crate::decode::DecodeError,
    },
    #[error("view {view}: {why}")]
    BadCapture { view: usize, why: String },
    #[error("the joint refinement did not converge: {0}")]
    RefinementFailed(String),
    #[error("only {found} valid decoded pixels around ({u:.1}, {v:.1}), {needed} are needed for a local fit")]
    TooFewPoints {
        u: f64,
        v: f64,
        found: usize,
        needed: usize,
    },
}
