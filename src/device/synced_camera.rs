//! A camera whose frames are labelled with the second-screen pattern they saw (see
//! [`screen_sync`](super::screen_sync) for the model). Two ways to label:
//!
//! * [`SyncMode::FreeRunning`]: the camera runs on its own clock. A frame gets the pattern its
//!   whole exposure (widened by the guard) fell in; a frame that straddles a change is dropped.
//! * [`SyncMode::Triggered`]: the projector triggers the camera (the LightCrafter's trigger out),
//!   so frame `k` shows pattern `(k + offset) mod L` and no frame straddles. The schedule only
//!   finds the offset: it locks after 5 frames agree, checks every later frame whose middle the
//!   schedule places clearly inside a pattern, and after 3 disagreements in a row (the screen
//!   missed a refresh and showed a pattern twice) drops frames until it locks again.
//!
//! A dropped frame is counted in [`SyncStats`] and its grab returns [`DeviceError::Idle`] (no
//! frame this time); delivered frames are renumbered around the dropped ones, so gaps in the
//! numbers still mean frames the camera itself lost.

use super::screen_sync::{host_time_s, DelayEstimate, PatternSchedule, Seen};
use super::{Camera, DeviceError, Grabbed};
use crate::frame::Frame;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// How frames are labelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyncMode {
    FreeRunning,
    Triggered { pattern_count: usize },
}

/// Agreeing frames before a triggered camera locks its offset.
const LOCK_AFTER: u32 = 5;
/// Disagreeing frames in a row before it unlocks.
const UNLOCK_AFTER: u32 = 3;

/// Counters of a synced camera, shared with the status bar.
#[derive(Debug, Default)]
pub struct SyncStats {
    pub delivered: AtomicU64,
    pub uncertain: AtomicU64,
    /// Triggered mode: whether the pattern phase is locked now.
    pub locked: AtomicBool,
}

/// Labels a camera's frames with the screen's patterns; drops the uncertain ones.
pub struct SyncedCamera<C: Camera> {
    inner: C,
    schedule: Arc<Mutex<PatternSchedule>>,
    pub mode: SyncMode,
    pub delay_s: f64,
    pub exposure_s: f64,
    /// Jitter allowance plus the delay's uncertainty, s.
    pub guard_s: f64,
    stats: Arc<SyncStats>,
    clock: Box<dyn Fn() -> f64 + Send>,
    /// Triggered mode: the locked offset, and agreement/disagreement streaks.
    offset: Option<usize>,
    candidate: Option<(usize, u32)>,
    disagreements: u32,
}

impl<C: Camera> SyncedCamera<C> {
    /// `guard_s` covers timing jitter; the delay's own uncertainty is added to it.
    pub fn new(
        inner: C,
        schedule: Arc<Mutex<PatternSchedule>>,
        mode: SyncMode,
        delay: DelayEstimate,
        exposure_s: f64,
        guard_s: f64,
    ) -> Self {
        Self {
            inner,
            schedule,
            mode,
            delay_s: delay.delay_s,
            exposure_s,
            guard_s: guard_s + delay.uncertainty_s,
            stats: Arc::default(),
            clock: Box::new(host_time_s),
            offset: None,
            candidate: None,
            disagreements: 0,
        }
    }

    /// Replaces the host clock (simulations).
    pub fn with_clock(mut self, clock: impl Fn() -> f64 + Send + 'static) -> Self {
        self.clock = Box::new(clock);
        self
    }

    pub fn stats(&self) -> Arc<SyncStats> {
        Arc::clone(&self.stats)
    }

    /// Whether a triggered camera has its offset (always true when free-running).
    pub fn is_locked(&self) -> bool {
        self.mode == SyncMode::FreeRunning || self.offset.is_some()
    }

    /// The label of frame `k` whose exposure ends at schedule time `end_s`, if certain.
    fn label(&mut self, k: u64, end_s: f64) -> Option<usize> {
        let schedule = self.schedule.lock().unwrap_or_else(|p| p.into_inner());
        match self.mode {
            SyncMode::FreeRunning => {
                match schedule.seen_during(end_s - self.exposure_s, end_s, self.guard_s) {
                    Seen::Pattern(p) if p != usize::MAX => Some(p),
                    _ => None,
                }
            }
            SyncMode::Triggered { pattern_count } => {
                let count = pattern_count.max(1);
                let middle = end_s - self.exposure_s / 2.0;
                let seen = match schedule.seen_during(middle, middle, self.guard_s) {
                    Seen::Pattern(p) if p < count => Some(p),
                    _ => None,
                };
                drop(schedule);
                let k = (k % count as u64) as usize;
                match (self.offset, seen) {
                    (Some(offset), Some(p)) if (k + offset) % count != p => {
                        self.disagreements += 1;
                        if self.disagreements >= UNLOCK_AFTER {
                            self.offset = None;
                            self.candidate = None;
                        }
                        None
                    }
                    (Some(offset), _) => {
                        if seen.is_some() {
                            self.disagreements = 0;
                        }
                        Some((k + offset) % count)
                    }
                    (None, Some(p)) => {
                        let offset = (p + count - k) % count;
                        let streak = match self.candidate {
                            Some((c, n)) if c == offset => n + 1,
                            _ => 1,
                        };
                        self.candidate = Some((offset, streak));
                        if streak >= LOCK_AFTER {
                            self.offset = Some(offset);
                            self.disagreements = 0;
                            return Some(p);
                        }
                        None
                    }
                    (None, None) => None,
                }
            }
        }
    }
}

impl<C: Camera> Camera for SyncedCamera<C> {
    fn name(&self) -> String {
        format!("{} + second screen", self.inner.name())
    }

    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    fn fps(&self) -> f64 {
        self.inner.fps()
    }

    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        let grabbed = self.inner.grab(frame)?;
        let end_s = (self.clock)() - self.delay_s;
        let label = self.label(grabbed.sequence_number, end_s);
        self.stats
            .locked
            .store(self.offset.is_some(), Ordering::Relaxed);
        match label {
            Some(pattern) => {
                frame.pattern_index = pattern;
                self.stats.delivered.fetch_add(1, Ordering::Relaxed);
                let uncertain = self.stats.uncertain.load(Ordering::Relaxed);
                Ok(Grabbed {
                    sequence_number: grabbed.sequence_number.saturating_sub(uncertain),
                })
            }
            None => {
                // Dropped, and no frame this time: the capture thread asks again (and sees a
                // stop request even when every frame is uncertain).
                self.stats.uncertain.fetch_add(1, Ordering::Relaxed);
                Err(DeviceError::Idle)
            }
        }
    }
}
