//! The tables of the fast triangulation path, and its row kernel.
//!
//! For coded coordinate `x`, the plane normal (projector frame) is affine in `x`:
//! `a(x) = n0 + x·n1` (columns: `n0 = (fx, 0, cx)`, `n1 = (0, 0, −1)`; rows and the diagonal
//! alike). A camera ray `d` (scaled to `d_z = 1`, so the scale is the depth) meets it at
//!
//! ```text
//! depth = −(a·t) / (a·(R·d)) = (num0 + num1·x) / (den0 + den1·x)
//! num_i = −n_i·t (global),   den_i = n_i·(R·d) (per pixel)
//! ```
//!
//! Projector distortion moves the coordinate a real projector shows along the ray by a smooth
//! offset, a polynomial in the shown coordinate ([`super::distortion_fit`]). From 1800 px wide
//! the polynomials are fitted on a grid of pixels ([`super::fit_grid`]; a fifth of the memory,
//! [`super::fit_grid::grid_pays`]): a whole 8-px cell's are blended in registers as its depths
//! are computed, the row's other pixels' are expanded into a row of scratch. Below 1800 px wide
//! every pixel's is a column of nine planes. The per-pixel work is then a Horner
//! polynomial in the fit's normalised variable, one division and three products in `f32`, in a
//! loop over structure-of-array rows that vectorises. `den_i` is not a table: it is affine in
//! the ray, `den_i = g_i·(d_x, d_y, 1)` with `g_i = Rᵀ·n_i` global, so two products and two sums
//! per pixel replace two planes.

use crate::decode::fastmath::colour_byte;
use crate::geometry::LensModel;
use crate::pattern::Axis;
use nalgebra::Vector3;

use super::distortion_fit::{quantities, DistortionFit, RaySamples, QUANTITIES, TERMS};
use super::fit_grid::{FitGrid, RowFit, Segment, SEGMENT_LANES};
use super::StereoModel;
use rayon::prelude::*;

/// The plane normal of coded coordinate `x` is `n0 + x·n1`.
pub(super) fn plane_basis(axis: Axis, projector: &LensModel) -> (Vector3<f64>, Vector3<f64>) {
    let k = &projector.intrinsics;
    match axis {
        Axis::Columns => (Vector3::new(k.fx, 0.0, k.cx), Vector3::new(0.0, 0.0, -1.0)),
        Axis::Rows => (Vector3::new(0.0, k.fy, k.cy), Vector3::new(0.0, 0.0, -1.0)),
        Axis::Diagonal => (
            Vector3::new(k.fx, k.fy, k.cx + k.cy),
            Vector3::new(0.0, 0.0, -std::f64::consts::SQRT_2),
        ),
    }
}

/// The distortion polynomials of every pixel: on a grid, or one plane per quantity.
#[derive(Debug, Clone)]
pub(super) enum Polynomials {
    Grid(FitGrid),
    /// `x_mid` (NaN where the fit is missing), `inv_half_span` and the coefficients, per pixel.
    PerPixel([Vec<f32>; QUANTITIES]),
}

/// The per-pixel rays (structure of arrays), the distortion polynomials and the global
/// constants.
#[derive(Debug, Clone)]
pub(super) struct FastTable {
    /// Ray direction over its depth: `point = (ray_x·z, ray_y·z, z)`.
    pub ray_x: Vec<f32>,
    pub ray_y: Vec<f32>,
    pub polynomials: Polynomials,
    pub num0: f32,
    pub num1: f32,
    /// `g_0` and `g_1`: `den_i = g_i·(ray_x, ray_y, 1)`.
    pub den_of_ray: [[f32; 3]; 2],
}

impl FastTable {
    /// Builds the table from the unit rays `rays` of every camera pixel (row-major), with the
    /// distortion polynomials on a grid of `grid_step` pixels, or per pixel.
    pub fn new(model: &StereoModel, rays: &[Vector3<f64>], grid_step: Option<usize>) -> Self {
        let (n0, n1) = plane_basis(model.axis, &model.projector);
        let pose = &model.projector_from_camera;
        let t = pose.translation_mm;
        let of_ray = |normal: &Vector3<f64>| {
            let g = pose.rotation.transpose() * normal;
            [g.x as f32, g.y as f32, g.z as f32]
        };
        let (ray_x, ray_y) = rays
            .iter()
            .map(|d| ((d.x / d.z) as f32, (d.y / d.z) as f32))
            .unzip();
        let (width, height) = (model.camera.width, model.camera.height);
        let samples = |d: &Vector3<f64>| RaySamples::along(model, &(d / d.z));
        let polynomials = match grid_step {
            Some(step) => Polynomials::Grid(FitGrid::new(width, height, step, |u, v| {
                samples(rays.get(v * width + u)?)
            })),
            None => Polynomials::PerPixel(per_pixel_planes(width, rays, samples)),
        };
        Self {
            ray_x,
            ray_y,
            polynomials,
            num0: -n0.dot(&t) as f32,
            num1: -n1.dot(&t) as f32,
            den_of_ray: [of_ray(&n0), of_ray(&n1)],
        }
    }

    pub fn memory_bytes(&self) -> usize {
        let polynomials = match &self.polynomials {
            Polynomials::Grid(grid) => grid.memory_bytes(),
            Polynomials::PerPixel(planes) => {
                planes.iter().map(Vec::capacity).sum::<usize>() * std::mem::size_of::<f32>()
            }
        };
        (self.ray_x.capacity() + self.ray_y.capacity()) * std::mem::size_of::<f32>() + polynomials
    }

    /// Whether pixel `x` of row `y` has no polynomial (its ray leaves the projector's image in
    /// the working volume), after [`triangulate_row`] of that row with `scratch`.
    pub fn fit_missing(&self, y: usize, x: usize, scratch: &RowScratch) -> bool {
        match &self.polynomials {
            Polynomials::Grid(_) => scratch.fit.missing(x),
            Polynomials::PerPixel(planes) => planes[0][y * scratch.depth.len() + x].is_nan(),
        }
    }
}

/// Every pixel's polynomial as one plane per quantity, each row's written in parallel into
/// planes allocated once (joining per-row parts would hold both for a moment).
fn per_pixel_planes(
    width: usize,
    rays: &[Vector3<f64>],
    samples: impl Fn(&Vector3<f64>) -> Option<RaySamples> + Sync,
) -> [Vec<f32>; QUANTITIES] {
    let mut planes: [Vec<f32>; QUANTITIES] = std::array::from_fn(|_| vec![0.0; rays.len()]);
    let mut chunks: Vec<_> = planes
        .iter_mut()
        .map(|plane| plane.chunks_mut(width.max(1)))
        .collect();
    let rows: Vec<Vec<&mut [f32]>> = (0..rays.len().div_ceil(width.max(1)))
        .map(|_| chunks.iter_mut().filter_map(Iterator::next).collect())
        .collect();
    rows.into_par_iter()
        .zip(rays.par_chunks(width.max(1)))
        .for_each(|(mut row, row_rays)| {
            for (x, d) in row_rays.iter().enumerate() {
                let q = quantities(&DistortionFit::through(samples(d).as_ref()));
                for (plane, value) in row.iter_mut().zip(q) {
                    plane[x] = value as f32;
                }
            }
        });
    planes
}

/// A row's scratch: the per-pixel polynomials expanded from the grid (empty with per-pixel
/// planes), and the depths.
pub(super) struct RowScratch {
    pub fit: RowFit,
    pub depth: Vec<f32>,
    /// The row's cells, in order (the grid only).
    pub segments: Vec<Segment>,
}

impl RowScratch {
    pub fn new(table: &FastTable, width: usize) -> Self {
        let expanded = match table.polynomials {
            Polynomials::Grid(_) => width,
            Polynomials::PerPixel(_) => 0,
        };
        Self {
            fit: RowFit::new(expanded),
            depth: vec![0.0; width],
            segments: Vec::with_capacity(expanded / SEGMENT_LANES + 2),
        }
    }
}

/// Output rows of [`triangulate_row`].
pub(super) struct CloudRow<'a> {
    pub points: &'a mut [[f32; 3]],
    pub colours: &'a mut [[u8; 3]],
    pub amplitudes: &'a mut [f32],
}

/// Input rows of [`triangulate_row`]: the decoded coordinate, per-frequency amplitude planes
/// and colour planes of one image row.
pub(super) struct DecodedRow<'a> {
    pub coordinate: &'a [f32],
    pub amplitude: &'a [f32],
    pub frequencies: usize,
    pub colour: &'a [f32],
    pub channels: usize,
}

/// Triangulates image row `y`, with `scratch` for its polynomials and depths. Pixels whose
/// distortion fit is missing ([`FastTable::fit_missing`]) are left NaN: the caller takes the
/// exact path for them.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub(super) fn triangulate_row(
    table: &FastTable,
    y: usize,
    input: &DecodedRow<'_>,
    scratch: &mut RowScratch,
    out: CloudRow<'_>,
) {
    let w = input.coordinate.len();
    let span = y * w..(y + 1) * w;
    let (rx, ry) = (&table.ray_x[span.clone()], &table.ray_y[span.clone()]);
    let coordinate = &input.coordinate[..w];
    let RowScratch {
        fit,
        depth,
        segments,
    } = scratch;
    let depth = &mut depth[..w];
    let rays = Rays { rx, ry };
    match &table.polynomials {
        Polynomials::Grid(grid) => {
            grid.expand_row_into_segments(y, fit, segments);
            let planes: [&[f32]; QUANTITIES] = std::array::from_fn(|k| &fit.planes[k][..w]);
            for segment in segments.iter() {
                let px = segment.x0..segment.end;
                match &segment.blend {
                    Some((base, slope)) => {
                        depth_of_cell(table, base, slope, &rays, coordinate, depth, segment.x0);
                    }
                    None => depth_of_pixels(table, &planes, &rays, coordinate, depth, px),
                }
            }
        }
        Polynomials::PerPixel(planes) => {
            let planes: [&[f32]; QUANTITIES] = std::array::from_fn(|k| &planes[k][span.clone()]);
            depth_of_pixels(table, &planes, &rays, coordinate, depth, 0..w);
        }
    }
    write_outputs(rx, ry, input, depth, out);
}

/// A row's rays over their depth.
struct Rays<'a> {
    rx: &'a [f32],
    ry: &'a [f32],
}

/// The depth along the ray where the coded surface of the coordinate `shown`, less its
/// distortion `offset`, meets it: NaN for an invalid coordinate, a missing fit or a point
/// behind the camera.
#[inline(always)]
fn depth_at(table: &FastTable, rx: f32, ry: f32, shown: f32, offset: f32) -> f32 {
    let [g0, g1] = table.den_of_ray;
    let d0 = g0[0] * rx + g0[1] * ry + g0[2];
    let d1 = g1[0] * rx + g1[1] * ry + g1[2];
    let ideal = shown - offset;
    let z = (table.num0 + table.num1 * ideal) / (d0 + d1 * ideal);
    if z > 0.0 && z < f32::MAX {
        z
    } else {
        f32::NAN
    }
}

/// Depths of pixels `px` with their polynomials in `planes` (`x_mid`, `inv_half_span`, the
/// coefficients).
#[inline(always)]
fn depth_of_pixels(
    table: &FastTable,
    planes: &[&[f32]; QUANTITIES],
    rays: &Rays<'_>,
    coordinate: &[f32],
    depth: &mut [f32],
    px: std::ops::Range<usize>,
) {
    let (xm, inv) = (&planes[0][px.clone()], &planes[1][px.clone()]);
    let c: [&[f32]; TERMS] = std::array::from_fn(|i| &planes[2 + i][px.clone()]);
    let (rx, ry) = (&rays.rx[px.clone()], &rays.ry[px.clone()]);
    let shown = &coordinate[px.clone()];
    let depth = &mut depth[px];
    for x in 0..depth.len() {
        let t = (shown[x] - xm[x]) * inv[x];
        let mut offset = c[TERMS - 1][x];
        for i in (0..TERMS - 1).rev() {
            offset = offset * t + c[i][x];
        }
        depth[x] = depth_at(table, rx[x], ry[x], shown[x], offset);
    }
}

/// Depths of the whole cell of the widest step starting at `x0`, its polynomials blended in
/// registers (`base + frac·slope`, the same operations [`FitGrid::expand_row`] writes out).
#[inline(always)]
fn depth_of_cell(
    table: &FastTable,
    base: &[f32; QUANTITIES],
    slope: &[f32; QUANTITIES],
    rays: &Rays<'_>,
    coordinate: &[f32],
    depth: &mut [f32],
    x0: usize,
) {
    const L: usize = SEGMENT_LANES;
    let px = x0..x0 + L;
    let frac: [f32; L] = std::array::from_fn(|s| s as f32 / L as f32);
    let (Some(rx), Some(ry), Some(shown), Some(out)) = (
        rays.rx
            .get(px.clone())
            .and_then(|s| <&[f32; L]>::try_from(s).ok()),
        rays.ry
            .get(px.clone())
            .and_then(|s| <&[f32; L]>::try_from(s).ok()),
        coordinate
            .get(px.clone())
            .and_then(|s| <&[f32; L]>::try_from(s).ok()),
        depth
            .get_mut(px)
            .and_then(|s| <&mut [f32; L]>::try_from(s).ok()),
    ) else {
        // A segment is a whole cell inside the row, so this is not reached; were it, the cell
        // would have no depth rather than a stale one.
        for d in depth.iter_mut().skip(x0).take(L) {
            *d = f32::NAN;
        }
        return;
    };
    for lane in 0..L {
        let f = frac[lane];
        let q = |k: usize| base[k] + f * slope[k];
        let t = (shown[lane] - q(0)) * q(1);
        let mut offset = q(QUANTITIES - 1);
        for k in (2..QUANTITIES - 1).rev() {
            offset = offset * t + q(k);
        }
        out[lane] = depth_at(table, rx[lane], ry[lane], shown[lane], offset);
    }
}

/// The point, smallest amplitude and colour bytes of each pixel of the row, from its depth.
/// Inlined into [`triangulate_row`], so it is compiled for the same instruction sets.
#[inline(always)]
fn write_outputs(rx: &[f32], ry: &[f32], input: &DecodedRow<'_>, depth: &[f32], out: CloudRow<'_>) {
    let w = input.coordinate.len();
    // Points: a NaN depth (invalid) makes all three coordinates NaN, so no select is needed,
    // and the flattened row takes the three values at stride 3 in a loop that vectorises.
    let points = &mut out.points.as_flattened_mut()[..3 * w];
    for (x, p) in points.chunks_exact_mut(3).enumerate() {
        let z = depth[x];
        p[0] = rx[x] * z;
        p[1] = ry[x] * z;
        p[2] = z;
    }
    let nf = input.frequencies;
    let amplitudes = &mut out.amplitudes[..w];
    let plane = |f: usize| &input.amplitude[f * w..(f + 1) * w];
    let depth = &depth[..w];
    #[allow(clippy::eq_op, reason = "the NaN test that vectorises")]
    if nf == 3 {
        let (a0, a1, a2) = (plane(0), plane(1), plane(2));
        for x in 0..w {
            let z = depth[x];
            let smallest = a0[x].min(a1[x]).min(a2[x]);
            amplitudes[x] = if z == z { smallest } else { 0.0 };
        }
    } else {
        for x in 0..w {
            let z = depth[x];
            let smallest = (1..nf).fold(plane(0)[x], |m, f| m.min(plane(f)[x]));
            amplitudes[x] = if z == z { smallest } else { 0.0 };
        }
    }
    let nc = input.channels;
    let gray = |ch: usize, x: usize| colour_byte(input.colour[ch * w + x]);
    let colours = &mut out.colours.as_flattened_mut()[..3 * w];
    if nc == 3 {
        for (x, c) in colours.chunks_exact_mut(3).enumerate() {
            c[0] = gray(0, x);
            c[1] = gray(1, x);
            c[2] = gray(2, x);
        }
    } else {
        for (x, c) in colours.chunks_exact_mut(3).enumerate() {
            let v = gray(0, x);
            c[0] = v;
            c[1] = v;
            c[2] = v;
        }
    }
}
