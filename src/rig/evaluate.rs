//! Comparison of a decoded window with the rig's ground truth.

use super::GroundTruth;
use crate::decode::DecodeOutput;

/// Accuracy of one decoded window against ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Accuracy {
    /// Pixels lit by the projector in the truth.
    pub lit: usize,
    /// Pixels the decoder marked valid.
    pub valid: usize,
    /// Valid pixels whose truth is unlit (shadow, outside the field): a depth from nothing.
    pub valid_unlit: usize,
    /// Valid, lit pixels whose error exceeds half a fine period: a wrong fringe order.
    pub unwrap_errors: usize,
    /// RMS coordinate error of the valid, lit pixels without unwrap error, projector px.
    pub rms_px: f64,
    /// Largest such error, projector px.
    pub max_px: f64,
}

impl Accuracy {
    /// Share of valid pixels with an unwrap error.
    pub fn unwrap_error_rate(&self) -> f64 {
        if self.valid == 0 {
            0.0
        } else {
            self.unwrap_errors as f64 / self.valid as f64
        }
    }

    /// Share of lit pixels that decoded valid.
    pub fn coverage(&self) -> f64 {
        if self.lit == 0 {
            0.0
        } else {
            (self.valid - self.valid_unlit) as f64 / self.lit as f64
        }
    }
}

/// Compares `out` with `truth`; `half_period_px` is half the finest fringe period.
pub fn compare(out: &DecodeOutput, truth: &GroundTruth, half_period_px: f64) -> Accuracy {
    let mut acc = Accuracy::default();
    let mut sum2 = 0.0;
    let mut good = 0usize;
    for ((&decoded, &expected), &flags) in out
        .coordinate_px
        .iter()
        .zip(&truth.coordinate_px)
        .zip(&out.invalid)
    {
        let lit = expected.is_finite();
        acc.lit += usize::from(lit);
        if flags != 0 {
            continue;
        }
        acc.valid += 1;
        if !lit {
            acc.valid_unlit += 1;
            continue;
        }
        let err = f64::from(decoded - expected).abs();
        if err > half_period_px {
            acc.unwrap_errors += 1;
        } else {
            sum2 += err * err;
            good += 1;
            acc.max_px = acc.max_px.max(err);
        }
    }
    acc.rms_px = if good > 0 {
        (sum2 / good as f64).sqrt()
    } else {
        0.0
    };
    acc
}
