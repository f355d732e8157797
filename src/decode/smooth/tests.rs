use super::*;
use crate::decode::WindowSolver;
use crate::pattern::{cps_rgb, Axis};

fn output(w: usize, h: usize) -> DecodeOutput {
    let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
    let solver = WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
    DecodeOutput::new(w, h, &solver)
}

#[test]
fn constant_field_keeps_its_angle_and_grows_support() {
    let (w, h) = (40, 30);
    let mut out = output(w, h);
    out.unit_re.fill(0.6);
    out.unit_im.fill(0.8);
    out.support.fill(1.0);
    out.colour.fill(100.0);
    smooth_unit_phasor(&mut out, &SmoothingParams::default(), None);
    let centre = 15 * w + 20;
    let angle = out.unit_im[centre].atan2(out.unit_re[centre]);
    assert!((angle - 0.8f32.atan2(0.6)).abs() < 1e-5);
    // 1D gain (1+a)/(1−a) = 5.67 per axis, about 32 in 2D away from borders.
    assert!(out.support[centre] > 25.0, "{}", out.support[centre]);
}

#[test]
fn phase_edge_stops_the_averaging() {
    let (w, h) = (40, 20);
    let mut out = output(w, h);
    out.support.fill(1.0);
    out.colour.fill(100.0);
    // Left half: angle 0.5 rad, guide phase 0; right half: angle 2.5 rad, guide phase 3.
    for y in 0..h {
        for x in 0..w {
            let left = x < w / 2;
            let a: f32 = if left { 0.5 } else { 2.5 };
            out.unit_re[y * w + x] = a.cos();
            out.unit_im[y * w + x] = a.sin();
            for f in 0..3 {
                out.phase_rad[(y * 3 + f) * w + x] = if left { 0.0 } else { 3.0 };
            }
        }
    }
    smooth_unit_phasor(&mut out, &SmoothingParams::default(), None);
    let p = 10 * w + w / 2 - 1;
    let q = p + 1;
    assert!((out.unit_im[p].atan2(out.unit_re[p]) - 0.5).abs() < 1e-4);
    assert!((out.unit_im[q].atan2(out.unit_re[q]) - 2.5).abs() < 1e-4);
}

/// Forward + backward recursion over one line: `g[i]` links element i to i + 1.
fn recurse_line(v: &[f32], g: &[f32]) -> Vec<f32> {
    let n = v.len();
    let mut fwd = vec![0.0; n];
    let mut bwd = vec![0.0; n];
    for i in 0..n {
        fwd[i] = v[i] + if i > 0 { g[i - 1] * fwd[i - 1] } else { 0.0 };
    }
    for i in (0..n).rev() {
        bwd[i] = v[i] + if i + 1 < n { g[i] * bwd[i + 1] } else { 0.0 };
    }
    (0..n).map(|i| fwd[i] + bwd[i] - v[i]).collect()
}

/// The straightforward recursion over whole rows, then whole columns.
fn reference(v: &[f32], links: &[u8], w: usize, h: usize, a: f32) -> Vec<f32> {
    let gain = |i: usize, bit: u8| if links[i] & bit != 0 { a } else { 0.0 };
    let mut horiz = vec![0.0; w * h];
    for y in 0..h {
        let g: Vec<f32> = (0..w).map(|x| gain(y * w + x, RIGHT)).collect();
        horiz[y * w..(y + 1) * w].copy_from_slice(&recurse_line(&v[y * w..(y + 1) * w], &g));
    }
    let mut out = vec![0.0; w * h];
    for x in 0..w {
        let g: Vec<f32> = (0..h).map(|y| gain(y * w + x, DOWN)).collect();
        let col: Vec<f32> = (0..h).map(|y| horiz[y * w + x]).collect();
        for (y, value) in recurse_line(&col, &g).into_iter().enumerate() {
            out[y * w + x] = value;
        }
    }
    out
}

/// Random planes over `w×h` pixels, each link cut with probability `cut`, smoothed by
/// [`smooth_planes`] at `decay` and compared with [`reference`].
fn blocked_against_plain(w: usize, h: usize, decay: f32, cut: f32) {
    let mut out = output(w, h);
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as f32 / (1u64 << 31) as f32
    };
    for i in 0..w * h {
        out.unit_re[i] = next() * 2.0 - 1.0;
        out.unit_im[i] = next() * 2.0 - 1.0;
        out.support[i] = f32::from(next() > 0.1);
        out.connect[i] = (u8::from(next() > cut) * RIGHT) | (u8::from(next() > cut) * DOWN);
    }
    for x in 0..w {
        out.connect[(h - 1) * w + x] &= !DOWN;
    }
    for y in 0..h {
        out.connect[y * w + w - 1] &= !RIGHT;
    }
    let expected: Vec<Vec<f32>> = [&out.unit_re, &out.unit_im, &out.support]
        .iter()
        .map(|v| reference(v, &out.connect, w, h, decay))
        .collect();
    smooth_planes(&mut Planes::of_unit_phasor(&mut out), decay);
    for (got, want) in [&out.unit_re, &out.unit_im, &out.support]
        .iter()
        .zip(&expected)
    {
        for (g, e) in got.iter().zip(want) {
            assert!(
                (g - e).abs() <= 1e-5 * (1.0 + e.abs()),
                "{decay}: {g} vs {e}"
            );
        }
    }
}

#[test]
fn blocked_parallel_passes_match_the_plain_recursion() {
    // 301 rows: two vertical blocks, the last one shorter; mostly connected, with random
    // cuts in both directions.
    blocked_against_plain(37, 301, 0.7, 0.15);
}

#[test]
fn blocked_passes_stay_exact_at_the_full_resolution_reach() {
    // The decays at 1920 px wide (0.7 and 0.8 raised to the power 1/3) over long unbroken
    // columns: with a fixed 48-row warm-up the blocks lost up to 3 % of each sum at their
    // boundaries (0.928⁴⁸).
    for decay in [0.7f32.powf(1.0 / 3.0), 0.8f32.powf(1.0 / 3.0)] {
        blocked_against_plain(23, 1200, decay, 0.0);
    }
}

#[test]
fn vertical_blocks_are_two_where_the_halo_allows() {
    // Two blocks at the rig's and the camera's sizes, for both filters' decays, whatever
    // the machine's threads.
    assert_eq!(vertical_block_rows(400, 0.7), 200);
    assert_eq!(vertical_block_rows(400, 0.8), 200);
    assert_eq!(vertical_block_rows(1200, 0.7f32.powf(1.0 / 3.0)), 600);
    assert_eq!(vertical_block_rows(1200, 0.8f32.powf(1.0 / 3.0)), 600);
    assert_eq!(vertical_block_rows(301, 0.7), 151);
    // One where the image is shorter than two halos, or the decay reaches the whole
    // column; never zero.
    assert_eq!(vertical_block_rows(150, 0.8), 150);
    assert_eq!(vertical_block_rows(4000, 1.0), 4000);
    assert_eq!(vertical_block_rows(0, 0.7), 1);
}

#[test]
fn the_sums_are_the_same_bits_on_any_number_of_threads() {
    // The blocks of rows depend on the image and the decay, not on the threads.
    let (w, h) = (203, 401);
    let smoothed = |threads: usize| {
        let mut out = output(w, h);
        for i in 0..w * h {
            out.unit_re[i] = ((i * 7919) % 1009) as f32 / 1009.0 - 0.5;
            out.unit_im[i] = ((i * 104_729) % 997) as f32 / 997.0 - 0.5;
            out.support[i] = 1.0;
            out.connect[i] = if i % 13 == 0 { RIGHT } else { RIGHT | DOWN };
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| smooth_planes(&mut Planes::of_unit_phasor(&mut out), 0.8));
        [out.unit_re, out.unit_im, out.support]
            .map(|p| p.iter().map(|v| v.to_bits()).collect::<Vec<u32>>())
    };
    let one = smoothed(1);
    for threads in [2, 3, 8] {
        assert!(one == smoothed(threads), "{threads} threads");
    }
}

#[test]
fn the_halo_reaches_below_f32_resolution() {
    assert_eq!(recursion_halo(0.7), 52);
    assert_eq!(recursion_halo(0.8), 83);
    assert_eq!(recursion_halo(0.85), 114);
    for decay in [0.5f32, 0.7, 0.85, 0.95, 0.99] {
        let k = recursion_halo(decay);
        assert!(decay.powi(k as i32) < 1e-8, "{decay}");
        assert!(decay.powi(k as i32 - 1) >= 1e-8, "{decay}");
    }
    assert_eq!(recursion_halo(0.0), 0);
    assert_eq!(recursion_halo(1.0), 1 << 16);
}

#[test]
fn unit_angle_range() {
    assert!((unit_angle(-1.0, -0.01) - (PI + 0.01)).abs() < 1e-3);
    assert!((unit_angle(1.0, -0.01) + 0.01).abs() < 1e-3);
}
