//! Builders for the codecs tremorscan knows: CPS-RGB, CPS-gray (7 and 9 images) and classic
//! multi-frequency phase shifting. Every builder returns a validated [`PatternSequence`].

use super::{Axis, ChannelCode, PatternEntry, PatternError, PatternSequence};
use std::f64::consts::{FRAC_PI_2, TAU};

/// The three-step shifts 0, 2π/3, 4π/3.
fn three_step_shift(k: usize) -> f64 {
    TAU * k as f64 / 3.0
}

fn finish(seq: PatternSequence) -> Result<PatternSequence, PatternError> {
    seq.validate()?;
    Ok(seq)
}

fn check_n(n: u32) -> Result<(), PatternError> {
    if n < 3 {
        return Err(PatternError::BadChebyshevN(n));
    }
    Ok(())
}

/// CPS packed into three RGB images (paper §5.2): red carries `f_{n−1}`, green `f_{n−2}`, blue
/// `f_n`; image k is shifted by `θ_k = 2πk/3` on all three channels. The paper's rig uses n = 107 on
/// a diagonal axis with x_max = 1481; the session example uses n = 65 on 912 columns.
pub fn cps_rgb(
    n: u32,
    x_max: f64,
    axis: Axis,
    projector_bits: u32,
) -> Result<PatternSequence, PatternError> {
    check_n(n)?;
    let entries = (0..3)
        .map(|k| {
            let shift_rad = three_step_shift(k);
            PatternEntry::Rgb {
                red: ChannelCode::new(n - 1, shift_rad),
                green: ChannelCode::new(n - 2, shift_rad),
                blue: ChannelCode::new(n, shift_rad),
            }
        })
        .collect();
    finish(PatternSequence {
        x_max,
        axis,
        projector_bits,
        entries,
    })
}

/// The gray CPS variants.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CpsGrayVariant {
    /// The 7-image minimum of paper §4: 2×f_{n−2}, 3×f_{n−1}, 2×f_n, solved with one common offset.
    Minimal7,
    /// Three shifts of each frequency: 9 images.
    Full9,
}

/// CPS with gray (white-light) patterns.
///
/// The two-image frequencies of the 7-image variant use shifts 0 and π/2; they are solvable because
/// the offset is shared with the three-image frequency.
pub fn cps_gray(
    n: u32,
    variant: CpsGrayVariant,
    x_max: f64,
    axis: Axis,
    projector_bits: u32,
) -> Result<PatternSequence, PatternError> {
    check_n(n)?;
    let two_step = [0.0, FRAC_PI_2];
    let three_step: Vec<f64> = (0..3).map(three_step_shift).collect();
    let plan: [(u32, &[f64]); 3] = match variant {
        CpsGrayVariant::Minimal7 => [(n - 2, &two_step), (n - 1, &three_step), (n, &two_step)],
        CpsGrayVariant::Full9 => [(n - 2, &three_step), (n - 1, &three_step), (n, &three_step)],
    };
    let entries = plan
        .iter()
        .flat_map(|&(m, shifts)| {
            shifts
                .iter()
                .map(move |&s| PatternEntry::Gray(ChannelCode::new(m, s)))
        })
        .collect();
    finish(PatternSequence {
        x_max,
        axis,
        projector_bits,
        entries,
    })
}

/// Classic multi-frequency phase shifting: `steps` equally spaced shifts of each frequency index
/// in `ms`, gray patterns. The lowest index must be ≤ 2 (f ≤ f_unit = 2π/x_max) so that eq. 8 can
/// start without ambiguity.
pub fn multi_frequency(
    ms: &[u32],
    steps: usize,
    x_max: f64,
    axis: Axis,
    projector_bits: u32,
) -> Result<PatternSequence, PatternError> {
    if steps < 3 {
        return Err(PatternError::TooFewSteps { min: 3, got: steps });
    }
    let lowest = ms.iter().copied().min().ok_or(PatternError::Empty)?;
    if lowest > 2 {
        return Err(PatternError::NoUnitFrequency(lowest));
    }
    let entries = ms
        .iter()
        .flat_map(|&m| {
            (0..steps).map(move |k| {
                PatternEntry::Gray(ChannelCode::new(m, TAU * k as f64 / steps as f64))
            })
        })
        .collect();
    finish(PatternSequence {
        x_max,
        axis,
        projector_bits,
        entries,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cps_rgb_matches_the_paper_layout() {
        let seq = cps_rgb(107, 1481.0, Axis::Diagonal, 6).unwrap();
        assert_eq!(seq.entries.len(), 3);
        assert_eq!(seq.chebyshev_n(), Some(107));
        match seq.entries[1] {
            PatternEntry::Rgb { red, green, blue } => {
                assert_eq!((red.m, green.m, blue.m), (106, 105, 107));
                assert!((red.shift_rad - TAU / 3.0).abs() < 1e-12);
            }
            PatternEntry::Gray(_) => panic!("expected colour"),
        }
        // Paper fig. 5: green f_105 has a period of about 28.2 px.
        assert!((seq.period_px(105) - 28.21).abs() < 0.01);
    }

    #[test]
    fn cps_gray_counts() {
        let seq = cps_gray(129, CpsGrayVariant::Minimal7, 1024.0, Axis::Columns, 8).unwrap();
        assert_eq!(seq.entries.len(), 7);
        assert_eq!(seq.distinct_frequencies(), vec![129, 128, 127]);
        // Paper eq. 17: f_128 has a period of exactly 16 px on 1024 columns.
        assert!((seq.period_px(128) - 16.0).abs() < 1e-12);
        let full = cps_gray(129, CpsGrayVariant::Full9, 1024.0, Axis::Columns, 8).unwrap();
        assert_eq!(full.entries.len(), 9);
        assert_eq!(
            cps_gray(2, CpsGrayVariant::Full9, 1024.0, Axis::Columns, 8),
            Err(PatternError::BadChebyshevN(2))
        );
    }

    #[test]
    fn multi_frequency_needs_unit_frequency_and_steps() {
        let seq = multi_frequency(&[2, 16, 64], 4, 912.0, Axis::Columns, 8).unwrap();
        assert_eq!(seq.entries.len(), 12);
        assert_eq!(seq.chebyshev_n(), None);
        assert_eq!(
            multi_frequency(&[8, 64], 4, 912.0, Axis::Columns, 8),
            Err(PatternError::NoUnitFrequency(8))
        );
        assert_eq!(
            multi_frequency(&[1, 64], 2, 912.0, Axis::Columns, 8),
            Err(PatternError::TooFewSteps { min: 3, got: 2 })
        );
    }
}
