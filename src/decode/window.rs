//! The sliding-window decoder: a new result at every frame (paper §5.5, Figure 9).
//!
//! The decoder keeps the last `L` frames (`L` = sequence length: 3 for CPS-RGB) in a ring of
//! reused buffers. Each pushed frame replaces the oldest; once the ring is full the window
//! (oldest first) is decoded if its pattern indices form a solvable system, so frame t reuses
//! frames t−1 and t−2. A dropped frame simply produces a different order (for example 2, 0, 1); a
//! window that repeats a shift is reported as [`WindowOutcome::Unsolvable`] and counted. Solvers
//! are cached per window order (unsolvable orders too): the pseudo-inverse is computed once per
//! order, never per pixel or per frame.
//! A result is stamped at the mean of its frames' times: in a 5 Hz, 2 mm tremor a finger moves
//! about 0.5 mm per frame, so a stamp one frame off would be a measurable error.

use super::backend::{CpuBackend, DecodeBackend, Window};
use super::{check_window, DecodeError, DecodeOutput, DecodeParams, WindowSolver};
use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::pattern::PatternSequence;
use std::collections::{HashMap, VecDeque};
use std::sync::Arc;

/// What a pushed frame produced.
#[derive(Debug)]
pub enum WindowOutcome<'a> {
    /// Fewer than `L` frames seen so far.
    Filling { have: usize, need: usize },
    /// The window's pattern order repeats a shift (frames were dropped); nothing decoded.
    Unsolvable { order: Vec<usize> },
    /// The window's frames span more time than allowed (frames were dropped between them);
    /// nothing decoded, since the scene may have moved.
    TooSpread { span_s: f64, max_span_s: f64 },
    /// A new decoded result.
    Decoded(&'a DecodeOutput),
}

/// Streams frames through the decoder.
#[derive(Debug)]
pub struct SlidingDecoder {
    sequence: PatternSequence,
    cross_talk: CrossTalk,
    params: DecodeParams,
    chebyshev_n: Option<u32>,
    /// The last frames, oldest first; buffers are recycled from the front to the back.
    ring: VecDeque<Frame>,
    /// Frames pushed since creation or the last reset, at most the window length.
    filled: usize,
    /// Solvers per window order; `None` for orders that cannot be solved.
    solvers: HashMap<Vec<usize>, Option<Arc<WindowSolver>>>,
    output: Option<DecodeOutput>,
    /// The output holds no complete window: its coordinates were moved out by
    /// [`SlidingDecoder::take_coordinate`], or the backend failed while writing it.
    output_stale: bool,
    order: Vec<usize>,
    max_span_s: Option<f64>,
    /// Windows that could not be solved since creation.
    pub unsolvable_windows: u64,
    /// Windows refused because their frames were too far apart in time, since creation.
    pub spread_windows: u64,
    /// Windows decoded since creation.
    pub decoded_windows: u64,
    backend: Box<dyn DecodeBackend>,
    /// Frames pushed since the backend last decoded a window (at most the window length).
    unsent_frames: usize,
}

impl SlidingDecoder {
    pub fn new(
        sequence: PatternSequence,
        cross_talk: CrossTalk,
        params: DecodeParams,
    ) -> Result<Self, DecodeError> {
        sequence.validate()?;
        let len = sequence.entries.len();
        let chebyshev_n = sequence.chebyshev_n();
        Ok(Self {
            sequence,
            cross_talk,
            params,
            chebyshev_n,
            ring: VecDeque::with_capacity(len),
            filled: 0,
            solvers: HashMap::new(),
            output: None,
            output_stale: false,
            order: Vec::with_capacity(len),
            max_span_s: None,
            unsolvable_windows: 0,
            spread_windows: 0,
            decoded_windows: 0,
            backend: Box::new(CpuBackend),
            unsent_frames: 0,
        })
    }

    /// Refuses windows whose first and last frames are more than `max_span_s` apart. For a
    /// stream at `fps` with no drops the span is `(L − 1)/fps`; a little more tolerates jitter.
    pub fn with_max_span(mut self, max_span_s: f64) -> Self {
        self.max_span_s = Some(max_span_s);
        self
    }

    /// Runs the decode on `backend` instead of the CPU.
    pub fn with_backend(mut self, backend: Box<dyn DecodeBackend>) -> Self {
        self.backend = backend;
        self.unsent_frames = self.window_len();
        self
    }

    /// What runs the decode.
    pub fn backend_name(&self) -> String {
        self.backend.name()
    }

    pub fn window_len(&self) -> usize {
        self.sequence.entries.len()
    }

    pub fn params(&self) -> &DecodeParams {
        &self.params
    }

    /// Forgets the frames seen so far (after a seek or a stream restart).
    pub fn reset(&mut self) {
        self.filled = 0;
        self.unsent_frames = self.window_len();
    }

    /// The last decoded result, if any (none once its coordinates were taken, or after a
    /// failed decode).
    pub fn output(&self) -> Option<&DecodeOutput> {
        self.output.as_ref().filter(|_| !self.output_stale)
    }

    /// Moves the last window's projector coordinates into `buffer` without copying them: the
    /// two allocations change places, and the decoder writes its next window into `buffer`'s
    /// old one (every backend fills all of `coordinate_px`). [`Self::output`] is `None` from
    /// then until the next decoded window. Returns false, leaving `buffer` alone, when there is
    /// no decoded window to take from.
    pub fn take_coordinate(&mut self, buffer: &mut Vec<f32>) -> bool {
        let Some(out) = self.output.as_mut().filter(|_| !self.output_stale) else {
            return false;
        };
        let n = out.coordinate_px.len();
        if buffer.len() != n {
            buffer.clear();
            buffer.resize(n, f32::NAN);
        }
        std::mem::swap(&mut out.coordinate_px, buffer);
        self.output_stale = true;
        true
    }

    /// Adds `frame` and decodes the window ending with it.
    pub fn push(&mut self, frame: &Frame) -> Result<WindowOutcome<'_>, DecodeError> {
        let len = self.window_len();
        if frame.pattern_index >= len {
            return Err(DecodeError::PatternIndex {
                index: frame.pattern_index,
                len,
            });
        }
        if self.filled > 0 {
            if let Some(newest) = self.ring.back() {
                frame.check_shape(newest.width, newest.height, newest.channels)?;
            }
        }
        if self.ring.len() < len {
            self.ring.push_back(frame.clone());
        } else if let Some(mut slot) = self.ring.pop_front() {
            // Reuse the oldest frame's allocation.
            slot.data.clone_from(&frame.data);
            slot.width = frame.width;
            slot.height = frame.height;
            slot.channels = frame.channels;
            slot.time_s = frame.time_s;
            slot.pattern_index = frame.pattern_index;
            self.ring.push_back(slot);
        }
        self.filled = (self.filled + 1).min(len);
        self.unsent_frames = (self.unsent_frames + 1).min(len);
        if self.filled < len {
            return Ok(WindowOutcome::Filling {
                have: self.filled,
                need: len,
            });
        }
        if let (Some(max_span_s), Some(first), Some(last)) =
            (self.max_span_s, self.ring.front(), self.ring.back())
        {
            let span_s = last.time_s - first.time_s;
            if span_s > max_span_s {
                self.spread_windows += 1;
                return Ok(WindowOutcome::TooSpread { span_s, max_span_s });
            }
        }
        self.order.clear();
        self.order.extend(self.ring.iter().map(|f| f.pattern_index));
        let solver = match self.solvers.get(&self.order) {
            Some(Some(s)) => Arc::clone(s),
            Some(None) => {
                self.unsolvable_windows += 1;
                return Ok(WindowOutcome::Unsolvable {
                    order: self.order.clone(),
                });
            }
            None => match WindowSolver::new(&self.sequence, &self.order, &self.cross_talk) {
                Ok(s) => {
                    let s = Arc::new(s);
                    self.solvers
                        .insert(self.order.clone(), Some(Arc::clone(&s)));
                    s
                }
                Err(DecodeError::Underdetermined { .. }) => {
                    self.solvers.insert(self.order.clone(), None);
                    self.unsolvable_windows += 1;
                    return Ok(WindowOutcome::Unsolvable {
                        order: self.order.clone(),
                    });
                }
                Err(e) => return Err(e),
            },
        };
        // Oldest first, contiguous: no per-frame allocation.
        let frames: &[Frame] = self.ring.make_contiguous();
        let (w, h) = (frames[0].width, frames[0].height);
        let out = self
            .output
            .get_or_insert_with(|| DecodeOutput::new(w, h, &solver));
        check_window(&solver, frames, &self.params, self.chebyshev_n, out)?;
        let window = Window {
            solver: &solver,
            frames,
            new_frames: self.unsent_frames,
            params: &self.params,
            chebyshev_n: self.chebyshev_n,
        };
        self.output_stale = true;
        self.backend.decode(&window, out)?;
        self.output_stale = false;
        self.unsent_frames = 0;
        self.decoded_windows += 1;
        Ok(WindowOutcome::Decoded(out))
    }
}
