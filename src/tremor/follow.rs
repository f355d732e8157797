//! Following a patch of skin from window to window, so that a control point measures one
//! material point of the hand rather than whatever skin passes a fixed camera pixel.
//!
//! *The image followed* is the skin's texture with its shading taken out ([`TextureImage`],
//! `tremor::texture`): what remains is the albedo's fine pattern, which the skin carries with
//! it.
//!
//! When a point is placed, the square patch around it (17×17 px) becomes its *template*, kept
//! for good: every later window is matched against that first appearance, so the track does
//! not drift, however long it runs. Each window:
//! 1. *Predict*: the last position moved on by the last step (constant velocity).
//! 2. *Search*: normalised cross-correlation (NCC) of the template at whole-pixel offsets around
//!    the prediction: ±3 px while tracking, ±24 px while the point is lost, which is how it
//!    re-acquires. While tracking, the template is first blurred as the window blurs moving
//!    skin: the offset image is the mean of three frames, so skin moving `s` px a frame shows
//!    its texture as the mean of the texture shifted by −s, 0 and +s, and so does the template
//!    (sampled from the first patch kept 3 px wider). At 5.3 Hz on the rig's swaying hand this
//!    kept the index fingertip 100 % valid where the sharp template lost it in 11 % of the
//!    windows.
//! 3. *Refine*: Gauss–Newton on an affine warp with a gain and a bias (forward-additive
//!    Lucas–Kanade, Baker & Matthews, IJCV 2004), `g·T(x) + b ≈ I(t + A·x)`, to a fraction of a
//!    pixel, so the patch may shear and change scale with the hand's roll and the finger's
//!    flexion. The affine part is held gently to the template's shape (a Tikhonov term), since
//!    faint texture constrains it less than the translation; undamped, it followed the noise.
//! 4. *Accept* only a match whose NCC after refinement reaches
//!    [`FollowOptions::min_correlation`] (a lost point: the stricter
//!    [`FollowOptions::reacquire_correlation`], its search being wide), which stays within 2 px
//!    of the search's best and inside the image. Otherwise the window's sample is invalid and
//!    the point is *lost*: nothing is invented, and the next windows search for it.
//!
//! What limits it on the rig: the decoded texture's noise and what motion adds to it. Fast
//! flexion towards the side where the decode window turns singular leaves the texture's
//! gradient, modulated by the fringe, in the offset image (a pixel's window has no redundancy
//! left to tell it from texture); the low-passed image (`tremor::texture`) keeps the 10 mm
//! tremor's fingertip matched in 96 % of the windows. And lateral motion: while the skin moves
//! across a pixel inside the decode window, the three frames see different albedo, and the
//! fringe terms of the window's mean no longer cancel; what they leave in the offset image is
//! fringe-shaped, does not move with the skin, and is as strong as faint texture. Tried and not
//! kept: a quadratic brightness term in the match (it absorbed texture, not shading), the
//! fringe amplitude as the image (holes wherever the decode refused a pixel), wider shading
//! boxes and templates (they reach the finger's outline and its shadow, which do not move with
//! the skin), and (2026-12-08) the template taken again at the first slow window when it was
//! placed on moving skin.
//!
//! The 3D position is then read at the matched sub-pixel location by [`locate_subpixel`]:
//! the neighbourhood's points, outliers removed as [`super::locate`] does, fitted as an affine
//! function of the pixel offset and evaluated at the exact location.

pub use super::texture::TextureImage;
pub use super::track::locate_subpixel;
use nalgebra::{SMatrix, SVector};

/// Settings of the skin follower.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowOptions {
    /// Half size of the template, px (8 → 17×17).
    pub template_radius_px: usize,
    /// Whole-pixel search radius around the prediction while tracking, px.
    pub step_search_px: usize,
    /// Search radius around the last position while the point is lost, px.
    pub reacquire_search_px: usize,
    /// Least normalised cross-correlation of an accepted match while tracking. On the
    /// low-passed texture image a true match of the rig's fingertip correlates at 0.8–0.9
    /// where the decoded texture is clean; where the moving skin's texture is disturbed, 0.5
    /// still accepted matches 1–5 px off (the 10 mm tremor's fingertip: 2.4 mm at most from
    /// its material point, against 1.0 mm at 0.6).
    pub min_correlation: f64,
    /// Least normalised cross-correlation for a lost point to be found again.
    pub reacquire_correlation: f64,
    /// Least standard deviation of the template's texture (log luminance, so a relative
    /// brightness, after the low-pass): below it the skin there shows nothing to follow. The
    /// rig's textured fingertip shows 0.006–0.013; its untextured skin, the camera's noise
    /// alone, about 0.002.
    pub min_template_std: f64,
    /// Gauss–Newton iterations at most.
    pub iterations: usize,
}

impl Default for FollowOptions {
    fn default() -> Self {
        Self {
            template_radius_px: 8,
            step_search_px: 3,
            reacquire_search_px: 24,
            min_correlation: 0.6,
            reacquire_correlation: 0.7,
            min_template_std: 0.004,
            iterations: 20,
        }
    }
}

/// Errors of placing a point to follow.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum FollowError {
    #[error("the point {u:.1},{v:.1} is too near the image's edge to follow")]
    AtEdge { u: f64, v: f64 },
    #[error(
        "the surface around {u:.1},{v:.1} shows too little texture to follow (relative spread {std:.4}, at least {needed} needed); use a fixed pixel there"
    )]
    NoTexture {
        u: f64,
        v: f64,
        std: f64,
        needed: f64,
    },
}

/// Weight of the affine part's pull towards the template's shape, relative to the mean
/// squared gradient.
const AFFINE_DAMPING: f64 = 0.1;

/// Pixels kept around the template on each side, so that it can be blurred along the motion
/// ([`SkinFollower::blurred`]): a step of up to this many pixels per frame.
const BLUR_MARGIN_PX: usize = 3;

/// A template's values at the offsets, with their mean and standard deviation.
#[derive(Debug, Clone)]
struct Template {
    values: Vec<f64>,
    mean: f64,
    std: f64,
}

impl Template {
    fn new(values: Vec<f64>) -> Self {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let std = (values.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / n).sqrt();
        Self { values, mean, std }
    }
}

/// One point followed over the skin.
#[derive(Debug, Clone)]
pub struct SkinFollower {
    offsets: Vec<(f64, f64)>,
    template: Template,
    /// The first window's patch with [`BLUR_MARGIN_PX`] more on each side (row-major), where
    /// the image had it.
    wide: Option<Vec<f64>>,
    position: (f64, f64),
    step: (f64, f64),
    lost: bool,
    options: FollowOptions,
}

impl SkinFollower {
    /// Takes the patch around `pixel` in `image` as the template.
    pub fn new(
        image: &TextureImage,
        pixel: (f64, f64),
        options: FollowOptions,
    ) -> Result<Self, FollowError> {
        let r = options.template_radius_px as i64;
        let offsets: Vec<(f64, f64)> = (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dx as f64, dy as f64)))
            .collect();
        let template: Option<Vec<f64>> = offsets
            .iter()
            .map(|(dx, dy)| image.sample(pixel.0 + dx, pixel.1 + dy))
            .collect();
        let template = Template::new(template.ok_or(FollowError::AtEdge {
            u: pixel.0,
            v: pixel.1,
        })?);
        if template.std.is_nan() || template.std < options.min_template_std {
            return Err(FollowError::NoTexture {
                u: pixel.0,
                v: pixel.1,
                std: template.std,
                needed: options.min_template_std,
            });
        }
        let wide_r = r + BLUR_MARGIN_PX as i64;
        let wide: Option<Vec<f64>> = (-wide_r..=wide_r)
            .flat_map(|dy| (-wide_r..=wide_r).map(move |dx| (dx as f64, dy as f64)))
            .map(|(dx, dy)| image.sample(pixel.0 + dx, pixel.1 + dy))
            .collect();
        Ok(Self {
            offsets,
            template,
            wide,
            position: pixel,
            step: (0.0, 0.0),
            lost: false,
            options,
        })
    }

    /// The last matched pixel (or where the point was lost).
    pub fn pixel(&self) -> (f64, f64) {
        self.position
    }

    /// Whether the last window lost the point.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// The template as a window sees skin moving `step` px per frame: its offset image is the
    /// mean of three frames, so the texture appears as the mean of the template shifted by
    /// −step, 0 and +step (bilinear on the wider first patch; the step clamped to
    /// [`BLUR_MARGIN_PX`]). The template itself where the wider patch is missing or the step
    /// is under half a pixel.
    fn blurred(&self, step: (f64, f64)) -> Option<Template> {
        let wide = self.wide.as_ref()?;
        let limit = BLUR_MARGIN_PX as f64;
        let step = (step.0.clamp(-limit, limit), step.1.clamp(-limit, limit));
        if step.0.hypot(step.1) < 0.5 {
            return None;
        }
        let side = 2 * (self.options.template_radius_px + BLUR_MARGIN_PX) + 1;
        let centre = (self.options.template_radius_px + BLUR_MARGIN_PX) as f64;
        let at = |u: f64, v: f64| {
            let (u, v) = (u + centre, v + centre);
            let (x0, y0) = (
                (u.floor() as usize).min(side - 2),
                (v.floor() as usize).min(side - 2),
            );
            let (fx, fy) = (u - x0 as f64, v - y0 as f64);
            let i = y0 * side + x0;
            let top = wide[i] + fx * (wide[i + 1] - wide[i]);
            let bottom = wide[i + side] + fx * (wide[i + side + 1] - wide[i + side]);
            top + fy * (bottom - top)
        };
        let values = self
            .offsets
            .iter()
            .map(|x| {
                [-1.0, 0.0, 1.0]
                    .iter()
                    .map(|k| at(x.0 + k * step.0, x.1 + k * step.1))
                    .sum::<f64>()
                    / 3.0
            })
            .collect();
        Some(Template::new(values))
    }

    /// Normalised cross-correlation of `template` placed at `at`, or `None` where part of the
    /// patch leaves the image.
    fn correlation(
        &self,
        template: &Template,
        image: &TextureImage,
        at: (f64, f64),
    ) -> Option<f64> {
        let n = self.offsets.len() as f64;
        let (mut sum, mut sum_sq, mut cross) = (0.0, 0.0, 0.0);
        for (x, &t) in self.offsets.iter().zip(&template.values) {
            let i = image.sample(at.0 + x.0, at.1 + x.1)?;
            sum += i;
            sum_sq += i * i;
            cross += i * (t - template.mean);
        }
        let var = (sum_sq - sum * sum / n).max(0.0);
        (var > 0.0).then(|| cross / (var.sqrt() * template.std * n.sqrt()))
    }

    /// Finds the patch in the next window's `image`: its pixel, or `None` (lost this window).
    pub fn follow(&mut self, image: &TextureImage) -> Option<(f64, f64)> {
        let (centre, radius) = if self.lost {
            (self.position, self.options.reacquire_search_px as i64)
        } else {
            (
                (self.position.0 + self.step.0, self.position.1 + self.step.1),
                self.options.step_search_px as i64,
            )
        };
        // While tracking, the template is blurred as the window blurs the moving skin.
        let blurred = (!self.lost).then(|| self.blurred(self.step)).flatten();
        let template = blurred.as_ref().unwrap_or(&self.template);
        let mut best: Option<(f64, (f64, f64))> = None;
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let at = (centre.0 + dx as f64, centre.1 + dy as f64);
                if let Some(c) = self.correlation(template, image, at) {
                    if best.is_none_or(|(b, _)| c > b) {
                        best = Some((c, at));
                    }
                }
            }
        }
        // A lost point comes back only on a clear match: its search is wide.
        let threshold = if self.lost {
            self.options.reacquire_correlation
        } else {
            self.options.min_correlation
        };
        let accepted = best
            .filter(|(c, _)| *c >= 0.8 * threshold)
            .and_then(|(_, start)| self.refine(template, image, start))
            .filter(|&at| {
                self.correlation(template, image, at)
                    .is_some_and(|c| c >= threshold)
            });
        match accepted {
            Some(at) => {
                self.step = if self.lost {
                    (0.0, 0.0)
                } else {
                    (at.0 - self.position.0, at.1 - self.position.1)
                };
                self.position = at;
                self.lost = false;
                Some(at)
            }
            None => {
                self.lost = true;
                self.step = (0.0, 0.0);
                None
            }
        }
    }

    /// Gauss–Newton on the translation with gain and bias from `start`; `None` where the
    /// normal equations are singular, the patch leaves the image or the refinement wanders
    /// more than two pixels from the search's best.
    fn refine(
        &self,
        template: &Template,
        image: &TextureImage,
        start: (f64, f64),
    ) -> Option<(f64, f64)> {
        // Parameters: translation (2), affine (4), gain and bias.
        let mut p = SVector::<f64, 8>::zeros();
        p[6] = 1.0;
        for _ in 0..self.options.iterations {
            let mut normal = SMatrix::<f64, 8, 8>::zeros();
            let mut rhs = SVector::<f64, 8>::zeros();
            for (x, &t) in self.offsets.iter().zip(&template.values) {
                let u = start.0 + p[0] + x.0 + p[2] * x.0 + p[3] * x.1;
                let v = start.1 + p[1] + x.1 + p[4] * x.0 + p[5] * x.1;
                let i = image.sample(u, v)?;
                // Central differences over one pixel.
                let gx = image.sample(u + 0.5, v)? - image.sample(u - 0.5, v)?;
                let gy = image.sample(u, v + 0.5)? - image.sample(u, v - 0.5)?;
                let j = SVector::<f64, 8>::from([
                    gx,
                    gy,
                    gx * x.0,
                    gx * x.1,
                    gy * x.0,
                    gy * x.1,
                    -t,
                    -1.0,
                ]);
                normal += j * j.transpose();
                rhs += j * (p[6] * t + p[7] - i);
            }
            // The affine part is held gently to the template's shape (Tikhonov): faint
            // texture constrains it less than the translation.
            let damping = AFFINE_DAMPING * (normal[(0, 0)] + normal[(1, 1)]) / 2.0;
            for k in 2..6 {
                normal[(k, k)] += damping;
                rhs[k] -= damping * p[k];
            }
            let step = normal.cholesky()?.solve(&rhs);
            p += step;
            if p[0].abs() > 2.0 || p[1].abs() > 2.0 {
                return None;
            }
            if step[0].abs() < 1e-4 && step[1].abs() < 1e-4 {
                break;
            }
        }
        Some((start.0 + p[0], start.1 + p[1]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tremor::track::TrackOptions;
    use crate::triangulate::PointCloud;

    /// A smooth texture, luminance 0–765 around 300.
    fn texture(u: f64, v: f64) -> f64 {
        300.0
            + 25.0 * (0.41 * u + 0.13 * v).sin()
            + 20.0 * (0.07 * u - 0.53 * v + 1.0).sin()
            + 15.0 * (0.29 * u + 0.31 * v + 2.0).sin()
    }

    /// A cloud whose colour is `texture` seen through `map` (image pixel → texture point), on a
    /// plane at 500 mm; `covered` pixels show a flat gray (an occluder).
    fn cloud(
        map: impl Fn(f64, f64) -> (f64, f64),
        covered: impl Fn(f64, f64) -> bool,
        gain: f64,
    ) -> PointCloud {
        let (w, h) = (120, 90);
        let mut c = PointCloud {
            width: w,
            height: h,
            time_s: 0.0,
            point_in_camera_mm: vec![[0.0; 3]; w * h],
            colour_rgb: vec![[0; 3]; w * h],
            fringe_amplitude: vec![1.0; w * h],
        };
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f64, y as f64);
                let l = if covered(u, v) {
                    200.0
                } else {
                    let (tu, tv) = map(u, v);
                    gain * texture(tu, tv)
                };
                let byte = (l / 3.0).round().clamp(0.0, 255.0) as u8;
                c.colour_rgb[y * w + x] = [byte; 3];
                c.point_in_camera_mm[y * w + x] = [
                    (u as f32 - 60.0) * 0.4,
                    (v as f32 - 45.0) * 0.4,
                    500.0 + 0.1 * u as f32,
                ];
            }
        }
        c
    }

    fn texture_image(c: &PointCloud) -> TextureImage {
        let mut l = TextureImage::default();
        l.fill_from(c);
        l
    }

    #[test]
    fn follows_a_patch_that_moves_turns_and_brightens_and_reacquires_it() {
        let start = cloud(|u, v| (u, v), |_, _| false, 1.0);
        let mut f = SkinFollower::new(
            &texture_image(&start),
            (50.0, 40.0),
            FollowOptions::default(),
        )
        .expect("textured");
        // The skin moves by 1.3 px right and 0.6 px up per window and turns by 0.4° per
        // window, about the followed point: where is texture point (50, 40) now?
        let mut truth = (50.0, 40.0);
        for k in 1..=8 {
            let angle = (0.4 * k as f64).to_radians();
            truth = (50.0 + 1.3 * k as f64, 40.0 - 0.6 * k as f64);
            let (c, s) = (angle.cos(), angle.sin());
            let image = cloud(
                |u, v| {
                    let (du, dv) = (u - truth.0, v - truth.1);
                    (50.0 + c * du + s * dv, 40.0 - s * du + c * dv)
                },
                |_, _| false,
                1.0 + 0.03 * k as f64,
            );
            let got = f.follow(&texture_image(&image)).expect("followed");
            assert!(
                (got.0 - truth.0).abs() < 0.05 && (got.1 - truth.1).abs() < 0.05,
                "window {k}: {got:?} against {truth:?}"
            );
        }
        // Covered by a flat occluder: lost, no position invented.
        let hidden = cloud(
            |u, v| (u, v),
            |u, v| (u - truth.0).abs() < 15.0 && (v - truth.1).abs() < 15.0,
            1.0,
        );
        assert_eq!(f.follow(&texture_image(&hidden)), None);
        assert!(f.is_lost());
        // It reappears 9 px further on: re-acquired.
        let back = (truth.0 + 9.0, truth.1 + 4.0);
        let angle = 3.2f64.to_radians();
        let (c, s) = (angle.cos(), angle.sin());
        let image = cloud(
            |u, v| {
                let (du, dv) = (u - back.0, v - back.1);
                (50.0 + c * du + s * dv, 40.0 - s * du + c * dv)
            },
            |_, _| false,
            0.9,
        );
        let got = f.follow(&texture_image(&image)).expect("re-acquired");
        assert!(
            (got.0 - back.0).abs() < 0.05 && (got.1 - back.1).abs() < 0.05,
            "{got:?}"
        );
    }

    #[test]
    fn follows_skin_blurred_by_the_window_as_it_moves_fast() {
        // Skin moving 2.5 px a frame: each window's image is the mean of three frames, the
        // texture at −2.5, 0 and +2.5 px about the centre frame's position.
        let step = 2.5;
        let window = |centre: f64| {
            let frames: Vec<PointCloud> = [-1.0, 0.0, 1.0]
                .iter()
                .map(|k| cloud(|u, v| (u - centre - k * step, v), |_, _| false, 1.0))
                .collect();
            let mut mean = frames[1].clone();
            for (i, c) in mean.colour_rgb.iter_mut().enumerate() {
                for ch in 0..3 {
                    let sum: u32 = frames.iter().map(|f| u32::from(f.colour_rgb[i][ch])).sum();
                    c[ch] = ((sum as f64) / 3.0).round() as u8;
                }
            }
            texture_image(&mean)
        };
        let mut f = SkinFollower::new(&window(0.0), (50.0, 40.0), FollowOptions::default())
            .expect("textured");
        for k in 1..=8 {
            let centre = step * k as f64;
            let got = f.follow(&window(centre)).expect("followed");
            assert!(
                (got.0 - 50.0 - centre).abs() < 0.1 && (got.1 - 40.0).abs() < 0.1,
                "window {k}: {got:?} against {:?}",
                (50.0 + centre, 40.0)
            );
        }
        // Blurred along a whole-pixel step, each value is the mean of the first patch at the
        // offset and one pixel either side; under half a pixel there is nothing to blur.
        let blurred = f.blurred((1.0, 0.0)).expect("a step to blur along");
        let wide = f.wide.as_ref().expect("the wide patch");
        let side = 2 * (FollowOptions::default().template_radius_px + BLUR_MARGIN_PX) + 1;
        let centre = side / 2;
        for (k, &(dx, dy)) in f.offsets.iter().enumerate() {
            let i = (centre as f64 + dy) as usize * side + (centre as f64 + dx) as usize;
            let expected = (wide[i - 1] + wide[i] + wide[i + 1]) / 3.0;
            assert!(
                (blurred.values[k] - expected).abs() < 1e-9,
                "offset {dx},{dy}"
            );
        }
        assert!(f.blurred((0.2, 0.1)).is_none());
    }

    #[test]
    fn refuses_skin_without_texture_and_the_image_edge() {
        let flat = cloud(|_, _| (0.0, 0.0), |_, _| false, 1.0);
        let l = texture_image(&flat);
        assert!(matches!(
            SkinFollower::new(&l, (50.0, 40.0), FollowOptions::default()),
            Err(FollowError::NoTexture { .. })
        ));
        let textured = texture_image(&cloud(|u, v| (u, v), |_, _| false, 1.0));
        assert!(matches!(
            SkinFollower::new(&textured, (3.0, 40.0), FollowOptions::default()),
            Err(FollowError::AtEdge { .. })
        ));
    }

    #[test]
    fn the_subpixel_position_lies_on_the_surface_between_pixels() {
        let mut c = cloud(|u, v| (u, v), |_, _| false, 1.0);
        // One wild point in the neighbourhood is left out.
        c.point_in_camera_mm[41 * 120 + 51] = [0.0, 0.0, 900.0];
        let (p, slope) =
            locate_subpixel(&c, (50.3, 40.6), &TrackOptions::default()).expect("valid");
        let expected = [(50.3 - 60.0) * 0.4, (40.6 - 45.0) * 0.4, 500.0 + 0.1 * 50.3];
        // The surface's change per pixel along u and along v.
        let expected_slope = [[0.4, 0.0, 0.1], [0.0, 0.4, 0.0]];
        for a in 0..3 {
            assert!(
                (p[a] - expected[a]).abs() < 1e-3,
                "{p:?} against {expected:?}"
            );
            for d in 0..2 {
                assert!(
                    (slope[d][a] - expected_slope[d][a]).abs() < 1e-4,
                    "{slope:?} against {expected_slope:?}"
                );
            }
        }
    }
}
