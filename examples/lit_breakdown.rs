//! Where the noise sweep's lit pixels are lost: the still hand of `tremorscan sweep` (same rig,
//! seed and decode settings), decoded with the default decoder, its lit pixels (the truth's ray
//! meets a lit surface) tallied by their distance to the nearest edge of the truth (a pixel that
//! is unlit, or whose 4-neighbour is unlit, on another surface or more than 3 projector px away
//! in coordinate), with the share refused and the refused pixels' flags.
//!
//! `cargo run --release -p tremorscan --example lit_breakdown -- [SIGMA…]` (default: 0 2)

use std::collections::BTreeMap;
use tremorscan::decode::{DecodeOutput, DecodeParams, SlidingDecoder};
use tremorscan::rig::{GroundTruth, NoiseModel, RigConfig, VirtualRig};

const WIDTH: usize = 640;
const HEIGHT: usize = 400;
/// Distances tallied one by one; farther ones share the last row.
const FAR_PX: usize = 5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sigmas: Vec<f64> = match std::env::args().skip(1).map(|a| a.parse()).collect() {
        Ok(v) if !Vec::is_empty(&v) => v,
        Ok(_) => vec![0.0, 2.0],
        Err(e) => return Err(format!("a noise level is not a number: {e}").into()),
    };
    for sigma in sigmas {
        let (out, truth) = decode_still_hand(sigma)?;
        report(sigma, &out, &truth);
    }
    Ok(())
}

/// The sweep's still hand at noise `sigma`, decoded as the sweep decodes it (checks on).
fn decode_still_hand(
    sigma: f64,
) -> Result<(DecodeOutput, GroundTruth), Box<dyn std::error::Error>> {
    let mut config = RigConfig::paper(WIDTH, HEIGHT)?;
    config.noise = NoiseModel::gaussian(sigma);
    config.seed = 1;
    if let Some(t) = config.scene.hand.as_mut() {
        t.tip_amplitude_mm = 0.0;
        t.hand_amplitude_mm = 0.0;
    }
    let seq = config.default_sequence()?;
    let rig = VirtualRig::new(config, seq)?;
    let params = DecodeParams {
        camera_noise_gray: (sigma as f32).max(1.0),
        ..DecodeParams::default()
    };
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params)?;
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    for i in 0..3 {
        rig.render(i, &mut frame, (i == 1).then_some(&mut truth))?;
        decoder.push(&frame)?;
    }
    let out = decoder.output().ok_or("the window did not decode")?.clone();
    Ok((out, truth))
}

/// Each pixel's distance to the nearest edge of the truth (8-connected steps), up to
/// [`FAR_PX`].
fn edge_distance(truth: &GroundTruth) -> Vec<usize> {
    let (w, h) = (WIDTH, HEIGHT);
    let lit = |p: usize| truth.coordinate_px[p].is_finite();
    let neighbours = |p: usize, diagonal: bool| {
        let (x, y) = ((p % w) as i64, (p / w) as i64);
        let steps: &[(i64, i64)] = if diagonal {
            &[
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (1, -1),
                (-1, 1),
                (-1, -1),
            ]
        } else {
            &[(1, 0), (-1, 0), (0, 1), (0, -1)]
        };
        steps
            .iter()
            .map(move |(dx, dy)| (x + dx, y + dy))
            .filter(|&(xx, yy)| xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64)
            .map(|(xx, yy)| yy as usize * w + xx as usize)
            .collect::<Vec<_>>()
    };
    let mut distance: Vec<usize> = (0..w * h)
        .map(|p| {
            let edge = !lit(p)
                || neighbours(p, false).into_iter().any(|q| {
                    !lit(q)
                        || truth.surface[q] != truth.surface[p]
                        || (truth.coordinate_px[q] - truth.coordinate_px[p]).abs() > 3.0
                });
            if edge {
                0
            } else {
                FAR_PX
            }
        })
        .collect();
    for d in 1..FAR_PX {
        let next: Vec<usize> = (0..w * h)
            .map(|p| {
                let near = neighbours(p, true)
                    .into_iter()
                    .any(|q| distance[q] == d - 1);
                if distance[p] == FAR_PX && near {
                    d
                } else {
                    distance[p]
                }
            })
            .collect();
        distance = next;
    }
    distance
}

fn report(sigma: f64, out: &DecodeOutput, truth: &GroundTruth) {
    let distance = edge_distance(truth);
    let mut rows = [(0usize, 0usize); FAR_PX + 1];
    let mut flags: BTreeMap<u16, usize> = BTreeMap::new();
    let mut flags_inside: BTreeMap<u16, usize> = BTreeMap::new();
    for p in (0..WIDTH * HEIGHT).filter(|&p| truth.coordinate_px[p].is_finite()) {
        let row = &mut rows[distance[p]];
        row.0 += 1;
        if out.invalid[p] != 0 {
            row.1 += 1;
            *flags.entry(out.invalid[p]).or_default() += 1;
            if distance[p] > 2 {
                *flags_inside.entry(out.invalid[p]).or_default() += 1;
            }
        }
    }
    let share = |(lit, refused): (usize, usize)| 100.0 * refused as f64 / lit.max(1) as f64;
    let total = rows.iter().fold((0, 0), |a, r| (a.0 + r.0, a.1 + r.1));
    println!(
        "σ = {sigma}: {} lit, {:.2} % valid ({} refused)",
        total.0,
        100.0 - share(total),
        total.1
    );
    for (d, &row) in rows.iter().enumerate() {
        let far = if d == FAR_PX { "+" } else { "" };
        println!(
            "  {d}{far} px from an edge: {} lit, {:.2} % refused",
            row.0,
            share(row)
        );
    }
    let inside = rows[3..].iter().fold((0, 0), |a, r| (a.0 + r.0, a.1 + r.1));
    println!(
        "  more than 2 px from an edge: {:.3} % valid",
        100.0 - share(inside)
    );
    println!("  flags of the refused (all): {flags:?}");
    println!("  flags of the refused (more than 2 px from an edge): {flags_inside:?}");
}
