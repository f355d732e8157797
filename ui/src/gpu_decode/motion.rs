//! The host's side of the GPU motion model (`shaders/decode_motion.wgsl`): the words of the
//! shader's model buffer, the order of the entry points, the noise estimate finished from the
//! device's grid, and the stream's clock.
//!
//! The model buffer holds the window's [`MotionBasis`] and the model's constants as the library
//! packs them ([`MotionBasis::packed`]), then the values of this window: whether the model is on,
//! the step constants ([`StepConstants`]: they need the window's noise, measured on the device by
//! `noise_grid` and finished here by the library's median, so a motion window is two
//! submissions), whether the previous window of the stream was the one just before, and the
//! evidence sums' decay and warm-up.
//!
//! **The stream lives on the device.** The patch velocities of the previous window (its
//! acceleration) and each pixel's temporal reference are planes of the shader's `state` buffer,
//! kept between windows; [`StreamClock`] keeps their time stamps, as the CPU keeps them in the
//! `DecodeOutput`. A new decoder starts afresh, and the output is told to forget its own (the CPU
//! taking over after a failure must not trust planes the GPU never wrote).

use tremorscan::decode::motion::{consecutive_since, StepConstants};
use tremorscan::decode::motion_noise::{noise_from_scaled_residuals, significance_noise_gray};
use tremorscan::decode::smooth::recursion_halo;
use tremorscan::decode::{motion_noise, DecodeParams, MotionBasis};

/// Words of the shader's model buffer (`M` there).
pub(super) const MODEL_WORDS: usize = MotionBasis::PACKED_WORDS + 16;
/// Where the window's values start (`M_ON` in the shader).
pub const MODEL_WINDOW_OFFSET: usize = MotionBasis::PACKED_WORDS;
/// Planes of `work` with the model (the evidence and its scratch added) and of `state`.
pub(super) const WORK_PLANES_WITH_MOTION: usize = 13;
pub(super) const STATE_PLANES: usize = 9;

/// Entry points of the model, beyond the still decode's.
pub const MOTION_STAGES: [&str; 14] = [
    "noise_grid",
    "step_predicted",
    "step_horizontal",
    "step_vertical",
    "step_rest",
    "step_rest_last",
    "step_refine",
    "step_refine_last",
    "settle",
    "temporal",
    "wide_copy",
    "wide_horizontal",
    "wide_vertical",
    "wide_select",
];

/// The entry points of a motion window after the noise is known: when `predicted`, a first
/// step from the previous window's patch velocities (its sums written, not summed, over the
/// pixels that have one: the CPU's `motion_predict`); `iterations` steps (the evidence's sums,
/// then the step); the still decode's stages on the corrected phasors (with the moving pixels'
/// wider average of the unit phasor around the plain one when `wide`), with the settling
/// before the spatial jumps and the temporal check after them.
pub(super) fn steps_then_unwrap(iterations: u32, wide: bool, predicted: bool) -> Vec<&'static str> {
    let mut stages = Vec::new();
    if predicted {
        stages.push("step_predicted");
    }
    for i in 0..iterations {
        let last = i + 1 == iterations;
        stages.extend(["step_horizontal", "step_vertical"]);
        stages.push(match (i == 0 && !predicted, last) {
            (true, false) => "step_rest",
            (true, true) => "step_rest_last",
            (false, false) => "step_refine",
            (false, true) => "step_refine_last",
        });
    }
    stages.push("connect");
    if wide {
        stages.push("wide_copy");
    }
    stages.extend(["horizontal", "vertical"]);
    if wide {
        stages.extend(["wide_horizontal", "wide_vertical", "wide_select"]);
    }
    stages.extend(["unwrap", "settle", "jumps", "temporal", "noise_grid_final"]);
    stages
}

/// Pixels the noise grid samples in a `width`×`height` window (the CPU's grid).
pub(super) fn grid_len(width: usize, height: usize) -> usize {
    let step = motion_noise::GRID_STEP_PX;
    let half = step / 2;
    let count = |len: usize| len.saturating_sub(half).div_ceil(step);
    count(width) * count(height)
}

/// The noise level the device's grid values show (negative: not sampled), or `None`.
pub(super) fn noise_from_grid(values: &[f32], scratch: &mut Vec<f32>) -> Option<f32> {
    scratch.clear();
    scratch.extend(
        values
            .iter()
            .copied()
            .filter(|v| *v >= 0.0 && v.is_finite()),
    );
    noise_from_scaled_residuals(scratch)
}

/// When the stream's state on the device was last written.
#[derive(Debug, Clone, Copy)]
pub(super) struct StreamClock {
    /// The window whose patch velocities the `state` planes hold.
    patch_velocity_time_s: f64,
    /// The window the temporal references were last updated by.
    recent_time_s: f64,
}

impl Default for StreamClock {
    fn default() -> Self {
        Self {
            patch_velocity_time_s: f64::NAN,
            recent_time_s: f64::NAN,
        }
    }
}

/// The links of one window to the stream's previous ones.
#[derive(Debug, Clone, Copy)]
pub(super) struct WindowLinks {
    /// Seconds since the previous window's patch velocities, when it was the one just before.
    pub previous_s: Option<f32>,
    /// Whether the temporal references are those of the window just before.
    pub consecutive: bool,
}

impl StreamClock {
    /// The links of the window at `time_s`, and the clock moved on to it (the references only
    /// where the temporal check runs).
    pub(super) fn advance(
        &mut self,
        time_s: f64,
        basis: &MotionBasis,
        check_time: bool,
    ) -> WindowLinks {
        let interval_s = basis.frame_interval_s();
        let links = WindowLinks {
            previous_s: consecutive_since(time_s, self.patch_velocity_time_s, interval_s),
            consecutive: consecutive_since(time_s, self.recent_time_s, interval_s).is_some(),
        };
        self.patch_velocity_time_s = time_s;
        if check_time {
            self.recent_time_s = time_s;
        }
        links
    }

    /// A window without the model: the next one takes no acceleration.
    pub(super) fn still_window(&mut self) {
        self.patch_velocity_time_s = f64::NAN;
    }
}

/// The model buffer of a still window: the model off.
pub(super) fn model_off() -> [f32; MODEL_WORDS] {
    [0.0; MODEL_WORDS]
}

/// The model buffer of a motion window of `basis` with `params` in an image `width_px` wide
/// (a Chebyshev sequence of order `chebyshev_n`), before its noise is known (the step
/// constants at the configured noise; [`window_words`] replaces them).
pub(super) fn model_words(
    basis: &MotionBasis,
    params: &DecodeParams,
    (width_px, chebyshev_n): (usize, u32),
    links: WindowLinks,
) -> [f32; MODEL_WORDS] {
    let mut words = [0.0; MODEL_WORDS];
    words[..MotionBasis::PACKED_WORDS].copy_from_slice(&basis.packed());
    words[MODEL_WINDOW_OFFSET..].copy_from_slice(&window_words(
        basis,
        params,
        (width_px, chebyshev_n),
        links,
        None,
    ));
    words
}

/// The window's values (from `M_ON` on), with the noise the window's grid showed (`measured`),
/// in an image `width_px` wide of a Chebyshev sequence of order `chebyshev_n`.
pub(super) fn window_words(
    basis: &MotionBasis,
    params: &DecodeParams,
    (width_px, chebyshev_n): (usize, u32),
    links: WindowLinks,
    measured: Option<f32>,
) -> [f32; MODEL_WORDS - MODEL_WINDOW_OFFSET] {
    let noise_gray = significance_noise_gray(measured, params.camera_noise_gray);
    let step = StepConstants::new(basis, noise_gray, links.previous_s);
    let flag = |b: bool| if b { 1.0 } else { 0.0 };
    let wide = params.moving_unit_decay_at(width_px);
    [
        1.0,
        step.prior_u,
        step.prior_k,
        step.inv_noise2,
        step.inv_since,
        step.max_velocity_change,
        step.shift_per_velocity_change,
        flag(links.consecutive),
        basis.max_velocity_px_per_s() * basis.frame_interval_s(),
        params.motion_decay_at(width_px),
        recursion_halo(params.motion_decay_at(width_px)) as f32,
        flag(params.check_order_jumps),
        wide.unwrap_or(0.0),
        wide.map_or(0.0, |d| recursion_halo(d) as f32),
        wide.map_or(0.0, |_| 1.0 / chebyshev_n.max(1) as f32),
        // The pixels' own brightness change only after the window just before (as the CPU's
        // last step).
        links
            .previous_s
            .map_or(0.0, |_| params.motion.offset_brightness_weight),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_counts_what_the_cpu_samples() {
        // The CPU's loops: from 3 in steps of 7.
        let count = |len: usize| (3..len).step_by(7).count();
        for (w, h) in [(640, 400), (333, 207), (3, 3), (4, 10), (1920, 1200)] {
            assert_eq!(grid_len(w, h), count(w) * count(h), "{w}×{h}");
        }
    }

    #[test]
    fn steps_end_with_the_last_step_and_the_time_checks() {
        let stages = steps_then_unwrap(2, false, false);
        assert_eq!(stages[2], "step_rest");
        assert_eq!(stages[5], "step_refine_last");
        // Started from the previous window: the predicted step, then every configured step
        // refining.
        let predicted = steps_then_unwrap(2, false, true);
        assert_eq!(predicted[0], "step_predicted");
        assert_eq!(predicted[3], "step_refine");
        assert_eq!(predicted[6], "step_refine_last");
        let temporal = stages.iter().position(|s| *s == "temporal");
        let jumps = stages.iter().position(|s| *s == "jumps");
        assert!(
            jumps.is_some() && temporal == jumps.map(|j| j + 1),
            "{stages:?}"
        );
        assert_eq!(stages.last(), Some(&"noise_grid_final"));
        assert_eq!(steps_then_unwrap(1, false, false)[2], "step_rest_last");
        let wide = steps_then_unwrap(2, true, false);
        let at = |name: &str| wide.iter().position(|s| *s == name);
        let (copy, plain, sum, select, unwrap) = (
            at("wide_copy"),
            at("horizontal"),
            at("wide_horizontal"),
            at("wide_select"),
            at("unwrap"),
        );
        assert!(
            copy < plain && plain < sum && sum < select && select < unwrap && copy.is_some(),
            "{wide:?}"
        );
    }
}
