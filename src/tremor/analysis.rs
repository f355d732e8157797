//! Clinical tremor figures of one displacement series. Measured figures with their definitions,
//! not a diagnosis.
//!
//! 1. The series is put on a uniform grid at its median sample interval ([`resample`]), the true
//!    time stamps kept and what was missing reported.
//! 2. Drift: the mean and linear trend are removed from the record and from each Welch segment;
//!    for the amplitude figures the record is band-passed to the tremor band (3–12 Hz by
//!    default) by zeroing FFT bins outside it, which removes all drift below 3 Hz.
//! 3. Spectrum: Welch, Hann, 50 % overlap, 2 s segments (or the whole record if shorter), in
//!    mm²/Hz. Band powers integrate it over 3–12 Hz and 4–6 Hz (mm²).
//! 4. Peak: the highest Welch bin in the band, refined by the record's periodogram maximum
//!    ([`refine_peak`]). A peak is reported only when the band-passed RMS reaches
//!    `significance_rms_mm` and the peak bin stands `peak_to_median` times above the band's
//!    median density; otherwise there is no tremor peak.
//! 5. Amplitude: RMS of the band-passed record; peak-to-peak as the median over 1 s windows of
//!    (max − min) of the band-passed record (a sinusoid of amplitude A gives 2A and A/√2), both
//!    over measured samples only (not those interpolated across gaps), and both compensated
//!    for the decode window's averaging (`window_frames`).
//! 6. Occupancy: the share of 1 s windows (hop 0.5 s) whose band-passed RMS reaches the
//!    significance level. Frequency stability: the standard deviation of 1/period over
//!    consecutive upward zero crossings of the band-passed record.
//! 7. No figure from too little data: a record of which less than half was measured, or in
//!    which no 1 s window has half of its samples measured, gets
//!    [`TremorError::TooFewValid`] saying so, never a peak-to-peak of 0 mm.
//! 8. The measures of [`super::measures`]: the tremor stability index of the band-passed
//!    record, the peak's half-power bandwidth and its first harmonic's relative power, and the
//!    TETRAS amplitude rating.
//! 9. Labels: the MDS-UPDRS amplitude bin of the peak-to-peak amplitude (0: no tremor peak,
//!    1: < 1 cm, 2: 1–3 cm, 3: 3–10 cm, 4: ≥ 10 cm) and the usual bands containing the peak:
//!    parkinsonian rest 3–7 Hz, essential 4–12 Hz, physiological 8–12 Hz.

use super::measures::{
    half_power_bandwidth, harmonic_relative_power, tetras_amplitude_rating, tremor_stability_index,
};
use super::spectrum::{
    band_pass_compensated, detrend_linear, moving_average_gain, refine_peak, resample, welch, Psd,
};
use super::TremorError;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalysisOptions {
    pub band_hz: (f64, f64),
    pub narrow_band_hz: (f64, f64),
    pub segment_s: f64,
    /// Band-passed RMS a tremor must reach (see `docs/accuracy.md` for the noise floor).
    pub significance_rms_mm: f64,
    pub peak_to_median: f64,
    /// Frames per decode window (3 for CPS), whose averaging of the moving surface attenuates
    /// the tremor by the moving-average gain (2.5 % at 5.3 Hz and 121 FPS); amplitudes and the
    /// spectrum are divided by it. 1 turns the compensation off (e.g. for exact truth series).
    pub window_frames: usize,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self {
            band_hz: (3.0, 12.0),
            narrow_band_hz: (4.0, 6.0),
            segment_s: 2.0,
            significance_rms_mm: 0.1,
            peak_to_median: 5.0,
            window_frames: 3,
        }
    }
}

/// The figures of one series.
#[derive(Debug, Clone, PartialEq)]
pub struct TremorReport {
    pub duration_s: f64,
    pub rate_hz: f64,
    pub valid_fraction: f64,
    pub longest_gap_s: f64,
    pub peak_frequency_hz: Option<f64>,
    /// Every significant local peak in the band, strongest first.
    pub peaks_hz: Vec<f64>,
    pub amplitude_peak_to_peak_mm: f64,
    pub amplitude_rms_mm: f64,
    pub band_power_mm2: f64,
    pub narrow_band_power_mm2: f64,
    pub occupancy: f64,
    pub frequency_stability_hz: Option<f64>,
    pub updrs_amplitude_bin: u8,
    /// The TETRAS upper-limb amplitude rating ([`super::measures`]).
    pub tetras_amplitude_rating: &'static str,
    /// Tremor stability index, Hz (`None`: too few cycles).
    pub tremor_stability_index_hz: Option<f64>,
    /// Half-power bandwidth of the peak, Hz (`None` without a peak).
    pub half_power_bandwidth_hz: Option<f64>,
    /// The first harmonic's power relative to the peak's (`None` without a peak).
    pub harmonic_relative_power: Option<f64>,
    pub frequency_bands: Vec<&'static str>,
    pub spectrum: Psd,
}

impl TremorReport {
    /// The field's measures in one line: the amplitude in cm with its TETRAS rating, the
    /// share of time with tremor, TSI, bandwidth, harmonic power; a measure the record cannot
    /// give is "—".
    pub fn measures_line(&self) -> String {
        let hz = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.2} Hz"));
        format!(
            "{:.2} cm, TETRAS amplitude {} · tremor {:.0} % of the time · TSI {} · half-power bandwidth {} · 1st harmonic {}",
            self.amplitude_peak_to_peak_mm / 10.0,
            self.tetras_amplitude_rating,
            100.0 * self.occupancy,
            hz(self.tremor_stability_index_hz),
            hz(self.half_power_bandwidth_hz),
            self.harmonic_relative_power
                .map_or("—".to_string(), |p| format!("{:.1} %", 100.0 * p)),
        )
    }
}

/// The least share of valid samples a record needs for figures.
pub const MIN_VALID_FRACTION: f64 = 0.5;

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

/// Analyses displacements (mm, `None` where invalid) sampled at `times_s`.
pub fn analyze(
    times_s: &[f64],
    displacement_mm: &[Option<f64>],
    options: &AnalysisOptions,
) -> Result<TremorReport, TremorError> {
    if times_s.len() != displacement_mm.len() {
        return Err(TremorError::Lengths {
            times: times_s.len(),
            values: displacement_mm.len(),
        });
    }
    let series = resample(times_s, displacement_mm).ok_or(TremorError::TooFewSamples {
        valid: displacement_mm.iter().flatten().count(),
    })?;
    if series.valid_fraction < MIN_VALID_FRACTION {
        return Err(TremorError::TooFewValid {
            why: format!(
                "only {:.0} % of the samples are valid; at least {:.0} % are needed",
                100.0 * series.valid_fraction,
                100.0 * MIN_VALID_FRACTION
            ),
        });
    }
    let fs = series.rate_hz;
    // Above Nyquist the band would fold back onto itself: refuse rather than report aliases.
    if fs < 2.0 * options.band_hz.1 {
        return Err(TremorError::RateTooLow {
            rate_hz: fs,
            band_hi_hz: options.band_hz.1,
            needed_hz: 2.0 * options.band_hz.1,
        });
    }
    let mut x = series.values.clone();
    detrend_linear(&mut x);
    let duration_s = x.len() as f64 / fs;
    let segment = ((options.segment_s * fs).round() as usize).min(x.len());
    let nfft = (8 * segment).next_power_of_two();
    let mut psd = welch(&x, fs, segment, nfft).ok_or(TremorError::TooShort { duration_s })?;
    for (d, f) in psd.density.iter_mut().zip(&psd.frequency_hz) {
        let gain = moving_average_gain(options.window_frames, *f, fs);
        if gain.abs() > 0.1 {
            *d /= gain * gain;
        }
    }
    let (lo, hi) = options.band_hz;
    let y = band_pass_compensated(&x, fs, lo, hi, options.window_frames);
    // Amplitudes from the measured samples only: values interpolated across gaps are lower
    // than the motion they replace.
    let measured: Vec<f64> = y
        .iter()
        .zip(&series.measured)
        .filter_map(|(v, m)| m.then_some(*v))
        .collect();
    let amplitude_rms_mm = rms(&measured);
    let second = (fs.round() as usize).max(2).min(y.len());
    let mut p2p: Vec<f64> = y
        .chunks(second)
        .zip(series.measured.chunks(second))
        .filter(|(c, _)| c.len() == second)
        .filter_map(|(c, m)| {
            let kept: Vec<f64> = c
                .iter()
                .zip(m)
                .filter_map(|(v, m)| m.then_some(*v))
                .collect();
            let max = kept.iter().copied().fold(f64::MIN, f64::max);
            let min = kept.iter().copied().fold(f64::MAX, f64::min);
            (kept.len() * 2 >= second).then_some(max - min)
        })
        .collect();
    p2p.sort_by(f64::total_cmp);
    let Some(&amplitude_peak_to_peak_mm) = p2p.get(p2p.len() / 2) else {
        return Err(TremorError::TooFewValid {
            why: format!(
                "no 1 s window has at least half of its samples valid ({:.0} % valid overall)",
                100.0 * series.valid_fraction
            ),
        });
    };
    let peaks_hz = significant_peaks(&psd, &x, fs, options, amplitude_rms_mm);
    let peak_frequency_hz = peaks_hz.first().copied();
    let hop = (second / 2).max(1);
    let windows: Vec<f64> = (0..)
        .map(|k| k * hop)
        .take_while(|s| s + second <= y.len())
        .map(|s| rms(&y[s..s + second]))
        .collect();
    let occupancy = if windows.is_empty() {
        0.0
    } else {
        windows
            .iter()
            .filter(|r| **r >= options.significance_rms_mm)
            .count() as f64
            / windows.len() as f64
    };
    let frequency_stability_hz = cycle_frequency_spread(&y, fs);
    let updrs_amplitude_bin = match (peak_frequency_hz, amplitude_peak_to_peak_mm / 10.0) {
        (None, _) => 0,
        (Some(_), cm) if cm < 1.0 => 1,
        (Some(_), cm) if cm < 3.0 => 2,
        (Some(_), cm) if cm < 10.0 => 3,
        _ => 4,
    };
    let frequency_bands = peak_frequency_hz.map_or_else(Vec::new, |f| {
        [
            ("parkinsonian rest 3-7 Hz", 3.0, 7.0),
            ("essential 4-12 Hz", 4.0, 12.0),
            ("physiological 8-12 Hz", 8.0, 12.0),
        ]
        .into_iter()
        .filter(|(_, lo, hi)| f >= *lo && f <= *hi)
        .map(|(name, _, _)| name)
        .collect()
    });
    Ok(TremorReport {
        duration_s,
        rate_hz: fs,
        valid_fraction: series.valid_fraction,
        longest_gap_s: series.longest_gap_s,
        peak_frequency_hz,
        peaks_hz,
        amplitude_peak_to_peak_mm,
        amplitude_rms_mm,
        band_power_mm2: psd.band_power(lo, hi),
        narrow_band_power_mm2: psd.band_power(options.narrow_band_hz.0, options.narrow_band_hz.1),
        occupancy,
        frequency_stability_hz,
        updrs_amplitude_bin,
        tetras_amplitude_rating: tetras_amplitude_rating(
            amplitude_peak_to_peak_mm,
            peak_frequency_hz.is_some(),
        ),
        tremor_stability_index_hz: tremor_stability_index(&y, fs),
        half_power_bandwidth_hz: peak_frequency_hz.and_then(|f| half_power_bandwidth(&psd, f)),
        harmonic_relative_power: peak_frequency_hz.and_then(|f| harmonic_relative_power(&psd, f)),
        frequency_bands,
        spectrum: psd,
    })
}

/// Local maxima of the density inside the band that pass the significance tests, refined.
fn significant_peaks(
    psd: &Psd,
    x: &[f64],
    fs: f64,
    options: &AnalysisOptions,
    band_rms_mm: f64,
) -> Vec<f64> {
    if band_rms_mm < options.significance_rms_mm {
        return Vec::new();
    }
    let (lo, hi) = options.band_hz;
    let inside: Vec<usize> = (0..psd.frequency_hz.len())
        .filter(|&k| psd.frequency_hz[k] >= lo && psd.frequency_hz[k] <= hi)
        .collect();
    let mut band: Vec<f64> = inside.iter().map(|&k| psd.density[k]).collect();
    band.sort_by(f64::total_cmp);
    let Some(&max) = band.last() else {
        return Vec::new();
    };
    let median = band[band.len() / 2];
    let d = &psd.density;
    let mut peaks: Vec<(f64, usize)> = inside
        .iter()
        .copied()
        .filter(|&k| k > 0 && k + 1 < d.len() && d[k] >= d[k - 1] && d[k] > d[k + 1])
        .filter(|&k| d[k] >= options.peak_to_median * median && d[k] >= 0.05 * max)
        .map(|k| (d[k], k))
        .collect();
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    // The Welch main lobe of a Hann window spans ±2 bins of the unpadded segment.
    let lobe = 2.0 * fs / (options.segment_s * fs).round().max(1.0);
    let mut kept: Vec<f64> = Vec::new();
    for (_, k) in peaks {
        let f = refine_peak(
            x,
            fs,
            psd.frequency_hz[k],
            psd.resolution_hz().max(1e-6) * 2.0,
        );
        if kept.iter().all(|g| (g - f).abs() > lobe) {
            kept.push(f);
        }
    }
    kept
}

/// Standard deviation of 1/period over consecutive upward zero crossings (linearly
/// interpolated); `None` with fewer than three periods.
fn cycle_frequency_spread(y: &[f64], fs: f64) -> Option<f64> {
    let crossings: Vec<f64> = y
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < 0.0 && w[1] >= 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) / fs)
        .collect();
    let freqs: Vec<f64> = crossings.windows(2).map(|c| 1.0 / (c[1] - c[0])).collect();
    if freqs.len() < 3 {
        return None;
    }
    let mean = freqs.iter().sum::<f64>() / freqs.len() as f64;
    Some((freqs.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / (freqs.len() - 1) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_series_sampled_below_twice_the_band_is_refused() {
        // 10 Hz sampling: the 3–12 Hz band needs at least 24 Hz.
        let times: Vec<f64> = (0..100).map(|i| i as f64 / 10.0).collect();
        let values: Vec<Option<f64>> = times.iter().map(|t| Some((5.3 * t).sin())).collect();
        let e = analyze(&times, &values, &AnalysisOptions::default());
        assert!(
            matches!(e, Err(TremorError::RateTooLow { rate_hz, .. }) if (rate_hz - 10.0).abs() < 0.1),
            "{e:?}"
        );
    }

    /// Synthetic series are exact: no decode window to compensate.
    fn exact() -> AnalysisOptions {
        AnalysisOptions {
            window_frames: 1,
            ..AnalysisOptions::default()
        }
    }

    fn series(f: impl Fn(f64) -> f64, seconds: f64) -> (Vec<f64>, Vec<Option<f64>>) {
        let n = (seconds * 121.0) as usize;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / 121.0).collect();
        let v = t.iter().map(|&t| Some(f(t))).collect();
        (t, v)
    }

    #[test]
    fn a_pure_tremor_gives_its_frequency_and_amplitudes() {
        let (t, v) = series(
            |t| 2.0 * (std::f64::consts::TAU * 5.3 * t + 0.3).sin() + 0.4 * t,
            3.0,
        );
        let r = analyze(&t, &v, &exact()).unwrap();
        let f = r.peak_frequency_hz.unwrap();
        assert!((f - 5.3).abs() < 0.01, "{f}");
        assert!(
            (r.amplitude_peak_to_peak_mm - 4.0).abs() < 0.1,
            "{}",
            r.amplitude_peak_to_peak_mm
        );
        assert!(
            (r.amplitude_rms_mm - 2.0 / 2f64.sqrt()).abs() < 0.05,
            "{}",
            r.amplitude_rms_mm
        );
        assert!((r.band_power_mm2 - 2.0).abs() < 0.2, "{}", r.band_power_mm2);
        assert_eq!(r.updrs_amplitude_bin, 1);
        assert_eq!(
            r.frequency_bands,
            vec!["parkinsonian rest 3-7 Hz", "essential 4-12 Hz"]
        );
        assert!(r.occupancy > 0.99);
        assert!(r.frequency_stability_hz.unwrap() < 0.1);
    }

    #[test]
    fn two_tones_give_two_peaks() {
        let (t, v) = series(
            |t| {
                1.5 * (std::f64::consts::TAU * 5.0 * t).sin()
                    + 0.8 * (std::f64::consts::TAU * 9.0 * t + 1.0).sin()
            },
            4.0,
        );
        let r = analyze(&t, &v, &exact()).unwrap();
        assert_eq!(r.peaks_hz.len(), 2, "{:?}", r.peaks_hz);
        assert!(
            (r.peaks_hz[0] - 5.0).abs() < 0.05 && (r.peaks_hz[1] - 9.0).abs() < 0.05,
            "{:?}",
            r.peaks_hz
        );
    }

    #[test]
    fn stillness_gives_no_peak() {
        let (t, v) = series(|t| 0.01 * (t * 1234.5).sin() + 0.3 * t, 3.0);
        let r = analyze(&t, &v, &exact()).unwrap();
        assert_eq!(r.peak_frequency_hz, None);
        assert_eq!(r.updrs_amplitude_bin, 0);
        assert!(r.frequency_bands.is_empty());
    }

    #[test]
    fn too_little_data_is_an_error() {
        let e = analyze(&[0.0, 0.1], &[Some(1.0), None], &exact()).unwrap_err();
        assert!(e.to_string().contains("valid"), "{e}");
    }

    #[test]
    fn a_mostly_missing_record_has_no_figures_rather_than_zero() {
        // A 14 mm peak-to-peak tremor of which only every third sample is valid (31 %).
        let (t, v) = series(|t| 7.0 * (std::f64::consts::TAU * 5.3 * t).sin(), 3.0);
        let sparse: Vec<Option<f64>> = v
            .iter()
            .enumerate()
            .map(|(i, v)| if i % 13 < 4 { *v } else { None })
            .collect();
        let e = analyze(&t, &sparse, &exact()).unwrap_err();
        let TremorError::TooFewValid { why } = &e else {
            panic!("{e}");
        };
        // The share is counted on the resampled grid, so it may differ from 4/13 by a sample
        // or two at either end of the record.
        let share: f64 = why
            .strip_prefix("only ")
            .and_then(|w| w.split(' ').next())
            .and_then(|p| p.parse().ok())
            .unwrap();
        assert!((share - 100.0 * 4.0 / 13.0).abs() <= 2.0, "{why}");
        assert!(why.contains("at least 50 %"), "{why}");
        // Enough data gives the figure.
        let r = analyze(&t, &v, &exact()).unwrap();
        assert!((r.amplitude_peak_to_peak_mm - 14.0).abs() < 0.3, "{r:?}");
    }
}
