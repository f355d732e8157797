//! The last stage of every window (CPU and GPU): a window whose frames break the phase
//! relation on most of its lit pixels is refused whole.
//!
//! Every per-pixel check asks whether one pixel's samples agree with a surface (moving or
//! not). A frame that is wrong as a whole fails that test everywhere: a corrupted transfer, a
//! half-written buffer, a channel from another exposure. Where the corruption happens to be
//! small for a pixel, though, the pixel passes, and nothing local tells it from its neighbours
//! that are right. Measured on the rig's still hand with one frame's red channel replaced by
//! the pattern a quarter period on (`tests/validity.rs`), stream of 12 frames. The three
//! windows holding that frame kept 0.4, 0.02 and 5.4 % of the image valid a fringe period
//! (or more) off: 900, 53 and 13,390 pixels, with the frame last, in the middle and first. The
//! motion model took the broken relation for motion. Where the frame comes first, the windows
//! before had been refused too, so the temporal check had no reference. The still window
//! kept 529–605 such pixels in each.
//!
//! The window as a whole shows it: those windows flagged 63–82 % of their lit pixels
//! [`invalid::DISAGREEMENT`] (65 % each with the still window), where the rig's hand flags at
//! most 0.07 % still and 5.8 % in a 20 mm tremor with 4 mm of sway (the worst window of the
//! motion sweep's 13 per row). So a window with more than [`MAX_DISAGREEING_SHARE`] of its lit
//! pixels (not flagged [`invalid::LOW_AMPLITUDE`] or [`invalid::SATURATED`]) in disagreement
//! is refused: every pixel flagged [`invalid::BROKEN_WINDOW`], no coordinate or motion, and the
//! stream's links cut ([`DecodeOutput::forget_stream`]), as after a dropped frame. The next window does
//! not take the refused one's coordinates as references or its velocities for acceleration.
//! [`DecodeOutput::refused_share`] tells the caller why. With the checks off (an infinite
//! `max_disagreement_chi2`) no pixel disagrees and no window is refused.

use super::{invalid, DecodeOutput};
use rayon::prelude::*;

/// The share of a window's lit pixels in [`invalid::DISAGREEMENT`] above which the window is
/// refused: over three times the worst the rig's moving hand shows (5.8 %), under a third of
/// the mildest corrupted frame measured (63 %).
pub const MAX_DISAGREEING_SHARE: f32 = 0.2;

/// Refuses `out` whole when more than [`MAX_DISAGREEING_SHARE`] of its lit pixels disagree,
/// and records the share in [`DecodeOutput::refused_share`] (`None` when kept).
pub fn refuse_broken_window(out: &mut DecodeOutput) -> Option<f32> {
    let unlit = invalid::LOW_AMPLITUDE | invalid::SATURATED;
    let (lit, disagreeing) = out
        .invalid
        .par_iter()
        .fold(
            || (0usize, 0usize),
            |(lit, bad), &f| {
                let is_lit = f & unlit == 0;
                let disagrees = is_lit & (f & invalid::DISAGREEMENT != 0);
                (lit + usize::from(is_lit), bad + usize::from(disagrees))
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let share = (lit > 0).then(|| disagreeing as f32 / lit as f32);
    out.refused_share = share.filter(|&s| s > MAX_DISAGREEING_SHARE);
    if out.refused_share.is_some() {
        out.invalid
            .par_iter_mut()
            .for_each(|f| *f |= invalid::BROKEN_WINDOW);
        out.coordinate_px.par_iter_mut().for_each(|c| *c = f32::NAN);
        // No pixel is valid, so no pixel has motion (the planes' contract).
        out.velocity_px_per_s.fill(0.0);
        out.brightness_rate_per_s.fill(0.0);
        out.acceleration_px_per_s2.fill(0.0);
        out.forget_stream();
    }
    out.refused_share
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    fn output(n: usize) -> DecodeOutput {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        let mut out = DecodeOutput::new(n, 1, &solver);
        out.coordinate_px.fill(100.0);
        out.time_s = 1.0;
        out.recent_time_s = 1.0 - 1.0 / 121.0;
        out
    }

    #[test]
    fn a_window_is_refused_only_when_most_of_its_lit_pixels_disagree() {
        // 10 pixels: 4 unlit (shadow, saturated), 6 lit of which 2 disagree: 1/3 > 0.2.
        let mut out = output(10);
        out.invalid[..3].fill(invalid::LOW_AMPLITUDE);
        // Unlit and disagreeing: not counted.
        out.invalid[3] = invalid::SATURATED | invalid::DISAGREEMENT;
        out.invalid[4] = invalid::DISAGREEMENT;
        out.invalid[5] = invalid::DISAGREEMENT | invalid::UNWRAP_MARGIN;
        let share = refuse_broken_window(&mut out).unwrap();
        assert!((share - 2.0 / 6.0).abs() < 1e-6, "{share}");
        assert_eq!(out.refused_share, Some(share));
        assert!(out.invalid.iter().all(|f| f & invalid::BROKEN_WINDOW != 0));
        assert!(out.coordinate_px.iter().all(|c| c.is_nan()));
        // The next window is not linked to this one.
        assert!(out.recent_time_s.is_nan());
        // One disagreeing pixel of six lit (1/6 < 0.2): kept as it is.
        let mut out = output(10);
        out.invalid[..4].fill(invalid::LOW_AMPLITUDE);
        out.invalid[4] = invalid::DISAGREEMENT;
        let before = out.invalid.clone();
        assert_eq!(refuse_broken_window(&mut out), None);
        assert_eq!(out.invalid, before);
        assert!(out.coordinate_px.iter().all(|&c| c == 100.0));
        assert!(out.recent_time_s.is_finite());
        // Nothing lit: nothing to judge.
        let mut out = output(3);
        out.invalid.fill(invalid::LOW_AMPLITUDE);
        assert_eq!(refuse_broken_window(&mut out), None);
    }
}
