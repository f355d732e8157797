//! Pipeline metrics: frame rates over the last second, end-to-end latency (capture to published
//! cloud) over the last 512 results, and what each stage dropped. Stages update a shared
//! [`Metrics`]; the GUI and the CLI read [`MetricsSnapshot`]s.

use std::collections::VecDeque;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

const LATENCY_WINDOW: usize = 512;
const RATE_WINDOW: Duration = Duration::from_secs(1);

#[derive(Default)]
struct State {
    captured: u64,
    capture_times: VecDeque<Instant>,
    source_lost: u64,
    decoded: u64,
    decode_times: VecDeque<Instant>,
    unsolvable_windows: u64,
    refused_windows: u64,
    decode_dropped: u64,
    latencies_ms: VecDeque<f64>,
    recorded: u64,
    recorder_lost: u64,
    display_overwritten: u64,
}

/// Shared, updated by the stages.
#[derive(Default)]
pub struct Metrics {
    state: Mutex<State>,
}

/// A copy of the metrics at one moment.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MetricsSnapshot {
    pub captured: u64,
    pub capture_fps: f64,
    /// Frames the source itself lost (gaps in its frame numbers).
    pub source_lost: u64,
    /// Windows decoded and triangulated.
    pub decoded: u64,
    pub decode_fps: f64,
    /// Windows not decoded because a frame was missing from them.
    pub unsolvable_windows: u64,
    /// Windows decoded but refused whole: a frame broke the phase relation on most of their
    /// lit pixels, or of a band of their rows' (`decode::broken`); their clouds are empty.
    pub refused_windows: u64,
    /// Frames the real-time decode stage dropped (it keeps the newest).
    pub decode_dropped: u64,
    pub latency_ms_median: f64,
    pub latency_ms_p99: f64,
    pub recorded: u64,
    /// Frames captured while recording that the recorder could not take (the recording stopped).
    pub recorder_lost: u64,
    /// Results replaced in the display slot before the display took them.
    pub display_overwritten: u64,
}

fn rate(times: &VecDeque<Instant>) -> f64 {
    match (times.front(), times.back()) {
        (Some(a), Some(b)) if times.len() > 1 && b > a => {
            (times.len() - 1) as f64 / (*b - *a).as_secs_f64()
        }
        _ => 0.0,
    }
}

fn push_time(times: &mut VecDeque<Instant>, now: Instant) {
    times.push_back(now);
    while times.front().is_some_and(|&t| now - t > RATE_WINDOW) {
        times.pop_front();
    }
}

impl Metrics {
    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(PoisonError::into_inner))
    }

    pub fn frame_captured(&self, now: Instant, lost_before: u64) {
        self.with(|s| {
            s.captured += 1;
            s.source_lost += lost_before;
            push_time(&mut s.capture_times, now);
        });
    }

    pub fn window_decoded(&self, now: Instant, latency: Duration) {
        self.with(|s| {
            s.decoded += 1;
            push_time(&mut s.decode_times, now);
            s.latencies_ms.push_back(latency.as_secs_f64() * 1e3);
            if s.latencies_ms.len() > LATENCY_WINDOW {
                s.latencies_ms.pop_front();
            }
        });
    }

    pub fn window_unsolvable(&self) {
        self.with(|s| s.unsolvable_windows += 1);
    }

    pub fn window_refused(&self) {
        self.with(|s| s.refused_windows += 1);
    }

    pub fn set_decode_dropped(&self, dropped: u64) {
        self.with(|s| s.decode_dropped = dropped);
    }

    pub fn set_display_overwritten(&self, overwritten: u64) {
        self.with(|s| s.display_overwritten = overwritten);
    }

    pub fn frame_recorded(&self) {
        self.with(|s| s.recorded += 1);
    }

    pub fn recorder_lost(&self, frames: u64) {
        self.with(|s| s.recorder_lost += frames);
    }

    pub fn snapshot(&self) -> MetricsSnapshot {
        self.with(|s| {
            let mut lat: Vec<f64> = s.latencies_ms.iter().copied().collect();
            lat.sort_by(f64::total_cmp);
            let pick = |q: f64| {
                if lat.is_empty() {
                    0.0
                } else {
                    lat[((lat.len() - 1) as f64 * q).round() as usize]
                }
            };
            MetricsSnapshot {
                captured: s.captured,
                capture_fps: rate(&s.capture_times),
                source_lost: s.source_lost,
                decoded: s.decoded,
                decode_fps: rate(&s.decode_times),
                unsolvable_windows: s.unsolvable_windows,
                refused_windows: s.refused_windows,
                decode_dropped: s.decode_dropped,
                latency_ms_median: pick(0.5),
                latency_ms_p99: pick(0.99),
                recorded: s.recorded,
                recorder_lost: s.recorder_lost,
                display_overwritten: s.display_overwritten,
            }
        })
    }
}

impl std::fmt::Display for MetricsSnapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "capture {:.1} FPS ({} frames, {} lost at source) | decode {:.1} FPS ({} windows, {} unsolvable, {} refused) | latency {:.1} ms median, {:.1} ms p99 | drops: decode {}, display {}, recorder {} | recorded {}",
            self.capture_fps,
            self.captured,
            self.source_lost,
            self.decode_fps,
            self.decoded,
            self.unsolvable_windows,
            self.refused_windows,
            self.latency_ms_median,
            self.latency_ms_p99,
            self.decode_dropped,
            self.display_overwritten,
            self.recorder_lost,
            self.recorded
        )
    }
}
