//! Phase-shifting pattern sequences: one description for every codec.
//!
//! A [`PatternSequence`] is a list of projected images ([`PatternEntry`]). Each image carries, per
//! channel (one gray channel, or red/green/blue), a [`ChannelCode`]: a frequency index `m` and a
//! shift `θ`. The channel shows
//!
//! ```text
//! P(x) = 0.5 + 0.5·cos(m·π/x_max · x + θ)
//! ```
//!
//! quantised to `projector_bits`, where `x` is the projector coordinate along the coded [`Axis`].
//! Builders for the codecs live in [`builders`]; rendering of pattern images in [`render`].

pub mod builders;
pub mod render;

pub use builders::{cps_gray, cps_rgb, multi_frequency, CpsGrayVariant};
pub use render::{render_pattern, PatternImage};

use std::f64::consts::PI;

/// Errors of pattern construction and rendering.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PatternError {
    #[error("x_max must be a positive finite number of projector pixels, got {0}")]
    BadXMax(f64),
    #[error("projector bit depth must be within 1..=8, got {0}")]
    BadBits(u32),
    #[error("CPS needs n ≥ 3 so that frequencies n, n−1 and n−2 are all positive, got n = {0}")]
    BadChebyshevN(u32),
    #[error("frequency index m must be ≥ 1, got {0}")]
    ZeroFrequency(u32),
    #[error("multi-frequency phase shifting needs at least {min} steps per frequency, got {got}")]
    TooFewSteps { min: usize, got: usize },
    #[error("multi-frequency phase shifting needs the unit frequency (lowest m ≤ 2), lowest given is {0}")]
    NoUnitFrequency(u32),
    #[error("pattern index {index} is out of range for a sequence of {len} images")]
    IndexOutOfRange { index: usize, len: usize },
    #[error("the sequence is empty")]
    Empty,
    #[error("pattern entry {index} mixes gray and colour channels with the rest of the sequence")]
    MixedChannels { index: usize },
    #[error("image size {width}×{height} is empty")]
    EmptyImage { width: usize, height: usize },
    #[error("x_max = {x_max} does not cover a {width}×{height} projector along this axis (needs at least {needed:.1}): the unit phase would wrap and depths alias")]
    RangeTooShort {
        x_max: f64,
        width: usize,
        height: usize,
        needed: f64,
    },
}

/// The projector coordinate a sequence encodes.
///
/// * `Columns`: `x = column`, pixel centres at integers.
/// * `Rows`: `x = row`.
/// * `Diagonal`: `x = (column + row) / √2`, the distance of the pixel centre from the top-left pixel
///   centre measured along the (1, 1)/√2 direction. Stripes run at 45°, which suits the
///   LightCrafter's diamond pixel layout (paper §5.2). With this definition a W×H projector needs
///   `x_max ≥ (W − 1 + H − 1)/√2`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    Columns,
    Rows,
    Diagonal,
}

impl Axis {
    /// Coded coordinate of the projector point `(column, row)` (pixel centres at integers).
    #[inline]
    pub fn coordinate(self, column: f64, row: f64) -> f64 {
        match self {
            Axis::Columns => column,
            Axis::Rows => row,
            Axis::Diagonal => (column + row) * std::f64::consts::FRAC_1_SQRT_2,
        }
    }

    /// The smallest `x_max` that codes every pixel of a `width`×`height` projector uniquely.
    pub fn min_x_max(self, width: usize, height: usize) -> f64 {
        let last_col = width.saturating_sub(1) as f64;
        let last_row = height.saturating_sub(1) as f64;
        self.coordinate(last_col, last_row) + 1.0
    }
}

/// One channel of one projected image: frequency index `m` (f = m·π/x_max) and phase shift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelCode {
    pub m: u32,
    pub shift_rad: f64,
}

impl ChannelCode {
    pub fn new(m: u32, shift_rad: f64) -> Self {
        Self { m, shift_rad }
    }
}

/// What one projected image shows on its channels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatternEntry {
    /// The same intensity on all projector channels (a white-light pattern).
    Gray(ChannelCode),
    /// Independent codes on the red, green and blue projector channels.
    Rgb {
        red: ChannelCode,
        green: ChannelCode,
        blue: ChannelCode,
    },
}

impl PatternEntry {
    /// The codes of the projector channels, in R, G, B order (one for gray).
    pub fn codes(&self) -> Vec<ChannelCode> {
        match *self {
            PatternEntry::Gray(code) => vec![code],
            PatternEntry::Rgb { red, green, blue } => vec![red, green, blue],
        }
    }

    pub fn is_rgb(&self) -> bool {
        matches!(self, PatternEntry::Rgb { .. })
    }
}

/// A phase-shifting pattern sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternSequence {
    /// Coded coordinate range: frequency index `m` means `f = m·π/x_max` radians per pixel.
    pub x_max: f64,
    pub axis: Axis,
    /// Projector bit depth per channel (the paper's rig uses 6 for 121 FPS).
    pub projector_bits: u32,
    pub entries: Vec<PatternEntry>,
}

impl PatternSequence {
    /// Checks the invariants every consumer relies on.
    pub fn validate(&self) -> Result<(), PatternError> {
        if !(self.x_max.is_finite() && self.x_max > 0.0) {
            return Err(PatternError::BadXMax(self.x_max));
        }
        if !(1..=8).contains(&self.projector_bits) {
            return Err(PatternError::BadBits(self.projector_bits));
        }
        let first = self.entries.first().ok_or(PatternError::Empty)?;
        for (index, entry) in self.entries.iter().enumerate() {
            if entry.is_rgb() != first.is_rgb() {
                return Err(PatternError::MixedChannels { index });
            }
            if let Some(code) = entry.codes().iter().find(|c| c.m == 0) {
                return Err(PatternError::ZeroFrequency(code.m));
            }
        }
        Ok(())
    }

    /// Checks that `x_max` covers every pixel of a `width`×`height` projector, so that the unit
    /// phase identifies each coded coordinate uniquely.
    pub fn check_covers(&self, width: usize, height: usize) -> Result<(), PatternError> {
        let needed = self.axis.min_x_max(width, height);
        if self.x_max < needed {
            return Err(PatternError::RangeTooShort {
                x_max: self.x_max,
                width,
                height,
                needed,
            });
        }
        Ok(())
    }

    /// Angular frequency in radians per projector pixel of index `m`.
    #[inline]
    pub fn frequency(&self, m: u32) -> f64 {
        f64::from(m) * PI / self.x_max
    }

    /// Whether the images are colour coded.
    pub fn is_rgb(&self) -> bool {
        self.entries.first().is_some_and(PatternEntry::is_rgb)
    }

    /// The distinct frequency indices in the sequence, sorted descending.
    pub fn distinct_frequencies(&self) -> Vec<u32> {
        let mut ms: Vec<u32> = self
            .entries
            .iter()
            .flat_map(|e| e.codes().into_iter().map(|c| c.m))
            .collect();
        ms.sort_unstable_by(|a, b| b.cmp(a));
        ms.dedup();
        ms
    }

    /// `Some(n)` when the distinct frequencies are exactly `{n, n−1, n−2}`: a Chebyshev sequence.
    pub fn chebyshev_n(&self) -> Option<u32> {
        match self.distinct_frequencies().as_slice() {
            &[a, b, c] if a >= 3 && b == a - 1 && c == a - 2 => Some(a),
            _ => None,
        }
    }

    /// The projected intensity in `[0, 1]` of `code` at coordinate `x`, quantised to the bit depth.
    #[inline]
    pub fn intensity(&self, code: ChannelCode, x: f64) -> f64 {
        let ideal = 0.5 + 0.5 * (self.frequency(code.m) * x + code.shift_rad).cos();
        quantise(ideal, self.projector_bits)
    }

    /// The period in projector pixels of frequency index `m`.
    pub fn period_px(&self, m: u32) -> f64 {
        2.0 * self.x_max / f64::from(m)
    }
}

/// Quantises `value` in `[0, 1]` to `bits` bits and maps it back to `[0, 1]`.
#[inline]
pub fn quantise(value: f64, bits: u32) -> f64 {
    let levels = f64::from((1u32 << bits) - 1);
    (value.clamp(0.0, 1.0) * levels).round() / levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_definition_and_min_x_max() {
        assert!((Axis::Diagonal.coordinate(1.0, 1.0) - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(Axis::Columns.min_x_max(912, 1140), 912.0);
        assert_eq!(Axis::Rows.min_x_max(912, 1140), 1140.0);
        let d = Axis::Diagonal.min_x_max(912, 1140);
        assert!((d - (2050.0 / 2f64.sqrt() + 1.0)).abs() < 1e-9);
    }

    #[test]
    fn range_must_cover_the_projector() {
        let seq = cps_rgb(107, 1400.0, Axis::Diagonal, 6).unwrap();
        let err = seq.check_covers(912, 1140).unwrap_err();
        assert!(err.to_string().contains("needs at least 1450.6"), "{err}");
        let seq = cps_rgb(65, 912.0, Axis::Columns, 6).unwrap();
        assert!(seq.check_covers(912, 1140).is_ok());
    }

    #[test]
    fn quantise_to_six_bits() {
        assert_eq!(quantise(0.0, 6), 0.0);
        assert_eq!(quantise(1.0, 6), 1.0);
        assert!((quantise(0.5, 6) - 32.0 / 63.0).abs() < 1e-12);
        assert_eq!(quantise(1.7, 8), 1.0);
    }

    #[test]
    fn validate_rejects_bad_sequences() {
        let mut seq = cps_rgb(65, 912.0, Axis::Columns, 6).unwrap();
        seq.projector_bits = 9;
        assert_eq!(seq.validate(), Err(PatternError::BadBits(9)));
        seq.projector_bits = 6;
        seq.entries
            .push(PatternEntry::Gray(ChannelCode::new(3, 0.0)));
        assert_eq!(
            seq.validate(),
            Err(PatternError::MixedChannels { index: 3 })
        );
        seq.entries.clear();
        assert_eq!(seq.validate(), Err(PatternError::Empty));
    }
}
