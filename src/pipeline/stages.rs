//! The loops the pipeline's threads run.

use super::{
    is_end, offer_to_recorder, CapturedFrame, CloudFrame, DecodePolicy, PipelineEvent,
    RecorderLink, Shared, StageQueue,
};
use crate::decode::window::SharedFrame;
use crate::decode::{SlidingDecoder, WindowOutcome};
use crate::device::{Camera, DeviceError};
use crate::frame::Frame;
use crate::session::record::RecordingSummary;
use crate::session::{Recorder, SessionError};
use crate::triangulate::{PointCloud, Triangulator};
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::sync::{Arc, PoisonError};
use std::time::Instant;

/// Frames kept for reuse by capture; beyond this, new ones are allocated (and later freed).
const FRAME_POOL: usize = 16;

/// "capture": grab, stamp, hand to decode and recorder.
pub(super) fn capture_loop(
    shared: &Shared,
    queue: &StageQueue<Arc<CapturedFrame>>,
    mut camera: Box<dyn Camera>,
    policy: DecodePolicy,
) {
    let mut pool: Vec<Arc<CapturedFrame>> = Vec::with_capacity(FRAME_POOL);
    let mut expected_next = 0u64;
    while !shared.stop.load(Ordering::SeqCst) {
        // Lossless: grab only once decode can take the frame, so that no finished frame waits
        // here for room (its wait would count as latency, and capture would gain nothing).
        if policy == DecodePolicy::Lossless
            && (!queue.wait_for_room() || shared.stop.load(Ordering::SeqCst))
        {
            break;
        }
        // A pooled frame nobody else holds any more, or a new one.
        let mut item = match pool.iter().position(|a| Arc::strong_count(a) == 1) {
            Some(i) => pool.swap_remove(i),
            None => Arc::new(CapturedFrame {
                frame: Frame::empty(),
                sequence_number: 0,
                arrived: Instant::now(),
            }),
        };
        let Some(slot) = Arc::get_mut(&mut item) else {
            continue;
        };
        match camera.grab(&mut slot.frame) {
            Ok(grabbed) => {
                slot.sequence_number = grabbed.sequence_number;
                slot.arrived = Instant::now();
                let lost = grabbed.sequence_number.saturating_sub(expected_next);
                expected_next = grabbed.sequence_number + 1;
                shared.metrics.frame_captured(slot.arrived, lost);
            }
            // A paused source: give the frame back, look at the stop flag, then ask again.
            Err(DeviceError::Idle) => {
                pool.push(item);
                continue;
            }
            Err(e) if is_end(&e) => {
                shared.event(PipelineEvent::SourceEnded {
                    frames: expected_next,
                });
                break;
            }
            Err(e) => {
                shared.event(PipelineEvent::SourceFailed(e.to_string()));
                break;
            }
        }
        offer_to_recorder(shared, &item);
        match policy {
            DecodePolicy::RealTime => {
                queue.push_newest(Arc::clone(&item));
                shared.metrics.set_decode_dropped(queue.dropped());
            }
            DecodePolicy::Lossless => {
                if !queue.push_wait(Arc::clone(&item)) {
                    break;
                }
            }
        }
        if pool.len() < FRAME_POOL {
            pool.push(item);
        }
    }
    queue.close();
}

/// Closes a queue when dropped, also when the thread unwinds: a producer blocked on a dead
/// consumer wakes up instead of waiting forever.
struct CloseOnDrop<'a, T>(&'a StageQueue<T>);

impl<T> Drop for CloseOnDrop<'_, T> {
    fn drop(&mut self) {
        self.0.close();
    }
}

/// "decode": sliding-window decode and triangulation of every frame that arrives.
pub(super) fn decode_loop(
    shared: &Shared,
    queue: &StageQueue<Arc<CapturedFrame>>,
    mut decoder: SlidingDecoder,
    triangulator: &Triangulator,
    display: bool,
) {
    let _close_input = CloseOnDrop(queue);
    // When the source ends (or this thread fails) consumers drain what is left, then see the end.
    let _close_consumers = shared.consumers.as_deref().map(CloseOnDrop);
    let mut spare: Vec<Arc<CloudFrame>> = Vec::new();
    while let Some(item) = queue.pop() {
        // The window keeps the captured frame itself (capture reuses it once nobody holds it).
        let outcome = match decoder.push_shared(Arc::clone(&item) as SharedFrame) {
            Ok(outcome) => outcome,
            Err(e) => {
                shared.event(PipelineEvent::DecodeFailed(e.to_string()));
                *shared
                    .decoder_name
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner) = decoder.backend_name();
                decoder.reset();
                continue;
            }
        };
        let out = match outcome {
            WindowOutcome::Decoded(out) => {
                if out.refused.is_some() {
                    shared.metrics.window_refused();
                }
                out
            }
            WindowOutcome::Filling { .. } => continue,
            WindowOutcome::Unsolvable { .. } | WindowOutcome::TooSpread { .. } => {
                shared.metrics.window_unsolvable();
                continue;
            }
        };
        // Reuse a cloud the display and consumers have let go of.
        let mut result = match spare.iter().position(|a| Arc::strong_count(a) == 1) {
            Some(i) => spare.swap_remove(i),
            None => Arc::new(CloudFrame {
                cloud: PointCloud::default(),
                camera: None,
                projector_px: Vec::new(),
                window_end: 0,
                latency: Default::default(),
            }),
        };
        let Some(slot) = Arc::get_mut(&mut result) else {
            continue;
        };
        if let Err(e) = triangulator.triangulate(out, &mut slot.cloud) {
            shared.event(PipelineEvent::DecodeFailed(e.to_string()));
            continue;
        }
        if display {
            // No copies: the captured frame is shared, and the coordinates change places with
            // the slot's buffer from an earlier window (no allocation once the spares exist).
            slot.camera = Some(Arc::clone(&item));
            decoder.take_coordinate(&mut slot.projector_px);
        } else {
            slot.camera = None;
        }
        slot.window_end = item.sequence_number;
        let now = Instant::now();
        slot.latency = now - item.arrived;
        shared.metrics.window_decoded(now, slot.latency);
        if display {
            shared.latest.put(Arc::clone(&result));
        }
        if let Some(consumers) = &shared.consumers {
            consumers.push_newest(Arc::clone(&result));
        }
        shared
            .metrics
            .set_display_overwritten(shared.latest.overwritten());
        if spare.len() < 4 {
            spare.push(result);
        }
    }
}

/// "recorder": writes every frame it is handed until the queue closes or the disk fails.
pub(super) fn record_loop(
    shared: &Shared,
    mut recorder: Recorder,
    frames: &Receiver<Arc<CapturedFrame>>,
) -> Result<RecordingSummary, SessionError> {
    let result = (|| {
        for item in frames.iter() {
            recorder.write_frame(&item.frame)?;
            shared.metrics.frame_recorded();
        }
        recorder.finish()
    })();
    shared.event(PipelineEvent::RecordingStopped(
        result.as_ref().map(|s| *s).map_err(|e| e.to_string()),
    ));
    result
}

/// Closes a recorder's queue and waits for it to write everything it holds.
pub(super) fn finish_recording(link: RecorderLink) -> Result<RecordingSummary, String> {
    let RecorderLink { sender, handle } = link;
    drop(sender);
    match handle.join() {
        Ok(result) => result.map_err(|e| e.to_string()),
        Err(_) => Err("the recorder thread panicked".to_string()),
    }
}
