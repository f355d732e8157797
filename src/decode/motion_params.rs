//! The motion model's settings ([`MotionParams`]): whether the window models motion, how the
//! velocity's evidence is summed and stepped, and the model's opt-in parts. The defaults carry
//! the measurements that chose them; `decode/motion.rs` says how the model works.

/// How motion of the surface inside the window is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionModel {
    /// The paper's window: the scene is still for its duration.
    Off,
    /// The coordinate moves linearly in time within the window, one velocity per pixel shared by
    /// the frequencies ([`super::motion`]). CPS-RGB windows only; other sequences decode as still.
    Linear,
}

/// The motion model and how its velocity is estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionParams {
    pub model: MotionModel,
    /// Decay of the edge-aware sums of the velocity evidence (as [`super::SmoothingParams::decay`]):
    /// smaller follows a velocity that changes across the surface more closely, with more noise.
    pub decay: f32,
    /// Gauss–Newton steps of the velocity (each one edge-aware sum and one correction).
    pub iterations: u32,
    /// The side of the blocks the evidence is summed over, camera px: 1 sums per pixel (the
    /// default); 2, 3 or 4 sums blocks of that many pixels square with the same reach, and
    /// larger values sum blocks of 4 (`motion_blocks`; CPU only, the GPU decoder refuses any
    /// value above 1; measured against the default in docs/accuracy.md).
    pub block_px: u32,
    /// The decay (at the reference width, as [`super::SmoothingParams::decay`]) of a second, wider
    /// average of the unit phasor, carried along the fine phase, which gives the coarse
    /// coordinate of every pixel the model found moving ([`super::smooth_moving`]); `None`: every
    /// pixel takes the one average of [`super::SmoothingParams`].
    pub moving_unit_decay: Option<f32>,
    /// The weight, beside its patch's, of each moving pixel's own brightness change, measured
    /// from its projector-lit offsets in the previous window and this one, on the last
    /// Gauss–Newton step (0: the patch's alone; `motion_moving`).
    pub offset_brightness_weight: f32,
    /// On the last Gauss–Newton step, each patch also solves for the image velocity of its
    /// light, and each moving pixel takes the brightness change it makes from the gradient of
    /// its own lit image (`motion_advect`; opt-in: CPU only, the GPU decoder refuses it, and it
    /// holds eleven more planes; measured in docs/accuracy.md, Motion, stop 53). Per-pixel sums
    /// only: with [`Self::block_px`] above 1 it is not taken.
    pub advected_brightness: bool,
    /// Start each window's Gauss–Newton steps from the motion of the stream's window just
    /// before (each pixel's patch velocity there, where that patch moved) rather than from
    /// rest: one more correction of those pixels, without sums (`motion_predict`; measured in
    /// docs/accuracy.md, Motion, stop 54). Per-pixel sums only: with [`Self::block_px`] above
    /// 1 it is not taken.
    pub predicted_start: bool,
}

impl MotionParams {
    /// The paper's still window.
    pub fn off() -> Self {
        Self {
            model: MotionModel::Off,
            ..Self::default()
        }
    }

    /// The side of the blocks the evidence is summed over: 1 (per pixel) for 0 or 1, else
    /// [`Self::block_px`] up to 4.
    pub fn block_size(&self) -> usize {
        self.block_px.clamp(1, 4) as usize
    }

    /// Whether a window that follows the stream's previous one starts from its motion
    /// ([`Self::predicted_start`], per-pixel sums only).
    pub fn predicts_start(&self) -> bool {
        self.predicted_start && self.block_size() == 1 && self.iterations > 0
    }
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            model: MotionModel::Linear,
            // A wider patch than the unit phasor's (0.7). Wider patches pool more evidence
            // where the velocity is uniform (fingers flexing: at a 10 mm tremor 94.4 % of the
            // moving skin kept at 0.7, 96.4 % at 0.8, 97.1 % at 0.9) but blur the velocity's
            // gradient where the hand rolls (5 mm with sway: 89.8 %, 90.5 % and 86.2 %); 0.8
            // serves both. Measured on the rig over 13 windows (docs/accuracy.md).
            decay: 0.8,
            iterations: 2,
            block_px: 1,
            // 10 mm tremor with 4 mm of sway: 90.4 % of the moving skin kept, 0.75 % gross
            // without it, 94.9 % and 0.21 % at 0.95; wider keeps more but takes the 10 mm RMS
            // past 0.17 mm (0.99: 0.173). The decay study: docs/accuracy.md, Motion, stop 48.
            moving_unit_decay: Some(0.95),
            // The two estimates' errors, measured on the rig's moving skin against its
            // brightness change rendered under flat light: the patch's 2.8/s at a 10 mm tremor
            // and 3.6–3.9/s with sway, the offsets' 2.5/s and 4.6–5.0/s. Their weights by
            // inverse variance are 0.55 and 0.35–0.41; 0.4 serves both (docs/accuracy.md,
            // Motion, stop 52: 0.3–0.7 measured).
            offset_brightness_weight: 0.4,
            advected_brightness: false,
            predicted_start: true,
        }
    }
}
