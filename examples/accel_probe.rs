//! Scratch: the still hand of tests/motion_decode.rs; where velocity and acceleration appear.
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::rig::{RigConfig, VirtualRig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut config = RigConfig::paper(640, 400)?;
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = 0.0;
        t.sway_amplitude_mm = 0.0;
        t.roll_amplitude_deg = 0.0;
    }
    let seq = config.default_sequence()?;
    let rig = VirtualRig::new(config, seq.clone())?;
    let mut params = DecodeParams::default();
    params.smoothing.transport = std::env::var("TRANSPORT").is_ok();
    if let Some(v) = std::env::var("UNIT_DECAY")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        params.smoothing.decay = v;
    }
    let frames: u64 = std::env::var("FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(9);
    let mut dec = SlidingDecoder::new(seq, rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut prev_valid: Vec<u16> = vec![];
    let (mut moving, mut accel) = (0, 0);
    for i in 0..frames {
        rig.render(i, &mut frame, None)?;
        if let WindowOutcome::Decoded(out) = dec.push(&frame)? {
            let w = out.width;
            for p in 0..w * out.height {
                let v = out.velocity_px_per_s[p];
                let a = out.acceleration_px_per_s2[p];
                if v != 0.0 || a != 0.0 {
                    println!(
                        "frame {i} px ({},{}) v {v:.1} a {a:.1} flags {:x} prev flags {:x?}",
                        p % w,
                        p / w,
                        out.invalid[p],
                        prev_valid.get(p)
                    );
                    moving += usize::from(v != 0.0);
                    accel += usize::from(a != 0.0);
                }
            }
            prev_valid = out.invalid.clone();
        }
    }
    println!("moving {moving} accelerating {accel}");
    Ok(())
}
