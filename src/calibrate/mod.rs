//! Calibration of the projector–camera rig. Today: colour (cross-talk) calibration; geometric
//! calibration lands here next.

pub mod colour;

pub use colour::{
    calibrate_colour, ColourCalibration, ColourOptions, ColourWarning, Roi, TABLE1_LEVELS,
};

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
    #[error("the colour samples do not determine the cross-talk matrix (singular system)")]
    Singular,
}
