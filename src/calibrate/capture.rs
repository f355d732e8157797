//! One geometric-calibration capture (a board pose): the room-light image and the pattern
//! frames of both coding axes, and how it becomes a [`ViewObservation`]: each axis's frames are
//! decoded into a dense projector-coordinate map, and the corners read from both maps.

use super::corners::{gray_of, BoardSpec};
use super::geometric::{observe_view, ViewObservation};
use super::local_fit::LocalFitOptions;
use super::CalibrationError;
use crate::color::CrossTalk;
use crate::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use crate::frame::Frame;
use crate::pattern::{Axis, PatternSequence};

/// Frames of one board pose.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationCapture {
    /// The board under room light, projector dark.
    pub ambient: Frame,
    /// A column-coding sequence and one frame per entry, in entry order.
    pub column_sequence: PatternSequence,
    pub column_frames: Vec<Frame>,
    /// A row-coding sequence and its frames.
    pub row_sequence: PatternSequence,
    pub row_frames: Vec<Frame>,
}

/// Decodes one full cycle of `frames` (entry order) into a row-major projector-coordinate map,
/// NaN where the decoder marked a pixel invalid.
pub fn coordinate_map(
    frames: &[Frame],
    sequence: &PatternSequence,
    cross_talk: CrossTalk,
    params: DecodeParams,
    view: usize,
) -> Result<Vec<f32>, CalibrationError> {
    let mut decoder = SlidingDecoder::new(sequence.clone(), cross_talk, params)
        .map_err(|source| CalibrationError::Decode { view, source })?;
    let mut decoded = false;
    for frame in frames {
        let outcome = decoder
            .push(frame)
            .map_err(|source| CalibrationError::Decode { view, source })?;
        decoded |= matches!(outcome, WindowOutcome::Decoded(_));
    }
    let out = decoder
        .output()
        .filter(|_| decoded)
        .ok_or_else(|| CalibrationError::BadCapture {
            view,
            why: format!(
                "{} pattern frames do not make a decodable window",
                frames.len()
            ),
        })?;
    Ok(out.coordinate_px.clone())
}

/// Decodes both axes of a capture and observes the board in it.
pub fn observe_capture(
    view: usize,
    capture: &CalibrationCapture,
    board: &BoardSpec,
    cross_talk: CrossTalk,
    fit: &LocalFitOptions,
) -> Result<ViewObservation, CalibrationError> {
    for (sequence, axis) in [
        (&capture.column_sequence, Axis::Columns),
        (&capture.row_sequence, Axis::Rows),
    ] {
        if sequence.axis != axis {
            return Err(CalibrationError::BadCapture {
                view,
                why: format!("expected a {axis:?} sequence, got {:?}", sequence.axis),
            });
        }
    }
    let (w, h) = (capture.ambient.width, capture.ambient.height);
    let params = DecodeParams::default();
    let columns = coordinate_map(
        &capture.column_frames,
        &capture.column_sequence,
        cross_talk,
        params,
        view,
    )?;
    let rows = coordinate_map(
        &capture.row_frames,
        &capture.row_sequence,
        cross_talk,
        params,
        view,
    )?;
    observe_view(
        view,
        &gray_of(&capture.ambient),
        &columns,
        &rows,
        w,
        h,
        board,
        fit,
    )
}
