//! Calibration of the projector–camera rig. Today: colour (cross-talk) calibration and the robust
//! local fit that reads the projector coordinate at a chessboard corner; the rest of geometric
//! calibration lands here next.

pub mod colour;
pub mod local_fit;

pub use colour::{
    calibrate_colour, ColourCalibration, ColourOptions, ColourWarning, Roi, TABLE1_LEVELS,
};
pub use local_fit::{fit_coordinate, LocalFit, LocalFitOptions};

use crate::frame::FrameError;

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
    #[error("only {found} valid decoded pixels around ({u:.1}, {v:.1}), {needed} are needed for a local fit")]
    TooFewPoints {
        u: f64,
        v: f64,
        found: usize,
        needed: usize,
    },
}
