//! GPU decode of CPS-RGB windows: `shaders/decode.wgsl` run with wgpu compute, headless.
//!
//! [`GpuContext`] opens the best adapter wgpu finds (a real GPU, or Mesa's lavapipe on a machine
//! without one). [`GpuDecoder`] holds the pipelines and every buffer for one image size; it keeps
//! the last three frames on the GPU (a new window uploads only its new frame), runs the stages
//! of the shader in a compute pass (wgpu orders the dispatches by their buffer use; with the
//! motion model, two submissions: the window's noise, measured on the device, is read back and
//! finished on the host between them) and reads back the projector coordinate, the
//! invalid-reason flags, the amplitudes and the colour into a
//! [`tremorscan::decode::DecodeOutput`], in the CPU decoder's conventions, then runs the host's
//! mixed-pixel stage as the CPU does. [`GpuBackend`]
//! puts it behind the library's `DecodeBackend`, so the pipeline runs on it; it falls back to
//! the CPU if the GPU fails. The results match the CPU path (tested on lavapipe).

mod backend;
mod decoder;
mod motion;
mod params;
mod readback;

pub use backend::{backend_for, start_pipeline, DecoderChoice, GpuBackend};
pub use decoder::GpuDecoder;
pub use motion::{MODEL_WINDOW_OFFSET, MOTION_STAGES};
pub use params::DecodeUniform;

use anyhow::{Context, Result};
use std::future::Future;
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Poll, Waker};

/// The decode shader: `decode.wgsl`, the motion model's part (`decode_motion.wgsl`) and the
/// links between windows (`decode_stream.wgsl`), as one module (validated together by naga in
/// `ui/tests/shaders.rs`).
pub const SHADER_WGSL: &str = concat!(
    include_str!("../../../shaders/decode.wgsl"),
    include_str!("../../../shaders/decode_motion.wgsl"),
    include_str!("../../../shaders/decode_stream.wgsl")
);

/// Entry points of the still decode, in the order they run (the motion model's:
/// [`MOTION_STAGES`]).
pub const STAGES: [&str; 7] = [
    "solve",
    "connect",
    "horizontal",
    "vertical",
    "unwrap",
    "jumps",
    "noise_grid_final",
];
/// Planes of the `solved` and `work` buffers and words per pixel of `bits` (see the shader).
const SOLVED_PLANES: usize = 9;
const WORK_PLANES: usize = 7;
const BIT_PLANES: usize = 3;
const COORD_PLANE: usize = 6;
/// Pixels per invocation of the shader's recursions (`SEGMENT` there; `ui/tests/shaders.rs`
/// checks they agree).
pub const RECURSION_SEGMENT: u32 = 64;
/// First plane of `solved` read back: amplitudes (3) then colour (3).
const AMP_PLANE: usize = 3;
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

/// When the decoder times its compute pass by the GPU's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimestampUse {
    /// On hardware adapters. Lavapipe has timestamp queries, but a pass that writes them takes
    /// about half as long again there (measured: 672–708 ms a window instead of 412–454 at
    /// 1920×1200).
    HardwareOnly,
    /// Wherever the adapter has them (tests of the timing itself).
    Always,
}

/// A headless wgpu device for compute.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Adapter name and backend, for reports.
    pub adapter: String,
    /// The adapter is a CPU implementation (lavapipe, llvmpipe, WARP): slower than the CPU
    /// decoder, good for tests only.
    pub is_software: bool,
    /// The device has timestamp queries: the decoder times its compute pass by the GPU's clock.
    pub timestamps: bool,
    /// The first error the device reported outside a call's result (validation, out of
    /// memory), kept instead of wgpu's default of panicking; see [`GpuContext::take_error`].
    errors: DeviceErrors,
}

/// Where a device's uncaptured errors go.
pub(crate) type DeviceErrors = Arc<Mutex<Option<String>>>;

/// Takes the error `errors` holds, if any.
pub(crate) fn take_error(errors: &DeviceErrors) -> Option<String> {
    errors.lock().unwrap_or_else(PoisonError::into_inner).take()
}

impl GpuContext {
    /// Opens the preferred adapter (`WGPU_BACKEND` and friends are honoured) with its own limits;
    /// timestamps on hardware adapters only.
    pub fn new() -> Result<Self> {
        Self::open(TimestampUse::HardwareOnly)
    }

    /// Opens the preferred adapter, with timestamps as `use_timestamps` says (where the adapter
    /// has them).
    pub fn open(use_timestamps: TimestampUse) -> Result<Self> {
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
        // Timestamps let the bench report the GPU's own compute time, apart from transfers.
        let software = info.device_type == wgpu::DeviceType::Cpu;
        let features = match use_timestamps {
            TimestampUse::HardwareOnly if software => wgpu::Features::empty(),
            _ => adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        };
        let (device, queue) = block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("tremorscan decode"),
            required_limits: adapter.limits(),
            required_features: features,
            ..Default::default()
        }))
        .with_context(|| format!("could not open {}", info.name))?;
        // wgpu's default handler panics, which would take the decode thread down; keep the
        // error for the decoder to return with its next result instead.
        let errors: DeviceErrors = Arc::default();
        let slot = Arc::clone(&errors);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            slot.lock()
                .unwrap_or_else(PoisonError::into_inner)
                .get_or_insert_with(|| e.to_string());
        }));
        Ok(Self {
            device,
            queue,
            adapter: format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type),
            is_software: software,
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            errors,
        })
    }

    /// The first error the device reported since the last call (buffers it could not allocate,
    /// invalid use), if any.
    pub fn take_error(&self) -> Option<String> {
        take_error(&self.errors)
    }
}
