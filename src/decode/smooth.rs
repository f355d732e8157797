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
//! a domain-transform filter. Two neighbours are *connected* when both are valid, their middle
//! frequency's wrapped phase differs by less than `edge_phase_rad` and their brightness and
//! chromaticity are similar;
//! the recursion does not cross unconnected pairs, so depth edges (where the phase jumps) and
//! object boundaries (where the colour changes) stop the averaging. The filter costs O(1) per
//! pixel whatever its reach. The phasor magnitude (∝ amplitude²) weights bright pixels more.
//! The weight of valid pixels is filtered alongside as `support`.

use super::{DecodeOutput, SmoothingParams, BAND_ROWS};
use rayon::prelude::*;
use std::f32::consts::{PI, TAU};

const RIGHT: u8 = 1;
const DOWN: u8 = 2;

/// Runs stage 2 in place on `out.unit_re`, `out.unit_im` and `out.support`.
pub(crate) fn smooth_unit_phasor(out: &mut DecodeOutput, params: &SmoothingParams) {
    compute_connectivity(out, params);
    horizontal_pass(out, params.decay);
    vertical_pass(out, params.decay);
}

#[inline]
fn wrapped_diff(a: f32, b: f32) -> f32 {
    let d = (a - b).abs();
    d.min(TAU - d)
}

fn compute_connectivity(out: &mut DecodeOutput, params: &SmoothingParams) {
    let w = out.width;
    let h = out.height;
    let nf = out.frequencies;
    let nc = out.channels;
    let phase = &out.phase_rad;
    let colour = &out.colour;
    let support = &out.support;
    out.connect
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, bits)| {
            let rows = |yy: usize| RowView {
                phase: &phase[yy * nf * w..(yy + 1) * nf * w],
                colour: &colour[yy * nc * w..(yy + 1) * nc * w],
                support: &support[yy * w..(yy + 1) * w],
            };
            let here = rows(y);
            let below = (y + 1 < h).then(|| rows(y + 1));
            connect_row(&here, below.as_ref(), w, nf, nc, params, bits);
        });
}

struct RowView<'a> {
    phase: &'a [f32],
    colour: &'a [f32],
    support: &'a [f32],
}

/// Whether pixel `p` of row `a` and pixel `q` of row `b` lie on one surface.
#[inline]
#[allow(
    clippy::too_many_arguments,
    reason = "hot inner test over two typed rows"
)]
fn similar(
    a: &RowView<'_>,
    p: usize,
    b: &RowView<'_>,
    q: usize,
    w: usize,
    nf: usize,
    nc: usize,
    params: &SmoothingParams,
) -> bool {
    if a.support[p] == 0.0 || b.support[q] == 0.0 {
        return false;
    }
    // Every frequency's phase must be continuous: a depth jump passes one frequency's test by
    // chance far more often than all of them.
    for f in 0..nf {
        if wrapped_diff(a.phase[f * w + p], b.phase[f * w + q]) > params.edge_phase_rad {
            return false;
        }
    }
    let mut sum_a = 0.0;
    let mut sum_b = 0.0;
    for c in 0..nc {
        sum_a += a.colour[c * w + p].max(0.0);
        sum_b += b.colour[c * w + q].max(0.0);
    }
    if (sum_a - sum_b).abs() > params.edge_colour_ratio * sum_a.max(sum_b) + 6.0 {
        return false;
    }
    // Chromaticity does not change with shading, but does between skin and most backgrounds.
    if nc == 3 && sum_a > 0.0 && sum_b > 0.0 {
        for c in [0, 2] {
            let ca = a.colour[c * w + p].max(0.0) / sum_a;
            let cb = b.colour[c * w + q].max(0.0) / sum_b;
            if (ca - cb).abs() > params.edge_chromaticity {
                return false;
            }
        }
    }
    true
}

fn connect_row(
    here: &RowView<'_>,
    below: Option<&RowView<'_>>,
    w: usize,
    nf: usize,
    nc: usize,
    params: &SmoothingParams,
    bits: &mut [u8],
) {
    for (x, b) in bits.iter_mut().enumerate() {
        let mut v = 0u8;
        if x + 1 < w && similar(here, x, here, x + 1, w, nf, nc, params) {
            v |= RIGHT;
        }
        if let Some(below) = below {
            if similar(here, x, below, x, w, nf, nc, params) {
                v |= DOWN;
            }
        }
        *b = v;
    }
}

fn horizontal_pass(out: &mut DecodeOutput, decay: f32) {
    let w = out.width;
    let band_px = BAND_ROWS * w;
    out.unit_re
        .par_chunks_mut(band_px)
        .zip(out.unit_im.par_chunks_mut(band_px))
        .zip(out.support.par_chunks_mut(band_px))
        .zip(out.connect.par_chunks(band_px))
        .zip(out.smooth_tmp.par_chunks_mut(3 * band_px))
        .for_each(|((((re, im), support), connect), tmp)| {
            let rows = connect.len() / w;
            for r in 0..rows {
                let span = r * w..(r + 1) * w;
                let link = &connect[span.clone()];
                for (plane, buf) in [
                    &mut re[span.clone()],
                    &mut im[span.clone()],
                    &mut support[span.clone()],
                ]
                .into_iter()
                .enumerate()
                {
                    let orig = &mut tmp[plane * w..(plane + 1) * w];
                    orig.copy_from_slice(buf);
                    // Forward: F[x] = v[x] + a·F[x−1] across connected pairs.
                    for x in 1..w {
                        if link[x - 1] & RIGHT != 0 {
                            buf[x] += decay * buf[x - 1];
                        }
                    }
                    // Backward: B[x] = v[x] + a·B[x+1]; result F + B − v.
                    let mut acc = 0.0f32;
                    for x in (0..w).rev() {
                        acc = if x + 1 < w && link[x] & RIGHT != 0 {
                            orig[x] + decay * acc
                        } else {
                            orig[x]
                        };
                        buf[x] += acc - orig[x];
                    }
                }
            }
        });
}

fn vertical_pass(out: &mut DecodeOutput, decay: f32) {
    let w = out.width;
    let h = out.height;
    let n = w * h;
    let connect = &out.connect;
    let (orig_re, rest) = out.smooth_tmp.split_at_mut(n);
    let (orig_im, orig_support) = rest.split_at_mut(n);
    for (buf, orig) in [
        (&mut out.unit_re, orig_re),
        (&mut out.unit_im, orig_im),
        (&mut out.support, orig_support),
    ] {
        orig.copy_from_slice(buf);
        // Forward (top-down) sweep, row by row so each step is a contiguous, vectorised loop:
        // F[y] = v[y] + a·F[y−1] across connected pairs.
        for y in 1..h {
            let (above, below) = buf.split_at_mut(y * w);
            let prev = &above[(y - 1) * w..];
            let cur = &mut below[..w];
            let links = &connect[(y - 1) * w..y * w];
            for x in 0..w {
                if links[x] & DOWN != 0 {
                    cur[x] += decay * prev[x];
                }
            }
        }
        backward_columns(buf, orig, connect, w, h, decay);
    }
}

/// Backward (bottom-up) sweep of the vertical pass: adds `B − v` to the forward result in `buf`.
/// `orig` holds `v` on entry and is overwritten with `B` row by row, which is all the state needed.
fn backward_columns(
    buf: &mut [f32],
    orig: &mut [f32],
    connect: &[u8],
    w: usize,
    h: usize,
    decay: f32,
) {
    for y in (0..h).rev() {
        let (upper, lower) = orig.split_at_mut((y + 1) * w);
        let v_and_b = &mut upper[y * w..];
        let row_out = &mut buf[y * w..(y + 1) * w];
        let links = &connect[y * w..(y + 1) * w];
        if y + 1 < h {
            let b_below = &lower[..w];
            for x in 0..w {
                let v = v_and_b[x];
                let b = if links[x] & DOWN != 0 {
                    v + decay * b_below[x]
                } else {
                    v
                };
                row_out[x] += b - v;
                v_and_b[x] = b;
            }
        }
        // The last row: B = v, nothing to add.
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
        smooth_unit_phasor(&mut out, &SmoothingParams::default());
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
        smooth_unit_phasor(&mut out, &SmoothingParams::default());
        let p = 10 * w + w / 2 - 1;
        let q = p + 1;
        assert!((out.unit_im[p].atan2(out.unit_re[p]) - 0.5).abs() < 1e-4);
        assert!((out.unit_im[q].atan2(out.unit_re[q]) - 2.5).abs() < 1e-4);
    }

    #[test]
    fn unit_angle_range() {
        assert!((unit_angle(-1.0, -0.01) - (PI + 0.01)).abs() < 1e-3);
        assert!((unit_angle(1.0, -0.01) + 0.01).abs() < 1e-3);
    }
}
