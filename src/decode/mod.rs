//! Decoding: from a window of camera frames to projector coordinate, amplitude, colour, validity.
//!
//! The work is split into plain stages over a preallocated [`DecodeOutput`]:
//!
//! 1. [`phasor`]: per pixel, solve the window's linear system (paper eqs. 4 / 22) with the
//!    precomputed pseudo-inverse of [`solver::WindowSolver`]; write wrapped phases, amplitudes, the
//!    offset colour and, for CPS, the Chebyshev unit phasor.
//!    With the motion model ([`MotionModel::Linear`], CPS-RGB windows), stage 1 writes the
//!    evidence of each pixel's velocity instead, [`smooth`] sums it over the pixel's patch and
//!    [`motion`] corrects every frequency's phasor for the motion inside the window.
//! 2. [`smooth`]: for the robust CPS unwrap only, average the unit phasor over an edge-aware
//!    neighbourhood (a recursive domain filter that stops at depth and colour edges).
//! 3. [`unwrap`]: unwrap each wrapped phase with the coarse coordinate (eq. 8), combine the maps
//!    weighted by amplitude, and mark invalid pixels with the reasons in [`invalid`].
//! 4. `consistency` (robust unwrap only): mark connected neighbours whose fringe orders
//!    disagree.
//!
//! Rows are processed in bands in parallel with rayon; buffers are laid out row-planar
//! (`[row][plane][x]`) so that every per-row loop runs over contiguous `f32` and vectorises.
//! [`window::SlidingDecoder`] drives a [`backend::DecodeBackend`] (these stages on the CPU, or a
//! GPU) over a stream of frames; [`reference`] is the
//! straightforward per-pixel solve the fast path is tested and benchmarked against.

pub mod backend;
pub mod broken;
mod connect;
mod consistency;
pub mod edges;
pub mod fastmath;
mod method;
pub mod motion;
mod motion_advect;
mod motion_basis;
pub use motion_basis::motion_basis;
mod motion_blocks;
mod motion_correct;
mod motion_evidence;
mod motion_moving;
pub mod motion_noise;
mod motion_params;
pub use motion_params::{MotionModel, MotionParams};
mod motion_predict;
pub mod noise;
mod output;
pub mod phasor;
mod phasor_blocks;
pub mod reference;
pub mod smooth;
mod smooth_blocks;
mod smooth_moving;
mod smooth_transport;
pub mod solver;
mod temporal;
pub mod unwrap;
pub mod window;

pub use backend::{CpuBackend, DecodeBackend};
pub use motion::MotionBasis;
pub use output::{DecodeOutput, StageTimings};
pub use solver::WindowSolver;
pub use window::{SlidingDecoder, WindowOutcome};

use crate::frame::{Frame, FrameError};
use crate::pattern::{PatternError, PatternSequence};
use std::borrow::Borrow;
use std::time::Instant;

/// Rows per parallel band.
pub(crate) const BAND_ROWS: usize = 8;

pub mod invalid;

/// Errors of the decode module.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DecodeError {
    #[error(transparent)]
    Pattern(#[from] PatternError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("pattern index {index} is out of range for a sequence of {len} images")]
    PatternIndex { index: usize, len: usize },
    #[error("window {order:?} gives {observations} observations for {unknowns} unknowns, or repeats a shift: it cannot be solved")]
    Underdetermined {
        order: Vec<usize>,
        observations: usize,
        unknowns: usize,
    },
    #[error("window has {observations} observations, at most {max} are supported")]
    WindowTooLong { observations: usize, max: usize },
    #[error("numerical failure while inverting the window system: {0}")]
    Numerical(String),
    #[error(
        "frame {position} of the window shows pattern {got}, the solver expects pattern {expected}"
    )]
    OrderMismatch {
        position: usize,
        expected: usize,
        got: usize,
    },
    #[error("frame size {width}×{height} is empty")]
    EmptyFrame { width: usize, height: usize },
    #[error("the window needs {expected} frames, got {got}")]
    WrongFrameCount { expected: usize, got: usize },
    #[error("an RGB pattern sequence needs RGB camera frames, got {0} channel(s)")]
    NeedsColourFrames(usize),
    #[error("unwrap method {method:?} needs a Chebyshev sequence (frequencies n, n−1, n−2), this one has {frequencies:?}")]
    NeedsChebyshev {
        method: UnwrapMethod,
        frequencies: Vec<u32>,
    },
    #[error("temporal unwrapping needs the unit frequency (lowest m ≤ 2), lowest here is {0}")]
    NeedsUnitFrequency(u32),
    #[error("no unwrap method can decode frequencies {frequencies:?}: the Chebyshev unwrap needs three consecutive frequencies (n, n−1, n−2), the temporal unwrap needs the unit frequency (lowest m ≤ 2) and a finer one")]
    NoUnwrapMethod { frequencies: Vec<u32> },
    /// The backend (a GPU) failed; the message says what it was doing.
    #[error("{backend}: {message}")]
    Backend { backend: String, message: String },
}

/// How the wrapped phases are unwrapped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnwrapMethod {
    /// (a) The paper's per-pixel Chebyshev formula, eqs. 13–15, with its c/s branch.
    ChebyshevPerPixel,
    /// (b) Branch-free least-squares use of both Chebyshev equations, averaged over an edge-aware
    /// neighbourhood before unwrapping. The default: the unit phase amplifies noise about n/2
    /// times, so per-pixel unwrapping fails on a large share of pixels at ordinary camera noise.
    ChebyshevRobust,
    /// (c) Sequential temporal unwrapping (eq. 8) of a multi-frequency sequence.
    Temporal,
}

/// Parameters of the edge-aware averaging of the unit phasor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothingParams {
    /// Per-pixel decay of the recursive filter; 0.7 gives about 11 effective samples per axis
    /// (`(1 + d)³ / ((1 − d)(1 + d²))`), 0.8 about 18.
    pub decay: f32,
    /// Neighbours whose wrapped phase of any frequency differs by more than this are not connected.
    pub edge_phase_rad: f32,
    /// Neighbours whose colour differs by more than this fraction (plus 6 gray levels) are not connected.
    pub edge_colour_ratio: f32,
    /// Neighbours whose red or blue chromaticity (share of r + g + b) differs by more than this
    /// are not connected: skin against most backgrounds.
    pub edge_chromaticity: f32,
    /// Pixels with less total filter weight than this are marked [`invalid::LOW_SUPPORT`].
    pub min_support: f32,
    /// Carry the unit phasor's sum along the fine phase (CPS windows, CPU and GPU;
    /// [`smooth`]'s `smooth_transport`): unbiased by the coordinate's gradient and curvature
    /// at any decay, so the decay can be raised. Off by default (see `decay`).
    pub transport: bool,
}

impl Default for SmoothingParams {
    fn default() -> Self {
        Self {
            // Carried along the fine phase (`transport`) a wider average is unbiased, and under
            // motion it removes the ripple the velocity's correction leaves on the unit phase.
            // On the motion sweep (10 mm; with 4 mm of sway), plain at 0.7: 97.3 % of the moving
            // skin kept, 0.32 % gross; 90.3 %, 0.80 %. Transported at 0.8: 97.5 %, 0.29 %;
            // 93.6 %, 0.48 %. Not yet the default: a wider, cleaner coarse estimate also rounds
            // the pixels a systematic error pulls together, which the narrow, noisy one refused
            // for the margin by chance. Behind a soft lens (σ = 1 px) the outlines keep 0.09 %
            // of the valid pixels more than 2 mm off at 0.8 (0.05 % at 0.7; 0.14 % at 0.85),
            // and a window with a corrupted frame gives 0.56 % of the image a wrong fringe
            // order (0.32 % at 0.7; `tests/validity.rs` allows 0.5 %) (docs/accuracy.md, Motion).
            // Both are still scenes: the pixels the motion model finds moving take a wider,
            // transported average instead (`MotionParams::moving_unit_decay`).
            decay: 0.7,
            edge_phase_rad: 1.0,
            edge_colour_ratio: 0.3,
            edge_chromaticity: 0.03,
            min_support: 15.0,
            transport: false,
        }
    }
}

impl SmoothingParams {
    /// The unit phasor carried along the fine phase at decay 0.8: under motion it keeps more of
    /// the moving skin (on the rig's swaying hand at 10 mm, 93.6 % with 0.48 % gross against
    /// 90.3 % and 0.80 %), at the costs docs/accuracy.md (Motion, stop 37) measures: more
    /// made-up points on outlines behind a soft lens and more wrong fringe orders in a window
    /// with a corrupted frame. Not the default for those.
    pub fn transported() -> Self {
        Self {
            decay: 0.8,
            transport: true,
            ..Self::default()
        }
    }
}

/// Decoder settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeParams {
    pub unwrap: UnwrapMethod,
    /// Smallest acceptable per-frequency amplitude, in the solver's intensity units (gray levels
    /// before cross-talk).
    pub min_amplitude: f32,
    /// A sample at or above this level marks the pixel saturated.
    pub saturation_level: u8,
    /// Largest accepted distance of the eq. 8 argument from its nearest integer (0.5 is the limit).
    pub max_rounding_residual: f32,
    /// Camera noise the disagreement test assumes, gray levels (standard deviation per sample).
    pub camera_noise_gray: f32,
    /// Largest accepted χ² (two degrees of freedom) of the unwrapped CPS maps about their
    /// combination, given `camera_noise_gray`; 25 is exceeded by chance with probability 4·10⁻⁶.
    pub max_disagreement_chi2: f32,
    /// Mark connected neighbours whose fringe orders disagree ([`invalid::ORDER_JUMP`]).
    pub check_order_jumps: bool,
    /// Smallest disagreement, projector px, between linear extrapolations of the coordinate
    /// that counts as a depth edge for [`invalid::MIXED`] ([`edges`]; the predicted noise may
    /// raise it); 0 turns the check off.
    pub mixed_limit_px: f32,
    pub smoothing: SmoothingParams,
    /// Motion inside the window.
    pub motion: MotionParams,
    /// How many camera px each px of the decays' reach stands for ([`Self::reach_scale_at`]):
    /// `None` follows the image's width, so that the edge-aware sums reach as far on the skin
    /// at the camera's full resolution as in the 640 px wide image they were chosen on.
    pub reach_scale: Option<f32>,
}

/// The image width, camera px, the decays of the edge-aware sums are stated for: the rig's
/// default image, the camera's 1920×1200 binned 3×3, where they were measured
/// (docs/accuracy.md, Motion).
pub const REACH_REFERENCE_WIDTH_PX: usize = 640;

impl Default for DecodeParams {
    fn default() -> Self {
        Self {
            unwrap: UnwrapMethod::ChebyshevRobust,
            min_amplitude: 4.0,
            saturation_level: 255,
            max_rounding_residual: 0.3,
            camera_noise_gray: 2.0,
            max_disagreement_chi2: 25.0,
            check_order_jumps: true,
            mixed_limit_px: 1.5,
            smoothing: SmoothingParams::default(),
            motion: MotionParams::default(),
            reach_scale: None,
        }
    }
}

impl DecodeParams {
    /// How many camera px of an image `width_px` wide each px of the decays' reach stands for:
    /// [`Self::reach_scale`] when set (at least 1), else `width_px` over
    /// [`REACH_REFERENCE_WIDTH_PX`], never below 1. A sum's decay is per camera px, so the same
    /// decay reaches a third as far on the skin at 1920 px as at 640 px: there the fringes and
    /// the ripple the velocity's correction leaves on them span three times the pixels, and
    /// sums that no longer average over them lose the moving skin (docs/accuracy.md). Narrower
    /// images keep the stated decays: their sums would otherwise pool too few samples.
    pub fn reach_scale_at(&self, width_px: usize) -> f32 {
        let scale = self
            .reach_scale
            .unwrap_or(width_px as f32 / REACH_REFERENCE_WIDTH_PX as f32);
        if scale.is_finite() {
            scale.max(1.0)
        } else {
            1.0
        }
    }

    /// The unit phasor's decay per camera px in an image `width_px` wide: the same reach on the
    /// skin as [`SmoothingParams::decay`] at the reference width.
    pub fn unit_decay_at(&self, width_px: usize) -> f32 {
        self.smoothing
            .decay
            .powf(1.0 / self.reach_scale_at(width_px))
    }

    /// The moving pixels' unit-phasor decay per camera px in an image `width_px` wide (as
    /// [`Self::unit_decay_at`] for [`MotionParams::moving_unit_decay`]).
    pub fn moving_unit_decay_at(&self, width_px: usize) -> Option<f32> {
        self.motion
            .moving_unit_decay
            .map(|d| d.powf(1.0 / self.reach_scale_at(width_px)))
    }

    /// The velocity evidence's decay per camera px in an image `width_px` wide (as
    /// [`Self::unit_decay_at`] for [`MotionParams::decay`]).
    pub fn motion_decay_at(&self, width_px: usize) -> f32 {
        self.motion.decay.powf(1.0 / self.reach_scale_at(width_px))
    }
}

/// Decodes one window of `frames` (oldest first, matching `solver.order`) into `out`. `frames`
/// may hold the frames themselves or references to them.
pub fn decode_window<F: Borrow<Frame> + Sync>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    chebyshev_n: Option<u32>,
    out: &mut DecodeOutput,
) -> Result<(), DecodeError> {
    check_window(solver, frames, params, chebyshev_n, out)?;
    let chebyshev = params.unwrap != UnwrapMethod::Temporal;
    let started = Instant::now();
    let basis = motion_basis(solver, frames, params);
    phasor::solve_phasors(solver, frames, params, chebyshev, basis.as_ref(), out);
    finish_window(solver, params, chebyshev_n, basis.as_ref(), started, out);
    Ok(())
}

/// How many frames each decoded coordinate of a stream of `sequence` averages, which the tremor
/// analysis undoes (`tremor::AnalysisOptions::window_frames`): 1 where the motion model moves
/// the coordinate to the window's centre time (CPS-RGB windows of three frames with
/// [`MotionModel::Linear`], see [`motion::remove_acceleration_shift`]), else the window's
/// length. Where the model takes no acceleration the coordinate keeps the frames' mean, and
/// the analysis undoes too little there (at most 2.5 % of the amplitude at 5 Hz): in a window
/// decoded without the one just before it (the first of a stream, or after a dropped frame,
/// as under a real-time decode that falls behind), and on skin whose velocity the model does
/// not find significant, which at a 2 mm tremor is most of it (there the shift is 0.02 px RMS;
/// at 10 mm, where it matters, the acceleration is taken on 56 % of the moving skin and the
/// rest moves too little to matter).
pub fn frames_averaged(sequence: &PatternSequence, params: &DecodeParams) -> usize {
    let takes_motion = params.motion.model == MotionModel::Linear
        && params.motion.iterations > 0
        && params.unwrap != UnwrapMethod::Temporal
        && sequence.entries.len() == 3
        && sequence.is_rgb()
        && sequence.chebyshev_n().is_some()
        && sequence.distinct_frequencies().len() == 3;
    if takes_motion {
        1
    } else {
        sequence.entries.len()
    }
}

/// Checks the window against `solver` and `params`, sizes `out` and stamps its time.
pub fn check_window<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    chebyshev_n: Option<u32>,
    out: &mut DecodeOutput,
) -> Result<(), DecodeError> {
    if frames.len() != solver.order.len() {
        return Err(DecodeError::WrongFrameCount {
            expected: solver.order.len(),
            got: frames.len(),
        });
    }
    if let Some((k, frame)) = frames
        .iter()
        .map(Borrow::borrow)
        .enumerate()
        .find(|(k, f)| f.pattern_index != solver.order[*k])
    {
        return Err(DecodeError::OrderMismatch {
            position: k,
            expected: solver.order[k],
            got: frame.pattern_index,
        });
    }
    let first: &Frame = frames[0].borrow();
    let (width, height) = (first.width, first.height);
    if width == 0 || height == 0 {
        return Err(DecodeError::EmptyFrame { width, height });
    }
    if solver.channels == 3 && first.channels != 3 {
        return Err(DecodeError::NeedsColourFrames(first.channels));
    }
    for frame in frames {
        frame.borrow().check_shape(width, height, first.channels)?;
    }
    match params.unwrap {
        UnwrapMethod::ChebyshevPerPixel | UnwrapMethod::ChebyshevRobust => {
            if chebyshev_n.is_none() || solver.frequencies.len() != 3 {
                return Err(DecodeError::NeedsChebyshev {
                    method: params.unwrap,
                    frequencies: solver.frequencies.clone(),
                });
            }
        }
        UnwrapMethod::Temporal => {
            let lowest = solver.frequencies.last().copied().unwrap_or(0);
            if lowest > 2 {
                return Err(DecodeError::NeedsUnitFrequency(lowest));
            }
        }
    }
    if !out.fits(width, height, solver) {
        *out = DecodeOutput::new(width, height, solver);
    }
    out.time_s = frames.iter().map(|f| f.borrow().time_s).sum::<f64>() / frames.len() as f64;
    Ok(())
}

/// Stages 2–4 after stage 1 (which started at `started`), and the timings.
pub(crate) fn finish_window(
    solver: &WindowSolver,
    params: &DecodeParams,
    chebyshev_n: Option<u32>,
    motion_basis: Option<&motion::MotionBasis>,
    started: Instant,
    out: &mut DecodeOutput,
) {
    let solved = Instant::now();
    if let Some(basis) = motion_basis {
        smooth::compute_connectivity(out, &params.smoothing);
        // The significance test's noise: the configured level, or the higher one the window's
        // residuals show.
        let mut scratch = std::mem::take(&mut out.noise_scratch);
        let measured = motion_noise::residual_noise_gray(solver, out, &mut scratch);
        out.noise_scratch = scratch;
        let noise_gray = motion_noise::significance_noise_gray(measured, params.camera_noise_gray);
        // The previous window's patch velocities give the acceleration only when that window
        // was the one just before.
        let previous = motion::consecutive_since(
            out.time_s,
            out.patch_velocity_time_s,
            basis.frame_interval_s,
        );
        let iterations = params.motion.iterations;
        // After the window just before, the first step starts from its motion.
        let predicted = previous.is_some() && params.motion.predicts_start();
        if predicted {
            let kind = motion::StepKind::Predicted;
            motion::motion_step(
                solver, params, noise_gray, basis, kind, false, previous, out,
            );
        }
        for i in 0..iterations {
            let kind = if i == 0 && !predicted {
                motion::StepKind::FromRest
            } else {
                motion::StepKind::Refine
            };
            let last = i + 1 == iterations;
            motion::motion_step(solver, params, noise_gray, basis, kind, last, previous, out);
        }
        out.patch_velocity_time_s = out.time_s;
    } else {
        out.patch_velocity_time_s = f64::NAN;
    }
    let corrected = Instant::now();
    let mut two_averages = false;
    if params.unwrap == UnwrapMethod::ChebyshevRobust {
        let smoothing = SmoothingParams {
            decay: params.unit_decay_at(out.width),
            ..params.smoothing
        };
        // A still scene (no velocity anywhere) skips the second average: it would change nothing.
        let moving = motion_basis
            .and(params.moving_unit_decay_at(out.width))
            .filter(|_| smooth_moving::any_moving(out));
        match (moving, chebyshev_n) {
            (Some(moving_decay), Some(n)) => {
                let check = smooth_moving::Agreement::new(solver, params, n);
                smooth_moving::smooth_both(out, &smoothing, moving_decay, &check);
                two_averages = true;
            }
            _ => smooth::smooth_unit_phasor(out, &smoothing, chebyshev_n),
        }
    }
    let smoothed = Instant::now();
    unwrap::unwrap_and_combine(solver, params, chebyshev_n, out);
    if let Some(basis) = motion_basis {
        // A pixel's own recent past settles an uncertain rounding; the references are those
        // of the temporal check below, so only with it.
        if params.unwrap == UnwrapMethod::ChebyshevRobust && params.check_order_jumps {
            let cps = unwrap::CpsMaps::new(&solver.frequency_rad_per_px, &solver.noise_gain);
            temporal::settle_margin_from_recent(
                out,
                &cps,
                params.max_rounding_residual,
                basis.frame_interval_s,
                two_averages,
            );
        }
        motion::remove_acceleration_shift(basis, out);
    }
    if params.unwrap == UnwrapMethod::ChebyshevRobust && params.check_order_jumps {
        let half_period_px = std::f32::consts::PI / solver.frequency_rad_per_px[0];
        consistency::flag_order_jumps(out, half_period_px);
        if let Some(basis) = motion_basis {
            temporal::flag_temporal_jumps(
                out,
                2.0 * half_period_px,
                basis.max_velocity * basis.frame_interval_s,
                basis.frame_interval_s,
            );
        }
    }
    edges::flag_mixed_pixels(solver, params, out);
    broken::refuse_broken_window(out);
    if motion_basis.is_some() {
        out.clear_motion_where_invalid();
    }
    let done = Instant::now();
    out.timings = StageTimings {
        solve_ms: (solved - started).as_secs_f64() * 1e3,
        motion_ms: (corrected - solved).as_secs_f64() * 1e3,
        smooth_ms: (smoothed - corrected).as_secs_f64() * 1e3,
        unwrap_ms: (done - smoothed).as_secs_f64() * 1e3,
        device_ms: None,
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pattern::{cps_gray, cps_rgb, Axis, CpsGrayVariant};

    #[test]
    fn only_the_motion_model_on_cps_rgb_reports_the_window_centre() {
        let rgb = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let gray = cps_gray(65, CpsGrayVariant::Minimal7, 912.0, Axis::Columns, 8).unwrap();
        let still = DecodeParams {
            motion: MotionParams::off(),
            ..DecodeParams::default()
        };
        assert_eq!(frames_averaged(&rgb, &DecodeParams::default()), 1);
        assert_eq!(frames_averaged(&rgb, &still), 3);
        assert_eq!(frames_averaged(&gray, &DecodeParams::default()), 7);
    }
}
