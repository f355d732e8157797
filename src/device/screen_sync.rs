//! Software synchronisation of a camera with a second screen used as the projector.
//!
//! A screen has no trigger output, so which pattern a camera frame saw is inferred from time:
//!
//! * The screen side records, for every pattern it puts on screen, the host time it handed the
//!   frame to the display ([`PatternSchedule::push`]). A pattern stays until the next one.
//! * A camera frame arrives at host time `t_a`. Its exposure, in the schedule's time, is
//!   `[t_a − D − e, t_a − D]`: `e` the exposure and `D` one constant delay that lumps the display's
//!   latency (frame handed over → light) and the camera's (exposure end → frame on the host).
//! * `D` is measured, not guessed ([`estimate_delay`]): the screen flashes a pseudo-random
//!   black/white code ([`flash_code`]) while the camera watches, and `D` is the delay at which the
//!   brightness the schedule predicts for each frame correlates best with what the camera saw.
//! * A frame whose exposure (widened by a guard for jitter) lies inside one pattern's time gets
//!   that pattern; one that straddles a change is uncertain and dropped
//!   ([`SyncedCamera`](super::synced_camera::SyncedCamera)), and counted. The rate of frames kept
//!   is the rate achieved, which the status bar states.

use std::collections::VecDeque;
use std::sync::OnceLock;
use std::time::Instant;

/// Seconds since the first call in this process: the clock both sides of the sync share.
pub fn host_time_s() -> f64 {
    static EPOCH: OnceLock<Instant> = OnceLock::new();
    EPOCH.get_or_init(Instant::now).elapsed().as_secs_f64()
}

/// Errors of screen synchronisation.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SyncError {
    #[error("only {usable} camera frames overlap the flash code; {needed} are needed")]
    TooFewFrames { usable: usize, needed: usize },
    #[error(
        "the camera does not see the projector screen (best match {correlation:.2} at \
         {delay_ms:.1} ms; 0.80 is needed): check that the screen lights the scene and the \
         camera looks at it"
    )]
    NotSeen { correlation: f64, delay_ms: f64 },
}

/// One pattern put on screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown {
    /// Index in the pattern sequence; `usize::MAX` for flash-code frames.
    pub pattern_index: usize,
    /// Mean brightness of what was shown, 0..1 (used to measure the delay).
    pub level: f64,
    /// Host time it was handed to the display, s.
    pub from_s: f64,
}

/// What a camera exposure saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    /// One pattern the whole time (with the guard).
    Pattern(usize),
    /// A change of pattern during the exposure (or within the guard of it).
    Straddles,
    /// Before the first or beyond the last recorded pattern.
    Unknown,
}

/// The recent history of what the screen showed.
#[derive(Debug, Clone, Default)]
pub struct PatternSchedule {
    entries: VecDeque<Shown>,
}

/// History kept, s: far more than any display and camera delay.
const KEEP_S: f64 = 3.0;

impl PatternSchedule {
    pub fn push(&mut self, shown: Shown) {
        self.entries.push_back(shown);
        while self
            .entries
            .front()
            .is_some_and(|e| e.from_s < shown.from_s - KEEP_S)
        {
            self.entries.pop_front();
        }
    }

    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// What was shown, oldest first.
    pub fn entries(&self) -> impl Iterator<Item = &Shown> {
        self.entries.iter()
    }

    /// The entries with their end times (the last one lasts until `f64::INFINITY`).
    fn spans(&self) -> impl Iterator<Item = (Shown, f64)> + '_ {
        self.entries.iter().enumerate().map(|(i, e)| {
            let until = self.entries.get(i + 1).map_or(f64::INFINITY, |n| n.from_s);
            (*e, until)
        })
    }

    /// The pattern shown during `[start_s, end_s]`, widened by `guard_s` each side.
    pub fn seen_during(&self, start_s: f64, end_s: f64, guard_s: f64) -> Seen {
        let (lo, hi) = (start_s - guard_s, end_s + guard_s);
        match self.entries.front() {
            Some(first) if first.from_s <= lo => {}
            _ => return Seen::Unknown,
        }
        for (shown, until) in self.spans() {
            if shown.from_s <= lo && hi <= until {
                return Seen::Pattern(shown.pattern_index);
            }
            if shown.from_s > lo {
                break;
            }
        }
        Seen::Straddles
    }

    /// Time-weighted mean level during `[start_s, end_s]` (None outside the history).
    pub fn level_during(&self, start_s: f64, end_s: f64) -> Option<f64> {
        if self.entries.front().is_none_or(|f| f.from_s > start_s) || end_s <= start_s {
            return None;
        }
        let mut sum = 0.0;
        for (shown, until) in self.spans() {
            let overlap = until.min(end_s) - shown.from_s.max(start_s);
            if overlap > 0.0 {
                sum += overlap * shown.level;
            }
        }
        Some(sum / (end_s - start_s))
    }
}

/// A pseudo-random black (false) / white (true) code of `len` elements, without long runs or a
/// period, so that its correlation with a delayed copy peaks at one delay only.
pub fn flash_code(len: usize) -> Vec<bool> {
    // 16-bit maximal-length LFSR (taps 16, 14, 13, 11).
    let mut state: u16 = 0xACE1;
    (0..len)
        .map(|_| {
            let bit = (state ^ (state >> 2) ^ (state >> 3) ^ (state >> 5)) & 1;
            state = (state >> 1) | (bit << 15);
            bit == 1
        })
        .collect()
}

/// The measured delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayEstimate {
    /// The middle of the delays that explain the camera best, s.
    pub delay_s: f64,
    /// Half the width of that range, s. When the camera's and the screen's rates are commensurate
    /// (90 FPS on a 60 Hz screen) exposures meet pattern changes at a few phases only, and every
    /// delay between those phases fits equally well; the guard must cover this.
    pub uncertainty_s: f64,
    /// Correlation of predicted and seen brightness at that delay, −1..1.
    pub correlation: f64,
}

/// Frames needed for a delay estimate.
const MIN_FRAMES: usize = 20;

/// Finds the delay `D` in `0..=max_delay_s` (0.25 ms steps) at which the brightness `schedule`
/// predicts for each camera frame `(arrival_s, brightness)` with exposure `exposure_s` correlates
/// best with the brightness seen.
pub fn estimate_delay(
    schedule: &PatternSchedule,
    frames: &[(f64, f64)],
    exposure_s: f64,
    max_delay_s: f64,
) -> Result<DelayEstimate, SyncError> {
    const STEP_S: f64 = 0.25e-3;
    let steps = (max_delay_s / STEP_S).round() as usize;
    let mut most_usable = 0;
    // Correlation at each step (None: too few frames overlap the schedule there).
    let scores: Vec<Option<f64>> = (0..=steps)
        .map(|step| {
            let delay_s = step as f64 * STEP_S;
            let pairs: Vec<(f64, f64)> = frames
                .iter()
                .filter_map(|&(arrival, seen)| {
                    let end = arrival - delay_s;
                    schedule
                        .level_during(end - exposure_s, end)
                        .map(|predicted| (predicted, seen))
                })
                .collect();
            most_usable = most_usable.max(pairs.len());
            (pairs.len() >= MIN_FRAMES).then(|| pearson(&pairs))
        })
        .collect();
    let Some((best_step, best)) = scores
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.map(|s| (i, s)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
    else {
        return Err(SyncError::TooFewFrames {
            usable: most_usable,
            needed: MIN_FRAMES,
        });
    };
    if best < 0.8 {
        return Err(SyncError::NotSeen {
            correlation: best,
            delay_ms: best_step as f64 * STEP_S * 1e3,
        });
    }
    // The plateau: neighbouring delays whose predictions are the same for every frame score the
    // same (up to rounding).
    let same = |i: usize| scores[i].is_some_and(|s| (s - best).abs() <= 1e-9);
    let mut lo = best_step;
    while lo > 0 && same(lo - 1) {
        lo -= 1;
    }
    let mut hi = best_step;
    while hi < steps && same(hi + 1) {
        hi += 1;
    }
    Ok(DelayEstimate {
        delay_s: (lo + hi) as f64 / 2.0 * STEP_S,
        uncertainty_s: (hi - lo) as f64 / 2.0 * STEP_S,
        correlation: best,
    })
}

fn pearson(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    let (mx, my) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        return 0.0;
    }
    sxy / (sxx * syy).sqrt()
}
