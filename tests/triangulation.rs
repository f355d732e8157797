//! Triangulation against the virtual rig's ground truth depth.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{decode_once, still_hand_rig};
use tremorscan::decode::DecodeParams;
use tremorscan::pattern::{cps_rgb, Axis};
use tremorscan::rig::edge_eval::outline_mask;
use tremorscan::rig::{GroundTruth, NoiseModel, VirtualRig};
use tremorscan::triangulate::{node_step_px, PointCloud, Triangulator};

/// The still hand under one coded axis, noise-free, with the truth of frame 0.
struct AxisCase {
    axis: Axis,
    rig: VirtualRig,
    triangulator: Triangulator,
    truth: GroundTruth,
}

fn axis_cases() -> Vec<AxisCase> {
    [
        (Axis::Columns, 65, 912.0),
        (Axis::Rows, 81, 1140.0),
        (Axis::Diagonal, 107, 1481.0),
    ]
    .into_iter()
    .map(|(axis, n, x_max)| {
        let config = still_hand_rig(NoiseModel::none());
        let seq = cps_rgb(n, x_max, axis, 6).unwrap();
        let rig = VirtualRig::new(config, seq).unwrap();
        let triangulator = Triangulator::new(rig.stereo_model()).unwrap();
        let mut frame = rig.blank_frame();
        let mut truth = GroundTruth::default();
        rig.render(0, &mut frame, Some(&mut truth)).unwrap();
        AxisCase {
            axis,
            rig,
            triangulator,
            truth,
        }
    })
    .collect()
}

#[test]
fn exact_coordinates_give_exact_depth_on_every_axis() {
    for AxisCase {
        axis,
        triangulator,
        truth,
        ..
    } in axis_cases()
    {
        let (mut worst, mut count) = (0f64, 0usize);
        for (p, (&x, &depth)) in truth.coordinate_px.iter().zip(&truth.depth_mm).enumerate() {
            if !x.is_finite() {
                continue;
            }
            let x = f64::from(x);
            let point = triangulator.point(p, x).unwrap();
            // The truth is stored in f32: the coordinate to about 6·10⁻⁵ px at 1500 px and the
            // depth to about 3·10⁻⁵ mm. The depth error allowed is that coordinate precision
            // times this pixel's depth sensitivity (large where the coded planes nearly contain
            // the camera ray, as for rows coded across a horizontal baseline), plus 10⁻⁴ mm.
            let z = |dx: f64| triangulator.point(p, x + dx).map_or(f64::NAN, |q| q.z);
            let sensitivity = ((z(0.01) - z(-0.01)) / 0.02).abs();
            let allowed = 1e-4 * sensitivity + 1e-4;
            let err = (point.z - f64::from(depth)).abs();
            assert!(
                err <= allowed,
                "{axis:?} pixel {p}: {err} mm (allowed {allowed})"
            );
            worst = worst.max(err);
            count += 1;
        }
        assert!(count > 200_000, "{axis:?}: {count} lit pixels");
        if axis != Axis::Rows {
            // With a baseline across the coded direction the sensitivity stays near 1 mm/px.
            assert!(worst < 1e-3, "{axis:?}: worst depth error {worst} mm");
        }
    }
}

#[test]
fn decoded_cloud_matches_the_true_surface() {
    let config = still_hand_rig(NoiseModel::default());
    let seq = config.default_sequence().unwrap();
    let (_, decoded) = decode_once(config.clone(), &seq, DecodeParams::default());
    let rig = VirtualRig::new(config, seq).unwrap();
    let mut truth = GroundTruth::default();
    let mut frame = rig.blank_frame();
    rig.render(1, &mut frame, Some(&mut truth)).unwrap();
    let triangulator = Triangulator::new(rig.stereo_model()).unwrap();
    let mut cloud = PointCloud::default();
    triangulator.triangulate(&decoded, &mut cloud).unwrap();
    assert_eq!(cloud.valid_count(), decoded.valid_count());
    // The fast path (per-pixel distortion polynomial, one f32 plane solve) against the exact
    // Newton solution, pixel by pixel.
    let mut worst_fast = 0f64;
    for (p, point) in cloud.point_in_camera_mm.iter().enumerate() {
        if point[2].is_finite() {
            let exact = triangulator
                .point(p, f64::from(decoded.coordinate_px[p]))
                .unwrap();
            worst_fast = worst_fast.max((f64::from(point[2]) - exact.z).abs());
        }
    }
    assert!(worst_fast < 1e-3, "fast path off by {worst_fast} mm");
    // The camera's blur mixes the two surfaces at a depth edge; the decoder refuses most such
    // pixels (`tests/mixed_pixels.rs` holds it to 0.05 % of the valid ones at 960×600), so the
    // outline is counted apart.
    let outline = outline_mask(&truth);
    let mut sum2 = 0.0;
    let (mut count, mut interior, mut gross_on_outline) = (0usize, 0usize, 0usize);
    let mut worst = 0f64;
    for ((point, &depth), &on_outline) in cloud
        .point_in_camera_mm
        .iter()
        .zip(&truth.depth_mm)
        .zip(&outline)
    {
        if !point[2].is_finite() {
            continue;
        }
        let err = f64::from(point[2] - depth);
        count += 1;
        if on_outline {
            gross_on_outline += usize::from(err.abs() > 5.0);
            continue;
        }
        sum2 += err * err;
        worst = worst.max(err.abs());
        interior += 1;
    }
    let rms = (sum2 / interior as f64).sqrt();
    eprintln!(
        "depth RMS {rms:.4} mm, worst {worst:.3} mm over {interior} points off the outline; \
         {gross_on_outline} of {count} valid points on it more than 5 mm off"
    );
    assert!(
        gross_on_outline * 2000 <= count,
        "{gross_on_outline} of {count} points on the outline more than 5 mm off"
    );
    // Depth sensitivity here is about z²/(f_p·b·cos) ≈ 500²/(1380·150) ≈ 1.2 mm per projector
    // pixel, and the decoded coordinate noise at the default noise is about 0.08 px RMS, so the
    // depth RMS should be near 0.1 mm; 0.25 mm leaves room for the steeper parts of the hand.
    assert!(rms < 0.25, "depth RMS {rms} mm over {interior} points");
    // No wrong fringe order off the outline: one period (28 px) would be about 30 mm.
    assert!(worst < 5.0, "worst depth error {worst} mm");
}

#[test]
fn a_map_of_the_wrong_size_is_refused() {
    let config = still_hand_rig(NoiseModel::default());
    let seq = config.default_sequence().unwrap();
    let (_, decoded) = decode_once(config.clone(), &seq, DecodeParams::default());
    let mut small = config;
    small.camera = small.camera.resized(320, 200).unwrap();
    let rig = VirtualRig::new(small, seq).unwrap();
    let triangulator = Triangulator::new(rig.stereo_model()).unwrap();
    let err = triangulator
        .triangulate(&decoded, &mut PointCloud::default())
        .unwrap_err();
    assert!(err.to_string().contains("640×400"), "{err}");
}

#[test]
fn fast_path_matches_the_exact_solution_on_every_axis() {
    use tremorscan::decode::{DecodeOutput, WindowSolver};
    for AxisCase {
        axis,
        rig,
        triangulator: per_pixel,
        truth,
    } in axis_cases()
    {
        let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
        let mut decoded = DecodeOutput::new(rig.width(), rig.height(), &solver);
        decoded.coordinate_px.clone_from(&truth.coordinate_px);
        decoded.amplitude.fill(10.0);
        // At 640×400 the default keeps per-pixel polynomials; the grid (of the same angle as
        // 1920×1200's, 3 px here) is what larger images take.
        assert_eq!(per_pixel.distortion_cells_kept_per_pixel(), None);
        let step = node_step_px(rig.width());
        let grid = Triangulator::with_distortion_grid(rig.stereo_model(), step).unwrap();
        for triangulator in [per_pixel, grid] {
            let mut cloud = PointCloud::default();
            triangulator.triangulate(&decoded, &mut cloud).unwrap();
            let mut worst = 0f64;
            for (p, &x) in truth.coordinate_px.iter().enumerate() {
                let Some(exact) = triangulator.point(p, f64::from(x)) else {
                    continue;
                };
                let fast = cloud.point_in_camera_mm[p];
                // The f32 plane solve and the degree-6 distortion fit both err like a coordinate
                // error: allow the point error of 10⁻³ projector px (the GPU-equality budget of the
                // decoder), i.e. 10⁻³ px times this pixel's depth sensitivity, at least 10⁻³ mm.
                let z = |dx: f64| {
                    triangulator
                        .point(p, f64::from(x) + dx)
                        .map_or(f64::NAN, |q| q.z)
                };
                let sensitivity = ((z(0.01) - z(-0.01)) / 0.02).abs();
                let err = (0..3)
                    .map(|i| (f64::from(fast[i]) - exact[i]).abs())
                    .fold(0.0, f64::max);
                let allowed = 1e-3 * sensitivity.max(1.0);
                assert!(
                    err <= allowed,
                    "{axis:?} pixel {p}: {err} mm (allowed {allowed})"
                );
                worst = worst.max(err / sensitivity.max(1.0));
                assert_eq!(cloud.fringe_amplitude[p], 10.0);
            }
            match triangulator.distortion_cells_kept_per_pixel() {
                Some((kept, cells)) => eprintln!(
                    "{axis:?}, grid of {step} px: worst {worst:.2e} px equivalent; {kept} of \
                 {cells} cells keep per-pixel polynomials"
                ),
                None => eprintln!("{axis:?}, per pixel: worst {worst:.2e} px equivalent"),
            }
        }
    }
}

#[test]
fn the_cloud_carries_each_pixels_colour_and_smallest_amplitude() {
    use tremorscan::decode::{DecodeOutput, WindowSolver};
    let Some(AxisCase {
        rig,
        triangulator,
        truth,
        ..
    }) = axis_cases().into_iter().next()
    else {
        panic!("no axis case");
    };
    let (w, h) = (rig.width(), rig.height());
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let mut decoded = DecodeOutput::new(w, h, &solver);
    decoded.coordinate_px.clone_from(&truth.coordinate_px);
    // Amplitudes and colours that differ per pixel, frequency and channel (row-planar: row,
    // then plane, then x), colours also below 0 and above 255, where the bytes must clamp.
    for (i, a) in decoded.amplitude.iter_mut().enumerate() {
        *a = ((i * 7919) % 1000) as f32 * 0.25;
    }
    for (i, c) in decoded.colour.iter_mut().enumerate() {
        *c = ((i * 104_729) % 400) as f32 - 60.5;
    }
    let mut cloud = PointCloud::default();
    triangulator.triangulate(&decoded, &mut cloud).unwrap();
    let (mut valid, mut invalid) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            let plane = |planes: &[f32], k: usize| planes[(y * 3 + k) * w + x];
            let expected_colour =
                [0, 1, 2].map(|k| plane(&decoded.colour, k).clamp(0.0, 255.0) as u8);
            assert_eq!(cloud.colour_rgb[p], expected_colour, "pixel {p}");
            let point = cloud.point_in_camera_mm[p];
            if point[2].is_finite() {
                let smallest = (0..3)
                    .map(|k| plane(&decoded.amplitude, k))
                    .fold(f32::INFINITY, f32::min);
                assert_eq!(cloud.fringe_amplitude[p], smallest, "pixel {p}");
                assert!(point.iter().all(|v| v.is_finite()), "pixel {p}: {point:?}");
                valid += 1;
            } else {
                assert_eq!(cloud.fringe_amplitude[p], 0.0, "pixel {p}");
                assert!(point.iter().all(|v| v.is_nan()), "pixel {p}: {point:?}");
                invalid += 1;
            }
        }
    }
    assert!(
        valid > 100_000 && invalid > 1000,
        "{valid} valid, {invalid} invalid"
    );
}

#[test]
fn at_full_resolution_the_distortion_grid_holds_at_every_pixel() {
    use tremorscan::decode::{DecodeOutput, WindowSolver};
    use tremorscan::rig::RigConfig;
    let config = RigConfig::paper(1920, 1200).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    let triangulator = Triangulator::new(rig.stereo_model()).unwrap();
    // Cells of 8 px; the blend met every pixel's own samples, so none keeps per-pixel
    // polynomials, and the tables are the rays (8 B/px) and the grid (148 B per 64 px): under
    // 11 B/px, where the per-pixel polynomials took 40.
    assert_eq!(
        triangulator.distortion_cells_kept_per_pixel(),
        Some((0, 240 * 150))
    );
    assert!(
        triangulator.memory_bytes() < 11 * 1920 * 1200,
        "{} B",
        triangulator.memory_bytes()
    );
    // The fast path against the exact solution on every 61st lit pixel of the still scene.
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    rig.render(0, &mut frame, Some(&mut truth)).unwrap();
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let mut decoded = DecodeOutput::new(rig.width(), rig.height(), &solver);
    decoded.coordinate_px.clone_from(&truth.coordinate_px);
    decoded.amplitude.fill(10.0);
    let mut cloud = PointCloud::default();
    triangulator.triangulate(&decoded, &mut cloud).unwrap();
    let (mut worst, mut count) = (0f64, 0usize);
    for (p, &x) in truth.coordinate_px.iter().enumerate().step_by(61) {
        let Some(exact) = triangulator.point(p, f64::from(x)) else {
            continue;
        };
        let z = |dx: f64| {
            triangulator
                .point(p, f64::from(x) + dx)
                .map_or(f64::NAN, |q| q.z)
        };
        let sensitivity = ((z(0.01) - z(-0.01)) / 0.02).abs().max(1.0);
        let fast = cloud.point_in_camera_mm[p];
        let err = (0..3)
            .map(|i| (f64::from(fast[i]) - exact[i]).abs())
            .fold(0.0, f64::max);
        assert!(err <= 1e-3 * sensitivity, "pixel {p}: {err} mm");
        worst = worst.max(err / sensitivity);
        count += 1;
    }
    assert!(count > 30_000, "{count} pixels compared");
    eprintln!("1920×1200, grid of 8 px: worst {worst:.2e} px equivalent over {count} pixels");
}
