//! The sliding-window decoder: a new result at every frame (paper §5.5, Figure 9).
//!
//! The decoder keeps the last `L` frames (`L` = sequence length: 3 for CPS-RGB) in a ring. A frame
//! pushed by reference is copied into a reused buffer; one pushed as a [`SharedFrame`] (the live
//! pipeline's captured frames) is kept without a copy, which saves the decode thread 0.7–1 ms per
//! 1920×1200 frame. Each pushed frame replaces the oldest; once the ring is full the window (oldest
//! first) is decoded if its pattern indices form a solvable system, so frame t reuses frames t−1
//! and t−2. A dropped frame simply produces a different order (for example 2, 0, 1); a window that
//! repeats a shift is reported as [`WindowOutcome::Unsolvable`] and counted. Solvers are cached per
//! window order (unsolvable orders too): the pseudo-inverse is computed once per order, never per
//! pixel or per frame.
//! A result is stamped at the mean of its frames' times: in a 5 Hz, 2 mm tremor a finger moves
//! about 0.5 mm per frame, so a stamp one frame off would be a measurable error.

use super::backend::{CpuBackend, DecodeBackend, Window};
use super::solver::MAX_OBSERVATIONS;
use super::{check_window, DecodeError, DecodeOutput, DecodeParams, WindowSolver};
use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::pattern::PatternSequence;
use std::borrow::Borrow;
use std::collections::{HashMap, VecDeque};
use std::sync::Arc;

/// A frame the decoder can keep without copying it, shared with whoever captured it.
pub type SharedFrame = Arc<dyn Borrow<Frame> + Send + Sync>;

/// A frame of the ring: a buffer of the decoder's own, or a shared one.
enum RingFrame {
    Owned(Frame),
    Shared(SharedFrame),
}

impl RingFrame {
    fn frame(&self) -> &Frame {
        match self {
            Self::Owned(frame) => frame,
            Self::Shared(shared) => (**shared).borrow(),
        }
    }
}

impl std::fmt::Debug for RingFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let frame = self.frame();
        let kind = match self {
            Self::Owned(_) => "owned",
            Self::Shared(_) => "shared",
        };
        write!(
            f,
            "{kind} {}×{} frame, pattern {}",
            frame.width, frame.height, frame.pattern_index
        )
    }
}

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
    /// The last frames, oldest first; owned buffers are recycled from the front to the back.
    ring: VecDeque<RingFrame>,
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

    /// Heap bytes the decoder holds: its output planes and stages' scratch, and the frames of
    /// its ring that are its own copies (shared frames belong to whoever captured them).
    pub fn memory_bytes(&self) -> usize {
        let owned: usize = self
            .ring
            .iter()
            .filter_map(|frame| match frame {
                RingFrame::Owned(frame) => Some(frame.data.capacity()),
                RingFrame::Shared(_) => None,
            })
            .sum();
        owned + self.output.as_ref().map_or(0, DecodeOutput::memory_bytes)
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

    /// Adds a copy of `frame` and decodes the window ending with it.
    pub fn push(&mut self, frame: &Frame) -> Result<WindowOutcome<'_>, DecodeError> {
        self.check_next(frame)?;
        let slot = if self.ring.len() < self.window_len() {
            RingFrame::Owned(frame.clone())
        } else {
            match self.ring.pop_front() {
                // Reuse the oldest frame's allocation.
                Some(RingFrame::Owned(mut slot)) => {
                    slot.data.clone_from(&frame.data);
                    slot.width = frame.width;
                    slot.height = frame.height;
                    slot.channels = frame.channels;
                    slot.time_s = frame.time_s;
                    slot.pattern_index = frame.pattern_index;
                    RingFrame::Owned(slot)
                }
                Some(RingFrame::Shared(_)) | None => RingFrame::Owned(frame.clone()),
            }
        };
        self.ring.push_back(slot);
        self.decode_newest()
    }

    /// Adds `frame` without copying it (the decoder holds it until it leaves the window) and
    /// decodes the window ending with it.
    pub fn push_shared(&mut self, frame: SharedFrame) -> Result<WindowOutcome<'_>, DecodeError> {
        self.check_next((*frame).borrow())?;
        if self.ring.len() >= self.window_len() {
            self.ring.pop_front();
        }
        self.ring.push_back(RingFrame::Shared(frame));
        self.decode_newest()
    }

    /// Refuses a frame that cannot join the window: a pattern index outside the sequence, or a
    /// size or channel count other than the newest frame's.
    fn check_next(&self, frame: &Frame) -> Result<(), DecodeError> {
        let len = self.window_len();
        if frame.pattern_index >= len {
            return Err(DecodeError::PatternIndex {
                index: frame.pattern_index,
                len,
            });
        }
        if self.filled > 0 {
            if let Some(newest) = self.ring.back().map(RingFrame::frame) {
                frame.check_shape(newest.width, newest.height, newest.channels)?;
            }
        }
        Ok(())
    }

    /// Decodes the window that ends with the frame just added to the ring.
    fn decode_newest(&mut self) -> Result<WindowOutcome<'_>, DecodeError> {
        let len = self.window_len();
        self.filled = (self.filled + 1).min(len);
        self.unsent_frames = (self.unsent_frames + 1).min(len);
        if self.filled < len {
            return Ok(WindowOutcome::Filling {
                have: self.filled,
                need: len,
            });
        }
        if let (Some(max_span_s), Some(first), Some(last)) = (
            self.max_span_s,
            self.ring.front().map(RingFrame::frame),
            self.ring.back().map(RingFrame::frame),
        ) {
            let span_s = last.time_s - first.time_s;
            if span_s > max_span_s {
                self.spread_windows += 1;
                return Ok(WindowOutcome::TooSpread { span_s, max_span_s });
            }
        }
        self.order.clear();
        self.order
            .extend(self.ring.iter().map(|f| f.frame().pattern_index));
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
        // Oldest first, in an array on the stack: no per-frame allocation. The solver refused
        // windows of more than MAX_OBSERVATIONS frames above. (The ring cannot be empty here,
        // a frame was just added; the `else` only keeps this free of panics.)
        let Some(first) = self.ring.front().map(RingFrame::frame) else {
            return Ok(WindowOutcome::Filling { have: 0, need: len });
        };
        let mut refs: [&Frame; MAX_OBSERVATIONS] = [first; MAX_OBSERVATIONS];
        let count = self.ring.len().min(MAX_OBSERVATIONS);
        for (slot, frame) in refs.iter_mut().zip(&self.ring) {
            *slot = frame.frame();
        }
        let frames = &refs[..count];
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
