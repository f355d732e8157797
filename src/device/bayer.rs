//! Bayer colour-filter mosaics to interleaved RGB, for cameras that stream raw Bayer data (most
//! colour machine-vision cameras do at full rate; RGB8 costs three times the link bandwidth).
//!
//! Bilinear demosaicing: at each pixel the colour it sampled is kept, and each missing colour is
//! the mean of the nearest samples of that colour (2 or 4 of them), with the image edge mirrored.
//! It reproduces any image that is linear in x and y exactly, which the tests use. Phase decoding
//! is per pixel, so a finer method (edge-aware) would change fringes more than it helps here.

/// Which colour the top-left 2×2 cell holds, in GenICam's naming: `RG` is R G / G B.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BayerPattern {
    Rg,
    Gr,
    Gb,
    Bg,
}

impl BayerPattern {
    /// The GenICam pixel-format name of the 8-bit variant (`BayerRG8`, …).
    pub fn pixel_format_name(self) -> &'static str {
        match self {
            Self::Rg => "BayerRG8",
            Self::Gr => "BayerGR8",
            Self::Gb => "BayerGB8",
            Self::Bg => "BayerBG8",
        }
    }

    /// The pattern of an 8-bit GenICam pixel-format name, if it is one.
    pub fn from_pixel_format_name(name: &str) -> Option<Self> {
        [Self::Rg, Self::Gr, Self::Gb, Self::Bg]
            .into_iter()
            .find(|p| p.pixel_format_name() == name)
    }

    /// Colour channel (0 R, 1 G, 2 B) sampled at pixel (x, y).
    pub fn channel_at(self, x: usize, y: usize) -> usize {
        // Top-left cell as [row 0: (even x, odd x), row 1: (even x, odd x)].
        let cell = match self {
            Self::Rg => [[0, 1], [1, 2]],
            Self::Gr => [[1, 0], [2, 1]],
            Self::Gb => [[1, 2], [0, 1]],
            Self::Bg => [[2, 1], [1, 0]],
        };
        cell[y % 2][x % 2]
    }
}

/// Errors of demosaicing.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum BayerError {
    #[error("a Bayer image of {width}×{height} needs {expected} bytes, got {got}")]
    WrongLength {
        width: usize,
        height: usize,
        expected: usize,
        got: usize,
    },
    #[error("a Bayer image needs at least 2×2 pixels, got {width}×{height}")]
    TooSmall { width: usize, height: usize },
}

/// Demosaics `raw` (one byte per pixel, rows of `width`) into interleaved RGB `rgb`, which is
/// resized to `width × height × 3` (no allocation once it has that size).
///
/// Interior pixels take fixed formulas by their place in the 2×2 cell (R and B sites: green from
/// the 4 crosses, the other colour from the 4 diagonals; G sites: each other colour from its 2
/// neighbours in the row or column); the one-pixel border takes the general mirrored rule. Both
/// give the same numbers (a test compares them on random mosaics).
pub fn demosaic_bilinear(
    raw: &[u8],
    width: usize,
    height: usize,
    pattern: BayerPattern,
    rgb: &mut Vec<u8>,
) -> Result<(), BayerError> {
    check(raw, width, height)?;
    rgb.resize(width * height * 3, 0);
    let mean2 = |a: u8, b: u8| (u16::from(a) + u16::from(b)).div_ceil(2) as u8;
    let mean4 = |a: u8, b: u8, c: u8, d: u8| {
        ((u16::from(a) + u16::from(b) + u16::from(c) + u16::from(d) + 2) / 4) as u8
    };
    for y in 1..height.saturating_sub(1) {
        let up = &raw[(y - 1) * width..y * width];
        let row = &raw[y * width..(y + 1) * width];
        let down = &raw[(y + 1) * width..(y + 2) * width];
        let out = &mut rgb[y * width * 3..(y + 1) * width * 3];
        for x in 1..width - 1 {
            let own = pattern.channel_at(x, y);
            let crosses = mean4(up[x], down[x], row[x - 1], row[x + 1]);
            let px = &mut out[x * 3..x * 3 + 3];
            px[own] = row[x];
            if own == 1 {
                // A green site: the row's neighbours are the colour of its row's other sites.
                let row_colour = pattern.channel_at(x + 1, y);
                px[row_colour] = mean2(row[x - 1], row[x + 1]);
                px[2 - row_colour] = mean2(up[x], down[x]);
            } else {
                px[1] = crosses;
                px[2 - own] = mean4(up[x - 1], up[x + 1], down[x - 1], down[x + 1]);
            }
        }
    }
    // The border: first and last rows and columns.
    for y in 0..height {
        let xs: Box<dyn Iterator<Item = usize>> = if y == 0 || y + 1 == height {
            Box::new(0..width)
        } else {
            Box::new([0, width - 1].into_iter())
        };
        for x in xs {
            demosaic_pixel(raw, width, height, pattern, x, y, rgb);
        }
    }
    Ok(())
}

fn check(raw: &[u8], width: usize, height: usize) -> Result<(), BayerError> {
    if raw.len() != width * height {
        return Err(BayerError::WrongLength {
            width,
            height,
            expected: width * height,
            got: raw.len(),
        });
    }
    if width < 2 || height < 2 {
        return Err(BayerError::TooSmall { width, height });
    }
    Ok(())
}

/// The general rule at one pixel: each missing colour is the mean of the 3×3 neighbours that
/// sampled it, with the image mirrored at its edges (−1 → 1, n → n − 2, which keeps the
/// mosaic's parity).
fn demosaic_pixel(
    raw: &[u8],
    width: usize,
    height: usize,
    pattern: BayerPattern,
    x: usize,
    y: usize,
    rgb: &mut [u8],
) {
    let mirror = |i: isize, n: usize| -> usize {
        if i < 0 {
            i.unsigned_abs()
        } else if i as usize >= n {
            2 * n - 2 - i as usize
        } else {
            i as usize
        }
    };
    let own = pattern.channel_at(x, y);
    let out = &mut rgb[(y * width + x) * 3..(y * width + x) * 3 + 3];
    out[own] = raw[y * width + x];
    for (channel, value) in out.iter_mut().enumerate() {
        if channel == own {
            continue;
        }
        let mut sum = 0u32;
        let mut count = 0u32;
        for dy in -1isize..=1 {
            for dx in -1isize..=1 {
                if dx == 0 && dy == 0 {
                    continue;
                }
                let sx = mirror(x as isize + dx, width);
                let sy = mirror(y as isize + dy, height);
                if pattern.channel_at(sx, sy) == channel {
                    sum += u32::from(raw[sy * width + sx]);
                    count += 1;
                }
            }
        }
        *value = ((sum + count / 2) / count.max(1)) as u8;
    }
}

/// The general rule at every pixel (the reference the fast path is tested against).
pub fn demosaic_reference(
    raw: &[u8],
    width: usize,
    height: usize,
    pattern: BayerPattern,
    rgb: &mut Vec<u8>,
) -> Result<(), BayerError> {
    check(raw, width, height)?;
    rgb.resize(width * height * 3, 0);
    for y in 0..height {
        for x in 0..width {
            demosaic_pixel(raw, width, height, pattern, x, y, rgb);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples an RGB function through the mosaic.
    fn mosaic(
        width: usize,
        height: usize,
        pattern: BayerPattern,
        f: impl Fn(usize, usize, usize) -> u8,
    ) -> Vec<u8> {
        let mut raw = vec![0; width * height];
        for y in 0..height {
            for x in 0..width {
                raw[y * width + x] = f(x, y, pattern.channel_at(x, y));
            }
        }
        raw
    }

    #[test]
    fn every_pattern_recovers_a_flat_colour_everywhere() {
        let colour = [200u8, 120, 40];
        for pattern in [
            BayerPattern::Rg,
            BayerPattern::Gr,
            BayerPattern::Gb,
            BayerPattern::Bg,
        ] {
            let raw = mosaic(7, 5, pattern, |_, _, c| colour[c]);
            let mut rgb = Vec::new();
            demosaic_bilinear(&raw, 7, 5, pattern, &mut rgb).unwrap();
            for px in rgb.chunks(3) {
                assert_eq!(px, colour, "{pattern:?}");
            }
        }
    }

    #[test]
    fn linear_ramps_are_reproduced_exactly_inside_the_image() {
        // Each channel a different plane in x and y, even values so that means of two or four
        // samples are whole numbers.
        let plane = |x: usize, y: usize, c: usize| -> u8 {
            let (a, b, k) = [(4, 2, 10), (2, 6, 20), (6, 4, 5)][c];
            (a * x + b * y + k) as u8
        };
        for pattern in [BayerPattern::Rg, BayerPattern::Bg] {
            let (w, h) = (12, 9);
            let raw = mosaic(w, h, pattern, plane);
            let mut rgb = Vec::new();
            demosaic_bilinear(&raw, w, h, pattern, &mut rgb).unwrap();
            for y in 1..h - 1 {
                for x in 1..w - 1 {
                    for c in 0..3 {
                        assert_eq!(rgb[(y * w + x) * 3 + c], plane(x, y, c), "({x},{y}) c{c}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_fast_path_equals_the_general_rule_on_random_mosaics() {
        let mut state = 12345u32;
        for (w, h) in [(2, 2), (3, 5), (17, 11), (64, 48)] {
            let raw: Vec<u8> = (0..w * h)
                .map(|_| {
                    state = state.wrapping_mul(1664525).wrapping_add(1013904223);
                    (state >> 24) as u8
                })
                .collect();
            for pattern in [
                BayerPattern::Rg,
                BayerPattern::Gr,
                BayerPattern::Gb,
                BayerPattern::Bg,
            ] {
                let (mut fast, mut reference) = (Vec::new(), Vec::new());
                demosaic_bilinear(&raw, w, h, pattern, &mut fast).unwrap();
                demosaic_reference(&raw, w, h, pattern, &mut reference).unwrap();
                assert_eq!(fast, reference, "{w}×{h} {pattern:?}");
            }
        }
    }

    #[test]
    fn names_round_trip_and_bad_buffers_are_refused() {
        for pattern in [
            BayerPattern::Rg,
            BayerPattern::Gr,
            BayerPattern::Gb,
            BayerPattern::Bg,
        ] {
            assert_eq!(
                BayerPattern::from_pixel_format_name(pattern.pixel_format_name()),
                Some(pattern)
            );
        }
        assert_eq!(BayerPattern::from_pixel_format_name("Mono8"), None);
        let mut rgb = Vec::new();
        assert!(matches!(
            demosaic_bilinear(&[0; 5], 2, 3, BayerPattern::Rg, &mut rgb),
            Err(BayerError::WrongLength { expected: 6, .. })
        ));
        assert!(matches!(
            demosaic_bilinear(&[0; 3], 3, 1, BayerPattern::Rg, &mut rgb),
            Err(BayerError::TooSmall { .. })
        ));
    }
}
