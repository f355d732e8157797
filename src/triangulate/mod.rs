//! Triangulation: decoded projector coordinates to an organised, coloured point cloud.
//!
//! A decoded coordinate `x` along the coded [`Axis`] selects a set of projector pixels: a column
//! `u = x`, a row `v = x`, or a diagonal `u + v = √2·x`. Without projector distortion that set,
//! with the projector centre, spans a plane; in the projector frame it is `a·Q = 0` with
//!
//! ```text
//! columns:  a = (fx, 0, cx − x)      rows:  a = (0, fy, cy − x)
//! diagonal: a = (fx, fy, cx + cy − √2·x)
//! ```
//!
//! A camera pixel's undistorted ray `d` gives `point_in_camera = s·d` and
//! `point_in_projector = s·R·d + t`, so `s = −(a·t) / (a·(R·d))`.
//!
//! Projector distortion bends the coded set slightly. The exact path ([`Triangulator::point`])
//! starts from the plane solution and takes Newton steps along the ray on the coordinate the
//! real (distorted) projector shows, `x(s) − x = 0`, to 10⁻⁹ px in two or three iterations. The
//! per-frame path ([`Triangulator::triangulate`]) uses tables precomputed once per calibration
//! ([`fast`]): each pixel's ray, and distortion polynomials on a grid of pixels
//! ([`fit_grid`]), interpolated between its nodes; then a ratio of two affine functions and a
//! scale.

use crate::decode::DecodeOutput;
use crate::geometry::{GeometryError, LensModel, Pose};
use crate::pattern::Axis;
use nalgebra::Vector3;
use rayon::prelude::*;

mod distortion_fit;
mod fast;
mod fit_grid;

pub use distortion_fit::{FIT_DEGREE, FIT_DEPTH_RANGE_MM};
pub use fit_grid::{grid_pays, node_step_px, GRID_TOLERANCE_PX};

/// Errors of triangulation.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TriangulateError {
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    #[error("decoded map is {got_width}×{got_height}, the camera calibration is {width}×{height}")]
    SizeMismatch {
        width: usize,
        height: usize,
        got_width: usize,
        got_height: usize,
    },
}

/// The calibrated projector–camera pair and the coded axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoModel {
    pub camera: LensModel,
    pub projector: LensModel,
    pub projector_from_camera: Pose,
    pub axis: Axis,
}

/// An organised point cloud: one slot per camera pixel, NaN where nothing was measured.
#[derive(Debug, Clone, Default)]
pub struct PointCloud {
    pub width: usize,
    pub height: usize,
    /// Time of the decoded window, seconds.
    pub time_s: f64,
    pub point_in_camera_mm: Vec<[f32; 3]>,
    /// Scene colour from the decoded offset image (gray repeated for gray sequences).
    pub colour_rgb: Vec<[u8; 3]>,
    /// Confidence: the smallest fringe amplitude of the pixel, in the decoder's intensity units.
    /// The coordinate noise is inversely proportional to it; 0 where invalid.
    pub fringe_amplitude: Vec<f32>,
}

impl PointCloud {
    /// Number of slots holding a point.
    pub fn valid_count(&self) -> usize {
        self.point_in_camera_mm
            .iter()
            .filter(|p| p[2].is_finite())
            .count()
    }
}

/// Per-pixel constants of one calibration.
#[derive(Debug, Clone)]
pub struct Triangulator {
    pub model: StereoModel,
    table: fast::FastTable,
}

impl Triangulator {
    /// Precomputes the rays of every camera pixel, the plane constants and the distortion
    /// polynomials on the fit grid.
    pub fn new(model: StereoModel) -> Result<Self, TriangulateError> {
        let cam = model.camera;
        if cam.width == 0 || cam.height == 0 {
            return Err(GeometryError::EmptySize {
                width: cam.width,
                height: cam.height,
            }
            .into());
        }
        let rays = (0..cam.width * cam.height)
            .into_par_iter()
            .map(|i| cam.ray((i % cam.width) as f64, (i / cam.width) as f64))
            .collect::<Result<Vec<_>, GeometryError>>()?;
        let grid_step = fit_grid::grid_pays(cam.width).then(|| node_step_px(cam.width));
        let table = fast::FastTable::new(&model, &rays, grid_step);
        Ok(Self { model, table })
    }

    /// [`Triangulator::new`] with the distortion polynomials on a grid of `step` pixels
    /// whatever the image's size (the tests' and the benchmarks' comparison; the default takes
    /// the grid from 1800 px wide, [`grid_pays`]).
    pub fn with_distortion_grid(model: StereoModel, step: usize) -> Result<Self, TriangulateError> {
        let mut triangulator = Self::new(model)?;
        let rays: Vec<Vector3<f64>> = (0..triangulator.table.ray_x.len())
            .map(|p| {
                let (x, y) = (triangulator.table.ray_x[p], triangulator.table.ray_y[p]);
                Vector3::new(f64::from(x), f64::from(y), 1.0)
            })
            .collect();
        triangulator.table = fast::FastTable::new(&model, &rays, Some(step));
        Ok(triangulator)
    }

    /// Heap bytes of the tables (the per-pixel rays and the fit grid).
    pub fn memory_bytes(&self) -> usize {
        self.table.memory_bytes()
    }

    /// Cells of the distortion grid that keep their pixels' own polynomials (the blend of their
    /// corners missed a pixel's samples by more than [`GRID_TOLERANCE_PX`]), and all cells;
    /// `None` where the polynomials are per pixel.
    pub fn distortion_cells_kept_per_pixel(&self) -> Option<(usize, usize)> {
        match &self.table.polynomials {
            fast::Polynomials::Grid(grid) => Some(grid.cells_kept_per_pixel()),
            fast::Polynomials::PerPixel(_) => None,
        }
    }

    /// The plane normal `a` (projector frame) of coded coordinate `x` in the undistorted model.
    #[inline]
    fn plane(&self, x: f64) -> Vector3<f64> {
        let (n0, n1) = fast::plane_basis(self.model.axis, &self.model.projector);
        n0 + n1 * x
    }

    /// Coded coordinate the real (distorted) projector shows at a projector-frame point.
    #[inline]
    fn shown_coordinate(&self, point_in_projector: &Vector3<f64>) -> Option<f64> {
        let (u, v) = self.model.projector.project(point_in_projector)?;
        Some(self.model.axis.coordinate(u, v))
    }

    /// The camera-frame point of pixel `pixel` seen at coded coordinate `x`, or `None` when the
    /// ray and the coded surface do not meet in front of both devices. Exact (Newton on the
    /// distorted projector); [`Triangulator::triangulate`] uses the faster precomputed path.
    pub fn point(&self, pixel: usize, x: f64) -> Option<Vector3<f64>> {
        let d = Vector3::new(
            f64::from(*self.table.ray_x.get(pixel)?),
            f64::from(*self.table.ray_y.get(pixel)?),
            1.0,
        );
        let e = self.model.projector_from_camera.rotation * d;
        let t = self.model.projector_from_camera.translation_mm;
        let a = self.plane(x);
        let denom = a.dot(&e);
        if denom.abs() < 1e-12 {
            return None;
        }
        let mut s = -a.dot(&t) / denom;
        // Newton on the real (distorted) coordinate along the ray, from the plane solution.
        let residual = |s: f64| self.shown_coordinate(&(e * s + t)).map(|shown| shown - x);
        for _ in 0..6 {
            // Also refuses NaN.
            if s.is_nan() || s <= 0.0 {
                return None;
            }
            let r0 = residual(s)?;
            if r0.abs() < 1e-9 {
                break;
            }
            let h = 1e-6 * s;
            let slope = (residual(s + h)? - r0) / h;
            if slope.abs() < 1e-15 {
                return None;
            }
            s -= r0 / slope;
        }
        (s > 0.0).then(|| d * s)
    }

    /// Triangulates every valid pixel of `decoded` into `cloud` (resized as needed), with the
    /// precomputed tables of [`fast`]: within 10⁻³ mm of [`Triangulator::point`] (tested).
    pub fn triangulate(
        &self,
        decoded: &DecodeOutput,
        cloud: &mut PointCloud,
    ) -> Result<(), TriangulateError> {
        let (w, h) = (self.model.camera.width, self.model.camera.height);
        if decoded.width != w || decoded.height != h {
            return Err(TriangulateError::SizeMismatch {
                width: w,
                height: h,
                got_width: decoded.width,
                got_height: decoded.height,
            });
        }
        let n = w * h;
        cloud.width = w;
        cloud.height = h;
        cloud.time_s = decoded.time_s;
        cloud.point_in_camera_mm.resize(n, [f32::NAN; 3]);
        cloud.colour_rgb.resize(n, [0; 3]);
        cloud.fringe_amplitude.resize(n, 0.0);
        let (nf, nc) = (decoded.frequencies, decoded.channels);
        cloud
            .point_in_camera_mm
            .par_chunks_mut(w)
            .zip(cloud.colour_rgb.par_chunks_mut(w))
            .zip(cloud.fringe_amplitude.par_chunks_mut(w))
            .zip(decoded.coordinate_px.par_chunks(w))
            .zip(decoded.amplitude.par_chunks(w * nf))
            .zip(decoded.colour.par_chunks(w * nc))
            .enumerate()
            .for_each_init(
                || fast::RowScratch::new(&self.table, w),
                |scratch, (y, (((((points, colours), amplitudes), coordinate), amplitude), colour))| {
                    let input = fast::DecodedRow {
                        coordinate,
                        amplitude,
                        frequencies: nf,
                        colour,
                        channels: nc,
                    };
                    let out = fast::CloudRow {
                        points,
                        colours,
                        amplitudes,
                    };
                    fast::triangulate_row(&self.table, y, &input, scratch, out);
                    // Rays whose distortion fit is missing (they leave the projector's
                    // image somewhere in the working volume) take the exact path.
                    for x in 0..w {
                        let c = coordinate[x];
                        if c.is_finite() && self.table.fit_missing(y, x, scratch) {
                            if let Some(q) = self.point(y * w + x, f64::from(c)) {
                                points[x] = [q.x as f32, q.y as f32, q.z as f32];
                                amplitudes[x] = (0..nf)
                                    .map(|f| amplitude[f * w + x])
                                    .fold(f32::INFINITY, f32::min);
                            }
                        }
                    }
                },
            );
        Ok(())
    }
}
