//! Per-pixel image formation of the virtual rig (rows in parallel, deterministic noise).

use super::noise::normal_pair;
use super::scene::{Material, PosedScene, SKIN_ALBEDO};
use super::truth::{surface, GroundTruth};
use super::VirtualRig;
use crate::pattern::PatternEntry;
use nalgebra::Vector3;
use rayon::prelude::*;

type V3 = Vector3<f64>;

pub(crate) struct Context<'a> {
    pub rig: &'a VirtualRig,
    pub posed: &'a PosedScene,
    pub entry: PatternEntry,
    pub noise_frame: u64,
    pub projector_centre: V3,
}

/// What one camera pixel sees.
struct Sample {
    rgb: [u8; 3],
    depth_mm: f32,
    coordinate_px: f32,
    surface: u8,
}

pub(crate) fn render_rows(
    ctx: &Context<'_>,
    rays: &[[f32; 3]],
    data: &mut [u8],
    truth: Option<&mut GroundTruth>,
) {
    let w = ctx.rig.width();
    match truth {
        Some(t) => {
            data.par_chunks_mut(w * 3)
                .zip(t.depth_mm.par_chunks_mut(w))
                .zip(t.coordinate_px.par_chunks_mut(w))
                .zip(t.surface.par_chunks_mut(w))
                .enumerate()
                .for_each(|(y, (((row, depth), coord), surf))| {
                    for x in 0..w {
                        let s = shade_pixel(ctx, rays, y * w + x);
                        row[x * 3..x * 3 + 3].copy_from_slice(&s.rgb);
                        depth[x] = s.depth_mm;
                        coord[x] = s.coordinate_px;
                        surf[x] = s.surface;
                    }
                });
        }
        None => {
            data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
                for x in 0..w {
                    let s = shade_pixel(ctx, rays, y * w + x);
                    row[x * 3..x * 3 + 3].copy_from_slice(&s.rgb);
                }
            });
        }
    }
}

fn shade_pixel(ctx: &Context<'_>, rays: &[[f32; 3]], pixel: usize) -> Sample {
    let cfg = &ctx.rig.config;
    let seq = &ctx.rig.sequence;
    let r = rays[pixel];
    let dir = V3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]));
    let origin = V3::zeros();
    let mut sample = Sample {
        rgb: [0; 3],
        depth_mm: f32::NAN,
        coordinate_px: f32::NAN,
        surface: surface::NONE,
    };
    // Projected light per projector channel reaching the camera (before cross-talk), and albedo.
    let mut projected = [0.0f64; 3];
    let mut albedo = [0.0f64; 3];
    if let Some(hit) = ctx.posed.intersect(&origin, &dir) {
        let point = dir * hit.distance_mm;
        let normal = if hit.normal.dot(&dir) > 0.0 {
            -hit.normal
        } else {
            hit.normal
        };
        sample.depth_mm = point.z as f32;
        let skin = hit.material == Material::Skin;
        sample.surface = if skin { surface::SKIN } else { surface::TABLE };
        albedo = if skin {
            SKIN_ALBEDO
        } else {
            ctx.posed.table_albedo(&point)
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
            let shadowed = ctx
                .posed
                .hand_occludes(&(point + normal * 1e-3), &light_dir, distance);
            if !shadowed {
                let x = seq.axis.coordinate(u, v);
                sample.coordinate_px = x as f32;
                let falloff = (cfg.reference_distance_mm / distance).powi(2);
                let shade = lambert * falloff * cfg.projector_gain_gray;
                let codes = ctx.entry.codes();
                for (i, p) in projected.iter_mut().enumerate() {
                    // Gray entries drive all three projector channels with the same code.
                    let code = codes[i.min(codes.len() - 1)];
                    let mut level = seq.intensity(code, x);
                    if skin {
                        // A Gaussian blur of σ px scales a sinusoid of frequency f by
                        // exp(−(fσ)²/2) and keeps its phase.
                        let f = seq.frequency(code.m) * cfg.subsurface_sigma_px;
                        level = 0.5 + (level - 0.5) * (-0.5 * f * f).exp();
                    }
                    *p = shade * level * albedo[i];
                }
            }
        }
    }
    let camera = cfg.cross_talk.a * V3::from(projected) + cfg.cross_talk.b_gray;
    let (n0, n1) = normal_pair(cfg.seed, ctx.noise_frame, pixel as u64, 0);
    let (n2, _) = normal_pair(cfg.seed, ctx.noise_frame, pixel as u64, 1);
    let noise = [n0, n1, n2];
    for j in 0..3 {
        let signal = camera[j] + cfg.ambient_gray * albedo[j];
        let value = signal + cfg.noise.sigma_at(signal) * noise[j];
        sample.rgb[j] = value.round().clamp(0.0, 255.0) as u8;
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
    }
}
