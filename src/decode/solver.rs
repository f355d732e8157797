//! The per-window linear system of paper eqs. 4 and 22, inverted once per window order.
//!
//! For a window of frames `k` showing known pattern entries, every camera channel `j` observes
//!
//! ```text
//! c_kj = o_j + Σ_i A_ji · (U_{m_ki} · cos θ_ki − V_{m_ki} · sin θ_ki)
//! ```
//!
//! where `i` runs over the projector channels of entry k (one for gray), `m_ki`, `θ_ki` are that
//! channel's frequency index and shift, `o_j` is the per-camera-channel offset (the scene colour
//! under flat half-intensity light, plus `b` and ambient light) and `(U_m, V_m) = a_m·(cos f_m x,
//! sin f_m x)` for every distinct frequency. For gray sequences there is one camera channel and
//! `A = 1`. Stacking all frames gives `c = M·u`; [`WindowSolver`] keeps the pseudo-inverse `M⁺` in
//! f32 so that each pixel costs one small matrix–vector product and no factorisation.
//!
//! CPS-RGB windows have more structure: three frames, every channel of frame `k` shifted by the
//! same `θ_k`, each projector channel carrying one frequency. Then
//! `c_kj = o_j + cos θ_k·(A·U)_j − sin θ_k·(A·V)_j`: the three-step closed form of each camera
//! channel gives `o_j`, `(A·U)_j` and `(A·V)_j`, and unmixing them gives `U` and `V`.
//! [`FactoredSolve`] holds these two small factors of `M⁺`: 27 + 18 multiply-adds per pixel
//! instead of 81. It is only used when its product equals `M⁺` (checked when it is built).

use super::DecodeError;
use crate::color::CrossTalk;
use crate::pattern::{PatternEntry, PatternSequence};
use nalgebra::DMatrix;

/// Largest number of observations (frames × channels) a window may have.
pub const MAX_OBSERVATIONS: usize = 64;

/// The pseudo-inverse of one window order, with the bookkeeping to read its solution.
#[derive(Debug, Clone)]
pub struct WindowSolver {
    /// Pattern indices of the window's frames, oldest first.
    pub order: Vec<usize>,
    /// Camera channels per frame (3 for RGB sequences, 1 for gray).
    pub channels: usize,
    /// Distinct frequency indices, descending: for CPS `[n, n−1, n−2]`.
    pub frequencies: Vec<u32>,
    /// Angular frequency (rad per projector pixel) of each entry of `frequencies`.
    pub frequency_rad_per_px: Vec<f32>,
    /// `M⁺`, row-major: `unknowns × observations`.
    pub pinv: Vec<f32>,
    /// The design matrix `M` itself, row-major `observations × unknowns`, in f64.
    pub design: Vec<f64>,
    pub observations: usize,
    pub unknowns: usize,
    /// Ratio of smallest to largest singular value of `M`.
    pub conditioning: f64,
    /// Per frequency slot: RMS norm of the `U` and `V` rows of `M⁺`, i.e. the standard deviation
    /// of each unknown per gray level of independent camera noise.
    pub noise_gain: Vec<f32>,
    /// `M⁺` as closed form then unmixing, for windows with that structure (CPS-RGB).
    pub factored: Option<FactoredSolve>,
}

/// `M⁺ = unmixing · closed form` for a window of three RGB frames with one shift per frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FactoredSolve {
    /// Per camera channel, `(o_j, (A·U)_j, (A·V)_j) = closed_form · (c_0j, c_1j, c_2j)`.
    pub closed_form: [[f32; 3]; 3],
    /// `A⁻¹`: `U_i = Σ_j unmix[i][j]·(A·U)_j`, the same for `V`.
    pub unmix: [[f32; 3]; 3],
    /// Frequency slot carried by each projector channel.
    pub slot_of_channel: [usize; 3],
    /// The projector channel carrying each frequency slot (the inverse permutation).
    pub channel_of_slot: [usize; 3],
    /// The cross-talk matrix `A` (camera channel × projector channel) and bias `b`, gray levels.
    pub mix: [[f32; 3]; 3],
    pub bias_gray: [f32; 3],
    /// The pattern shift of each frame of the window (the same in every channel), radians:
    /// frame k's sample of a channel is `o + cos θ_k·U − sin θ_k·V`.
    pub shift_rad: [f32; 3],
}

impl FactoredSolve {
    /// The factors for `entries` (the window's frames) when they have the structure, and when
    /// their product equals `pinv` (unknowns × observations, row-major).
    fn find(
        entries: &[&PatternEntry],
        frequencies: &[u32],
        cross_talk: &CrossTalk,
        pinv: &DMatrix<f64>,
    ) -> Option<Self> {
        if entries.len() != 3 || frequencies.len() != 3 {
            return None;
        }
        let mut slot_of_channel = [0; 3];
        let mut shifts = [0.0; 3];
        for (k, entry) in entries.iter().enumerate() {
            let codes = entry.codes();
            if codes.len() != 3 {
                return None;
            }
            shifts[k] = codes[0].shift_rad;
            for (i, code) in codes.iter().enumerate() {
                let slot = frequencies.iter().position(|&m| m == code.m)?;
                // Shifts read from a file may differ in the last bits; the check of the product
                // below decides whether they are close enough.
                if (k > 0 && slot != slot_of_channel[i])
                    || (code.shift_rad - shifts[k]).abs() > 1e-9
                {
                    return None;
                }
                slot_of_channel[i] = slot;
            }
        }
        // Frame k's sample of one channel: o + cos θ_k·X − sin θ_k·Y.
        let basis = nalgebra::Matrix3::from_fn(|k, col| match col {
            0 => 1.0,
            1 => shifts[k].cos(),
            _ => -shifts[k].sin(),
        });
        let closed_form = basis.try_inverse()?;
        let unmix = cross_talk.a.try_inverse()?;
        // The product, unknowns × observations (observation k·3 + j), against M⁺.
        let mut product = DMatrix::<f64>::zeros(9, 9);
        for k in 0..3 {
            for j in 0..3 {
                product[(j, k * 3 + j)] = closed_form[(0, k)];
                for (i, &slot) in slot_of_channel.iter().enumerate() {
                    product[(3 + 2 * slot, k * 3 + j)] = unmix[(i, j)] * closed_form[(1, k)];
                    product[(4 + 2 * slot, k * 3 + j)] = unmix[(i, j)] * closed_form[(2, k)];
                }
            }
        }
        let scale = pinv.amax();
        if (product - pinv).amax() > 1e-9 * scale {
            return None;
        }
        // Three channels carry the three slots, one each (a match of the product implies it).
        let mut channel_of_slot = [usize::MAX; 3];
        for (i, &slot) in slot_of_channel.iter().enumerate() {
            channel_of_slot[slot] = i;
        }
        if channel_of_slot.contains(&usize::MAX) {
            return None;
        }
        let to_f32 = |m: &nalgebra::Matrix3<f64>| {
            std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32))
        };
        Some(Self {
            closed_form: to_f32(&closed_form),
            unmix: to_f32(&unmix),
            slot_of_channel,
            channel_of_slot,
            shift_rad: shifts.map(|s| s as f32),
            mix: to_f32(&cross_talk.a),
            bias_gray: [0, 1, 2].map(|j| cross_talk.b_gray[j] as f32),
        })
    }
}

impl WindowSolver {
    /// Builds the solver for frames showing `order` (indices into `seq.entries`).
    pub fn new(
        seq: &PatternSequence,
        order: &[usize],
        cross_talk: &CrossTalk,
    ) -> Result<Self, DecodeError> {
        seq.validate()?;
        let channels = if seq.is_rgb() { 3 } else { 1 };
        let entries: Vec<&PatternEntry> = order
            .iter()
            .map(|&i| {
                seq.entries.get(i).ok_or(DecodeError::PatternIndex {
                    index: i,
                    len: seq.entries.len(),
                })
            })
            .collect::<Result<_, _>>()?;
        let mut frequencies: Vec<u32> = entries
            .iter()
            .flat_map(|e| e.codes().into_iter().map(|c| c.m))
            .collect();
        frequencies.sort_unstable_by(|a, b| b.cmp(a));
        frequencies.dedup();
        let observations = order.len() * channels;
        let unknowns = channels + 2 * frequencies.len();
        if observations > MAX_OBSERVATIONS {
            return Err(DecodeError::WindowTooLong {
                observations,
                max: MAX_OBSERVATIONS,
            });
        }
        if observations < unknowns {
            return Err(DecodeError::Underdetermined {
                order: order.to_vec(),
                observations,
                unknowns,
            });
        }
        let column_of =
            |m: u32| channels + 2 * frequencies.iter().position(|&f| f == m).unwrap_or_default();
        let mut design = DMatrix::<f64>::zeros(observations, unknowns);
        for (k, entry) in entries.iter().enumerate() {
            let codes = entry.codes();
            for j in 0..channels {
                let row = k * channels + j;
                design[(row, j)] = 1.0;
                for (i, code) in codes.iter().enumerate() {
                    // Gray light passes all projector channels equally: gain 1 for the one channel.
                    let gain = if channels == 3 {
                        cross_talk.a[(j, i)]
                    } else {
                        1.0
                    };
                    let col = column_of(code.m);
                    design[(row, col)] += gain * code.shift_rad.cos();
                    design[(row, col + 1)] -= gain * code.shift_rad.sin();
                }
            }
        }
        let svd = design.clone().svd(true, true);
        let max_sv = svd.singular_values.max();
        let min_sv = svd.singular_values.min();
        let conditioning = if max_sv > 0.0 { min_sv / max_sv } else { 0.0 };
        if conditioning < 1e-6 {
            return Err(DecodeError::Underdetermined {
                order: order.to_vec(),
                observations,
                unknowns,
            });
        }
        let pinv = svd
            .pseudo_inverse(1e-12)
            .map_err(|e| DecodeError::Numerical(e.to_string()))?;
        let mut pinv_f32 = Vec::with_capacity(unknowns * observations);
        for r in 0..unknowns {
            for c in 0..observations {
                pinv_f32.push(pinv[(r, c)] as f32);
            }
        }
        let noise_gain = (0..frequencies.len())
            .map(|f| {
                let row_norm2 =
                    |r: usize| -> f64 { (0..observations).map(|c| pinv[(r, c)].powi(2)).sum() };
                let u = channels + 2 * f;
                ((row_norm2(u) + row_norm2(u + 1)) / 2.0).sqrt() as f32
            })
            .collect();
        let factored = if channels == 3 && observations == unknowns {
            FactoredSolve::find(&entries, &frequencies, cross_talk, &pinv)
        } else {
            None
        };
        let design_rows = (0..observations)
            .flat_map(|r| (0..unknowns).map(move |c| (r, c)))
            .map(|rc| design[rc])
            .collect();
        Ok(Self {
            design: design_rows,
            noise_gain,
            order: order.to_vec(),
            channels,
            frequency_rad_per_px: frequencies
                .iter()
                .map(|&m| seq.frequency(m) as f32)
                .collect(),
            frequencies,
            pinv: pinv_f32,
            observations,
            unknowns,
            conditioning,
            factored,
        })
    }

    /// Index of the unknown `U_m` of frequency slot `f` (its `V_m` follows).
    #[inline]
    pub fn cos_unknown(&self, f: usize) -> usize {
        self.channels + 2 * f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pattern::{cps_gray, cps_rgb, multi_frequency, Axis, CpsGrayVariant};

    #[test]
    fn cps_rgb_window_is_square_and_well_conditioned() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 6).unwrap();
        let s = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
        assert_eq!((s.observations, s.unknowns), (9, 9));
        assert_eq!(s.frequencies, vec![65, 64, 63]);
        assert!(s.conditioning > 0.05, "{}", s.conditioning);
        // Any rotation of the three shifts decodes.
        assert!(WindowSolver::new(&seq, &[2, 0, 1], &CrossTalk::paper()).is_ok());
    }

    #[test]
    fn noise_gain_of_the_three_step_solve() {
        // Without cross-talk, U = (2/3)·Σ c_k cos θ_k: the row norm² is (4/9)·(3/2) = 2/3.
        let seq = cps_rgb(65, 912.0, Axis::Columns, 6).unwrap();
        let s = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::identity()).unwrap();
        for g in &s.noise_gain {
            assert!((g - (2.0f32 / 3.0).sqrt()).abs() < 1e-5, "{g}");
        }
        // Unmixing the paper's cross-talk amplifies the noise, most on the weakest (blue) channel.
        let s = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
        assert!(s.noise_gain.iter().all(|&g| g > 0.9));
        assert!(s.noise_gain[0] > s.noise_gain[1], "{:?}", s.noise_gain);
    }

    #[test]
    fn shifts_that_differ_in_the_last_bits_still_factor() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let mut nudged = seq.clone();
        if let PatternEntry::Rgb { green, .. } = &mut nudged.entries[1] {
            green.shift_rad += 1e-13;
        }
        let s = WindowSolver::new(&nudged, &[0, 1, 2], &CrossTalk::paper()).unwrap();
        assert!(s.factored.is_some());
        // A real difference of shift within a frame breaks the structure: the plain product.
        if let PatternEntry::Rgb { green, .. } = &mut nudged.entries[1] {
            green.shift_rad += 0.1;
        }
        let s = WindowSolver::new(&nudged, &[0, 1, 2], &CrossTalk::paper()).unwrap();
        assert!(s.factored.is_none());
    }

    #[test]
    fn repeated_shift_is_underdetermined() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 6).unwrap();
        let err = WindowSolver::new(&seq, &[0, 2, 0], &CrossTalk::paper()).unwrap_err();
        assert!(matches!(err, DecodeError::Underdetermined { .. }), "{err}");
        let err = WindowSolver::new(&seq, &[0, 1, 7], &CrossTalk::paper()).unwrap_err();
        assert_eq!(err, DecodeError::PatternIndex { index: 7, len: 3 });
    }

    #[test]
    fn gray_and_multi_frequency_windows_solve() {
        let seq = cps_gray(129, CpsGrayVariant::Minimal7, 1024.0, Axis::Columns, 8).unwrap();
        let s = WindowSolver::new(&seq, &[0, 1, 2, 3, 4, 5, 6], &CrossTalk::identity()).unwrap();
        assert_eq!((s.observations, s.unknowns), (7, 7));
        let seq = multi_frequency(&[1, 8, 64], 4, 912.0, Axis::Columns, 8).unwrap();
        let order: Vec<usize> = (0..12).collect();
        let s = WindowSolver::new(&seq, &order, &CrossTalk::identity()).unwrap();
        assert_eq!((s.observations, s.unknowns), (12, 7));
    }

    #[test]
    fn pinv_inverts_the_model() {
        // Synthesise one pixel with the forward model and check the solve recovers it.
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let ct = CrossTalk::paper();
        let s = WindowSolver::new(&seq, &[1, 2, 0], &ct).unwrap();
        let x = 321.7;
        let albedo = [0.8, 0.55, 0.45];
        let mut obs = Vec::new();
        for &k in &s.order {
            let codes = seq.entries[k].codes();
            let p: Vec<f64> = codes
                .iter()
                .zip(albedo)
                .map(|(c, a)| {
                    200.0 * a * (0.5 + 0.5 * (seq.frequency(c.m) * x + c.shift_rad).cos())
                })
                .collect();
            let c = ct.apply(&nalgebra::Vector3::new(p[0], p[1], p[2]));
            obs.extend([c.x, c.y, c.z]);
        }
        let u: Vec<f64> = (0..s.unknowns)
            .map(|r| {
                (0..s.observations)
                    .map(|c| f64::from(s.pinv[r * 9 + c]) * obs[c])
                    .sum()
            })
            .collect();
        // Blue carries m = 65 = slot 0.
        let (cu, sv) = (u[s.cos_unknown(0)], u[s.cos_unknown(0) + 1]);
        let phase = sv.atan2(cu).rem_euclid(std::f64::consts::TAU);
        let truth = (seq.frequency(65) * x).rem_euclid(std::f64::consts::TAU);
        assert!((phase - truth).abs() < 1e-4, "{phase} vs {truth}");
        assert!(((cu * cu + sv * sv).sqrt() - 100.0 * 0.45).abs() < 1e-3);
    }
}
