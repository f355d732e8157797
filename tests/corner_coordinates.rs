//! Reading the projector coordinate at sub-pixel camera positions (chessboard corners) from the
//! decoded map of the virtual rig.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::decode_once;
use tremorscan::calibrate::{fit_coordinate, LocalFitOptions};
use tremorscan::decode::DecodeParams;
use tremorscan::rig::{NoiseModel, RigConfig, SceneConfig};

#[test]
fn local_fit_reads_the_coordinate_at_sub_pixel_positions() {
    let mut config = RigConfig::paper(640, 400).unwrap();
    config.scene = SceneConfig::plane();
    config.noise = NoiseModel::default();
    let seq = config.default_sequence().unwrap();
    let (_, decoded) = decode_once(config.clone(), &seq, DecodeParams::default());
    for &(u, v) in &[
        (100.3, 80.7),
        (320.5, 200.25),
        (555.9, 333.1),
        (47.2, 360.8),
    ] {
        // Exact coordinate at (u, v): the camera ray meets the plane z = 500 mm, and the real
        // (distorted) projector shows that point at this coordinate.
        let ray = config.camera.ray(u, v).unwrap();
        let point = ray * (config.scene.table_distance_mm / ray.z);
        let (pu, pv) = config
            .projector
            .project(&config.projector_from_camera.transform(&point))
            .unwrap();
        let truth = seq.axis.coordinate(pu, pv);
        let fit = fit_coordinate(
            &decoded.coordinate_px,
            decoded.width,
            decoded.height,
            (u, v),
            &LocalFitOptions::default(),
        )
        .unwrap();
        // The decoded coordinate noise on the plane is about 0.05 px per pixel; a fit over about
        // 110 Gaussian-weighted pixels leaves about 0.01 px. The quadratic surface follows the
        // lens distortion over ±6 px exactly enough.
        assert!(
            (fit.value_px - truth).abs() < 0.03,
            "at ({u}, {v}): {fit:?} vs {truth}"
        );
    }
}
