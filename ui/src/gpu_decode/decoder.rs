//! [`GpuDecoder`]: the buffers and pipelines of one image size, and one window's round trip.
//!
//! Frames live in three slots of one buffer; the slot of the next upload turns round, so a
//! window that shares two frames with the previous one uploads one frame (6.9 MB at 1920×1200)
//! and tells the shader where its oldest frame is (`first_slot`). The solver's pseudo-inverse
//! and the uniform are rewritten for every window (the window order turns with the patterns).
//! One read-back buffer receives eight planes (coordinate, final flags, three amplitudes and
//! three colours), the final noise grid and the timestamps; the host copies the planes into the
//! row-planar [`DecodeOutput`] and runs the mixed-pixel stage with the grid's noise. With the
//! motion model ([`super::motion`]) a window is two submissions: stage 1 and its noise grid,
//! whose median the host takes, then the steps and the rest.

use super::motion::{self, StreamClock, MODEL_WORDS, MOTION_STAGES};
pub(super) use super::params::unsupported;
use super::readback::{
    map_and_wait, read_window, Layout, Timestamps, READBACK_PLANES, TIMESTAMPS, TIMESTAMP_BYTES,
};
use super::{
    take_error, DecodeUniform, DeviceErrors, GpuContext, AMP_PLANE, BIT_PLANES, COORD_PLANE,
    FINAL_PLANE, RECURSION_SEGMENT, SHADER_WGSL, SOLVED_PLANES, STAGES, WORK_PLANES,
};
use anyhow::{bail, ensure, Context, Result};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;
use tremorscan::decode::backend::Window;
use tremorscan::decode::{
    broken, edges, motion_basis, DecodeOutput, DecodeParams, MotionBasis, MotionModel, WindowSolver,
};

/// Pipelines and buffers for one image size.
pub struct GpuDecoder {
    device: wgpu::Device,
    queue: wgpu::Queue,
    width: usize,
    height: usize,
    frame_bytes: usize,
    pipelines: HashMap<&'static str, wgpu::ComputePipeline>,
    bind_group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    pinv: wgpu::Buffer,
    frames: wgpu::Buffer,
    solved: wgpu::Buffer,
    work: wgpu::Buffer,
    bits: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// The motion model's constants (`M` in the shader; its planes, `state`, live on in the
    /// bind group); with the model, the noise grid's read-back (`None` without).
    model: wgpu::Buffer,
    noise_readback: Option<wgpu::Buffer>,
    /// The noise grid's values (`grid` in the shader) and how many there are.
    grid: wgpu::Buffer,
    grid_len: usize,
    noise_scratch: Vec<f32>,
    /// When the stream's planes on the device were written.
    clock: StreamClock,
    /// The noise the last window's final planes showed, gray levels (`None`: too few pixels).
    final_noise_gray: Option<f32>,
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
        // The motion model's planes only where it may run.
        let with_motion = params.motion.model != MotionModel::Off && params.motion.iterations > 0;
        let work_planes = if with_motion {
            motion::WORK_PLANES_WITH_MOTION
        } else {
            WORK_PLANES
        };
        let work = buffer("work", work_planes * n * 4, U::STORAGE | U::COPY_SRC);
        let model = buffer("motion model", MODEL_WORDS * 4, U::STORAGE | U::COPY_DST);
        let state_bytes = if with_motion {
            motion::STATE_PLANES * n * 4
        } else {
            4
        };
        let state = buffer("motion state", state_bytes, U::STORAGE | U::COPY_SRC);
        let grid_len = motion::grid_len(width, height);
        let grid = buffer("noise grid", grid_len.max(1) * 4, U::STORAGE | U::COPY_SRC);
        let noise_readback = with_motion.then(|| {
            buffer(
                "noise grid read-back",
                grid_len.max(1) * 4,
                U::MAP_READ | U::COPY_DST,
            )
        });
        let bits = buffer("bits", BIT_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let readback = buffer(
            "readback",
            (READBACK_PLANES * n + grid_len.max(1)) * 4 + TIMESTAMP_BYTES as usize,
            U::MAP_READ | U::COPY_DST,
        );
        let timestamps = device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| Timestamps {
                queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("decode pass"),
                    ty: wgpu::QueryType::Timestamp,
                    count: TIMESTAMPS,
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
                storage_entry(6, true),
                storage_entry(7, false),
                storage_entry(8, false),
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
                (6, &model),
                (7, &state),
                (8, &grid),
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
            .chain(MOTION_STAGES.iter().filter(|_| with_motion))
            .map(|&entry| {
                let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                });
                (entry, pipeline)
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
            model,
            noise_readback,
            noise_scratch: Vec::with_capacity(grid_len),
            grid,
            grid_len,
            clock: StreamClock::default(),
            final_noise_gray: None,
            timestamps,
            staging: vec![0; frame_bytes],
            next_slot: 0,
            slots_filled: 0,
        })
    }

    /// The noise level the last window's final planes showed on the device's grid (what the
    /// host's mixed-pixel stage took), gray levels; `None` with too few pixels.
    pub fn final_noise_gray(&self) -> Option<f32> {
        self.final_noise_gray
    }

    /// The image size this decoder was set up for.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Decodes `window` into `out` (sized for it): coordinate (NaN where invalid), reasons,
    /// amplitudes, colour and the timing (the whole round trip as `solve_ms`, the compute
    /// passes by the GPU's clock as `device_ms` where the adapter has timestamps, the host's
    /// mixed-pixel stage as `unwrap_ms`). That last stage runs here, on the host, as after the
    /// CPU's stages, with the noise the final planes show (measured on the device's grid).
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
        let basis = motion_basis(window.solver, window.frames, window.params);
        let stages = match &basis {
            Some(basis) => {
                let links =
                    self.motion_first_pass(basis, window.params, chebyshev_n, out.time_s)?;
                let predicted = links.previous_s.is_some() && window.params.motion.predicts_start();
                motion::steps_then_unwrap(
                    window.params.motion.iterations,
                    window.params.motion.moving_unit_decay.is_some(),
                    predicted,
                )
            }
            None => {
                self.clock.still_window();
                let off = motion::model_off();
                self.queue
                    .write_buffer(&self.model, 0, bytemuck::cast_slice(&off));
                STAGES.to_vec()
            }
        };
        let passes = if basis.is_some() { 2 } else { 1 };
        let commands = self.commands(&stages, passes - 1)?;
        self.queue.submit([commands]);
        map_and_wait(&self.device, &self.readback)?;
        let (device_ms, final_noise_gray) = self.copy_out(out, passes as usize)?;
        // The stream's state is on the device: the CPU, should it take over, starts afresh.
        out.forget_stream();
        if let Some(e) = take_error(&self.errors) {
            bail!("the GPU reported an error during the decode: {e}");
        }
        self.slots_filled = 3;
        self.final_noise_gray = final_noise_gray;
        let read_back = Instant::now();
        edges::flag_mixed_pixels_with_noise(window.solver, window.params, final_noise_gray, out);
        if broken::refuse_broken_window(out) {
            // As on the CPU, the next window is not linked to a refused one.
            self.clock = StreamClock::default();
        }
        out.timings = tremorscan::decode::StageTimings {
            solve_ms: (read_back - started).as_secs_f64() * 1e3,
            motion_ms: 0.0,
            smooth_ms: 0.0,
            unwrap_ms: read_back.elapsed().as_secs_f64() * 1e3,
            device_ms,
        };
        Ok(())
    }

    /// The motion window's first submission: stage 1 with the evidence, the links, the noise
    /// grid, read back and finished on the host; then the window's values with that noise.
    /// Returns the window's links to the stream.
    fn motion_first_pass(
        &mut self,
        basis: &MotionBasis,
        params: &DecodeParams,
        chebyshev_n: u32,
        time_s: f64,
    ) -> Result<motion::WindowLinks> {
        let noise_readback = self
            .noise_readback
            .as_ref()
            .context("the GPU decoder was set up without the motion model")?;
        let links = self.clock.advance(time_s, basis, params.check_order_jumps);
        let words = motion::model_words(basis, params, (self.width, chebyshev_n), links);
        self.queue
            .write_buffer(&self.model, 0, bytemuck::cast_slice(&words));
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("decode, motion: stage 1"),
            });
        self.encode_pass(&mut encoder, &["solve", "connect", "noise_grid"], 0)?;
        let grid = self.grid_len;
        encoder.copy_buffer_to_buffer(&self.grid, 0, noise_readback, 0, grid.max(1) as u64 * 4);
        self.queue.submit([encoder.finish()]);
        map_and_wait(&self.device, noise_readback)?;
        let measured = (|| {
            let view = noise_readback
                .get_mapped_range(..)
                .context("could not read the noise grid's read-back")?;
            let values: &[f32] = bytemuck::try_cast_slice(&view)
                .map_err(|e| anyhow::anyhow!("the noise grid's read-back is not words: {e:?}"))?;
            Ok::<_, anyhow::Error>(motion::noise_from_grid(
                &values[..grid],
                &mut self.noise_scratch,
            ))
        })();
        noise_readback.unmap();
        let measured = measured?;
        let window =
            motion::window_words(basis, params, (self.width, chebyshev_n), links, measured);
        self.queue.write_buffer(
            &self.model,
            (motion::MODEL_WINDOW_OFFSET * 4) as u64,
            bytemuck::cast_slice(&window),
        );
        Ok(links)
    }

    /// One compute pass of `stages`, in order, with timestamps `2·pass` and `2·pass + 1`.
    fn encode_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        stages: &[&str],
        pass_index: u32,
    ) -> Result<()> {
        let (w, h) = (self.width as u32, self.height as u32);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("decode"),
            timestamp_writes: self
                .timestamps
                .as_ref()
                .map(|t| wgpu::ComputePassTimestampWrites {
                    query_set: &t.queries,
                    beginning_of_pass_write_index: Some(2 * pass_index),
                    end_of_pass_write_index: Some(2 * pass_index + 1),
                }),
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        // The recursions: one invocation per segment of a row or column (the evidence's: two
        // sets of planes).
        let segments = |lines: u32, len: u32| lines * len.div_ceil(RECURSION_SEGMENT);
        let groups = |invocations: u32| invocations.div_ceil(64);
        for entry in stages {
            let Some(pipeline) = self.pipelines.get(entry) else {
                bail!("the GPU decoder was set up without its stage `{entry}`");
            };
            pass.set_pipeline(pipeline);
            match *entry {
                "horizontal" => pass.dispatch_workgroups(groups(segments(h, w)), 1, 1),
                "vertical" => pass.dispatch_workgroups(groups(segments(w, h)), 1, 1),
                "step_horizontal" => pass.dispatch_workgroups(groups(2 * segments(h, w)), 1, 1),
                "step_vertical" => pass.dispatch_workgroups(groups(2 * segments(w, h)), 1, 1),
                "wide_horizontal" => pass.dispatch_workgroups(groups(segments(h, w)), 1, 1),
                "wide_vertical" => pass.dispatch_workgroups(groups(segments(w, h)), 1, 1),
                // One invocation per grid pixel (the grid's kernels read only `id.x`).
                "noise_grid" | "noise_grid_final" => {
                    pass.dispatch_workgroups(groups(self.grid_len as u32).max(1), 1, 1);
                }
                _ => pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1),
            }
        }
        Ok(())
    }

    /// The stages of the window's (last) pass, and the copies into the read-back buffer.
    fn commands(&self, stages: &[&str], pass_index: u32) -> Result<wgpu::CommandBuffer> {
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("decode"),
            });
        self.encode_pass(&mut encoder, stages, pass_index)?;
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
        let grid_bytes = self.grid_len.max(1) as u64 * 4;
        let planes_bytes = READBACK_PLANES as u64 * plane;
        encoder.copy_buffer_to_buffer(&self.grid, 0, &self.readback, planes_bytes, grid_bytes);
        if let Some(t) = &self.timestamps {
            encoder.resolve_query_set(&t.queries, 0..2 * (pass_index + 1), &t.resolved, 0);
            encoder.copy_buffer_to_buffer(
                &t.resolved,
                0,
                &self.readback,
                planes_bytes + grid_bytes,
                TIMESTAMP_BYTES,
            );
        }
        Ok(encoder.finish())
    }

    /// Pixel-planar read-back → the row-planar output; unmaps the buffer whatever happens.
    /// Returns the `passes` compute passes' duration by the GPU's clock, ms, where it has
    /// timestamps, and the noise the final planes' grid shows.
    fn copy_out(
        &mut self,
        out: &mut DecodeOutput,
        passes: usize,
    ) -> Result<(Option<f64>, Option<f32>)> {
        let scratch = &mut self.noise_scratch;
        let result = (|| {
            let view = self
                .readback
                .get_mapped_range(..)
                .context("could not read the GPU read-back buffer")?;
            let words: &[u32] = bytemuck::try_cast_slice(&view)
                .map_err(|e| anyhow::anyhow!("GPU read-back is not word aligned: {e:?}"))?;
            let layout = Layout {
                width: self.width,
                height: self.height,
                grid_len: self.grid_len,
                passes,
            };
            Ok(read_window(
                words,
                layout,
                self.timestamps.as_ref(),
                scratch,
                out,
            ))
        })();
        self.readback.unmap();
        result
    }
}

#[cfg(test)]
mod tests;
