//! Depth accuracy at depth edges: does the decoder make up points where a pixel mixes two
//! surfaces?
//!
//! The protocol of the mixed-pixel issue: render one window of a still scene (the camera's
//! optical blur on, [`super::optics`]), decode it, triangulate with the rig's exact calibration
//! and compare every valid pixel's depth with the truth along its centre ray. A pixel is on the
//! *outline* when it lies within [`OUTLINE_MARGIN_PX`] (chessboard distance) of an *edge pixel*:
//! one whose 4-neighbour lies more than [`EDGE_STEP_MM`] deeper or shallower, is off every
//! surface, or differs from it in being lit by the projector (a shadow's border). The figures:
//!
//! * the share of the valid pixels more than [`GROSS_MM`] off, and how many of those lie on the
//!   outline;
//! * the share of the lit pixels off the outline that decoded valid;
//! * the RMS depth error of the valid pixels off the outline (gross errors apart).

use super::motion_eval::{MotionEvalError, GROSS_MM};
use super::{GroundTruth, VirtualRig};
use crate::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use crate::triangulate::{PointCloud, Triangulator};

/// Pixels this close (px, chessboard distance) to an edge pixel are on the outline.
pub const OUTLINE_MARGIN_PX: usize = 2;
/// Neighbours whose true depths differ by more than this straddle a depth edge, mm.
pub const EDGE_STEP_MM: f32 = 3.0;

/// The figures of one decoded window.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EdgeAccuracy {
    /// Valid pixels whose centre ray meets a surface.
    pub valid: usize,
    /// Of those, more than [`GROSS_MM`] off.
    pub gross: usize,
    /// Of the gross ones, on the outline.
    pub gross_on_outline: usize,
    /// Lit pixels off the outline.
    pub lit_interior: usize,
    /// Of those, decoded valid.
    pub valid_interior: usize,
    /// Valid pixels off the outline that are not gross errors, and their squared errors.
    good_interior: usize,
    sum2_interior_mm2: f64,
}

impl EdgeAccuracy {
    /// Share of the valid pixels that are gross errors (`None` with none valid).
    pub fn gross_rate(&self) -> Option<f64> {
        (self.valid > 0).then(|| self.gross as f64 / self.valid as f64)
    }

    /// Share of the lit pixels off the outline that decoded valid (`None` with none lit).
    pub fn interior_coverage(&self) -> Option<f64> {
        (self.lit_interior > 0).then(|| self.valid_interior as f64 / self.lit_interior as f64)
    }

    /// RMS depth error off the outline, gross errors apart, mm (`None` with none).
    pub fn interior_rms_mm(&self) -> Option<f64> {
        (self.good_interior > 0)
            .then(|| (self.sum2_interior_mm2 / self.good_interior as f64).sqrt())
    }
}

/// Decodes the window of `rig`'s frames `first..first + len` with `params` and compares it with
/// the truth of its middle frame (the scene should be still: the truth is taken at one time).
pub fn evaluate_edges(
    rig: &VirtualRig,
    params: DecodeParams,
    first: u64,
) -> Result<EdgeAccuracy, MotionEvalError> {
    let len = rig.sequence.entries.len() as u64;
    let triangulator = Triangulator::new(rig.stereo_model())?;
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    let mut cloud = PointCloud::default();
    let mut decoded = false;
    for i in first..first + len {
        let middle = i == first + len / 2;
        rig.render(i, &mut frame, middle.then_some(&mut truth))?;
        decoded = matches!(decoder.push(&frame)?, WindowOutcome::Decoded(_));
    }
    let out = decoder.output().filter(|_| decoded);
    let Some(out) = out else {
        return Ok(EdgeAccuracy::default());
    };
    triangulator.triangulate(out, &mut cloud)?;
    let outline = outline_mask(&truth);
    let mut acc = EdgeAccuracy::default();
    for (p, &on_outline) in outline.iter().enumerate() {
        let truth_mm = truth.depth_mm[p];
        let lit = truth.coordinate_px[p].is_finite();
        let decoded_mm = cloud.point_in_camera_mm[p][2];
        if lit && !on_outline {
            acc.lit_interior += 1;
        }
        if !(decoded_mm.is_finite() && truth_mm.is_finite()) {
            continue;
        }
        acc.valid += 1;
        let err = decoded_mm - truth_mm;
        let gross = err.abs() > GROSS_MM;
        acc.gross += usize::from(gross);
        acc.gross_on_outline += usize::from(gross && on_outline);
        if lit && !on_outline {
            acc.valid_interior += 1;
            if !gross {
                acc.good_interior += 1;
                acc.sum2_interior_mm2 += f64::from(err) * f64::from(err);
            }
        }
    }
    Ok(acc)
}

/// Per pixel: whether it lies on the outline of `truth` (see the module header).
pub fn outline_mask(truth: &GroundTruth) -> Vec<bool> {
    let (w, h) = (truth.width, truth.height);
    let depth = &truth.depth_mm;
    let lit = |p: usize| truth.coordinate_px[p].is_finite();
    let differ = |p: usize, q: usize| {
        let (a, b) = (depth[p], depth[q]);
        !(a.is_finite() && b.is_finite()) || (a - b).abs() > EDGE_STEP_MM || lit(p) != lit(q)
    };
    let mut edge = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            edge[p] = (x + 1 < w && differ(p, p + 1))
                || (x > 0 && differ(p, p - 1))
                || (y + 1 < h && differ(p, p + w))
                || (y > 0 && differ(p, p - w));
        }
    }
    // Dilation by the square of half-width OUTLINE_MARGIN_PX: rows, then columns.
    let m = OUTLINE_MARGIN_PX;
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (lo, hi) = (x.saturating_sub(m), (x + m).min(w - 1));
            rows[y * w + x] = (lo..=hi).any(|q| edge[y * w + q]);
        }
    }
    let mut mask = vec![false; w * h];
    for y in 0..h {
        let (lo, hi) = (y.saturating_sub(m), (y + m).min(h - 1));
        for x in 0..w {
            mask[y * w + x] = (lo..=hi).any(|q| rows[q * w + x]);
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_outline_is_two_pixels_either_side_of_a_depth_step() {
        let (w, h) = (12, 3);
        let mut t = GroundTruth::default();
        t.resize(w, h);
        for p in 0..w * h {
            // A 20 mm step between columns 5 and 6, every pixel lit.
            t.depth_mm[p] = if p % w < 6 { 480.0 } else { 500.0 };
            t.coordinate_px[p] = 100.0;
        }
        let mask = outline_mask(&t);
        let row: Vec<bool> = (0..w).map(|x| mask[w + x]).collect();
        // Edge pixels 5 and 6, dilated by 2: columns 3..=8.
        let expected: Vec<bool> = (0..w).map(|x| (3..=8).contains(&x)).collect();
        assert_eq!(row, expected);
    }
}
