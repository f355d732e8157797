//! Stage 1 of a motion window whose evidence is summed over blocks
//! ([`super::MotionParams::block_px`] of 2 to 4): the phases, amplitudes, colour and flags as
//! [`super::phasor`] writes them, and the motion model's six evidence values per pixel summed
//! into the blocks as each row is solved, never written at full resolution.
//!
//! Each task takes a band of whole block rows (`B·⌈8/B⌉` pixel rows). A pixel row's evidence
//! goes into a row of scratch (six planes of one row, in the cache); the block row's pixel rows
//! are added into a line ([`super::smooth_blocks::add_to_line`]), and after its last one each
//! run of `B` values of the line becomes a block's sum ([`super::smooth_blocks::line_to_blocks`]),
//! written row-planar into the blocks' next sums, which the first Gauss–Newton step takes
//! ([`super::motion_blocks`]). The order of the additions is the one the blocks had when they
//! were summed from full-resolution planes after stage 1, so the sums are the same bit for bit;
//! what goes is the write of five full-resolution planes and the second read of six. (The
//! sixth, `kk`, is also written to the support plane: the pixels' links need to know which
//! pixels have evidence.)

use super::motion::MotionBasis;
use super::phasor::{solve_row, RowOut, CHUNK_PX};
use super::smooth_blocks::{add_to_line, line_to_blocks};
use super::{DecodeOutput, DecodeParams, WindowSolver, BAND_ROWS};
use crate::frame::Frame;
use rayon::prelude::*;
use std::borrow::Borrow;

/// Stage 1 over the whole image with the evidence summed over blocks of `block` (2 to 4)
/// pixels square into `out.motion_blocks`' next sums.
pub(super) fn solve_phasors_in_blocks<F: Borrow<Frame> + Sync>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    basis: &MotionBasis,
    block: usize,
    out: &mut DecodeOutput,
) {
    match block {
        2 => solve_in_blocks_of::<2, F>(solver, frames, params, basis, out),
        3 => solve_in_blocks_of::<3, F>(solver, frames, params, basis, out),
        _ => solve_in_blocks_of::<4, F>(solver, frames, params, basis, out),
    }
}

/// Pixel rows per task: whole block rows, at least [`BAND_ROWS`] (so that the bands are no
/// more than the band scratch was sized for).
const fn band_rows(block: usize) -> usize {
    block * BAND_ROWS.div_ceil(block)
}

fn solve_in_blocks_of<const B: usize, F: Borrow<Frame> + Sync>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    basis: &MotionBasis,
    out: &mut DecodeOutput,
) {
    let (w, h) = (out.width, out.height);
    let (nf, nc) = (out.frequencies, out.channels);
    let (bw, bh) = (w.div_ceil(B), h.div_ceil(B));
    let rows = band_rows(B);
    let band_px = rows * w;
    let mut blocks = std::mem::take(&mut out.motion_blocks);
    blocks.fit(bw, bh);
    out.phase_rad
        .par_chunks_mut(band_px * nf)
        .zip(out.amplitude.par_chunks_mut(band_px * nf))
        .zip(out.colour.par_chunks_mut(band_px * nc))
        .zip(out.invalid.par_chunks_mut(band_px))
        .zip(out.support.par_chunks_mut(band_px))
        .zip(out.band_scratch.par_chunks_mut(out.band_scratch_len))
        .zip(blocks.next.par_chunks_mut(rows / B * 6 * bw))
        .enumerate()
        .for_each_init(
            // One row of the six evidence planes, then the block row's line of each.
            || vec![0.0f32; 12 * w],
            |buffers, (band, ((((((phase, amp), colour), flags), support), scratch), next))| {
                let (evidence, lines) = buffers.split_at_mut(6 * w);
                for r in 0..flags.len() / w {
                    let y = band * rows + r;
                    solve_evidence_row(
                        solver,
                        frames,
                        params,
                        basis,
                        (y, w),
                        scratch,
                        RowsOf {
                            phase: &mut phase[r * nf * w..(r + 1) * nf * w],
                            amp: &mut amp[r * nf * w..(r + 1) * nf * w],
                            colour: &mut colour[r * nc * w..(r + 1) * nc * w],
                            flags: &mut flags[r * w..(r + 1) * w],
                        },
                        evidence,
                    );
                    // The links between pixels (stage 2) need the pixels whose light counts:
                    // those with evidence (`kk` > 0), as the per-pixel path leaves them.
                    support[r * w..(r + 1) * w].copy_from_slice(&evidence[2 * w..3 * w]);
                    let first = y.is_multiple_of(B);
                    for (row, line) in evidence.chunks_exact(w).zip(lines.chunks_exact_mut(w)) {
                        add_to_line(first, row, line);
                    }
                    if (y + 1).is_multiple_of(B) || y + 1 == h {
                        let sums = &mut next[r / B * 6 * bw..(r / B + 1) * 6 * bw];
                        for (line, sums) in lines.chunks_exact(w).zip(sums.chunks_exact_mut(bw)) {
                            line_to_blocks::<B>(line, sums);
                        }
                    }
                }
            },
        );
    out.motion_blocks = blocks;
}

/// One pixel row's full-resolution outputs of stage 1 (planes `w` apart).
struct RowsOf<'a> {
    phase: &'a mut [f32],
    amp: &'a mut [f32],
    colour: &'a mut [f32],
    flags: &'a mut [u16],
}

/// Solves row `y` (of `w` pixels) in column chunks, its evidence (`uu`, `uk`, `kk`, `ue`, `ke`,
/// count) into the six planes of `evidence`.
#[allow(
    clippy::too_many_arguments,
    reason = "the window, the row and its two kinds of output are distinct"
)]
fn solve_evidence_row<F: Borrow<Frame>>(
    solver: &WindowSolver,
    frames: &[F],
    params: &DecodeParams,
    basis: &MotionBasis,
    (y, w): (usize, usize),
    scratch: &mut [f32],
    row: RowsOf<'_>,
    evidence: &mut [f32],
) {
    let (uu, rest) = evidence.split_at_mut(w);
    let (uk, rest) = rest.split_at_mut(w);
    let (kk, rest) = rest.split_at_mut(w);
    let (ue, rest) = rest.split_at_mut(w);
    let (ke, count) = rest.split_at_mut(w);
    for x0 in (0..w).step_by(CHUNK_PX) {
        let cw = CHUNK_PX.min(w - x0);
        let px = x0..x0 + cw;
        let view = RowOut {
            stride: w,
            phase: &mut row.phase[x0..],
            amp: &mut row.amp[x0..],
            colour: &mut row.colour[x0..],
            re: &mut uu[px.clone()],
            im: &mut uk[px.clone()],
            support: &mut kk[px.clone()],
            motion: [
                &mut ue[px.clone()],
                &mut ke[px.clone()],
                &mut count[px.clone()],
            ],
            flags: &mut row.flags[px],
        };
        solve_row(
            solver,
            frames,
            params,
            (true, Some(basis)),
            y * w + x0,
            cw,
            scratch,
            view,
        );
    }
}
