//! [`GpuBackend`]: the GPU decoder behind the library's `DecodeBackend`, and the choice of
//! backend the commands and the GUI offer (`--decoder auto|cpu|gpu`).
//!
//! The backend sets its [`GpuDecoder`] up on the first window (and again when the image size
//! changes). If the GPU fails (device lost, out of memory) it reports the error once, for that
//! window, and decodes every later window on the CPU: a session keeps going.

use super::decoder::unsupported;
use super::{GpuContext, GpuDecoder};
use anyhow::{Context, Result};
use std::sync::OnceLock;
use tremorscan::color::CrossTalk;
use tremorscan::decode::backend::Window;
use tremorscan::decode::{CpuBackend, DecodeBackend, DecodeError, DecodeOutput, DecodeParams};
use tremorscan::device::Camera;
use tremorscan::pattern::PatternSequence;
use tremorscan::pipeline::{Pipeline, PipelineConfig};
use tremorscan::triangulate::StereoModel;

/// Which decode backend to run.
#[derive(
    clap::ValueEnum,
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum DecoderChoice {
    /// A hardware GPU if wgpu finds one, otherwise the CPU (a software adapter such as
    /// lavapipe is slower than the CPU decoder, so it is not used).
    #[default]
    Auto,
    /// The CPU decoder.
    Cpu,
    /// The GPU decoder on wgpu's preferred adapter, software adapters included.
    Gpu,
}

/// Why `auto` decodes on the CPU, once a probe found no hardware adapter: adapters do not come
/// and go while the app runs, and each probe opens the driver (tens of milliseconds), so later
/// pipeline starts in this process skip it.
static NO_HARDWARE_GPU: OnceLock<String> = OnceLock::new();

/// The decode backend for `choice`, for windows of `sequence` decoded with `params`, and a note
/// on why `auto` chose the CPU (`None` when it did not).
pub fn backend_for(
    choice: DecoderChoice,
    sequence: &PatternSequence,
    params: &DecodeParams,
) -> Result<(Box<dyn DecodeBackend>, Option<String>)> {
    match choice {
        DecoderChoice::Cpu => Ok((Box::new(CpuBackend), None)),
        DecoderChoice::Gpu => {
            let backend = GpuContext::new()
                .and_then(|ctx| GpuBackend::new(ctx, sequence, params))
                .context("the GPU decoder was asked for")?;
            Ok((Box::new(backend), None))
        }
        DecoderChoice::Auto => {
            let cpu = |why: String| -> (Box<dyn DecodeBackend>, Option<String>) {
                (Box::new(CpuBackend), Some(why))
            };
            if let Some(why) = NO_HARDWARE_GPU.get() {
                return Ok(cpu(why.clone()));
            }
            let why = match GpuContext::new() {
                Ok(ctx) if !ctx.is_software => {
                    return Ok(match GpuBackend::new(ctx, sequence, params) {
                        Ok(backend) => (Box::new(backend), None),
                        Err(e) => cpu(format!("decoding on the CPU: {e:#}")),
                    });
                }
                Ok(ctx) => format!(
                    "decoding on the CPU: the only GPU adapter is software ({})",
                    ctx.adapter
                ),
                Err(e) => format!("decoding on the CPU: {e:#}"),
            };
            Ok(cpu(NO_HARDWARE_GPU.get_or_init(|| why).clone()))
        }
    }
}

/// Starts a pipeline with its decode on `decoder`; also returns why `auto` chose the CPU, if it
/// did.
pub fn start_pipeline(
    decoder: DecoderChoice,
    camera: Box<dyn Camera>,
    sequence: PatternSequence,
    cross_talk: CrossTalk,
    stereo: StereoModel,
    config: PipelineConfig,
) -> Result<(Pipeline, Option<String>)> {
    let (backend, why_cpu) = backend_for(decoder, &sequence, &config.decode_params)?;
    let pipeline =
        Pipeline::start_with_backend(camera, sequence, cross_talk, stereo, config, backend)?;
    Ok((pipeline, why_cpu))
}

/// Decodes CPS-RGB windows with the robust unwrap on a GPU.
pub struct GpuBackend {
    ctx: GpuContext,
    decoder: Option<GpuDecoder>,
    /// Set when the GPU failed: why. Every later window runs on `cpu`.
    failed: Option<String>,
    cpu: CpuBackend,
}

impl std::fmt::Debug for GpuBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBackend")
            .field("adapter", &self.ctx.adapter)
            .field("size", &self.decoder.as_ref().map(GpuDecoder::size))
            .field("failed", &self.failed)
            .finish()
    }
}

impl GpuBackend {
    /// A backend on `ctx` for windows of `sequence` decoded with `params`; refuses what the
    /// shader does not implement (gray or multi-frequency sequences, other unwrap methods).
    pub fn new(ctx: GpuContext, sequence: &PatternSequence, params: &DecodeParams) -> Result<Self> {
        let len = sequence.entries.len();
        let channels = if sequence.is_rgb() { 3 } else { 1 };
        let frequencies = sequence.distinct_frequencies().len();
        // A CPS-RGB window: 3 colour frames, 3 offsets and 3 frequencies × (cos, sin).
        let shape = (channels, len * channels, channels + 2 * frequencies);
        if sequence.chebyshev_n().is_none() {
            anyhow::bail!("the GPU decoder needs a Chebyshev (CPS) sequence");
        }
        if let Some(why) = unsupported(shape, params) {
            anyhow::bail!(why);
        }
        Ok(Self {
            ctx,
            decoder: None,
            failed: None,
            cpu: CpuBackend,
        })
    }

    fn decode_on_gpu(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<()> {
        let size = (out.width, out.height);
        let decoder = match &mut self.decoder {
            Some(d) if d.size() == size => d,
            slot => slot.insert(GpuDecoder::new(
                &self.ctx,
                size.0,
                size.1,
                window.solver,
                window.params,
            )?),
        };
        decoder.decode(window, out)
    }
}

impl DecodeBackend for GpuBackend {
    fn name(&self) -> String {
        match &self.failed {
            None => format!("GPU: {}", self.ctx.adapter),
            Some(why) => format!("{} after the GPU failed ({why})", self.cpu.name()),
        }
    }

    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError> {
        if self.failed.is_some() {
            return self.cpu.decode(window, out);
        }
        self.decode_on_gpu(window, out).map_err(|e| {
            let message = format!("{e:#}");
            self.failed = Some(message.clone());
            self.decoder = None;
            DecodeError::Backend {
                backend: format!("GPU {}", self.ctx.adapter),
                message: format!("{message}; the next windows are decoded on the CPU"),
            }
        })
    }
}
