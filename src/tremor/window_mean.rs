//! Undoing the decode window's mean in a followed point's track, offline.
//!
//! A followed point is matched in the window's offset image, the mean of its three frames, so
//! the matched pixel is the mean of the skin's image positions at the three frame times:
//! with frames at −1, 0, +1 about the window's centre, `p_mean = p_centre + p''/3` (`p''` per
//! frame²), a three-tap moving average whose gain is (1 + 2·cos(2πf/fs))/3: 0.984 at 4.2 Hz and
//! 121 FPS, 0.968 at 6 Hz. The depth needs no such step where the motion model gives it at the
//! window's centre time (`decode::frames_averaged` is 1), but the position read at `p_mean` is
//! the surface there, beside the material point, by the surface's slope times `p''/3`.
//!
//! [`undo_window_mean`] estimates `p''` at each sample as twice the quadratic coefficient of a
//! least-squares quartic fitted to the matched pixels of the ±[`ACCELERATION_HALF_WIDTH`]
//! windows around it (at least all but two of the 13 measured), moves the pixel back by
//! `p''/3` and the position by the slope the sample kept ([`TrackSample::slope_mm_per_px`])
//! times that. Why this fit: a second difference of single windows would carry the match's
//! noise (0.1–0.4 px a window on the rig) into the track at 0.8 times its size; a quadratic
//! over ±4 windows reads the curvature of a 4.2 Hz tremor only 0.93 of its size (0.85 at 6 Hz),
//! the quartic over ±6 0.98 (0.96 at 6 Hz) while passing 0.055 of the match noise. Samples
//! without enough measured neighbours (the newest six of a live history, the edges of a gap)
//! stay as measured. Where the decode itself averages the window (`frames_averaged` is 3, the still
//! window), the whole position is that average and the analysis divides by the gain
//! (`AnalysisOptions::window_frames`), so the step is not taken there.

use super::track::TrackSample;
use nalgebra::{SMatrix, SVector};

/// Half width, in windows, of the fit that gives a followed point's image acceleration.
pub const ACCELERATION_HALF_WIDTH: usize = 6;

/// The fit's degree: a quartic, whose curvature at the centre is nearly free of the bias a
/// quadratic has over a window this wide (module header).
const DEGREE: usize = 4;

/// Moves each followed sample of `samples` from the window's mean to its centre time (module
/// header). A sample so moved no longer carries a slope, so the step is taken once.
pub fn undo_window_mean(samples: &mut [TrackSample]) {
    type Basis = SVector<f64, { DEGREE + 1 }>;
    let measured: Vec<Option<(f64, f64)>> = samples
        .iter()
        .map(|s| s.pixel.filter(|_| s.position_mm.is_some()))
        .collect();
    let h = ACCELERATION_HALF_WIDTH;
    for k in 0..samples.len() {
        let (Some(_), Some(slope)) = (measured[k], samples[k].slope_mm_per_px) else {
            continue;
        };
        let centre = samples[k].frame as f64;
        let mut normal = SMatrix::<f64, { DEGREE + 1 }, { DEGREE + 1 }>::zeros();
        let (mut ru, mut rv) = (Basis::zeros(), Basis::zeros());
        let mut used = 0;
        for j in k.saturating_sub(h)..(k + h + 1).min(samples.len()) {
            let t = samples[j].frame as f64 - centre;
            if let (Some(p), true) = (measured[j], t.abs() <= h as f64) {
                let b = Basis::from_fn(|i, _| t.powi(i as i32));
                normal += b * b.transpose();
                ru += b * p.0;
                rv += b * p.1;
                used += 1;
            }
        }
        if used + 2 < 2 * h + 1 {
            continue;
        }
        let lu = normal.lu();
        let (Some(cu), Some(cv)) = (lu.solve(&ru), lu.solve(&rv)) else {
            continue;
        };
        // p''/3 = 2·c₂/3.
        let shift = (2.0 * cu[2] / 3.0, 2.0 * cv[2] / 3.0);
        let s = &mut samples[k];
        s.pixel = s.pixel.map(|p| (p.0 - shift.0, p.1 - shift.1));
        if let Some(p) = s.position_mm.as_mut() {
            for axis in 0..3 {
                p[axis] -= slope[0][axis] * shift.0 + slope[1][axis] * shift.1;
            }
        }
        s.slope_mm_per_px = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A skin point moving sinusoidally across a sloped plane seen at 121 FPS, sampled as a
    /// followed point is: the pixel the mean of the three frames' image positions, the position
    /// the plane at that pixel. Returns the samples and the truth at each window's centre.
    fn followed(
        frequency_hz: f64,
        amplitude_px: f64,
        frames: usize,
    ) -> (Vec<TrackSample>, Vec<[f64; 3]>) {
        let fs = 121.0;
        let slope = [[0.4, 0.0, 0.3], [0.0, 0.4, -0.1]];
        let image_at = |frame: f64| {
            let phase = 2.0 * std::f64::consts::PI * frequency_hz * frame / fs;
            (
                100.0 + amplitude_px * phase.sin(),
                80.0 + 0.5 * amplitude_px * phase.cos(),
            )
        };
        let surface = |p: (f64, f64)| {
            [0, 1, 2].map(|a| 500.0 * f64::from(a == 2) + slope[0][a] * p.0 + slope[1][a] * p.1)
        };
        let mut samples = Vec::new();
        let mut truth = Vec::new();
        for k in 2..frames {
            let c = k as f64 - 1.0;
            let frames = [image_at(c - 1.0), image_at(c), image_at(c + 1.0)];
            let mean = (
                frames.iter().map(|p| p.0).sum::<f64>() / 3.0,
                frames.iter().map(|p| p.1).sum::<f64>() / 3.0,
            );
            samples.push(TrackSample {
                time_s: c / fs,
                frame: k,
                pixel: Some(mean),
                position_mm: Some(surface(mean)),
                slope_mm_per_px: Some(slope),
            });
            truth.push(surface(image_at(c)));
        }
        (samples, truth)
    }

    fn rms_error(
        samples: &[TrackSample],
        truth: &[[f64; 3]],
        range: std::ops::Range<usize>,
    ) -> f64 {
        let e: Vec<f64> = range
            .map(|k| {
                let p = samples[k].position_mm.expect("measured");
                (0..3).map(|a| (p[a] - truth[k][a]).powi(2)).sum::<f64>()
            })
            .collect();
        (e.iter().sum::<f64>() / e.len() as f64).sqrt()
    }

    #[test]
    fn the_followed_position_moves_to_the_window_centre() {
        // 6 Hz, 20 px: the window's mean is 3 % short of the motion, 0.64 px at the turns.
        let (mut samples, truth) = followed(6.0, 20.0, 200);
        let inner = 6..samples.len() - 6;
        let before = rms_error(&samples, &truth, inner.clone());
        undo_window_mean(&mut samples);
        let after = rms_error(&samples, &truth, inner);
        println!("RMS from the material point: {before:.4} → {after:.4} mm");
        assert!(before > 0.1, "{before}");
        // The ±6-window quartic reads the curvature 0.96 of its size at 6 Hz.
        assert!(after < 0.1 * before, "{after} against {before}");
        // The ends, without four neighbours on a side, stay as measured and keep their slope.
        assert!(samples[0].slope_mm_per_px.is_some());
        assert!(samples[samples.len() / 2].slope_mm_per_px.is_none());
    }

    #[test]
    fn gaps_and_fixed_pixels_are_left_as_measured() {
        let (mut samples, _) = followed(5.0, 10.0, 60);
        for s in &mut samples[20..23] {
            *s = TrackSample::missing(s.time_s, s.frame);
        }
        samples[40].slope_mm_per_px = None;
        let kept = samples.clone();
        undo_window_mean(&mut samples);
        // Within four windows of the gap, all three of its windows are among the ±6.
        for k in [16, 19, 23, 26] {
            assert_eq!(samples[k], kept[k], "sample {k}");
        }
        assert_eq!(samples[40], kept[40]);
        assert_ne!(samples[15], kept[15]);
        assert_ne!(samples[27], kept[27]);
        // Taken once: a second pass changes nothing.
        let once = samples.clone();
        undo_window_mean(&mut samples);
        assert_eq!(samples, once);
    }
}
