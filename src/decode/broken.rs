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
//! [`DecodeOutput::refused`] tells the caller why. With the checks off (an infinite
//! `max_disagreement_chi2`) no pixel disagrees and no window is refused.
//!
//! A frame can also break on a band of rows only: a projector that switches its pattern while
//! the camera's rolling shutter is half way down the frame, or a transfer that filled a band of
//! rows from another exposure. Measured on the rig's still hand with the red channel a quarter
//! period on for rows 180–219 of one 640×400 frame (`tests/validity.rs`), the three windows
//! holding it kept 143, 0 and 850 pixels inside the band a fringe (or more) off, and 28–43
//! outside it (at the motion test's 10⁻³: 146, 0, 860 and 27–53, up to 19 rows away): the
//! edge-aware average of the unit phase carries the band's coarse coordinate out of it. The windows as a whole disagreed on under 20 %. Counted in
//! bands of [`BAND_ROWS`] rows (scaled with the image's width from 640 px), bands inside the
//! broken rows disagreed on 71–91 % of their lit pixels; the motion sweep's hand on at most
//! 29 % (a 20 mm tremor with 4 mm of sway: the fingertips' fastest skin, beyond the motion
//! model), the still hand on 0.2 %. So a window is also refused whole when a band of rows
//! disagrees on more than [`MAX_BAND_DISAGREEING_SHARE`] of at least [`MIN_LIT_PER_BAND`] lit
//! pixels. (Refusing only the broken rows and 24 around them, with the stream's links cut,
//! left the window with the broken frame in the middle 124 pixels a fringe off up to 40 rows
//! away, where the temporal check had caught all but 27: how far the broken coordinates
//! spread depends on how many rows broke, so no fixed margin is safe.)

use super::{invalid, DecodeOutput};
use rayon::prelude::*;

/// The share of a window's lit pixels in [`invalid::DISAGREEMENT`] above which the window is
/// refused: over three times the worst the rig's moving hand shows (5.8 %), under a third of
/// the mildest corrupted frame measured (63 %).
pub const MAX_DISAGREEING_SHARE: f32 = 0.2;

/// Height of the bands of rows tested on their own, at 640 px wide (scaled with the width).
pub const BAND_ROWS: usize = 8;
/// The share of a band's lit pixels in [`invalid::DISAGREEMENT`] above which the window is
/// refused: over 1.7× the worst band of the rig's moving hand (29 %), under the mildest band
/// inside the broken rows measured (71 %).
pub const MAX_BAND_DISAGREEING_SHARE: f32 = 0.5;
/// Fewest lit pixels a band needs to be judged, at 640 px wide (scaled with the area).
pub const MIN_LIT_PER_BAND: usize = 256;

/// Why a window was refused: the share of the lit pixels on `rows` that disagree (all rows when
/// the window as a whole broke, else the first band of rows that did).
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub share: f32,
    pub rows: std::ops::Range<usize>,
}

/// Refuses `out` whole when more than [`MAX_DISAGREEING_SHARE`] of its lit pixels, or more
/// than [`MAX_BAND_DISAGREEING_SHARE`] of a band of its rows' lit pixels, disagree, and says
/// why in [`DecodeOutput::refused`] (`None` when kept). Returns whether it refused.
pub fn refuse_broken_window(out: &mut DecodeOutput) -> bool {
    let width = out.width.max(1);
    let scale = (width as f32 / 640.0).max(1.0);
    let band = ((BAND_ROWS as f32 * scale).round() as usize).max(1);
    let min_lit = (MIN_LIT_PER_BAND as f32 * scale * scale).round() as usize;
    // Per band: its counts, and its index and share where it is over the band limit; summed,
    // keeping the first such band (nothing allocated).
    let (lit, disagreeing, broken) = out
        .invalid
        .par_chunks(band * width)
        .enumerate()
        .map(|(k, rows)| {
            let (lit, bad) = rows.iter().fold((0, 0), |(lit, bad), &f| {
                let is_lit = f & UNLIT == 0;
                let disagrees = is_lit & (f & invalid::DISAGREEMENT != 0);
                (lit + usize::from(is_lit), bad + usize::from(disagrees))
            });
            let broken = lit >= min_lit && bad as f32 > MAX_BAND_DISAGREEING_SHARE * lit as f32;
            (lit, bad, broken.then(|| (k, bad as f32 / lit as f32)))
        })
        .reduce(
            || (0, 0, None),
            |a, b| {
                let first = match (a.2, b.2) {
                    (Some(x), Some(y)) => Some(if x.0 <= y.0 { x } else { y }),
                    (x, y) => x.or(y),
                };
                (a.0 + b.0, a.1 + b.1, first)
            },
        );
    let whole =
        (lit > 0 && disagreeing as f32 > MAX_DISAGREEING_SHARE * lit as f32).then(|| Refusal {
            share: disagreeing as f32 / lit as f32,
            rows: 0..out.height,
        });
    out.refused = whole.or_else(|| {
        broken.map(|(k, share)| Refusal {
            share,
            rows: k * band..((k + 1) * band).min(out.height),
        })
    });
    if out.refused.is_some() {
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
    out.refused.is_some()
}

/// Flags that make a pixel unlit: it has no phase relation to break.
const UNLIT: u16 = invalid::LOW_AMPLITUDE | invalid::SATURATED;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    fn output(width: usize, height: usize) -> DecodeOutput {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        let mut out = DecodeOutput::new(width, height, &solver);
        out.coordinate_px.fill(100.0);
        out.time_s = 1.0;
        out.recent_time_s = 1.0 - 1.0 / 121.0;
        out
    }

    #[test]
    fn a_window_is_refused_only_when_most_of_its_lit_pixels_disagree() {
        // 10 pixels: 4 unlit (shadow, saturated), 6 lit of which 2 disagree: 1/3 > 0.2.
        let mut out = output(10, 1);
        out.invalid[..3].fill(invalid::LOW_AMPLITUDE);
        // Unlit and disagreeing: not counted.
        out.invalid[3] = invalid::SATURATED | invalid::DISAGREEMENT;
        out.invalid[4] = invalid::DISAGREEMENT;
        out.invalid[5] = invalid::DISAGREEMENT | invalid::UNWRAP_MARGIN;
        assert!(refuse_broken_window(&mut out));
        let refusal = out.refused.clone().unwrap();
        assert!((refusal.share - 2.0 / 6.0).abs() < 1e-6, "{refusal:?}");
        assert_eq!(refusal.rows, 0..1);
        assert!(out.invalid.iter().all(|f| f & invalid::BROKEN_WINDOW != 0));
        assert!(out.coordinate_px.iter().all(|c| c.is_nan()));
        // The next window is not linked to this one.
        assert!(out.recent_time_s.is_nan());
        // One disagreeing pixel of six lit (1/6 < 0.2): kept as it is.
        let mut out = output(10, 1);
        out.invalid[..4].fill(invalid::LOW_AMPLITUDE);
        out.invalid[4] = invalid::DISAGREEMENT;
        let before = out.invalid.clone();
        assert!(!refuse_broken_window(&mut out));
        assert_eq!(out.refused, None);
        assert_eq!(out.invalid, before);
        assert!(out.coordinate_px.iter().all(|&c| c == 100.0));
        assert!(out.recent_time_s.is_finite());
        // Nothing lit: nothing to judge.
        let mut out = output(3, 1);
        out.invalid.fill(invalid::LOW_AMPLITUDE);
        assert!(!refuse_broken_window(&mut out));
    }

    #[test]
    fn a_band_of_rows_that_disagrees_refuses_the_window() {
        // 640×80: ten bands of 8 rows, all lit. Rows 40–47 disagree on 60 % of their pixels,
        // the image on 6 %: refused for that band.
        let (w, h) = (640, 80);
        let disagree = |out: &mut DecodeOutput, y: usize, n: usize| {
            out.invalid[y * w..y * w + n].fill(invalid::DISAGREEMENT);
        };
        let mut out = output(w, h);
        for y in 40..48 {
            disagree(&mut out, y, 384);
        }
        assert!(refuse_broken_window(&mut out));
        let refusal = out.refused.clone().unwrap();
        assert_eq!(refusal.rows, 40..48);
        assert!((refusal.share - 0.6).abs() < 1e-6, "{refusal:?}");
        assert!(out.invalid.iter().all(|f| f & invalid::BROKEN_WINDOW != 0));
        assert!(out.coordinate_px.iter().all(|c| c.is_nan()));
        assert!(out.recent_time_s.is_nan());
        // At 40 % the band is a moving hand's, not a broken frame's: kept.
        let mut out = output(w, h);
        for y in 40..48 {
            disagree(&mut out, y, 256);
        }
        assert!(!refuse_broken_window(&mut out));
        assert!(out.coordinate_px.iter().all(|&c| c == 100.0));
        // A band with too few lit pixels is not judged: 200 lit, all disagreeing.
        let mut out = output(w, h);
        out.invalid[..8 * w].fill(invalid::LOW_AMPLITUDE);
        for y in 0..8 {
            disagree(&mut out, y, 25);
        }
        assert!(!refuse_broken_window(&mut out));
    }
}
