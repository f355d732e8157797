//! Faults a real camera link makes, rendered on purpose so that the decoder's defences can be
//! tested against them: a frame whose red channel comes from another exposure (a corrupted or
//! mixed-up transfer), on every row or on a band of rows (a torn transfer, or a pattern that
//! changed while a rolling shutter was half way down the frame). Every pixel there then sees red
//! phases that disagree with green and blue, as no moving or mixed surface makes them
//! everywhere at once (`decode::broken`).

use super::{RigError, VirtualRig};
use crate::frame::Frame;
use crate::pattern::PatternEntry;

impl VirtualRig {
    /// Renders frame `index` into `frame` with its red channel replaced by the one the rig shows
    /// when every red pattern is shifted by `shift_rad` (green and blue as rendered).
    pub fn render_with_shifted_red(
        &self,
        index: u64,
        shift_rad: f64,
        frame: &mut Frame,
    ) -> Result<(), RigError> {
        let rows = 0..frame.height;
        self.render_with_shifted_red_on_rows(index, shift_rad, rows, frame)
    }

    /// [`Self::render_with_shifted_red`] on image rows `rows` only (the rest as rendered): a
    /// transfer that lost the packets of a band of rows and filled them from another exposure.
    pub fn render_with_shifted_red_on_rows(
        &self,
        index: u64,
        shift_rad: f64,
        rows: std::ops::Range<usize>,
        frame: &mut Frame,
    ) -> Result<(), RigError> {
        let mut sequence = self.sequence.clone();
        for entry in &mut sequence.entries {
            if let PatternEntry::Rgb { red, .. } = entry {
                red.shift_rad += shift_rad;
            }
        }
        let shifted_rig = VirtualRig::new(self.config.clone(), sequence)?;
        let mut shifted = shifted_rig.blank_frame();
        shifted_rig.render(index, &mut shifted, None)?;
        self.render(index, frame, None)?;
        let row_len = 3 * frame.width;
        let first = rows.start.min(frame.height);
        let (start, end) = (
            first * row_len,
            rows.end.clamp(first, frame.height) * row_len,
        );
        for (dst, src) in frame.data[start..end]
            .chunks_exact_mut(3)
            .zip(shifted.data[start..end].chunks_exact(3))
        {
            dst[0] = src[0];
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::rig::{RigConfig, VirtualRig};

    #[test]
    fn only_the_red_channel_changes() {
        let config = RigConfig::paper(64, 40).unwrap();
        let seq = config.default_sequence().unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        let (mut clean, mut broken) = (rig.blank_frame(), rig.blank_frame());
        rig.render(1, &mut clean, None).unwrap();
        rig.render_with_shifted_red(1, std::f64::consts::FRAC_PI_2, &mut broken)
            .unwrap();
        let differ = |c: usize| {
            clean
                .data
                .chunks_exact(3)
                .zip(broken.data.chunks_exact(3))
                .filter(|(a, b)| a[c] != b[c])
                .count()
        };
        assert!(differ(0) > 64 * 40 / 2, "{}", differ(0));
        assert_eq!((differ(1), differ(2)), (0, 0));
        // On a band of rows only: the red channel changes there and nowhere else.
        let mut band = rig.blank_frame();
        rig.render_with_shifted_red_on_rows(1, std::f64::consts::FRAC_PI_2, 10..20, &mut band)
            .unwrap();
        for (p, (a, b)) in clean
            .data
            .chunks_exact(3)
            .zip(band.data.chunks_exact(3))
            .enumerate()
        {
            let inside = (10..20).contains(&(p / 64));
            assert_eq!(a[1..], b[1..], "pixel {p}");
            if !inside {
                assert_eq!(a[0], b[0], "pixel {p}");
            }
        }
        let changed = |rows: std::ops::Range<usize>| {
            rows.flat_map(|y| (0..64).map(move |x| y * 64 + x))
                .filter(|&p| clean.data[3 * p] != band.data[3 * p])
                .count()
        };
        assert!(changed(10..20) > 64 * 10 / 2, "{}", changed(10..20));
    }
}
