//! Stage 2's recursion for the unit phasor, carried along the surface by the fine phase.
//!
//! The plain recursion of [`super::smooth`] sums the unit phasors of a pixel's connected
//! neighbours as they are, so the sum's angle is that of the neighbourhood's weighted mean
//! coordinate. Where the neighbourhood is one-sided (an edge, an outline) or the coordinate
//! curves (the side of a finger), that mean is not the pixel's own coordinate: the average is
//! biased by the coordinate's gradient and curvature, the more the wider the filter. A decay of
//! 0.9 refused 2.7 % of a still hand's lit pixels for the rounding margin against 0.17 % at 0.7.
//!
//! Every link of the recursion joins two neighbours whose fine phases differ by less than
//! [`super::SmoothingParams::edge_phase_rad`], so the difference of their unit angles is known
//! exactly, up to noise: `f_1·(x_q − x_p) = wrap(φ_0(q) − φ_0(p)) / n`, with φ_0 the finest
//! frequency's phase (slot 0, frequency n·f_1). Each step of the recursion therefore turns the
//! running sum by that difference before adding the next pixel's phasor, so that every term of a
//! pixel's sum is aligned to the pixel's own coordinate (a parallel transport along the path):
//! the gradient and the curvature cancel, whatever the width, and only the noise is averaged.
//! The noise the transport adds is that of fine phase differences divided by n (about 2 mrad
//! per link on dark skin at σ = 2, a random walk over the filter's reach), against the unit
//! phase's own 80 mrad. The support plane is summed unturned.

use super::connect::{DOWN, RIGHT};
use super::smooth::Planes;
use super::BAND_ROWS;
use rayon::prelude::*;
use std::f32::consts::TAU;

/// The fine phase that carries the recursion: slot 0's plane of the row-planar phases, and the
/// ratio of the unit frequency to slot 0's (1/n).
#[derive(Clone, Copy)]
pub(crate) struct Transport<'a> {
    /// `out.phase_rad`: per row, the phases of slots 0, 1, 2, `w` each.
    pub phase_rad: &'a [f32],
    pub unit_per_fine: f32,
}

impl Transport<'_> {
    /// Slot 0's phases of row `y`.
    #[inline(always)]
    fn row(&self, y: usize, w: usize) -> &[f32] {
        &self.phase_rad[3 * w * y..3 * w * y + w]
    }
}

/// `(decay·cos θ, decay·sin θ)` of the unit angle's change `θ` from phase `from` to `to`.
#[inline(always)]
fn turn(from: f32, to: f32, unit_per_fine: f32, decay: f32) -> (f32, f32) {
    let d = to - from;
    let theta = (d - TAU * (d / TAU).round()) * unit_per_fine;
    // |θ| < 1/n: the series to θ³ is exact in f32.
    let t2 = theta * theta;
    (decay * (1.0 - 0.5 * t2), decay * theta * (1.0 - t2 / 6.0))
}

/// Runs the horizontal and the vertical pass on the unit phasor and its support.
pub(crate) fn smooth_transported(p: &mut Planes<'_>, decay: f32, transport: Transport<'_>) {
    horizontal_pass(p, decay, transport);
    vertical_pass(p, decay, transport);
}

/// Horizontal recursion of one row, turned: forward `F[x] = v[x] + g·R(θ[x−1])·F[x−1]`,
/// backward `B[x] = v[x] + g·R(−θ[x])·B[x+1]`, result `F + B − v`; the support (third plane)
/// is carried unturned.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn horizontal_row(
    src: [&[f32]; 3],
    dst: [&mut [f32]; 3],
    link: &[u8],
    phase: &[f32],
    [unit_per_fine, decay]: [f32; 2],
    scratch: &mut [f32],
) {
    let w = link.len();
    let (gc, rest) = scratch.split_at_mut(w);
    let (gs, rest) = rest.split_at_mut(w);
    let (b0s, rest) = rest.split_at_mut(w);
    let (b1s, rest) = rest.split_at_mut(w);
    let b2s = &mut rest[..w];
    for x in 0..w {
        let linked = x + 1 < w && link[x] & RIGHT != 0;
        let (c, s) = if linked {
            turn(phase[x], phase[x + 1], unit_per_fine, decay)
        } else {
            (0.0, 0.0)
        };
        gc[x] = c;
        gs[x] = s;
    }
    let [v0, v1, v2] = src;
    let (v0, v1, v2) = (&v0[..w], &v1[..w], &v2[..w]);
    let [p0, p1, p2] = dst;
    let (p0, p1, p2) = (&mut p0[..w], &mut p1[..w], &mut p2[..w]);
    let (mut f0, mut f1, mut f2) = (0.0f32, 0.0f32, 0.0f32);
    let (mut b0, mut b1, mut b2) = (0.0f32, 0.0f32, 0.0f32);
    for i in 0..w {
        let linked = i > 0 && link[i - 1] & RIGHT != 0;
        let (c, s, g) = if linked {
            (gc[i - 1], gs[i - 1], decay)
        } else {
            (0.0, 0.0, 0.0)
        };
        (f0, f1) = (v0[i] + c * f0 - s * f1, v1[i] + s * f0 + c * f1);
        f2 = v2[i] + g * f2;
        p0[i] = f0;
        p1[i] = f1;
        p2[i] = f2;
        let x = w - 1 - i;
        let (c, s) = (gc[x], gs[x]);
        let g = if link[x] & RIGHT != 0 { decay } else { 0.0 };
        (b0, b1) = (v0[x] + c * b0 + s * b1, v1[x] - s * b0 + c * b1);
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

/// Rows of the three planes → `tmp`, the vertical pass's input.
fn horizontal_pass(p: &mut Planes<'_>, decay: f32, transport: Transport<'_>) {
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
        .enumerate()
        .for_each(
            |(band, (((((((re, im), support), link), d0), d1), d2), scratch))| {
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
                        transport.row(band * BAND_ROWS + r, w),
                        [transport.unit_per_fine, decay],
                        scratch,
                    );
                }
            },
        );
}

/// Vertical recursion over whole columns in strips ([`vertical_strips`]), turned.
fn vertical_pass(p: &mut Planes<'_>, decay: f32, transport: Transport<'_>) {
    let w = p.w;
    vertical_strips(p, |state, v, links, at| {
        let sw = links.len();
        let phase = |y: usize| &transport.row(y, w)[at.x0..at.x0 + sw];
        let turn = [phase(at.from), phase(at.to)];
        let gains = [transport.unit_per_fine, decay];
        step(state, v, links, turn, gains);
    });
}

/// Where one vertical step of a strip stands: the step carries the state from row `from` to
/// row `to` (`to = from ± 1`), on the strip's columns from `x0`.
#[derive(Clone, Copy)]
struct StripStep {
    from: usize,
    to: usize,
    x0: usize,
}

/// Vertical recursion over whole columns, exactly, in parallel strips of columns (the plain
/// pass's blocks of rows warm up on their decay's [`super::smooth::recursion_halo`] instead):
/// each strip runs down its columns (`F[y] = v[y] + carry(F[y − 1])`, written to the planes)
/// and back up (`B[y] = v[y] + carry(B[y + 1])`, adding `B − v`), reading each row's segment of
/// the horizontal pass's output once per direction. `step(state, v, links, at)` sets the state to
/// `v + carry(state)` across `links` (the DOWN bits between the two rows).
fn vertical_strips<F>(p: &mut Planes<'_>, step: F)
where
    F: Fn([&mut [f32]; 3], [&[f32]; 3], &[u8], StripStep) + Sync,
{
    let w = p.w;
    let h = p.h;
    let n = w * h;
    if n == 0 {
        return;
    }
    let orig: &[f32] = &p.tmp[..3 * n];
    let connect = p.connect;
    // Two strips per thread even out the threads' shares.
    let strip_w = w.div_ceil(2 * rayon::current_num_threads()).max(16).min(w);
    let strips = w.div_ceil(strip_w);
    // Each strip's segments of every row of the three planes (a few pointers per row).
    let mut segments: Vec<[Vec<&mut [f32]>; 3]> = (0..strips)
        .map(|_| [(); 3].map(|()| Vec::with_capacity(h)))
        .collect();
    for (k, plane) in p.planes.iter_mut().enumerate() {
        for row in plane[..n].chunks_mut(w) {
            for (s, segment) in row.chunks_mut(strip_w).enumerate() {
                segments[s][k].push(segment);
            }
        }
    }
    segments
        .into_par_iter()
        .zip(p.vertical_state.par_chunks_mut(3 * strip_w))
        .enumerate()
        .for_each(|(strip, ([mut p0, mut p1, mut p2], state))| {
            let x0 = strip * strip_w;
            let sw = strip_w.min(w - x0);
            let (s0, rest) = state.split_at_mut(sw);
            let (s1, rest) = rest.split_at_mut(sw);
            let s2 = &mut rest[..sw];
            let v = |k: usize, y: usize| &orig[k * n + y * w + x0..k * n + y * w + x0 + sw];
            let links = |y: usize| &connect[y * w + x0..y * w + x0 + sw];
            for y in 0..h {
                let a = [v(0, y), v(1, y), v(2, y)];
                if y == 0 {
                    s0.copy_from_slice(a[0]);
                    s1.copy_from_slice(a[1]);
                    s2.copy_from_slice(a[2]);
                } else {
                    let at = StripStep {
                        from: y - 1,
                        to: y,
                        x0,
                    };
                    step([s0, s1, s2], a, links(y - 1), at);
                }
                p0[y].copy_from_slice(s0);
                p1[y].copy_from_slice(s1);
                p2[y].copy_from_slice(s2);
            }
            for y in (0..h).rev() {
                let a = [v(0, y), v(1, y), v(2, y)];
                if y + 1 == h {
                    s0.copy_from_slice(a[0]);
                    s1.copy_from_slice(a[1]);
                    s2.copy_from_slice(a[2]);
                } else {
                    let at = StripStep {
                        from: y + 1,
                        to: y,
                        x0,
                    };
                    step([s0, s1, s2], a, links(y), at);
                }
                add_difference([&mut *p0[y], &mut *p1[y], &mut *p2[y]], [s0, s1, s2], a);
            }
        });
}

/// `dst += state − v`, per plane.
#[inline(always)]
fn add_difference(dst: [&mut [f32]; 3], state: [&[f32]; 3], v: [&[f32]; 3]) {
    for ((d, s), v) in dst.into_iter().zip(state).zip(v) {
        for ((d, s), v) in d.iter_mut().zip(s).zip(v) {
            *d += s - v;
        }
    }
}

/// One vertical step of the state, in place: `s = v + g·R(θ)·s` where `links` has the DOWN bit
/// (the link between the two rows), `s = v` elsewhere; `θ` turns the unit angle of row `from`
/// to that of row `to`.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn step(
    state: [&mut [f32]; 3],
    v: [&[f32]; 3],
    links: &[u8],
    [from, to]: [&[f32]; 2],
    [unit_per_fine, decay]: [f32; 2],
) {
    let [s0, s1, s2] = state;
    let [a0, a1, a2] = v;
    let w = s0.len();
    let (s0, s1, s2) = (&mut s0[..w], &mut s1[..w], &mut s2[..w]);
    let (a0, a1, a2, links, from, to) = (
        &a0[..w],
        &a1[..w],
        &a2[..w],
        &links[..w],
        &from[..w],
        &to[..w],
    );
    for x in 0..w {
        let linked = links[x] & DOWN != 0;
        let (c, s) = turn(from[x], to[x], unit_per_fine, decay);
        let (c, s, g) = if linked {
            (c, s, decay)
        } else {
            (0.0, 0.0, 0.0)
        };
        let (r, i) = (s0[x], s1[x]);
        s0[x] = a0[x] + c * r - s * i;
        s1[x] = a1[x] + s * r + c * i;
        s2[x] = a2[x] + g * s2[x];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::smooth::smooth_planes;
    use crate::decode::{DecodeOutput, WindowSolver};
    use crate::pattern::{cps_rgb, Axis};

    const N: u32 = 65;

    fn output(w: usize, h: usize) -> DecodeOutput {
        let seq = cps_rgb(N, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        DecodeOutput::new(w, h, &solver)
    }

    fn transport(out: &mut DecodeOutput, decay: f32) {
        let (mut planes, phase_rad) = Planes::of_unit_phasor_with_phases(out);
        let transport = Transport {
            phase_rad,
            unit_per_fine: 1.0 / N as f32,
        };
        smooth_transported(&mut planes, decay, transport);
    }

    /// The transported recursion written out plainly, in f64 with exact rotations, over whole
    /// rows and then whole columns: `(re, im, support)` per pixel.
    fn reference(out: &DecodeOutput, decay: f64) -> Vec<[f64; 3]> {
        let (w, h) = (out.width, out.height);
        let phase = |x: usize, y: usize| f64::from(out.phase_rad[3 * w * y + x]);
        let theta = |from: f64, to: f64| {
            let d = to - from;
            (d - std::f64::consts::TAU * (d / std::f64::consts::TAU).round()) / f64::from(N)
        };
        // One line: values, the gain of each link to the next element, and its turn.
        let line = |v: &[[f64; 3]], g: &[f64], t: &[f64]| -> Vec<[f64; 3]> {
            let carry = |s: [f64; 3], g: f64, t: f64| {
                let (c, sn) = (g * t.cos(), g * t.sin());
                [c * s[0] - sn * s[1], sn * s[0] + c * s[1], g * s[2]]
            };
            let len = v.len();
            let mut fwd = v.to_vec();
            for i in 1..len {
                let c = carry(fwd[i - 1], g[i - 1], t[i - 1]);
                fwd[i] = [v[i][0] + c[0], v[i][1] + c[1], v[i][2] + c[2]];
            }
            let mut bwd = v.to_vec();
            for i in (0..len.saturating_sub(1)).rev() {
                let c = carry(bwd[i + 1], g[i], -t[i]);
                bwd[i] = [v[i][0] + c[0], v[i][1] + c[1], v[i][2] + c[2]];
            }
            (0..len)
                .map(|i| [0, 1, 2].map(|k| fwd[i][k] + bwd[i][k] - v[i][k]))
                .collect()
        };
        let mut field: Vec<[f64; 3]> = (0..w * h)
            .map(|i| [out.unit_re[i], out.unit_im[i], out.support[i]].map(f64::from))
            .collect();
        for y in 0..h {
            let v = &field[y * w..(y + 1) * w];
            let g: Vec<f64> = (0..w)
                .map(|x| f64::from(u8::from(out.connect[y * w + x] & RIGHT != 0)) * decay)
                .collect();
            let t: Vec<f64> = (0..w)
                .map(|x| {
                    if x + 1 < w {
                        theta(phase(x, y), phase(x + 1, y))
                    } else {
                        0.0
                    }
                })
                .collect();
            let row = line(v, &g, &t);
            field[y * w..(y + 1) * w].copy_from_slice(&row);
        }
        for x in 0..w {
            let v: Vec<[f64; 3]> = (0..h).map(|y| field[y * w + x]).collect();
            let g: Vec<f64> = (0..h)
                .map(|y| f64::from(u8::from(out.connect[y * w + x] & DOWN != 0)) * decay)
                .collect();
            let t: Vec<f64> = (0..h)
                .map(|y| {
                    if y + 1 < h {
                        theta(phase(x, y), phase(x, y + 1))
                    } else {
                        0.0
                    }
                })
                .collect();
            for (y, value) in line(&v, &g, &t).into_iter().enumerate() {
                field[y * w + x] = value;
            }
        }
        field
    }

    #[test]
    fn strips_and_rows_match_the_plain_transported_recursion() {
        // Odd sizes: several strips and a narrow last one.
        let (w, h) = (83, 57);
        let mut out = output(w, h);
        let mut state = 987654321u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f32 / (1u64 << 31) as f32
        };
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                out.unit_re[i] = next() * 2.0 - 1.0;
                out.unit_im[i] = next() * 2.0 - 1.0;
                out.support[i] = f32::from(next() > 0.1);
                out.connect[i] =
                    (u8::from(next() > 0.15) * RIGHT) | (u8::from(next() > 0.15) * DOWN);
                // Any phase in [0, 2π): neighbours' differences wrap both ways.
                out.phase_rad[3 * w * y + x] = next() * TAU;
            }
        }
        for x in 0..w {
            out.connect[(h - 1) * w + x] &= !DOWN;
        }
        for y in 0..h {
            out.connect[y * w + w - 1] &= !RIGHT;
        }
        let expected = reference(&out, 0.97);
        transport(&mut out, 0.97);
        for (i, e) in expected.iter().enumerate() {
            let got = [out.unit_re[i], out.unit_im[i], out.support[i]];
            for k in 0..3 {
                let tolerance = 1e-4 * (1.0 + e[k].abs());
                assert!(
                    (f64::from(got[k]) - e[k]).abs() <= tolerance,
                    "pixel {i} plane {k}: {} vs {}",
                    got[k],
                    e[k]
                );
            }
        }
    }

    /// A surface whose coordinate curves (a finger's side) and ends at an outline: the unit
    /// phasor's angle is `f_1·x`, the fine phase `n·f_1·x` wrapped.
    fn curved_surface(out: &mut DecodeOutput) -> Vec<f32> {
        let (w, h) = (out.width, out.height);
        let f1 = std::f32::consts::PI / 912.0;
        let mut angle = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                // 2.5 projector px per camera px, steepening to the right.
                let coordinate = 300.0 + 2.5 * x as f32 + 0.04 * (x * x) as f32 + 0.5 * y as f32;
                angle[i] = f1 * coordinate;
                out.unit_re[i] = angle[i].cos();
                out.unit_im[i] = angle[i].sin();
                out.support[i] = 1.0;
                out.phase_rad[3 * w * y + x] = (N as f32 * f1 * coordinate).rem_euclid(TAU);
                let inside = x + 1 < w;
                out.connect[i] = (u8::from(inside) * RIGHT) | (u8::from(y + 1 < h) * DOWN);
            }
        }
        angle
    }

    #[test]
    fn the_transport_removes_the_bias_of_gradient_and_curvature() {
        let (w, h) = (60, 40);
        let worst = |out: &DecodeOutput, angle: &[f32]| {
            (0..w * h)
                .map(|i| (out.unit_im[i].atan2(out.unit_re[i]) - angle[i]).abs())
                .fold(0.0f32, f32::max)
        };
        let mut plain = output(w, h);
        let angle = curved_surface(&mut plain);
        smooth_planes(&mut Planes::of_unit_phasor(&mut plain), 0.97);
        let mut carried = output(w, h);
        curved_surface(&mut carried);
        transport(&mut carried, 0.97);
        // Half a fine period is π/n ≈ 0.048 rad of unit angle: the plain average at the outline
        // is more than that off, the carried one at no pixel more than a hundredth of it.
        let (plain_worst, carried_worst) = (worst(&plain, &angle), worst(&carried, &angle));
        assert!(plain_worst > 0.05, "plain: {plain_worst}");
        assert!(carried_worst < 5e-4, "carried: {carried_worst}");
    }
}
