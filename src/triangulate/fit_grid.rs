//! The projector-distortion polynomials of the fast path ([`super::distortion_fit`]), fitted
//! on a grid of camera pixels and interpolated bilinearly between its nodes (issue 23: narrow,
//! reduced-resolution tables). The triangulator takes it from 1800 px wide ([`grid_pays`]).
//!
//! The offset between the shown and the ideal coded coordinate changes smoothly from one camera
//! pixel to the next, so the polynomials are fitted only at nodes [`node_step_px`] pixels apart
//! in both directions: 8 at 1920 columns, and as many pixels for the same angle on smaller
//! images (3 at 640), where the blend's error would otherwise grow with the square of the
//! angle. Each is a polynomial in `t = (x − x_mid)·inv_half_span`, which runs over [−1, 1]
//! between the shown coordinates of the outermost depth samples. The shown coordinate is nearly
//! affine in inverse depth, so one `t` is nearly one depth on every ray: a bilinear blend of four
//! corners' coefficients (and of their `x_mid` and `inv_half_span`) blends their offsets at the
//! same depth. (Blending at the same shown coordinate instead fails where the coded coordinate
//! barely changes with depth, rows coded across a horizontal baseline: each ray's polynomial
//! spans a fraction of a pixel there, and a neighbour's, evaluated a pixel away, extrapolates
//! far out of its range, 2 mm off on the rig.)
//!
//! A cell stores each quantity as `a + wx·bx + wy·(by + wx·bxy)` (`wx`, `wy` ∈ [0, 1] across
//! it): per image row the `wy` terms fold into two values per cell, and per pixel one product and
//! one sum per quantity give its polynomial: into a row of scratch that stays in cache
//! ([`FitGrid::expand_row`]), or, for a whole cell of 8 px, in registers as the kernel computes
//! its depths ([`FitGrid::expand_row_into_segments`]). Per-pixel polynomials take nine planes (36 B/px, 83 MB at 1920×1200); the
//! grid takes 148 B per cell of 8×8 pixels (5.3 MB).
//!
//! Every pixel is checked when the grid is built: the blended polynomial, evaluated in `f32` as
//! the kernel does, must reproduce the pixel's own offset samples that fall on the projector's
//! image to [`GRID_TOLERANCE_PX`]. A cell where some pixel does not keeps every pixel's own
//! polynomial instead (where the ray grazes the coded planes, so the coordinate hardly changes
//! with depth and the `t` of one depth differs between neighbours). A pixel whose ray leaves the
//! projector's image somewhere in the working volume has no polynomial (NaN `x_mid`): it takes
//! the exact path.

use super::distortion_fit::{quantities, DistortionFit, RaySamples, QUANTITIES};
use rayon::prelude::*;

/// Camera pixels between neighbouring nodes of the fit grid, in both directions, for an image
/// `width` pixels wide: 8 at 1920, the same angle at other widths (at least 2, at most 8).
pub fn node_step_px(width: usize) -> usize {
    ((LANES * width + 960) / 1920).clamp(2, LANES)
}
/// The largest error the grid's polynomial may make at a pixel's own offset samples, projector
/// px; a tenth of the fast path's budget of 10⁻³ px (`tests/triangulation.rs`).
pub const GRID_TOLERANCE_PX: f32 = 1e-4;

/// Pixels of a whole cell at the widest step, expanded as one vector per quantity.
const LANES: usize = 8;
/// No per-pixel polynomials: the cell's blend holds.
const BLENDED: u32 = u32::MAX;

/// Whether an image `width` pixels wide takes the grid: where its cells are whole vectors
/// ([`node_step_px`] is 8, from 1800 px). On smaller images a cell's few pixels cost more to
/// expand than per-pixel planes cost to read (640×400: 1.8 against 0.9 ms per window), and
/// those planes are small (9 MiB).
pub fn grid_pays(width: usize) -> bool {
    node_step_px(width) == LANES
}

/// One grid cell's fit as a bilinear form in the cell's fractions `wx`, `wy`, per quantity:
/// `a + wx·bx + wy·(by + wx·bxy)`.
#[derive(Debug, Clone, Copy)]
struct CellFit {
    /// Where the cell's per-pixel polynomials start in [`FitGrid::pixel_fits`], or
    /// [`BLENDED`].
    pixels: u32,
    a: [f32; QUANTITIES],
    bx: [f32; QUANTITIES],
    by: [f32; QUANTITIES],
    bxy: [f32; QUANTITIES],
}

impl CellFit {
    /// The cell between corners `[top-left, top-right, bottom-left, bottom-right]`. A missing
    /// corner makes every quantity NaN.
    fn new(corners: [&DistortionFit; 4]) -> Self {
        let [p00, p01, p10, p11] = corners.map(quantities);
        let f = |v: f64| v as f32;
        Self {
            pixels: BLENDED,
            a: p00.map(f),
            bx: std::array::from_fn(|k| f(p01[k] - p00[k])),
            by: std::array::from_fn(|k| f(p10[k] - p00[k])),
            bxy: std::array::from_fn(|k| f(p11[k] - p01[k] - p10[k] + p00[k])),
        }
    }
}

/// Node positions along an axis of `len` pixels: every `step`, the last one on the last pixel
/// (at least two nodes, so there is at least one cell).
fn node_positions(len: usize, step: usize) -> Vec<usize> {
    let last = len.saturating_sub(1);
    let mut nodes: Vec<usize> = (0..last.div_ceil(step)).map(|j| j * step).collect();
    nodes.push(last);
    if nodes.len() < 2 {
        nodes.push(last);
    }
    nodes
}

/// The distortion fits of one camera, on the node grid.
#[derive(Debug, Clone, Default)]
pub(super) struct FitGrid {
    /// Pixels between nodes.
    step: usize,
    node_x: Vec<usize>,
    node_y: Vec<usize>,
    /// `(node_y.len() − 1) × (node_x.len() − 1)` cells, row-major.
    cells: Vec<CellFit>,
    /// Each image column's fraction of the way across its cell (`wx`).
    frac_x: Vec<f32>,
    /// The per-pixel polynomials of the cells that keep them: `(step + 1)²` per cell, row-major
    /// from the cell's top-left node (a cell's pixels reach its right and bottom nodes at the
    /// image's last column and row).
    pixel_fits: Vec<[f32; QUANTITIES]>,
}

/// A row of per-pixel polynomials, expanded from the grid: planes of `x_mid` (NaN where the fit
/// is missing), `inv_half_span` and the coefficients.
#[derive(Debug, Clone)]
pub(super) struct RowFit {
    pub planes: [Vec<f32>; QUANTITIES],
}

impl RowFit {
    pub fn new(width: usize) -> Self {
        Self {
            planes: std::array::from_fn(|_| vec![0.0; width]),
        }
    }

    /// Whether pixel `x`'s fit is missing.
    pub fn missing(&self, x: usize) -> bool {
        self.planes[0][x].is_nan()
    }

    /// Whether pixel `x`'s polynomial, evaluated as the kernel does, reproduces its samples on
    /// the projector's image (the coordinates a decode can give) to [`GRID_TOLERANCE_PX`], or is
    /// missing where they are.
    fn reproduces(&self, x: usize, samples: Option<&RaySamples>) -> bool {
        let Some(samples) = samples else {
            return self.missing(x);
        };
        if self.missing(x) {
            return false;
        }
        let (x_mid, inv) = (self.planes[0][x], self.planes[1][x]);
        let on_projector = samples.on_projector.iter();
        let shown_and_offset = samples.shown.iter().zip(&samples.offset);
        let checked = shown_and_offset.zip(on_projector).filter(|(_, &on)| on);
        checked.map(|(pair, _)| pair).all(|(&shown, &truth)| {
            let t = (shown as f32 - x_mid) * inv;
            let mut offset = self.planes[QUANTITIES - 1][x];
            for plane in self.planes[2..QUANTITIES - 1].iter().rev() {
                offset = offset * t + plane[x];
            }
            (f64::from(offset) - truth).abs() <= f64::from(GRID_TOLERANCE_PX)
        })
    }

    #[cfg(test)]
    fn offset(&self, x: usize, shown: f64) -> f64 {
        let t = (shown - f64::from(self.planes[0][x])) * f64::from(self.planes[1][x]);
        self.planes[2..]
            .iter()
            .rev()
            .fold(0.0, |acc, c| acc * t + f64::from(c[x]))
    }
}

impl FitGrid {
    /// Fits the grid of a `width`×`height` camera, checks it at every pixel and keeps the
    /// pixels' own polynomials where it fails; `samples(u, v)` samples the ray of pixel `(u, v)`.
    pub fn new(
        width: usize,
        height: usize,
        step: usize,
        samples: impl Fn(usize, usize) -> Option<RaySamples> + Sync,
    ) -> Self {
        let step = step.max(1);
        let (node_x, node_y) = (node_positions(width, step), node_positions(height, step));
        let nodes: Vec<Vec<DistortionFit>> = node_y
            .par_iter()
            .map(|&v| {
                let fit = |&u: &usize| DistortionFit::through(samples(u, v).as_ref());
                node_x.iter().map(fit).collect()
            })
            .collect();
        // Allocated to size: a collect from `flat_map` grows by doubling (9.7 MB held for
        // 5.3 MB of cells at 1920×1200).
        let mut cells = Vec::with_capacity((node_x.len() - 1) * (node_y.len() - 1));
        cells.extend(nodes.windows(2).flat_map(|rows| {
            rows[0]
                .windows(2)
                .zip(rows[1].windows(2))
                .map(|(top, bottom)| CellFit::new([&top[0], &top[1], &bottom[0], &bottom[1]]))
        }));
        let frac_x = (0..width)
            .map(|x| {
                let j = (x / step).min(node_x.len() - 2);
                let (x0, x1) = (node_x[j], node_x[j + 1]);
                if x1 > x0 {
                    (x - x0) as f32 / (x1 - x0) as f32
                } else {
                    0.0
                }
            })
            .collect();
        let mut grid = Self {
            step,
            node_x,
            node_y,
            cells,
            frac_x,
            pixel_fits: Vec::new(),
        };
        grid.keep_pixels_where_the_blend_fails(width, height, &samples);
        grid
    }

    /// The cell row of image row `y`, and the cell column of each image column.
    fn cell_row(&self, y: usize) -> usize {
        (y / self.step).min(self.node_y.len() - 2)
    }

    fn cell_column(&self, x: usize) -> usize {
        (x / self.step).min(self.node_x.len() - 2)
    }

    /// Checks every pixel's blended polynomial against its samples (`f32`, as the kernel
    /// evaluates it) and stores per-pixel polynomials for the cells where one fails.
    fn keep_pixels_where_the_blend_fails(
        &mut self,
        width: usize,
        height: usize,
        samples: &(impl Fn(usize, usize) -> Option<RaySamples> + Sync),
    ) {
        let cells_x = self.node_x.len() - 1;
        let failing: Vec<Vec<usize>> = (0..height)
            .into_par_iter()
            .map_init(
                || RowFit::new(width),
                |row, y| {
                    self.expand_row(y, row);
                    let mut columns: Vec<usize> = (0..width)
                        .filter(|&x| !row.reproduces(x, samples(x, y).as_ref()))
                        .map(|x| self.cell_column(x))
                        .collect();
                    columns.dedup();
                    columns
                },
            )
            .collect();
        let mut keep = vec![false; self.cells.len()];
        for (y, columns) in failing.iter().enumerate() {
            for &j in columns {
                keep[self.cell_row(y) * cells_x + j] = true;
            }
        }
        let side = self.step + 1;
        let kept = keep.iter().filter(|&&k| k).count();
        self.pixel_fits.reserve_exact(kept * side * side);
        for (index, _) in keep.iter().enumerate().filter(|(_, &k)| k) {
            let (i, j) = (index / cells_x, index % cells_x);
            let (x0, y0) = (self.node_x[j], self.node_y[i]);
            self.cells[index].pixels = u32::try_from(self.pixel_fits.len()).unwrap_or(BLENDED);
            for dy in 0..side {
                for dx in 0..side {
                    let (x, y) = (x0 + dx, y0 + dy);
                    let fit = if x < width && y < height {
                        DistortionFit::through(samples(x, y).as_ref())
                    } else {
                        DistortionFit::MISSING
                    };
                    self.pixel_fits.push(quantities(&fit).map(|v| v as f32));
                }
            }
        }
    }

    /// Cells that keep their pixels' own polynomials, and all cells.
    pub fn cells_kept_per_pixel(&self) -> (usize, usize) {
        let kept = self.cells.iter().filter(|c| c.pixels != BLENDED).count();
        (kept, self.cells.len())
    }

    pub fn memory_bytes(&self) -> usize {
        self.cells.capacity() * std::mem::size_of::<CellFit>()
            + self.pixel_fits.capacity() * std::mem::size_of::<[f32; QUANTITIES]>()
            + (self.node_x.capacity() + self.node_y.capacity()) * std::mem::size_of::<usize>()
            + self.frac_x.capacity() * std::mem::size_of::<f32>()
    }

    /// Each pixel's polynomial along image row `y` into `row` (its first `width` pixels).
    #[inline(always)]
    pub fn expand_row(&self, y: usize, row: &mut RowFit) {
        self.expand(y, row, None);
    }

    /// [`Self::expand_row`], except that each whole blended cell of the widest step is handed
    /// over in `segments` as its blend (`base + frac·slope` per quantity) for the kernel to
    /// evaluate in registers; only its `x_mid` plane is written (for
    /// [`RowFit::missing`]). `segments` lists every cell of the row in order.
    pub fn expand_row_into_segments(
        &self,
        y: usize,
        row: &mut RowFit,
        segments: &mut Vec<Segment>,
    ) {
        segments.clear();
        self.expand(y, row, Some(segments));
    }

    #[inline(always)]
    fn expand(&self, y: usize, row: &mut RowFit, mut segments: Option<&mut Vec<Segment>>) {
        let cells_x = self.node_x.len() - 1;
        let i = self.cell_row(y);
        let (y0, y1) = (self.node_y[i], self.node_y[i + 1]);
        let wy = if y1 > y0 {
            (y - y0) as f32 / (y1 - y0) as f32
        } else {
            0.0
        };
        let cells = &self.cells[i * cells_x..(i + 1) * cells_x];
        for (j, cell) in cells.iter().enumerate() {
            let (x0, x1) = (self.node_x[j], self.node_x[j + 1]);
            let along = |k: usize| (cell.a[k] + wy * cell.by[k], cell.bx[k] + wy * cell.bxy[k]);
            let end = if j + 1 == cells_x { x1 + 1 } else { x1 };
            if cell.pixels != BLENDED {
                let first = cell.pixels as usize + (y - y0) * (self.step + 1);
                let fits = &self.pixel_fits[first..first + (end - x0)];
                for (k, plane) in row.planes.iter_mut().enumerate() {
                    for (o, fit) in plane[x0..end].iter_mut().zip(fits) {
                        *o = fit[k];
                    }
                }
            } else if x1 - x0 == LANES && end == x1 {
                // A whole cell of the widest step: one vector per quantity.
                let frac: [f32; LANES] = std::array::from_fn(|s| s as f32 / LANES as f32);
                if let Some(segments) = segments.as_deref_mut() {
                    let base = std::array::from_fn(|k| along(k).0);
                    let slope = std::array::from_fn(|k| along(k).1);
                    for (o, f) in row.planes[0][x0..end].iter_mut().zip(frac) {
                        *o = base[0] + f * slope[0];
                    }
                    segments.push(Segment {
                        x0,
                        end,
                        blend: Some((base, slope)),
                    });
                    continue;
                }
                for (k, plane) in row.planes.iter_mut().enumerate() {
                    let (base, slope) = along(k);
                    if let Ok(out) = <&mut [f32; LANES]>::try_from(&mut plane[x0..end]) {
                        for (o, f) in out.iter_mut().zip(frac) {
                            *o = base + f * slope;
                        }
                    }
                }
            } else {
                let frac = &self.frac_x[x0..end];
                for (k, plane) in row.planes.iter_mut().enumerate() {
                    let (base, slope) = along(k);
                    for (o, f) in plane[x0..end].iter_mut().zip(frac) {
                        *o = base + f * slope;
                    }
                }
            }
            if let Some(segments) = segments.as_deref_mut() {
                segments.push(Segment {
                    x0,
                    end,
                    blend: None,
                });
            }
        }
    }
}

/// A run of a row's pixels: a whole cell of the widest step with its blend per quantity
/// (`base + frac·slope`, `frac = s / 8`), or pixels whose polynomials are in the row's scratch.
#[derive(Debug, Clone, Copy)]
pub(super) struct Segment {
    pub x0: usize,
    pub end: usize,
    pub blend: Option<([f32; QUANTITIES], [f32; QUANTITIES])>,
}

/// Pixels of a whole cell of the widest step, evaluated as one vector.
pub(super) const SEGMENT_LANES: usize = LANES;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::super::distortion_fit::TERMS;
    use super::*;

    /// Samples at the Chebyshev nodes of `t` of a ray centred on `x_mid` with half span 40 px.
    fn samples(x_mid: f64, offset: impl Fn(f64) -> f64) -> RaySamples {
        let t = |j: usize| ((2 * j + 1) as f64 * std::f64::consts::PI / (2 * TERMS) as f64).cos();
        let scale = 1.0 / t(0);
        RaySamples {
            shown: std::array::from_fn(|j| x_mid + 40.0 * scale * t(j)),
            offset: std::array::from_fn(|j| offset(scale * t(j))),
            on_projector: [true; TERMS],
        }
    }

    /// The offset of pixel `(u, v)` at `t`: bilinear in the pixel at each depth (each `t`).
    fn bilinear_offset(u: usize, v: usize, t: f64) -> f64 {
        0.5 + 0.01 * u as f64 - 0.02 * v as f64 + 1e-4 * (u * v) as f64 + 0.25 * t * t
    }

    fn bilinear_grid(width: usize, height: usize) -> FitGrid {
        FitGrid::new(width, height, 8, |u, v| {
            Some(samples((3 * u + v) as f64, |t| bilinear_offset(u, v, t)))
        })
    }

    #[test]
    fn the_grid_reproduces_a_bilinear_offset_at_every_pixel() {
        // 8-pixel cells and a last, narrower one in both directions.
        let (width, height) = (45, 21);
        let grid = bilinear_grid(width, height);
        assert_eq!(grid.cells_kept_per_pixel(), (0, 6 * 3));
        let mut row = RowFit::new(width);
        for y in 0..height {
            grid.expand_row(y, &mut row);
            for x in 0..width {
                for t in [-1.0, -0.3, 0.0, 0.8] {
                    let shown = (3 * x + y) as f64 + 40.0 * t;
                    let truth = bilinear_offset(x, y, t);
                    let got = row.offset(x, shown);
                    assert!(
                        (got - truth).abs() < 1e-4,
                        "({x}, {y}, {t}): {got} against {truth}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_cell_the_blend_does_not_fit_keeps_its_pixels_own_polynomials() {
        // One pixel's offset is 0.01 px off the bilinear field: a hundred times the tolerance.
        let odd = (19, 10);
        let offset = |u, v, t| bilinear_offset(u, v, t) + if (u, v) == odd { 0.01 } else { 0.0 };
        let grid = FitGrid::new(45, 21, 8, |u, v| {
            Some(samples((3 * u + v) as f64, |t| offset(u, v, t)))
        });
        assert_eq!(grid.cells_kept_per_pixel(), (1, 18));
        let mut row = RowFit::new(45);
        for y in 0..21 {
            grid.expand_row(y, &mut row);
            for x in 0..45 {
                for t in [-1.0, 0.4] {
                    let (got, truth) = (
                        row.offset(x, (3 * x + y) as f64 + 40.0 * t),
                        offset(x, y, t),
                    );
                    assert!(
                        (got - truth).abs() < 1e-4,
                        "({x}, {y}, {t}): {got} against {truth}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_pixel_without_samples_alone_takes_the_exact_path() {
        let grid = FitGrid::new(40, 20, 8, |u, v| {
            ((u, v) != (16, 8)).then(|| samples(100.0, |_| 0.0))
        });
        // The four cells around the missing node keep their pixels' own polynomials.
        assert_eq!(grid.cells_kept_per_pixel(), (4, 15));
        let mut row = RowFit::new(40);
        for y in 0..20 {
            grid.expand_row(y, &mut row);
            let missing: Vec<usize> = (0..40).filter(|&x| row.missing(x)).collect();
            assert_eq!(missing, if y == 8 { vec![16] } else { vec![] }, "row {y}");
        }
    }

    #[test]
    fn a_one_pixel_image_has_one_cell() {
        let grid = bilinear_grid(1, 1);
        let mut row = RowFit::new(1);
        grid.expand_row(0, &mut row);
        assert!((row.offset(0, 0.0) - 0.5).abs() < 1e-6);
    }
}
