//! The window's motion model: how the still three-step solve responds to a phasor that turns
//! (the surface moves along the projector's coordinate) and brightens (its shading changes)
//! within the window, and the model's derivatives, for the correction of [`super::motion`].
//!
//! For a window whose frames were taken at `τ_k` from its centre, with frame shifts `d_k` and
//! the closed form's rows `L_k`, the still solve returns `(M(g) + κ·N(g))·z + κ·ō·v` for a
//! phasor `z` turning at `g` rad/s and brightening at `κ` per second: `M(g) = Σ_k L_k·d_kᵀ·
//! R(gτ_k)`, `N(g) = Σ_k τ_k·L_k·d_kᵀ·R(gτ_k)`, `v = Σ_k τ_k·L_k` (derivation in
//! [`super::motion`]). [`MotionBasis`] holds the per-window constants, built once per window
//! from its frame times; its methods evaluate the model and its slopes per pixel.
//!
//! [`motion_basis`] builds it for a window when the settings ask for the model, with the noise
//! the window's frames show (measured on a sparse grid before stage 1), for which
//! [`MotionBasis::noise_bias`] takes out of a still pixel's evidence the part its own noise
//! puts there.

use super::fastmath::sin_cos_small;
use super::{noise, DecodeParams, MotionModel, UnwrapMethod, WindowSolver};
use crate::frame::Frame;
use std::borrow::Borrow;

/// Largest phase turn of one frame against the window's centre that the model corrects, rad.
/// At 2π/3 the three-step window cannot see the fringe at all (`M` is singular); a turn of 1
/// rad keeps `det M ≥ 0.4`.
pub const MAX_TURN_RAD: f32 = 1.0;
/// Largest brightness change the model accepts, per frame interval of the window. The swaying
/// rig's finger sides change by up to about a third; data that no motion made can also look
/// like a large brightness change (a frame with one channel a quarter period off fits κ of
/// 40–50/s, about 0.4 per frame). At 0.5 that frame left 3,638 wrong fringe orders in a 640×400
/// window, at 0.3 712 (the still window: about 360); the moving skin of the sweep lost 0.2
/// points of coverage with sway and none without.
const MAX_BRIGHTNESS_STEP: f32 = 0.3;
/// A 2×2 matrix, row-major.
pub(super) type M2 = [f32; 4];

#[inline(always)]
pub(super) fn apply(m: &M2, (x, y): (f32, f32)) -> (f32, f32) {
    (m[0] * x + m[1] * y, m[2] * x + m[3] * y)
}

#[inline(always)]
pub(super) fn cross((ax, ay): (f32, f32), (bx, by): (f32, f32)) -> f32 {
    ax * by - ay * bx
}

/// The window's motion model: the still solve's response to a turning, brightening phasor.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionBasis {
    /// `P_k = L_k·d_kᵀ` per frame.
    pub(super) p: [M2; 3],
    /// `Q_k = P_k·J` per frame.
    pub(super) q: [M2; 3],
    /// Frame time minus the window's centre time, s.
    pub(super) tau_s: [f32; 3],
    /// `M'(0) = Σ_k τ_k·Q_k`.
    pub(super) dm: M2,
    /// `N(0) = Σ_k τ_k·P_k`.
    pub(super) n0: M2,
    /// `v = Σ_k τ_k·L_k`.
    pub(super) v: (f32, f32),
    /// The offset row of the closed form, `O_k`, and each frame's `d_k`.
    pub(super) offset_row: [f32; 3],
    pub(super) d: [(f32, f32); 3],
    /// Frequency of each slot, rad per projector px.
    pub(super) f_rad_per_px: [f32; 3],
    /// Row of `A⁻¹` giving each slot's projector channel, column of `A` it mixes in with.
    pub(super) unmix_of_slot: [[f32; 3]; 3],
    pub(super) mix_of_slot: [[f32; 3]; 3],
    pub(super) bias_gray: [f32; 3],
    /// The largest |κ| accepted, per second.
    pub(super) max_brightness_rate: f32,
    /// The largest |u| whose turns stay within [`MAX_TURN_RAD`] at every frequency, px/s.
    pub(super) max_velocity: f32,
    /// The frame interval: half the window's span, s.
    pub(super) frame_interval_s: f32,
    /// `mean(τ_k²)`, s².
    pub(super) mean_tau2_s2: f32,
    /// The camera noise variance, gray levels², that the evidence at rest is corrected for
    /// ([`Self::noise_bias`]); 0 until [`Self::with_noise_gray`] sets it.
    pub(super) bias_noise2: f32,
}

impl MotionBasis {
    /// The basis of a CPS-RGB window (`None` for other windows) whose frames were taken at
    /// `frame_times_s`, oldest first.
    pub fn new(solver: &WindowSolver, frame_times_s: [f64; 3]) -> Option<Self> {
        let factored = solver.factored.as_ref()?;
        if solver.frequency_rad_per_px.len() != 3 {
            return None;
        }
        let centre_s = frame_times_s.iter().sum::<f64>() / 3.0;
        let [offset_row, cos_row, sin_row] = factored.closed_form;
        let d: [(f32, f32); 3] = factored.shift_rad.map(|s| (s.cos(), -s.sin()));
        let p: [M2; 3] = std::array::from_fn(|k| {
            let (l0, l1) = (cos_row[k], sin_row[k]);
            let (d0, d1) = d[k];
            [l0 * d0, l0 * d1, l1 * d0, l1 * d1]
        });
        let q: [M2; 3] = p.map(|m| [m[1], -m[0], m[3], -m[2]]);
        let tau_s: [f32; 3] = std::array::from_fn(|k| (frame_times_s[k] - centre_s) as f32);
        let (mut dm, mut n0, mut v) = ([0.0; 4], [0.0; 4], (0.0, 0.0));
        for k in 0..3 {
            for i in 0..4 {
                dm[i] += tau_s[k] * q[k][i];
                n0[i] += tau_s[k] * p[k][i];
            }
            v.0 += tau_s[k] * cos_row[k];
            v.1 += tau_s[k] * sin_row[k];
        }
        let span_s = tau_s.iter().fold(0f32, |m, t| m.max(t.abs()));
        if !(span_s.is_finite() && span_s > 0.0) {
            return None;
        }
        let f = &solver.frequency_rad_per_px;
        let ch = factored.channel_of_slot;
        Some(Self {
            p,
            q,
            tau_s,
            dm,
            n0,
            v,
            offset_row,
            d,
            f_rad_per_px: [f[0], f[1], f[2]],
            unmix_of_slot: ch.map(|c| factored.unmix[c]),
            mix_of_slot: ch.map(|c| [0, 1, 2].map(|j| factored.mix[j][c])),
            bias_gray: factored.bias_gray,
            max_brightness_rate: MAX_BRIGHTNESS_STEP / span_s,
            max_velocity: MAX_TURN_RAD / (f[0].max(f[1]).max(f[2]) * span_s),
            frame_interval_s: (tau_s[2] - tau_s[0]) / 2.0,
            mean_tau2_s2: tau_s.iter().map(|t| t * t).sum::<f32>() / 3.0,
            bias_noise2: 0.0,
        })
    }

    /// The basis with its evidence at rest corrected for a camera noise of `noise_gray`
    /// (`noise_bias`). The decoders give it the noise the window's own frames show
    /// ([`super::noise::window_noise_samples`] on its sparse grid), at most the configured level:
    /// the correction grows with the noise variance, and the configured level, set high to keep
    /// the tests conservative, over-corrects (the rig's default camera shows 1.3 gray levels
    /// against the default setting of 2; corrected for 2, the still hand behind a soft lens got
    /// a point more than 2 mm off inside its outline, where none was before).
    pub fn with_noise_gray(mut self, noise_gray: f32) -> Self {
        let noise2 = noise_gray * noise_gray;
        self.bias_noise2 = if noise2.is_finite() { noise2 } else { 0.0 };
        self
    }

    /// `M(g) + κ·N(g)` and whether every frame's turn `g·τ_k` is within [`MAX_TURN_RAD`].
    #[inline(always)]
    pub(super) fn response(&self, g: f32, kappa: f32) -> (M2, bool) {
        let mut m = [0.0; 4];
        let mut within = true;
        for k in 0..3 {
            let turn = g * self.tau_s[k];
            within &= turn.abs() <= MAX_TURN_RAD;
            let (s, c) = sin_cos_small(turn.clamp(-MAX_TURN_RAD, MAX_TURN_RAD));
            let scale = 1.0 + kappa * self.tau_s[k];
            let (cs, ss) = (c * scale, s * scale);
            for i in 0..4 {
                m[i] += cs * self.p[k][i] + ss * self.q[k][i];
            }
        }
        (m, within)
    }

    /// `B = M(g) + κ·N(g)`, `∂B/∂g` and `N(g)`, and whether every turn is within
    /// [`MAX_TURN_RAD`]: the model and its derivatives at `(g, κ)`.
    #[inline(always)]
    pub(super) fn linearised(&self, g: f32, kappa: f32) -> Linearised {
        let (mut b, mut db, mut n) = ([0.0; 4], [0.0; 4], [0.0; 4]);
        let mut within = true;
        for k in 0..3 {
            let tau = self.tau_s[k];
            let turn = g * tau;
            within &= turn.abs() <= MAX_TURN_RAD;
            let (s, c) = sin_cos_small(turn.clamp(-MAX_TURN_RAD, MAX_TURN_RAD));
            let scale = 1.0 + kappa * tau;
            for i in 0..4 {
                let rotated = c * self.p[k][i] + s * self.q[k][i];
                b[i] += scale * rotated;
                n[i] += tau * rotated;
                db[i] += scale * tau * (c * self.q[k][i] - s * self.p[k][i]);
            }
        }
        let det = b[0] * b[3] - b[1] * b[2];
        let inverse = [b[3] / det, -b[1] / det, -b[2] / det, b[0] / det];
        Linearised {
            inverse,
            db,
            n,
            det,
            within,
        }
    }

    /// The projector-lit offset of each slot: the camera offsets less the bias, unmixed.
    #[inline(always)]
    pub(super) fn lit_offsets(&self, offsets: [f32; 3]) -> [f32; 3] {
        let lit = [0, 1, 2].map(|j| offsets[j] - self.bias_gray[j]);
        self.unmix_of_slot
            .map(|r| r[0] * lit[0] + r[1] * lit[1] + r[2] * lit[2])
    }

    /// The slopes `(D_u, D_κ)` of the Chebyshev residual at phasors `z` whose derivatives
    /// with respect to `u` and `κ` are `dz`.
    #[inline(always)]
    pub(super) fn residual_slopes(z: [(f32, f32); 3], dz: [[(f32, f32); 2]; 3]) -> (f32, f32) {
        let (mut du, mut dk) = (0.0, 0.0);
        for (slot, weight) in [(0, 1.0), (1, -2.0), (2, 1.0)] {
            let zs = z[slot];
            let inv = 1.0 / (zs.0 * zs.0 + zs.1 * zs.1);
            du += weight * cross(zs, dz[slot][0]) * inv;
            dk += weight * cross(zs, dz[slot][1]) * inv;
        }
        (du, dk)
    }

    /// The expected `(D_u·e, D_κ·e)` of a still pixel with phasors `z` and lit offsets `lit`
    /// that its own noise alone produces, over the camera noise variance: the slopes are
    /// computed from the same noisy phasors as the residual, so where a slot's phase noise
    /// `δ_s` moves its slope term `D_s(φ_s)` it also moves `e`, and
    /// `E[D·e] = Σ_s ∂D_s/∂φ_s·Cov(δ_s, e) = σ²·Σ_s ∂D_s/∂φ_s·gain2_s/(w_s·a_s²)`, with
    /// `Cov(δ_s, e) = w_s·var(δ_s)` and the weights `w = (1, −2, 1)` cancelling against the
    /// `w_s` inside `D_s`. The terms turn twice (`D_u`) and once (`D_κ`) per fringe, so they
    /// cancel over a patch that spans several fringes but not over one that spans part of
    /// one: at 1920×1200 a still hand at σ = 2 gave 0.6 % of its skin a velocity, in sign
    /// locked to the fringe phase, and 0.9 % a wrong fringe order (docs/accuracy.md).
    /// The slots' noise is taken as independent and isotropic, as `var_over_noise` takes it.
    #[inline(always)]
    pub(super) fn noise_bias(
        &self,
        z: [(f32, f32); 3],
        lit: [f32; 3],
        gain2: (f32, f32, f32),
    ) -> (f32, f32) {
        let g = [gain2.0, gain2.1, gain2.2];
        let (mut bu, mut bk) = (0.0, 0.0);
        for slot in 0..3 {
            let zs = z[slot];
            // The quarter turn: how `z` moves as its phase grows.
            let jz = (-zs.1, zs.0);
            let a2 = zs.0 * zs.0 + zs.1 * zs.1;
            let scale = g[slot] / (a2 * a2);
            let turn_g = cross(jz, apply(&self.dm, zs)) + cross(zs, apply(&self.dm, jz));
            let n = apply(&self.n0, zs);
            let lit_v = (lit[slot] * self.v.0, lit[slot] * self.v.1);
            let turn_n = cross(jz, (n.0 + lit_v.0, n.1 + lit_v.1)) + cross(zs, apply(&self.n0, jz));
            bu += self.f_rad_per_px[slot] * turn_g * scale;
            bk += turn_n * scale;
        }
        (bu, bk)
    }

    /// The derivatives of the still solution at rest: `(f·M'(0)·z, N(0)·z + lit·v)`.
    #[inline(always)]
    pub(super) fn slopes_at_rest(&self, z: [(f32, f32); 3], lit: [f32; 3]) -> [[(f32, f32); 2]; 3] {
        let mut out = [[(0.0, 0.0); 2]; 3];
        for slot in 0..3 {
            let zs = z[slot];
            let (gx, gy) = apply(&self.dm, zs);
            let (nx, ny) = apply(&self.n0, zs);
            let f = self.f_rad_per_px[slot];
            out[slot] = [
                (f * gx, f * gy),
                (nx + lit[slot] * self.v.0, ny + lit[slot] * self.v.1),
            ];
        }
        out
    }
}

/// The model at one slot's `(g, κ)`: `B⁻¹`, `∂B/∂g`, `N(g)`, `det B`, and whether the turns
/// are within range.
#[derive(Clone, Copy)]
pub(super) struct Linearised {
    pub(super) inverse: M2,
    pub(super) db: M2,
    pub(super) n: M2,
    pub(super) det: f32,
    pub(super) within: bool,
}

impl Linearised {
    /// How the corrected phasor `z` of a slot with frequency `f` and lit offset `lit` moves as
    /// the true `u` and `κ` depart from the estimate: `(B⁻¹·f·∂B/∂g·z, B⁻¹·(N·z + lit·v))`.
    #[inline(always)]
    pub(super) fn slopes(&self, z: (f32, f32), f: f32, lit: f32, v: (f32, f32)) -> [(f32, f32); 2] {
        let (gx, gy) = apply(&self.db, z);
        let (nx, ny) = apply(&self.n, z);
        [
            apply(&self.inverse, (f * gx, f * gy)),
            apply(&self.inverse, (nx + lit * v.0, ny + lit * v.1)),
        ]
    }
}

impl MotionBasis {
    /// Words of [`Self::packed`].
    pub const PACKED_WORDS: usize = 76;

    /// The basis and the model's constants as one array of `f32`, for the GPU decode
    /// (`shaders/decode_motion.wgsl` names the offsets): `P_k` (3 × 4, row-major), `Q_k`
    /// (3 × 4), `τ_k` (3), `M'(0)` (4), `N(0)` (4), `v` (2), the offset row `O_k` (3), `d_k`
    /// (3 × 2), the unmixing row of each slot (3 × 3), the mixing column of each slot (3 × 3),
    /// the bias (3), the largest `|κ|` and `|u|`, the frame interval, `mean(τ²)`; then
    /// [`MAX_TURN_RAD`], the smallest determinant, the significance χ² and the smallest
    /// acceleration shift of [`super::motion`]; last the noise variance the evidence at rest is
    /// corrected for.
    pub fn packed(&self) -> [f32; Self::PACKED_WORDS] {
        use super::motion::{MIN_ACCELERATION_SHIFT_PX, MIN_DET, MOTION_SIGNIFICANCE};
        let mut words = Vec::with_capacity(Self::PACKED_WORDS);
        words.extend(self.p.iter().flatten());
        words.extend(self.q.iter().flatten());
        words.extend(self.tau_s);
        words.extend(self.dm);
        words.extend(self.n0);
        words.extend([self.v.0, self.v.1]);
        words.extend(self.offset_row);
        words.extend(self.d.iter().flat_map(|&(x, y)| [x, y]));
        words.extend(self.unmix_of_slot.iter().flatten());
        words.extend(self.mix_of_slot.iter().flatten());
        words.extend(self.bias_gray);
        words.extend([
            self.max_brightness_rate,
            self.max_velocity,
            self.frame_interval_s,
            self.mean_tau2_s2,
            MAX_TURN_RAD,
            MIN_DET,
            MOTION_SIGNIFICANCE,
            MIN_ACCELERATION_SHIFT_PX,
            self.bias_noise2,
        ]);
        let mut packed = [0.0; Self::PACKED_WORDS];
        packed.copy_from_slice(&words);
        packed
    }

    /// The frame interval of the window, s: half its span.
    pub fn frame_interval_s(&self) -> f32 {
        self.frame_interval_s
    }

    /// The largest velocity the model corrects, projector px/s.
    pub fn max_velocity_px_per_s(&self) -> f32 {
        self.max_velocity
    }

    /// Row `j` of `A` with its columns in slot order: how each slot's light reaches camera
    /// channel `j`.
    #[inline(always)]
    pub(super) fn mix_of_slot_row(&self, j: usize) -> [f32; 3] {
        [
            self.mix_of_slot[0][j],
            self.mix_of_slot[1][j],
            self.mix_of_slot[2][j],
        ]
    }
}

/// Grid pixels the motion model's noise level is measured on per window (about; the image's
/// lit share of them count): the median of a thousand samples gives the noise to a few per
/// cent, at a fixed cost whatever the image size.
const BIAS_NOISE_SAMPLES: f64 = 1024.0;

/// The window's motion model, when `params` ask for one and the window can take it (a CPS-RGB
/// window unwrapped by the Chebyshev relation), with its evidence at rest corrected for the
/// noise the window's frames show.
pub fn motion_basis<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
) -> Option<MotionBasis> {
    if params.motion.model != MotionModel::Linear
        || params.motion.iterations == 0
        || params.unwrap == UnwrapMethod::Temporal
        || frames.len() != 3
    {
        return None;
    }
    let times = [0, 1, 2].map(|k| frames[k].borrow().time_s);
    let basis = MotionBasis::new(solver, times)?;
    // The evidence at rest is corrected for the noise the window's frames show (on a sparse
    // grid of about BIAS_NOISE_SAMPLES pixels, before stage 1), at most the configured level:
    // the residual also grows with motion and with anything else that breaks the Chebyshev
    // relation (corrected at the level a window with a corrupted frame showed, 0.84 % of the
    // image took a wrong fringe order, `tests/validity.rs`), so it bounds the camera's noise
    // from above.
    let first = frames.first()?.borrow();
    let pixels = (first.width * first.height) as f64;
    // A whole number of at least 7, so the cast is exact.
    let step_px = (pixels / BIAS_NOISE_SAMPLES).sqrt().round().max(7.0) as usize;
    let mut samples = Vec::with_capacity(BIAS_NOISE_SAMPLES as usize * 2);
    let measured = noise::window_noise_samples_every(
        solver,
        frames,
        (params.min_amplitude, params.saturation_level),
        step_px,
        &mut samples,
    )
    .and_then(|_| noise::noise_from_samples(&mut samples));
    let configured = params.camera_noise_gray;
    Some(basis.with_noise_gray(measured.map_or(configured, |m| m.min(configured))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::CrossTalk;
    use crate::decode::motion_evidence::{chebyshev3, gain2};
    use crate::pattern::{cps_rgb, Axis};

    /// A channel's three samples of a phasor turning at `g` rad/s, through the still closed
    /// form: what stage 1 returns.
    fn still_solve(solver: &WindowSolver, z: (f32, f32), g: f32, times: [f64; 3]) -> (f32, f32) {
        still_solve_brightening(solver, z, (g, 0.0), times)
    }

    /// [`still_solve`] of a pixel whose light also scales by `1 + κ·τ` (its offset, 40, and its
    /// fringe alike), at `(g, κ)`.
    fn still_solve_brightening(
        solver: &WindowSolver,
        z: (f32, f32),
        (g, kappa): (f32, f32),
        times: [f64; 3],
    ) -> (f32, f32) {
        let f = solver.factored.as_ref().unwrap();
        let centre = times.iter().sum::<f64>() / 3.0;
        let (mut u, mut v) = (0.0, 0.0);
        for k in 0..3 {
            let tau = (times[k] - centre) as f32;
            let turn = g * tau;
            let (x, y) = (
                z.0 * turn.cos() - z.1 * turn.sin(),
                z.0 * turn.sin() + z.1 * turn.cos(),
            );
            let sample =
                (40.0 + f.shift_rad[k].cos() * x - f.shift_rad[k].sin() * y) * (1.0 + kappa * tau);
            u += f.closed_form[1][k] * sample;
            v += f.closed_form[2][k] * sample;
        }
        (u, v)
    }

    #[test]
    fn the_response_inverts_what_the_still_solve_does_to_a_moving_phasor() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        for order in [[0, 1, 2], [1, 2, 0], [2, 0, 1]] {
            let solver = WindowSolver::new(&seq, &order, &CrossTalk::paper()).unwrap();
            let times = [0.0, 1.0 / 121.0, 2.0 / 121.0];
            let basis = MotionBasis::new(&solver, times).unwrap();
            for g in [0.0f32, 30.0, -60.0, 110.0] {
                for phase in [0.3f32, 1.9, 4.0] {
                    let z = (25.0 * phase.cos(), 25.0 * phase.sin());
                    let seen = still_solve(&solver, z, g, times);
                    let (m, within) = basis.response(g, 0.0);
                    assert!(within);
                    let predicted = apply(&m, z);
                    assert!(
                        (predicted.0 - seen.0).abs() < 1e-3 && (predicted.1 - seen.1).abs() < 1e-3,
                        "{order:?} g {g}: {predicted:?} vs {seen:?}"
                    );
                    if g != 0.0 {
                        // Motion does bend the still solution: the test is not vacuous.
                        let bent = (seen.0 - z.0).hypot(seen.1 - z.1);
                        assert!(bent > 0.05, "{bent}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_residual_slope_predicts_the_chebyshev_residual_of_slow_motion() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver = WindowSolver::new(&seq, &[1, 2, 0], &CrossTalk::paper()).unwrap();
        let times = [0.0, 1.0 / 121.0, 2.0 / 121.0];
        let basis = MotionBasis::new(&solver, times).unwrap();
        let f = basis.f_rad_per_px;
        let x0 = 437.3f32;
        // A slow velocity, so that first order is exact to a few per cent.
        let u = 2.0f32; // px/s
        let z: [(f32, f32); 3] = std::array::from_fn(|s| {
            let phase = f[s] * x0;
            let z = (30.0 * phase.cos(), 30.0 * phase.sin());
            still_solve(&solver, z, f[s] * u, times)
        });
        let c = chebyshev3(z, gain2(&solver));
        let e = c.t.1.atan2(c.t.0);
        let slopes = MotionBasis::residual_slopes(z, basis.slopes_at_rest(z, [60.0; 3]));
        let predicted = slopes.0 * u;
        assert!(
            (e - predicted).abs() < 0.05 * predicted.abs() + 1e-6,
            "{e} vs {predicted}"
        );
        assert!(predicted.abs() > 1e-4, "{predicted}");
    }

    #[test]
    fn the_residual_slope_predicts_the_chebyshev_residual_of_a_slow_brightness_change() {
        // The brightness term's scale (`N(0)·z + ō·v`) against samples that brighten: a
        // mis-scaled term would take a patch's κ too small or too large everywhere.
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver = WindowSolver::new(&seq, &[1, 2, 0], &CrossTalk::paper()).unwrap();
        let times = [0.0, 1.0 / 121.0, 2.0 / 121.0];
        let basis = MotionBasis::new(&solver, times).unwrap();
        let f = basis.f_rad_per_px;
        let kappa = 0.5f32; // 1/s, slow: first order holds
        let mut worst = 0f32;
        let mut largest = 0f32;
        for x0 in [37.1f32, 211.9, 437.3, 688.4] {
            let z0: [(f32, f32); 3] = std::array::from_fn(|s| {
                let phase = f[s] * x0;
                (30.0 * phase.cos(), 30.0 * phase.sin())
            });
            let z: [(f32, f32); 3] = std::array::from_fn(|s| {
                still_solve_brightening(&solver, z0[s], (0.0, kappa), times)
            });
            let c = chebyshev3(z, gain2(&solver));
            let e = c.t.1.atan2(c.t.0);
            let slopes = MotionBasis::residual_slopes(z, basis.slopes_at_rest(z, [40.0; 3]));
            let predicted = slopes.1 * kappa;
            worst = worst.max((e - predicted).abs() / predicted.abs().max(1e-6));
            largest = largest.max(predicted.abs());
        }
        assert!(largest > 1e-4, "{largest}");
        assert!(worst < 0.05, "relative error {worst}");
    }

    #[test]
    fn a_still_pixels_evidence_carries_no_bias_from_its_own_noise() {
        // Still phasors with independent isotropic noise of each slot's gain (the model
        // `var_over_noise` assumes): averaged over many draws the evidence for a velocity
        // must vanish at every fringe phase. Without the correction it does not: the slopes
        // move with the same noise as the residual.
        use crate::decode::motion_evidence::evidence;
        use crate::rig::noise::normal_pair;
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
        let (sigma, amplitude, draws) = (2.0f32, 25.0f32, 200_000u64);
        let raw_basis = MotionBasis::new(&solver, [0.0, 1.0 / 121.0, 2.0 / 121.0]).unwrap();
        let basis = raw_basis.clone().with_noise_gray(sigma);
        let g2 = gain2(&solver);
        let f = basis.f_rad_per_px;
        let mut worst_raw = 0.0f64;
        for (i, x) in [101.0f32, 102.5, 104.0, 105.5, 107.0, 433.3]
            .into_iter()
            .enumerate()
        {
            let clean: [(f32, f32); 3] = std::array::from_fn(|s| {
                (amplitude * (f[s] * x).cos(), amplitude * (f[s] * x).sin())
            });
            let (mut sum, mut sum2) = ([0.0f64; 2], [0.0f64; 2]);
            let mut raw_sum = [0.0f64; 2];
            for d in 0..draws {
                let z: [(f32, f32); 3] = std::array::from_fn(|s| {
                    let (a, b) = normal_pair(7, i as u64, d, s as u64);
                    let sd = sigma * solver.noise_gain[s];
                    (clean[s].0 + sd * a, clean[s].1 + sd * b)
                });
                let c = chebyshev3(z, g2);
                let ev = evidence(&basis, z, &c, [60.0; 3], 1.0, g2);
                let raw = evidence(&raw_basis, z, &c, [60.0; 3], 1.0, g2);
                for (k, v) in [ev.ue, ev.ke].into_iter().enumerate() {
                    sum[k] += f64::from(v);
                    sum2[k] += f64::from(v) * f64::from(v);
                }
                raw_sum[0] += f64::from(raw.ue);
                raw_sum[1] += f64::from(raw.ke);
            }
            let n = draws as f64;
            for k in 0..2 {
                let mean = sum[k] / n;
                let se = ((sum2[k] / n - mean * mean) / n).sqrt();
                let raw_mean = raw_sum[k] / n;
                // The brightness term keeps a remainder of higher order in σ/a (its slope also
                // follows the amplitude): 5 % of the bias at a = 12.5·σ, none at 25·σ.
                let allowed = if k == 0 { 0.0 } else { 0.15 * raw_mean.abs() };
                assert!(
                    mean.abs() < 4.5 * se + allowed,
                    "x {x}, term {k}: mean {mean} ± {se} (raw {raw_mean})"
                );
                worst_raw = worst_raw.max(raw_mean.abs() / se);
            }
        }
        // The uncorrected evidence is biased far beyond its sampling error somewhere.
        assert!(worst_raw > 10.0, "{worst_raw}");
    }
}
