//! Timing of the CPS-RGB sequence on the LightCrafter 4500, and the video frames that carry it.
//!
//! The DMD shows an n-bit pattern as n binary bit planes, and the DLPC350 needs a minimum time to
//! do so (DLPC350 data sheet, "pattern exposure" by bit depth): 1 bit 235 µs, 2 bits 700, 3 bits
//! 1570, 4 bits 1700, 5 bits 2000, 6 bits 2500, 7 bits 4500, 8 bits 8333 µs.
//!
//! CPS-RGB projects each of its 3 images as 3 colour patterns in a row: the red channel under the
//! red LED, then green, then blue, and the camera exposes once over all three (trigger out 1 held
//! high across them). So one image takes 3 × the pattern exposure:
//!
//! * 6 bits: 3 × 2.5 ms = 7.5 ms per image (the paper's Figure 8). At 121 FPS an image period is
//!   1/121 s = 8264 µs, leaving 764 µs, more than the 230 µs the controller needs between the
//!   last pattern and the next trigger.
//! * 7 bits: 3 × 4.5 ms = 13.5 ms: 74 FPS at most. 8 bits: 25 ms: 40 FPS.
//!
//! so 6 bits is the deepest quantisation that reaches 121 FPS ([`deepest_bit_depth`]).
//!
//! The patterns come over the video (HDMI) input, which needs no flash writes: each video frame
//! carries one CPS image, its three channels quantised to 6 bits and packed into the frame's 24
//! bit planes, and VSYNC (at the image rate) starts its three colour patterns. The DLPC350 numbers
//! bit planes G0..G7, R0..R7, B0..B7 (0..23), and n-bit pattern k uses planes k·n .. k·n + n − 1
//! (DLPU010 table "bit planes of each pattern number"). [`pack_video_pixel`] does that packing.

/// Minimum pattern exposure by bit depth 1..=8, µs.
pub const MIN_EXPOSURE_MICROS: [u32; 8] = [235, 700, 1570, 1700, 2000, 2500, 4500, 8333];

/// Time the controller needs between a pattern's end and the next trigger (black fill), µs.
pub const POST_PATTERN_MICROS: u32 = 230;

/// Colour patterns per CPS image (R, G, B).
pub const PATTERNS_PER_IMAGE: u32 = 3;

/// Errors of the timing plan.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TimingError {
    #[error("bit depth {0} is not 1..=8")]
    BitDepth(u8),
    #[error(
        "{fps} FPS leaves {period_micros} µs per image; {bit_depth}-bit patterns need \
         {needed_micros} µs (3 × {exposure_micros} µs + {POST_PATTERN_MICROS} µs): lower the bit \
         depth or the frame rate"
    )]
    TooFast {
        fps: f64,
        bit_depth: u8,
        period_micros: u32,
        exposure_micros: u32,
        needed_micros: u32,
    },
}

/// The programmed timing of one CPS-RGB image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CpsTiming {
    pub bit_depth: u8,
    /// Exposure of each colour pattern, µs.
    pub pattern_exposure_micros: u32,
    /// Frame period of each colour pattern, µs (equal to the exposure: no dark gap inside an
    /// image, which the controller allows).
    pub pattern_period_micros: u32,
    /// VSYNC period: one video frame, one camera frame, µs.
    pub image_period_micros: u32,
}

impl CpsTiming {
    /// The plan for `fps` images per second at `bit_depth` bits, with the shortest exposure the
    /// depth allows (the rest of the period is idle until the next VSYNC).
    pub fn new(fps: f64, bit_depth: u8) -> Result<Self, TimingError> {
        let exposure = *MIN_EXPOSURE_MICROS
            .get(usize::from(bit_depth).wrapping_sub(1))
            .ok_or(TimingError::BitDepth(bit_depth))?;
        let period = (1e6 / fps).floor() as u32;
        let needed = PATTERNS_PER_IMAGE * exposure + POST_PATTERN_MICROS;
        if needed > period {
            return Err(TimingError::TooFast {
                fps,
                bit_depth,
                period_micros: period,
                exposure_micros: exposure,
                needed_micros: needed,
            });
        }
        Ok(Self {
            bit_depth,
            pattern_exposure_micros: exposure,
            pattern_period_micros: exposure,
            image_period_micros: period,
        })
    }

    /// Light time of one image (what the camera integrates), µs.
    pub fn image_exposure_micros(&self) -> u32 {
        PATTERNS_PER_IMAGE * self.pattern_exposure_micros
    }
}

/// The deepest bit depth whose CPS image fits `fps` (None if even 1 bit does not).
pub fn deepest_bit_depth(fps: f64) -> Option<u8> {
    (1..=8u8).rev().find(|&d| CpsTiming::new(fps, d).is_ok())
}

/// Packs one pixel of a CPS image (8-bit R, G, B) into the 24-bit video pixel the LightCrafter
/// reads as patterns 0 (R), 1 (G) and 2 (B) of `bit_depth` bits each. Returns the video pixel's
/// (R, G, B) bytes. Each value keeps its `bit_depth` most significant bits.
pub fn pack_video_pixel(rgb: [u8; 3], bit_depth: u8) -> [u8; 3] {
    let depth = u32::from(bit_depth.clamp(1, 8));
    // Bit planes 0..23 in the controller's order G0..G7, R0..R7, B0..B7.
    let mut planes = 0u32;
    for (k, value) in rgb.into_iter().enumerate() {
        let quantised = u32::from(value) >> (8 - depth);
        planes |= quantised << (k as u32 * depth);
    }
    let green = (planes & 0xFF) as u8;
    let red = ((planes >> 8) & 0xFF) as u8;
    let blue = ((planes >> 16) & 0xFF) as u8;
    [red, green, blue]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_bits_is_the_deepest_that_reaches_121_fps() {
        let t = CpsTiming::new(121.0, 6).unwrap();
        assert_eq!(t.pattern_exposure_micros, 2500);
        assert_eq!(t.image_exposure_micros(), 7500);
        assert_eq!(t.image_period_micros, 8264);
        assert_eq!(deepest_bit_depth(121.0), Some(6));
        assert!(matches!(
            CpsTiming::new(121.0, 7),
            Err(TimingError::TooFast {
                needed_micros: 13730,
                ..
            })
        ));
        // 8-bit fits 36 FPS (3 × 8333 + 230 = 25229 µs ≤ 27777), not 40.
        assert_eq!(deepest_bit_depth(36.0), Some(8));
        assert_eq!(deepest_bit_depth(40.0), Some(7));
        assert_eq!(CpsTiming::new(60.0, 9), Err(TimingError::BitDepth(9)));
    }

    #[test]
    fn packing_puts_each_channel_in_its_pattern_bit_planes() {
        // 6-bit: R → planes 0..5 (G0..G5), G → 6..11 (G6, G7, R0..R3), B → 12..17 (R4..R7,
        // B0, B1).
        let [r, g, b] = pack_video_pixel([0xFF, 0, 0], 6);
        assert_eq!((r, g, b), (0x00, 0x3F, 0x00));
        let [r, g, b] = pack_video_pixel([0, 0xFF, 0], 6);
        assert_eq!((r, g, b), (0x0F, 0xC0, 0x00));
        let [r, g, b] = pack_video_pixel([0, 0, 0xFF], 6);
        assert_eq!((r, g, b), (0xF0, 0x00, 0x03));
        // 8-bit is the plain G, R, B order of patterns 0, 1, 2 with R first in the input.
        assert_eq!(pack_video_pixel([1, 2, 3], 8), [2, 1, 3]);
        // Only the top bits survive: 0b1010_1111 at 6 bits is 0b101011.
        assert_eq!(pack_video_pixel([0b1010_1111, 0, 0], 6)[1], 0b10_1011);
    }
}
