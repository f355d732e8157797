//! The tremor measures used in the field, beyond peak frequency and amplitude. Each is a plain
//! function over a band-passed record or its spectrum, and each returns `None` rather than a
//! number when the record is too short for it. Definitions and sources (also in
//! `docs/accuracy.md`):
//!
//! - **Tremor stability index** (TSI; di Biase et al., *Brain* 2017): each cycle's frequency is
//!   1 / (time between consecutive upward zero crossings of the band-passed record, found by
//!   linear interpolation); TSI is the interquartile range of the change of frequency from one
//!   cycle to the next, Hz. Steady tremor (Parkinson's) gives small values, essential tremor
//!   larger ones. At least [`TSI_MIN_CHANGES`] changes are needed.
//! - **Half-power bandwidth** of the spectral peak: the width, Hz, of the frequency interval
//!   around the peak bin where the Welch density stays at or above half the peak's, its ends
//!   interpolated linearly between bins. `None` where the density does not fall to half within
//!   the spectrum.
//! - **First harmonic's relative power**: the power within ±[`HARMONIC_HALF_WIDTH_HZ`] (or one
//!   bin, if wider) of twice the peak frequency over the power within the same width of the
//!   peak. `None` where the harmonic lies beyond the Nyquist frequency.
//! - **TETRAS amplitude rating** (Elble et al., Tremor Research Group, *Mov. Disord.* 2012,
//!   upper-limb items): from the peak-to-peak amplitude in cm, 2 for 1–3 cm, 2.5 for 3–5, 3 for
//!   5–10, 3.5 for 10–20, 4 for 20 or more. Below 1 cm the scale separates 1 ("barely
//!   visible") from 1.5 by eye, not by a length, so the measure says "1–1.5"; with no tremor
//!   peak it is 0.
//! - **Magnitude-squared coherence** between two points: [`super::coherence`].

use super::spectrum::Psd;

/// Cycle-to-cycle changes a TSI needs.
pub const TSI_MIN_CHANGES: usize = 8;
/// Half width of the bands compared by the harmonic's relative power, Hz.
pub const HARMONIC_HALF_WIDTH_HZ: f64 = 0.5;

/// Times (s, from the record's start) of the upward zero crossings of `x`.
fn upward_crossings(x: &[f64], rate_hz: f64) -> Vec<f64> {
    x.windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < 0.0 && w[1] >= 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) / rate_hz)
        .collect()
}

/// The `q` quantile (0–1) of sorted `v`, linear between order statistics.
fn quantile(v: &[f64], q: f64) -> f64 {
    let pos = q * (v.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos.fract());
    if i + 1 < v.len() {
        v[i] + frac * (v[i + 1] - v[i])
    } else {
        v[i]
    }
}

/// Tremor stability index of a band-passed record sampled at `rate_hz`, Hz.
pub fn tremor_stability_index(band_passed: &[f64], rate_hz: f64) -> Option<f64> {
    let crossings = upward_crossings(band_passed, rate_hz);
    let frequencies: Vec<f64> = crossings.windows(2).map(|c| 1.0 / (c[1] - c[0])).collect();
    let mut changes: Vec<f64> = frequencies.windows(2).map(|f| f[1] - f[0]).collect();
    if changes.len() < TSI_MIN_CHANGES {
        return None;
    }
    changes.sort_by(f64::total_cmp);
    Some(quantile(&changes, 0.75) - quantile(&changes, 0.25))
}

/// Half-power bandwidth of the peak of `psd` nearest `peak_hz`, Hz.
pub fn half_power_bandwidth(psd: &Psd, peak_hz: f64) -> Option<f64> {
    let df = psd.resolution_hz();
    if df <= 0.0 || psd.density.is_empty() {
        return None;
    }
    // The highest bin within a bin of the peak.
    let near = (peak_hz / df).round() as usize;
    let k = (near.saturating_sub(1)..=(near + 1).min(psd.density.len() - 1))
        .max_by(|&a, &b| psd.density[a].total_cmp(&psd.density[b]))?;
    let half = psd.density[k] / 2.0;
    if half <= 0.0 {
        return None;
    }
    // Walk out to the first bin below half on each side, then interpolate.
    let edge = |step: isize| -> Option<f64> {
        let mut i = k as isize;
        loop {
            let next = i + step;
            if next < 0 || next as usize >= psd.density.len() {
                return None;
            }
            let (a, b) = (psd.density[i as usize], psd.density[next as usize]);
            if b < half {
                let t = (a - half) / (a - b);
                return Some(psd.frequency_hz[i as usize] + step as f64 * t * df);
            }
            i = next;
        }
    };
    Some(edge(1)? - edge(-1)?)
}

/// The first harmonic's power relative to the peak's.
pub fn harmonic_relative_power(psd: &Psd, peak_hz: f64) -> Option<f64> {
    let w = HARMONIC_HALF_WIDTH_HZ.max(psd.resolution_hz());
    let nyquist = *psd.frequency_hz.last()?;
    if 2.0 * peak_hz + w > nyquist {
        return None;
    }
    let fundamental = psd.band_power(peak_hz - w, peak_hz + w);
    (fundamental > 0.0).then(|| psd.band_power(2.0 * peak_hz - w, 2.0 * peak_hz + w) / fundamental)
}

/// The TETRAS upper-limb amplitude rating of a peak-to-peak amplitude (mm), or "0" without a
/// tremor peak.
pub fn tetras_amplitude_rating(peak_to_peak_mm: f64, has_peak: bool) -> &'static str {
    let cm = peak_to_peak_mm / 10.0;
    match () {
        _ if !has_peak => "0",
        _ if cm < 1.0 => "1–1.5",
        _ if cm < 3.0 => "2",
        _ if cm < 5.0 => "2.5",
        _ if cm < 10.0 => "3",
        _ if cm < 20.0 => "3.5",
        _ => "4",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tremor::spectrum::welch;
    use std::f64::consts::TAU;

    const RATE: f64 = 121.0;

    #[test]
    fn tsi_of_a_steady_tremor_is_near_zero_and_of_a_wandering_one_is_its_spread() {
        let n = (20.0 * RATE) as usize;
        let steady: Vec<f64> = (0..n)
            .map(|i| (TAU * 5.0 * i as f64 / RATE).sin())
            .collect();
        let tsi = tremor_stability_index(&steady, RATE).unwrap();
        assert!(tsi < 0.01, "{tsi}");
        // Each cycle's frequency alternates 4.5 / 5.5 Hz: the changes are ±1 Hz, half each,
        // so their interquartile range is 2 Hz.
        let mut x = Vec::new();
        let mut k = 0;
        while x.len() < n {
            let f = if k % 2 == 0 { 4.5 } else { 5.5 };
            let samples = (RATE / f).round() as usize;
            x.extend((0..samples).map(|i| (TAU * i as f64 / samples as f64).sin()));
            k += 1;
        }
        let tsi = tremor_stability_index(&x, RATE).unwrap();
        // The rounding to whole samples makes the cycles 22 and 27 samples: 5.5 and 4.48 Hz.
        let expected = 2.0 * (RATE / 22.0 - RATE / 27.0);
        assert!((tsi - expected).abs() < 0.05, "{tsi} against {expected}");
        // Too few cycles: no figure.
        assert_eq!(
            tremor_stability_index(&steady[..(2.0 * RATE) as usize], RATE),
            None
        );
    }

    #[test]
    fn bandwidth_and_harmonic_of_known_spectra() {
        // A chirp sweeping 4 → 6 Hz over 20 s spreads its power evenly over 2 Hz: the half-power
        // band is about 2 Hz wide.
        let n = (20.0 * RATE) as usize;
        let chirp: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / RATE;
                (TAU * (4.0 * t + 0.05 * t * t)).sin()
            })
            .collect();
        let psd = welch(&chirp, RATE, 4 * RATE as usize, 8 * RATE as usize).unwrap();
        let bw = half_power_bandwidth(&psd, 5.0).unwrap();
        assert!((bw - 2.0).abs() < 0.3, "{bw}");
        // A pure 5 Hz sine in a 4 s segment: the Hann main lobe's half-power width, about
        // 1.44 bins of 0.25 Hz.
        let sine: Vec<f64> = (0..n)
            .map(|i| (TAU * 5.0 * i as f64 / RATE).sin())
            .collect();
        let psd = welch(&sine, RATE, 4 * RATE as usize, 4 * RATE as usize).unwrap();
        let bw = half_power_bandwidth(&psd, 5.0).unwrap();
        assert!(bw > 0.25 && bw < 0.5, "{bw}");
        // Fundamental amplitude 1, harmonic 0.3: relative power 0.09.
        let both: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / RATE;
                (TAU * 5.0 * t).sin() + 0.3 * (TAU * 10.0 * t + 1.0).sin()
            })
            .collect();
        let psd = welch(&both, RATE, 4 * RATE as usize, 4 * RATE as usize).unwrap();
        let h = harmonic_relative_power(&psd, 5.0).unwrap();
        assert!((h - 0.09).abs() < 0.005, "{h}");
        assert_eq!(harmonic_relative_power(&psd, 40.0), None);
    }

    #[test]
    fn tetras_ratings_follow_the_scale() {
        assert_eq!(tetras_amplitude_rating(50.0, false), "0");
        assert_eq!(tetras_amplitude_rating(9.9, true), "1–1.5");
        assert_eq!(tetras_amplitude_rating(10.0, true), "2");
        assert_eq!(tetras_amplitude_rating(35.0, true), "2.5");
        assert_eq!(tetras_amplitude_rating(99.0, true), "3");
        assert_eq!(tetras_amplitude_rating(150.0, true), "3.5");
        assert_eq!(tetras_amplitude_rating(200.0, true), "4");
    }
}
