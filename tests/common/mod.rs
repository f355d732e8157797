//! Shared helpers of the integration tests: render a window with the virtual rig and decode it.
#![allow(
    dead_code,
    unused_imports,
    reason = "each test binary uses a different subset of the helpers"
)]

use tremorscan::decode::{DecodeOutput, DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::pattern::PatternSequence;
use tremorscan::rig::evaluate::{compare, Accuracy};
use tremorscan::rig::{GroundTruth, NoiseModel, RigConfig, SceneConfig, VirtualRig};

/// The paper rig at 640×400 with a still hand (no tremor) and the given noise.
pub fn still_hand_rig(noise: NoiseModel) -> RigConfig {
    still_hand_rig_at(noise, 640, 400)
}

/// [`still_hand_rig`] with the camera binned to `width`×`height` instead of 640×400.
#[allow(dead_code, reason = "each test binary uses its own helpers")]
pub fn still_hand_rig_at(noise: NoiseModel, width: usize, height: usize) -> RigConfig {
    let mut config = RigConfig::paper(width, height).unwrap();
    config.noise = noise;
    config.scene = SceneConfig {
        hand: config.scene.hand.map(|mut t| {
            t.tip_amplitude_mm = 0.0;
            t.hand_amplitude_mm = 0.0;
            t
        }),
        ..config.scene
    };
    config
}

/// Renders one full sequence of `seq` with `config`, decodes the window, and compares it with the
/// truth of the middle frame. Returns the accuracy and the decoded output.
pub fn decode_once(
    config: RigConfig,
    seq: &PatternSequence,
    params: DecodeParams,
) -> (Accuracy, DecodeOutput) {
    let finest = *seq.distinct_frequencies().first().unwrap();
    let half_period = seq.period_px(finest) / 2.0;
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let mut decoder = SlidingDecoder::new(seq.clone(), rig.config.cross_talk, params).unwrap();
    let len = seq.entries.len() as u64;
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in 0..len {
        let t = if i == len / 2 { Some(&mut truth) } else { None };
        rig.render(i, &mut frame, t).unwrap();
        let outcome = decoder.push(&frame).unwrap();
        assert_eq!(matches!(outcome, WindowOutcome::Decoded(_)), i + 1 == len);
    }
    let out = decoder.output().unwrap().clone();
    (compare(&out, &truth, half_period), out)
}

/// Decode parameters with every validity check after the signal checks switched off.
pub fn checks_off(mut params: DecodeParams) -> DecodeParams {
    params.max_rounding_residual = 0.5;
    params.max_disagreement_chi2 = f32::INFINITY;
    params.smoothing.min_support = 0.0;
    params.check_order_jumps = false;
    params.mixed_limit_px = 0.0;
    params
}

mod scratch;
pub use scratch::{scratch, scratch_dir, Scratch};

/// Frames `numbers` of the rig's stream, rendered without ground truth.
pub fn rendered(rig: &VirtualRig, numbers: std::ops::Range<u64>) -> Vec<tremorscan::frame::Frame> {
    numbers
        .map(|i| {
            let mut f = rig.blank_frame();
            rig.render(i, &mut f, None).unwrap();
            f
        })
        .collect()
}

/// The paper rig at `width`×`height` with the trembling hand and its default sequence.
pub fn rig(width: usize, height: usize) -> VirtualRig {
    let config = RigConfig::paper(width, height).unwrap();
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

/// Frame `index` of `rig`'s stream with its red channel from the pattern a quarter period on
/// (`VirtualRig::render_with_shifted_red`): a corrupted transfer.
pub fn corrupted_red(rig: &VirtualRig, index: u64) -> tremorscan::frame::Frame {
    corrupted_red_rows(rig, index, 0..rig.height())
}

/// [`corrupted_red`] on image rows `rows` only: a band of rows from another exposure.
pub fn corrupted_red_rows(
    rig: &VirtualRig,
    index: u64,
    rows: std::ops::Range<usize>,
) -> tremorscan::frame::Frame {
    let mut frame = rig.blank_frame();
    rig.render_with_shifted_red_on_rows(index, std::f64::consts::FRAC_PI_2, rows, &mut frame)
        .unwrap();
    frame
}

/// The paper rig at 640×400 with the hand's fingertip trembling `amplitude_mm` along the
/// optical axis, swaying `sway_mm` sideways and rolling `roll_deg` (the motion sweep's rig).
pub fn trembling_hand(amplitude_mm: f64, sway_mm: f64, roll_deg: f64) -> VirtualRig {
    let mut config = RigConfig::paper(640, 400).unwrap();
    let tremor = config.scene.hand.as_mut().unwrap();
    tremor.tip_amplitude_mm = amplitude_mm;
    tremor.sway_amplitude_mm = sway_mm;
    tremor.roll_amplitude_deg = roll_deg;
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

/// Two decoders' coordinates over the same windows, pixel by pixel, away from motion.
#[derive(Debug, Default)]
pub struct StillPixelsCompared {
    /// Windows both decoded.
    pub windows: usize,
    /// Pixel-windows where either decoder found motion (not compared).
    pub moving: usize,
    /// Pixel-windows the first decoder found valid.
    pub valid: usize,
    /// Pixel-windows without motion whose coordinates differ in any bit (NaN included).
    pub differing: usize,
    /// The largest difference among them where both are valid, projector px.
    pub worst_px: f32,
}

/// Frames `0..frames` of `rig` through a decoder with `a` and one with `b`, compared as
/// [`StillPixelsCompared`] says.
pub fn still_pixels_compared(
    rig: &VirtualRig,
    a: DecodeParams,
    b: DecodeParams,
    frames: u64,
) -> StillPixelsCompared {
    let decoder =
        |params| SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params).unwrap();
    let (mut first, mut second) = (decoder(a), decoder(b));
    let mut frame = rig.blank_frame();
    let mut result = StillPixelsCompared::default();
    for i in 0..frames {
        rig.render(i, &mut frame, None).unwrap();
        let decoded = |outcome| match outcome {
            WindowOutcome::Decoded(out) => {
                Some((out.coordinate_px.clone(), out.velocity_px_per_s.clone()))
            }
            _ => None,
        };
        let x = decoded(first.push(&frame).unwrap());
        let y = decoded(second.push(&frame).unwrap());
        let (Some((x, x_velocity)), Some((y, y_velocity))) = (x, y) else {
            continue;
        };
        for p in 0..x.len() {
            let moves = x_velocity[p] != 0.0 || y_velocity[p] != 0.0;
            result.moving += usize::from(moves);
            result.valid += usize::from(x[p].is_finite());
            if !(moves || x[p].to_bits() == y[p].to_bits()) {
                result.differing += 1;
                if x[p].is_finite() && y[p].is_finite() {
                    result.worst_px = result.worst_px.max((x[p] - y[p]).abs());
                }
            }
        }
        result.windows += 1;
    }
    eprintln!("{result:?}");
    result
}
