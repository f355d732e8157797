//! Stage 2: edge-aware averaging of the Chebyshev unit phasor (robust unwrap, method b).
//!
//! Why: the unit phase `f_1·x` carries the coordinate with about n/2 times the noise of a fine
//! phase. At ordinary camera noise its per-pixel error exceeds half a fine period on a large share
//! of dark pixels, so per-pixel unwrapping picks the wrong fringe there. The unit phase changes
//! very slowly across the image (f_1 = π/x_max: a few milliradians per pixel), so averaging the
//! phasor over a neighbourhood removes the noise without bias, as long as the neighbourhood stays
//! on one surface.
//!
//! How: a recursive exponential filter (forward + backward, rows then columns), in the manner of
//! a domain-transform filter. The recursion does not cross pairs of neighbours that
//! [`super::connect`] finds unconnected, so depth edges (where the phase jumps) and
//! object boundaries (where the colour changes) stop the averaging. The filter costs O(1) per
//! pixel whatever its reach. The phasor magnitude (∝ amplitude²) weights bright pixels more.
//! The weight of valid pixels is filtered alongside as `support`.

pub(crate) use super::connect::compute_connectivity;
use super::connect::{DOWN, RIGHT};
use super::smooth_strips::vertical_strips;
use super::smooth_transport::{smooth_transported, Transport};
use super::{DecodeOutput, SmoothingParams, BAND_ROWS};
use rayon::prelude::*;
use std::f32::consts::{PI, TAU};

/// Runs stage 2 in place on `out.unit_re`, `out.unit_im` and `out.support`. With
/// [`SmoothingParams::transport`] and a Chebyshev window (`chebyshev_n`, the finest frequency's
/// index) the recursion is carried along the fine phase ([`super::smooth_transport`]).
pub(crate) fn smooth_unit_phasor(
    out: &mut DecodeOutput,
    params: &SmoothingParams,
    chebyshev_n: Option<u32>,
) {
    compute_connectivity(out, params);
    let Some(n) = chebyshev_n.filter(|&n| n > 0 && params.transport) else {
        smooth_planes(&mut Planes::of_unit_phasor(out), params.decay);
        return;
    };
    let (mut planes, phase_rad) = Planes::of_unit_phasor_with_phases(out);
    let transport = Transport {
        phase_rad,
        unit_per_fine: 1.0 / n as f32,
    };
    smooth_transported(&mut planes, params.decay, transport);
}

/// Three planes to smooth in place, with the scratch and the connectivity the passes use.
pub(crate) struct Planes<'a> {
    pub planes: [&'a mut [f32]; 3],
    pub w: usize,
    pub h: usize,
    pub connect: &'a [u8],
    /// Three planes of scratch: the horizontal pass's output.
    pub tmp: &'a mut [f32],
    pub band_scratch: &'a mut [f32],
    pub band_scratch_len: usize,
    pub vertical_state: &'a mut [f32],
}

impl<'a> Planes<'a> {
    /// The unit phasor and the support, beside the (row-planar) phases, which the transported
    /// recursion reads.
    pub(crate) fn of_unit_phasor_with_phases(out: &'a mut DecodeOutput) -> (Self, &'a [f32]) {
        let planes = Self {
            planes: [&mut out.unit_re, &mut out.unit_im, &mut out.support],
            w: out.width,
            h: out.height,
            connect: &out.connect,
            tmp: &mut out.smooth_tmp,
            band_scratch: &mut out.band_scratch,
            band_scratch_len: out.band_scratch_len,
            vertical_state: &mut out.vertical_state,
        };
        (planes, &out.phase_rad)
    }

    /// The unit phasor and the support.
    pub(crate) fn of_unit_phasor(out: &'a mut DecodeOutput) -> Self {
        Self::of_unit_phasor_with_phases(out).0
    }
}

/// The recursion alone, over the connectivity already computed, with `decay`: the motion
/// model's passes (see [`super::motion`]) sum their evidence in the same way.
pub(crate) fn smooth_planes(planes: &mut Planes<'_>, decay: f32) {
    horizontal_pass(planes, decay);
    vertical_pass(planes, decay);
}

/// Horizontal recursion of one row: `F[x] = v[x] + g[x−1]·F[x−1]`, `B[x] = v[x] + g[x]·B[x+1]`,
/// result `F + B − v` written to `dst`, for the three planes at once. The forward and the
/// backward recursion run in the same loop (from both ends), so six independent chains hide the
/// latency of each step; `B` goes to `scratch` and is added in a last, vectorised pass.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn horizontal_row(
    src: [&[f32]; 3],
    dst: [&mut [f32]; 3],
    link: &[u8],
    decay: f32,
    scratch: &mut [f32],
) {
    let w = link.len();
    let (gain, rest) = scratch.split_at_mut(w);
    let (b0s, rest) = rest.split_at_mut(w);
    let (b1s, rest) = rest.split_at_mut(w);
    let b2s = &mut rest[..w];
    for x in 0..w {
        gain[x] = if link[x] & RIGHT != 0 { decay } else { 0.0 };
    }
    let [v0, v1, v2] = src;
    let (v0, v1, v2) = (&v0[..w], &v1[..w], &v2[..w]);
    let [p0, p1, p2] = dst;
    let (p0, p1, p2) = (&mut p0[..w], &mut p1[..w], &mut p2[..w]);
    let (mut f0, mut f1, mut f2) = (0.0f32, 0.0f32, 0.0f32);
    let (mut b0, mut b1, mut b2) = (0.0f32, 0.0f32, 0.0f32);
    for i in 0..w {
        let g = if i > 0 { gain[i - 1] } else { 0.0 };
        f0 = v0[i] + g * f0;
        f1 = v1[i] + g * f1;
        f2 = v2[i] + g * f2;
        p0[i] = f0;
        p1[i] = f1;
        p2[i] = f2;
        let x = w - 1 - i;
        let g = gain[x];
        b0 = v0[x] + g * b0;
        b1 = v1[x] + g * b1;
        b2 = v2[x] + g * b2;
        b0s[x] = b0;
        b1s[x] = b1;
        b2s[x] = b2;
    }
    for x in 0..w {
        p0[x] += b0s[x] - v0[x];
        p1[x] += b1s[x] - v1[x];
        p2[x] += b2s[x] - v2[x];
    }
}

/// Rows of the three planes → `tmp` (three planes), the vertical pass's input.
fn horizontal_pass(p: &mut Planes<'_>, decay: f32) {
    let w = p.w;
    let n = w * p.h;
    let band_px = BAND_ROWS * w;
    let (t0, rest) = p.tmp.split_at_mut(n);
    let (t1, t2) = rest.split_at_mut(n);
    let [a, b, c] = &p.planes;
    a[..n]
        .par_chunks(band_px)
        .zip(b[..n].par_chunks(band_px))
        .zip(c[..n].par_chunks(band_px))
        .zip(p.connect[..n].par_chunks(band_px))
        .zip(t0.par_chunks_mut(band_px))
        .zip(t1.par_chunks_mut(band_px))
        .zip(t2[..n].par_chunks_mut(band_px))
        .zip(p.band_scratch.par_chunks_mut(p.band_scratch_len))
        .for_each(|(((((((re, im), support), link), d0), d1), d2), gain)| {
            for r in 0..link.len() / w {
                let span = r * w..(r + 1) * w;
                horizontal_row(
                    [&re[span.clone()], &im[span.clone()], &support[span.clone()]],
                    [
                        &mut d0[span.clone()],
                        &mut d1[span.clone()],
                        &mut d2[span.clone()],
                    ],
                    &link[span],
                    decay,
                    gain,
                );
            }
        });
}

/// Pixels a recursion of `decay` must warm up on before its sum is that of the whole line to
/// f32 resolution: the smallest `k` with `decay^k < 10⁻⁸` (52 at 0.7, 83 at 0.8, 114 at 0.85),
/// or a whole image's length for a decay of 1 or more. The GPU's recursion segments warm up on
/// this many pixels (the CPU's vertical pass runs down whole columns, [`super::smooth_strips`]).
pub fn recursion_halo(decay: f32) -> u32 {
    const WHOLE_LINE: u32 = 1 << 16;
    if decay.is_nan() || decay <= 0.0 {
        return 0;
    }
    if decay >= 1.0 {
        return WHOLE_LINE;
    }
    let k = (1e-8f64.ln() / f64::from(decay).ln()).ceil();
    // In 0..=WHOLE_LINE, so the cast is exact.
    k.min(f64::from(WHOLE_LINE)) as u32
}

/// Vertical recursion over whole columns, exactly, in parallel strips of columns
/// ([`super::smooth_strips`]).
fn vertical_pass(p: &mut Planes<'_>, decay: f32) {
    vertical_strips(p, |state, v, links, _| plain_step(state, v, links, decay));
}

/// One vertical step of the state, in place: `s = v + g·s`, with `g = decay` where `links` has
/// the DOWN bit (the link between the two rows) and `g = 0` (a fresh start) without it.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn plain_step(state: [&mut [f32]; 3], v: [&[f32]; 3], links: &[u8], decay: f32) {
    let [s0, s1, s2] = state;
    let [a0, a1, a2] = v;
    // Every slice cut to one length, so that indexing needs no checks and the loop vectorises.
    let w = s0.len();
    let (s0, s1, s2) = (&mut s0[..w], &mut s1[..w], &mut s2[..w]);
    let (a0, a1, a2, links) = (&a0[..w], &a1[..w], &a2[..w], &links[..w]);
    for x in 0..w {
        let g = if links[x] & DOWN != 0 { decay } else { 0.0 };
        s0[x] = a0[x] + g * s0[x];
        s1[x] = a1[x] + g * s1[x];
        s2[x] = a2[x] + g * s2[x];
    }
}

/// Angle of a unit phasor mapped to `[−π/2, 3π/2)`: the true angle `f_1·x` lies in `[0, π)`, so
/// this keeps noisy estimates near both ends of the range on the correct side.
#[inline]
pub(crate) fn unit_angle(re: f32, im: f32) -> f32 {
    let a = super::fastmath::atan2(im, re);
    if a < -0.5 * PI {
        a + TAU
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    fn output(w: usize, h: usize) -> DecodeOutput {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        DecodeOutput::new(w, h, &solver)
    }

    #[test]
    fn constant_field_keeps_its_angle_and_grows_support() {
        let (w, h) = (40, 30);
        let mut out = output(w, h);
        out.unit_re.fill(0.6);
        out.unit_im.fill(0.8);
        out.support.fill(1.0);
        out.colour.fill(100.0);
        smooth_unit_phasor(&mut out, &SmoothingParams::default(), None);
        let centre = 15 * w + 20;
        let angle = out.unit_im[centre].atan2(out.unit_re[centre]);
        assert!((angle - 0.8f32.atan2(0.6)).abs() < 1e-5);
        // 1D gain (1+a)/(1−a) = 5.67 per axis, about 32 in 2D away from borders.
        assert!(out.support[centre] > 25.0, "{}", out.support[centre]);
    }

    #[test]
    fn phase_edge_stops_the_averaging() {
        let (w, h) = (40, 20);
        let mut out = output(w, h);
        out.support.fill(1.0);
        out.colour.fill(100.0);
        // Left half: angle 0.5 rad, guide phase 0; right half: angle 2.5 rad, guide phase 3.
        for y in 0..h {
            for x in 0..w {
                let left = x < w / 2;
                let a: f32 = if left { 0.5 } else { 2.5 };
                out.unit_re[y * w + x] = a.cos();
                out.unit_im[y * w + x] = a.sin();
                for f in 0..3 {
                    out.phase_rad[(y * 3 + f) * w + x] = if left { 0.0 } else { 3.0 };
                }
            }
        }
        smooth_unit_phasor(&mut out, &SmoothingParams::default(), None);
        let p = 10 * w + w / 2 - 1;
        let q = p + 1;
        assert!((out.unit_im[p].atan2(out.unit_re[p]) - 0.5).abs() < 1e-4);
        assert!((out.unit_im[q].atan2(out.unit_re[q]) - 2.5).abs() < 1e-4);
    }

    /// Forward + backward recursion over one line: `g[i]` links element i to i + 1.
    fn recurse_line(v: &[f32], g: &[f32]) -> Vec<f32> {
        let n = v.len();
        let mut fwd = vec![0.0; n];
        let mut bwd = vec![0.0; n];
        for i in 0..n {
            fwd[i] = v[i] + if i > 0 { g[i - 1] * fwd[i - 1] } else { 0.0 };
        }
        for i in (0..n).rev() {
            bwd[i] = v[i] + if i + 1 < n { g[i] * bwd[i + 1] } else { 0.0 };
        }
        (0..n).map(|i| fwd[i] + bwd[i] - v[i]).collect()
    }

    /// The straightforward recursion over whole rows, then whole columns.
    fn reference(v: &[f32], links: &[u8], w: usize, h: usize, a: f32) -> Vec<f32> {
        let gain = |i: usize, bit: u8| if links[i] & bit != 0 { a } else { 0.0 };
        let mut horiz = vec![0.0; w * h];
        for y in 0..h {
            let g: Vec<f32> = (0..w).map(|x| gain(y * w + x, RIGHT)).collect();
            horiz[y * w..(y + 1) * w].copy_from_slice(&recurse_line(&v[y * w..(y + 1) * w], &g));
        }
        let mut out = vec![0.0; w * h];
        for x in 0..w {
            let g: Vec<f32> = (0..h).map(|y| gain(y * w + x, DOWN)).collect();
            let col: Vec<f32> = (0..h).map(|y| horiz[y * w + x]).collect();
            for (y, value) in recurse_line(&col, &g).into_iter().enumerate() {
                out[y * w + x] = value;
            }
        }
        out
    }

    /// Random planes over `w×h` pixels, each link cut with probability `cut`, smoothed by
    /// [`smooth_planes`] at `decay` and compared with [`reference`].
    fn parallel_against_plain(w: usize, h: usize, decay: f32, cut: f32) {
        let mut out = output(w, h);
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f32 / (1u64 << 31) as f32
        };
        for i in 0..w * h {
            out.unit_re[i] = next() * 2.0 - 1.0;
            out.unit_im[i] = next() * 2.0 - 1.0;
            out.support[i] = f32::from(next() > 0.1);
            out.connect[i] = (u8::from(next() > cut) * RIGHT) | (u8::from(next() > cut) * DOWN);
        }
        for x in 0..w {
            out.connect[(h - 1) * w + x] &= !DOWN;
        }
        for y in 0..h {
            out.connect[y * w + w - 1] &= !RIGHT;
        }
        let expected: Vec<Vec<f32>> = [&out.unit_re, &out.unit_im, &out.support]
            .iter()
            .map(|v| reference(v, &out.connect, w, h, decay))
            .collect();
        smooth_planes(&mut Planes::of_unit_phasor(&mut out), decay);
        for (got, want) in [&out.unit_re, &out.unit_im, &out.support]
            .iter()
            .zip(&expected)
        {
            for (g, e) in got.iter().zip(want) {
                assert!(
                    (g - e).abs() <= 1e-5 * (1.0 + e.abs()),
                    "{decay}: {g} vs {e}"
                );
            }
        }
    }

    #[test]
    fn parallel_passes_match_the_plain_recursion() {
        // 37 columns: strips of 16, the last one shorter; 301 rows in bands; mostly connected,
        // with random cuts in both directions.
        parallel_against_plain(37, 301, 0.7, 0.15);
    }

    #[test]
    fn passes_stay_exact_at_the_full_resolution_reach() {
        // The decays at 1920 px wide (0.7 and 0.8 raised to the power 1/3) over long unbroken
        // columns: when the vertical pass ran in blocks of rows with a fixed 48-row warm-up,
        // they lost up to 3 % of each sum at their boundaries (0.928⁴⁸).
        for decay in [0.7f32.powf(1.0 / 3.0), 0.8f32.powf(1.0 / 3.0)] {
            parallel_against_plain(23, 1200, decay, 0.0);
        }
    }

    #[test]
    fn the_sums_are_the_same_bits_on_any_number_of_threads() {
        // The strips follow the threads; each column's recursion does not.
        let (w, h) = (203, 61);
        let smoothed = |threads: usize| {
            let mut out = output(w, h);
            for i in 0..w * h {
                out.unit_re[i] = ((i * 7919) % 1009) as f32 / 1009.0 - 0.5;
                out.unit_im[i] = ((i * 104_729) % 997) as f32 / 997.0 - 0.5;
                out.support[i] = 1.0;
                out.connect[i] = if i % 13 == 0 { RIGHT } else { RIGHT | DOWN };
            }
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| smooth_planes(&mut Planes::of_unit_phasor(&mut out), 0.8));
            [out.unit_re, out.unit_im, out.support]
                .map(|p| p.iter().map(|v| v.to_bits()).collect::<Vec<u32>>())
        };
        let one = smoothed(1);
        for threads in [2, 3, 8] {
            assert!(one == smoothed(threads), "{threads} threads");
        }
    }

    #[test]
    fn the_halo_reaches_below_f32_resolution() {
        assert_eq!(recursion_halo(0.7), 52);
        assert_eq!(recursion_halo(0.8), 83);
        assert_eq!(recursion_halo(0.85), 114);
        for decay in [0.5f32, 0.7, 0.85, 0.95, 0.99] {
            let k = recursion_halo(decay);
            assert!(decay.powi(k as i32) < 1e-8, "{decay}");
            assert!(decay.powi(k as i32 - 1) >= 1e-8, "{decay}");
        }
        assert_eq!(recursion_halo(0.0), 0);
        assert_eq!(recursion_halo(1.0), 1 << 16);
    }

    #[test]
    fn unit_angle_range() {
        assert!((unit_angle(-1.0, -0.01) - (PI + 0.01)).abs() < 1e-3);
        assert!((unit_angle(1.0, -0.01) + 0.01).abs() < 1e-3);
    }
}
