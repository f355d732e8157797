//! Per-pixel image formation of the virtual rig (rows in parallel, deterministic noise): shade
//! each pixel's ray into a linear image, blur it with the lens ([`optics`]), add the sensor's
//! noise and quantise.

use super::noise::normal_pair;
use super::optics;
use super::scene::{Material, PosedScene};
use super::truth::{surface, GroundTruth};
use super::VirtualRig;
use crate::pattern::PatternEntry;
use nalgebra::Vector3;
use rayon::prelude::*;

type V3 = Vector3<f64>;

pub(crate) struct Context<'a> {
    pub rig: &'a VirtualRig,
    pub posed: &'a PosedScene,
    pub noise_frame: u64,
    pub projector_centre: V3,
    /// Per projector channel (R, G, B): frequency (rad/px), shift (rad) and the AC attenuation of
    /// skin's subsurface blur. Gray entries drive all three channels with the same code.
    pub channels: [ChannelPlan; 3],
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct ChannelPlan {
    frequency: f64,
    shift_rad: f64,
    skin_attenuation: f64,
    /// A constant level in `[0, 1]` instead of a fringe (colour calibration patterns).
    flat: Option<f64>,
}

/// What the projector shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// An entry of the rig's pattern sequence.
    Pattern(PatternEntry),
    /// A constant colour, 8-bit levels per projector channel (paper Table 1).
    Flat([u8; 3]),
}

impl<'a> Context<'a> {
    pub fn new(
        rig: &'a VirtualRig,
        posed: &'a PosedScene,
        projection: Projection,
        noise_frame: u64,
        projector_centre: V3,
    ) -> Self {
        let channels = std::array::from_fn(|i| match projection {
            Projection::Pattern(entry) => {
                let codes = entry.codes();
                let code = codes[i.min(codes.len() - 1)];
                let frequency = rig.sequence.frequency(code.m);
                // A Gaussian blur of σ px scales a sinusoid of frequency f by exp(−(fσ)²/2) and
                // keeps its phase.
                let fs = frequency * rig.config.subsurface_sigma_px;
                ChannelPlan {
                    frequency,
                    shift_rad: code.shift_rad,
                    skin_attenuation: (-0.5 * fs * fs).exp(),
                    flat: None,
                }
            }
            Projection::Flat(levels) => ChannelPlan {
                frequency: 0.0,
                shift_rad: 0.0,
                // A constant has no fringe to blur.
                skin_attenuation: 1.0,
                flat: Some(f64::from(levels[i]) / 255.0),
            },
        });
        Self {
            rig,
            posed,
            noise_frame,
            projector_centre,
            channels,
        }
    }
}

/// The projected level in `[0, 1]` of `plan` at coordinate `x`, quantised to `levels` steps. The
/// phase (hundreds of radians) is reduced to `(−2π, 2π)` in f64, by truncation rather than a
/// libm `fmod`, and its cosine taken in f32.
#[inline]
fn projected_level(plan: &ChannelPlan, x: f64, levels: f64) -> f64 {
    use std::f64::consts::TAU;
    if let Some(flat) = plan.flat {
        return (flat * levels + 0.5) as u32 as f64 / levels;
    }
    let phase = plan.frequency * x + plan.shift_rad;
    let phase = phase - TAU * ((phase * (1.0 / TAU)) as i64 as f64);
    let ideal = 0.5 + 0.5 * f64::from((phase as f32).cos());
    // Round half up by truncation: the value is never negative.
    (ideal * levels + 0.5) as u32 as f64 / levels
}

/// What one camera pixel's ray sees.
struct Sample {
    /// The linear signal per camera channel, gray levels, before blur and noise.
    signal: [f32; 3],
    depth_mm: f32,
    coordinate_px: f32,
    surface: u8,
}

thread_local! {
    /// The linear image and the blur's scratch, kept between the frames one thread renders (a
    /// live rig renders every frame on its capture thread): 55 MB at 1920×1200, not worth
    /// allocating and faulting in again per frame.
    static LINEAR_IMAGE: std::cell::RefCell<(Vec<f32>, Vec<f32>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// Shades every pixel into the linear image, blurs it with the camera's PSF, then adds the
/// sensor's noise and quantises into `data`.
pub(crate) fn render_rows(
    ctx: &Context<'_>,
    rays: &[[f32; 3]],
    data: &mut [u8],
    truth: Option<&mut GroundTruth>,
) {
    let (mut signal, mut scratch) = LINEAR_IMAGE.with_borrow_mut(std::mem::take);
    render_linear(ctx, rays, data, truth, &mut signal, &mut scratch);
    LINEAR_IMAGE.with_borrow_mut(|kept| *kept = (signal, scratch));
}

/// [`render_rows`] with its buffers.
fn render_linear(
    ctx: &Context<'_>,
    rays: &[[f32; 3]],
    data: &mut [u8],
    truth: Option<&mut GroundTruth>,
    signal: &mut Vec<f32>,
    scratch: &mut Vec<f32>,
) {
    let (w, h) = (ctx.rig.width(), ctx.rig.height());
    // Every value is written below: only the length matters.
    signal.resize(w * h * 3, 0.0);
    match truth {
        Some(t) => {
            signal
                .par_chunks_mut(w * 3)
                .zip(t.depth_mm.par_chunks_mut(w))
                .zip(t.coordinate_px.par_chunks_mut(w))
                .zip(t.surface.par_chunks_mut(w))
                .enumerate()
                .for_each(|(y, (((row, depth), coord), surf))| {
                    for x in 0..w {
                        let s = shade_pixel(ctx, rays, y * w + x);
                        row[x * 3..x * 3 + 3].copy_from_slice(&s.signal);
                        depth[x] = s.depth_mm;
                        coord[x] = s.coordinate_px;
                        surf[x] = s.surface;
                    }
                });
        }
        None => {
            signal
                .par_chunks_mut(w * 3)
                .enumerate()
                .for_each(|(y, row)| {
                    for x in 0..w {
                        let s = shade_pixel(ctx, rays, y * w + x);
                        row[x * 3..x * 3 + 3].copy_from_slice(&s.signal);
                    }
                });
        }
    }
    if let Some(kernel) = optics::kernel(ctx.rig.config.camera_psf_sigma_px) {
        optics::blur(signal, w, h, 3, &kernel, scratch);
    }
    let cfg = &ctx.rig.config;
    data.par_chunks_mut(w * 3)
        .zip(signal.par_chunks(w * 3))
        .enumerate()
        .for_each(|(y, (out, row))| {
            for x in 0..w {
                let pixel = (y * w + x) as u64;
                let (n0, n1) = normal_pair(cfg.seed, ctx.noise_frame, pixel, 0);
                let (n2, _) = normal_pair(cfg.seed, ctx.noise_frame, pixel, 1);
                for (j, n) in [n0, n1, n2].into_iter().enumerate() {
                    let signal = f64::from(row[x * 3 + j]);
                    let value = signal + cfg.noise.sigma_at(signal) * f64::from(n);
                    // Round half up by truncation after clamping to the sensor's range.
                    out[x * 3 + j] = (value.clamp(0.0, 255.0) + 0.5) as u8;
                }
            }
        });
}

/// Area-averaged board albedo at `pixel`, its footprint taken from the neighbouring rays (the
/// previous ones, mirrored, on the last row and column).
fn board_albedo(ctx: &Context<'_>, rays: &[[f32; 3]], pixel: usize, dir: &V3) -> [f64; 3] {
    let (w, h) = (ctx.rig.width(), ctx.rig.height());
    let (x, y) = (pixel % w, pixel / w);
    let ray = |p: usize| {
        let r = rays[p];
        V3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]))
    };
    let step_u = if x + 1 < w {
        ray(pixel + 1)
    } else {
        dir * 2.0 - ray(pixel - 1)
    };
    let step_v = if y + 1 < h {
        ray(pixel + w)
    } else {
        dir * 2.0 - ray(pixel - w)
    };
    ctx.posed.board_albedo_over_pixel(dir, &step_u, &step_v)
}

fn shade_pixel(ctx: &Context<'_>, rays: &[[f32; 3]], pixel: usize) -> Sample {
    let cfg = &ctx.rig.config;
    let seq = &ctx.rig.sequence;
    let r = rays[pixel];
    let dir = V3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]));
    let origin = V3::zeros();
    let mut sample = Sample {
        signal: [0.0; 3],
        depth_mm: f32::NAN,
        coordinate_px: f32::NAN,
        surface: surface::NONE,
    };
    // Projected light per projector channel reaching the camera (before cross-talk), and albedo.
    let mut projected = [0.0f64; 3];
    let mut albedo = [0.0f64; 3];
    let w = ctx.rig.width();
    let pixel_uv = ((pixel % w) as f64, (pixel / w) as f64);
    if let Some(hit) = ctx.posed.intersect(&origin, &dir, pixel_uv) {
        let point = dir * hit.distance_mm;
        let normal = if hit.normal.dot(&dir) > 0.0 {
            -hit.normal
        } else {
            hit.normal
        };
        sample.depth_mm = point.z as f32;
        let skin = hit.material == Material::Skin;
        (sample.surface, albedo) = match hit.material {
            Material::Skin => (surface::SKIN, ctx.posed.skin_albedo(&hit)),
            Material::Table => (surface::TABLE, ctx.posed.table_albedo(&point)),
            Material::Board => (surface::BOARD, board_albedo(ctx, rays, pixel, &dir)),
        };
        let to_projector = ctx.projector_centre - point;
        let distance = to_projector.norm();
        let light_dir = to_projector / distance;
        let lambert = normal.dot(&light_dir);
        let point_in_projector = cfg.projector_from_camera.transform(&point);
        let lit_pixel = cfg
            .projector
            .project(&point_in_projector)
            .filter(|&(u, v)| cfg.projector.contains(u, v));
        if let (Some((u, v)), true) = (lit_pixel, lambert > 0.0) {
            let shadowed =
                ctx.posed
                    .occludes(&(point + normal * 1e-3), &light_dir, distance, (u, v));
            if !shadowed {
                let x = seq.axis.coordinate(u, v);
                sample.coordinate_px = x as f32;
                let falloff = (cfg.reference_distance_mm / distance).powi(2);
                let shade = lambert * falloff * cfg.projector_gain_gray;
                let levels = f64::from((1u32 << seq.projector_bits) - 1);
                for (i, p) in projected.iter_mut().enumerate() {
                    let plan = &ctx.channels[i];
                    let mut level = projected_level(plan, x, levels);
                    if skin {
                        level = 0.5 + (level - 0.5) * plan.skin_attenuation;
                    }
                    *p = shade * level * albedo[i];
                }
            }
        }
    }
    let camera = cfg.cross_talk.a * V3::from(projected) + cfg.cross_talk.b_gray;
    for j in 0..3 {
        sample.signal[j] = (camera[j] + cfg.ambient_gray * albedo[j]) as f32;
    }
    sample
}

#[cfg(test)]
mod tests {
    use crate::rig::{GroundTruth, RigConfig, SceneConfig, VirtualRig};

    #[test]
    fn renders_deterministically_with_truth() {
        let config = RigConfig::paper(160, 100).unwrap();
        let seq = config.default_sequence().unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        let mut a = rig.blank_frame();
        let mut b = rig.blank_frame();
        let mut truth = GroundTruth::default();
        rig.render(4, &mut a, Some(&mut truth)).unwrap();
        rig.render(4, &mut b, None).unwrap();
        assert_eq!(a.data, b.data);
        assert_eq!(a.pattern_index, 1);
        let skin = truth
            .surface
            .iter()
            .filter(|&&s| s == super::surface::SKIN)
            .count();
        assert!(skin > 1000, "hand covers {skin} px");
        assert!(truth.depth_mm.iter().all(|d| d.is_finite()));
        let lit = truth.coordinate_px.iter().filter(|c| c.is_finite()).count();
        assert!(lit > 14_000, "{lit} px lit");
        assert_eq!(truth.points_in_camera.len(), crate::rig::POINT_NAMES.len());
    }

    #[test]
    fn plane_depth_matches_the_table() {
        let mut config = RigConfig::paper(64, 40).unwrap();
        config.scene = SceneConfig::plane();
        let seq = config.default_sequence().unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        let mut frame = rig.blank_frame();
        let mut truth = GroundTruth::default();
        rig.render(0, &mut frame, Some(&mut truth)).unwrap();
        assert!(truth.depth_mm.iter().all(|&d| (d - 500.0).abs() < 1e-3));
        assert!(rig
            .render(0, &mut crate::frame::Frame::new(3, 3, 3).unwrap(), None)
            .is_err());
        let mut empty = rig.config.clone();
        empty.camera.width = 0;
        assert!(VirtualRig::new(empty, rig.sequence.clone()).is_err());
    }

    #[test]
    fn rendered_noise_matches_the_noise_model() {
        // Two noise draws of the same still image differ by noise only: E[(a − b)²] = 2σ² plus
        // twice the 8-bit rounding variance 1/12, with σ² = read² + k·signal per pixel.
        let mut config = RigConfig::paper(320, 200).unwrap();
        config.scene = SceneConfig::plane();
        let seq = config.default_sequence().unwrap();
        let noisy = VirtualRig::new(config.clone(), seq.clone()).unwrap();
        config.noise = crate::rig::NoiseModel::none();
        let clean = VirtualRig::new(config, seq).unwrap();
        let (mut a, mut b, mut c) = (
            noisy.blank_frame(),
            noisy.blank_frame(),
            clean.blank_frame(),
        );
        noisy.render_pattern(1, 0, 0.0, &mut a, None).unwrap();
        noisy.render_pattern(2, 0, 0.0, &mut b, None).unwrap();
        clean.render_pattern(1, 0, 0.0, &mut c, None).unwrap();
        let model = noisy.config.noise;
        let (mut measured, mut predicted) = (0.0, 0.0);
        for ((&va, &vb), &signal) in a.data.iter().zip(&b.data).zip(&c.data) {
            // Stay clear of clipping at 0 and 255, where the model no longer holds.
            if !(20..=235).contains(&signal) {
                continue;
            }
            let d = f64::from(va) - f64::from(vb);
            measured += d * d;
            predicted += 2.0 * model.sigma_at(f64::from(signal)).powi(2) + 2.0 / 12.0;
        }
        let ratio = measured / predicted;
        // About 190,000 samples: the ratio's standard error is about √(2/190000) ≈ 0.3 %.
        assert!(
            (ratio - 1.0).abs() < 0.03,
            "measured / predicted variance = {ratio}"
        );
    }

    #[test]
    fn the_rig_projects_what_the_encoder_renders() {
        // At projector pixel centres the rig's projected level must equal the 8-bit pattern
        // image the encoder renders for the projector (6-bit level k shown as round(255·k/63)).
        use crate::pattern::{cps_rgb, render_pattern, Axis};
        let config = RigConfig::paper(64, 40).unwrap();
        for (axis, n, x_max) in [(Axis::Columns, 65, 912.0), (Axis::Diagonal, 107, 1481.0)] {
            let seq = cps_rgb(n, x_max, axis, 6).unwrap();
            let rig = VirtualRig::new(config.clone(), seq.clone()).unwrap();
            let levels = 63.0;
            for index in 0..3 {
                let image = render_pattern(&seq, index, 912, 1140).unwrap();
                let posed = rig.scene.at(0.0);
                let ctx = super::Context::new(
                    &rig,
                    &posed,
                    super::Projection::Pattern(seq.entries[index]),
                    0,
                    super::V3::zeros(),
                );
                for &(u, v) in &[
                    (0usize, 0usize),
                    (17, 3),
                    (455, 570),
                    (911, 1139),
                    (300, 901),
                ] {
                    let x = axis.coordinate(u as f64, v as f64);
                    for c in 0..3 {
                        let rig_level = super::projected_level(&ctx.channels[c], x, levels);
                        let encoded = f64::from(image.data[(v * 912 + u) * 3 + c]) / 255.0;
                        assert!(
                            (rig_level - encoded).abs() < 0.5 / 255.0,
                            "{axis:?} image {index} ({u},{v}) channel {c}: {rig_level} vs {encoded}"
                        );
                    }
                }
            }
        }
    }
}
