//! Stage 4 (robust CPS only): fringe-order consistency between connected neighbours.
//!
//! Two neighbours that [`super::connect`] links have wrapped phases within about a radian of each
//! other, so their true coordinates differ by well under half a fringe period. If their unwrapped
//! coordinates differ by more than half a period, one of them took the wrong fringe order (most
//! often where the edge-aware average leaked across an edge whose phases happened to match).
//! Which one cannot be told locally, so both are marked [`invalid::ORDER_JUMP`]: a wrong depth is
//! worse than a missing one.

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
            let row = &coord[y * w..(y + 1) * w];
            let links = &connect[y * w..(y + 1) * w];
            jump.fill(0);
            // Right and left neighbours share the RIGHT link of the left pixel of each pair.
            pair_jumps(
                &row[..w - 1],
                &row[1..],
                &links[..w - 1],
                RIGHT,
                half_period_px,
                &mut jump[..w - 1],
            );
            pair_jumps(
                &row[1..],
                &row[..w - 1],
                &links[..w - 1],
                RIGHT,
                half_period_px,
                &mut jump[1..],
            );
            if y + 1 < h {
                let below = &coord[(y + 1) * w..(y + 2) * w];
                pair_jumps(row, below, links, DOWN, half_period_px, jump);
            }
            if y > 0 {
                let above = &coord[(y - 1) * w..y * w];
                let above_links = &connect[(y - 1) * w..y * w];
                pair_jumps(row, above, above_links, DOWN, half_period_px, jump);
            }
        });
    out.invalid
        .par_chunks_mut(w)
        .zip(out.coordinate_px.par_chunks_mut(w))
        .zip(out.jump.par_chunks(w))
        .for_each(|((flags, coord), jump)| apply_jumps(flags, coord, jump));
}

/// `jump[x] |= 1` where `links[x]` has `bit` and `here[x]`, `there[x]` are both valid and more
/// than `limit` apart (NaN compares false, so invalid pixels never count).
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn pair_jumps(here: &[f32], there: &[f32], links: &[u8], bit: u8, limit: f32, jump: &mut [u8]) {
    for x in 0..jump.len() {
        let linked = links[x] & bit != 0;
        let far = (here[x] - there[x]).abs() > limit;
        jump[x] |= u8::from(linked & far);
    }
}

#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn apply_jumps(flags: &mut [u8], coord: &mut [f32], jump: &[u8]) {
    let n = flags.len();
    let (coord, jump) = (&mut coord[..n], &jump[..n]);
    for x in 0..n {
        let j = jump[x];
        flags[x] |= j * invalid::ORDER_JUMP;
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
}
