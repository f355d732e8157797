//! Faults a real camera link makes, rendered on purpose so that the decoder's defences can be
//! tested against them: a frame whose red channel comes from another exposure (a corrupted or
//! mixed-up transfer). Every pixel of it then sees red phases that disagree with green and blue,
//! as no moving or mixed surface makes them everywhere at once (`decode::broken`).

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
        for (dst, src) in frame
            .data
            .chunks_exact_mut(3)
            .zip(shifted.data.chunks_exact(3))
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
    }
}
