//! Stage 1: per-pixel solve of the window system, wrapped phases, amplitudes, colour and the
//! Chebyshev unit phasor.
//!
//! Each band of rows is processed in column chunks of [`CHUNK_PX`] pixels, so that the kernel's
//! scratch planes stay in the L1 cache: a chunk unpacks its observations into planar `f32`
//! rows, multiplies them by `M⁺` plane by plane, or for CPS-RGB windows applies its two factors
//! ([`super::solver::FactoredSolve`]: closed form per camera channel, then unmixing), in
//! contiguous loops that vectorise (the flags too are computed in `f32` lanes), then derives per
//! pixel:
//!
//! * `phase_f = atan2(V_f, U_f)` in `[0, 2π)` and `amplitude_f = |U_f + iV_f|`;
//! * for CPS, with `z_f = U_f + iV_f` (slots 0, 1, 2 = frequencies n, n−1, n−2), the unit phasor
//!   `w = z_0·z̄_1 + z_1·z̄_2`. Both terms equal `a·a'·e^{i f_1 x}` (f_1 = π/x_max), and
//!   `Re w`, `Im w` are exactly the least-squares combinations of the paper's cosine and sine
//!   Chebyshev equations (eq. 13 and its sine counterpart): the branch-free estimate of method (b).
//!   Its angle lies in `[0, π)` because `x ∈ [0, x_max)`.
//! * the agreement of the two terms (`φ0 − 2φ1 + φ2 ≈ 0`) against the noise predicted from the
//!   amplitudes: pixels where the Chebyshev relation fails (motion inside the window, mixed
//!   pixels at edges) are marked [`invalid::DISAGREEMENT`] here, before they can pollute the
//!   averaged unit phasor of their neighbours.

use super::fastmath::{phase_0_tau, whole_to_flags};
use super::motion::{self, MotionBasis};
use super::solver::FactoredSolve;
use super::{invalid, DecodeOutput, DecodeParams, WindowSolver, BAND_ROWS};
use crate::frame::Frame;
use rayon::prelude::*;
use std::borrow::Borrow;

/// Runs stage 1 over the whole image.
pub(crate) fn solve_phasors<F: Borrow<Frame> + Sync>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    chebyshev: bool,
    motion_basis: Option<&MotionBasis>,
    out: &mut DecodeOutput,
) {
    if let Some(basis) = motion_basis {
        let block = params.motion.block_size();
        if block > 1 {
            super::phasor_blocks::solve_phasors_in_blocks(
                solver, frames, params, basis, block, out,
            );
            return;
        }
    }
    let w = out.width;
    let nf = out.frequencies;
    let nc = out.channels;
    let scratch_len = out.band_scratch_len;
    let band_px = BAND_ROWS * w;
    let n = w * out.height;
    let (ev0, rest) = out.motion_evidence.split_at_mut(n);
    let (ev1, ev2) = rest.split_at_mut(n);
    out.phase_rad
        .par_chunks_mut(band_px * nf)
        .zip(out.amplitude.par_chunks_mut(band_px * nf))
        .zip(out.colour.par_chunks_mut(band_px * nc))
        .zip(out.unit_re.par_chunks_mut(band_px))
        .zip(out.unit_im.par_chunks_mut(band_px))
        .zip(out.support.par_chunks_mut(band_px))
        .zip(out.invalid.par_chunks_mut(band_px))
        .zip(out.band_scratch.par_chunks_mut(scratch_len))
        .zip(ev0.par_chunks_mut(band_px))
        .zip(ev1.par_chunks_mut(band_px))
        .zip(ev2[..n].par_chunks_mut(band_px))
        .enumerate()
        .for_each(
            |(
                band,
                (
                    (((((((((phase, amp), colour), re), im), support), flags), scratch), ev0), ev1),
                    ev2,
                ),
            )| {
                let rows = flags.len() / w;
                for r in 0..rows {
                    let y = band * BAND_ROWS + r;
                    // Column chunks of `CHUNK_PX`: the kernel's scratch planes stay in the L1
                    // cache. Its outputs are written in place; plane p of a chunk starts p·w
                    // after its first value.
                    for x0 in (0..w).step_by(CHUNK_PX) {
                        let cw = CHUNK_PX.min(w - x0);
                        let px = r * w + x0..r * w + x0 + cw;
                        let view = RowOut {
                            stride: w,
                            phase: &mut phase[r * nf * w + x0..(r + 1) * nf * w],
                            amp: &mut amp[r * nf * w + x0..(r + 1) * nf * w],
                            colour: &mut colour[r * nc * w + x0..(r + 1) * nc * w],
                            re: &mut re[px.clone()],
                            im: &mut im[px.clone()],
                            support: &mut support[px.clone()],
                            motion: [
                                &mut ev0[px.clone()],
                                &mut ev1[px.clone()],
                                &mut ev2[px.clone()],
                            ],
                            flags: &mut flags[px],
                        };
                        let start = y * w + x0;
                        solve_row(
                            solver,
                            frames,
                            params,
                            (chebyshev, motion_basis),
                            start,
                            cw,
                            scratch,
                            view,
                        );
                    }
                }
            },
        );
}

/// Pixels per column chunk of stage 1.
pub(crate) const CHUNK_PX: usize = 256;

/// Scratch floats per band of stage 1: one chunk of observation and unknown planes and a row
/// of saturation flags.
pub(crate) fn scratch_len(solver: &WindowSolver) -> usize {
    CHUNK_PX * (solver.observations + solver.unknowns + 1)
}

pub(super) struct RowOut<'a> {
    /// Distance between the planes of `phase`, `amp` and `colour`.
    pub(super) stride: usize,
    pub(super) phase: &'a mut [f32],
    pub(super) amp: &'a mut [f32],
    pub(super) colour: &'a mut [f32],
    pub(super) re: &'a mut [f32],
    pub(super) im: &'a mut [f32],
    pub(super) support: &'a mut [f32],
    /// The motion model's evidence planes `ue`, `ke` and count (see [`motion::evidence`]).
    pub(super) motion: [&'a mut [f32]; 3],
    pub(super) flags: &'a mut [u16],
}

#[allow(
    clippy::too_many_arguments,
    reason = "a stage kernel over one row's typed buffers"
)]
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub(super) fn solve_row<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    (chebyshev, motion_basis): (bool, Option<&MotionBasis>),
    start: usize,
    w: usize,
    scratch: &mut [f32],
    row: RowOut<'_>,
) {
    let n_obs = solver.observations;
    let n_u = solver.unknowns;
    let (obs, rest) = scratch.split_at_mut(n_obs * w);
    let (u, rest) = rest.split_at_mut(n_u * w);
    let saturated = &mut rest[..w];
    saturated.fill(0.0);
    let sat_level = params.saturation_level;

    // Unpack observations into planes: plane k·channels + j holds frame k, camera channel j.
    // Each loop reads one interleaved row with fixed stride so it vectorises.
    for (k, frame) in frames.iter().map(Borrow::borrow).enumerate() {
        let src_channels = frame.channels;
        let src = &frame.data[start * src_channels..(start + w) * src_channels];
        if src_channels == 1 {
            let plane = &mut obs[k * w..(k + 1) * w];
            for x in 0..w {
                let s = src[x];
                plane[x] = f32::from(s);
                saturated[x] = saturated[x].max(f32::from(u8::from(s >= sat_level)));
            }
        } else if solver.channels == 3 {
            let (p0, rest) = obs[k * 3 * w..(k + 1) * 3 * w].split_at_mut(w);
            let (p1, p2) = rest.split_at_mut(w);
            for (x, px) in src.chunks_exact(3).enumerate() {
                let (r, g, b) = (px[0], px[1], px[2]);
                p0[x] = f32::from(r);
                p1[x] = f32::from(g);
                p2[x] = f32::from(b);
                let hi = r.max(g).max(b);
                saturated[x] = saturated[x].max(f32::from(u8::from(hi >= sat_level)));
            }
        } else {
            // Gray patterns seen by a colour camera: decode the channel mean.
            let plane = &mut obs[k * w..(k + 1) * w];
            for (x, px) in src.chunks_exact(3).enumerate() {
                let (r, g, b) = (px[0], px[1], px[2]);
                plane[x] = (f32::from(r) + f32::from(g) + f32::from(b)) * (1.0 / 3.0);
                let hi = r.max(g).max(b);
                saturated[x] = saturated[x].max(f32::from(u8::from(hi >= sat_level)));
            }
        }
    }

    // u = M⁺ · obs: factored for CPS-RGB windows, else one unknown plane at a time. Common
    // window sizes get an unrolled kernel that reads every observation plane once per pixel and
    // writes each unknown once.
    let nc = solver.channels;
    let stride = row.stride;
    match &solver.factored {
        Some(factored) => {
            // The offsets go straight to the colour output.
            let (c0, rest) = row.colour.split_at_mut(stride);
            let (c1, c2) = rest.split_at_mut(stride);
            solve_factored(factored, w, obs, [c0, c1, c2], u);
        }
        None => {
            for q in 0..n_u {
                let coeffs = &solver.pinv[q * n_obs..(q + 1) * n_obs];
                let uq = &mut u[q * w..(q + 1) * w];
                match n_obs {
                    9 => dot_planes::<9>(coeffs, obs, uq),
                    7 => dot_planes::<7>(coeffs, obs, uq),
                    12 => dot_planes::<12>(coeffs, obs, uq),
                    _ => {
                        uq.fill(0.0);
                        for (o, &coeff) in coeffs.iter().enumerate() {
                            let plane = &obs[o * w..(o + 1) * w];
                            for (acc, &v) in uq.iter_mut().zip(plane) {
                                *acc += coeff * v;
                            }
                        }
                    }
                }
            }
        }
    }

    let nf = solver.frequencies.len();
    if solver.factored.is_none() {
        for c in 0..nc {
            row.colour[c * stride..c * stride + w].copy_from_slice(&u[c * w..(c + 1) * w]);
        }
    }
    if chebyshev && nf == 3 {
        derive_chebyshev3(solver, params, motion_basis, w, u, saturated, row);
        return;
    }
    for f in 0..nf {
        let cu = &u[solver.cos_unknown(f) * w..(solver.cos_unknown(f) + 1) * w];
        let sv = &u[(solver.cos_unknown(f) + 1) * w..(solver.cos_unknown(f) + 2) * w];
        let phase = &mut row.phase[f * stride..f * stride + w];
        let amp = &mut row.amp[f * stride..f * stride + w];
        for x in 0..w {
            phase[x] = phase_0_tau(sv[x], cu[x]);
            amp[x] = (cu[x] * cu[x] + sv[x] * sv[x]).sqrt();
        }
    }
    // No unit phasor and no Chebyshev check for this window.
    row.re[..w].fill(0.0);
    row.im[..w].fill(0.0);
    let min_amplitude = params.min_amplitude;
    // The reasons as f32 sums of distinct powers of two, so this loop stays in f32 lanes and
    // vectorises; narrowed to bytes in the next.
    let reasons = &mut saturated[..w];
    let support = &mut row.support[..w];
    // The smallest amplitude per pixel, into the unknowns' first plane (no longer needed).
    let min_amps = &mut u[..w];
    min_amps.copy_from_slice(&row.amp[..w]);
    for f in 1..nf {
        for (m, &a) in min_amps
            .iter_mut()
            .zip(&row.amp[f * stride..f * stride + w])
        {
            *m = m.min(a);
        }
    }
    for x in 0..w {
        let min_amp = min_amps[x];
        // A NaN amplitude counts as low.
        let low = min_amp.is_nan() | (min_amp < min_amplitude);
        let bit = |set: bool, value: u16| if set { f32::from(value) } else { 0.0 };
        let reason = bit(low, invalid::LOW_AMPLITUDE) + bit(reasons[x] > 0.0, invalid::SATURATED);
        reasons[x] = reason;
        support[x] = if reason == 0.0 { 1.0 } else { 0.0 };
    }
    for (flag, &reason) in row.flags[..w].iter_mut().zip(&*reasons) {
        *flag = whole_to_flags(reason);
    }
}

/// The rest of stage 1 for a CPS window of three frequencies, in one loop over the pixels of
/// a chunk: phases and amplitudes, the Chebyshev unit phasor and its check, the reasons, the
/// support and the flag bytes. `u` holds the solved unknowns; `saturated` is 1 where a frame
/// saturated.
#[inline(always)]
fn derive_chebyshev3(
    solver: &WindowSolver,
    params: &DecodeParams,
    motion_basis: Option<&MotionBasis>,
    w: usize,
    u: &[f32],
    saturated: &[f32],
    row: RowOut<'_>,
) {
    let plane = |q: usize| &u[q * w..(q + 1) * w];
    let (cu0, sv0) = (
        plane(solver.cos_unknown(0)),
        plane(solver.cos_unknown(0) + 1),
    );
    let (cu1, sv1) = (
        plane(solver.cos_unknown(1)),
        plane(solver.cos_unknown(1) + 1),
    );
    let (cu2, sv2) = (
        plane(solver.cos_unknown(2)),
        plane(solver.cos_unknown(2) + 1),
    );
    let stride = row.stride;
    let [ph0, ph1, ph2] = three_planes(row.phase, stride, w);
    let [am0, am1, am2] = three_planes(row.amp, stride, w);
    let (re, im) = (&mut row.re[..w], &mut row.im[..w]);
    let (support, flags) = (&mut row.support[..w], &mut row.flags[..w]);
    // The offsets feed the motion model's brightness term. Only a colour window has the model
    // (a CPS-gray window of three frequencies has one colour plane and none).
    let motion_model = match motion_basis {
        Some(basis) if row.colour.len() >= 2 * stride + w => {
            Some((basis, three_planes(row.colour, stride, w)))
        }
        _ => None,
    };
    let [mue, mke, mcount] = row.motion;
    let (mue, mke, mcount) = (&mut mue[..w], &mut mke[..w], &mut mcount[..w]);
    let saturated = &saturated[..w];
    let noise2 = params.camera_noise_gray * params.camera_noise_gray;
    let gain2 = motion::gain2(solver);
    let limit = params.max_disagreement_chi2 * noise2;
    let min_amplitude = params.min_amplitude;
    let bit = |set: bool, value: u16| if set { f32::from(value) } else { 0.0 };
    // One loop per model, chosen once per chunk. With the choice inside one loop LLVM did not
    // vectorise it across pixels (78 % of stage 1's samples were scalar or 4-wide; profile of
    // 2026-12-05): split, the motion window's stage 1 took 1.4 ms instead of 5.3 at 640×400,
    // with the same values bit for bit. Their shared first lines are written out twice: a
    // closure that wrote them (capturing the output slices) left stage 1 slower than before.
    match motion_model {
        // The still model: the Chebyshev residual φ0 − 2φ1 + φ2 must vanish up to noise
        // (motion inside the window and mixed pixels break it).
        None => {
            for x in 0..w {
                let z = [(cu0[x], sv0[x]), (cu1[x], sv1[x]), (cu2[x], sv2[x])];
                let c = motion::chebyshev3(z, gain2);
                ph0[x] = c.phase[0];
                ph1[x] = c.phase[1];
                ph2[x] = c.phase[2];
                am0[x] = c.amplitude[0];
                am1[x] = c.amplitude[1];
                am2[x] = c.amplitude[2];
                let signal = light_reasons(&c, min_amplitude, saturated[x]);
                let reason = signal + bit(motion::inconsistent(&c, limit), invalid::DISAGREEMENT);
                let keep = if reason == 0.0 { 1.0 } else { 0.0 };
                support[x] = keep;
                re[x] = c.unit.0 * keep;
                im[x] = c.unit.1 * keep;
                flags[x] = whole_to_flags(reason);
            }
        }
        // The motion model: the residual is the velocity's evidence, weighted by its inverse
        // variance, for stage 2 to sum over the patch; it is tested after the correction.
        Some((basis, [co0, co1, co2])) => {
            let (co0, co1, co2) = (&co0[..w], &co1[..w], &co2[..w]);
            for x in 0..w {
                let z = [(cu0[x], sv0[x]), (cu1[x], sv1[x]), (cu2[x], sv2[x])];
                let c = motion::chebyshev3(z, gain2);
                ph0[x] = c.phase[0];
                ph1[x] = c.phase[1];
                ph2[x] = c.phase[2];
                am0[x] = c.amplitude[0];
                am1[x] = c.amplitude[1];
                am2[x] = c.amplitude[2];
                let signal = light_reasons(&c, min_amplitude, saturated[x]);
                let keep = if signal == 0.0 { 1.0 } else { 0.0 };
                let ev = motion::evidence(basis, z, &c, [co0[x], co1[x], co2[x]], keep, gain2);
                re[x] = ev.uu;
                im[x] = ev.uk;
                support[x] = ev.kk;
                mue[x] = ev.ue;
                mke[x] = ev.ke;
                mcount[x] = keep;
                flags[x] = whole_to_flags(signal);
            }
        }
    }
}

/// The reasons of a pixel's light as a sum of flag bits: a fringe too weak (a NaN amplitude
/// counts as low) or a saturated frame (`saturated` > 0).
#[inline(always)]
fn light_reasons(
    c: &super::motion_evidence::Chebyshev3,
    min_amplitude: f32,
    saturated: f32,
) -> f32 {
    let bit = |set: bool, value: u16| if set { f32::from(value) } else { 0.0 };
    let min_amp = c.amplitude[0].min(c.amplitude[1]).min(c.amplitude[2]);
    let low = min_amp.is_nan() | (min_amp < min_amplitude);
    bit(low, invalid::LOW_AMPLITUDE) + bit(saturated > 0.0, invalid::SATURATED)
}

/// The first `w` values of planes 0, 1 and 2 of `planes`, `stride` apart.
#[inline(always)]
fn three_planes(planes: &mut [f32], stride: usize, w: usize) -> [&mut [f32]; 3] {
    let (p0, rest) = planes.split_at_mut(stride);
    let (p1, p2) = rest.split_at_mut(stride);
    [&mut p0[..w], &mut p1[..w], &mut p2[..w]]
}

/// `u = M⁺·obs` through the factors of [`FactoredSolve`], for planes of `w` values: nine
/// observation planes (frame k, camera channel j at plane 3k + j) in; the three offsets (the
/// colour) to `offsets`, the six cosine and sine unknowns to their planes 3–8 of `u` (planes
/// 0–2 are not written). One loop: per pixel the closed form per camera channel, then the
/// unmixing of the cosine and the sine terms, in registers.
#[inline(always)]
fn solve_factored(
    factored: &FactoredSolve,
    w: usize,
    obs: &[f32],
    offsets: [&mut [f32]; 3],
    u: &mut [f32],
) {
    let [offset_row, cos_row, sin_row] = factored.closed_form;
    // Row of `A⁻¹` that gives each slot's U and V.
    let m: [[f32; 3]; 3] = factored.channel_of_slot.map(|i| factored.unmix[i]);
    // Plane 3k + j holds frame k, camera channel j; each sliced to `w` so that the loop has no
    // bounds checks and vectorises.
    let (frame0, rest) = obs.split_at(3 * w);
    let (frame1, rest) = rest.split_at(3 * w);
    let frame2 = &rest[..3 * w];
    let (r0, g0, bl0) = (&frame0[..w], &frame0[w..2 * w], &frame0[2 * w..3 * w]);
    let (r1, g1, bl1) = (&frame1[..w], &frame1[w..2 * w], &frame1[2 * w..3 * w]);
    let (r2, g2, bl2) = (&frame2[..w], &frame2[w..2 * w], &frame2[2 * w..3 * w]);
    let [o0, o1, o2] = offsets;
    let (o0, o1, o2) = (&mut o0[..w], &mut o1[..w], &mut o2[..w]);
    let (_, unknowns) = u.split_at_mut(3 * w);
    let (u0, rest) = unknowns.split_at_mut(w);
    let (v0, rest) = rest.split_at_mut(w);
    let (u1, rest) = rest.split_at_mut(w);
    let (v1, rest) = rest.split_at_mut(w);
    let (u2, v2) = rest.split_at_mut(w);
    let v2 = &mut v2[..w];
    for x in 0..w {
        let dot = |b: [f32; 3], (s0, s1, s2): (f32, f32, f32)| b[0] * s0 + b[1] * s1 + b[2] * s2;
        // Camera channel j's samples in frames 0, 1, 2.
        let (c0, c1, c2) = (
            (r0[x], r1[x], r2[x]),
            (g0[x], g1[x], g2[x]),
            (bl0[x], bl1[x], bl2[x]),
        );
        o0[x] = dot(offset_row, c0);
        o1[x] = dot(offset_row, c1);
        o2[x] = dot(offset_row, c2);
        let cos_terms = (dot(cos_row, c0), dot(cos_row, c1), dot(cos_row, c2));
        let sin_terms = (dot(sin_row, c0), dot(sin_row, c1), dot(sin_row, c2));
        u0[x] = dot(m[0], cos_terms);
        v0[x] = dot(m[0], sin_terms);
        u1[x] = dot(m[1], cos_terms);
        v1[x] = dot(m[1], sin_terms);
        u2[x] = dot(m[2], cos_terms);
        v2[x] = dot(m[2], sin_terms);
    }
}

/// `out[x] = Σ_o coeffs[o] · planes[o][x]` for `N` planes of `out.len()` values.
#[inline(always)]
fn dot_planes<const N: usize>(coeffs: &[f32], planes: &[f32], out: &mut [f32]) {
    let w = out.len();
    let c: [f32; N] = std::array::from_fn(|o| coeffs[o]);
    let p: [&[f32]; N] = std::array::from_fn(|o| &planes[o * w..(o + 1) * w]);
    for x in 0..w {
        let mut acc = 0.0;
        for o in 0..N {
            acc += c[o] * p[o][x];
        }
        out[x] = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::CrossTalk;
    use crate::pattern::{cps_gray, cps_rgb, Axis, CpsGrayVariant};

    #[test]
    fn factored_solve_equals_the_pseudo_inverse() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let w = 24;
        // Observations like a camera's: 0–255 with structure across pixels and planes.
        let obs: Vec<f32> = (0..9 * w)
            .map(|i| ((i * 37 + i / w * 11) % 256) as f32)
            .collect();
        for cross_talk in [CrossTalk::paper(), CrossTalk::identity()] {
            for order in [[0, 1, 2], [1, 2, 0], [2, 0, 1]] {
                let solver = WindowSolver::new(&seq, &order, &cross_talk).unwrap();
                let factored = solver.factored.expect("a CPS-RGB window factors");
                let mut expected = vec![0.0; 9 * w];
                for (q, plane) in expected.chunks_mut(w).enumerate() {
                    dot_planes::<9>(&solver.pinv[q * 9..(q + 1) * 9], &obs, plane);
                }
                let mut got = vec![0.0; 9 * w];
                let mut offsets = vec![0.0; 3 * w];
                let (o0, rest) = offsets.split_at_mut(w);
                let (o1, o2) = rest.split_at_mut(w);
                solve_factored(&factored, w, &obs, [o0, o1, o2], &mut got);
                got[..3 * w].copy_from_slice(&offsets);
                for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
                    // Both are f32 sums of nine products (the factored one in two rounds of
                    // three, through intermediate terms of similar size): each rounds to a few
                    // ε of the sum of the magnitudes of its terms.
                    let (q, x) = (i / w, i % w);
                    let magnitude: f32 = (0..9)
                        .map(|o| (solver.pinv[q * 9 + o] * obs[o * w + x]).abs())
                        .sum();
                    let tolerance = 16.0 * f32::EPSILON * magnitude;
                    assert!((g - e).abs() <= tolerance, "{g} vs {e} (±{tolerance})");
                }
            }
        }
        // Windows without the structure keep the plain product.
        let gray = cps_gray(129, CpsGrayVariant::Minimal7, 1024.0, Axis::Columns, 8).unwrap();
        let order: Vec<usize> = (0..7).collect();
        let solver = WindowSolver::new(&gray, &order, &CrossTalk::identity()).unwrap();
        assert!(solver.factored.is_none());
    }
}
