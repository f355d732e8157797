//! A saved session as a camera: its frames in order, at their recorded times or as fast as they
//! load, then [`DeviceError::EndOfStream`].

use super::{Camera, DeviceError, Grabbed, Pacing};
use crate::frame::Frame;
use crate::session::Session;
use std::time::{Duration, Instant};

pub struct ReplayCamera {
    session: Session,
    next: usize,
    pacing: Pacing,
    started: Option<Instant>,
}

impl ReplayCamera {
    pub fn new(session: Session, pacing: Pacing) -> Self {
        Self {
            session,
            next: 0,
            pacing,
            started: None,
        }
    }

    pub fn session(&self) -> &Session {
        &self.session
    }
}

impl Camera for ReplayCamera {
    fn name(&self) -> String {
        format!("replay of {}", self.session.dir.display())
    }

    fn size(&self) -> (usize, usize) {
        self.session.camera_size()
    }

    fn fps(&self) -> f64 {
        self.session.frame_rate_hz()
    }

    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        let count = self.session.frame_count();
        if self.next >= count {
            return Err(DeviceError::EndOfStream {
                frames: count as u64,
            });
        }
        let started = *self.started.get_or_insert_with(Instant::now);
        if self.pacing == Pacing::Recorded {
            let first = self.session.manifest.frames[0].time_s;
            let offset = (self.session.manifest.frames[self.next].time_s - first).max(0.0);
            let due = started + Duration::from_secs_f64(offset);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        *frame = self
            .session
            .load_frame(self.next)
            .map_err(|e| DeviceError::Frame(e.to_string()))?;
        let grabbed = Grabbed {
            sequence_number: self.next as u64,
        };
        self.next += 1;
        Ok(grabbed)
    }
}
