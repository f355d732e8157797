//! Which neighbouring pixels lie on one surface, for the edge-aware filter of [`super::smooth`].
//!
//! Two neighbours are *connected* when both passed the signal checks and
//! * every frequency's wrapped phase differs by less than `edge_phase_rad`: across a depth edge
//!   the phases jump by arbitrary amounts, and all three passing by chance is rare;
//! * their brightness (r + g + b of the offset image) differs by less than `edge_colour_ratio`
//!   of the brighter plus 6 gray levels;
//! * for colour sequences, their red and blue chromaticity (share of r + g + b) differ by less
//!   than `edge_chromaticity`: shading does not change chromaticity, skin against most
//!   backgrounds does. Tested as `|r_a·s_b − r_b·s_a| ≤ t·s_a·s_b + 6·max(s_a, s_b)`, with no
//!   division; the second term allows 6 gray levels of noise on dark pixels.
//!
//! Bit [`RIGHT`] links a pixel to its right neighbour, bit [`DOWN`] to the one below. Smoothing
//! only runs for CPS, so there are always exactly three phase planes.

use super::fastmath::{max_or_second as max, min_or_second as min};
use super::{DecodeOutput, SmoothingParams};
use rayon::prelude::*;
use std::f32::consts::TAU;

pub(crate) const RIGHT: u8 = 1;
pub(crate) const DOWN: u8 = 2;

#[inline]
fn wrapped_diff(a: f32, b: f32) -> f32 {
    // NaN phases give NaN, which fails every `<=` test.
    let d = (a - b).abs();
    min(d, TAU - d)
}

pub(crate) fn compute_connectivity(out: &mut DecodeOutput, params: &SmoothingParams) {
    let w = out.width;
    let h = out.height;
    let nc = out.channels;
    debug_assert_eq!(out.frequencies, 3);
    let phase = &out.phase_rad;
    let colour = &out.colour;
    let support = &out.support;
    out.connect
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, bits)| {
            let view = |yy: usize| RowView {
                phase: &phase[yy * 3 * w..(yy + 1) * 3 * w],
                colour: &colour[yy * nc * w..(yy + 1) * nc * w],
                support: &support[yy * w..(yy + 1) * w],
            };
            let here = view(y);
            bits.fill(0);
            // Right neighbours: the same row shifted by one.
            link_rows(&here, 0, &here, 1, w - 1, nc, params, RIGHT, bits);
            if y + 1 < h {
                link_rows(&here, 0, &view(y + 1), 0, w, nc, params, DOWN, bits);
            }
        });
}

struct RowView<'a> {
    phase: &'a [f32],
    colour: &'a [f32],
    support: &'a [f32],
}

/// `len` values of plane `p` of a row-planar row of width `w`, starting at `offset`.
#[inline]
fn plane(row: &[f32], w: usize, p: usize, offset: usize, len: usize) -> &[f32] {
    &row[p * w + offset..p * w + offset + len]
}

/// Sets `bit` in `bits[x]` when pixel `x + da` of row `a` and pixel `x + db` of row `b` are
/// connected, for `x < len`.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
#[allow(
    clippy::too_many_arguments,
    reason = "a row kernel over two typed rows"
)]
fn link_rows<'a>(
    a: &RowView<'a>,
    da: usize,
    b: &RowView<'a>,
    db: usize,
    len: usize,
    nc: usize,
    params: &SmoothingParams,
    bit: u8,
    bits: &mut [u8],
) {
    let w = a.support.len();
    let sup_a = &a.support[da..da + len];
    let sup_b = &b.support[db..db + len];
    let ph = |r: &RowView<'a>, f: usize, d: usize| plane(r.phase, w, f, d, len);
    let (a0, a1, a2) = (ph(a, 0, da), ph(a, 1, da), ph(a, 2, da));
    let (b0, b1, b2) = (ph(b, 0, db), ph(b, 1, db), ph(b, 2, db));
    let col = |r: &RowView<'a>, c: usize, d: usize| plane(r.colour, w, c, d, len);
    let max_phase = params.edge_phase_rad;
    let ratio = params.edge_colour_ratio;
    let chroma = params.edge_chromaticity;
    let bits = &mut bits[..len];
    if nc == 3 {
        let (ra, ga, ba) = (col(a, 0, da), col(a, 1, da), col(a, 2, da));
        let (rb, gb, bb) = (col(b, 0, db), col(b, 1, db), col(b, 2, db));
        for x in 0..len {
            // Negative (and NaN) colour counts as 0.
            let (red1, blue1) = (max(ra[x], 0.0), max(ba[x], 0.0));
            let (red2, blue2) = (max(rb[x], 0.0), max(bb[x], 0.0));
            let s1 = red1 + max(ga[x], 0.0) + blue1;
            let s2 = red2 + max(gb[x], 0.0) + blue2;
            // Chromaticity noise grows as 1/brightness: allow 6 gray levels on top of `chroma`.
            let tol = chroma * s1 * s2 + 6.0 * max(s1, s2);
            let ok = (sup_a[x] > 0.0)
                & (sup_b[x] > 0.0)
                & (wrapped_diff(a0[x], b0[x]) <= max_phase)
                & (wrapped_diff(a1[x], b1[x]) <= max_phase)
                & (wrapped_diff(a2[x], b2[x]) <= max_phase)
                & ((s1 - s2).abs() <= ratio * max(s1, s2) + 6.0)
                & ((red1 * s2 - red2 * s1).abs() <= tol)
                & ((blue1 * s2 - blue2 * s1).abs() <= tol);
            bits[x] |= if ok { bit } else { 0 };
        }
    } else {
        let (ya, yb) = (col(a, 0, da), col(b, 0, db));
        for x in 0..len {
            let (s1, s2) = (max(ya[x], 0.0), max(yb[x], 0.0));
            let ok = (sup_a[x] > 0.0)
                & (sup_b[x] > 0.0)
                & (wrapped_diff(a0[x], b0[x]) <= max_phase)
                & (wrapped_diff(a1[x], b1[x]) <= max_phase)
                & (wrapped_diff(a2[x], b2[x]) <= max_phase)
                & ((s1 - s2).abs() <= ratio * max(s1, s2) + 6.0);
            bits[x] |= if ok { bit } else { 0 };
        }
    }
}
