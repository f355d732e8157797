//! The uniform of `shaders/decode.wgsl`, filled from a window solver and the decode settings,
//! and which settings the GPU decoder does not implement.

use bytemuck::{Pod, Zeroable};
use std::f32::consts::PI;
use tremorscan::decode::smooth::recursion_halo;
use tremorscan::decode::{DecodeParams, UnwrapMethod, WindowSolver};

/// `Params` of `shaders/decode.wgsl`, byte for byte (112 bytes; the vec3 members are 16-byte
/// aligned there, which the field order here reproduces).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct DecodeUniform {
    pub width: u32,
    pub height: u32,
    pub frame_words: u32,
    pub n: u32,
    pub saturation_level: u32,
    pub check_jumps: u32,
    /// The frame slot holding the window's oldest frame.
    pub first_slot: u32,
    pub pad0: u32,
    pub freq: [f32; 3],
    pub inv_f_unit: f32,
    pub gain: [f32; 3],
    pub x_max: f32,
    pub min_amplitude: f32,
    pub camera_noise_gray: f32,
    pub max_disagreement_chi2: f32,
    pub max_rounding_residual: f32,
    pub decay: f32,
    pub edge_phase_rad: f32,
    pub edge_colour_ratio: f32,
    pub edge_chromaticity: f32,
    pub min_support: f32,
    pub half_period_px: f32,
    /// 1/n with [`tremorscan::decode::SmoothingParams::transport`], else 0.
    pub unit_per_fine: f32,
    /// The recursions' warm-up beyond a segment's ends, px (see `recursion_halo`).
    pub halo: u32,
}

impl DecodeUniform {
    /// The constants for a `width`×`height` window of `solver` (a CPS-RGB window with
    /// frequencies n, n−1, n−2) decoded with `params`; the same values the CPU stages derive.
    pub fn new(
        width: usize,
        height: usize,
        solver: &WindowSolver,
        params: &DecodeParams,
        chebyshev_n: u32,
    ) -> Self {
        let f = &solver.frequency_rad_per_px;
        let g = &solver.noise_gain;
        let n = width * height;
        let s = &params.smoothing;
        Self {
            width: width as u32,
            height: height as u32,
            frame_words: (n * 3).div_ceil(4) as u32,
            n: n as u32,
            saturation_level: u32::from(params.saturation_level),
            check_jumps: u32::from(params.check_order_jumps),
            first_slot: 0,
            pad0: 0,
            freq: [f[0], f[1], f[2]],
            inv_f_unit: 1.0 / (f[0] / chebyshev_n as f32),
            gain: [g[0], g[1], g[2]],
            x_max: solver.frequencies[0] as f32 * PI / f[0],
            min_amplitude: params.min_amplitude,
            camera_noise_gray: params.camera_noise_gray,
            max_disagreement_chi2: params.max_disagreement_chi2,
            max_rounding_residual: params.max_rounding_residual,
            decay: params.unit_decay_at(width),
            edge_phase_rad: s.edge_phase_rad,
            edge_colour_ratio: s.edge_colour_ratio,
            edge_chromaticity: s.edge_chromaticity,
            min_support: s.min_support,
            half_period_px: PI / f[0],
            unit_per_fine: if s.transport {
                1.0 / chebyshev_n as f32
            } else {
                0.0
            },
            halo: recursion_halo(params.unit_decay_at(width)),
        }
    }
}

/// Why `solver` and `params` cannot run on the GPU, if they cannot.
pub(crate) fn unsupported(
    solver_shape: (usize, usize, usize),
    params: &DecodeParams,
) -> Option<String> {
    let (channels, observations, unknowns) = solver_shape;
    if channels != 3 || observations != 9 || unknowns != 9 {
        return Some(format!(
            "the GPU decoder handles CPS-RGB windows (9 observations, 9 unknowns), not {observations} × {unknowns}"
        ));
    }
    if params.unwrap != UnwrapMethod::ChebyshevRobust {
        return Some(format!(
            "the GPU decoder implements the robust Chebyshev unwrap, not {:?}",
            params.unwrap
        ));
    }
    if params.motion.block_px > 1 {
        return Some(format!(
            "the GPU decoder sums the motion model's evidence per pixel, not over blocks of {} px",
            params.motion.block_px
        ));
    }
    if params.motion.advected_brightness {
        let why = "the GPU decoder keeps each patch's one brightness change";
        return Some(format!("{why} (MotionParams::advected_brightness)"));
    }
    None
}
