//! `--unwrap` and `--coarse-average`, shared by every command that decodes a session: the unwrap
//! method, when a user wants another than the one the sequence takes, and how the coarse phase is
//! averaged.

use anyhow::{Context, Result};
use tremorscan::decode::{DecodeParams, SmoothingParams, UnwrapMethod};
use tremorscan::session::{Session, SessionDecoding};

#[derive(clap::Args, Debug, Clone, Default)]
pub struct UnwrapArgs {
    /// Unwrap method. Default: the one the sequence takes (chebyshev-robust for CPS, temporal
    /// for a multi-frequency sequence with the unit frequency).
    #[arg(long, value_enum)]
    pub unwrap: Option<UnwrapArg>,
    /// How the robust unwrap averages the coarse (unit) phase over each pixel's neighbourhood.
    /// Default: plain.
    #[arg(long, value_enum)]
    pub coarse_average: Option<CoarseAverageArg>,
}

/// The coarse averages by their command-line names (and as the GUI's settings store them).
#[derive(
    clap::ValueEnum,
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum CoarseAverageArg {
    /// The unit phasor summed as it is, decay 0.7 (the default). Pixels the motion model finds
    /// moving take a wider average of their own either way (`MotionParams::moving_unit_decay`).
    #[default]
    Plain,
    /// Carried along the fine phase, decay 0.8: keeps a little more of a swaying hand, with more
    /// made-up points behind a soft lens and after a corrupted frame (docs/accuracy.md, Motion).
    Transported,
}

impl CoarseAverageArg {
    pub fn smoothing(self) -> SmoothingParams {
        match self {
            CoarseAverageArg::Plain => SmoothingParams::default(),
            CoarseAverageArg::Transported => SmoothingParams::transported(),
        }
    }
}

/// The unwrap methods by their command-line names.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnwrapArg {
    /// Chebyshev relation, averaged over an edge-aware neighbourhood (CPS sequences).
    ChebyshevRobust,
    /// The paper's per-pixel Chebyshev formula, eqs. 13–15 (CPS sequences).
    ChebyshevPerPixel,
    /// Eq. 8 from the unit frequency up (multi-frequency sequences).
    Temporal,
}

impl UnwrapArg {
    pub fn method(self) -> UnwrapMethod {
        match self {
            UnwrapArg::ChebyshevRobust => UnwrapMethod::ChebyshevRobust,
            UnwrapArg::ChebyshevPerPixel => UnwrapMethod::ChebyshevPerPixel,
            UnwrapArg::Temporal => UnwrapMethod::Temporal,
        }
    }
}

impl UnwrapArgs {
    /// The requested method, if any.
    pub fn requested(&self) -> Option<UnwrapMethod> {
        self.unwrap.map(UnwrapArg::method)
    }

    /// The smoothing of the requested coarse average (the default's when none was asked for).
    pub fn smoothing(&self) -> SmoothingParams {
        self.coarse_average
            .map_or_else(SmoothingParams::default, CoarseAverageArg::smoothing)
    }

    /// How `session` is decoded: `base` with the method, the coarse average and the session's
    /// camera noise.
    pub fn session_decoding(
        &self,
        session: &Session,
        mut base: DecodeParams,
    ) -> Result<SessionDecoding> {
        if self.coarse_average.is_some() {
            base.smoothing = self.smoothing();
        }
        SessionDecoding::new(session, self.requested(), base)
            .with_context(|| format!("choosing how to decode session {}", session.dir.display()))
    }
}
