//! `--unwrap`, shared by every command that decodes a session or the rig: the unwrap method,
//! when a user wants another than the one the sequence takes.

use anyhow::{Context, Result};
use tremorscan::decode::{DecodeParams, UnwrapMethod};
use tremorscan::session::{Session, SessionDecoding};

#[derive(clap::Args, Debug, Clone, Default)]
pub struct UnwrapArgs {
    /// Unwrap method. Default: the one the sequence takes (chebyshev-robust for CPS, temporal
    /// for a multi-frequency sequence with the unit frequency).
    #[arg(long, value_enum)]
    pub unwrap: Option<UnwrapArg>,
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

    /// How `session` is decoded: `base` with the method and the session's camera noise.
    pub fn session_decoding(
        &self,
        session: &Session,
        base: DecodeParams,
    ) -> Result<SessionDecoding> {
        SessionDecoding::new(session, self.requested(), base)
            .with_context(|| format!("choosing how to decode session {}", session.dir.display()))
    }
}
