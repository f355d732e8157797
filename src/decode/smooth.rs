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

/// [`smooth_planes`] of three planes held apart from `out` (taken out of it, or scratch of
/// their own), with `out`'s connectivity and scratch.
pub(crate) fn smooth_apart(out: &mut DecodeOutput, planes: [&mut [f32]; 3], decay: f32) {
    let mut planes = Planes {
        planes,
        w: out.width,
        h: out.height,
        connect: &out.connect,
        tmp: &mut out.smooth_tmp,
        band_scratch: &mut out.band_scratch,
        band_scratch_len: out.band_scratch_len,
        vertical_state: &mut out.vertical_state,
    };
    smooth_planes(&mut planes, decay);
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

/// Rows of one vertical block at the least: the vertical recursion's state buffer holds one row
/// of state per block of this many rows.
pub(crate) const VERTICAL_BLOCK_ROWS: usize = 64;

/// Pixels a recursion of `decay` must warm up on before its sum is that of the whole line to
/// f32 resolution: the smallest `k` with `decay^k < 10⁻⁸` (52 at 0.7, 83 at 0.8, 114 at 0.85),
/// or a whole image's length for a decay of 1 or more. The CPU's vertical blocks and the GPU's
/// recursion segments both warm up on this many pixels.
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

/// Rows per vertical block for a recursion of `decay` over `h` rows: two blocks, one for each
/// of the two cores the decode is built for (issue 23), where each is at least as tall as the
/// halo it warms up on (and [`VERTICAL_BLOCK_ROWS`]); else one. Every block warms up on
/// [`recursion_halo`] rows beyond its inner end whatever its size, so more blocks would pay more
/// warm-up for threads the target machine does not have (at 1920×1200 the decays are raised to
/// the power 1/3 and the halos triple, to 155 and 247 rows). The layout depends on the image and
/// the decay alone, not on the machine's threads, so a session decodes to the same bits
/// everywhere.
fn vertical_block_rows(h: usize, decay: f32) -> usize {
    let least = (recursion_halo(decay) as usize).max(VERTICAL_BLOCK_ROWS);
    let blocks = if h >= 2 * least { 2 } else { 1 };
    h.div_ceil(blocks).max(1)
}

/// Vertical recursion, in parallel blocks of rows. Each block warms its state up on the halo rows
/// above (forward) and below (backward), reading the unmodified input copy.
fn vertical_pass(p: &mut Planes<'_>, decay: f32) {
    let w = p.w;
    let h = p.h;
    let n = w * h;
    // The horizontal pass's output, read while the blocks write their rows of the final planes.
    let orig: &[f32] = &p.tmp[..3 * n];
    let connect = p.connect;
    let block_rows = vertical_block_rows(h, decay);
    let halo = recursion_halo(decay) as usize;
    let block_px = block_rows * w;
    let [a, b, c] = &mut p.planes;
    a[..n]
        .par_chunks_mut(block_px)
        .zip(b[..n].par_chunks_mut(block_px))
        .zip(c[..n].par_chunks_mut(block_px))
        .zip(p.vertical_state.par_chunks_mut(3 * w))
        .enumerate()
        .for_each(|(block, (((re, im), support), state))| {
            let first = block * block_rows;
            let rows = re.len() / w;
            let ctx = VerticalBlock {
                halo,
                orig,
                connect,
                w,
                h,
                n,
                first,
                rows,
                decay,
            };
            vertical_block(&ctx, [re, im, support], state);
        });
}

struct VerticalBlock<'a> {
    /// Rows the recursion warms up on beyond the block's ends ([`recursion_halo`]).
    halo: usize,
    orig: &'a [f32],
    connect: &'a [u8],
    w: usize,
    h: usize,
    n: usize,
    first: usize,
    rows: usize,
    decay: f32,
}

/// One step of the vertical recursion for three planes: `next = v + g·previous`, with
/// `g = decay` where `links` has the DOWN bit, and `g = 0` (a fresh start) without links.
#[inline(always)]
fn step_rows(
    next: [&mut [f32]; 3],
    previous: [&[f32]; 3],
    v: [&[f32]; 3],
    links: Option<&[u8]>,
    decay: f32,
) {
    let [n0, n1, n2] = next;
    let [s0, s1, s2] = previous;
    let [a0, a1, a2] = v;
    match links {
        Some(l) => {
            for x in 0..n0.len() {
                let g = if l[x] & DOWN != 0 { decay } else { 0.0 };
                n0[x] = a0[x] + g * s0[x];
                n1[x] = a1[x] + g * s1[x];
                n2[x] = a2[x] + g * s2[x];
            }
        }
        None => {
            n0.copy_from_slice(a0);
            n1.copy_from_slice(a1);
            n2.copy_from_slice(a2);
        }
    }
}

/// [`step_rows`] with the state updated in place.
#[inline(always)]
fn step_state(state: [&mut [f32]; 3], v: [&[f32]; 3], links: Option<&[u8]>, decay: f32) {
    let [s0, s1, s2] = state;
    let [a0, a1, a2] = v;
    match links {
        Some(l) => {
            for x in 0..s0.len() {
                let g = if l[x] & DOWN != 0 { decay } else { 0.0 };
                s0[x] = a0[x] + g * s0[x];
                s1[x] = a1[x] + g * s1[x];
                s2[x] = a2[x] + g * s2[x];
            }
        }
        None => {
            s0.copy_from_slice(a0);
            s1.copy_from_slice(a1);
            s2.copy_from_slice(a2);
        }
    }
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn vertical_block(c: &VerticalBlock<'_>, planes: [&mut [f32]; 3], state: &mut [f32]) {
    let w = c.w;
    let [p0, p1, p2] = planes;
    let (s0, rest) = state.split_at_mut(w);
    let (s1, s2) = rest.split_at_mut(w);
    let v = |plane: usize, y: usize| &c.orig[plane * c.n + y * w..plane * c.n + (y + 1) * w];
    // Link from row y to row y + 1.
    let links = |y: usize| &c.connect[y * w..(y + 1) * w];
    // Forward: F[y] = v[y] + g(y−1→y)·F[y−1], warmed up on the halo above in the state; the
    // block's rows then recurse on each other in place, with no copy of the state.
    let warm_start = c.first.saturating_sub(c.halo);
    s0.fill(0.0);
    s1.fill(0.0);
    s2.fill(0.0);
    for y in warm_start..c.first {
        let previous = (y > warm_start).then(|| links(y - 1));
        step_state([s0, s1, s2], [v(0, y), v(1, y), v(2, y)], previous, c.decay);
    }
    for y in c.first..c.first + c.rows {
        let links_above = (y > warm_start).then(|| links(y - 1));
        let r = (y - c.first) * w;
        let (above0, row0) = p0.split_at_mut(r);
        let (above1, row1) = p1.split_at_mut(r);
        let (above2, row2) = p2.split_at_mut(r);
        let previous: [&[f32]; 3] = if y == c.first {
            [s0, s1, s2]
        } else {
            [&above0[r - w..], &above1[r - w..], &above2[r - w..]]
        };
        step_rows(
            [&mut row0[..w], &mut row1[..w], &mut row2[..w]],
            previous,
            [v(0, y), v(1, y), v(2, y)],
            links_above,
            c.decay,
        );
    }
    // Backward: B[y] = v[y] + g(y→y+1)·B[y+1], warmed up on the halo below; adds B − v.
    let warm_end = (c.first + c.rows + c.halo).min(c.h);
    s0.fill(0.0);
    s1.fill(0.0);
    s2.fill(0.0);
    for y in (c.first..warm_end).rev() {
        let (a0, a1, a2) = (v(0, y), v(1, y), v(2, y));
        let next = (y + 1 < warm_end).then(|| links(y));
        step_state([s0, s1, s2], [a0, a1, a2], next, c.decay);
        if y < c.first + c.rows {
            let r = (y - c.first) * w;
            for x in 0..w {
                p0[r + x] += s0[x] - a0[x];
                p1[r + x] += s1[x] - a1[x];
                p2[r + x] += s2[x] - a2[x];
            }
        }
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
mod tests;
