//! The brightness change carried with the image ([`super::MotionParams::advected_brightness`],
//! opt-in, CPU only): on the last Gauss–Newton step each patch also solves for the image
//! velocity of its light, and each pixel takes the brightness change that velocity makes from
//! its own lit image's gradient.
//!
//! **Why.** A patch's one brightness change `κ` ([`super::motion`]) is the model's weakest value
//! on skin that moves sideways: within a patch the change differs from pixel to pixel, most near
//! an outline, where the patch is one-sided and the light turns fastest. Much of that variation
//! is the image moving: when the skin's light pattern `L` (its shading and texture) slides
//! across the pixels with an image velocity `w`, each pixel's light changes by `−w·∇L`, so
//! `κ(p) = κ₀ + v·∇ln L(p)` with `v = −w` shared by the patch and `∇ln L` the pixel's own. On
//! the rig's swaying hand (no noise; the truth's brightness change from frames rendered under
//! flat light, fitted over the patch's weights), a patch constant leaves 6.9/s of error 3 px
//! from the outline and 2.0/s inside; `κ₀ + v·∇ln L` leaves 2.0/s and 0.9/s
//! (docs/accuracy.md, Motion, stop 53). A linear trend in position instead (`κ₀ + b·Δp`) left
//! 6.7/s and 2.0/s: it is not the patch's one-sidedness.
//!
//! **How.** The patch's unknowns become `(u, κ₀, v_x, v_y)`; each pixel's Chebyshev residual
//! is `e = D_u·u + D_κ·(κ₀ + v·g)` with `g = ∇ln L`. Its normal equations are the step's five
//! sums (`uu`, `uk`, `kk`, `ue`, `ke`) and nine more, each a sum the step already forms times
//! the pixel's gradient (`uk·g`, `kk·g`, `kk·g·gᵀ`, `ke·g`): they are summed over the same
//! patch by the same edge-aware filter, and the 4×4 system is solved by its Schur complement on
//! `v` (2×2 blocks, written out), with a prior on `v` like the step's on `u` and `κ`
//! ([`PRIOR_IMAGE_VELOCITY_PX_PER_S`]). `L` is this window's lit offset sum without the
//! fringe the first step's correction says motion leaked into it
//! ([`super::motion_moving::lit_sum_without_leak`]), and its gradient the central difference
//! over connected neighbours (one-sided at an edge, none across one). Dropping the `uk·g` sums
//! (the coupling of `v` with `u`) lost the gain and more; `v` along image x alone gained
//! nothing.
//!
//! **Where it acts.** Only pixels whose patch the step finds moving take the advected `(u, κ)`;
//! their right-hand sides `ue`, `ke` are replaced by those that give it with the patch's own
//! 2×2 matrix, so the step's significance test, clamps and fall-backs
//! ([`super::motion_correct::patch_step`]) run unchanged on it. On a still hand only the
//! significance test's chance hits and a few pixels beside them or after them change (4 and 2
//! of 978,814 valid pixel-windows, by 4.6·10⁻⁴ px at most). It costs nine more planes smoothed
//! (three passes of the filter, the bulk of its 5–6 ms per 640×400 window here) and eleven
//! more planes of memory (44 B per pixel), allocated only when it is on.

use super::connect::{DOWN, RIGHT};
use super::motion::MOTION_SIGNIFICANCE;
use super::motion_basis::MotionBasis;
use super::motion_correct::Step;
use super::motion_moving::lit_sum_without_leak;
use super::smooth::smooth_apart;
use super::DecodeOutput;
use rayon::prelude::*;

/// The prior of a patch's image velocity before its evidence: zero, with this standard
/// deviation (camera px/s), so that a patch whose lit image has no gradient keeps its `κ₀`.
/// On the motion sweep's rows 150 and 400 gave the same RMS within 1 µm and the same coverage
/// within 0.3 points.
pub const PRIOR_IMAGE_VELOCITY_PX_PER_S: f32 = 150.0;

/// The largest gradient of `ln L` taken, per px (a guard, not tuned): a steeper one is an
/// outline's mixed pixel or a specular glint rather than shading that slides.
const MAX_LOG_GRADIENT_PER_PX: f32 = 0.5;

/// Number of summed planes beside the step's own.
const SUMS: usize = 9;

/// The planes of the advected brightness change, allocated on first use.
#[derive(Debug, Clone, Default)]
pub(crate) struct AdvectScratch {
    /// `∂ln L/∂x` and `∂ln L/∂y` per pixel.
    gradient: [Vec<f32>; 2],
    /// Summed: `uk·g_x`, `uk·g_y`, `kk·g_x`, `kk·g_y`, `kk·g_x²`, `kk·g_x·g_y`, `kk·g_y²`,
    /// `ke·g_x`, `ke·g_y`.
    sums: [Vec<f32>; SUMS],
}

impl AdvectScratch {
    fn fit(&mut self, n: usize) {
        for plane in self.gradient.iter_mut().chain(self.sums.iter_mut()) {
            plane.resize(n, 0.0);
        }
    }

    /// Heap bytes held.
    pub(crate) fn memory_bytes(&self) -> usize {
        let floats: usize = self
            .gradient
            .iter()
            .chain(self.sums.iter())
            .map(Vec::capacity)
            .sum();
        floats * std::mem::size_of::<f32>()
    }
}

/// Before the last step's sums: each pixel's `∇ln L` and its nine products with the step's
/// raw evidence (in `unit_im`, `support` and `motion_evidence`), summed over the patches with
/// `decay`.
pub(crate) fn sum_advection(basis: &MotionBasis, out: &mut DecodeOutput, decay: f32) {
    let (w, h) = (out.width, out.height);
    let n = w * h;
    let mut scratch = std::mem::take(&mut out.advect);
    scratch.fit(n);
    {
        // L, in the last sum's plane until the products overwrite it.
        let [.., lit] = &mut scratch.sums;
        lit.par_chunks_mut(w)
            .zip(out.phase_rad.par_chunks(3 * w))
            .zip(out.amplitude.par_chunks(3 * w))
            .zip(out.colour.par_chunks(3 * w))
            .zip(out.velocity_px_per_s.par_chunks(w))
            .zip(out.brightness_rate_per_s.par_chunks(w))
            .for_each(|(((((dst, phase), amp), offset), u), kappa)| {
                lit_row(basis, [phase, amp, offset], [u, kappa], dst);
            });
        let [gx, gy] = &mut scratch.gradient;
        let (lit, connect) = (&*lit, &out.connect);
        gx.par_chunks_mut(w)
            .zip(gy.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (gx, gy))| {
                let row = |y: usize| &lit[y * w..(y + 1) * w];
                let links = |y: usize| &connect[y * w..(y + 1) * w];
                let (has_above, has_below) = (y > 0, y + 1 < h);
                let above = if has_above { y - 1 } else { y };
                let below = if has_below { y + 1 } else { y };
                let rows = [row(above), row(y), row(below)];
                let links = [links(above), links(y)];
                gradient_row(rows, links, [has_above, has_below], [gx, gy]);
            });
    }
    {
        let [gx, gy] = &scratch.gradient;
        let ke = &out.motion_evidence[n..2 * n];
        let (uk, kk) = (&out.unit_im, &out.support);
        let [s0, s1, s2, s3, s4, s5, s6, s7, s8] = &mut scratch.sums;
        let rows = (
            s0.par_chunks_mut(w),
            s1.par_chunks_mut(w),
            s2.par_chunks_mut(w),
            s3.par_chunks_mut(w),
            s4.par_chunks_mut(w),
            s5.par_chunks_mut(w),
            s6.par_chunks_mut(w),
            s7.par_chunks_mut(w),
            s8.par_chunks_mut(w),
        );
        rows.into_par_iter()
            .enumerate()
            .for_each(|(y, (s0, s1, s2, s3, s4, s5, s6, s7, s8))| {
                let r = y * w..(y + 1) * w;
                let g = [&gx[r.clone()], &gy[r.clone()]];
                let dst = [s0, s1, s2, s3, s4, s5, s6, s7, s8];
                products_row([&uk[r.clone()], &kk[r.clone()], &ke[r]], g, dst);
            });
    }
    for triple in scratch.sums.chunks_mut(3) {
        let [a, b, c] = triple else { continue };
        smooth_apart(out, [a, b, c], decay);
    }
    out.advect = scratch;
}

/// One row's lit sums `L` ([`lit_sum_without_leak`]) from its row-planar phases, amplitudes
/// and offsets and its previous correction `(u, κ)`.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn lit_row(basis: &MotionBasis, planes: [&[f32]; 3], [u, kappa]: [&[f32]; 2], dst: &mut [f32]) {
    let w = dst.len();
    let [phase, amp, offset] = planes;
    let (phase, amp, offset) = (&phase[..3 * w], &amp[..3 * w], &offset[..3 * w]);
    let (u, kappa) = (&u[..w], &kappa[..w]);
    if u.iter().chain(kappa).all(|&v| v == 0.0) {
        // No pixel of the row was corrected, so none leaked: the same sums, without the
        // leak's nine sines and cosines per pixel.
        for x in 0..w {
            dst[x] = lit_sum_without_leak(
                basis,
                (0.0, 0.0),
                [0.0; 3],
                [0.0; 3],
                [offset[x], offset[w + x], offset[2 * w + x]],
            );
        }
        return;
    }
    for x in 0..w {
        dst[x] = lit_sum_without_leak(
            basis,
            (u[x], kappa[x]),
            [phase[x], phase[w + x], phase[2 * w + x]],
            [amp[x], amp[w + x], amp[2 * w + x]],
            [offset[x], offset[w + x], offset[2 * w + x]],
        );
    }
}

/// One row's `∇ln L` from the lit sums of the rows above, at and below it (`rows`; where a
/// row has no neighbour, any row stands in), the links down from the row above and from this
/// row (`links`) and whether the rows above and below exist: across each axis the difference of
/// `ln L` between the connected neighbours, taken as `2·(L_b − L_a)/(L_b + L_a)` per pixel of
/// distance (one-sided with one neighbour, 0 with none or a sum that is not positive), limited
/// to [`MAX_LOG_GRADIENT_PER_PX`].
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn gradient_row(
    rows: [&[f32]; 3],
    links: [&[u8]; 2],
    [has_above, has_below]: [bool; 2],
    [gx, gy]: [&mut [f32]; 2],
) {
    let w = gx.len();
    if w == 0 {
        return;
    }
    let [above, at, below] = rows;
    let (above, at, below, gy) = (&above[..w], &at[..w], &below[..w], &mut gy[..w]);
    let (from_above, here) = (&links[0][..w], &links[1][..w]);
    // The row's inside with plain indices, which vectorises; then its two ends.
    for x in 0..w {
        let up = has_above & (from_above[x] & DOWN != 0);
        let down = has_below & (here[x] & DOWN != 0);
        gy[x] = log_difference(at[x], (above[x], up), (below[x], down));
    }
    for x in 1..w - 1 {
        let left = here[x - 1] & RIGHT != 0;
        let right = here[x] & RIGHT != 0;
        gx[x] = log_difference(at[x], (at[x - 1], left), (at[x + 1], right));
    }
    for x in [0, w - 1] {
        let left = x > 0 && here[x - 1] & RIGHT != 0;
        let right = x + 1 < w && here[x] & RIGHT != 0;
        let (l, r) = (at[x.saturating_sub(1)], at[(x + 1).min(w - 1)]);
        gx[x] = log_difference(at[x], (l, left), (r, right));
    }
}

/// The difference of `ln L` per pixel at a pixel of sum `centre` between its neighbours `lo`
/// and `hi` where linked (see [`gradient_row`]).
#[inline(always)]
fn log_difference(centre: f32, (lo, lo_linked): (f32, bool), (hi, hi_linked): (f32, bool)) -> f32 {
    let a = if lo_linked { lo } else { centre };
    let b = if hi_linked { hi } else { centre };
    let steps = f32::from(u8::from(lo_linked)) + f32::from(u8::from(hi_linked));
    let d = 2.0 * (b - a) / ((b + a) * steps.max(1.0));
    let usable = (a > 0.0) & (b > 0.0) & d.is_finite();
    let d = if usable { d } else { 0.0 };
    d.clamp(-MAX_LOG_GRADIENT_PER_PX, MAX_LOG_GRADIENT_PER_PX)
}

/// One row's nine products of the raw evidence `[uk, kk, ke]` with the gradient `g`.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn products_row(evidence: [&[f32]; 3], [gx, gy]: [&[f32]; 2], dst: [&mut [f32]; SUMS]) {
    let [s0, s1, s2, s3, s4, s5, s6, s7, s8] = dst;
    let w = s0.len();
    let [uk, kk, ke] = evidence;
    let (uk, kk, ke, gx, gy) = (&uk[..w], &kk[..w], &ke[..w], &gx[..w], &gy[..w]);
    let (s1, s2, s3, s4) = (&mut s1[..w], &mut s2[..w], &mut s3[..w], &mut s4[..w]);
    let (s5, s6, s7, s8) = (&mut s5[..w], &mut s6[..w], &mut s7[..w], &mut s8[..w]);
    for x in 0..w {
        let (a, b) = (gx[x], gy[x]);
        s0[x] = uk[x] * a;
        s1[x] = uk[x] * b;
        s2[x] = kk[x] * a;
        s3[x] = kk[x] * b;
        s4[x] = kk[x] * a * a;
        s5[x] = kk[x] * a * b;
        s6[x] = kk[x] * b * b;
        s7[x] = ke[x] * a;
        s8[x] = ke[x] * b;
    }
}

/// After the last step's sums: for every pixel whose patch moves, its `(u, κ)` with the image
/// velocity (`κ = κ₀ + v·∇ln L` at the pixel), written as the right-hand sides `ue`, `ke` that
/// give it with the patch's 2×2 matrix.
pub(crate) fn apply_advection(step: &Step<'_>, out: &mut DecodeOutput) {
    let w = out.width;
    let n = w * out.height;
    let prior_v = step.prior_k * (PRIOR_BRIGHTNESS_SCALE / PRIOR_IMAGE_VELOCITY_PX_PER_S).powi(2);
    let priors = [step.prior_u, step.prior_k, prior_v];
    let scratch = &out.advect;
    let (ev_u, rest) = out.motion_evidence.split_at_mut(n);
    let (ev_k, count) = rest.split_at_mut(n);
    let matrix = [&out.unit_re, &out.unit_im, &out.support];
    ev_u.par_chunks_mut(w)
        .zip(ev_k.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (ru, rk))| {
            let r = y * w..(y + 1) * w;
            let inputs = AdvectRow {
                matrix: matrix.map(|p| span(p, &r)),
                count: &count[r.clone()],
                sums: scratch.sums.each_ref().map(|p| span(p, &r)),
                gradient: scratch.gradient.each_ref().map(|p| span(p, &r)),
            };
            advect_row(&inputs, priors, step.inv_noise2, [ru, rk]);
        });
}

/// The `r` part of `plane`.
fn span<'a>(plane: &'a [f32], r: &std::ops::Range<usize>) -> &'a [f32] {
    &plane[r.clone()]
}

/// One row's inputs to [`advect_row`].
struct AdvectRow<'a> {
    /// The step's summed `uu`, `uk`, `kk`.
    matrix: [&'a [f32]; 3],
    count: &'a [f32],
    sums: [&'a [f32]; SUMS],
    gradient: [&'a [f32]; 2],
}

/// [`Patch::advected`] over a row, its right-hand sides `[ue, ke]` replaced where it applies.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn advect_row(
    row: &AdvectRow<'_>,
    [prior_u, prior_k, prior_v]: [f32; 3],
    inv_noise2: f32,
    rhs: [&mut [f32]; 2],
) {
    let [ru, rk] = rhs;
    let w = ru.len();
    let rk = &mut rk[..w];
    let [uu, uk, kk] = row.matrix.map(|p| &p[..w]);
    let s = row.sums.map(|p| &p[..w]);
    let [gx, gy] = row.gradient.map(|p| &p[..w]);
    let count = &row.count[..w];
    for x in 0..w {
        let patch = Patch {
            a: uu[x] + prior_u,
            b: uk[x],
            c: kk[x] + prior_k,
            ru: ru[x],
            rk: rk[x],
            coupling: [s[0][x], s[1][x], s[2][x], s[3][x]],
            image: [s[4][x] + prior_v, s[5][x], s[6][x] + prior_v],
            rv: [s[7][x], s[8][x]],
        };
        let (u, kappa, taken) = patch.advected(inv_noise2, [gx[x], gy[x]]);
        let taken = taken & (count[x] > 0.0);
        ru[x] = if taken {
            patch.a * u + patch.b * kappa
        } else {
            ru[x]
        };
        rk[x] = if taken {
            patch.b * u + patch.c * kappa
        } else {
            rk[x]
        };
    }
}

/// The brightness prior's standard deviation ([`super::motion`]'s, 1/s), by which the step's
/// `prior_k` is rescaled to the image velocity's.
const PRIOR_BRIGHTNESS_SCALE: f32 = super::motion::PRIOR_BRIGHTNESS_RATE_PER_S;

/// One patch's normal equations in `(u, κ₀)` and `v`: `[[A, B], [Bᵀ, D]]·(θ, v) = (r_θ, r_v)`
/// with `A = [[a, b], [b, c]]`, `B = [[uk·g_x, uk·g_y], [kk·g_x, kk·g_y]]` (summed) and
/// `D = [[kk·g_x², kk·g_x·g_y], [·, kk·g_y²]]` (summed, with the prior).
#[derive(Debug, Clone, Copy)]
struct Patch {
    a: f32,
    b: f32,
    c: f32,
    ru: f32,
    rk: f32,
    /// `B` row by row: `uk·g_x`, `uk·g_y`, `kk·g_x`, `kk·g_y`.
    coupling: [f32; 4],
    /// `D`: `xx`, `xy`, `yy`.
    image: [f32; 3],
    rv: [f32; 2],
}

impl Patch {
    /// The advected `(u, κ)` at a pixel of gradient `g`, and whether it is taken: where the
    /// patch's own 2×2 solution is significant motion (as the step tests it) and both systems
    /// are solvable. Computed whatever the case, without branches, so that its loop vectorises.
    #[inline(always)]
    fn advected(&self, inv_noise2: f32, g: [f32; 2]) -> (f32, f32, bool) {
        let det_a = self.a * self.c - self.b * self.b;
        let (u2, k2) = (
            (self.c * self.ru - self.b * self.rk) / det_a,
            (self.a * self.rk - self.b * self.ru) / det_a,
        );
        let significance =
            (self.a * u2 * u2 + 2.0 * self.b * u2 * k2 + self.c * k2 * k2) * inv_noise2;
        // A⁻¹·B, column by column (B's columns are v_x's and v_y's couplings).
        let [bux, buy, bkx, bky] = self.coupling;
        let (ax_u, ax_k) = (
            (self.c * bux - self.b * bkx) / det_a,
            (self.a * bkx - self.b * bux) / det_a,
        );
        let (ay_u, ay_k) = (
            (self.c * buy - self.b * bky) / det_a,
            (self.a * bky - self.b * buy) / det_a,
        );
        // The Schur complement S = D − Bᵀ·A⁻¹·B and its right-hand side r_v − Bᵀ·A⁻¹·r_θ.
        let [dxx, dxy, dyy] = self.image;
        let sxx = dxx - (bux * ax_u + bkx * ax_k);
        let sxy = dxy - (bux * ay_u + bkx * ay_k);
        let syy = dyy - (buy * ay_u + bky * ay_k);
        let tx = self.rv[0] - (bux * u2 + bkx * k2);
        let ty = self.rv[1] - (buy * u2 + bky * k2);
        let det_s = sxx * syy - sxy * sxy;
        let vx = (syy * tx - sxy * ty) / det_s;
        let vy = (sxx * ty - sxy * tx) / det_s;
        // θ = A⁻¹·(r_θ − B·v).
        let u = u2 - (ax_u * vx + ay_u * vy);
        let kappa = k2 - (ax_k * vx + ay_k * vy) + vx * g[0] + vy * g[1];
        let taken = (det_a > 0.0)
            & (det_s > 0.0)
            & (significance > MOTION_SIGNIFICANCE)
            & u.is_finite()
            & kappa.is_finite();
        (u, kappa, taken)
    }
}

#[cfg(test)]
mod tests;
