//! The validity mask: what must never come out as a valid coordinate.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{corrupted_red, still_hand_rig};
use tremorscan::decode::{invalid, DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::frame::Frame;
use tremorscan::rig::{NoiseModel, VirtualRig};

#[test]
fn saturated_pixels_are_never_valid() {
    let mut config = still_hand_rig(NoiseModel::default());
    // Twice the projector power: bright table and skin clip at 255 on part of the fringe.
    config.projector_gain_gray *= 2.0;
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let mut decoder =
        SlidingDecoder::new(seq, rig.config.cross_talk, DecodeParams::default()).unwrap();
    let mut clipped = vec![false; rig.width() * rig.height()];
    let mut frame = rig.blank_frame();
    for i in 0..3 {
        rig.render(i, &mut frame, None).unwrap();
        for (p, px) in frame.data.chunks_exact(3).enumerate() {
            clipped[p] |= px.contains(&255);
        }
        decoder.push(&frame).unwrap();
    }
    let out = decoder.output().unwrap();
    let saturated = invalid::SATURATED;
    let n_clipped = clipped.iter().filter(|&&c| c).count();
    assert!(
        n_clipped > 10_000,
        "the test needs clipping, got {n_clipped} px"
    );
    for (p, &c) in clipped.iter().enumerate() {
        assert_eq!(out.invalid[p] & saturated != 0, c, "pixel {p}");
        if c {
            assert!(out.coordinate_px[p].is_nan());
        }
    }
}

/// Pixels valid in both whose coordinates differ by half a fringe period or more.
fn wrong_orders(clean: &[f32], other: &[f32]) -> usize {
    clean
        .iter()
        .zip(other)
        .filter(|(c, o)| c.is_finite() && o.is_finite() && (*c - *o).abs() > 14.0)
        .count()
}

fn disagreeing(out: &tremorscan::decode::DecodeOutput) -> usize {
    out.invalid
        .iter()
        .filter(|&&r| r & invalid::DISAGREEMENT != 0)
        .count()
}

#[test]
fn a_frame_that_breaks_the_chebyshev_relation_refuses_its_window() {
    let config = still_hand_rig(NoiseModel::default());
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let frames = common::rendered(&rig, 0..3);
    let decode = |middle: &Frame| {
        let mut d =
            SlidingDecoder::new(seq.clone(), rig.config.cross_talk, DecodeParams::default())
                .unwrap();
        d.push(&frames[0]).unwrap();
        d.push(middle).unwrap();
        d.push(&frames[2]).unwrap();
        let out = d.output().unwrap().clone();
        out
    };
    let clean = decode(&frames[1]);
    let n = clean.width * clean.height;
    assert!(disagreeing(&clean) < n / 50, "{}", disagreeing(&clean));
    assert_eq!(clean.refused, None);
    // The whole frame broken: most pixels disagree, and the window is refused whole.
    let broken = decode(&corrupted_red(&rig, 1));
    assert!(
        disagreeing(&broken) > n / 2,
        "{} of {n}",
        disagreeing(&broken)
    );
    let refusal = broken.refused.expect("the window is refused");
    assert!(refusal.share > 0.5, "{refusal:?}");
    assert_eq!(refusal.rows, 0..broken.height);
    assert!(broken
        .invalid
        .iter()
        .all(|f| f & invalid::BROKEN_WINDOW != 0));
    assert!(broken.coordinate_px.iter().all(|c| c.is_nan()));
    // Before windows were refused whole, the per-pixel checks kept 0.39 % of the image a fringe
    // off here (0.14 % with the still window): where the induced red phase error happens to be
    // small (it varies with the phase) a pixel passes them, and the motion model takes part of
    // such a frame for motion.
}

#[test]
fn a_corrupted_frame_refuses_the_three_windows_that_hold_it_and_no_more() {
    // In a stream, a broken frame is first, middle and last of three windows. Before windows
    // were refused whole, the one where it came first kept 5.4 % of the image a fringe off: the
    // windows before were refused too, so no reference checked it.
    let refusals = refused_around(corrupted_red);
    assert!(refusals.iter().all(|r| r.rows == (0..400)), "{refusals:?}");
}

#[test]
fn a_frame_broken_on_a_band_of_rows_refuses_the_three_windows_that_hold_it() {
    // A tenth of the rows from another exposure: the windows as a whole disagree on under
    // 20 %. Before bands of rows were judged on their own they kept 143, 0 and 850 pixels of
    // the band a fringe off, and 28–43 outside it.
    let band = 180..220;
    let refusals = refused_around(|rig, i| common::corrupted_red_rows(rig, i, band.clone()));
    for r in &refusals {
        // Refused for a band inside the broken rows, not for the window as a whole.
        assert!(r.share > 0.5 && r.rows.len() < 40, "{r:?}");
        assert!(r.rows.start < band.end && band.start < r.rows.end, "{r:?}");
    }
}

/// Decodes 12 frames of the still hand with frame 6 replaced by `corrupt(rig, 6)`, checks that
/// the three windows holding it are refused and give no coordinate, and that the others give
/// what the clean stream gives; returns the three refusals.
fn refused_around(
    corrupt: impl Fn(&VirtualRig, u64) -> Frame,
) -> Vec<tremorscan::decode::broken::Refusal> {
    let config = still_hand_rig(NoiseModel::default());
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let frames = common::rendered(&rig, 0..12);
    let bad = 6;
    let broken_frame = corrupt(&rig, bad as u64);
    let decode_all = |corrupt: bool| {
        let mut d =
            SlidingDecoder::new(seq.clone(), rig.config.cross_talk, DecodeParams::default())
                .unwrap();
        let mut outs = Vec::new();
        for (i, f) in frames.iter().enumerate() {
            let f = if corrupt && i == bad {
                &broken_frame
            } else {
                f
            };
            if let WindowOutcome::Decoded(out) = d.push(f).unwrap() {
                outs.push((i, out.clone()));
            }
        }
        outs
    };
    let clean = decode_all(false);
    let broken = decode_all(true);
    let mut refusals = Vec::new();
    for ((i, c), (_, b)) in clean.iter().zip(&broken) {
        let valid = |o: &tremorscan::decode::DecodeOutput| {
            o.coordinate_px.iter().filter(|c| c.is_finite()).count()
        };
        if (bad..bad + 3).contains(i) {
            refusals.push(
                b.refused
                    .clone()
                    .expect("a window holding the broken frame"),
            );
            assert_eq!(valid(b), 0, "window ending at {i}");
        } else {
            assert_eq!(b.refused, None, "window ending at {i}");
            // The windows after start afresh, as after a dropped frame: no reference is
            // missed that matters on a still hand.
            assert!(
                valid(b).abs_diff(valid(c)) * 1000 <= valid(c),
                "window ending at {i}: {} valid against {}",
                valid(b),
                valid(c)
            );
            assert_eq!(wrong_orders(&c.coordinate_px, &b.coordinate_px), 0, "{i}");
        }
    }
    refusals
}
