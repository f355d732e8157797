//! The GPU decode's read-back, on the host: the layout of the read-back buffer (eight planes,
//! the final noise grid, the timestamps), the wait for a mapping, and the pixel-planar words
//! turned into the row-planar [`DecodeOutput`], the final grid's noise and the passes' time by
//! the GPU's clock.

use super::motion;
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::sync::mpsc;
use tremorscan::decode::DecodeOutput;

/// Planes of the read-back buffer: coordinate, final flags, amplitudes (3), colours (3); the
/// final noise grid and the timestamps (four: the start and end of up to two compute passes,
/// 32 bytes) follow them.
pub(super) const READBACK_PLANES: usize = 8;
pub(super) const TIMESTAMPS: u32 = 4;
pub(super) const TIMESTAMP_BYTES: u64 = 8 * TIMESTAMPS as u64;

/// The query set of the compute passes' timestamps and the buffer they resolve into.
pub(super) struct Timestamps {
    pub queries: wgpu::QuerySet,
    pub resolved: wgpu::Buffer,
    /// Nanoseconds per tick.
    pub period_ns: f64,
}

/// Where the parts of one window's read-back lie.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    pub width: usize,
    pub height: usize,
    /// Values of the noise grid (the buffer holds at least one word).
    pub grid_len: usize,
    /// Compute passes timed (one, or two with the motion model).
    pub passes: usize,
}

/// One window's read-back `words` into `out`; returns the passes' time by the GPU's clock, ms,
/// where there are `timestamps`, and the noise the final planes' grid shows.
pub(super) fn read_window(
    words: &[u32],
    layout: Layout,
    timestamps: Option<&Timestamps>,
    scratch: &mut Vec<f32>,
    out: &mut DecodeOutput,
) -> (Option<f64>, Option<f32>) {
    let (planes, rest) = words.split_at(READBACK_PLANES * layout.width * layout.height);
    let (grid, stamps) = rest.split_at(layout.grid_len.max(1));
    unpack(planes, layout.width, out);
    let grid: &[f32] = bytemuck::cast_slice(&grid[..layout.grid_len]);
    let noise = motion::noise_from_grid(grid, scratch);
    let device_ms = timestamps.and_then(|t| {
        let tick = |i: usize| u64::from(stamps[2 * i]) | (u64::from(stamps[2 * i + 1]) << 32);
        let mut ticks = 0;
        for p in 0..layout.passes {
            ticks += tick(2 * p + 1).checked_sub(tick(2 * p))?;
        }
        Some(ticks as f64 * t.period_ns * 1e-6)
    });
    (device_ms, noise)
}

/// Maps `buffer` for reading once the GPU has finished what was submitted.
pub(super) fn map_and_wait(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<()> {
    let (sender, receiver) = mpsc::sync_channel(1);
    buffer.map_async(wgpu::MapMode::Read, .., move |result| {
        // The receiver waits below; a send cannot fail while it does.
        let _ = sender.send(result);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .context("the GPU did not finish the decode")?;
    receiver
        .recv()
        .context("the GPU read-back was abandoned")?
        .context("could not map the GPU read-back buffer")
}

/// Copies the eight read-back planes (pixel-planar, as words) into `out`, rows in parallel
/// (5.6 ms on one core at 1920×1200 on the development machine: the host's largest share of a
/// GPU window after the transfers).
fn unpack(words: &[u32], w: usize, out: &mut DecodeOutput) {
    let n = out.width * out.height;
    let (coords, rest) = words.split_at(n);
    let (flags, rest) = rest.split_at(n);
    let plane = |p: usize| &rest[p * n..(p + 1) * n];
    let (amp, colour) = (
        [plane(0), plane(1), plane(2)],
        [plane(3), plane(4), plane(5)],
    );
    out.coordinate_px
        .par_chunks_mut(w)
        .zip(out.invalid.par_chunks_mut(w))
        .zip(out.amplitude.par_chunks_mut(3 * w))
        .zip(out.colour.par_chunks_mut(3 * w))
        .enumerate()
        .for_each(|(y, (((coordinate, reason), amp_row), colour_row))| {
            let span = y * w..(y + 1) * w;
            for ((c, r), (&word, &f)) in coordinate
                .iter_mut()
                .zip(reason.iter_mut())
                .zip(coords[span.clone()].iter().zip(&flags[span.clone()]))
            {
                *r = f as u16;
                *c = if f == 0 {
                    f32::from_bits(word)
                } else {
                    f32::NAN
                };
            }
            for f in 0..3 {
                let dst = f * w..(f + 1) * w;
                for (d, &s) in amp_row[dst.clone()].iter_mut().zip(&amp[f][span.clone()]) {
                    *d = f32::from_bits(s);
                }
                for (d, &s) in colour_row[dst].iter_mut().zip(&colour[f][span.clone()]) {
                    *d = f32::from_bits(s);
                }
            }
        });
}
