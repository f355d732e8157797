//! `tremorscan snapshot`: one decoded window of the virtual rig written as PNG images, to look at.
//!
//! Writes `frame.png` (the raw middle camera frame), `colour.png` (the decoded offset colour),
//! `coordinate.png` (projector coordinate, false colour, invalid pixels dark blue) and
//! `error.png` (gray where right, red where the fringe order is wrong, dark blue where invalid).

use anyhow::{Context, Result};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use tremorscan::decode::{DecodeParams, SlidingDecoder, UnwrapMethod};
use tremorscan::rig::{GroundTruth, RigConfig, VirtualRig};

#[derive(clap::Args, Debug, Clone)]
pub struct SnapshotArgs {
    /// Folder to write the PNG files into (created if missing).
    #[arg(long, default_value = "snapshot")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 400)]
    pub height: usize,
    /// First frame of the window (the tremor phase changes with it).
    #[arg(long, default_value_t = 0)]
    pub frame: u64,
    #[command(flatten)]
    pub unwrap: crate::unwrap_args::UnwrapArgs,
}

const INVALID_RGB: [u8; 3] = [0, 0, 80];

fn write_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .with_context(|| format!("writing {}", path.display()))?;
    writer
        .write_image_data(rgb)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// A smooth blue–green–yellow–red ramp for `t` in `[0, 1]`.
fn ramp(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let r = (1.5 - (4.0 * t - 3.0).abs()).clamp(0.0, 1.0);
    let g = (1.5 - (4.0 * t - 2.0).abs()).clamp(0.0, 1.0);
    let b = (1.5 - (4.0 * t - 1.0).abs()).clamp(0.0, 1.0);
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

pub fn run(args: &SnapshotArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let config =
        RigConfig::paper(args.width, args.height).context("configuring the virtual rig")?;
    let seq = config.default_sequence()?;
    let half_period = seq.period_px(65) / 2.0;
    let rig = VirtualRig::new(config, seq.clone())?;
    let (unwrap, _) = UnwrapMethod::resolve(args.unwrap.requested(), &seq)?;
    let params = DecodeParams {
        unwrap,
        smoothing: args.unwrap.smoothing(),
        ..DecodeParams::default()
    };
    let mut decoder = SlidingDecoder::new(seq.clone(), rig.config.cross_talk, params)?;
    let (w, h) = (rig.width(), rig.height());
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in args.frame..args.frame + 3 {
        let middle = i == args.frame + 1;
        rig.render(i, &mut frame, middle.then_some(&mut truth))?;
        if middle {
            write_png(&args.out.join("frame.png"), w, h, &frame.data)?;
        }
        decoder.push(&frame)?;
    }
    let out = decoder.output().context("the window did not decode")?;
    let mut colour = vec![0u8; w * h * 3];
    let mut coordinate = vec![0u8; w * h * 3];
    let mut error = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            for c in 0..3 {
                colour[p * 3 + c] = out.colour_at(c, x, y).clamp(0.0, 255.0) as u8;
            }
            let value = out.coordinate_px[p];
            let px = if value.is_finite() {
                ramp(value / seq.x_max as f32)
            } else {
                INVALID_RGB
            };
            coordinate[p * 3..p * 3 + 3].copy_from_slice(&px);
            let expected = truth.coordinate_px[p];
            let px = if !value.is_finite() {
                INVALID_RGB
            } else if !expected.is_finite() || f64::from((value - expected).abs()) > half_period {
                [255, 0, 0]
            } else {
                [150, 150, 150]
            };
            error[p * 3..p * 3 + 3].copy_from_slice(&px);
        }
    }
    write_png(&args.out.join("colour.png"), w, h, &colour)?;
    write_png(&args.out.join("coordinate.png"), w, h, &coordinate)?;
    write_png(&args.out.join("error.png"), w, h, &error)?;
    println!(
        "wrote frame.png, colour.png, coordinate.png, error.png to {} ({} of {} pixels valid)",
        args.out.display(),
        out.valid_count(),
        w * h
    );
    Ok(())
}
