//! GenICam cameras (USB3 Vision, GigE Vision) through aravis, behind the `genicam` feature.
//!
//! [`list_cameras`] enumerates what aravis sees; [`GenicamCamera::open`] opens one by its id,
//! applies [`GenicamSettings`] (pixel format, exposure, gain, region, frame rate, trigger), hands
//! the stream a pool of [`GenicamSettings::buffer_count`] buffers and starts acquisition. Each
//! grab pops one filled buffer, copies (RGB8) or demosaics (Bayer 8-bit) it into the frame, and
//! gives the buffer back to the pool at once.
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

/// How long a free-running camera may deliver nothing before the grab checks that it is there.
pub const STALL_TIMEOUT: Duration = Duration::from_secs(2);

/// Incomplete frames in a row that mean the link cannot carry the stream.
const INCOMPLETE_LIMIT: u32 = 30;

/// How long one grab waits for a buffer before it returns [`DeviceError::Idle`] (so the capture
/// thread sees stop requests).
const POP_TIMEOUT: Duration = Duration::from_millis(200);

/// Errors of opening and configuring a GenICam camera.
#[derive(Debug, thiserror::Error)]
pub enum GenicamError {
    #[error("no GenICam camera found{}", if .0.is_empty() { String::new() } else { format!(" with id '{}' (found: {})", .0, .1) })]
    NoCamera(String, String),
    #[error("camera '{id}' is in use by another program: {detail}")]
    Busy { id: String, detail: String },
    #[error("the link to '{id}' carries {available_mb_s:.0} MB/s, {needed_mb_s:.0} MB/s are needed for {width}×{height} {format} at {fps:.1} FPS: lower the frame rate or the region, or use a Bayer format")]
    BandwidthTooLow {
        id: String,
        available_mb_s: f64,
        needed_mb_s: f64,
        width: usize,
        height: usize,
        format: String,
        fps: f64,
    },
    #[error("camera '{id}' offers none of RGB8 or Bayer 8-bit (it offers {offered})")]
    NoColourFormat { id: String, offered: String },
    #[error("camera '{id}' has no trigger line '{line}' (it has {})", .offered.join(", "))]
    NoTriggerLine {
        id: String,
        line: String,
        offered: Vec<String>,
    },
    #[error("camera '{id}': cannot set {what}: {detail}")]
    Setting {
        id: String,
        what: &'static str,
        detail: String,
    },
}

impl From<GenicamError> for DeviceError {
    fn from(e: GenicamError) -> Self {
        DeviceError::Open(e.to_string())
    }
}

/// One camera as aravis lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraInfo {
    /// What [`GenicamCamera::open`] takes.
    pub id: String,
    pub vendor: String,
    pub model: String,
    /// "GigEVision", "USB3Vision" or "Fake".
    pub protocol: String,
    pub address: String,
}

/// Pixel format to stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelChoice {
    /// RGB8 if the camera has it, else its 8-bit Bayer format.
    Auto,
    Rgb8,
    Bayer(BayerPattern),
}

/// When the camera exposes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TriggerChoice {
    /// At its own frame rate.
    FreeRun,
    /// On each edge of a hardware line (e.g. "Line1", wired to the projector's trigger out).
    Hardware { line: String },
}

/// Camera settings; `None` leaves the camera's own value.
#[derive(Debug, Clone, PartialEq)]
pub struct GenicamSettings {
    pub pixel: PixelChoice,
    pub exposure_micros: Option<f64>,
    pub gain_db: Option<f64>,
    /// Region of interest: x, y, width, height in sensor pixels.
    pub region: Option<[usize; 4]>,
    pub frame_rate_hz: Option<f64>,
    pub trigger: TriggerChoice,
    /// Buffers in the stream's pool.
    pub buffer_count: usize,
    /// Length of the projected sequence and the pattern the first frame shows.
    pub pattern_count: usize,
    pub pattern_offset: usize,
}

impl Default for GenicamSettings {
    fn default() -> Self {
        Self {
            pixel: PixelChoice::Auto,
            exposure_micros: None,
            gain_db: None,
            region: None,
            frame_rate_hz: None,
            trigger: TriggerChoice::FreeRun,
            buffer_count: 16,
            pattern_count: 3,
            pattern_offset: 0,
        }
    }
}

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

/// Unwraps GigE Vision's 16-bit block ids (1..=65535, 0 unused) into a running count; larger ids
/// (USB3 Vision, GigE Vision 2 extended ids) pass through.
#[derive(Debug, Default, Clone, Copy)]
pub struct FrameIdUnwrapper {
    last_raw: Option<u64>,
    count: u64,
}

impl FrameIdUnwrapper {
    /// Frames since the first one (0 for the first).
    pub fn next(&mut self, raw: u64) -> u64 {
        let Some(last) = self.last_raw.replace(raw) else {
            return 0;
        };
        let step = if raw > last {
            raw - last
        } else if last <= 0xFFFF && raw <= 0xFFFF && last - raw > 0x8000 {
            // Wrapped past 65535 back to 1.
            raw + 0xFFFF - last
        } else {
            // A repeated or reset id: count one frame rather than go back.
            1
        };
        self.count += step;
        self.count
    }
}

/// What the camera reports for the settings it was given (cameras round to their increments).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraReadback {
    pub pixel_format: String,
    pub exposure_micros: f64,
    pub gain_db: f64,
    /// x, y, width, height in sensor pixels.
    pub region: [usize; 4],
    pub frame_rate_hz: f64,
    /// The `TriggerMode` feature ("On" / "Off").
    pub trigger_mode: String,
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

fn setting_error<'a>(
    id: &'a str,
    what: &'static str,
) -> impl Fn(aravis::glib::Error) -> GenicamError + 'a {
    move |e| GenicamError::Setting {
        id: id.to_string(),
        what,
        detail: e.message().to_string(),
    }
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
        let err = |what| setting_error(id, what);
        // Stop whatever a previous program left running before changing settings.
        let _ = camera.stop_acquisition();

        let offered: Vec<String> = camera
            .dup_available_pixel_formats_as_strings()
            .map_err(err("pixel format"))?
            .iter()
            .map(|s| s.to_string())
            .collect();
        let rgb_name = offered
            .iter()
            .find(|f| *f == "RGB8" || *f == "RGB8Packed")
            .cloned();
        let bayer_offered = offered
            .iter()
            .find_map(|f| BayerPattern::from_pixel_format_name(f));
        let (format_name, bayer) = match settings.pixel {
            PixelChoice::Rgb8 => (rgb_name, None),
            PixelChoice::Bayer(p) => (
                offered
                    .iter()
                    .find(|f| *f == p.pixel_format_name())
                    .cloned(),
                Some(p),
            ),
            PixelChoice::Auto => match (rgb_name, bayer_offered) {
                (Some(n), _) => (Some(n), None),
                (None, Some(p)) => (Some(p.pixel_format_name().to_string()), Some(p)),
                (None, None) => (None, None),
            },
        };
        let Some(format_name) = format_name else {
            return Err(GenicamError::NoColourFormat {
                id: id.to_string(),
                offered: offered.join(", "),
            });
        };
        camera
            .set_pixel_format_from_string(&format_name)
            .map_err(err("pixel format"))?;
        if let Some([x, y, w, h]) = settings.region {
            camera
                .set_region(x as i32, y as i32, w as i32, h as i32)
                .map_err(err("region"))?;
        }
        if let Some(us) = settings.exposure_micros {
            camera.set_exposure_time(us).map_err(err("exposure"))?;
        }
        if let Some(db) = settings.gain_db {
            camera.set_gain(db).map_err(err("gain"))?;
        }
        match &settings.trigger {
            TriggerChoice::FreeRun => {
                camera.clear_triggers().map_err(err("trigger off"))?;
                if let Some(fps) = settings.frame_rate_hz {
                    camera.set_frame_rate(fps).map_err(err("frame rate"))?;
                }
            }
            TriggerChoice::Hardware { line } => {
                let offered: Vec<String> = camera
                    .dup_available_trigger_sources()
                    .map_err(err("trigger source"))?
                    .iter()
                    .map(|s| s.to_string())
                    .collect();
                if !offered.contains(line) {
                    return Err(GenicamError::NoTriggerLine {
                        id: id.to_string(),
                        line: line.clone(),
                        offered,
                    });
                }
                camera.set_trigger(line).map_err(err("hardware trigger"))?;
            }
        }
        let (_, _, w, h) = camera.region().map_err(err("region"))?;
        let (width, height) = (w.max(0) as usize, h.max(0) as usize);
        let fps = match (&settings.trigger, settings.frame_rate_hz) {
            (TriggerChoice::Hardware { .. }, Some(f)) => f,
            _ => camera.frame_rate().unwrap_or(0.0),
        };
        Self::check_bandwidth(&camera, id, width, height, &format_name, fps)?;

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

    /// USB3 Vision cameras state their link bandwidth; refuse a stream that cannot fit.
    fn check_bandwidth(
        camera: &aravis::Camera,
        id: &str,
        width: usize,
        height: usize,
        format: &str,
        fps: f64,
    ) -> Result<(), GenicamError> {
        if !camera.is_uv_device() || camera.uv_is_bandwidth_control_available().is_err() {
            return Ok(());
        }
        let Ok((_, max_bytes_s)) = camera.uv_get_bandwidth_bounds() else {
            return Ok(());
        };
        let bytes_per_pixel = if format.starts_with("Bayer") {
            1.0
        } else {
            3.0
        };
        let needed = width as f64 * height as f64 * bytes_per_pixel * fps;
        if needed > f64::from(max_bytes_s) {
            return Err(GenicamError::BandwidthTooLow {
                id: id.to_string(),
                available_mb_s: f64::from(max_bytes_s) / 1e6,
                needed_mb_s: needed / 1e6,
                width,
                height,
                format: format.to_string(),
                fps,
            });
        }
        Ok(())
    }

    /// Reads the settings back from the camera.
    pub fn readback(&self) -> Result<CameraReadback, GenicamError> {
        let err = |what| setting_error(&self.id, what);
        let (x, y, w, h) = self.camera.region().map_err(err("region"))?;
        Ok(CameraReadback {
            pixel_format: self
                .camera
                .pixel_format_as_string()
                .map_err(err("pixel format"))?
                .to_string(),
            exposure_micros: self.camera.exposure_time().map_err(err("exposure"))?,
            gain_db: self.camera.gain().map_err(err("gain"))?,
            region: [x, y, w, h].map(|v| v.max(0) as usize),
            frame_rate_hz: self.camera.frame_rate().map_err(err("frame rate"))?,
            trigger_mode: self
                .camera
                .string("TriggerMode")
                .map_err(err("trigger mode"))?
                .to_string(),
        })
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

#[cfg(test)]
mod tests {
    use super::FrameIdUnwrapper;

    #[test]
    fn gige_block_ids_unwrap_across_65535_and_gaps_survive() {
        let mut u = FrameIdUnwrapper::default();
        let got: Vec<u64> = [65533, 65534, 65535, 1, 2, 5]
            .into_iter()
            .map(|id| u.next(id))
            .collect();
        assert_eq!(got, vec![0, 1, 2, 3, 4, 7]);
        let mut big = FrameIdUnwrapper::default();
        assert_eq!(big.next(1 << 40), 0);
        assert_eq!(big.next((1 << 40) + 3), 3);
    }
}
