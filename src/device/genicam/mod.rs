//! GenICam cameras (USB3 Vision, GigE Vision) through aravis, behind the `genicam` feature.
//!
//! [`list_cameras`] enumerates what aravis sees; [`GenicamCamera::open`] opens one by its id,
//! applies [`GenicamSettings`] (pixel format, binning, exposure, gain, region, frame rate,
//! trigger), hands the stream a pool of [`GenicamSettings::buffer_count`] buffers and starts
//! acquisition. Each grab pops one filled buffer, copies (RGB8) or demosaics (Bayer 8-bit) it
//! into the frame, and gives the buffer back to the pool at once.
//!
//! * Frame numbers are the camera's block ids, unwrapped to 64 bits (GigE Vision's are 16-bit and
//!   skip 0); incomplete buffers are given back and show as a gap, which the pipeline counts as
//!   lost frames. Times are the camera's time stamps (ns), relative to the first frame.
//! * The pattern shown by frame `k` is `(k + pattern_offset) mod pattern_count`: with the
//!   projector's trigger driving the camera, every camera frame is one pattern image.
//! * Unplugging: aravis's `control-lost` signal (missed heartbeats on GigE Vision, a USB error on
//!   USB3 Vision) sets a flag; a grab that finds it, or that waits [`STALL_TIMEOUT`] with no
//!   frame in free run and then fails to read the camera, reports [`DeviceError::Disconnected`].
//!   The pipeline then ends the stream, and a recording keeps every frame it already has.
//! * A link too slow for the stream (USB3 Vision states its bandwidth and is checked on opening;
//!   GigE Vision shows it as buffers with missing packets): [`INCOMPLETE_LIMIT`] incomplete
//!   frames in a row end the stream with [`DeviceError::Link`] saying what to change.
//!
//! Aravis's global state is initialised once per process ([`aravis::Aravis::initialize`]); this
//! module keeps that token behind a mutex so tests and threads can share it.

use super::bayer::{demosaic_bilinear, BayerPattern};
use super::{Camera, DeviceError, Grabbed};
use crate::frame::Frame;
use aravis::glib::prelude::Cast;
use aravis::prelude::*;
use aravis::{Aravis, Buffer, BufferStatus, Stream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

mod configure;
mod types;

pub use types::{
    CameraInfo, CameraReadback, FrameIdUnwrapper, GenicamError, GenicamSettings, PixelChoice,
    TriggerChoice,
};

/// How long a free-running camera may deliver nothing before the grab checks that it is there.
pub const STALL_TIMEOUT: Duration = Duration::from_secs(2);

/// Incomplete frames in a row that mean the link cannot carry the stream.
const INCOMPLETE_LIMIT: u32 = 30;

/// How long one grab waits for a buffer before it returns [`DeviceError::Idle`] (so the capture
/// thread sees stop requests).
const POP_TIMEOUT: Duration = Duration::from_millis(200);

fn aravis() -> &'static Mutex<Option<Aravis>> {
    static TOKEN: OnceLock<Mutex<Option<Aravis>>> = OnceLock::new();
    TOKEN.get_or_init(|| Mutex::new(Aravis::initialize().ok()))
}

/// Every camera aravis finds now (an empty list is not an error).
pub fn list_cameras() -> Vec<CameraInfo> {
    let guard = aravis().lock().unwrap_or_else(|p| p.into_inner());
    let Some(token) = guard.as_ref() else {
        return Vec::new();
    };
    token
        .get_device_list()
        .into_iter()
        .map(|d| CameraInfo {
            id: d.id.to_string_lossy().into_owned(),
            vendor: d.vendor.to_string_lossy().into_owned(),
            model: d.model.to_string_lossy().into_owned(),
            protocol: d.protocol.to_string_lossy().into_owned(),
            address: d.address.to_string_lossy().into_owned(),
        })
        .collect()
}

/// An open, streaming GenICam camera.
pub struct GenicamCamera {
    id: String,
    camera: aravis::Camera,
    stream: Stream,
    width: usize,
    height: usize,
    bayer: Option<BayerPattern>,
    fps: f64,
    free_run: bool,
    settings: GenicamSettings,
    control_lost: Arc<AtomicBool>,
    ids: FrameIdUnwrapper,
    first_timestamp_ns: Option<u64>,
    last_frame_at: Instant,
    /// Buffers given back incomplete (missing packets, timeouts), since opening.
    incomplete: u64,
    /// Incomplete buffers in a row.
    incomplete_streak: u32,
}

impl GenicamCamera {
    /// Opens the camera `id` (from [`list_cameras`]), configures it and starts streaming.
    pub fn open(id: &str, settings: &GenicamSettings) -> Result<Self, GenicamError> {
        let cameras = list_cameras();
        if !cameras.iter().any(|c| c.id == id) {
            let found: Vec<&str> = cameras.iter().map(|c| c.id.as_str()).collect();
            let found = if found.is_empty() {
                "none".to_string()
            } else {
                found.join(", ")
            };
            return Err(GenicamError::NoCamera(id.to_string(), found));
        }
        let camera = aravis::Camera::new(Some(id)).map_err(|e| GenicamError::Busy {
            id: id.to_string(),
            detail: e.message().to_string(),
        })?;
        // GigE Vision lets one program control a camera; a second one gets it read-only.
        if let Some(gv) = camera
            .device()
            .and_then(|d| d.downcast::<aravis::GvDevice>().ok())
        {
            if !gv.is_controller() {
                return Err(GenicamError::Busy {
                    id: id.to_string(),
                    detail: "another program controls it".to_string(),
                });
            }
        }
        let err = |what| configure::setting_error(id, what);
        // Stop whatever a previous program left running before changing settings.
        let _ = camera.stop_acquisition();

        let (format_name, bayer) = configure::choose_format(&camera, id, settings.pixel)?;
        configure::apply(&camera, id, settings, &format_name)?;
        let (_, _, w, h) = camera.region().map_err(err("region"))?;
        let (width, height) = (w.max(0) as usize, h.max(0) as usize);
        let fps = match (&settings.trigger, settings.frame_rate_hz) {
            (TriggerChoice::Hardware { .. }, Some(f)) => f,
            _ => camera.frame_rate().unwrap_or(0.0),
        };
        configure::check_bandwidth(&camera, id, width, height, &format_name, fps)?;

        let control_lost = Arc::new(AtomicBool::new(false));
        if let Some(device) = camera.device() {
            let flag = Arc::clone(&control_lost);
            device.connect_control_lost(move |_| flag.store(true, Ordering::SeqCst));
        }
        let stream = camera.create_stream().map_err(err("a stream"))?;
        let payload = camera.payload().map_err(err("payload"))? as usize;
        for _ in 0..settings.buffer_count.max(2) {
            stream.push_buffer(Buffer::new_allocate(payload));
        }
        camera
            .start_acquisition()
            .map_err(err("acquisition start"))?;
        Ok(Self {
            id: id.to_string(),
            camera,
            stream,
            width,
            height,
            bayer,
            fps,
            free_run: settings.trigger == TriggerChoice::FreeRun,
            settings: settings.clone(),
            control_lost,
            ids: FrameIdUnwrapper::default(),
            first_timestamp_ns: None,
            last_frame_at: Instant::now(),
            incomplete: 0,
            incomplete_streak: 0,
        })
    }

    /// Reads the settings back from the camera.
    pub fn readback(&self) -> Result<CameraReadback, GenicamError> {
        configure::readback(&self.camera, &self.id)
    }

    /// Buffers that arrived incomplete and were dropped (also counted as gaps in frame numbers).
    pub fn incomplete_buffers(&self) -> u64 {
        self.incomplete
    }

    /// The camera's device id.
    pub fn id(&self) -> &str {
        &self.id
    }

    fn disconnected(&self, why: &str) -> DeviceError {
        DeviceError::Disconnected(format!("camera '{}' {why}", self.id))
    }

    /// Copies or demosaics a complete buffer into `frame`.
    fn fill(&self, buffer: &Buffer, frame: &mut Frame) -> Result<(), DeviceError> {
        let (w, h) = (
            buffer.image_width().max(0) as usize,
            buffer.image_height().max(0) as usize,
        );
        let bytes_per_pixel = if self.bayer.is_some() { 1 } else { 3 };
        let all = image_bytes(buffer);
        let Some(data) = all.get(..w * h * bytes_per_pixel) else {
            return Err(DeviceError::Frame(format!(
                "camera '{}' sent {} bytes for a {w}×{h} image",
                self.id,
                all.len()
            )));
        };
        frame.width = w;
        frame.height = h;
        frame.channels = 3;
        match self.bayer {
            Some(pattern) => demosaic_bilinear(data, w, h, pattern, &mut frame.data)
                .map_err(|e| DeviceError::Frame(format!("camera '{}': {e}", self.id)))?,
            None => {
                frame.data.clear();
                frame.data.extend_from_slice(data);
            }
        }
        Ok(())
    }
}

/// The bytes of a filled buffer, without a copy.
#[allow(
    unsafe_code,
    reason = "aravis hands out the buffer's own memory as pointer and length; the slice borrows \
              the Buffer, which owns that memory until it is pushed back to the stream"
)]
fn image_bytes(buffer: &Buffer) -> &[u8] {
    let (ptr, len) = buffer.data();
    if ptr.is_null() {
        return &[];
    }
    // SAFETY: ptr/len describe the buffer's allocation, alive while `buffer` is borrowed.
    unsafe { std::slice::from_raw_parts(ptr, len) }
}

impl Camera for GenicamCamera {
    fn name(&self) -> String {
        let model = self
            .camera
            .model_name()
            .map(|m| m.to_string())
            .unwrap_or_default();
        format!("{} {} {}×{}", model, self.id, self.width, self.height)
    }

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn fps(&self) -> f64 {
        self.fps
    }

    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        loop {
            if self.control_lost.load(Ordering::SeqCst) {
                return Err(self.disconnected("stopped answering (cable unplugged?)"));
            }
            let Some(buffer) = self
                .stream
                .timeout_pop_buffer(POP_TIMEOUT.as_micros() as u64)
            else {
                if self.free_run && self.last_frame_at.elapsed() > STALL_TIMEOUT {
                    // Silence in free run: is the camera still there?
                    if self.camera.frame_rate().is_err() || self.camera.payload().is_err() {
                        return Err(self.disconnected("stopped answering (cable unplugged?)"));
                    }
                    self.last_frame_at = Instant::now();
                }
                return Err(DeviceError::Idle);
            };
            if buffer.status() != BufferStatus::Success {
                let status = buffer.status();
                self.incomplete += 1;
                self.incomplete_streak += 1;
                self.stream.push_buffer(buffer);
                if self.incomplete_streak >= INCOMPLETE_LIMIT {
                    return Err(DeviceError::Link(format!(
                        "camera '{}': {} frames in a row arrived incomplete ({status:?}); the link \
                         cannot carry this stream: lower the frame rate or the region, use a \
                         Bayer format, or (GigE Vision) enable jumbo frames",
                        self.id, self.incomplete_streak
                    )));
                }
                continue;
            }
            self.incomplete_streak = 0;
            let filled = self.fill(&buffer, frame);
            let raw_id = buffer.frame_id();
            let timestamp_ns = match buffer.timestamp() {
                0 => buffer.system_timestamp(),
                t => t,
            };
            self.stream.push_buffer(buffer);
            filled?;
            let k = self.ids.next(raw_id);
            let first = *self.first_timestamp_ns.get_or_insert(timestamp_ns);
            frame.time_s = timestamp_ns.saturating_sub(first) as f64 * 1e-9;
            frame.pattern_index =
                (k as usize + self.settings.pattern_offset) % self.settings.pattern_count.max(1);
            self.last_frame_at = Instant::now();
            return Ok(Grabbed { sequence_number: k });
        }
    }
}

impl Drop for GenicamCamera {
    fn drop(&mut self) {
        // Best effort: an unplugged camera cannot be stopped.
        let _ = self.camera.stop_acquisition();
    }
}
