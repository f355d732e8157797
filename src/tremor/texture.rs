//! The image a control point follows: the skin's texture with its shading taken out. The
//! decoded offset image (the scene without the pattern: the cloud's colour) as the logarithm of
//! its luminance `R + G + B`, less that logarithm's mean over the surrounding 7×7 pixels.
//! Brightness is albedo times shading, so the logarithm makes it a sum, and the local mean
//! removes the shading, which varies smoothly across a finger and changes as the hand rolls
//! towards or away from the projector; what remains is the albedo's fine pattern, which the
//! skin carries with it. The box mean runs on column sums, O(1) per pixel, into buffers the
//! caller keeps between clouds.

use crate::triangulate::PointCloud;

/// Half size of the box whose mean log luminance is taken out (3 → 7×7).
const SHADING_RADIUS_PX: usize = 3;

/// A cloud's texture image: log luminance less its local mean (caller-allocated, reused).
#[derive(Debug, Clone, Default)]
pub struct TextureImage {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
    log: Vec<f32>,
    column_sums: Vec<f32>,
}

impl TextureImage {
    /// Fills `self` from `cloud`'s colour: box sums by running column sums, O(1) per pixel.
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
