//! GPU decode of CPS-RGB windows: `shaders/decode.wgsl` run with wgpu compute, headless.
//!
//! [`GpuContext`] opens the best adapter wgpu finds (a real GPU, or Mesa's lavapipe on a machine
//! without one). [`GpuDecoder`] holds the pipelines and every buffer for one image size and
//! window solver; [`GpuDecoder::decode`] uploads the three frames, runs the six stages of the
//! shader in one compute pass (wgpu orders the dispatches by their buffer use) and reads back
//! the projector coordinate and the invalid-reason flags, in the CPU decoder's conventions
//! (NaN where invalid). The result matches the CPU path (tested on lavapipe).

mod params;

pub use params::DecodeUniform;

use anyhow::{bail, ensure, Context, Result};
use std::future::Future;
use std::sync::mpsc;
use std::task::{Poll, Waker};
use tremorscan::decode::{DecodeParams, UnwrapMethod, WindowSolver};
use tremorscan::frame::Frame;

/// The decode shader, validated by naga in `ui/tests/shaders.rs`.
pub const SHADER_WGSL: &str = include_str!("../../../shaders/decode.wgsl");

/// Entry points of the shader, in the order they run.
pub const STAGES: [&str; 6] = [
    "solve",
    "connect",
    "horizontal",
    "vertical",
    "unwrap",
    "jumps",
];
/// Planes of the `solved` and `work` buffers and words per pixel of `bits` (see the shader).
const SOLVED_PLANES: usize = 9;
const WORK_PLANES: usize = 7;
const BIT_PLANES: usize = 3;
const COORD_PLANE: usize = 6;
const FINAL_PLANE: usize = 2;

/// Runs a wgpu future to completion; on native backends they are ready at once or soon.
fn block_on<F: Future>(future: F) -> F::Output {
    let mut future = std::pin::pin!(future);
    let mut cx = std::task::Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(value) = future.as_mut().poll(&mut cx) {
            return value;
        }
        std::thread::yield_now();
    }
}

/// A headless wgpu device for compute.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Adapter name and backend, for reports.
    pub adapter: String,
}

impl GpuContext {
    /// Opens the preferred adapter (`WGPU_BACKEND` and friends are honoured) with its own limits.
    pub fn new() -> Result<Self> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        }))
        .context("no GPU adapter (install a Vulkan driver, e.g. Mesa's lavapipe)")?;
        let info = adapter.get_info();
        let (device, queue) = block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("tremorscan decode"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .with_context(|| format!("could not open {}", info.name))?;
        Ok(Self {
            device,
            queue,
            adapter: format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type),
        })
    }
}

/// Pipelines and buffers for one size and window solver.
pub struct GpuDecoder {
    device: wgpu::Device,
    queue: wgpu::Queue,
    width: usize,
    height: usize,
    order: Vec<usize>,
    frame_bytes: usize,
    pipelines: Vec<wgpu::ComputePipeline>,
    bind_group: wgpu::BindGroup,
    frames: wgpu::Buffer,
    work: wgpu::Buffer,
    bits: wgpu::Buffer,
    readback: wgpu::Buffer,
    upload: Vec<u8>,
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
    /// Prepares decoding of `width`×`height` windows of `solver` (CPS-RGB, robust unwrap).
    pub fn new(
        ctx: &GpuContext,
        width: usize,
        height: usize,
        solver: &WindowSolver,
        params: &DecodeParams,
        chebyshev_n: u32,
    ) -> Result<Self> {
        ensure!(
            width > 0 && height > 0,
            "image size {width}×{height} is empty"
        );
        ensure!(
            solver.channels == 3 && solver.observations == 9 && solver.unknowns == 9,
            "the GPU decoder handles CPS-RGB windows (9 observations, 9 unknowns), not {} × {}",
            solver.observations,
            solver.unknowns
        );
        if params.unwrap != UnwrapMethod::ChebyshevRobust {
            bail!(
                "the GPU decoder implements the robust Chebyshev unwrap, not {:?}",
                params.unwrap
            );
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
        let uniform = DecodeUniform::new(width, height, solver, params, chebyshev_n);
        let frame_bytes = uniform.frame_words as usize * 4;
        let buffer = |label: &str, size: usize, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let uniform_buffer = buffer("decode params", 112, U::UNIFORM | U::COPY_DST);
        let frames = buffer("frames", 3 * frame_bytes, U::STORAGE | U::COPY_DST);
        let pinv = buffer("pinv", 81 * 4, U::STORAGE | U::COPY_DST);
        let solved = buffer("solved", SOLVED_PLANES * n * 4, U::STORAGE);
        let work = buffer("work", WORK_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let bits = buffer("bits", BIT_PLANES * n * 4, U::STORAGE | U::COPY_SRC);
        let readback = buffer("readback", 2 * n * 4, U::MAP_READ | U::COPY_DST);
        ctx.queue
            .write_buffer(&uniform_buffer, 0, bytemuck::bytes_of(&uniform));
        ctx.queue
            .write_buffer(&pinv, 0, bytemuck::cast_slice(&solver.pinv));
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
                (0, &uniform_buffer),
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
        Ok(Self {
            device,
            queue: ctx.queue.clone(),
            width,
            height,
            order: solver.order.clone(),
            frame_bytes,
            pipelines,
            bind_group,
            frames,
            work,
            bits,
            readback,
            upload: vec![0; 3 * frame_bytes],
        })
    }

    /// Decodes the window `frames` (oldest first, in the solver's pattern order) into
    /// `coordinate_px` (NaN where invalid) and `invalid` (the CPU decoder's reason bits).
    pub fn decode(
        &mut self,
        frames: [&Frame; 3],
        coordinate_px: &mut Vec<f32>,
        invalid: &mut Vec<u8>,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        let n = w * h;
        for (k, frame) in frames.iter().enumerate() {
            ensure!(
                frame.width == w && frame.height == h && frame.channels == 3,
                "frame {k} is {}×{}×{}, the GPU decoder was set up for {w}×{h} RGB",
                frame.width,
                frame.height,
                frame.channels
            );
            ensure!(
                frame.pattern_index == self.order[k],
                "frame {k} shows pattern {}, the window expects {}",
                frame.pattern_index,
                self.order[k]
            );
            let start = k * self.frame_bytes;
            self.upload[start..start + 3 * n].copy_from_slice(&frame.data[..3 * n]);
        }
        self.queue.write_buffer(&self.frames, 0, &self.upload);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("decode"),
            });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("decode"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            let tiles = ((w as u32).div_ceil(8), (h as u32).div_ceil(8));
            for (entry, pipeline) in STAGES.iter().zip(&self.pipelines) {
                pass.set_pipeline(pipeline);
                match *entry {
                    "horizontal" => pass.dispatch_workgroups((h as u32).div_ceil(64), 1, 1),
                    "vertical" => pass.dispatch_workgroups((w as u32).div_ceil(64), 1, 1),
                    _ => pass.dispatch_workgroups(tiles.0, tiles.1, 1),
                }
            }
        }
        let plane = (n * 4) as u64;
        encoder.copy_buffer_to_buffer(
            &self.work,
            COORD_PLANE as u64 * plane,
            &self.readback,
            0,
            plane,
        );
        encoder.copy_buffer_to_buffer(
            &self.bits,
            FINAL_PLANE as u64 * plane,
            &self.readback,
            plane,
            plane,
        );
        self.queue.submit([encoder.finish()]);
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
            .context("could not map the GPU read-back buffer")?;
        {
            let view = self
                .readback
                .get_mapped_range(..)
                .context("could not read the GPU read-back buffer")?;
            let (coords, flags) = view.split_at(n * 4);
            coordinate_px.clear();
            invalid.clear();
            for (c, f) in coords.chunks_exact(4).zip(flags.chunks_exact(4)) {
                let reason = u32::from_le_bytes([f[0], f[1], f[2], f[3]]);
                let value = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                invalid.push(reason as u8);
                coordinate_px.push(if reason == 0 { value } else { f32::NAN });
            }
        }
        self.readback.unmap();
        Ok(())
    }
}
