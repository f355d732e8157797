//! The GenICam camera's public types: errors, the settings it takes, what discovery lists, what it
//! reads back, and the unwrapping of GigE Vision's 16-bit frame ids.

use crate::device::bayer::BayerPattern;
use crate::device::DeviceError;

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
    #[error("camera '{id}' cannot bin its pixels {binning}×{binning}: {detail}")]
    NoBinning {
        id: String,
        binning: u32,
        detail: String,
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
    /// Binning, the same factor across and down (2: each frame pixel sums 2×2 sensor pixels,
    /// a quarter of the pixels to decode); set before the region, whose pixels are then binned
    /// ones. A camera that cannot bin by that factor is refused.
    pub binning: Option<u32>,
    /// Region of interest: x, y, width, height in sensor pixels (binned pixels with `binning`).
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
            binning: None,
            region: None,
            frame_rate_hz: None,
            trigger: TriggerChoice::FreeRun,
            buffer_count: 16,
            pattern_count: 3,
            pattern_offset: 0,
        }
    }
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
    /// Binning across and down; `None` where the camera has none.
    pub binning: Option<(u32, u32)>,
    pub frame_rate_hz: f64,
    /// The `TriggerMode` feature ("On" / "Off").
    pub trigger_mode: String,
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
