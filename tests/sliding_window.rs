//! The sliding window: a moving scene decodes at every frame, stamped at the window centre.
#![allow(clippy::unwrap_used, reason = "tests")]

use std::sync::Arc;
use tremorscan::decode::window::SharedFrame;
use tremorscan::decode::{
    decode_window, DecodeError, DecodeOutput, DecodeParams, SlidingDecoder, WindowOutcome,
    WindowSolver,
};
use tremorscan::frame::Frame;
use tremorscan::rig::evaluate::compare;
use tremorscan::rig::{GroundTruth, RigConfig, VirtualRig};

fn label(outcome: &WindowOutcome<'_>) -> &'static str {
    match outcome {
        WindowOutcome::Filling { .. } => "filling",
        WindowOutcome::Unsolvable { .. } => "unsolvable",
        WindowOutcome::TooSpread { .. } => "spread",
        WindowOutcome::Decoded(_) => "decoded",
    }
}

fn new_decoder(rig: &VirtualRig) -> SlidingDecoder {
    SlidingDecoder::new(
        rig.sequence.clone(),
        rig.config.cross_talk,
        DecodeParams::default(),
    )
    .unwrap()
}

fn trembling_rig() -> VirtualRig {
    let config = RigConfig::paper(640, 400).unwrap();
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

#[test]
fn a_trembling_hand_decodes_at_every_frame() {
    let rig = trembling_rig();
    let half_period = rig.sequence.period_px(65) / 2.0;
    let mut decoder = new_decoder(&rig);
    let mut frames: Vec<Frame> = Vec::new();
    let mut truths: Vec<GroundTruth> = Vec::new();
    for i in 0..9u64 {
        let mut frame = rig.blank_frame();
        let mut truth = GroundTruth::default();
        rig.render(i, &mut frame, Some(&mut truth)).unwrap();
        let outcome = decoder.push(&frame).unwrap();
        frames.push(frame);
        truths.push(truth);
        if i < 2 {
            assert!(matches!(outcome, WindowOutcome::Filling { .. }));
            continue;
        }
        let WindowOutcome::Decoded(out) = outcome else {
            panic!("frame {i} did not decode: {outcome:?}");
        };
        // Stamped at the centre of frames i−2, i−1, i: the middle frame's time.
        let centre = (frames[i as usize - 2].time_s + frames[i as usize].time_s) / 2.0;
        assert!((out.time_s - centre).abs() < 1e-12);
        assert!((out.time_s - truths[i as usize - 1].time_s).abs() < 1e-12);
        // Against the truth at the window centre. The fingertips move up to 0.55 mm per frame;
        // the symmetric window cancels the linear part of that motion, so the result stays close
        // to the middle frame's geometry and no fringe order may be lost.
        let acc = compare(out, &truths[i as usize - 1], half_period);
        assert!(acc.unwrap_error_rate() < 0.005, "frame {i}: {acc:?}");
        assert!(acc.coverage() > 0.95, "frame {i}: {acc:?}");
        assert!(acc.rms_px < 0.25, "frame {i}: {acc:?}");
    }
    assert_eq!(decoder.decoded_windows, 7);
}

#[test]
fn a_dropped_frame_is_reported_and_decoding_resumes() {
    let rig = trembling_rig();
    let mut decoder = new_decoder(&rig);
    let mut frame = rig.blank_frame();
    let mut outcomes = Vec::new();
    for i in [0u64, 1, 2, 4, 5, 6] {
        rig.render(i, &mut frame, None).unwrap();
        outcomes.push(label(&decoder.push(&frame).unwrap()));
    }
    // Patterns 0 1 2 | 1 2 0: windows (1,2,1) and (2,1,2) repeat a shift.
    assert_eq!(
        outcomes,
        [
            "filling",
            "filling",
            "decoded",
            "unsolvable",
            "unsolvable",
            "decoded"
        ]
    );
    assert_eq!(decoder.unsolvable_windows, 2);
}

#[test]
fn a_window_spanning_a_whole_dropped_cycle_is_refused() {
    let rig = trembling_rig();
    // Two frame periods plus jitter allowance: a window without drops spans exactly two.
    let max_span_s = 2.5 / rig.config.fps;
    let mut decoder = new_decoder(&rig).with_max_span(max_span_s);
    let mut frame = rig.blank_frame();
    let mut outcomes = Vec::new();
    // Frames 3, 4 and 5 (one whole cycle) are lost: (1, 2, 0) from frames 1, 2, 6 is solvable
    // but 5 frame periods long.
    for i in [0u64, 1, 2, 6, 7, 8] {
        rig.render(i, &mut frame, None).unwrap();
        outcomes.push(label(&decoder.push(&frame).unwrap()));
    }
    assert_eq!(
        outcomes,
        ["filling", "filling", "decoded", "spread", "spread", "decoded"]
    );
    assert_eq!(decoder.spread_windows, 2);
}

#[test]
fn bad_frames_are_refused_with_a_clear_error() {
    let rig = trembling_rig();
    let mut decoder = new_decoder(&rig);
    let mut frame = rig.blank_frame();
    rig.render(0, &mut frame, None).unwrap();
    decoder.push(&frame).unwrap();
    let small = Frame::new(320, 200, 3).unwrap();
    let err = decoder.push(&small).unwrap_err();
    assert!(err.to_string().contains("expected 640×400×3"), "{err}");
    let mut wrong_index = frame.clone();
    wrong_index.pattern_index = 5;
    assert_eq!(
        decoder.push(&wrong_index).unwrap_err(),
        DecodeError::PatternIndex { index: 5, len: 3 }
    );
    let gray = Frame::new(640, 400, 1).unwrap();
    let mut fresh = new_decoder(&rig);
    for i in 0..2 {
        let mut g = gray.clone();
        g.pattern_index = i;
        fresh.push(&g).unwrap();
    }
    let mut g = gray;
    g.pattern_index = 2;
    assert_eq!(
        fresh.push(&g).unwrap_err(),
        DecodeError::NeedsColourFrames(1)
    );
}

#[test]
fn decode_window_checks_its_frames_against_the_solver() {
    let rig = trembling_rig();
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let mut out = DecodeOutput::new(rig.width(), rig.height(), &solver);
    let frames: Vec<Frame> = [0u64, 1, 2]
        .iter()
        .map(|&i| {
            let mut f = rig.blank_frame();
            rig.render(i, &mut f, None).unwrap();
            f
        })
        .collect();
    let params = DecodeParams::default();
    // Frames in the wrong order for this solver.
    let wrong = [&frames[1], &frames[0], &frames[2]];
    assert_eq!(
        decode_window(&solver, &wrong, &params, Some(65), &mut out).unwrap_err(),
        DecodeError::OrderMismatch {
            position: 0,
            expected: 0,
            got: 1
        }
    );
    // Too few frames.
    let two = [&frames[0], &frames[1]];
    assert_eq!(
        decode_window(&solver, &two, &params, Some(65), &mut out).unwrap_err(),
        DecodeError::WrongFrameCount {
            expected: 3,
            got: 2
        }
    );
    // Empty frames.
    let empty: Vec<Frame> = (0..3)
        .map(|i| {
            let mut f = Frame::new(0, 0, 3).unwrap();
            f.pattern_index = i;
            f
        })
        .collect();
    let empty_refs: Vec<&Frame> = empty.iter().collect();
    assert_eq!(
        decode_window(&solver, &empty_refs, &params, Some(65), &mut out).unwrap_err(),
        DecodeError::EmptyFrame {
            width: 0,
            height: 0
        }
    );
    // The right order decodes.
    let right: Vec<&Frame> = frames.iter().collect();
    decode_window(&solver, &right, &params, Some(65), &mut out).unwrap();
    assert!(out.valid_count() > out.width * out.height / 2);
}

#[test]
fn after_a_reset_the_stream_may_change_size() {
    let rig = trembling_rig();
    let small = {
        let config = RigConfig::paper(320, 200).unwrap();
        let seq = config.default_sequence().unwrap();
        VirtualRig::new(config, seq).unwrap()
    };
    let mut decoder = new_decoder(&rig);
    let mut frame = rig.blank_frame();
    for i in 0..3 {
        rig.render(i, &mut frame, None).unwrap();
        decoder.push(&frame).unwrap();
    }
    decoder.reset();
    let mut frame = small.blank_frame();
    let mut decoded = None;
    for i in 0..3 {
        small.render(i, &mut frame, None).unwrap();
        match decoder.push(&frame).unwrap() {
            WindowOutcome::Filling { .. } if i < 2 => {}
            WindowOutcome::Decoded(out) if i == 2 => {
                decoded = Some((out.width, out.height, out.valid_count()));
            }
            other => panic!("frame {i}: {other:?}"),
        }
    }
    let (w, h, valid) = decoded.unwrap();
    assert_eq!((w, h), (320, 200));
    assert!(valid > 320 * 200 * 9 / 10, "{valid}");
}

/// The rig at 160×100 and its first `n` frames.
fn small_rig_frames(n: u64) -> (VirtualRig, Vec<Frame>) {
    let config = RigConfig::paper(160, 100).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    let frames = (0..n)
        .map(|i| {
            let mut frame = rig.blank_frame();
            rig.render(i, &mut frame, None).unwrap();
            frame
        })
        .collect();
    (rig, frames)
}

#[test]
fn taking_the_coordinates_moves_them_and_the_next_window_overwrites_the_buffer() {
    let (rig, frames) = small_rig_frames(5);
    // The same stream through a decoder whose coordinates are never taken.
    let mut plain = new_decoder(&rig);
    let mut expected: Vec<Vec<f32>> = Vec::new();
    for frame in &frames {
        if let WindowOutcome::Decoded(out) = plain.push(frame).unwrap() {
            expected.push(out.coordinate_px.clone());
        }
    }
    assert_eq!(expected.len(), 3);

    let mut decoder = new_decoder(&rig);
    let mut taken = Vec::new();
    assert!(!decoder.take_coordinate(&mut taken), "nothing decoded yet");
    assert!(taken.is_empty());
    // A buffer of garbage: the decoder must overwrite all of it in the next window.
    let mut buffer = vec![-7.0f32; 160 * 100];
    let mut window = 0;
    for frame in &frames {
        if let WindowOutcome::Decoded(_) = decoder.push(frame).unwrap() {
            assert!(decoder.take_coordinate(&mut buffer));
            assert!(decoder.output().is_none(), "taken: no stale output");
            assert!(!decoder.take_coordinate(&mut taken), "taken once only");
            let same = buffer
                .iter()
                .zip(&expected[window])
                .all(|(a, b)| a == b || (a.is_nan() && b.is_nan()));
            assert!(same, "window {window}: the taken coordinates differ");
            window += 1;
        }
    }
    assert_eq!(window, 3);
}

#[test]
fn shared_frames_decode_like_copied_ones_and_are_let_go_when_they_leave_the_window() {
    let (rig, frames) = small_rig_frames(7);
    let results = |out: &DecodeOutput| (out.coordinate_px.clone(), out.invalid.clone());
    let mut copying = new_decoder(&rig);
    let mut expected = Vec::new();
    for frame in &frames {
        if let WindowOutcome::Decoded(out) = copying.push(frame).unwrap() {
            expected.push(results(out));
        }
    }
    assert_eq!(expected.len(), 5);

    // Shared frames, with copied ones in between: the ring mixes both kinds.
    let shared: Vec<Arc<Frame>> = frames.iter().cloned().map(Arc::new).collect();
    let mut decoder = new_decoder(&rig);
    let mut got = Vec::new();
    for (i, frame) in shared.iter().enumerate() {
        let outcome = if i == 3 {
            decoder.push(frame).unwrap()
        } else {
            decoder
                .push_shared(Arc::clone(frame) as SharedFrame)
                .unwrap()
        };
        if let WindowOutcome::Decoded(out) = outcome {
            got.push(results(out));
        }
        // Held while in the window (the last three frames), let go after; frame 3 was copied.
        for (k, f) in shared.iter().enumerate().take(i + 1) {
            let held = k + 3 > i && k != 3;
            assert_eq!(
                Arc::strong_count(f),
                1 + usize::from(held),
                "frame {k} after push {i}"
            );
        }
    }
    let same = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
    };
    assert_eq!(got.len(), expected.len());
    for (window, ((coordinate, invalid), (want_coordinate, want_invalid))) in
        got.iter().zip(&expected).enumerate()
    {
        assert!(
            same(coordinate, want_coordinate),
            "window {window}: coordinates differ"
        );
        assert_eq!(invalid, want_invalid, "window {window}: validity differs");
    }
    // A shared frame is checked like a copied one.
    let mut small = Frame::new(80, 50, 3).unwrap();
    small.pattern_index = 1;
    let err = decoder
        .push_shared(Arc::new(small) as SharedFrame)
        .unwrap_err();
    assert!(err.to_string().contains("expected 160×100×3"), "{err}");
}
