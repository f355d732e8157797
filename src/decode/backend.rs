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
//! planes (`phase_rad`, `coarse_px`) and the motion model's (`velocity_px_per_s`,
//! `brightness_rate_per_s`, `acceleration_px_per_s2`); other backends may leave them as they
//! were (the GPU's stay on the device).

use super::WindowSolver;
use super::{
    finish_window, motion_basis, phasor, DecodeError, DecodeOutput, DecodeParams, UnwrapMethod,
};
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
    /// What runs the decode, for status lines and reports ("CPU (AVX-512, 2 threads)").
    fn name(&self) -> String;

    /// Decodes `window` into `out`, which is already sized for it and stamped with its time.
    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError>;
}

/// The instruction set the decode's row kernels run on this CPU, as their runtime dispatch
/// (`multiversion`, with the targets of the kernels) chooses it: "AVX-512", "AVX2+FMA", "SSE4.1"
/// or "baseline".
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub fn kernel_instruction_set() -> &'static str {
    multiversion::target::match_target! {
        "x86_64+avx512f" => "AVX-512",
        "x86_64+avx2+fma" => "AVX2+FMA",
        "x86_64+sse4.1" => "SSE4.1",
        _ => "baseline",
    }
}

/// The stages of this module on the CPU, in parallel row bands.
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuBackend;

impl DecodeBackend for CpuBackend {
    fn name(&self) -> String {
        format!(
            "CPU ({}, {} threads)",
            kernel_instruction_set(),
            rayon::current_num_threads()
        )
    }

    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError> {
        let started = Instant::now();
        let chebyshev = window.params.unwrap != UnwrapMethod::Temporal;
        let basis = motion_basis(window.solver, window.frames, window.params);
        phasor::solve_phasors(
            window.solver,
            window.frames,
            window.params,
            chebyshev,
            basis.as_ref(),
            out,
        );
        finish_window(
            window.solver,
            window.params,
            window.chebyshev_n,
            basis.as_ref(),
            started,
            out,
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reported_instruction_set_is_the_best_this_cpu_has() {
        let got = kernel_instruction_set();
        #[cfg(target_arch = "x86_64")]
        {
            // The AVX-512 kernels need the whole Ice Lake / Zen 4 set (multiversion adds it), so
            // only the AVX2 and SSE4.1 steps are implied by single features.
            let avx2 = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
            let expected_floor = if avx2 {
                ["AVX-512", "AVX2+FMA"].as_slice()
            } else if is_x86_feature_detected!("sse4.1") {
                ["SSE4.1"].as_slice()
            } else {
                ["baseline"].as_slice()
            };
            assert!(expected_floor.contains(&got), "{got}");
            let ice_lake_set = is_x86_feature_detected!("avx512f")
                && is_x86_feature_detected!("avx512bw")
                && is_x86_feature_detected!("avx512cd")
                && is_x86_feature_detected!("avx512dq")
                && is_x86_feature_detected!("avx512vl")
                && is_x86_feature_detected!("avx512ifma")
                && is_x86_feature_detected!("avx512vbmi")
                && is_x86_feature_detected!("avx512vbmi2")
                && is_x86_feature_detected!("avx512vnni")
                && is_x86_feature_detected!("avx512bitalg")
                && is_x86_feature_detected!("avx512vpopcntdq")
                && is_x86_feature_detected!("gfni")
                && is_x86_feature_detected!("vaes")
                && is_x86_feature_detected!("vpclmulqdq");
            assert_eq!(got == "AVX-512", avx2 && ice_lake_set, "{got}");
        }
        #[cfg(not(target_arch = "x86_64"))]
        assert_eq!(got, "baseline");
        assert!(CpuBackend.name().starts_with(&format!("CPU ({got}, ")));
    }
}
