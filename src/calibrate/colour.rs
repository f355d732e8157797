//! Colour calibration (paper §5.3): the cross-talk matrix `A` and offset `b` of `c = A·p + b`.
//!
//! The projector shows the ten constant colours of the paper's Table 1 (black, then red, green
//! and blue at 85, 170 and 255) on a white target and the camera captures each. `p` is the
//! projected colour in 8-bit projector levels and `c` the camera colour in gray levels, so `A`
//! maps projector levels to camera levels.
//!
//! * The same pseudo-random pixels of a region of interest are sampled in every capture.
//! * `b` is the mean of the black capture's samples (eq. 19).
//! * Each camera channel's row of `A` is the least-squares solution of eq. 20 over the samples
//!   of the nine coloured captures, with `b` removed; the three rows are independent problems.
//! * Samples with a channel at or above the saturation level are dropped (a clipped sample
//!   pulls `A` down); a capture with more than 1 % of them, or whose strongest channel rises less
//!   than 10 gray levels above `b`, raises a warning, as does a matrix that is not diagonally
//!   dominant.
//!
//! The decoder is invariant to a common scale of `A` (it only rescales the fringe amplitudes), so
//! a uniformly grey target of any albedo calibrates it as well as a white one.

use super::CalibrationError;
use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::hash::{splitmix64, SPLITMIX_INCREMENT};
use nalgebra::{Matrix3, Vector3};

/// The paper's Table 1: projected colours (R, G, B levels) of the ten calibration captures.
pub const TABLE1_LEVELS: [[u8; 3]; 10] = [
    [0, 0, 0],
    [85, 0, 0],
    [0, 85, 0],
    [0, 0, 85],
    [170, 0, 0],
    [0, 170, 0],
    [0, 0, 170],
    [255, 0, 0],
    [0, 255, 0],
    [0, 0, 255],
];

/// A rectangle of camera pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Roi {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

/// Settings of the colour calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourOptions {
    pub roi: Roi,
    /// Pixels sampled in the region (the paper uses 10,000).
    pub samples: usize,
    /// A sample with any channel at or above this level is dropped.
    pub saturation_level: u8,
    /// Seed of the pixel choice.
    pub seed: u64,
}

/// Something the operator should look at; the fit was still made.
#[derive(Debug, Clone, PartialEq)]
pub enum ColourWarning {
    /// More than 1 % of a capture's samples were clipped.
    Saturated { capture: usize, share: f64 },
    /// A coloured capture barely rises above the black level.
    TooDark { capture: usize, rise_gray: f64 },
    /// `A` is not diagonally dominant by rows or by columns: the camera and projector primaries
    /// do not match well and the decoder's noise grows.
    NotDiagonallyDominant,
}

impl std::fmt::Display for ColourWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ColourWarning::Saturated { capture, share } => write!(
                f,
                "capture {capture} is saturated on {:.1} % of the samples: lower the exposure",
                share * 100.0
            ),
            ColourWarning::TooDark { capture, rise_gray } => write!(
                f,
                "capture {capture} rises only {rise_gray:.1} gray levels above black: raise the exposure"
            ),
            ColourWarning::NotDiagonallyDominant => write!(
                f,
                "the cross-talk matrix is not diagonally dominant: check the camera's white balance and the projector's colour mode"
            ),
        }
    }
}

/// The result of a colour calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourCalibration {
    pub cross_talk: CrossTalk,
    /// RMS of `c − (A·p + b)` over the samples used, gray levels.
    pub residual_rms_gray: f64,
    /// Samples used per coloured capture.
    pub samples_used: Vec<usize>,
    pub warnings: Vec<ColourWarning>,
}

/// Fits `A` and `b` from the ten Table 1 captures, in [`TABLE1_LEVELS`] order.
pub fn calibrate_colour(
    captures: &[Frame],
    options: &ColourOptions,
) -> Result<ColourCalibration, CalibrationError> {
    if captures.len() != TABLE1_LEVELS.len() {
        return Err(CalibrationError::CaptureCount {
            expected: TABLE1_LEVELS.len(),
            got: captures.len(),
        });
    }
    let first = &captures[0];
    for capture in captures {
        capture.check_shape(first.width, first.height, 3)?;
    }
    let roi = options.roi;
    if roi.width == 0
        || roi.height == 0
        || roi.x + roi.width > first.width
        || roi.y + roi.height > first.height
    {
        return Err(CalibrationError::RoiOutside {
            roi,
            width: first.width,
            height: first.height,
        });
    }
    let pixels = sample_pixels(roi, first.width, options.samples, options.seed);
    let sample = |capture: &Frame, p: usize| -> Option<Vector3<f64>> {
        let px = &capture.data[p * 3..p * 3 + 3];
        if px.iter().any(|&v| v >= options.saturation_level) {
            return None;
        }
        Some(Vector3::new(
            f64::from(px[0]),
            f64::from(px[1]),
            f64::from(px[2]),
        ))
    };
    let mut warnings = Vec::new();
    let mut saturation_check = |index: usize, used: usize| {
        let share = 1.0 - used as f64 / pixels.len() as f64;
        if share > 0.01 {
            warnings.push(ColourWarning::Saturated {
                capture: index,
                share,
            });
        }
    };

    // b: mean of the black capture (eq. 19).
    let black: Vec<Vector3<f64>> = pixels.iter().filter_map(|&p| sample(first, p)).collect();
    saturation_check(0, black.len());
    if black.is_empty() {
        return Err(CalibrationError::NoUsableSamples { capture: 0 });
    }
    let b = black.iter().sum::<Vector3<f64>>() / black.len() as f64;

    // Normal equations of the three row problems: Σ p·pᵀ and Σ p·(c − b)ᵀ.
    let mut ptp = Matrix3::<f64>::zeros();
    let mut ptc = Matrix3::<f64>::zeros();
    let mut samples_used = Vec::with_capacity(9);
    let mut rises = Vec::with_capacity(9);
    for (index, (capture, levels)) in captures.iter().zip(&TABLE1_LEVELS).enumerate().skip(1) {
        let p = Vector3::new(
            f64::from(levels[0]),
            f64::from(levels[1]),
            f64::from(levels[2]),
        );
        let mut used = 0usize;
        let mut mean = Vector3::zeros();
        for &pixel in &pixels {
            if let Some(c) = sample(capture, pixel) {
                let y = c - b;
                ptp += p * p.transpose();
                ptc += p * y.transpose();
                mean += y;
                used += 1;
            }
        }
        saturation_check(index, used);
        if used == 0 {
            return Err(CalibrationError::NoUsableSamples { capture: index });
        }
        rises.push((index, (mean / used as f64).max()));
        samples_used.push(used);
    }
    for (capture, rise_gray) in rises {
        if rise_gray < 10.0 {
            warnings.push(ColourWarning::TooDark { capture, rise_gray });
        }
    }
    // Rows of A: ptp · A_jᵀ = ptc[:, j], i.e. ptp · Aᵀ = ptc.
    let a_transposed = ptp.try_inverse().ok_or(CalibrationError::Singular)? * ptc;
    let a = a_transposed.transpose();

    let mut sum2 = 0.0;
    let mut count = 0usize;
    for (capture, levels) in captures.iter().zip(&TABLE1_LEVELS) {
        let p = Vector3::new(
            f64::from(levels[0]),
            f64::from(levels[1]),
            f64::from(levels[2]),
        );
        let predicted = a * p + b;
        for &pixel in &pixels {
            if let Some(c) = sample(capture, pixel) {
                sum2 += (c - predicted).norm_squared();
                count += 3;
            }
        }
    }
    if !diagonally_dominant(&a) {
        warnings.push(ColourWarning::NotDiagonallyDominant);
    }
    Ok(ColourCalibration {
        cross_talk: CrossTalk { a, b_gray: b },
        residual_rms_gray: (sum2 / count.max(1) as f64).sqrt(),
        samples_used,
        warnings,
    })
}

/// Whether every diagonal entry outweighs the rest of its row and of its column.
pub fn diagonally_dominant(a: &Matrix3<f64>) -> bool {
    (0..3).all(|i| {
        let row: f64 = (0..3).filter(|&j| j != i).map(|j| a[(i, j)].abs()).sum();
        let col: f64 = (0..3).filter(|&j| j != i).map(|j| a[(j, i)].abs()).sum();
        a[(i, i)] > row && a[(i, i)] > col
    })
}

/// `count` pseudo-random pixel indices inside `roi` (with repetition when the region is smaller).
fn sample_pixels(roi: Roi, width: usize, count: usize, seed: u64) -> Vec<usize> {
    // SplitMix64: consecutive outputs are independent, unlike the low bits of an LCG.
    let mut state = seed;
    let mut next = || {
        let value = splitmix64(state) as usize;
        state = state.wrapping_add(SPLITMIX_INCREMENT);
        value
    };
    (0..count.max(1))
        .map(|_| {
            let x = roi.x + next() % roi.width;
            let y = roi.y + next() % roi.height;
            y * width + x
        })
        .collect()
}
