//! The decoder's output for one window, and the buffers the stages share.
//!
//! [`DecodeOutput`] holds the public results (wrapped phases, amplitudes, the offset colour, the
//! coarse and final coordinates, the invalid bits, the motion model's velocity, brightness
//! change and acceleration) beside the stages' scratch planes and what a stream carries from
//! one window to the next (the patch velocities for the acceleration, each pixel's recent
//! coordinate for the temporal order check). Everything is allocated once for a shape by
//! [`DecodeOutput::new`] (the opt-in advected brightness change's planes on its first window)
//! and reused: no stage allocates per window.

use super::motion_advect::AdvectScratch;
use super::smooth_blocks::BlockScratch;
use super::{invalid, motion_noise, phasor, smooth, WindowSolver, BAND_ROWS};

/// Flags that say a pixel's motion was not measured: too little light, saturation, a residual
/// the motion model does not explain, or too few connected neighbours for a patch. A chance
/// patch velocity at such a pixel (two on the rig's still hand, with the unit phasor
/// transported at 0.8: refused for the margin, the disagreement and the support together) gave
/// the next window an acceleration of 14,000 px/s².
const UNMEASURED_MOTION: u16 =
    invalid::LOW_AMPLITUDE | invalid::SATURATED | invalid::DISAGREEMENT | invalid::LOW_SUPPORT;

/// Wall-clock time of each decode stage for the last window, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StageTimings {
    pub solve_ms: f64,
    /// The motion model's velocity estimate and correction (0 without it).
    pub motion_ms: f64,
    pub smooth_ms: f64,
    pub unwrap_ms: f64,
    /// Time the device itself spent on the window's compute, as it measured it (GPU timestamp
    /// queries), when the backend has such a clock; transfers are not included.
    pub device_ms: Option<f64>,
}

impl StageTimings {
    pub fn total_ms(&self) -> f64 {
        self.solve_ms + self.motion_ms + self.smooth_ms + self.unwrap_ms
    }
}

/// The decoded result of one window, and the scratch the stages reuse. Per-frequency and
/// per-channel planes are row-planar: `plane[(row · planes + p) · width + x]`.
#[derive(Debug, Clone)]
pub struct DecodeOutput {
    pub width: usize,
    pub height: usize,
    /// Number of distinct frequencies (planes of `phase_rad` and `amplitude`), descending `m`.
    pub frequencies: usize,
    /// Number of colour planes (3 for RGB sequences, 1 for gray).
    pub channels: usize,
    /// Centre time of the window's frames, seconds.
    pub time_s: f64,
    /// Wrapped phase of each frequency in `[0, 2π)`.
    pub phase_rad: Vec<f32>,
    /// Amplitude of each frequency.
    pub amplitude: Vec<f32>,
    /// Offset image: the scene colour without the pattern, gray levels.
    pub colour: Vec<f32>,
    /// Coarse coordinate from the unit phase, projector px (NaN where not computed).
    pub coarse_px: Vec<f32>,
    /// Final projector coordinate, projector px; NaN where invalid.
    pub coordinate_px: Vec<f32>,
    /// Invalid-reason bits of [`super::invalid`]; 0 where valid.
    pub invalid: Vec<u16>,
    /// The motion model's coordinate velocity, projector px/s (0 where the pixel is invalid;
    /// untouched by windows decoded without the model). This and the next two planes are the
    /// CPU decoder's: the GPU backend keeps its motion planes on the device and leaves them
    /// untouched (nothing downstream of the decode reads them).
    pub velocity_px_per_s: Vec<f32>,
    /// The motion model's brightness change, relative per second (`κ`; as the velocity).
    pub brightness_rate_per_s: Vec<f32>,
    /// The motion model's coordinate acceleration, projector px/s²: the change of the pixel's
    /// patch velocity since the previous window, where that window was the one just before and
    /// the change moves the coordinate by more than the noise (see [`super::motion`]); 0
    /// elsewhere and where the pixel is invalid.
    pub acceleration_px_per_s2: Vec<f32>,
    /// How long each stage took for this window.
    pub timings: StageTimings,
    /// Set when the window was refused whole (a corrupted frame, [`super::broken`]): the rows
    /// that showed it (all of them, or the first broken band) and the share of their lit pixels
    /// that broke the phase relation. Every pixel is then [`super::invalid::BROKEN_WINDOW`].
    pub refused: Option<super::broken::Refusal>,
    pub(crate) unit_re: Vec<f32>,
    pub(crate) unit_im: Vec<f32>,
    pub(crate) support: Vec<f32>,
    pub(crate) connect: Vec<u8>,
    pub(crate) jump: Vec<u8>,
    pub(crate) smooth_tmp: Vec<f32>,
    /// Three planes of the motion model's evidence (`ue`, `ke`, count).
    pub(crate) motion_evidence: Vec<f32>,
    pub(crate) vertical_state: Vec<f32>,
    pub(crate) band_scratch: Vec<f32>,
    pub(crate) band_scratch_len: usize,
    /// The motion model's noise estimate's samples.
    pub(crate) noise_scratch: Vec<f32>,
    /// The motion model's block planes, when it sums its evidence over blocks.
    pub(crate) motion_blocks: BlockScratch,
    /// The advected brightness change's planes, when it is on.
    pub(crate) advect: AdvectScratch,
    /// The patch velocity of every pixel in the last window the motion model decoded (NaN where
    /// its patch had no evidence), px/s, and that window's centre time (NaN before the first):
    /// the acceleration's other end.
    pub(crate) patch_velocity_px_per_s: Vec<f32>,
    pub(crate) patch_velocity_time_s: f64,
    /// Whether that velocity was significant (1) or not (0).
    pub(crate) patch_moving: Vec<u8>,
    /// The sum of every pixel's projector-lit offsets (its slots', gray levels) in the same
    /// window, without the fringe that motion leaked into them: the brightness change's other
    /// end (`motion_moving`).
    pub(crate) lit_offset_sum: Vec<f32>,
    /// Each pixel's last valid coordinate in the motion model's recent windows (NaN before
    /// any), projector px, how many windows ago it was, and the time of the window that last
    /// updated them: the temporal order check's reference (`temporal`).
    pub(crate) recent_coordinate_px: Vec<f32>,
    pub(crate) recent_age_windows: Vec<u8>,
    pub(crate) recent_time_s: f64,
}

impl DecodeOutput {
    /// Forgets the stream's previous windows: the next window takes no acceleration and no
    /// temporal reference from what this output holds. A backend that keeps those on its own
    /// device (the GPU decode) calls it, so that the CPU taking over after a failure starts
    /// afresh rather than from planes it did not write.
    pub fn forget_stream(&mut self) {
        self.patch_velocity_time_s = f64::NAN;
        self.recent_time_s = f64::NAN;
    }

    /// Sets the motion model's planes (velocity, brightness change, acceleration) to 0 where
    /// the pixel is invalid, as their contract says. The model writes them before the later
    /// stages (unwrap, order jumps, mixed pixels) refuse a pixel, and a refused pixel's motion
    /// is no measurement: on the rig's still hand with the camera's blur, 12 refused
    /// pixel-windows at depth edges kept an acceleration from chance evidence.
    ///
    /// Where the pixel's own signal or neighbourhood failed ([`UNMEASURED_MOTION`]), the patch
    /// velocity the next window takes its acceleration from is forgotten too (NaN: no
    /// acceleration from it). Where only its fringe order failed, the patch velocity (from the
    /// neighbours' evidence) stays: forgetting it as well cost the moving skin's RMS 0.01 mm at
    /// a 20 mm tremor, the acceleration of pixels that regain their order being lost.
    pub fn clear_motion_where_invalid(&mut self) {
        for ((((flags, v), k), a), patch) in self
            .invalid
            .iter()
            .zip(&mut self.velocity_px_per_s)
            .zip(&mut self.brightness_rate_per_s)
            .zip(&mut self.acceleration_px_per_s2)
            .zip(&mut self.patch_velocity_px_per_s)
        {
            if *flags != 0 {
                (*v, *k, *a) = (0.0, 0.0, 0.0);
            }
            if *flags & UNMEASURED_MOTION != 0 {
                *patch = f32::NAN;
            }
        }
    }

    /// Allocates every buffer for `solver`'s shape at `width`×`height`.
    pub fn new(width: usize, height: usize, solver: &WindowSolver) -> Self {
        let n = width * height;
        let bands = height.div_ceil(BAND_ROWS);
        let band_scratch_len = scratch_per_band(width, solver);
        Self {
            width,
            height,
            frequencies: solver.frequencies.len(),
            channels: solver.channels,
            time_s: 0.0,
            phase_rad: vec![0.0; n * solver.frequencies.len()],
            amplitude: vec![0.0; n * solver.frequencies.len()],
            colour: vec![0.0; n * solver.channels],
            coarse_px: vec![f32::NAN; n],
            coordinate_px: vec![f32::NAN; n],
            invalid: vec![0; n],
            velocity_px_per_s: vec![0.0; n],
            brightness_rate_per_s: vec![0.0; n],
            acceleration_px_per_s2: vec![0.0; n],
            motion_evidence: vec![0.0; 3 * n],
            timings: StageTimings::default(),
            refused: None,
            unit_re: vec![0.0; n],
            unit_im: vec![0.0; n],
            support: vec![0.0; n],
            connect: vec![0; n],
            jump: vec![0; n],
            smooth_tmp: vec![0.0; 3 * n],
            vertical_state: vec![0.0; 3 * width * height.div_ceil(smooth::VERTICAL_BLOCK_ROWS)],
            band_scratch: vec![0.0; bands * band_scratch_len],
            band_scratch_len,
            noise_scratch: Vec::with_capacity(n / (motion_noise::GRID_STEP_PX.pow(2)) + width),
            motion_blocks: BlockScratch::default(),
            advect: AdvectScratch::default(),
            patch_velocity_px_per_s: vec![f32::NAN; n],
            patch_velocity_time_s: f64::NAN,
            patch_moving: vec![0; n],
            lit_offset_sum: vec![f32::NAN; n],
            recent_coordinate_px: vec![f32::NAN; n],
            recent_age_windows: vec![u8::MAX; n],
            recent_time_s: f64::NAN,
        }
    }

    /// Whether the buffers fit `solver` at `width`×`height`.
    pub fn fits(&self, width: usize, height: usize, solver: &WindowSolver) -> bool {
        self.width == width
            && self.height == height
            && self.frequencies == solver.frequencies.len()
            && self.channels == solver.channels
            && self.band_scratch_len >= scratch_per_band(width, solver)
    }

    #[inline]
    fn planar(&self, planes: usize, plane: usize, x: usize, y: usize) -> usize {
        (y * planes + plane) * self.width + x
    }

    /// Wrapped phase of frequency slot `f` at pixel `(x, y)`.
    pub fn phase_at(&self, f: usize, x: usize, y: usize) -> f32 {
        self.phase_rad[self.planar(self.frequencies, f, x, y)]
    }

    /// Amplitude of frequency slot `f` at pixel `(x, y)`.
    pub fn amplitude_at(&self, f: usize, x: usize, y: usize) -> f32 {
        self.amplitude[self.planar(self.frequencies, f, x, y)]
    }

    /// Offset colour of channel `c` at pixel `(x, y)`.
    pub fn colour_at(&self, c: usize, x: usize, y: usize) -> f32 {
        self.colour[self.planar(self.channels, c, x, y)]
    }

    /// Heap bytes held by the output and its scratch buffers.
    pub fn memory_bytes(&self) -> usize {
        let floats = self.phase_rad.capacity()
            + self.amplitude.capacity()
            + self.colour.capacity()
            + self.coarse_px.capacity()
            + self.coordinate_px.capacity()
            + self.velocity_px_per_s.capacity()
            + self.brightness_rate_per_s.capacity()
            + self.acceleration_px_per_s2.capacity()
            + self.patch_velocity_px_per_s.capacity()
            + self.lit_offset_sum.capacity()
            + self.recent_coordinate_px.capacity()
            + self.motion_evidence.capacity()
            + self.unit_re.capacity()
            + self.unit_im.capacity()
            + self.support.capacity()
            + self.smooth_tmp.capacity()
            + self.vertical_state.capacity()
            + self.band_scratch.capacity()
            + self.noise_scratch.capacity();
        let bytes = self.invalid.capacity()
            + self.connect.capacity()
            + self.jump.capacity()
            + self.patch_moving.capacity()
            + self.recent_age_windows.capacity();
        floats * std::mem::size_of::<f32>() + bytes + self.advect.memory_bytes()
    }

    /// Number of valid pixels.
    pub fn valid_count(&self) -> usize {
        self.invalid.iter().filter(|&&r| r == 0).count()
    }
}

/// Scratch floats each band needs: stage 1's chunk planes, or four rows (gains and the backward
/// recursion) for the smoothing (the rows of a band are processed one after another and reuse
/// it).
fn scratch_per_band(width: usize, solver: &WindowSolver) -> usize {
    // Five rows: the transported horizontal pass's two turn gains and three backward sums.
    (width * 5).max(phasor::scratch_len(solver))
}
