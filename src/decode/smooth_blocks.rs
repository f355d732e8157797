//! The motion model's edge-aware sums at block resolution ([`super::MotionParams::block_px`],
//! opt-in): issue 23's "coarse evidence on blocks", measured against the per-pixel sums.
//!
//! A patch's velocity and brightness change are smooth along a surface, and the motion model
//! sums their evidence over a neighbourhood that reaches several pixels ([`super::motion`]).
//! At full resolution that sum is four recursive filters of three planes per window (two
//! Gauss–Newton steps), the bulk of the model's cost. Here each plane is first summed over
//! blocks of `B×B` pixels; the same recursion ([`super::smooth::smooth_planes`]) then runs over
//! the blocks with the decay raised to the block's size (`decay^B`, the same reach in pixels),
//! and every pixel takes its block's sum. Two blocks are linked where at least half of the
//! pixel pairs across their common side are ([`super::connect`]), so a depth edge still stops
//! the sum, at the block's resolution: a block that straddles the edge pools both surfaces.
//!
//! The full-resolution evidence planes are read once (stage 1's, summed into blocks); the
//! Gauss–Newton steps ([`super::motion_blocks`]) read each pixel's sums from its block and add
//! the evidence they write for the next step straight into the next step's blocks, so no
//! full-resolution plane is smoothed, expanded or written for the sums. The block planes and
//! their scratch are kept in [`BlockScratch`] between windows and grown only when the image or
//! the block size changes.

use super::connect::{DOWN, RIGHT};
use super::smooth::{smooth_planes, Planes, VERTICAL_BLOCK_ROWS};
use super::BAND_ROWS;
use rayon::prelude::*;

/// The block planes and the scratch of their recursion.
#[derive(Debug, Default, Clone)]
pub(crate) struct BlockScratch {
    /// The six sums (`uu`, `uk`, `kk`, `ue`, `ke`, count) per block, one plane each.
    pub(crate) sums: [Vec<f32>; 6],
    /// The next step's sums, row-planar (`[block row][sum][block]`), so that each block row is
    /// written by one task.
    pub(crate) next: Vec<f32>,
    connect: Vec<u8>,
    tmp: Vec<f32>,
    band_scratch: Vec<f32>,
    vertical_state: Vec<f32>,
}

impl BlockScratch {
    /// Sizes every buffer for `bw`×`bh` blocks (allocating only when they grow).
    pub(crate) fn fit(&mut self, bw: usize, bh: usize) {
        let nb = bw * bh;
        for plane in &mut self.sums {
            plane.resize(nb, 0.0);
        }
        self.next.resize(6 * nb, 0.0);
        self.connect.resize(nb, 0);
        self.tmp.resize(3 * nb, 0.0);
        self.band_scratch
            .resize(bh.div_ceil(BAND_ROWS) * band_scratch_len(bw), 0.0);
        self.vertical_state
            .resize(3 * bw * bh.div_ceil(VERTICAL_BLOCK_ROWS), 0.0);
    }

    /// Links the blocks of `block` pixels from the pixels' links `connect` (`w`×`h`).
    pub(crate) fn link(&mut self, connect: &[u8], (w, h): (usize, usize), block: usize) {
        link_blocks(connect, (w, h), block, &mut self.connect);
    }

    /// The next step's sums become the sums (`bw` blocks per row).
    pub(crate) fn advance(&mut self, bw: usize) {
        for (by, row) in self.next.chunks_exact(6 * bw).enumerate() {
            for (k, sums) in self.sums.iter_mut().enumerate() {
                sums[by * bw..(by + 1) * bw].copy_from_slice(&row[k * bw..(k + 1) * bw]);
            }
        }
    }

    /// The edge-aware sum of every block plane over its connected blocks (`bw`×`bh`), with
    /// `decay` per block.
    pub(crate) fn smooth(&mut self, (bw, bh): (usize, usize), decay: f32) {
        let [s0, s1, s2, s3, s4, s5] = &mut self.sums;
        for triple in [[s0, s1, s2], [s3, s4, s5]] {
            let [a, b, c] = triple;
            let mut blocks = Planes {
                planes: [a, b, c],
                w: bw,
                h: bh,
                connect: &self.connect,
                tmp: &mut self.tmp,
                band_scratch: &mut self.band_scratch,
                band_scratch_len: band_scratch_len(bw),
                vertical_state: &mut self.vertical_state,
            };
            smooth_planes(&mut blocks, decay);
        }
    }
}

/// The horizontal recursion's scratch per band of rows: the gains and three backward sums.
fn band_scratch_len(bw: usize) -> usize {
    4 * bw
}

/// Adds one pixel row of a block row into `line`, which the block row's first pixel row
/// (`first`) overwrites. With [`line_to_blocks`] after its last row: the block sums, rows
/// added along the whole line first (a loop that vectorises), then each run of `B`.
#[inline]
pub(crate) fn add_to_line(first: bool, row: &[f32], line: &mut [f32]) {
    if first {
        line.copy_from_slice(row);
    } else {
        for (total, &v) in line.iter_mut().zip(row) {
            *total += v;
        }
    }
}

/// `sums[i]` = the sum of the `i`-th run of `B` values of `line` (the last run may be short).
#[inline]
pub(crate) fn line_to_blocks<const B: usize>(line: &[f32], sums: &mut [f32]) {
    let whole = line.len() / B;
    for (sum, pixels) in sums[..whole].iter_mut().zip(line.chunks_exact(B)) {
        *sum = pixels.iter().sum();
    }
    if let Some(last) = sums.get_mut(whole) {
        *last = line[whole * B..].iter().sum();
    }
}

/// The blocks' links: [`RIGHT`] (or [`DOWN`]) where at least half of the pixel pairs across the
/// block's right (or lower) side are linked.
fn link_blocks(connect: &[u8], (w, h): (usize, usize), block: usize, links: &mut [u8]) {
    let (bw, bh) = (w.div_ceil(block), h.div_ceil(block));
    links.par_chunks_mut(bw).enumerate().for_each(|(by, row)| {
        let rows = by * block..((by + 1) * block).min(h);
        for (bx, link) in row.iter_mut().enumerate() {
            let cols = bx * block..((bx + 1) * block).min(w);
            *link = 0;
            if bx + 1 < bw {
                let x = cols.end - 1;
                let linked = rows
                    .clone()
                    .filter(|&y| connect[y * w + x] & RIGHT != 0)
                    .count();
                if 2 * linked >= rows.len() {
                    *link |= RIGHT;
                }
            }
            if by + 1 < bh {
                let y = rows.end - 1;
                let linked = cols
                    .clone()
                    .filter(|&x| connect[y * w + x] & DOWN != 0)
                    .count();
                if 2 * linked >= cols.len() {
                    *link |= DOWN;
                }
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The block sums of `plane` (`w`×`h`), a row at a time as stage 1 adds them.
    fn sum_blocks<const B: usize>(plane: &[f32], (w, h): (usize, usize)) -> Vec<f32> {
        let bw = w.div_ceil(B);
        let mut sums = vec![f32::NAN; bw * h.div_ceil(B)];
        let mut line = vec![0.0; w];
        for (y, row) in plane.chunks_exact(w).enumerate() {
            add_to_line(y.is_multiple_of(B), row, &mut line);
            if (y + 1).is_multiple_of(B) || y + 1 == h {
                line_to_blocks::<B>(&line, &mut sums[y / B * bw..(y / B + 1) * bw]);
            }
        }
        sums
    }

    #[test]
    fn a_connected_field_sums_like_the_pixels_and_an_edge_stops_it() {
        // 12×8 pixels in blocks of 2, all linked except across the column between x = 5 and 6.
        let (w, h) = (12, 8);
        let mut connect = vec![RIGHT | DOWN; w * h];
        for y in 0..h {
            connect[y * w + 5] &= !RIGHT;
            connect[y * w + w - 1] &= !RIGHT;
        }
        for x in 0..w {
            connect[(h - 1) * w + x] &= !DOWN;
        }
        let a: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 6 { 1.0 } else { 3.0 })
            .collect();
        let b = vec![1.0; w * h];
        let zero = vec![0.0; w * h];
        let mut blocks = BlockScratch::default();
        let (bw, bh) = (w / 2, h / 2);
        blocks.fit(bw, bh);
        for (k, plane) in [&a, &b, &zero, &zero, &zero, &zero].into_iter().enumerate() {
            let sums = sum_blocks::<2>(plane, (w, h));
            for (by, row) in sums.chunks_exact(bw).enumerate() {
                blocks.next[(6 * by + k) * bw..(6 * by + k + 1) * bw].copy_from_slice(row);
            }
        }
        blocks.advance(bw);
        blocks.link(&connect, (w, h), 2);
        blocks.smooth((bw, bh), 0.8f32.powi(2));
        // Each side keeps its own value: the ratio of the sums is its mean.
        for by in 0..bh {
            for bx in 0..bw {
                let i = by * bw + bx;
                let mean = blocks.sums[0][i] / blocks.sums[1][i];
                let want = if bx < 3 { 1.0 } else { 3.0 };
                assert!((mean - want).abs() < 1e-5, "({bx}, {by}): {mean}");
                assert_eq!(blocks.sums[2][i], 0.0);
            }
        }
        // A block pools its four pixels and its linked neighbours.
        assert!(blocks.sums[1][bw + 1] > 4.0, "{}", blocks.sums[1][bw + 1]);
    }

    #[test]
    fn partial_blocks_at_the_border_sum_what_they_hold() {
        let (w, h) = (5, 3);
        let plane: Vec<f32> = (0..w * h).map(|i| i as f32).collect();
        let sums = sum_blocks::<2>(&plane, (w, h));
        // Block (2, 0): pixels (4, 0) and (4, 1); block (2, 1): pixel (4, 2).
        assert_eq!(sums[2], 4.0 + 9.0);
        assert_eq!(sums[5], 14.0);
        assert_eq!(sums[0], 0.0 + 1.0 + 5.0 + 6.0);
    }
}
