//! Tests of the virtual scene: the tremor's amplitude, the rigid sway and roll, the skin
//! texture moving with the skin, what the camera sees, and that culling changes no hit.

use super::*;

#[test]
fn fingertips_tremble_at_the_set_amplitude() {
    let scene = Scene::new(SceneConfig {
        hand: Some(Tremor::flexion(5.0, 2.0, 0.0)),
        ..SceneConfig::trembling_hand()
    });
    let zs: Vec<f64> = (0..200)
        .map(|i| scene.at(i as f64 / 1000.0).points[0].z)
        .collect();
    let span =
        zs.iter().cloned().fold(f64::MIN, f64::max) - zs.iter().cloned().fold(f64::MAX, f64::min);
    // Peak-to-peak of the tracked tip point is 2·A up to the sampling of the sine (1 ms of
    // 200 ms) and the second-order term of the rotation.
    assert!((span - 4.0).abs() < 0.05, "span {span}");
}

#[test]
fn sway_and_roll_move_the_hand_rigidly_and_its_surface_with_it() {
    let still = Scene::new(SceneConfig {
        hand: Some(Tremor::flexion(5.0, 0.0, 0.0)),
        ..SceneConfig::trembling_hand()
    });
    let swaying = Scene::new(SceneConfig {
        hand: Some(Tremor {
            sway_amplitude_mm: 4.0,
            roll_amplitude_deg: 3.0,
            ..Tremor::flexion(5.0, 0.0, 0.0)
        }),
        ..SceneConfig::trembling_hand()
    });
    // At t = 0 the sway is at its peak (phase π/2) and the roll at sin(π/4) of its peak.
    let (a, b) = (still.at(0.0), swaying.at(0.0));
    let roll = 3f64.to_radians() * (TAU / 8.0).sin();
    let centre = V3::new(45.0, 0.0, 455.0);
    for (p, q) in a.points.iter().zip(&b.points) {
        let r = p - centre;
        let expected = centre
            + V3::new(
                r.x,
                r.y * roll.cos() - r.z * roll.sin() + 4.0,
                r.y * roll.sin() + r.z * roll.cos(),
            );
        assert!((q - expected).norm() < 1e-9, "{q:?} vs {expected:?}");
    }
    // The moved surface is where the moved points are: the ray to each tracked point hits
    // skin at its distance.
    for q in &b.points[..5] {
        let dir = q.normalize();
        let hit = b.intersect(&V3::zeros(), &dir, (0.0, 0.0)).unwrap();
        assert_eq!(hit.material, Material::Skin);
        assert!((hit.distance_mm - q.norm()).abs() < 1e-6, "{q:?}");
    }
    // A quarter period later the sway is zero and the roll at sin(3π/4) of its peak: the
    // back of the hand, 12 mm above the axis, is only rolled.
    let later = swaying.at(0.05).points[5];
    let roll = 3f64.to_radians() * (TAU * 3.0 / 8.0).sin();
    assert!((later.y - 12.0 * roll.sin()).abs() < 1e-9, "{later:?}");
}

#[test]
fn the_skin_texture_moves_with_the_skin() {
    let scene = Scene::new(SceneConfig {
        hand: Some(Tremor {
            sway_amplitude_mm: 4.0,
            roll_amplitude_deg: 5.0,
            ..Tremor::flexion(4.2, 3.0, 0.5)
        }),
        ..SceneConfig::trembling_hand()
    });
    // Every tracked point is a material point: the ray to it at any time hits the skin at
    // the same place on the hand at rest, so it carries the same texture.
    let at_rest: Vec<V3> = {
        let posed = scene.at(0.0);
        posed.points[..5]
            .iter()
            .map(|q| {
                let hit = posed.intersect(&V3::zeros(), &q.normalize(), (0.0, 0.0));
                hit.unwrap().rest_point_mm
            })
            .collect()
    };
    for t in [0.013, 0.05, 0.11, 0.2] {
        let posed = scene.at(t);
        for (q, rest) in posed.points[..5].iter().zip(&at_rest) {
            let hit = posed
                .intersect(&V3::zeros(), &q.normalize(), (0.0, 0.0))
                .unwrap();
            assert!((hit.rest_point_mm - rest).norm() < 1e-6, "t {t}: {q:?}");
            assert_eq!(posed.skin_albedo(&hit), scene.at(0.0).skin_albedo(&hit));
        }
    }
    // And the texture is there: albedo differs between nearby points on the back of the hand.
    let posed = scene.at(0.0);
    let albedo = |dx: f64| {
        let q = posed.points[5] + V3::new(dx, 0.0, 0.0);
        let hit = posed
            .intersect(&V3::zeros(), &q.normalize(), (0.0, 0.0))
            .unwrap();
        posed.skin_albedo(&hit)[0]
    };
    let spread: Vec<f64> = (0..8).map(|i| albedo(f64::from(i))).collect();
    let (lo, hi) = spread
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(hi / lo > 1.03, "{spread:?}");
}

#[test]
fn the_hand_is_seen_from_the_camera() {
    let posed = Scene::new(SceneConfig::trembling_hand()).at(0.0);
    let to_tip = posed.points[0].normalize();
    let hit = posed.intersect(&V3::zeros(), &to_tip, (0.0, 0.0)).unwrap();
    assert_eq!(hit.material, Material::Skin);
    assert!((hit.distance_mm - posed.points[0].norm()).abs() < 1.0);
}

#[test]
fn culling_changes_no_hit_and_no_shadow() {
    let config = crate::rig::RigConfig::paper(320, 200).unwrap();
    let scene = Scene::new(config.scene.clone());
    let plain = scene.at(0.031);
    let mut culled = plain.clone();
    culled.cull(
        &config.camera,
        &config.projector,
        &config.projector_from_camera,
    );
    let projector_centre = config.projector_from_camera.inverse().translation_mm;
    let (mut hand_hits, mut shadows) = (0, 0);
    for v in 0..200 {
        for u in 0..320 {
            let pixel = (f64::from(u), f64::from(v));
            let dir = config.camera.ray(pixel.0, pixel.1).unwrap();
            let a = plain.intersect(&V3::zeros(), &dir, pixel).unwrap();
            let b = culled.intersect(&V3::zeros(), &dir, pixel).unwrap();
            assert_eq!(a.distance_mm, b.distance_mm, "pixel {pixel:?}");
            hand_hits += usize::from(a.material == Material::Skin);
            let point = dir * a.distance_mm;
            let to_projector = projector_centre - point;
            let light = to_projector.normalize();
            let in_projector = config.projector_from_camera.transform(&point);
            let Some(pp) = config.projector.project(&in_projector) else {
                continue;
            };
            let origin = point + light * 1e-3;
            let sa = plain.occludes(&origin, &light, to_projector.norm(), pp);
            let sb = culled.occludes(&origin, &light, to_projector.norm(), pp);
            assert_eq!(sa, sb, "shadow at {pixel:?}");
            shadows += usize::from(sa);
        }
    }
    assert!(hand_hits > 5000 && shadows > 500, "{hand_hits} {shadows}");
}
