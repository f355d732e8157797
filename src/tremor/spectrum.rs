//! Spectral tools for displacement series: resampling irregular, gappy samples onto a uniform
//! grid, Welch's power spectral density, band power, sub-bin peak refinement and an FFT band-pass.
//!
//! - **Resampling**: the true time stamps are kept; the uniform grid (at the median sample
//!   interval) is filled by linear interpolation between the valid samples around each grid
//!   point. What was missing is reported: the share of valid samples and the longest gap.
//! - **Welch**: Hann-windowed segments with 50 % overlap, each with its mean and linear trend
//!   removed, averaged periodograms, one-sided density in mm²/Hz (so that the integral over
//!   frequency is the variance; a sinusoid of amplitude A integrates to A²/2).
//! - **Peak refinement**: the peak's frequency is refined by maximising the periodogram of the
//!   whole record over a continuous frequency near the Welch peak (golden-section search), which
//!   is the least-squares single-sinusoid fit of the record; its resolution is not limited by the
//!   Welch bin width.

use realfft::RealFftPlanner;

/// A uniform series from irregular samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    pub rate_hz: f64,
    pub start_s: f64,
    pub values: Vec<f64>,
    /// Valid samples over the grid's length (samples a regular series of this span holds), at
    /// most 1: frames lost before they became samples count as missing too.
    pub valid_fraction: f64,
    /// Longest stretch without a valid sample, seconds (between the valid neighbours).
    pub longest_gap_s: f64,
    /// Per grid sample: whether a valid sample lies within half an interval of it (false where
    /// the value was interpolated across a gap).
    pub measured: Vec<bool>,
}

/// Puts `(time_s, value)` samples (`None` = invalid) on a uniform grid at the median interval of
/// the time stamps. `None` with fewer than 4 valid samples or no positive interval.
pub fn resample(times_s: &[f64], values: &[Option<f64>]) -> Option<Resampled> {
    let mut dt: Vec<f64> = times_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if dt.is_empty() {
        return None;
    }
    dt.sort_by(f64::total_cmp);
    let interval = dt[dt.len() / 2];
    let valid: Vec<(f64, f64)> = times_s
        .iter()
        .zip(values)
        .filter_map(|(&t, v)| v.map(|v| (t, v)))
        .filter(|(t, v)| t.is_finite() && v.is_finite())
        .collect();
    if valid.len() < 4 {
        return None;
    }
    let (start, end) = (valid[0].0, valid[valid.len() - 1].0);
    // A hair of tolerance so that a regular series keeps its last sample despite rounding.
    let n = ((end - start) / interval + 1e-6).floor() as usize + 1;
    let mut out = Vec::with_capacity(n);
    let mut measured = Vec::with_capacity(n);
    let mut k = 0;
    for i in 0..n {
        let t = start + i as f64 * interval;
        while k + 1 < valid.len() && valid[k + 1].0 < t {
            k += 1;
        }
        let (t0, v0) = valid[k];
        let (t1, v1) = valid[(k + 1).min(valid.len() - 1)];
        measured.push((t - t0).abs().min((t1 - t).abs()) <= 0.5 * interval);
        let value = if t1 > t0 {
            v0 + (v1 - v0) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            v0
        };
        out.push(value);
    }
    // Gaps between consecutive valid samples, less the one interval a regular series has.
    let longest_gap_s = valid
        .windows(2)
        .map(|w| w[1].0 - w[0].0 - interval)
        .fold(0.0, f64::max)
        .max(0.0);
    Some(Resampled {
        rate_hz: 1.0 / interval,
        start_s: start,
        values: out,
        valid_fraction: (valid.len() as f64 / n as f64).min(1.0),
        longest_gap_s,
        measured,
    })
}

/// Removes the mean and the least-squares line.
pub fn detrend_linear(x: &mut [f64]) {
    let n = x.len() as f64;
    if x.len() < 2 {
        return;
    }
    let tm = (n - 1.0) / 2.0;
    let xm = x.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in x.iter().enumerate() {
        let dt = i as f64 - tm;
        sxy += dt * (v - xm);
        sxx += dt * dt;
    }
    let slope = sxy / sxx;
    for (i, v) in x.iter_mut().enumerate() {
        *v -= xm + slope * (i as f64 - tm);
    }
}

/// A one-sided power spectral density.
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    pub frequency_hz: Vec<f64>,
    pub density: Vec<f64>,
    /// Segments averaged.
    pub segments: usize,
}

impl Psd {
    pub fn resolution_hz(&self) -> f64 {
        self.frequency_hz.get(1).copied().unwrap_or(0.0)
    }

    /// Integral of the density over `[lo, hi]` Hz (bins whose centre lies inside).
    pub fn band_power(&self, lo: f64, hi: f64) -> f64 {
        let df = self.resolution_hz();
        self.frequency_hz
            .iter()
            .zip(&self.density)
            .filter(|(f, _)| **f >= lo && **f <= hi)
            .map(|(_, d)| d * df)
            .sum()
    }
}

/// Welch's method with `segment` samples per Hann-windowed segment, 50 % overlap, zero-padded
/// to `nfft` (≥ `segment`). `None` when the series is shorter than one segment.
pub fn welch(x: &[f64], rate_hz: f64, segment: usize, nfft: usize) -> Option<Psd> {
    if segment < 8 || x.len() < segment {
        return None;
    }
    let nfft = nfft.max(segment);
    let window: Vec<f64> = (0..segment)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / segment as f64).cos())
        .collect();
    let window_power: f64 = window.iter().map(|w| w * w).sum();
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(nfft);
    let mut input = fft.make_input_vec();
    let mut spectrum = fft.make_output_vec();
    let mut density = vec![0.0; nfft / 2 + 1];
    let hop = segment / 2;
    let mut segments = 0;
    let mut start = 0;
    while start + segment <= x.len() {
        let mut seg = x[start..start + segment].to_vec();
        detrend_linear(&mut seg);
        input.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..segment {
            input[i] = seg[i] * window[i];
        }
        fft.process(&mut input, &mut spectrum).ok()?;
        for (d, c) in density.iter_mut().zip(&spectrum) {
            *d += c.norm_sqr();
        }
        segments += 1;
        start += hop;
    }
    let last = density.len() - 1;
    for (k, d) in density.iter_mut().enumerate() {
        // One-sided: double every bin but DC and (for even nfft) Nyquist.
        let two = if k == 0 || (k == last && nfft.is_multiple_of(2)) {
            1.0
        } else {
            2.0
        };
        *d *= two / (rate_hz * window_power * segments as f64);
    }
    let frequency_hz = (0..density.len())
        .map(|k| k as f64 * rate_hz / nfft as f64)
        .collect();
    Some(Psd {
        frequency_hz,
        density,
        segments,
    })
}

/// |Σ x[n]·e^(−iωn)|² of a (detrended) record at frequency `f` Hz.
fn periodogram_at(x: &[f64], rate_hz: f64, f: f64) -> f64 {
    let w = std::f64::consts::TAU * f / rate_hz;
    let (mut re, mut im) = (0.0, 0.0);
    for (n, v) in x.iter().enumerate() {
        let (s, c) = (w * n as f64).sin_cos();
        re += v * c;
        im -= v * s;
    }
    re * re + im * im
}

/// The frequency in `[f0 − half_width, f0 + half_width]` maximising the record's periodogram
/// (golden-section search; the periodogram is unimodal within a bin of the main lobe).
pub fn refine_peak(x: &[f64], rate_hz: f64, f0: f64, half_width: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = ((f0 - half_width).max(0.0), f0 + half_width);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (periodogram_at(x, rate_hz, c), periodogram_at(x, rate_hz, d));
    for _ in 0..60 {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = periodogram_at(x, rate_hz, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = periodogram_at(x, rate_hz, d);
        }
    }
    0.5 * (a + b)
}

/// Amplitude response of an `taps`-sample moving average at `f` Hz (the Dirichlet kernel).
pub fn moving_average_gain(taps: usize, f: f64, rate_hz: f64) -> f64 {
    let x = std::f64::consts::PI * f / rate_hz;
    if taps <= 1 || x.sin().abs() < 1e-12 {
        return 1.0;
    }
    (taps as f64 * x).sin() / (taps as f64 * x.sin())
}

/// Zero-phase band-pass by the FFT of the whole record: bins outside `[lo, hi]` Hz are zeroed.
pub fn band_pass(x: &[f64], rate_hz: f64, lo: f64, hi: f64) -> Vec<f64> {
    band_pass_compensated(x, rate_hz, lo, hi, 1)
}

/// [`band_pass`], dividing each kept bin by the gain of a `taps`-sample moving average (undoes
/// the averaging of a sliding decode window over the band).
pub fn band_pass_compensated(x: &[f64], rate_hz: f64, lo: f64, hi: f64, taps: usize) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return x.to_vec();
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let mut input = x.to_vec();
    let mut spectrum = forward.make_output_vec();
    if forward.process(&mut input, &mut spectrum).is_err() {
        return vec![0.0; n];
    }
    for (k, c) in spectrum.iter_mut().enumerate() {
        let f = k as f64 * rate_hz / n as f64;
        if f < lo || f > hi {
            *c = realfft::num_complex::Complex::new(0.0, 0.0);
        } else {
            *c /= moving_average_gain(taps, f, rate_hz);
        }
    }
    // The inverse needs real DC and Nyquist bins; they are zero or real already.
    if let Some(first) = spectrum.first_mut() {
        first.im = 0.0;
    }
    if n.is_multiple_of(2) {
        if let Some(last) = spectrum.last_mut() {
            last.im = 0.0;
        }
    }
    let mut out = inverse.make_output_vec();
    if inverse.process(&mut spectrum, &mut out).is_err() {
        return vec![0.0; n];
    }
    out.iter().map(|v| v / n as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic standard normal draws (Box–Muller over a SplitMix64 stream).
    fn normals(n: usize, seed: u64) -> Vec<f64> {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let (u1, u2) = (next().max(1e-300), next());
                (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            })
            .collect()
    }

    #[test]
    fn white_noise_has_the_closed_form_flat_density() {
        // σ² spread over 0..fs/2 one-sided: density 2σ²/fs.
        let (fs, sigma) = (121.0, 0.3);
        let x: Vec<f64> = normals(121 * 200, 3).iter().map(|v| v * sigma).collect();
        let psd = welch(&x, fs, 256, 256).unwrap();
        let expected = 2.0 * sigma * sigma / fs;
        let inner = &psd.density[5..psd.density.len() - 5];
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        // ~188 segments: each bin's estimate has a relative spread of about 1/√188 ≈ 7 %; the
        // mean over ~118 bins is within 2 %.
        assert!((mean / expected - 1.0).abs() < 0.02, "{mean} vs {expected}");
        // Parseval: the density integrates to the variance.
        let total = psd.band_power(0.0, fs / 2.0);
        assert!((total / (sigma * sigma) - 1.0).abs() < 0.03, "{total}");
    }

    #[test]
    fn a_sinusoid_integrates_to_half_its_squared_amplitude() {
        let (fs, f, a) = (121.0, 5.3, 2.0);
        let x: Vec<f64> = (0..121 * 20)
            .map(|n| a * (std::f64::consts::TAU * f * n as f64 / fs + 0.4).sin())
            .collect();
        let psd = welch(&x, fs, 242, 1024).unwrap();
        let p = psd.band_power(4.0, 6.5);
        assert!((p / (a * a / 2.0) - 1.0).abs() < 0.01, "{p}");
        let (k, _) = psd
            .density
            .iter()
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(y.1))
            .unwrap();
        let refined = refine_peak(&x, fs, psd.frequency_hz[k], psd.resolution_hz());
        assert!((refined - f).abs() < 1e-3, "{refined}");
    }

    #[test]
    fn resampling_reports_what_was_missing() {
        let times: Vec<f64> = (0..100).map(|i| i as f64 / 100.0).collect();
        let values: Vec<Option<f64>> = (0..100)
            .map(|i| (!(40..45).contains(&i)).then_some(i as f64))
            .collect();
        let r = resample(&times, &values).unwrap();
        assert_eq!(r.values.len(), 100);
        assert!((r.valid_fraction - 0.95).abs() < 1e-12);
        assert!((r.longest_gap_s - 0.05).abs() < 1e-9, "{}", r.longest_gap_s);
        // A line is interpolated exactly across the gap.
        assert!((r.values[42] - 42.0).abs() < 1e-9);
    }

    #[test]
    fn band_pass_keeps_the_band_and_removes_drift() {
        let fs = 121.0;
        let x: Vec<f64> = (0..1210)
            .map(|n| {
                let t = n as f64 / fs;
                (std::f64::consts::TAU * 5.0 * t).sin()
                    + 3.0 * (std::f64::consts::TAU * 0.2 * t).sin()
            })
            .collect();
        let y = band_pass(&x, fs, 3.0, 12.0);
        let rms = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
        assert!((rms - 0.5f64.sqrt()).abs() < 0.01, "{rms}");
    }
}
