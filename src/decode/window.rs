//! The sliding-window decoder: a new result at every frame (paper §5.5, Figure 9).
//!
//! The decoder keeps the last `L` frames (`L` = sequence length: 3 for CPS-RGB) in a ring of
//! preallocated buffers. Each pushed frame replaces the oldest; once the ring is full the window
//! (oldest first) is decoded if its pattern indices form a solvable system, so frame t reuses
//! frames t−1 and t−2. A dropped frame simply produces a different order (for example 2, 0, 1); a
//! window that repeats a shift is reported as [`WindowOutcome::Unsolvable`] and counted. Solvers
//! are cached per window order: the pseudo-inverse is computed once per order, never per pixel.
//! A result is stamped at the mean of its frames' times: in a 5 Hz, 2 mm tremor a finger moves
//! about 0.5 mm per frame, so a stamp one frame off would be a measurable error.

use super::{decode_window, DecodeError, DecodeOutput, DecodeParams, WindowSolver};
use crate::color::CrossTalk;
use crate::frame::Frame;
use crate::pattern::PatternSequence;
use std::collections::HashMap;
use std::sync::Arc;

/// What a pushed frame produced.
#[derive(Debug)]
pub enum WindowOutcome<'a> {
    /// Fewer than `L` frames seen so far.
    Filling { have: usize, need: usize },
    /// The window's pattern order repeats a shift (frames were dropped); nothing decoded.
    Unsolvable { order: Vec<usize> },
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
    ring: Vec<Frame>,
    /// Index in `ring` of the next slot to overwrite (the oldest frame once full).
    next: usize,
    filled: usize,
    solvers: HashMap<Vec<usize>, Arc<WindowSolver>>,
    output: Option<DecodeOutput>,
    order: Vec<usize>,
    /// Windows that could not be solved since creation.
    pub unsolvable_windows: u64,
    /// Windows decoded since creation.
    pub decoded_windows: u64,
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
            ring: Vec::with_capacity(len),
            next: 0,
            filled: 0,
            solvers: HashMap::new(),
            output: None,
            order: Vec::with_capacity(len),
            unsolvable_windows: 0,
            decoded_windows: 0,
        })
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
        self.next = 0;
    }

    /// The last decoded result, if any.
    pub fn output(&self) -> Option<&DecodeOutput> {
        self.output.as_ref()
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
        if let Some(first) = self.ring.first() {
            if self.filled > 0 {
                frame.check_shape(first.width, first.height, first.channels)?;
            }
        }
        if self.ring.len() < len {
            self.ring.push(frame.clone());
        } else {
            // Reuse the slot's allocation.
            let slot = &mut self.ring[self.next];
            slot.data.clone_from(&frame.data);
            slot.width = frame.width;
            slot.height = frame.height;
            slot.channels = frame.channels;
            slot.time_s = frame.time_s;
            slot.pattern_index = frame.pattern_index;
        }
        self.next = (self.next + 1) % len;
        self.filled = (self.filled + 1).min(len);
        if self.filled < len {
            return Ok(WindowOutcome::Filling {
                have: self.filled,
                need: len,
            });
        }
        self.order.clear();
        for i in 0..len {
            self.order
                .push(self.ring[(self.next + i) % len].pattern_index);
        }
        let solver = match self.solvers.get(&self.order) {
            Some(s) => Arc::clone(s),
            None => match WindowSolver::new(&self.sequence, &self.order, &self.cross_talk) {
                Ok(s) => {
                    let s = Arc::new(s);
                    self.solvers.insert(self.order.clone(), Arc::clone(&s));
                    s
                }
                Err(DecodeError::Underdetermined { .. }) => {
                    self.unsolvable_windows += 1;
                    return Ok(WindowOutcome::Unsolvable {
                        order: self.order.clone(),
                    });
                }
                Err(e) => return Err(e),
            },
        };
        let frames: Vec<&Frame> = (0..len)
            .map(|i| &self.ring[(self.next + i) % len])
            .collect();
        let (w, h) = (frames[0].width, frames[0].height);
        let out = self
            .output
            .get_or_insert_with(|| DecodeOutput::new(w, h, &solver));
        decode_window(&solver, &frames, &self.params, self.chebyshev_n, out)?;
        self.decoded_windows += 1;
        Ok(WindowOutcome::Decoded(out))
    }
}
