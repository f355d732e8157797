//! The virtual rig renders calibration chessboards with exact corner truth.
#![allow(clippy::unwrap_used, reason = "tests")]

use nalgebra::{Rotation3, Vector3};
use tremorscan::geometry::Pose;
use tremorscan::rig::truth::surface;
use tremorscan::rig::{Chessboard, GroundTruth, RigConfig, SceneConfig, VirtualRig};

fn board_rig_with_ambient(ambient_gray: f64) -> (VirtualRig, Chessboard) {
    let rotation = Rotation3::from_euler_angles(0.17, -0.35, 0.1).into_inner();
    let board = Chessboard::standard(Pose {
        rotation,
        translation_mm: Vector3::new(-85.0, -45.0, 430.0),
    });
    let mut config = RigConfig::paper(640, 400).unwrap();
    config.scene = SceneConfig::chessboard(board);
    config.ambient_gray = ambient_gray;
    let seq = config.default_sequence().unwrap();
    (VirtualRig::new(config, seq).unwrap(), board)
}

#[test]
fn corners_are_where_the_squares_meet_in_the_image() {
    // Room light strong enough to see the board with the projector dark.
    let (rig, board) = board_rig_with_ambient(150.0);
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    rig.render_flat(0, [0, 0, 0], 0.0, &mut frame, Some(&mut truth))
        .unwrap();
    assert_eq!(truth.board_corners_in_camera, board.corners_in_camera());
    let camera = rig.config.camera;
    let gray = |p: &Vector3<f64>| {
        let (u, v) = camera.project(p).unwrap();
        let (x, y) = (u.round() as usize, v.round() as usize);
        let px = &frame.data[(y * rig.width() + x) * 3..(y * rig.width() + x) * 3 + 3];
        px.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0
    };
    let to_board = board.camera_from_board.inverse();
    let mut checked = 0;
    for corner in &truth.board_corners_in_camera {
        let (u, v) = camera.project(corner).unwrap();
        assert!(
            camera.contains(u, v),
            "corner outside the image at ({u}, {v})"
        );
        let p = (u.round() as usize, v.round() as usize);
        assert_eq!(truth.surface[p.1 * rig.width() + p.0], surface::BOARD);
        // A quarter square away along the board's diagonals: opposite quadrants alike,
        // neighbouring ones far apart (dark 0.06 and light 0.85 albedo under 150 gray of light).
        let q = board.square_mm / 4.0;
        let c = to_board.transform(corner);
        let at = |dx: f64, dy: f64| {
            gray(
                &board
                    .camera_from_board
                    .transform(&(c + Vector3::new(dx, dy, 0.0))),
            )
        };
        let (a, b, d, e) = (at(q, q), at(-q, -q), at(q, -q), at(-q, q));
        assert!(
            (a - b).abs() < 15.0 && (d - e).abs() < 15.0,
            "{a} {b} {d} {e}"
        );
        assert!((a - d).abs() > 60.0, "no contrast at corner: {a} vs {d}");
        checked += 1;
    }
    assert_eq!(checked, 54);
}

#[test]
fn the_board_is_lit_by_the_patterns_and_decodes() {
    // Room light dimmed for the pattern captures, as in a calibration session.
    let (rig, _) = board_rig_with_ambient(6.0);
    let mut decoder = tremorscan::decode::SlidingDecoder::new(
        rig.sequence.clone(),
        rig.config.cross_talk,
        tremorscan::decode::DecodeParams::default(),
    )
    .unwrap();
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in 0..3 {
        rig.render(i, &mut frame, if i == 1 { Some(&mut truth) } else { None })
            .unwrap();
        decoder.push(&frame).unwrap();
    }
    let out = decoder.output().unwrap();
    let acc = tremorscan::rig::evaluate::compare(out, &truth, rig.sequence.period_px(65) / 2.0);
    // The dark squares reflect 6 % of the light, so their fringes are weak (amplitude 5–9), but
    // most of them still decode along with the light squares and the margin.
    let board_px = truth
        .surface
        .iter()
        .filter(|&&s| s == surface::BOARD)
        .count();
    let board_valid = truth
        .surface
        .iter()
        .zip(&out.invalid)
        .filter(|(&s, &r)| s == surface::BOARD && r == 0)
        .count();
    assert!(
        board_valid * 2 > board_px,
        "{board_valid} of {board_px} board pixels valid"
    );
    // Known weak spot (docs/accuracy.md): small islands inside the dark squares, where the
    // amplitude is barely above the minimum, can keep a wrong fringe order. Measured 28 of
    // 221,224 valid pixels (0.013 %) at the default noise; fail beyond 0.05 %.
    assert!(acc.unwrap_error_rate() < 5e-4, "{acc:?}");
}
