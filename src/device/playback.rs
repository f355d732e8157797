//! A saved session as a camera that a user drives: play, pause, step one frame, seek, and a
//! speed factor. The GUI holds a [`PlaybackControl`] (shared with the camera on the capture
//! thread) and changes it; [`PlaybackCamera::grab`] reads it before every frame.
//!
//! - Playing, frames come at their recorded spacing divided by the speed.
//! - Paused, a grab waits on the control's condition variable for at most
//!   [`IDLE_WAIT`] and returns [`DeviceError::Idle`], so the capture thread keeps seeing stop
//!   requests.
//! - A seek moves the next frame; the decoder's window check (time span of its frames) makes the
//!   window across the jump unsolvable instead of mixing two moments.
//! - At the last frame playback pauses (it does not end the stream), so the user can seek back.
//! - Sequence numbers count delivered frames, so seeks are not reported as lost frames.

use super::{Camera, DeviceError, Grabbed};
use crate::frame::Frame;
use crate::session::Session;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// Longest a paused grab waits before returning [`DeviceError::Idle`].
pub const IDLE_WAIT: Duration = Duration::from_millis(50);

/// What the user asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaybackState {
    pub playing: bool,
    /// Index of the next frame to deliver.
    pub next_frame: usize,
    /// Frames still to deliver while paused (step requests).
    pub steps: usize,
    /// Playback speed relative to the recording, > 0.
    pub speed: f64,
    /// Index of the last frame delivered, if any.
    pub shown_frame: Option<usize>,
}

/// The shared control of a [`PlaybackCamera`].
#[derive(Debug)]
pub struct PlaybackControl {
    state: Mutex<PlaybackState>,
    changed: Condvar,
    frame_count: usize,
}

impl PlaybackControl {
    fn lock(&self) -> MutexGuard<'_, PlaybackState> {
        // The state is a few numbers, consistent after any panic elsewhere.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn change(&self, f: impl FnOnce(&mut PlaybackState)) {
        f(&mut self.lock());
        self.changed.notify_all();
    }

    pub fn state(&self) -> PlaybackState {
        *self.lock()
    }

    pub fn frame_count(&self) -> usize {
        self.frame_count
    }

    pub fn play(&self) {
        self.change(|s| {
            if s.next_frame >= self.frame_count {
                s.next_frame = 0;
            }
            s.steps = 0;
            s.playing = true;
        });
    }

    pub fn pause(&self) {
        self.change(|s| s.playing = false);
    }

    /// Pauses and delivers one more frame.
    pub fn step(&self) {
        self.change(|s| {
            s.playing = false;
            s.steps += 1;
        });
    }

    /// Moves the next frame to `frame` (clamped to the session).
    pub fn seek(&self, frame: usize) {
        self.change(|s| {
            s.next_frame = frame.min(self.frame_count.saturating_sub(1));
            s.steps = 0;
        });
    }

    /// Sets the speed factor; non-positive or non-finite values are ignored.
    pub fn set_speed(&self, speed: f64) {
        if speed.is_finite() && speed > 0.0 {
            self.change(|s| s.speed = speed);
        }
    }
}

pub struct PlaybackCamera {
    session: Session,
    control: std::sync::Arc<PlaybackControl>,
    delivered: u64,
    /// When the previous frame was delivered and its recorded time.
    last: Option<(Instant, f64)>,
}

impl PlaybackCamera {
    /// A camera over `session`, paused at its first frame; the returned control drives it.
    pub fn new(session: Session) -> (Self, std::sync::Arc<PlaybackControl>) {
        let control = std::sync::Arc::new(PlaybackControl {
            state: Mutex::new(PlaybackState {
                playing: false,
                next_frame: 0,
                steps: 0,
                speed: 1.0,
                shown_frame: None,
            }),
            changed: Condvar::new(),
            frame_count: session.frame_count(),
        });
        let camera = Self {
            session,
            control: std::sync::Arc::clone(&control),
            delivered: 0,
            last: None,
        };
        (camera, control)
    }

    fn recorded_time_s(&self, index: usize) -> f64 {
        self.session
            .manifest
            .frames
            .get(index)
            .map_or(index as f64 / 121.0, |f| f.time_s)
    }
}

impl Camera for PlaybackCamera {
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
        let count = self.control.frame_count;
        let index = {
            let mut s = self.control.lock();
            let ready = |s: &PlaybackState| (s.playing || s.steps > 0) && s.next_frame < count;
            if !ready(&s) {
                if s.playing && s.next_frame >= count {
                    s.playing = false;
                }
                s = self
                    .control
                    .changed
                    .wait_timeout(s, IDLE_WAIT)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
                if !ready(&s) {
                    return Err(DeviceError::Idle);
                }
            }
            let index = s.next_frame;
            if !s.playing {
                s.steps -= 1;
                // Stepping has no pacing: the frame is wanted now.
                self.last = None;
            }
            s.next_frame += 1;
            (index, s.playing, s.speed)
        };
        let (index, playing, speed) = index;
        let time_s = self.recorded_time_s(index);
        if playing {
            if let Some((at, previous_s)) = self.last {
                let gap_s = (time_s - previous_s).clamp(0.0, 1.0) / speed;
                let due = at + Duration::from_secs_f64(gap_s);
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
        }
        *frame = self
            .session
            .load_frame(index)
            .map_err(|e| DeviceError::Frame(e.to_string()))?;
        self.last = Some((Instant::now(), time_s));
        self.control.change(|s| s.shown_frame = Some(index));
        let grabbed = Grabbed {
            sequence_number: self.delivered,
        };
        self.delivered += 1;
        Ok(grabbed)
    }
}
