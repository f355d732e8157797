//! The image a control point follows: the skin's texture with its shading taken out. The
//! decoded offset image (the scene without the pattern: the cloud's colour) as the logarithm of
//! its luminance `R + G + B`, less that logarithm's mean over the surrounding 7×7 pixels.
//! Brightness is albedo times shading, so the logarithm makes it a sum, and the local mean
//! removes the shading, which varies smoothly across a finger and changes as the hand rolls
//! towards or away from the projector; what remains is the albedo's fine pattern, which the
//! skin carries with it. The box mean runs on column sums, O(1) per pixel, into buffers the
//! caller keeps between clouds.
//!
//! *Then low-passed* by the 5-tap binomial `[1, 4, 6, 4, 1]/16` (σ = 1 px) along rows and
//! columns, the smoothing Bouguet's pyramidal Lucas–Kanade tracker applies before matching:
//! the camera's noise is white, while skin texture that can be followed spans several pixels,
//! so the filter keeps the texture and passes 27 % of the noise's standard deviation. On the
//! rig's fingertip the decoded texture had about as much noise as texture (0.008 against
//! 0.008–0.013, log units, measured against a noiseless rendering); the fast fingertip of a
//! 10 mm tremor then lost its match in a quarter of the windows (`docs/accuracy.md`,
//! "Following the skin").

use crate::triangulate::PointCloud;

/// Half size of the box whose mean log luminance is taken out (3 → 7×7).
const SHADING_RADIUS_PX: usize = 3;

/// The low-pass taps (binomial, σ = 1 px).
const LOW_PASS: [f32; 5] = [0.0625, 0.25, 0.375, 0.25, 0.0625];

/// A cloud's texture image: log luminance less its local mean (caller-allocated, reused).
#[derive(Debug, Clone, Default)]
pub struct TextureImage {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
    log: Vec<f32>,
    column_sums: Vec<f32>,
}

/// The taps of [`LOW_PASS`] centred on sample `j` of a line of `len`: `(sample, weight)`, the
/// taps that fall outside the line left out and the rest renormalised.
fn low_pass_taps(j: usize, len: usize) -> impl Iterator<Item = (usize, f32)> {
    let half = LOW_PASS.len() / 2;
    let inside = move |k: usize| (j + k).checked_sub(half).filter(|&at| at < len);
    let total: f32 = (0..LOW_PASS.len())
        .filter(|&k| inside(k).is_some())
        .map(|k| LOW_PASS[k])
        .sum();
    (0..LOW_PASS.len()).filter_map(move |k| inside(k).map(|at| (at, LOW_PASS[k] / total)))
}

impl TextureImage {
    /// Fills `self` from `cloud`'s colour: box sums by running column sums, O(1) per pixel,
    /// then the low-pass along rows and columns.
    pub fn fill_from(&mut self, cloud: &PointCloud) {
        let (w, h) = (cloud.width, cloud.height);
        self.width = w;
        self.height = h;
        self.log.clear();
        self.log.extend(cloud.colour_rgb.iter().map(|c| {
            (f32::from(c[0]) + f32::from(c[1]) + f32::from(c[2]))
                .max(1.0)
                .ln()
        }));
        self.values.clear();
        self.values.resize(w * h, 0.0);
        if w == 0 || h == 0 {
            return;
        }
        let r = SHADING_RADIUS_PX;
        // Column sums over rows y−r..=y+r (clamped), updated row by row.
        self.column_sums.clear();
        self.column_sums.resize(w, 0.0);
        for y in 0..=r.min(h - 1) {
            for x in 0..w {
                self.column_sums[x] += self.log[y * w + x];
            }
        }
        for y in 0..h {
            let rows = (y + r).min(h - 1) + 1 - y.saturating_sub(r);
            let mut sum: f32 = self.column_sums[..=r.min(w - 1)].iter().sum();
            for x in 0..w {
                let cols = (x + r).min(w - 1) + 1 - x.saturating_sub(r);
                let mean = sum / (rows * cols) as f32;
                self.values[y * w + x] = self.log[y * w + x] - mean;
                if x + r + 1 < w {
                    sum += self.column_sums[x + r + 1];
                }
                if x >= r {
                    sum -= self.column_sums[x - r];
                }
            }
            if y + r + 1 < h {
                for x in 0..w {
                    self.column_sums[x] += self.log[(y + r + 1) * w + x];
                }
            }
            if y >= r {
                for x in 0..w {
                    self.column_sums[x] -= self.log[(y - r) * w + x];
                }
            }
        }
        // The low-pass: along rows into `log` (no longer needed), then down the columns back
        // into `values`, each output row a weighted sum of whole rows.
        let half = LOW_PASS.len() / 2;
        for (row, out) in self
            .values
            .chunks_exact(w)
            .zip(self.log.chunks_exact_mut(w))
        {
            // Inside the row the taps as they are (a loop that vectorises), at its ends
            // renormalised.
            for (o, taps) in out.iter_mut().skip(half).zip(row.windows(LOW_PASS.len())) {
                *o = LOW_PASS[0] * (taps[0] + taps[4])
                    + LOW_PASS[1] * (taps[1] + taps[3])
                    + LOW_PASS[2] * taps[2];
            }
            for x in (0..half.min(w)).chain(w.saturating_sub(half).max(half)..w) {
                out[x] = low_pass_taps(x, w).map(|(at, tap)| tap * row[at]).sum();
            }
        }
        for (y, out) in self.values.chunks_exact_mut(w).enumerate() {
            out.fill(0.0);
            for (at, tap) in low_pass_taps(y, h) {
                for (o, &v) in out.iter_mut().zip(&self.log[at * w..(at + 1) * w]) {
                    *o += tap * v;
                }
            }
        }
    }

    /// Bilinear sample at `(u, v)`, `None` outside the image.
    #[inline]
    pub(crate) fn sample(&self, u: f64, v: f64) -> Option<f64> {
        if !(u >= 0.0 && v >= 0.0) {
            return None;
        }
        let (x0, y0) = (u.floor() as usize, v.floor() as usize);
        if x0 + 1 >= self.width || y0 + 1 >= self.height {
            return None;
        }
        let (fx, fy) = (u - x0 as f64, v - y0 as f64);
        let i = y0 * self.width + x0;
        let at = |k: usize| f64::from(self.values[k]);
        let top = at(i) + fx * (at(i + 1) - at(i));
        let bottom = at(i + self.width) + fx * (at(i + self.width + 1) - at(i + self.width));
        Some(top + fy * (bottom - top))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud whose luminance is `600·exp(a·cos(2πx/λ))`, constant down the columns.
    fn wave(a: f64, wavelength_px: f64) -> PointCloud {
        let (w, h) = (64, 24);
        let colour_rgb = (0..w * h)
            .map(|i| {
                let x = (i % w) as f64;
                let l = 600.0 * (a * (std::f64::consts::TAU * x / wavelength_px).cos()).exp();
                [(l / 3.0).round() as u8; 3]
            })
            .collect();
        PointCloud {
            width: w,
            height: h,
            time_s: 0.0,
            point_in_camera_mm: vec![[0.0; 3]; w * h],
            colour_rgb,
            fringe_amplitude: vec![1.0; w * h],
        }
    }

    #[test]
    fn a_texture_wave_passes_the_shading_box_and_the_low_pass_as_their_responses_say() {
        for wavelength_px in [4.0, 6.0, 12.0, 24.0] {
            let (a, omega) = (0.1, std::f64::consts::TAU / wavelength_px);
            let mut image = TextureImage::default();
            image.fill_from(&wave(a, wavelength_px));
            // The 7-px box mean of cos(ωx) is B·cos(ωx); the binomial's gain is
            // (6 + 8·cos ω + 2·cos 2ω)/16.
            let box_gain = (3.5 * omega).sin() / (7.0 * (omega / 2.0).sin());
            let low_pass_gain = (6.0 + 8.0 * omega.cos() + 2.0 * (2.0 * omega).cos()) / 16.0;
            let gain = (1.0 - box_gain) * low_pass_gain;
            for y in [0, 11, 23] {
                for x in 6..58 {
                    let expected = a * gain * (omega * x as f64).cos();
                    let got = f64::from(image.values[y * image.width + x]);
                    // Each channel rounded to a whole level: at most 1.5 of 600 in the sum.
                    assert!(
                        (got - expected).abs() < 0.004,
                        "λ {wavelength_px}: {got} against {expected} at {x},{y}"
                    );
                }
            }
        }
    }
}
