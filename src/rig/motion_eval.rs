//! Depth accuracy of moving skin: decoded windows against the rig's truth where the hand moves.
//!
//! The protocol of the motion issue: render frames `0..frames` of a rig, decode every
//! `stride`-th window with the sliding decoder, triangulate with the rig's exact calibration and
//! compare each pixel's depth with the truth at the window's centre frame. Pixels counted are on
//! skin in all three frames of the window and at least [`OUTLINE_MARGIN_PX`] from its outline
//! (every pixel of the `(2·margin + 1)²` square around them is skin in every frame), so that the
//! figures say how the decoder copes with motion, not with the outline. A counted pixel is
//! *moving* when its true depth changes by more than [`MOVING_MM`] across the window, *still*
//! otherwise. A valid pixel more than [`GROSS_MM`] off is a gross error; the RMS is over the
//! other valid pixels.

use super::{GroundTruth, RigError, VirtualRig};
use crate::decode::{DecodeError, DecodeParams, SlidingDecoder, WindowOutcome};
use crate::triangulate::{PointCloud, TriangulateError, Triangulator};

/// Counted pixels keep this far (px, chessboard distance) from the skin's outline.
pub const OUTLINE_MARGIN_PX: usize = 2;
/// A pixel whose true depth changes by more than this across the window is moving, mm.
pub const MOVING_MM: f32 = 0.5;
/// A valid pixel farther than this from the truth is a gross error, mm.
pub const GROSS_MM: f32 = 2.0;

/// Errors of the motion evaluation.
#[derive(Debug, thiserror::Error)]
pub enum MotionEvalError {
    #[error(transparent)]
    Rig(#[from] RigError),
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error(transparent)]
    Triangulate(#[from] TriangulateError),
    #[error("the sequence has {0} patterns; the motion evaluation needs a window of three")]
    NotThreeFrames(usize),
}

/// Counts and errors over one class of pixels (moving or still).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DepthTally {
    /// Counted pixels.
    pub counted: usize,
    /// Of those, decoded valid.
    pub valid: usize,
    /// Of the valid ones, more than [`GROSS_MM`] off.
    pub gross: usize,
    sum2_mm2: f64,
}

impl DepthTally {
    fn add(&mut self, decoded_mm: f32, truth_mm: f32) {
        self.counted += 1;
        if !decoded_mm.is_finite() {
            return;
        }
        self.valid += 1;
        let err = f64::from(decoded_mm - truth_mm);
        if err.abs() > f64::from(GROSS_MM) {
            self.gross += 1;
        } else {
            self.sum2_mm2 += err * err;
        }
    }

    /// Share of the counted pixels that decoded valid (`None` with none counted).
    pub fn coverage(&self) -> Option<f64> {
        (self.counted > 0).then(|| self.valid as f64 / self.counted as f64)
    }

    /// Share of the valid pixels that are gross errors (`None` with none valid).
    pub fn gross_rate(&self) -> Option<f64> {
        (self.valid > 0).then(|| self.gross as f64 / self.valid as f64)
    }

    /// RMS error of the valid pixels that are not gross errors, mm (`None` with none).
    pub fn rms_mm(&self) -> Option<f64> {
        let good = self.valid - self.gross;
        (good > 0).then(|| (self.sum2_mm2 / good as f64).sqrt())
    }
}

/// The evaluation of one rig over many windows.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MotionAccuracy {
    pub moving: DepthTally,
    pub still: DepthTally,
    /// Windows decoded and compared.
    pub windows: usize,
}

/// Renders frames `0..frames` of `rig`, decodes every `stride`-th complete window with `params`
/// and compares it with the truth at its centre frame.
pub fn evaluate_motion(
    rig: &VirtualRig,
    params: DecodeParams,
    frames: u64,
    stride: u64,
) -> Result<MotionAccuracy, MotionEvalError> {
    let len = rig.sequence.entries.len();
    if len != 3 {
        return Err(MotionEvalError::NotThreeFrames(len));
    }
    let triangulator = Triangulator::new(rig.stereo_model())?;
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    // Truth of the last three frames, oldest first.
    let mut truths: [GroundTruth; 3] = Default::default();
    let mut cloud = PointCloud::default();
    let mut mask = Vec::new();
    let mut result = MotionAccuracy::default();
    for i in 0..frames.max(1) {
        truths.rotate_left(1);
        rig.render(i, &mut frame, Some(&mut truths[2]))?;
        let decoded = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => out,
            _ => continue,
        };
        // Window k ends with frame k + 2.
        if i < 2 || (i - 2) % stride.max(1) != 0 {
            continue;
        }
        triangulator.triangulate(decoded, &mut cloud)?;
        counted_mask(&truths, OUTLINE_MARGIN_PX, &mut mask);
        for (p, &counted) in mask.iter().enumerate() {
            if !counted {
                continue;
            }
            let depths = [
                truths[0].depth_mm[p],
                truths[1].depth_mm[p],
                truths[2].depth_mm[p],
            ];
            let lo = depths.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = depths.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            let decoded_mm = cloud.point_in_camera_mm[p][2];
            let tally = if hi - lo > MOVING_MM {
                &mut result.moving
            } else {
                &mut result.still
            };
            tally.add(decoded_mm, depths[1]);
        }
        result.windows += 1;
    }
    Ok(result)
}

/// Pixels on skin in every one of `truths`, with every pixel within `margin` (chessboard
/// distance) on skin too.
fn counted_mask(truths: &[GroundTruth; 3], margin: usize, mask: &mut Vec<bool>) {
    let (w, h) = (truths[0].width, truths[0].height);
    let skin: Vec<bool> = (0..w * h)
        .map(|p| {
            truths
                .iter()
                .all(|t| t.surface[p] == super::truth::surface::SKIN)
        })
        .collect();
    // Erosion by a square: rows, then columns.
    let erode = |src: &[bool], dst: &mut Vec<bool>, horizontal: bool| {
        dst.clear();
        dst.resize(w * h, false);
        for y in 0..h {
            for x in 0..w {
                let (pos, len) = if horizontal { (x, w) } else { (y, h) };
                if pos < margin || pos + margin >= len {
                    continue;
                }
                dst[y * w + x] = (0..=2 * margin).all(|k| {
                    let q = pos + k - margin;
                    let i = if horizontal { y * w + q } else { q * w + x };
                    src[i]
                });
            }
        }
    };
    let mut rows = Vec::new();
    erode(&skin, &mut rows, true);
    erode(&rows, mask, false);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rig::truth::surface;

    #[test]
    fn the_mask_keeps_only_pixels_away_from_the_outline() {
        let (w, h) = (9, 7);
        let mut t = GroundTruth::default();
        t.resize(w, h);
        // Skin on columns 1..=7, rows 0..=6.
        for y in 0..h {
            for x in 1..=7 {
                t.surface[y * w + x] = surface::SKIN;
            }
        }
        let truths = [t.clone(), t.clone(), t];
        let mut mask = Vec::new();
        counted_mask(&truths, 2, &mut mask);
        let kept: Vec<(usize, usize)> = (0..w * h)
            .filter(|&p| mask[p])
            .map(|p| (p % w, p / w))
            .collect();
        // Columns 3..=5 are 2 px inside; rows 2..=4 are 2 px from the image border.
        assert_eq!(kept.len(), 9, "{kept:?}");
        assert!(kept
            .iter()
            .all(|&(x, y)| (3..=5).contains(&x) && (2..=4).contains(&y)));
    }

    #[test]
    fn a_tally_reports_nothing_from_nothing() {
        let mut t = DepthTally::default();
        assert_eq!(t.coverage(), None);
        t.add(f32::NAN, 500.0);
        assert_eq!(t.coverage(), Some(0.0));
        assert_eq!(t.gross_rate(), None);
        assert_eq!(t.rms_mm(), None);
        t.add(503.0, 500.0);
        t.add(500.5, 500.0);
        assert_eq!(t.gross_rate(), Some(0.5));
        assert!((t.rms_mm().unwrap() - 0.5).abs() < 1e-9);
    }
}
