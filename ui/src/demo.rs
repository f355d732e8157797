//! `tremorscan demo`: the virtual rig streamed through the sliding-window decoder and the
//! triangulation, with the error against the rig's ground truth.

use anyhow::{Context, Result};
use nalgebra::Vector3;
use std::time::Instant;
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::rig::evaluate::compare;
use tremorscan::rig::{GroundTruth, RigConfig, VirtualRig, POINT_NAMES};
use tremorscan::triangulate::{PointCloud, Triangulator};

#[derive(clap::Args, Debug, Clone)]
pub struct DemoArgs {
    /// Camera width in pixels (the 1920×1200 sensor is binned to this).
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    /// Camera height in pixels.
    #[arg(long, default_value_t = 400)]
    pub height: usize,
    /// Number of camera frames to stream.
    #[arg(long, default_value_t = 121)]
    pub frames: u64,
    /// Print one line every this many frames.
    #[arg(long, default_value_t = 10)]
    pub every: u64,
}

impl Default for DemoArgs {
    fn default() -> Self {
        Self {
            width: 640,
            height: 400,
            frames: 121,
            every: 10,
        }
    }
}

pub fn run(args: &DemoArgs) -> Result<()> {
    let config =
        RigConfig::paper(args.width, args.height).context("configuring the virtual rig")?;
    let seq = config
        .default_sequence()
        .context("building the CPS-RGB sequence")?;
    let half_period = seq.period_px(65) / 2.0;
    let rig = VirtualRig::new(config, seq.clone()).context("building the virtual rig")?;
    // A window without drops spans two frame periods; allow half a period of jitter.
    let mut decoder = SlidingDecoder::new(seq, rig.config.cross_talk, DecodeParams::default())
        .context("creating the decoder")?
        .with_max_span(2.5 / rig.config.fps);
    println!(
        "tremorscan demo: virtual rig {}×{} at {} FPS, CPS-RGB n = 65 on 912 projector columns",
        rig.width(),
        rig.height(),
        rig.config.fps
    );
    println!(
        "{:>6} {:>8} {:>8} {:>9} {:>9} {:>10} {:>10} {:>8} {:>11} {:>11}",
        "frame",
        "time_s",
        "valid%",
        "rms_px",
        "unwrap!",
        "render_ms",
        "decode_ms",
        "tri_ms",
        "tip_z_true",
        "tip_z_meas"
    );
    let mut frame = rig.blank_frame();
    // Truth of the last two frames: a window is compared with its middle frame.
    let mut truths = [GroundTruth::default(), GroundTruth::default()];
    let (mut render_total, mut decode_total, mut decoded) = (0.0, 0.0, 0u64);
    let mut triangulate_total = 0.0;
    let triangulator =
        Triangulator::new(rig.stereo_model()).context("precomputing the triangulation")?;
    let mut cloud = PointCloud::default();
    for i in 0..args.frames {
        let started = Instant::now();
        let slot = (i % 2) as usize;
        rig.render(i, &mut frame, Some(&mut truths[slot]))
            .with_context(|| format!("rendering frame {i}"))?;
        let render_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let outcome = decoder
            .push(&frame)
            .with_context(|| format!("decoding frame {i}"))?;
        let decode_ms = started.elapsed().as_secs_f64() * 1e3;
        render_total += render_ms;
        if let WindowOutcome::Decoded(out) = outcome {
            decoded += 1;
            decode_total += decode_ms;
            let started = Instant::now();
            triangulator
                .triangulate(out, &mut cloud)
                .with_context(|| format!("triangulating frame {i}"))?;
            let triangulate_ms = started.elapsed().as_secs_f64() * 1e3;
            triangulate_total += triangulate_ms;
            if i % args.every == 0 {
                let middle = &truths[1 - slot];
                let acc = compare(out, middle, half_period);
                let tip = middle.points_in_camera.first();
                let true_z = tip.map_or(f64::NAN, |p| p.z);
                let measured_z = tip.map_or(f64::NAN, |p| depth_at(&cloud, &rig, p));
                println!(
                    "{:>6} {:>8.4} {:>8.2} {:>9.4} {:>9} {:>10.2} {:>10.2} {:>8.2} {:>11.3} {:>11.3}",
                    i,
                    out.time_s,
                    100.0 * out.valid_count() as f64 / (out.width * out.height) as f64,
                    acc.rms_px,
                    acc.unwrap_errors,
                    render_ms,
                    decode_ms,
                    triangulate_ms,
                    true_z,
                    measured_z
                );
            }
        }
    }
    println!(
        "{} frames, {} windows decoded, {} unsolvable, {} too spread in time; mean render {:.2} ms, decode {:.2} ms, triangulate {:.2} ms",
        args.frames,
        decoded,
        decoder.unsolvable_windows,
        decoder.spread_windows,
        render_total / args.frames.max(1) as f64,
        decode_total / decoded.max(1) as f64,
        triangulate_total / decoded.max(1) as f64
    );
    println!(
        "tip_z: depth of the {} surface point, true and measured at its pixel (mm); tracked truth points: {}",
        POINT_NAMES[0],
        POINT_NAMES.join(", ")
    );
    Ok(())
}

/// Measured depth at the camera pixel where `point_in_camera` appears (NaN when invalid).
fn depth_at(cloud: &PointCloud, rig: &VirtualRig, point_in_camera: &Vector3<f64>) -> f64 {
    let Some((u, v)) = rig.config.camera.project(point_in_camera) else {
        return f64::NAN;
    };
    let (x, y) = (u.round(), v.round());
    if x < 0.0 || y < 0.0 || x >= cloud.width as f64 || y >= cloud.height as f64 {
        return f64::NAN;
    }
    let p = y as usize * cloud.width + x as usize;
    f64::from(cloud.point_in_camera_mm[p][2])
}
