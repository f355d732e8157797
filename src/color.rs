//! Colour cross-talk model of the projector–camera pair (paper eq. 18): `c = A·p + b`.
//!
//! `p` is the projected colour (per projector channel, in the decoder's intensity units) and `c` the
//! camera colour in gray levels. Column `i` of `A` says how much projector channel `i` leaks into each
//! camera channel. Fitting `A` and `b` from the Table 1 captures is the calibration module's job.

use nalgebra::{Matrix3, Vector3};

/// The cross-talk matrix `A` (row = camera channel, column = projector channel) and offset `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossTalk {
    pub a: Matrix3<f64>,
    pub b_gray: Vector3<f64>,
}

impl CrossTalk {
    /// No cross-talk and no offset.
    pub fn identity() -> Self {
        Self {
            a: Matrix3::identity(),
            b_gray: Vector3::zeros(),
        }
    }

    /// The paper's measured matrix (eq. 24) with a small dark offset.
    pub fn paper() -> Self {
        Self {
            a: Matrix3::new(0.82, 0.11, 0.02, 0.22, 0.71, 0.08, 0.02, 0.14, 0.51),
            b_gray: Vector3::new(6.0, 7.0, 9.0),
        }
    }

    /// Observed camera colour for projected colour `p`.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.a * p + self.b_gray
    }
}

impl Default for CrossTalk {
    fn default() -> Self {
        Self::paper()
    }
}
