//! Which unwrap method decodes a sequence: the one that follows from its frequencies, or the
//! one a user asks for when the sequence can take it.
//!
//! A CPS sequence (RGB, or gray with 7 or 9 images) carries the frequencies `n, n−1, n−2`, whose
//! Chebyshev relation gives the unit phase: it takes the robust Chebyshev unwrap. A classic
//! multi-frequency phase-shift sequence, as many open-source scanners record, carries the unit
//! frequency (`m ≤ 2`, one period or less over the coded range): it takes the temporal unwrap of
//! eq. 8. A sequence with both (for example `3, 2, 1`) is Chebyshev first, the method the rest
//! of the decoder is tuned for. Anything else cannot be unwrapped, and the error says what it
//! lacks.

use super::{DecodeError, UnwrapMethod};
use crate::pattern::PatternSequence;

impl UnwrapMethod {
    /// The method that follows from `sequence`'s frequencies.
    pub fn for_sequence(sequence: &PatternSequence) -> Result<Self, DecodeError> {
        if sequence.chebyshev_n().is_some() {
            return Ok(Self::ChebyshevRobust);
        }
        let frequencies = sequence.distinct_frequencies();
        match frequencies.last() {
            Some(&lowest) if lowest <= 2 && frequencies.len() >= 2 => Ok(Self::Temporal),
            _ => Err(DecodeError::NoUnwrapMethod { frequencies }),
        }
    }

    /// Whether this method can unwrap `sequence`; the error says why not.
    pub fn check(self, sequence: &PatternSequence) -> Result<(), DecodeError> {
        match self {
            Self::ChebyshevRobust | Self::ChebyshevPerPixel => {
                if sequence.chebyshev_n().is_none() {
                    return Err(DecodeError::NeedsChebyshev {
                        method: self,
                        frequencies: sequence.distinct_frequencies(),
                    });
                }
            }
            Self::Temporal => {
                let lowest = sequence.distinct_frequencies().last().copied().unwrap_or(0);
                if lowest > 2 {
                    return Err(DecodeError::NeedsUnitFrequency(lowest));
                }
            }
        }
        Ok(())
    }

    /// `requested` when there is one and it can unwrap `sequence`, else the sequence's own
    /// method; the flag says whether the method was requested.
    pub fn resolve(
        requested: Option<Self>,
        sequence: &PatternSequence,
    ) -> Result<(Self, bool), DecodeError> {
        match requested {
            Some(method) => method.check(sequence).map(|()| (method, true)),
            None => Self::for_sequence(sequence).map(|m| (m, false)),
        }
    }

    /// The method's name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::ChebyshevRobust => "chebyshev-robust",
            Self::ChebyshevPerPixel => "chebyshev-per-pixel",
            Self::Temporal => "temporal",
        }
    }
}

impl std::fmt::Display for UnwrapMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;
    use crate::pattern::{cps_gray, cps_rgb, multi_frequency, Axis, CpsGrayVariant};

    #[test]
    fn the_method_follows_from_the_sequence() {
        let rgb = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let gray = cps_gray(65, CpsGrayVariant::Full9, 912.0, Axis::Columns, 8).unwrap();
        let multi = multi_frequency(&[16, 1], 3, 912.0, Axis::Columns, 8).unwrap();
        let both = multi_frequency(&[3, 2, 1], 3, 912.0, Axis::Columns, 8).unwrap();
        assert_eq!(
            UnwrapMethod::for_sequence(&rgb),
            Ok(UnwrapMethod::ChebyshevRobust)
        );
        assert_eq!(
            UnwrapMethod::for_sequence(&gray),
            Ok(UnwrapMethod::ChebyshevRobust)
        );
        assert_eq!(
            UnwrapMethod::for_sequence(&multi),
            Ok(UnwrapMethod::Temporal)
        );
        assert_eq!(
            UnwrapMethod::for_sequence(&both),
            Ok(UnwrapMethod::ChebyshevRobust)
        );
    }

    #[test]
    fn a_sequence_no_method_can_unwrap_says_what_it_lacks() {
        // Two high frequencies: neither a Chebyshev triple nor the unit frequency.
        let mut seq = multi_frequency(&[16, 1], 3, 912.0, Axis::Columns, 8).unwrap();
        for entry in &mut seq.entries {
            if let crate::pattern::PatternEntry::Gray(code) = entry {
                if code.m == 1 {
                    code.m = 8;
                }
            }
        }
        let err = UnwrapMethod::for_sequence(&seq).unwrap_err();
        assert_eq!(
            err,
            DecodeError::NoUnwrapMethod {
                frequencies: vec![16, 8]
            }
        );
        let text = err.to_string();
        assert!(
            text.contains("[16, 8]") && text.contains("unit frequency"),
            "{text}"
        );
    }

    #[test]
    fn a_requested_method_must_fit_the_sequence() {
        let multi = multi_frequency(&[32, 2], 3, 912.0, Axis::Columns, 8).unwrap();
        let rgb = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        assert_eq!(
            UnwrapMethod::resolve(Some(UnwrapMethod::ChebyshevPerPixel), &rgb),
            Ok((UnwrapMethod::ChebyshevPerPixel, true))
        );
        assert_eq!(
            UnwrapMethod::resolve(None, &multi),
            Ok((UnwrapMethod::Temporal, false))
        );
        assert!(matches!(
            UnwrapMethod::resolve(Some(UnwrapMethod::ChebyshevRobust), &multi),
            Err(DecodeError::NeedsChebyshev { .. })
        ));
        assert_eq!(
            UnwrapMethod::resolve(Some(UnwrapMethod::Temporal), &rgb),
            Err(DecodeError::NeedsUnitFrequency(63))
        );
    }
}
