//! The DLP LightCrafter 4500 (DLPC350 controller) as the rig's projector.
//!
//! [`protocol`] encodes the USB HID commands, [`timing`] plans the CPS-RGB sequence, and
//! [`LightCrafter`] runs them over any [`HidTransport`]: the USB one ([`usb`], feature
//! `lightcrafter`, through rusb) or a test double. Every write asks for an ACK; a NACK stops the
//! programming with the command's name.
//!
//! [`LightCrafter::program_cps`] puts the controller in pattern mode fed by the video input (no
//! flash writes), VSYNC-triggered, with a 9-entry LUT: for each of the 3 images its red, green and
//! blue 6-bit patterns under the matching LED, the first of them waiting for VSYNC and swapping to
//! the new video frame, the other two continuing and sharing trigger out 1, so the camera sees one
//! exposure pulse per image. It then validates (polling the busy bit) and starts the sequence.

pub mod protocol;
pub mod timing;
#[cfg(feature = "lightcrafter")]
pub mod usb;

use protocol::{
    decode_reply, encode_read, encode_write, Command, Led, LutEntry, PatternTrigger, Validation,
    REPORT_LEN,
};
use std::time::{Duration, Instant};
use timing::CpsTiming;

/// USB ids of the LightCrafter 4500.
pub const VENDOR_ID: u16 = 0x0451;
pub const PRODUCT_ID: u16 = 0x6401;

/// How long validation may stay busy before we give up.
const VALIDATION_TIMEOUT: Duration = Duration::from_secs(5);

/// Errors of the LightCrafter.
#[derive(Debug, thiserror::Error)]
pub enum LightcrafterError {
    #[error("no LightCrafter 4500 (USB 0451:6401) is connected")]
    Absent,
    #[error(
        "no permission to open the LightCrafter 4500: install the udev rules \
         (packaging/udev/60-tremorscan.rules) and plug it in again"
    )]
    Permission,
    #[error("the LightCrafter 4500 was unplugged")]
    Unplugged,
    #[error("USB error talking to the LightCrafter 4500: {0}")]
    Usb(String),
    #[error("the LightCrafter did not answer '{0}' in time")]
    Timeout(&'static str),
    #[error("the LightCrafter refused '{0}' (NACK)")]
    Nack(&'static str),
    #[error("the LightCrafter rejected the pattern sequence: {}", .0.join("; "))]
    ValidationFailed(Vec<&'static str>),
    #[error(transparent)]
    Timing(#[from] timing::TimingError),
}

/// Moves 64-byte HID reports to and from the controller.
pub trait HidTransport: Send {
    fn write_report(&mut self, report: &[u8; REPORT_LEN]) -> Result<(), LightcrafterError>;
    fn read_report(&mut self) -> Result<[u8; REPORT_LEN], LightcrafterError>;
}

/// A LightCrafter 4500 on a transport.
pub struct LightCrafter<T: HidTransport> {
    transport: T,
    sequence: u8,
    /// Images per second that [`Projector::show`](crate::device::Projector::show) programs.
    pub fps: f64,
    /// Warnings of the last validation (bits 2..4), for the status bar.
    pub warnings: Vec<&'static str>,
}

impl<T: HidTransport> LightCrafter<T> {
    pub fn new(transport: T) -> Self {
        Self {
            transport,
            sequence: 0,
            fps: 121.0,
            warnings: Vec::new(),
        }
    }

    /// Gives the transport back (tests inspect it).
    pub fn into_transport(self) -> T {
        self.transport
    }

    /// Writes a command and waits for its ACK.
    pub fn write(&mut self, command: Command, data: &[u8]) -> Result<(), LightcrafterError> {
        let sequence = self.next_sequence();
        for report in encode_write(command, sequence, data) {
            self.transport.write_report(&report)?;
        }
        let reply = decode_reply(&self.transport.read_report()?);
        if reply.nack {
            return Err(LightcrafterError::Nack(command.name));
        }
        Ok(())
    }

    /// Reads a command's current value.
    pub fn read(&mut self, command: Command, params: &[u8]) -> Result<Vec<u8>, LightcrafterError> {
        let sequence = self.next_sequence();
        self.transport
            .write_report(&encode_read(command, sequence, params))?;
        let reply = decode_reply(&self.transport.read_report()?);
        if reply.nack {
            return Err(LightcrafterError::Nack(command.name));
        }
        Ok(reply.data)
    }

    fn next_sequence(&mut self) -> u8 {
        let s = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        s
    }

    /// Stops the pattern sequence.
    pub fn stop(&mut self) -> Result<(), LightcrafterError> {
        self.write(protocol::PATTERN_START_STOP, &[0])
    }

    /// Starts the programmed sequence.
    pub fn start(&mut self) -> Result<(), LightcrafterError> {
        self.write(protocol::PATTERN_START_STOP, &[2])
    }

    /// Asks the controller to validate the programmed sequence and polls until it is done.
    pub fn validate(&mut self) -> Result<Validation, LightcrafterError> {
        self.write(protocol::VALIDATE, &[0])?;
        let started = Instant::now();
        loop {
            let data = self.read(protocol::VALIDATE, &[])?;
            let status = Validation(data.first().copied().unwrap_or(0x80));
            if !status.busy() {
                if !status.is_valid() {
                    return Err(LightcrafterError::ValidationFailed(status.reasons()));
                }
                self.warnings = status.reasons();
                return Ok(status);
            }
            if started.elapsed() > VALIDATION_TIMEOUT {
                return Err(LightcrafterError::Timeout(protocol::VALIDATE.name));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Programs and starts the CPS-RGB sequence (3 images × R, G, B) at `timing`.
    pub fn program_cps(&mut self, timing: &CpsTiming) -> Result<(), LightcrafterError> {
        let lut = cps_lut(timing.bit_depth);
        self.stop()?;
        self.write(protocol::DISPLAY_MODE, &[1])?; // pattern display mode
        self.write(protocol::PATTERN_SOURCE, &[0])?; // video port
        self.write(protocol::PATTERN_TRIGGER_MODE, &[0])?; // VSYNC triggers
        let mut exposure_period = [0u8; 8];
        exposure_period[..4].copy_from_slice(&timing.pattern_exposure_micros.to_le_bytes());
        exposure_period[4..].copy_from_slice(&timing.pattern_period_micros.to_le_bytes());
        self.write(protocol::EXPOSURE_PERIOD, &exposure_period)?;
        // Trigger out 1: active high, rising and falling edges with no delay (0xBB).
        self.write(protocol::TRIGGER_OUT1, &[0, 0xBB, 0xBB])?;
        self.write(protocol::MAILBOX_CONTROL, &[2])?; // open the pattern LUT
        self.write(protocol::MAILBOX_ADDRESS, &[0])?;
        let bytes: Vec<u8> = lut.iter().flat_map(LutEntry::bytes).collect();
        self.write(protocol::MAILBOX_DATA, &bytes)?;
        self.write(protocol::MAILBOX_CONTROL, &[0])?; // close it
        let entries = lut.len() as u8;
        // LUT entries − 1, repeat, patterns per TRIG_OUT_2 − 1, images − 1 (unused: video).
        self.write(protocol::PATTERN_CONFIG, &[entries - 1, 1, entries - 1, 0])?;
        self.validate()?;
        self.start()
    }
}

/// The 9-entry LUT of CPS-RGB: image i's red, green and blue patterns (numbers 0, 1, 2 of the
/// video frame, see [`timing::pack_video_pixel`]).
pub fn cps_lut(bit_depth: u8) -> Vec<LutEntry> {
    let channels = [(0, Led::Red), (1, Led::Green), (2, Led::Blue)];
    (0..3)
        .flat_map(|_image| channels)
        .map(|(pattern, led)| {
            let first = pattern == 0;
            LutEntry {
                trigger: if first {
                    PatternTrigger::ExternalPositive
                } else {
                    PatternTrigger::Continue
                },
                pattern,
                bit_depth,
                led,
                invert: false,
                insert_black: false,
                buffer_swap: first,
                trigger_out_previous: !first,
            }
        })
        .collect()
}

impl<T: HidTransport> crate::device::Projector for LightCrafter<T> {
    fn name(&self) -> String {
        "DLP LightCrafter 4500".to_string()
    }

    fn show(
        &mut self,
        sequence: &crate::pattern::PatternSequence,
    ) -> Result<(), crate::device::DeviceError> {
        let rgb = sequence
            .entries
            .iter()
            .all(|e| matches!(e, crate::pattern::PatternEntry::Rgb { .. }));
        if sequence.entries.len() != 3 || !rgb {
            return Err(crate::device::DeviceError::Sequence(format!(
                "the LightCrafter runs CPS-RGB (3 RGB images), this sequence has {} {} images",
                sequence.entries.len(),
                if rgb { "RGB" } else { "gray" }
            )));
        }
        // The deepest quantisation that fits the rate: 6 bits at 121 FPS.
        let depth = timing::deepest_bit_depth(self.fps).unwrap_or(1);
        let timing = CpsTiming::new(self.fps, depth).map_err(LightcrafterError::from)?;
        self.program_cps(&timing)
            .map_err(|e| crate::device::DeviceError::Sequence(e.to_string()))
    }
}

impl From<LightcrafterError> for crate::device::DeviceError {
    fn from(e: LightcrafterError) -> Self {
        match e {
            LightcrafterError::Unplugged => Self::Disconnected(e.to_string()),
            other => Self::Open(other.to_string()),
        }
    }
}
