//! Control points that follow the skin, against the rig's truth (issue 24's targets): a point
//! placed on the index fingertip of a hand whose fingers flex by 3 mm while the whole hand sways
//! 4 mm sideways and rolls 5° at 4.2 Hz stays within 0.25 mm RMS of the material point it was
//! placed on, with at least 95 % of the samples valid; a fixed pixel there does not (the skin
//! slides past it by millimetres). On a still hand the followed point does not drift, and a
//! point on skin without texture is refused by name rather than tracked blindly.
#![allow(clippy::unwrap_used, reason = "tests")]

use tremorscan::decode::{frames_averaged, DecodeParams};
use tremorscan::rig::skin_eval::skin_tracking;
use tremorscan::rig::{RigConfig, Tremor, VirtualRig};
use tremorscan::tremor::{
    ControlPoint, FollowError, FollowOptions, PointMode, TextureImage, TrackOptions,
};

fn rig(tremor: Tremor, texture: Option<f64>) -> VirtualRig {
    let mut config = RigConfig::paper(640, 400).unwrap();
    config.scene.hand = Some(tremor);
    if let Some(contrast) = texture {
        config.scene.skin_texture_contrast = contrast;
    }
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

/// The rig: flexion 3 mm, sway 4 mm, roll 5°, 4.2 Hz.
fn rolling_hand() -> Tremor {
    Tremor {
        sway_amplitude_mm: 4.0,
        roll_amplitude_deg: 5.0,
        ..Tremor::flexion(4.2, 3.0, 0.3)
    }
}

#[test]
fn fingertip_points_follow_their_skin_within_a_quarter_millimetre() {
    // The index (0) and middle (1) fingertips, two seconds each: eight tremor cycles.
    for point in [0, 1] {
        fingertip_follows_its_skin(point);
    }
}

fn fingertip_follows_its_skin(point: usize) {
    let rig = rig(rolling_hand(), None);
    let r = skin_tracking(&rig, DecodeParams::default(), 242, point).unwrap();
    let (follow_rms, fixed_rms) = (r.follow.rms_mm().unwrap(), r.fixed.rms_mm().unwrap());
    println!(
        "point {point} followed: {:.1} % valid, {follow_rms:.3} mm RMS; fixed pixel: {:.1} % valid, {fixed_rms:.3} mm RMS",
        100.0 * r.follow.valid_share(),
        100.0 * r.fixed.valid_share()
    );
    assert!(r.follow.valid_share() >= 0.95, "{}", r.follow.valid_share());
    assert!(follow_rms <= 0.25, "{follow_rms} mm");
    // The premise: at a fixed pixel the skin slides by millimetres.
    assert!(fixed_rms > 1.0, "{fixed_rms} mm");
    // Along the principal axis of the 3D motion, the figures match the material point's.
    let window = frames_averaged(&rig.sequence, &DecodeParams::default());
    let p2p_error = |track: &tremorscan::rig::skin_eval::TrackAgainstTruth| {
        let (measured, truth) = track.principal_figures(window);
        let (measured, truth) = (measured.unwrap(), truth.unwrap());
        let (fm, ft) = (
            measured.peak_frequency_hz.unwrap(),
            truth.peak_frequency_hz.unwrap(),
        );
        let p2p = measured.amplitude_peak_to_peak_mm / truth.amplitude_peak_to_peak_mm - 1.0;
        println!(
            "  principal axis: {fm:.3} Hz ({ft:.3}), peak-to-peak {:.3} mm ({:.3}, {:+.2} %)",
            measured.amplitude_peak_to_peak_mm,
            truth.amplitude_peak_to_peak_mm,
            100.0 * p2p
        );
        assert!((fm - ft).abs() <= 0.05, "{fm} against {ft}");
        p2p
    };
    let p2p = p2p_error(&r.follow);
    assert!(p2p.abs() <= 0.03, "{p2p}");
    // The lateral motion as matched is the decode window's three-frame mean, 1.6 % short at
    // 4.2 Hz; moving the samples to the window's centre takes most of that back.
    let as_matched = p2p_error(&r.follow_window_mean);
    assert!(
        p2p - as_matched > 0.005,
        "{p2p} against {as_matched} as matched"
    );
    // The pixel moves with the skin: it spans the sway's several pixels.
    let vs: Vec<f64> = r
        .follow
        .samples
        .iter()
        .filter_map(|s| s.pixel.map(|p| p.1))
        .collect();
    let span =
        vs.iter().cloned().fold(f64::MIN, f64::max) - vs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 10.0, "v spans {span} px");
}

/// Issue 21's fingertip: the index finger flexing 10 mm at 5.3 Hz (no sway), three seconds.
/// Its fast skin's decoded texture is about as noisy as the texture is strong; before the
/// texture image was low-passed the point lost its match in 24 % of the windows.
#[test]
fn a_fingertip_flexing_ten_millimetres_stays_followed() {
    let flexing = Tremor {
        sway_amplitude_mm: 0.0,
        roll_amplitude_deg: 0.0,
        ..Tremor::flexion(5.3, 10.0, 0.3)
    };
    let rig = rig(flexing, None);
    let r = skin_tracking(&rig, DecodeParams::default(), 363, 0).unwrap();
    let rms = r.follow.rms_mm().unwrap();
    println!(
        "followed: {:.1} % valid, {rms:.3} mm RMS from the material point",
        100.0 * r.follow.valid_share()
    );
    // The share of valid samples at a fingertip control point.
    assert!(r.follow.valid_share() >= 0.95, "{}", r.follow.valid_share());
    // Measured 0.255 mm; before, 0.299 mm over the 76 % of the windows it kept.
    assert!(rms <= 0.3, "{rms} mm");
    let window = frames_averaged(&rig.sequence, &DecodeParams::default());
    let (measured, truth) = r.follow.principal_figures(window);
    let (measured, truth) = (measured.unwrap(), truth.unwrap());
    let (fm, ft) = (
        measured.peak_frequency_hz.unwrap(),
        truth.peak_frequency_hz.unwrap(),
    );
    assert!((fm - ft).abs() <= 0.05, "{fm} against {ft}");
    let p2p = measured.amplitude_peak_to_peak_mm / truth.amplitude_peak_to_peak_mm - 1.0;
    assert!(p2p.abs() <= 0.03, "{p2p}");
}

#[test]
fn a_point_on_a_still_hand_does_not_drift() {
    let still = Tremor::flexion(4.2, 0.0, 0.0);
    let r = skin_tracking(&rig(still, None), DecodeParams::default(), 242, 0).unwrap();
    assert!(r.follow.valid_share() >= 0.99, "{}", r.follow.valid_share());
    let positions: Vec<[f64; 3]> = r
        .follow
        .samples
        .iter()
        .filter_map(|s| s.position_mm)
        .collect();
    let mean = |part: &[[f64; 3]]| {
        [0, 1, 2].map(|a| part.iter().map(|p| p[a]).sum::<f64>() / part.len() as f64)
    };
    // Half a second at either end of the two seconds.
    let (first, last) = (
        mean(&positions[..60]),
        mean(&positions[positions.len() - 60..]),
    );
    let drift = (0..3)
        .map(|a| (last[a] - first[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    println!("drift over 2 s: {drift:.4} mm");
    assert!(drift < 0.05, "{drift} mm");
}

#[test]
fn a_point_on_skin_without_texture_is_refused() {
    let plain = rig(Tremor::flexion(4.2, 0.0, 0.0), Some(0.0));
    let r = skin_tracking(&plain, DecodeParams::default(), 12, 5).unwrap();
    assert!(r.follow.samples.iter().all(|s| s.position_mm.is_none()));
    assert!(r.fixed.samples.iter().all(|s| s.position_mm.is_some()));
    // The reason is kept on the point.
    let mut cloud = tremorscan::triangulate::PointCloud::default();
    let (w, h) = (40, 40);
    cloud.width = w;
    cloud.height = h;
    cloud.point_in_camera_mm = vec![[0.0, 0.0, 500.0]; w * h];
    cloud.colour_rgb = vec![[120, 90, 70]; w * h];
    cloud.fringe_amplitude = vec![1.0; w * h];
    let mut image = TextureImage::default();
    image.fill_from(&cloud);
    let mut point = ControlPoint::new((20.0, 20.0), PointMode::FollowSkin);
    let sample = point.measure(
        &cloud,
        &image,
        0,
        &TrackOptions::default(),
        &FollowOptions::default(),
    );
    assert_eq!(sample.position_mm, None);
    assert!(
        matches!(point.error(), Some(FollowError::NoTexture { .. })),
        "{:?}",
        point.error()
    );
}
