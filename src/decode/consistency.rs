//! Stage 4 (robust CPS only): fringe-order consistency between connected neighbours.
//!
//! Two neighbours that [`super::connect`] links have wrapped phases within about a radian of each
//! other, so their true coordinates differ by well under half a fringe period. If their unwrapped
//! coordinates differ by more than half a period, one of them took the wrong fringe order (most
//! often where the edge-aware average leaked across an edge whose phases happened to match).
//! Which one cannot be told locally, so both are marked [`invalid::ORDER_JUMP`]: a wrong depth is
//! worse than a missing one.
//!
//! How: one pass per row tests each pixel against its four linked neighbours and writes a jump
//! byte; a second pass, once every row is tested, marks the pixels and clears their coordinates.

use super::connect::{DOWN, RIGHT};
use super::{invalid, DecodeOutput};
use rayon::prelude::*;

pub(crate) fn flag_order_jumps(out: &mut DecodeOutput, half_period_px: f32) {
    let w = out.width;
    let h = out.height;
    let coord = &out.coordinate_px;
    let connect = &out.connect;
    out.jump
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, jump)| {
            let rows = |y: usize| y * w..(y + 1) * w;
            // The first and last rows stand in for their missing neighbour row: a pixel is never
            // far from itself.
            let above = if y > 0 { rows(y - 1) } else { rows(y) };
            let below = if y + 1 < h { rows(y + 1) } else { rows(y) };
            let row = Neighbourhood {
                here: &coord[rows(y)],
                links: &connect[rows(y)],
                above: &coord[above.clone()],
                above_links: &connect[above],
                below: &coord[below],
            };
            row_jumps(&row, half_period_px, jump);
        });
    out.invalid
        .par_chunks_mut(w)
        .zip(out.coordinate_px.par_chunks_mut(w))
        .zip(out.jump.par_chunks(w))
        .for_each(|((flags, coord), jump)| apply_jumps(flags, coord, jump));
}

/// One row of coordinates with the links and coordinates around it.
struct Neighbourhood<'a> {
    here: &'a [f32],
    /// The row's links: `RIGHT` to the next pixel, `DOWN` to the row below.
    links: &'a [u8],
    above: &'a [f32],
    /// The links of the row above (its `DOWN` bits link to this row).
    above_links: &'a [u8],
    below: &'a [f32],
}

/// Whether pixel `x` of `row` and a linked neighbour are more than `limit` apart (NaN compares
/// false, so invalid pixels never count). Used at the row's ends.
fn pixel_jumps(row: &Neighbourhood<'_>, x: usize, limit: f32) -> u8 {
    let w = row.here.len();
    let c = row.here[x];
    let far = |other: f32| (c - other).abs() > limit;
    let left = x > 0 && row.links[x - 1] & RIGHT != 0 && far(row.here[x - 1]);
    let right = x + 1 < w && row.links[x] & RIGHT != 0 && far(row.here[x + 1]);
    let down = row.links[x] & DOWN != 0 && far(row.below[x]);
    let up = row.above_links[x] & DOWN != 0 && far(row.above[x]);
    u8::from(left | right | down | up)
}

/// `jump[x] = 1` where pixel `x` is linked to its left, right, upper or lower neighbour and the
/// two coordinates are more than `limit` apart, else 0: the four tests in one pass, the inner
/// pixels in a loop that vectorises.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn row_jumps(row: &Neighbourhood<'_>, limit: f32, jump: &mut [u8]) {
    let w = row.here.len();
    if w < 3 {
        for (x, j) in jump.iter_mut().enumerate().take(w) {
            *j = pixel_jumps(row, x, limit);
        }
        return;
    }
    // Pixel x = i + 1 for i in 0..n: its left neighbour at i, its right one at i + 2.
    let n = w - 2;
    let (left, here, right) = (&row.here[..n], &row.here[1..=n], &row.here[2..n + 2]);
    let (left_links, links) = (&row.links[..n], &row.links[1..=n]);
    let (above, above_links, below) = (
        &row.above[1..=n],
        &row.above_links[1..=n],
        &row.below[1..=n],
    );
    let inner = &mut jump[1..=n];
    for i in 0..n {
        let c = here[i];
        let far = |other: f32| (c - other).abs() > limit;
        let j = ((left_links[i] & RIGHT != 0) & far(left[i]))
            | ((links[i] & RIGHT != 0) & far(right[i]))
            | ((links[i] & DOWN != 0) & far(below[i]))
            | ((above_links[i] & DOWN != 0) & far(above[i]));
        inner[i] = u8::from(j);
    }
    jump[0] = pixel_jumps(row, 0, limit);
    jump[w - 1] = pixel_jumps(row, w - 1, limit);
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn apply_jumps(flags: &mut [u16], coord: &mut [f32], jump: &[u8]) {
    let n = flags.len();
    let (coord, jump) = (&mut coord[..n], &jump[..n]);
    for x in 0..n {
        let j = jump[x];
        flags[x] |= u16::from(j) * invalid::ORDER_JUMP;
        // A select rather than a conditional store, so the loop vectorises.
        coord[x] = if j != 0 { f32::NAN } else { coord[x] };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    #[test]
    fn a_fringe_jump_between_connected_neighbours_marks_both() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        let (w, h) = (6, 3);
        let mut out = DecodeOutput::new(w, h, &solver);
        for y in 0..h {
            for x in 0..w {
                out.coordinate_px[y * w + x] = 100.0 + x as f32;
                out.connect[y * w + x] = RIGHT | DOWN;
            }
        }
        // Pixel (3, 1) took the next fringe order; pixel (5, 2) is not connected to its left.
        out.coordinate_px[w + 3] += 28.06;
        out.coordinate_px[2 * w + 5] += 28.06;
        out.connect[2 * w + 4] &= !RIGHT;
        out.connect[w + 5] &= !DOWN;
        flag_order_jumps(&mut out, 14.03);
        let marked: Vec<usize> = (0..w * h)
            .filter(|&i| out.invalid[i] & invalid::ORDER_JUMP != 0)
            .collect();
        // (3,1) and its four connected neighbours; (5,2) is isolated and left alone.
        assert_eq!(marked, vec![3, w + 2, w + 3, w + 4, 2 * w + 3]);
        assert!(out.coordinate_px[w + 3].is_nan());
    }

    /// Every pixel's jump by the definition: a linked neighbour more than `limit` away.
    fn jumps_by_definition(coord: &[f32], links: &[u8], w: usize, h: usize, limit: f32) -> Vec<u8> {
        let far = |a: usize, b: usize| (coord[a] - coord[b]).abs() > limit;
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let left = x > 0 && links[i - 1] & RIGHT != 0 && far(i, i - 1);
                let right = x + 1 < w && links[i] & RIGHT != 0 && far(i, i + 1);
                let up = y > 0 && links[i - w] & DOWN != 0 && far(i, i - w);
                let down = y + 1 < h && links[i] & DOWN != 0 && far(i, i + w);
                u8::from(left | right | up | down)
            })
            .collect()
    }

    #[test]
    fn the_one_pass_check_equals_the_definition_at_every_size() {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let solver =
            WindowSolver::new(&seq, &[0, 1, 2], &crate::color::CrossTalk::paper()).unwrap();
        // Pseudo-random coordinates (some NaN, some a fringe off) and links, by a 64-bit LCG.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as u32
        };
        for (w, h) in [(1, 1), (1, 4), (2, 3), (3, 2), (17, 5), (64, 9)] {
            let mut out = DecodeOutput::new(w, h, &solver);
            for i in 0..w * h {
                let r = next();
                out.coordinate_px[i] = match r % 10 {
                    0 => f32::NAN,
                    1 | 2 => 128.06 + (r % 7) as f32,
                    _ => 100.0 + (r % 7) as f32,
                };
                out.connect[i] = (next() % 4) as u8;
            }
            let limit = 14.03;
            let expected = jumps_by_definition(&out.coordinate_px, &out.connect, w, h, limit);
            flag_order_jumps(&mut out, limit);
            assert_eq!(out.jump, expected, "{w}×{h}");
            for (i, &j) in expected.iter().enumerate() {
                assert_eq!(
                    out.invalid[i] & invalid::ORDER_JUMP != 0,
                    j != 0,
                    "{w}×{h} at {i}"
                );
                assert!(j == 0 || out.coordinate_px[i].is_nan());
            }
        }
    }
}
