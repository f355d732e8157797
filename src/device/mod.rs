//! The device layer: a [`Camera`] delivers frames, a [`Projector`] shows the pattern sequence.
//! The virtual rig is the default implementation of both ([`virtual_rig`]); a saved session
//! replays as a camera ([`replay`]). Real devices (GenICam cameras, the LightCrafter 4500, a
//! second screen) implement the same traits behind cargo features.
//!
//! Devices are driven from one thread each (`Send`), never shared.

pub mod bayer;
#[cfg(feature = "genicam")]
pub mod genicam;
pub mod lightcrafter;
pub mod playback;
pub mod replay;
pub mod screen_sync;
pub mod synced_camera;
pub mod virtual_rig;

pub use playback::{PlaybackCamera, PlaybackControl, PlaybackState};
pub use replay::ReplayCamera;
pub use virtual_rig::VirtualCamera;

use crate::frame::Frame;
use crate::pattern::PatternSequence;

/// Errors of devices.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// A finite source (a replayed session) has delivered its last frame.
    #[error("end of stream after {frames} frames")]
    EndOfStream { frames: u64 },
    /// A device could not be found, opened or configured.
    #[error("{0}")]
    Open(String),
    /// The camera is there but its link cannot carry the stream.
    #[error("{0}")]
    Link(String),
    #[error("the camera is gone: {0}")]
    Disconnected(String),
    #[error("{0}")]
    Frame(String),
    #[error("the projector cannot show this sequence: {0}")]
    Sequence(String),
    /// No frame right now (a paused replay); the caller asks again. Grabs return it within a
    /// fraction of a second so the capture thread can notice a stop request.
    #[error("the source is paused")]
    Idle,
}

/// How a finite source paces its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// At the recorded (or nominal) frame rate, sleeping between frames.
    Recorded,
    /// As fast as frames can be produced.
    AsFastAsPossible,
}

/// What a grab delivered besides the pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grabbed {
    /// Running number of the frame at the source; a gap means the source lost frames.
    pub sequence_number: u64,
}

/// A source of camera frames.
pub trait Camera: Send {
    /// Human-readable name for the status bar.
    fn name(&self) -> String;
    /// Image size, pixels.
    fn size(&self) -> (usize, usize);
    /// Nominal frame rate, frames per second.
    fn fps(&self) -> f64;
    /// Waits for the next frame and writes it into `frame` (resized as needed), with its time
    /// stamp and pattern index.
    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError>;
}

/// A boxed camera is a camera (so wrappers such as
/// [`SyncedCamera`](synced_camera::SyncedCamera) take any device).
impl<C: Camera + ?Sized> Camera for Box<C> {
    fn name(&self) -> String {
        (**self).name()
    }

    fn size(&self) -> (usize, usize) {
        (**self).size()
    }

    fn fps(&self) -> f64 {
        (**self).fps()
    }

    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        (**self).grab(frame)
    }
}

/// A projector showing a cyclic pattern sequence.
pub trait Projector: Send {
    fn name(&self) -> String;
    /// Programs the sequence (and starts it cycling).
    fn show(&mut self, sequence: &PatternSequence) -> Result<(), DeviceError>;
}
