//! Every codec round-trips: encode, render through the virtual rig, decode.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{decode_once, still_hand_rig};
use tremorscan::decode::{DecodeError, DecodeParams, SlidingDecoder, UnwrapMethod};
use tremorscan::pattern::{cps_gray, cps_rgb, multi_frequency, Axis, CpsGrayVariant};
use tremorscan::rig::NoiseModel;

fn robust() -> DecodeParams {
    DecodeParams::default()
}

#[test]
fn cps_rgb_on_columns_rows_and_diagonal() {
    for (axis, n, x_max) in [
        (Axis::Columns, 65, 912.0),
        (Axis::Rows, 81, 1140.0),
        // Paper §5.2: n = 107 on the diagonal with x_max = 1481 ≥ (911 + 1139)/√2 + 1.
        (Axis::Diagonal, 107, 1481.0),
    ] {
        let seq = cps_rgb(n, x_max, axis, 6).unwrap();
        let (acc, _) = decode_once(still_hand_rig(NoiseModel::default()), &seq, robust());
        // Default noise (≈1–1.6 gray levels): robust unwrap leaves no wrong fringe order, and the
        // coordinate noise is a few hundredths to tenths of a pixel.
        assert!(acc.unwrap_error_rate() < 0.001, "{axis:?}: {acc:?}");
        assert!(acc.coverage() > 0.95, "{axis:?}: {acc:?}");
        assert!(acc.rms_px < 0.2, "{axis:?}: {acc:?}");
    }
}

#[test]
fn cps_gray_seven_and_nine_images() {
    for variant in [CpsGrayVariant::Minimal7, CpsGrayVariant::Full9] {
        let seq = cps_gray(65, variant, 912.0, Axis::Columns, 8).unwrap();
        let (acc, out) = decode_once(still_hand_rig(NoiseModel::default()), &seq, robust());
        assert_eq!(out.channels, 1);
        // White light: three channels averaged, full 8-bit patterns; far less noise than RGB.
        assert!(acc.unwrap_error_rate() < 0.001, "{variant:?}: {acc:?}");
        assert!(acc.rms_px < 0.1, "{variant:?}: {acc:?}");
        assert!(acc.coverage() > 0.9, "{variant:?}: {acc:?}");

        // The paper's per-pixel formula decodes the same frames too. Its arccos is ill-conditioned
        // near both ends of the range (dx = dC / (f1·sin f1·x): three times the noise at
        // x = 100 px), where it loses about 1 % of the fringe orders even at this low noise.
        let params = DecodeParams {
            unwrap: UnwrapMethod::ChebyshevPerPixel,
            ..robust()
        };
        let (paper, _) = decode_once(still_hand_rig(NoiseModel::default()), &seq, params);
        assert!(
            paper.unwrap_error_rate() < 0.02,
            "{variant:?} per pixel: {paper:?}"
        );
        assert!(paper.rms_px < 0.1, "{variant:?} per pixel: {paper:?}");
        assert!(
            paper.unwrap_errors > acc.unwrap_errors,
            "{paper:?} vs {acc:?}"
        );
    }
}

#[test]
fn multi_frequency_unwraps_temporally() {
    let seq = multi_frequency(&[1, 8, 64], 4, 912.0, Axis::Columns, 8).unwrap();
    let params = DecodeParams {
        unwrap: UnwrapMethod::Temporal,
        ..robust()
    };
    let (acc, _) = decode_once(still_hand_rig(NoiseModel::default()), &seq, params);
    assert!(acc.unwrap_error_rate() < 0.002, "{acc:?}");
    assert!(acc.rms_px < 0.1, "{acc:?}");
    assert!(acc.coverage() > 0.9, "{acc:?}");
}

#[test]
fn unwrap_methods_refuse_sequences_they_cannot_unwrap() {
    let seq = multi_frequency(&[1, 8, 64], 4, 912.0, Axis::Columns, 8).unwrap();
    let config = still_hand_rig(NoiseModel::default());
    let rig = tremorscan::rig::VirtualRig::new(config, seq.clone()).unwrap();
    let mut decoder = SlidingDecoder::new(seq, rig.config.cross_talk, robust()).unwrap();
    let mut frame = rig.blank_frame();
    let mut last = None;
    for i in 0..12 {
        rig.render(i, &mut frame, None).unwrap();
        last = Some(decoder.push(&frame).map(|_| ()));
    }
    assert!(
        matches!(last, Some(Err(DecodeError::NeedsChebyshev { .. }))),
        "{last:?}"
    );
}
