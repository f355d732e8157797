//! Decode backends: where the stages of one window run.
//!
//! [`super::SlidingDecoder`] keeps the frames, checks each window, picks its solver and sizes the
//! output; a [`DecodeBackend`] then turns the window into projector coordinates. [`CpuBackend`]
//! runs the stages of this module with rayon. A GPU backend (the application crate's
//! `gpu_decode`, on wgpu) implements the same trait, so the pipeline, the bench and the tests
//! drive both alike.
//!
//! The contract, what every backend fills for a window: `coordinate_px` (NaN where invalid),
//! `invalid` (the [`super::invalid`] reason bits), `amplitude` and `colour` (row-planar, as
//! [`DecodeOutput`] lays them out) and `timings`. The CPU backend also fills the intermediate
//! planes (`phase_rad`, `coarse_px`); other backends may leave them as they were.

use super::WindowSolver;
use super::{finish_window, phasor, DecodeError, DecodeOutput, DecodeParams, UnwrapMethod};
use crate::frame::Frame;
use std::time::Instant;

/// One checked window, handed to a backend.
#[derive(Debug, Clone, Copy)]
pub struct Window<'a> {
    pub solver: &'a WindowSolver,
    /// The window's frames, oldest first, in `solver.order`; same size and channel count.
    pub frames: &'a [&'a Frame],
    /// How many of the newest frames were not part of the previous window handed to this
    /// backend (the window length after a reset). A backend that keeps frames (on a GPU) uploads
    /// only these.
    pub new_frames: usize,
    pub params: &'a DecodeParams,
    /// `n` of a Chebyshev sequence.
    pub chebyshev_n: Option<u32>,
}

/// Runs the decode stages of a window.
pub trait DecodeBackend: Send + std::fmt::Debug {
    /// What runs the decode, for status lines and reports ("CPU (2 threads)").
    fn name(&self) -> String;

    /// Decodes `window` into `out`, which is already sized for it and stamped with its time.
    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError>;
}

/// The stages of this module on the CPU, in parallel row bands.
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuBackend;

impl DecodeBackend for CpuBackend {
    fn name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError> {
        let started = Instant::now();
        let chebyshev = window.params.unwrap != UnwrapMethod::Temporal;
        phasor::solve_phasors(window.solver, window.frames, window.params, chebyshev, out);
        finish_window(
            window.solver,
            window.params,
            window.chebyshev_n,
            started,
            out,
        );
        Ok(())
    }
}
