//! Magnitude-squared coherence between two control points: how much of one point's motion is
//! linearly predictable from the other's, per frequency (a left/right or finger/wrist pair
//! moving as one tremor gives values near 1, independent motions near 0).
//!
//! Welch's method: Hann segments with 50 % overlap, each detrended; `|S_xy|² / (S_xx·S_yy)`
//! per frequency bin, reported as its value at a point's peak frequency and its mean over
//! [`COHERENCE_BAND_HZ`]. One segment gives 1 everywhere, so at least
//! [`COHERENCE_MIN_SEGMENTS`] are needed; the estimate's bias for K segments of unrelated
//! records is about 1/K. Two tracked points are compared at the instants where both were
//! measured ([`series_coherence`]), so a gap in one never shifts the other's time axis.

use super::analysis::MIN_VALID_FRACTION;
use super::spectrum::{detrend_linear, resample};
use realfft::RealFftPlanner;

/// Welch segments a coherence needs.
pub const COHERENCE_MIN_SEGMENTS: usize = 4;

/// The band the coherence is summarised over, Hz.
pub const COHERENCE_BAND_HZ: (f64, f64) = (2.0, 12.0);

/// Magnitude-squared coherence of two records per frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct Coherence {
    pub frequency_hz: Vec<f64>,
    pub msc: Vec<f64>,
    pub segments: usize,
}

impl Coherence {
    /// The coherence at the bin nearest `f` Hz.
    pub fn at(&self, f: f64) -> Option<f64> {
        let df = self.frequency_hz.get(1)?;
        self.msc.get((f / df).round() as usize).copied()
    }

    /// The mean coherence over the bins in `[lo, hi]` Hz.
    pub fn band_mean(&self, (lo, hi): (f64, f64)) -> Option<f64> {
        let inside: Vec<f64> = self
            .frequency_hz
            .iter()
            .zip(&self.msc)
            .filter(|(f, _)| **f >= lo && **f <= hi)
            .map(|(_, c)| *c)
            .collect();
        (!inside.is_empty()).then(|| inside.iter().sum::<f64>() / inside.len() as f64)
    }
}

/// Coherence of `x` and `y` (same rate and length) with `segment` samples per segment.
pub fn coherence(x: &[f64], y: &[f64], rate_hz: f64, segment: usize) -> Option<Coherence> {
    if x.len() != y.len() || segment < 8 {
        return None;
    }
    let window: Vec<f64> = (0..segment)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / segment as f64).cos())
        .collect();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(segment);
    let (mut input, mut sx, mut sy) = (
        fft.make_input_vec(),
        fft.make_output_vec(),
        fft.make_output_vec(),
    );
    let bins = segment / 2 + 1;
    let (mut pxx, mut pyy) = (vec![0.0; bins], vec![0.0; bins]);
    let mut pxy = vec![realfft::num_complex::Complex::<f64>::new(0.0, 0.0); bins];
    let mut segments = 0;
    let mut start = 0;
    while start + segment <= x.len() {
        for (series, out) in [(x, &mut sx), (y, &mut sy)] {
            let mut seg = series[start..start + segment].to_vec();
            detrend_linear(&mut seg);
            for (i, v) in input.iter_mut().enumerate() {
                *v = seg[i] * window[i];
            }
            fft.process(&mut input, out).ok()?;
        }
        for k in 0..bins {
            pxx[k] += sx[k].norm_sqr();
            pyy[k] += sy[k].norm_sqr();
            pxy[k] += sx[k] * sy[k].conj();
        }
        segments += 1;
        start += segment / 2;
    }
    if segments < COHERENCE_MIN_SEGMENTS {
        return None;
    }
    let msc = (0..bins)
        .map(|k| {
            let d = pxx[k] * pyy[k];
            if d > 0.0 {
                pxy[k].norm_sqr() / d
            } else {
                0.0
            }
        })
        .collect();
    Some(Coherence {
        frequency_hz: (0..bins)
            .map(|k| k as f64 * rate_hz / segment as f64)
            .collect(),
        msc,
        segments,
    })
}

/// One point's displacement series: its samples' times, s, and displacements, mm (`None`: not
/// measured).
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    pub times_s: &'a [f64],
    pub displacement_mm: &'a [Option<f64>],
}

/// The coherence of two points' series: at the instants both were measured (samples of one
/// window share its time stamp; points placed at different times share only their common
/// stretch), put on one uniform grid, in Hann segments of 2 s, or of 0.4 of the record if that
/// is shorter, so that a short record still gives the segments a coherence needs (0.8 s for a
/// 2 s record: 1.25 Hz resolution). `None` where fewer than half of the instants of the common
/// stretch have both points, or the record is too short.
pub fn series_coherence(a: Series<'_>, b: Series<'_>) -> Option<Coherence> {
    if a.times_s.len() != a.displacement_mm.len() || b.times_s.len() != b.displacement_mm.len() {
        return None;
    }
    // Walk both (time-ordered) series together, keeping the instants they share.
    let (mut i, mut j) = (0, 0);
    let (mut times, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new());
    while i < a.times_s.len() && j < b.times_s.len() {
        let (ta, tb) = (a.times_s[i], b.times_s[j]);
        if (ta - tb).abs() <= 1e-9 {
            let both = a.displacement_mm[i].zip(b.displacement_mm[j]);
            times.push(ta);
            x.push(both.map(|p| p.0));
            y.push(both.map(|p| p.1));
            i += 1;
            j += 1;
        } else if ta < tb {
            i += 1;
        } else {
            j += 1;
        }
    }
    let joint = x.iter().filter(|v| v.is_some()).count();
    if joint == 0 || (joint as f64) < MIN_VALID_FRACTION * times.len() as f64 {
        return None;
    }
    let (x, y) = (resample(&times, &x)?, resample(&times, &y)?);
    let segment = (2.0 * x.rate_hz).min(0.4 * x.values.len() as f64).round() as usize;
    coherence(&x.values, &y.values, x.rate_hz, segment)
}

/// One point's coherence with another.
#[derive(Debug, Clone, PartialEq)]
pub struct PairCoherence {
    /// The other point's name.
    pub with: String,
    /// At this point's peak frequency (`None`: no peak, or no coherence).
    pub at_peak: Option<f64>,
    /// The mean over [`COHERENCE_BAND_HZ`].
    pub band_mean: Option<f64>,
}

/// Every point's coherence with each other point; `points` has each point's name, series and
/// peak frequency.
pub fn pair_coherences(points: &[(&str, Series<'_>, Option<f64>)]) -> Vec<Vec<PairCoherence>> {
    points
        .iter()
        .enumerate()
        .map(|(i, (_, a, peak_hz))| {
            points
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, (name, b, _))| {
                    let c = series_coherence(*a, *b);
                    PairCoherence {
                        with: name.to_string(),
                        at_peak: c.as_ref().zip(*peak_hz).and_then(|(c, f)| c.at(f)),
                        band_mean: c.as_ref().and_then(|c| c.band_mean(COHERENCE_BAND_HZ)),
                    }
                })
                .collect()
        })
        .collect()
}

/// The coherence with the other points in one line ("—" where a figure cannot be given);
/// `None` for a single point.
pub fn coherence_line(pairs: &[PairCoherence]) -> Option<String> {
    let value = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.2}"));
    let parts: Vec<String> = pairs
        .iter()
        .map(|c| {
            format!(
                "{}: {} at the peak, {} over 2–12 Hz",
                c.with,
                value(c.at_peak),
                value(c.band_mean)
            )
        })
        .collect();
    (!parts.is_empty()).then(|| format!("coherence with {}", parts.join(" · ")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    const RATE: f64 = 121.0;

    /// Deterministic noise, uniform in [−1, 1].
    fn noise(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn coherence_of_related_and_unrelated_records() {
        let n = (30.0 * RATE) as usize;
        let (a, b) = (noise(1, n), noise(2, n));
        let tremor = |phase: f64| -> Vec<f64> {
            (0..n)
                .map(|i| (TAU * 5.0 * i as f64 / RATE + phase).sin())
                .collect()
        };
        // Two points sharing a 5 Hz tremor at a fixed phase lag, each with its own noise.
        let (t0, t1) = (tremor(0.0), tremor(1.2));
        let x: Vec<f64> = t0.iter().zip(&a).map(|(t, e)| t + 0.3 * e).collect();
        let y: Vec<f64> = t1.iter().zip(&b).map(|(t, e)| t + 0.3 * e).collect();
        let c = coherence(&x, &y, RATE, 2 * RATE as usize).unwrap();
        assert!(c.at(5.0).unwrap() > 0.95, "{:?}", c.at(5.0));
        // Noise against noise: the coherence's bias for K segments is about 1/K.
        let c = coherence(&a, &b, RATE, 2 * RATE as usize).unwrap();
        let mean = c.band_mean(COHERENCE_BAND_HZ).unwrap();
        assert!(
            mean < 3.0 / c.segments as f64,
            "{mean} over {} segments",
            c.segments
        );
        // Too short for four segments: no figure.
        assert_eq!(
            coherence(&x[..300], &y[..300], RATE, 2 * RATE as usize),
            None
        );
    }

    #[test]
    fn tracked_points_are_compared_where_both_were_measured() {
        let n = (10.0 * RATE) as usize;
        let times: Vec<f64> = (0..n).map(|i| i as f64 / RATE).collect();
        let (ea, eb) = (noise(3, n), noise(4, n));
        let wave = |i: usize, phase: f64| (TAU * 5.0 * i as f64 / RATE + phase).sin();
        // The fingertip misses its first half second and a later stretch; the wrist moves with
        // it, lagging, misses other windows and was placed a second later.
        let tip: Vec<Option<f64>> = (0..n)
            .map(|i| (i >= 60 && !(400..440).contains(&i)).then(|| wave(i, 0.0) + 0.3 * ea[i]))
            .collect();
        let wrist: Vec<Option<f64>> = (121..n)
            .map(|i| (i % 17 != 0).then(|| 0.4 * wave(i, 0.8) + 0.1 * eb[i]))
            .collect();
        let unrelated: Vec<Option<f64>> = eb.iter().map(|e| Some(*e)).collect();
        let (tip, wrist) = (
            Series {
                times_s: &times,
                displacement_mm: &tip,
            },
            Series {
                times_s: &times[121..],
                displacement_mm: &wrist,
            },
        );
        let c = series_coherence(tip, wrist).expect("coherence");
        assert!(c.at(5.0).expect("5 Hz") > 0.9, "{:?}", c.at(5.0));
        let pairs = pair_coherences(&[
            ("tip", tip, Some(5.0)),
            ("wrist", wrist, Some(5.0)),
            (
                "noise",
                Series {
                    times_s: &times,
                    displacement_mm: &unrelated,
                },
                None,
            ),
        ]);
        assert_eq!(pairs.len(), 3);
        assert_eq!(pairs[0][0].with, "wrist");
        assert!(pairs[0][0].at_peak.expect("at the peak") > 0.9);
        assert!(
            pairs[0][1].band_mean.expect("band") < 0.3,
            "{:?}",
            pairs[0][1]
        );
        // Without a peak there is no value at the peak, and a point measured in under half of
        // the instants gives no coherence at all.
        assert_eq!(pairs[2][0].at_peak, None);
        let sparse: Vec<Option<f64>> = (0..n).map(|i| (i % 3 == 0).then_some(1.0)).collect();
        let sparse = Series {
            times_s: &times,
            displacement_mm: &sparse,
        };
        assert_eq!(series_coherence(tip, sparse), None);
    }
}
