//! [`GpuDecoder`]: the buffers and pipelines of one image size, and one window's round trip.
//!
//! Frames live in three slots of one buffer; the slot of the next upload turns round, so a
//! window that shares two frames with the previous one uploads one frame (6.9 MB at 1920×1200)
//! and tells the shader where its oldest frame is (`first_slot`). The solver's pseudo-inverse
//! and the uniform are rewritten for every window (the window order turns with the patterns).
//! One read-back buffer receives eight planes: coordinate, final flags, three amplitudes and
//! three colours; the host copies them into the row-planar [`DecodeOutput`].

use super::{
    take_error, DecodeUniform, DeviceErrors, GpuContext, AMP_PLANE, BIT_PLANES, COORD_PLANE,
    FINAL_PLANE, RECURSION_SEGMENT, SHADER_WGSL, SOLVED_PLANES, STAGES, WORK_PLANES,
};
use anyhow::{bail, ensure, Context, Result};
use rayon::prelude::*;
use std::sync::{mpsc, Arc};
use std::time::Instant;
use tremorscan::decode::backend::Window;
use tremorscan::decode::{DecodeOutput, DecodeParams, UnwrapMethod, WindowSolver};

/// Planes of the read-back buffer: coordinate, final flags, amplitudes (3), colours (3); the
/// two timestamps (16 bytes) follow them.
const READBACK_PLANES: usize = 8;
const TIMESTAMP_BYTES: u64 = 16;

/// The query set of the compute pass's two timestamps and the buffer they resolve into.
struct Timestamps {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    /// Nanoseconds per tick.
    period_ns: f64,
}

/// Pipelines and buffers for one image size.
pub struct GpuDecoder {
    device: wgpu::Device,
    queue: wgpu::Queue,
    width: usize,
    height: usize,
    frame_bytes: usize,
    pipelines: Vec<wgpu::ComputePipeline>,
    bind_group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    pinv: wgpu::Buffer,
    frames: wgpu::Buffer,
    solved: wgpu::Buffer,
    work: wgpu::Buffer,
    bits: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Timestamps at the start and end of the compute pass, where the device has them.
    timestamps: Option<Timestamps>,
    /// One frame padded to whole words, for sizes whose frames are not.
    staging: Vec<u8>,
    /// The slot the next frame goes to; the oldest frame of a full ring is there.
    next_slot: usize,
    /// Frames whose upload completed, at most 3; 0 after a failure.
    slots_filled: usize,
    errors: DeviceErrors,
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// Why `solver` and `params` cannot run on the GPU, if they cannot.
pub(super) fn unsupported(
    solver_shape: (usize, usize, usize),
    params: &DecodeParams,
) -> Option<String> {
    let (channels, observations, unknowns) = solver_shape;
    if channels != 3 || observations != 9 || unknowns != 9 {
        return Some(format!(
            "the GPU decoder handles CPS-RGB windows (9 observations, 9 unknowns), not {observations} × {unknowns}"
        ));
    }
    if params.unwrap != UnwrapMethod::ChebyshevRobust {
        return Some(format!(
            "the GPU decoder implements the robust Chebyshev unwrap, not {:?}",
            params.unwrap
        ));
    }
    if params.motion.model != tremorscan::decode::MotionModel::Off {
        return Some(
            "the GPU decoder has no motion model yet: it decodes the still window only (decode \
             on the CPU, or ask for the still window: `--motion off`)"
                .into(),
        );
    }
    None
}

impl GpuDecoder {
    /// Prepares decoding of `width`×`height` windows shaped like `solver` (CPS-RGB) with
    /// `params` (robust unwrap).
    pub fn new(
        ctx: &GpuContext,
        width: usize,
        height: usize,
        solver: &WindowSolver,
        params: &DecodeParams,
    ) -> Result<Self> {
        ensure!(
            width > 0 && height > 0,
            "image size {width}×{height} is empty"
        );
        if let Some(why) = unsupported(
            (solver.channels, solver.observations, solver.unknowns),
            params,
        ) {
            bail!(why);
        }
        let device = ctx.device.clone();
        let n = width * height;
        let limits = device.limits();
        let largest = (SOLVED_PLANES * n * 4) as u64;
        ensure!(
            largest <= limits.max_storage_buffer_binding_size && largest <= limits.max_buffer_size,
            "{width}×{height} needs {largest} bytes in one GPU buffer; this adapter allows {}",
            limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        );
        let frame_bytes = (n * 3).div_ceil(4) * 4;
        let buffer = |label: &str, size: usize, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let uniform = buffer(
            "decode params",
            std::mem::size_of::<DecodeUniform>(),
            U::UNIFORM | U::COPY_DST,
        );
        let frames = buffer("frames", 3 * frame_bytes, U::STORAGE | U::COPY_DST);
        let pinv = buffer("pinv", 81 * 4, U::STORAGE | U::COPY_DST);
        let solved = buffer("solved", SOLVED_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let work = buffer("work", WORK_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let bits = buffer("bits", BIT_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let readback = buffer(
            "readback",
            READBACK_PLANES * n * 4 + TIMESTAMP_BYTES as usize,
            U::MAP_READ | U::COPY_DST,
        );
        let timestamps = device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| Timestamps {
                queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("decode pass"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                }),
                resolved: buffer(
                    "decode pass timestamps",
                    TIMESTAMP_BYTES as usize,
                    U::QUERY_RESOLVE | U::COPY_SRC,
                ),
                period_ns: f64::from(ctx.queue.get_timestamp_period()),
            });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("decode"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, false),
                storage_entry(4, false),
                storage_entry(5, false),
            ],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("decode"),
            layout: &layout,
            entries: &[
                (0, &uniform),
                (1, &frames),
                (2, &pinv),
                (3, &solved),
                (4, &work),
                (5, &bits),
            ]
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("decode"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("decode.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER_WGSL.into()),
        });
        let pipelines = STAGES
            .iter()
            .map(|&entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .collect();
        if let Some(e) = take_error(&ctx.errors) {
            bail!("the GPU could not set up the decoder for {width}×{height}: {e}");
        }
        Ok(Self {
            errors: Arc::clone(&ctx.errors),
            device,
            queue: ctx.queue.clone(),
            width,
            height,
            frame_bytes,
            pipelines,
            bind_group,
            uniform,
            pinv,
            frames,
            solved,
            work,
            bits,
            readback,
            timestamps,
            staging: vec![0; frame_bytes],
            next_slot: 0,
            slots_filled: 0,
        })
    }

    /// The image size this decoder was set up for.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Decodes `window` into `out` (sized for it): coordinate (NaN where invalid), reasons,
    /// amplitudes, colour and the timing (the whole round trip as `solve_ms`, the compute pass
    /// by the GPU's clock as `device_ms` where the adapter has timestamps).
    pub fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<()> {
        let started = Instant::now();
        let (w, h) = (self.width, self.height);
        let n = w * h;
        ensure!(
            out.width == w && out.height == h && out.frequencies == 3 && out.channels == 3,
            "the output is {}×{}, the GPU decoder was set up for {w}×{h}",
            out.width,
            out.height
        );
        ensure!(
            window.frames.len() == 3,
            "a CPS-RGB window has 3 frames, got {}",
            window.frames.len()
        );
        for (k, frame) in window.frames.iter().enumerate() {
            ensure!(
                frame.width == w
                    && frame.height == h
                    && frame.channels == 3
                    && frame.data.len() >= 3 * n,
                "frame {k} is {}×{}×{} ({} bytes), the GPU decoder was set up for {w}×{h} RGB",
                frame.width,
                frame.height,
                frame.channels,
                frame.data.len()
            );
            ensure!(
                frame.pattern_index == window.solver.order[k],
                "frame {k} shows pattern {}, the window expects {}",
                frame.pattern_index,
                window.solver.order[k]
            );
        }
        let chebyshev_n = window
            .chebyshev_n
            .context("the GPU decoder needs a Chebyshev sequence")?;
        // Upload the new frames into the slots after the newest; after a failure, all three.
        let fresh = if self.slots_filled == 3 {
            window.new_frames.min(3)
        } else {
            3
        };
        self.slots_filled = 0;
        for frame in &window.frames[3 - fresh..] {
            let offset = (self.next_slot * self.frame_bytes) as u64;
            let bytes = &frame.data[..3 * n];
            if bytes.len() == self.frame_bytes {
                self.queue.write_buffer(&self.frames, offset, bytes);
            } else {
                self.staging[..3 * n].copy_from_slice(bytes);
                self.queue.write_buffer(&self.frames, offset, &self.staging);
            }
            self.next_slot = (self.next_slot + 1) % 3;
        }
        let mut uniform = DecodeUniform::new(w, h, window.solver, window.params, chebyshev_n);
        uniform.first_slot = self.next_slot as u32;
        self.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        self.queue
            .write_buffer(&self.pinv, 0, bytemuck::cast_slice(&window.solver.pinv));
        self.queue.submit([self.commands()]);
        self.wait_for_readback()?;
        let device_ms = self.copy_out(out)?;
        if let Some(e) = take_error(&self.errors) {
            bail!("the GPU reported an error during the decode: {e}");
        }
        self.slots_filled = 3;
        out.timings = tremorscan::decode::StageTimings {
            solve_ms: started.elapsed().as_secs_f64() * 1e3,
            motion_ms: 0.0,
            smooth_ms: 0.0,
            unwrap_ms: 0.0,
            device_ms,
        };
        Ok(())
    }

    /// The six stages and the copies into the read-back buffer.
    fn commands(&self) -> wgpu::CommandBuffer {
        let (w, h) = (self.width as u32, self.height as u32);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("decode"),
            });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("decode"),
                timestamp_writes: self.timestamps.as_ref().map(|t| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: &t.queries,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }
                }),
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            for (entry, pipeline) in STAGES.iter().zip(&self.pipelines) {
                pass.set_pipeline(pipeline);
                // The recursions: one invocation per segment of a row or column.
                let segments =
                    |lines: u32, len: u32| (lines * len.div_ceil(RECURSION_SEGMENT)).div_ceil(64);
                match *entry {
                    "horizontal" => pass.dispatch_workgroups(segments(h, w), 1, 1),
                    "vertical" => pass.dispatch_workgroups(segments(w, h), 1, 1),
                    _ => pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1),
                }
            }
        }
        let plane = (self.width * self.height * 4) as u64;
        let copy =
            |encoder: &mut wgpu::CommandEncoder, src, src_plane: usize, dst_plane, planes| {
                encoder.copy_buffer_to_buffer(
                    src,
                    src_plane as u64 * plane,
                    &self.readback,
                    dst_plane * plane,
                    planes * plane,
                );
            };
        copy(&mut encoder, &self.work, COORD_PLANE, 0, 1);
        copy(&mut encoder, &self.bits, FINAL_PLANE, 1, 1);
        copy(&mut encoder, &self.solved, AMP_PLANE, 2, 6);
        if let Some(t) = &self.timestamps {
            encoder.resolve_query_set(&t.queries, 0..2, &t.resolved, 0);
            encoder.copy_buffer_to_buffer(
                &t.resolved,
                0,
                &self.readback,
                READBACK_PLANES as u64 * plane,
                TIMESTAMP_BYTES,
            );
        }
        encoder.finish()
    }

    fn wait_for_readback(&self) -> Result<()> {
        let (sender, receiver) = mpsc::sync_channel(1);
        self.readback
            .map_async(wgpu::MapMode::Read, .., move |result| {
                // The receiver waits below; a send cannot fail while it does.
                let _ = sender.send(result);
            });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("the GPU did not finish the decode")?;
        receiver
            .recv()
            .context("the GPU read-back was abandoned")?
            .context("could not map the GPU read-back buffer")
    }

    /// Pixel-planar read-back → the row-planar output; unmaps the buffer whatever happens.
    /// Returns the compute pass's duration by the GPU's clock, ms, where it has timestamps.
    fn copy_out(&self, out: &mut DecodeOutput) -> Result<Option<f64>> {
        let result = (|| {
            let view = self
                .readback
                .get_mapped_range(..)
                .context("could not read the GPU read-back buffer")?;
            let words: &[u32] = bytemuck::try_cast_slice(&view)
                .map_err(|e| anyhow::anyhow!("GPU read-back is not word aligned: {e:?}"))?;
            let (planes, stamps) = words.split_at(READBACK_PLANES * self.width * self.height);
            unpack(planes, self.width, out);
            Ok(self.timestamps.as_ref().and_then(|t| {
                let tick =
                    |i: usize| u64::from(stamps[2 * i]) | (u64::from(stamps[2 * i + 1]) << 32);
                let ticks = tick(1).checked_sub(tick(0))?;
                Some(ticks as f64 * t.period_ns * 1e-6)
            }))
        })();
        self.readback.unmap();
        result
    }
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
