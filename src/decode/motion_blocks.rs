//! One Gauss–Newton step of the motion model ([`super::motion`]) with its evidence summed over
//! blocks of pixels ([`super::MotionParams::block_px`] of 2 to 4; opt-in, CPU only).
//!
//! Stage 1 sums its evidence over the blocks as it solves each row
//! ([`super::phasor_blocks`]); the first step links the blocks ([`super::smooth_blocks`]);
//! every step then smooths the block planes (the edge-aware
//! recursion over the blocks, with the decay raised to the block's size, so that the reach in
//! pixels stays) and works through the image one row of blocks at a time. For each of its pixel
//! rows the row's sums are expanded from the blocks into a scratch row, the step's kernel
//! ([`super::motion_correct::correct_row`], unchanged) solves and corrects the row, and the
//! evidence it leaves in the scratch row for the next step is added into that step's blocks;
//! on the last step the scratch row's unit phasor and support are copied to their planes for
//! stage 2. So the per-pixel evidence never exists at full resolution: of the four edge-aware
//! sums of three planes and the three passes writing six evidence planes that the per-pixel
//! steps cost, none stays.

use super::motion::split3;
use super::motion_correct::{correct_row, RowPlanes, Step};
use super::DecodeOutput;
use rayon::prelude::*;

/// One step of the motion model over blocks of `block` (2 to 4) pixels square, with the
/// evidence's `decay` per pixel. Stage 1 (on the first step) or the step before left the
/// evidence summed into `out.motion_blocks`' next sums.
pub(super) fn step_in_blocks(step: &Step<'_>, decay: f32, block: usize, out: &mut DecodeOutput) {
    match block {
        2 => step_in_blocks_of::<2>(step, decay, out),
        3 => step_in_blocks_of::<3>(step, decay, out),
        _ => step_in_blocks_of::<4>(step, decay, out),
    }
}

fn step_in_blocks_of<const B: usize>(step: &Step<'_>, decay: f32, out: &mut DecodeOutput) {
    let (w, h) = (out.width, out.height);
    let (bw, bh) = (w.div_ceil(B), h.div_ceil(B));
    let mut blocks = std::mem::take(&mut out.motion_blocks);
    blocks.fit(bw, bh);
    if step.kind == super::motion::StepKind::FromRest {
        // Stage 1 left its evidence summed into the blocks' next sums.
        blocks.link(&out.connect, (w, h), B);
        blocks.advance(bw);
    }
    blocks.smooth((bw, bh), decay.powi(B as i32));
    let sums = &blocks.sums;
    let band = B * w;
    out.phase_rad
        .par_chunks_mut(3 * band)
        .zip(out.amplitude.par_chunks_mut(3 * band))
        .zip(out.colour.par_chunks_mut(3 * band))
        .zip(out.unit_re.par_chunks_mut(band))
        .zip(out.unit_im.par_chunks_mut(band))
        .zip(out.support.par_chunks_mut(band))
        .zip(out.invalid.par_chunks_mut(band))
        .zip(out.velocity_px_per_s.par_chunks_mut(band))
        .zip(out.brightness_rate_per_s.par_chunks_mut(band))
        .zip(out.acceleration_px_per_s2.par_chunks_mut(band))
        .zip(out.patch_velocity_px_per_s.par_chunks_mut(band))
        .zip(out.patch_moving.par_chunks_mut(band))
        .zip(out.lit_offset_sum.par_chunks_mut(band))
        .zip(blocks.next.par_chunks_mut(6 * bw))
        .enumerate()
        .for_each_init(
            || vec![0.0f32; 6 * w],
            |scratch, (by, planes)| {
                let (
                    (
                        (
                            (
                                (
                                    (
                                        (
                                            (
                                                (
                                                    ((((phase, amp), colour), unit_re), unit_im),
                                                    support,
                                                ),
                                                flags,
                                            ),
                                            velocity,
                                        ),
                                        brightness,
                                    ),
                                    acceleration,
                                ),
                                patch_velocity,
                            ),
                            patch_moving,
                        ),
                        lit_sum,
                    ),
                    next,
                ) = planes;
                next.fill(0.0);
                let block_row = |k: usize| &sums[k][by * bw..(by + 1) * bw];
                for r in 0..flags.len() / w {
                    let px = r * w..(r + 1) * w;
                    let (ev, rest) = scratch.split_at_mut(3 * w);
                    let [uu, uk, kk] = split3(ev, w);
                    let [ue, ke, count] = split3(rest, w);
                    for (k, row) in [&mut *uu, uk, kk, ue, ke, count].into_iter().enumerate() {
                        expand_row::<B>(block_row(k), row);
                    }
                    let r3 = 3 * r * w..3 * (r + 1) * w;
                    correct_row(
                        step,
                        RowPlanes {
                            phase: split3(&mut phase[r3.clone()], w),
                            amp: split3(&mut amp[r3.clone()], w),
                            offset: split3(&mut colour[r3], w),
                            uu,
                            uk,
                            kk,
                            ue,
                            ke,
                            count,
                            flags: &mut flags[px.clone()],
                            velocity: &mut velocity[px.clone()],
                            brightness: &mut brightness[px.clone()],
                            acceleration: &mut acceleration[px.clone()],
                            patch_velocity: &mut patch_velocity[px.clone()],
                            patch_moving: &mut patch_moving[px.clone()],
                            lit_sum: &mut lit_sum[px.clone()],
                        },
                    );
                    if step.last {
                        unit_re[px.clone()].copy_from_slice(&scratch[..w]);
                        unit_im[px.clone()].copy_from_slice(&scratch[w..2 * w]);
                        support[px].copy_from_slice(&scratch[2 * w..3 * w]);
                    } else {
                        for (k, row) in scratch.chunks_exact(w).enumerate() {
                            add_row::<B>(row, &mut next[k * bw..(k + 1) * bw]);
                        }
                    }
                }
            },
        );
    if !step.last {
        blocks.advance(bw);
    }
    out.motion_blocks = blocks;
}

/// Every pixel of `row` takes its block's sum in `sums`.
#[inline]
fn expand_row<const B: usize>(sums: &[f32], row: &mut [f32]) {
    let whole = row.len() / B;
    let mut chunks = row.chunks_exact_mut(B);
    for (pixels, &sum) in (&mut chunks).zip(sums) {
        pixels.copy_from_slice(&[sum; B]);
    }
    if let Some(&sum) = sums.get(whole) {
        chunks.into_remainder().fill(sum);
    }
}

/// Adds each run of `B` pixels of `row` into its block of `sums`.
#[inline]
fn add_row<const B: usize>(row: &[f32], sums: &mut [f32]) {
    let mut chunks = row.chunks_exact(B);
    for (pixels, sum) in (&mut chunks).zip(sums.iter_mut()) {
        *sum += pixels.iter().sum::<f32>();
    }
    let rest = chunks.remainder();
    if !rest.is_empty() {
        if let Some(last) = sums.last_mut() {
            *last += rest.iter().sum::<f32>();
        }
    }
}
