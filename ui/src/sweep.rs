//! `tremorscan sweep`: unwrap robustness against camera noise, as a Markdown table.
//!
//! For each noise level the still hand is rendered once (seeded), and the same frames are decoded
//! with the paper's per-pixel formula (a) and the robust estimate (b), each with the validity
//! checks after the signal checks off (what the unwrap itself achieves) and on (what the
//! application reports). The decoder is told the noise level it runs at.

use anyhow::{Context, Result};
use tremorscan::decode::{DecodeParams, SlidingDecoder, UnwrapMethod};
use tremorscan::rig::evaluate::{compare, Accuracy};
use tremorscan::rig::{GroundTruth, NoiseModel, RigConfig, VirtualRig};

#[derive(clap::Args, Debug, Clone)]
pub struct SweepArgs {
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 400)]
    pub height: usize,
    /// Noise levels (σ, gray levels), comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0])]
    pub sigmas: Vec<f64>,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sweep the tremor amplitude instead (moving fingertips, default noise): depth coverage,
    /// gross errors and RMS of moving skin, along the optical axis and with lateral sway.
    #[arg(long)]
    pub motion: bool,
    /// Peak fingertip amplitudes for `--motion`, mm, comma separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.0, 2.0, 5.0, 10.0, 20.0])]
    pub amplitudes_mm: Vec<f64>,
    /// Frames rendered per amplitude for `--motion` (every third window is compared).
    #[arg(long, default_value_t = 40)]
    pub frames: u64,
    /// Frames of the fingertip trials for `--motion` (3 s at 121 FPS; 0 leaves them out).
    #[arg(long, default_value_t = 363)]
    pub tip_frames: u64,
    /// For `--motion`: the motion model with its brightness change carried with the image
    /// (`MotionParams::advected_brightness`, opt-in, CPU only).
    #[arg(long)]
    pub advected_brightness: bool,
    /// For `--motion`: the motion model's steps from rest in every window, as before the
    /// predicted start (`MotionParams::predicted_start` off).
    #[arg(long)]
    pub from_rest: bool,
}

fn decode(rig: &VirtualRig, params: DecodeParams) -> Result<Accuracy> {
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in 0..3 {
        rig.render(i, &mut frame, if i == 1 { Some(&mut truth) } else { None })?;
        decoder.push(&frame)?;
    }
    let out = decoder.output().context("the window did not decode")?;
    Ok(compare(out, &truth, rig.sequence.period_px(65) / 2.0))
}

pub fn run(args: &SweepArgs) -> Result<()> {
    if args.motion {
        return crate::sweep_motion::run(args);
    }
    println!("| σ (gray) | method | checks | valid % of lit | unwrap errors % of valid | RMS px |");
    println!("|---:|---|---|---:|---:|---:|");
    for &sigma in &args.sigmas {
        let mut config = RigConfig::paper(args.width, args.height)?;
        config.noise = NoiseModel::gaussian(sigma);
        config.seed = args.seed;
        if let Some(t) = config.scene.hand.as_mut() {
            t.tip_amplitude_mm = 0.0;
            t.hand_amplitude_mm = 0.0;
        }
        let seq = config.default_sequence()?;
        let rig = VirtualRig::new(config, seq)?;
        for (name, method) in [
            ("(a) per-pixel", UnwrapMethod::ChebyshevPerPixel),
            ("(b) robust", UnwrapMethod::ChebyshevRobust),
        ] {
            for checks in [false, true] {
                // The decoder is told the camera noise, as an operator who measured it would;
                // below 1 gray level the 6-bit and 8-bit quantisation set the floor.
                let mut params = DecodeParams {
                    unwrap: method,
                    camera_noise_gray: sigma.max(1.0) as f32,
                    ..DecodeParams::default()
                };
                if !checks {
                    params.max_rounding_residual = 0.5;
                    params.max_disagreement_chi2 = f32::INFINITY;
                    params.smoothing.min_support = 0.0;
                    params.check_order_jumps = false;
                    // The mixed-pixel stage tests coordinates too: off, as the column says.
                    params.mixed_limit_px = 0.0;
                }
                let acc = decode(&rig, params)
                    .with_context(|| format!("decoding σ = {sigma} with {name}"))?;
                println!(
                    "| {sigma:.1} | {name} | {} | {:.2} | {:.3} | {:.4} |",
                    if checks { "on" } else { "off" },
                    100.0 * acc.coverage(),
                    100.0 * acc.unwrap_error_rate(),
                    acc.rms_px
                );
            }
        }
    }
    Ok(())
}
