//! Rendering of one pattern image at any projector resolution, 8-bit, interleaved.

use super::{PatternEntry, PatternError, PatternSequence};

/// An 8-bit projector image. `channels` is 1 for gray entries and 3 (R, G, B interleaved) for RGB.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternImage {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<u8>,
}

/// Renders entry `index` of `seq` at `width`×`height`. Values are the sequence's quantised
/// intensities scaled to 0..=255 (a 6-bit level k becomes round(255·k/63)).
pub fn render_pattern(
    seq: &PatternSequence,
    index: usize,
    width: usize,
    height: usize,
) -> Result<PatternImage, PatternError> {
    seq.validate()?;
    if width == 0 || height == 0 {
        return Err(PatternError::EmptyImage { width, height });
    }
    let entry = seq
        .entries
        .get(index)
        .ok_or(PatternError::IndexOutOfRange {
            index,
            len: seq.entries.len(),
        })?;
    let codes = entry.codes();
    let channels = codes.len();
    let mut data = vec![0u8; width * height * channels];
    for row in 0..height {
        for column in 0..width {
            let x = seq.axis.coordinate(column as f64, row as f64);
            let base = (row * width + column) * channels;
            for (c, code) in codes.iter().enumerate() {
                data[base + c] = (seq.intensity(*code, x) * 255.0).round() as u8;
            }
        }
    }
    debug_assert_eq!(
        channels,
        if matches!(entry, PatternEntry::Gray(_)) {
            1
        } else {
            3
        }
    );
    Ok(PatternImage {
        width,
        height,
        channels,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pattern::{cps_rgb, Axis};

    #[test]
    fn renders_rgb_columns_with_expected_values() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let img = render_pattern(&seq, 0, 912, 4).unwrap();
        assert_eq!(img.channels, 3);
        // Column 0, shift 0: cos(0) = 1 → full intensity on every channel.
        assert_eq!(&img.data[0..3], &[255, 255, 255]);
        // Columns code x = column, so every row is identical.
        assert_eq!(img.data[0..912 * 3], img.data[912 * 3..2 * 912 * 3]);
        // Blue (m = 65) has its first minimum half a period (14.03 px) from column 0.
        let blue_at = |col: usize| img.data[col * 3 + 2];
        assert!(blue_at(14) < 2 && blue_at(7) > 100);
    }

    #[test]
    fn diagonal_images_are_constant_along_anti_diagonals() {
        let seq = cps_rgb(107, 1481.0, Axis::Diagonal, 6).unwrap();
        let img = render_pattern(&seq, 2, 40, 30).unwrap();
        let at = |c: usize, r: usize| &img.data[(r * 40 + c) * 3..(r * 40 + c) * 3 + 3];
        assert_eq!(at(10, 5), at(5, 10));
        assert_eq!(at(0, 15), at(15, 0));
        // Six-bit quantisation: every value is a multiple of 255/63.
        assert!(img
            .data
            .iter()
            .all(|&v| (0..=63).any(|k| (f64::from(k) * 255.0 / 63.0).round() as u8 == v)));
    }

    #[test]
    fn rejects_empty_size() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        assert_eq!(
            render_pattern(&seq, 0, 0, 3),
            Err(PatternError::EmptyImage {
                width: 0,
                height: 3
            })
        );
    }
}
