//! The virtual rig as a camera (and its projector): frame `i` shows pattern `i mod L` at
//! simulated time `i / fps`. Paced at the nominal rate it never runs ahead of real time; it runs
//! behind when rendering is slower than the rate (the rig renders about 31 frames/s at 640×400 on
//! two cores), and the time stamps stay the simulated ones.

use super::{Camera, DeviceError, Grabbed, Pacing, Projector};
use crate::frame::Frame;
use crate::pattern::PatternSequence;
use crate::rig::VirtualRig;
use std::time::{Duration, Instant};

pub struct VirtualCamera {
    rig: VirtualRig,
    next: u64,
    pacing: Pacing,
    started: Option<Instant>,
    /// Stop after this many frames (None: endless).
    limit: Option<u64>,
}

impl VirtualCamera {
    pub fn new(rig: VirtualRig, pacing: Pacing) -> Self {
        Self {
            rig,
            next: 0,
            pacing,
            started: None,
            limit: None,
        }
    }

    /// Ends the stream after `frames` frames.
    pub fn with_limit(mut self, frames: u64) -> Self {
        self.limit = Some(frames);
        self
    }

    pub fn rig(&self) -> &VirtualRig {
        &self.rig
    }
}

impl Camera for VirtualCamera {
    fn name(&self) -> String {
        format!("virtual rig {}×{}", self.rig.width(), self.rig.height())
    }

    fn size(&self) -> (usize, usize) {
        (self.rig.width(), self.rig.height())
    }

    fn fps(&self) -> f64 {
        self.rig.config.fps
    }

    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        if self.limit.is_some_and(|l| self.next >= l) {
            return Err(DeviceError::EndOfStream { frames: self.next });
        }
        let started = *self.started.get_or_insert_with(Instant::now);
        if self.pacing == Pacing::Recorded {
            let due = started + Duration::from_secs_f64(self.rig.frame_time_s(self.next));
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        if frame.width != self.rig.width()
            || frame.height != self.rig.height()
            || frame.channels != 3
        {
            *frame = self.rig.blank_frame();
        }
        self.rig
            .render(self.next, frame, None)
            .map_err(|e| DeviceError::Frame(e.to_string()))?;
        let grabbed = Grabbed {
            sequence_number: self.next,
        };
        self.next += 1;
        Ok(grabbed)
    }
}

/// The virtual rig's projector: it projects whatever sequence the rig was built with.
pub struct VirtualProjector {
    pub sequence: PatternSequence,
}

impl Projector for VirtualProjector {
    fn name(&self) -> String {
        "virtual projector 912×1140".to_string()
    }

    fn show(&mut self, sequence: &PatternSequence) -> Result<(), DeviceError> {
        if *sequence != self.sequence {
            return Err(DeviceError::Sequence(
                "the virtual rig projects the sequence it was built with".to_string(),
            ));
        }
        Ok(())
    }
}
