//! A followed fingertip window by window, against the rig's truth, and the decoded texture
//! image against a noiseless one: the figures behind `docs/accuracy.md`'s "Following the skin
//! fast" (2026-12-08).
//!
//! `cargo run --release -p tremorscan --example follow_breakdown -- FRAMES POINT HZ`: the hand
//! flexing `FLEX_MM` (10 by default) at `HZ`, no sway, 640×400. Each line: the texture's spread
//! (`tex_sd`, a noiseless rendering's texture image, the mean of the window's three frame times)
//! and the decoded texture image's error from it (`err_sd`), the fringe-shaped part of the
//! luminance error (`fringe_res`, gray levels), the decoded velocity and brightness change at
//! the point, the correlation of the decoded patch and of the template with the noiseless one,
//! where the decoded patch matches the noiseless one best (`decshift`, px), the error regressed
//! on the noiseless texture's gradient alone and modulated by the finest fringe (`reg`: px,
//! the modulation's size and phase), the valid pixels of
//! the patch, the true pixel of the material point and the follower's (`err`, px).
//! `TEXTURE` sets the skin's texture contrast, `ADVECTED` the advected brightness, `MOTION_OFF`
//! the still window.
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::rig::{RigConfig, Scene, Tremor, VirtualRig};
use tremorscan::tremor::follow::{FollowOptions, SkinFollower, TextureImage};
use tremorscan::triangulate::{PointCloud, Triangulator};

fn ncc(img: &TextureImage, t: &[f64], at: (f64, f64), r: i64) -> f64 {
    let mut v = Vec::new();
    for dy in -r..=r {
        for dx in -r..=r {
            let (x, y) = (
                (at.0 + dx as f64).round() as i64,
                (at.1 + dy as f64).round() as i64,
            );
            if x < 0 || y < 0 || x >= img.width as i64 || y >= img.height as i64 {
                return f64::NAN;
            }
            v.push(f64::from(img.values[y as usize * img.width + x as usize]));
        }
    }
    let n = v.len() as f64;
    let (mi, mt) = (v.iter().sum::<f64>() / n, t.iter().sum::<f64>() / n);
    let (mut c, mut a, mut b) = (0.0, 0.0, 0.0);
    for (i, tt) in v.iter().zip(t) {
        c += (i - mi) * (tt - mt);
        a += (i - mi).powi(2);
        b += (tt - mt).powi(2);
    }
    c / (a * b).sqrt()
}

/// The index of the pixel nearest `at + (dx, dy)` in an image `width` wide.
fn index(at: (f64, f64), dx: i64, dy: i64, width: usize) -> usize {
    let x = (at.0 + dx as f64).round() as usize;
    let y = (at.1 + dy as f64).round() as usize;
    y * width + x
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let frames: u64 = a[0].parse()?;
    let point: usize = a[1].parse()?;
    let hz: f64 = a[2].parse()?;
    let flex: f64 = std::env::var("FLEX_MM")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0);
    let mut config = RigConfig::paper(640, 400)?;
    config.scene.hand = Some(Tremor {
        sway_amplitude_mm: 0.0,
        roll_amplitude_deg: 0.0,
        ..Tremor::flexion(hz, flex, 0.3)
    });
    if let Some(c) = std::env::var("TEXTURE").ok().and_then(|v| v.parse().ok()) {
        config.scene.skin_texture_contrast = c;
    }
    let sequence = config.default_sequence()?;
    let rig = VirtualRig::new(config.clone(), sequence)?;
    let scene = Scene::new(config.scene.clone());
    let mut flat_config = config.clone();
    flat_config.noise = tremorscan::rig::NoiseModel::none();
    let flat_rig = VirtualRig::new(flat_config, rig.sequence.clone())?;
    let mut params = DecodeParams::default();
    if std::env::var("ADVECTED").is_ok() {
        params.motion.advected_brightness = true;
    }
    if std::env::var("MOTION_OFF").is_ok() {
        params.motion.model = tremorscan::decode::MotionModel::Off;
    }
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), config.cross_talk, params)?
        .with_max_span((3.0 - 0.5) / config.fps);
    let tri = Triangulator::new(rig.stereo_model())?;
    let mut cloud = PointCloud::default();
    let mut image = TextureImage::default();
    let mut frame = rig.blank_frame();
    let start: u64 = std::env::var("START")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let mut follower: Option<SkinFollower> = None;
    let mut flat_follower: Option<SkinFollower> = None;
    let mut template: Vec<f64> = Vec::new();
    let r = 8i64;
    for i in 0..frames {
        rig.render(i, &mut frame, None)?;
        let out = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => out,
            _ => continue,
        };
        tri.triangulate(out, &mut cloud)?;
        if i < start {
            continue;
        }
        let (ow, planes) = (out.width, out.frequencies);
        let phase0: Vec<f32> = (0..out.width * out.height)
            .map(|k| out.phase_rad[((k / ow) * planes) * ow + k % ow])
            .collect();
        let vel = out.velocity_px_per_s.clone();
        let kap = out.brightness_rate_per_s.clone();
        image.fill_from(&cloud);
        let m = scene.at(cloud.time_s).points[point];
        let mut flat = rig.blank_frame();
        let mut acc = vec![0.0f64; flat.data.len()];
        let blur_frames: Vec<f64> = if std::env::var("SHARP").is_ok() {
            vec![0.0]
        } else {
            vec![-1.0, 0.0, 1.0]
        };
        for k in &blur_frames {
            flat_rig.render_flat(
                1_000_000 + i,
                [128, 128, 128],
                cloud.time_s + k / config.fps,
                &mut flat,
                None,
            )?;
            for (a, &b) in acc.iter_mut().zip(&flat.data) {
                *a += f64::from(b) / blur_frames.len() as f64;
            }
        }
        let mut flat_cloud = cloud.clone();
        for (k, c) in flat_cloud.colour_rgb.iter_mut().enumerate() {
            *c = [
                acc[3 * k].round() as u8,
                acc[3 * k + 1].round() as u8,
                acc[3 * k + 2].round() as u8,
            ];
        }
        let mut flat_image = TextureImage::default();
        flat_image.fill_from(&flat_cloud);
        let truth = config.camera.project(&m).unwrap_or((f64::NAN, f64::NAN));
        match flat_follower.as_mut() {
            None => {
                flat_follower = SkinFollower::new(&flat_image, truth, FollowOptions::default()).ok()
            }
            Some(f) => {
                let got = f.follow(&flat_image);
                print!(
                    "flaterr {} ",
                    got.map_or("lost".to_string(), |g| format!(
                        "{:5.2} {:5.2}",
                        g.0 - truth.0,
                        g.1 - truth.1
                    ))
                );
            }
        }
        match follower.as_mut() {
            None => {
                follower = Some(SkinFollower::new(&image, truth, FollowOptions::default())?);
                for dy in -r..=r {
                    for dx in -r..=r {
                        template.push(f64::from(image.values[index(truth, dx, dy, image.width)]));
                    }
                }
                println!("placed {truth:?}");
            }
            Some(f) => {
                let got = f.follow(&image);
                let c = ncc(&image, &template, truth, r);
                let mut here = Vec::new();
                for dy in -r..=r {
                    for dx in -r..=r {
                        here.push(f64::from(image.values[index(truth, dx, dy, image.width)]));
                    }
                }
                let vs_flat = ncc(&flat_image, &here, truth, r);
                {
                    let (mut st, mut se, mut mt, mut me, mut nn2) = (0.0, 0.0, 0.0, 0.0, 0.0);
                    for dy in -r..=r {
                        for dx in -r..=r {
                            let k = index(truth, dx, dy, image.width);
                            let t = f64::from(flat_image.values[k]);
                            let e = f64::from(image.values[k]) - t;
                            st += t * t;
                            mt += t;
                            se += e * e;
                            me += e;
                            nn2 += 1.0;
                        }
                    }
                    print!(
                        "tex_sd {:.4} err_sd {:.4} ",
                        (st / nn2 - (mt / nn2).powi(2)).sqrt(),
                        (se / nn2 - (me / nn2).powi(2)).sqrt()
                    );
                }
                let tmpl_flat = ncc(&flat_image, &template, truth, r);
                {
                    // Where the decoded patch at the truth pixel best matches the flat truth.
                    let mut grid = [[0.0f64; 7]; 7];
                    for (j, row) in grid.iter_mut().enumerate() {
                        for (k, g) in row.iter_mut().enumerate() {
                            *g = ncc(
                                &flat_image,
                                &here,
                                (truth.0 + k as f64 - 3.0, truth.1 + j as f64 - 3.0),
                                r,
                            );
                        }
                    }
                    let (mut bj, mut bk) = (3, 3);
                    for j in 1..6 {
                        for k in 1..6 {
                            if grid[j][k] > grid[bj][bk] {
                                bj = j;
                                bk = k;
                            }
                        }
                    }
                    let sub = |a: f64, b: f64, c: f64| 0.5 * (a - c) / (a - 2.0 * b + c);
                    let du =
                        bk as f64 - 3.0 + sub(grid[bj][bk - 1], grid[bj][bk], grid[bj][bk + 1]);
                    let dv =
                        bj as f64 - 3.0 + sub(grid[bj - 1][bk], grid[bj][bk], grid[bj + 1][bk]);
                    print!("decshift {du:5.2} {dv:5.2} ");
                }
                let (mut d2, mut nv, mut n) = (0.0, 0, 0);
                let mut dsum = 0.0;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let k = index(truth, dx, dy, image.width);
                        let l = |c: [u8; 3]| f64::from(c[0]) + f64::from(c[1]) + f64::from(c[2]);
                        let d = l(cloud.colour_rgb[k]) - l(flat_cloud.colour_rgb[k]);
                        d2 += d * d;
                        dsum += d;
                        n += 1;
                        nv += usize::from(cloud.point_in_camera_mm[k][2].is_finite());
                    }
                }
                let nn = n as f64;
                // Fringe-shaped residue: regress the luminance error on cos/sin of the finest phase.
                let mut nm = nalgebra::Matrix3::<f64>::zeros();
                let mut rh = nalgebra::Vector3::<f64>::zeros();
                for dy in -r..=r {
                    for dx in -r..=r {
                        let k = index(truth, dx, dy, image.width);
                        let l = |c: [u8; 3]| f64::from(c[0]) + f64::from(c[1]) + f64::from(c[2]);
                        let d = l(cloud.colour_rgb[k]) - l(flat_cloud.colour_rgb[k]);
                        let ph = f64::from(phase0[k]);
                        let j = nalgebra::Vector3::new(1.0, ph.cos(), ph.sin());
                        nm += j * j.transpose();
                        rh += j * d;
                    }
                }
                let sol = nm.try_inverse().map(|m| m * rh).unwrap_or_default();
                {
                    // The texture error regressed on the truth texture's gradient, alone and
                    // modulated by the finest fringe.
                    let mut nm = nalgebra::SMatrix::<f64, 7, 7>::zeros();
                    let mut rh = nalgebra::SVector::<f64, 7>::zeros();
                    let r2 = 2 * r;
                    for dy in -r2..=r2 {
                        for dx in -r2..=r2 {
                            let k = index(truth, dx, dy, image.width);
                            let f = |k: usize| f64::from(flat_image.values[k]);
                            let gu = 0.5 * (f(k + 1) - f(k - 1));
                            let gv = 0.5 * (f(k + image.width) - f(k - image.width));
                            let e = f64::from(image.values[k]) - f(k);
                            let ph = f64::from(phase0[k]);
                            let j = nalgebra::SVector::<f64, 7>::from([
                                gu,
                                gv,
                                gu * ph.cos(),
                                gu * ph.sin(),
                                gv * ph.cos(),
                                gv * ph.sin(),
                                f(k),
                            ]);
                            nm += j * j.transpose();
                            rh += j * e;
                        }
                    }
                    if let Some(inv) = nm.try_inverse() {
                        let b = inv * rh;
                        print!(
                            "reg du {:5.2} dv {:5.2} mod_u {:5.2} at {:6.1}° mod_v {:5.2} gain {:5.2} ",
                            b[0],
                            b[1],
                            b[2].hypot(b[3]),
                            b[3].atan2(b[2]).to_degrees(),
                            b[4].hypot(b[5]),
                            b[6]
                        );
                    }
                }
                let kc = truth.0.round() as usize + truth.1.round() as usize * image.width;
                print!(
                    "fringe_res {:4.1} vel {:7.1} kap {:6.2} ",
                    sol[1].hypot(sol[2]),
                    vel[kc],
                    kap[kc]
                );
                print!(
                    "dec~flat {vs_flat:.3} tmpl~flat {tmpl_flat:.3} dlum_sd {:5.1} valid {:3}/{n} ",
                    (d2 / nn - (dsum / nn).powi(2)).sqrt(),
                    nv
                );
                let x = truth.0.round() as usize + truth.1.round() as usize * image.width;
                println!(
                    "{i:4} truth {:7.2} {:7.2} got {} ncc_truth {c:.3} valid_frac_at {:.2} amp {:.1}",
                    truth.0,
                    truth.1,
                    got.map_or("lost".to_string(), |g| format!("{:7.2} {:7.2} err {:5.2}", g.0, g.1, (g.0 - truth.0).hypot(g.1 - truth.1))),
                    f64::from(u8::from(cloud.point_in_camera_mm[x][2].is_finite())),
                    cloud.fringe_amplitude[x],
                );
            }
        }
    }
    Ok(())
}
