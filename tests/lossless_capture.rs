//! A lossless pipeline grabs a frame only when decode can take it: no finished frame waits in
//! capture for room in the queue (that wait would count as latency and buy nothing), and the
//! queue is still kept full, so decode never waits for capture.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{rendered, rig};

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tremorscan::decode::backend::Window;
use tremorscan::decode::{CpuBackend, DecodeBackend, DecodeError, DecodeOutput};
use tremorscan::device::{Camera, DeviceError, Grabbed};
use tremorscan::frame::Frame;
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig};

const FPS: f64 = 121.0;

/// `total` frames from memory, as fast as asked for, counting the grabs.
struct CountingCamera {
    frames: Vec<Frame>,
    total: usize,
    grabbed: Arc<AtomicUsize>,
}

impl Camera for CountingCamera {
    fn name(&self) -> String {
        "counting".into()
    }
    fn size(&self) -> (usize, usize) {
        (self.frames[0].width, self.frames[0].height)
    }
    fn fps(&self) -> f64 {
        FPS
    }
    fn grab(&mut self, frame: &mut Frame) -> Result<Grabbed, DeviceError> {
        let next = self.grabbed.load(Ordering::SeqCst);
        if next >= self.total {
            return Err(DeviceError::EndOfStream {
                frames: next as u64,
            });
        }
        frame.clone_from(&self.frames[next % self.frames.len()]);
        frame.time_s = next as f64 / FPS;
        frame.pattern_index = next % 3;
        self.grabbed.store(next + 1, Ordering::SeqCst);
        Ok(Grabbed {
            sequence_number: next as u64,
        })
    }
}

/// The CPU decode after a pause that gives capture all the time it wants; records how many
/// frames capture had grabbed beyond those decode had taken, at each window.
#[derive(Debug)]
struct SlowBackend {
    grabbed: Arc<AtomicUsize>,
    ahead: Arc<Mutex<Vec<usize>>>,
}

impl DecodeBackend for SlowBackend {
    fn name(&self) -> String {
        "slow CPU".into()
    }
    fn decode(&mut self, window: &Window<'_>, out: &mut DecodeOutput) -> Result<(), DecodeError> {
        std::thread::sleep(Duration::from_millis(60));
        // The window's newest frame is the last one decode has taken from the queue.
        let newest = window.frames.last().map_or(0.0, |f| f.time_s);
        let taken = (newest * FPS).round() as usize + 1;
        let grabbed = self.grabbed.load(Ordering::SeqCst);
        self.ahead.lock().unwrap().push(grabbed - taken);
        CpuBackend.decode(window, out)
    }
}

#[test]
fn a_lossless_capture_grabs_only_what_the_queue_can_take() {
    let rig = rig(160, 100);
    let frames = rendered(&rig, 0..3);
    let grabbed = Arc::new(AtomicUsize::new(0));
    let ahead = Arc::new(Mutex::new(Vec::new()));
    let total = 20;
    let depth = 2;
    let camera = CountingCamera {
        frames,
        total,
        grabbed: Arc::clone(&grabbed),
    };
    let backend = SlowBackend {
        grabbed: Arc::clone(&grabbed),
        ahead: Arc::clone(&ahead),
    };
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        decode_queue: depth,
        display: false,
        ..PipelineConfig::default()
    };
    let pipeline = Pipeline::start_with_backend(
        Box::new(camera),
        rig.sequence.clone(),
        rig.config.cross_talk,
        rig.stereo_model(),
        config,
        Box::new(backend),
    )
    .unwrap();
    assert!(pipeline.wait_for_end(Duration::from_secs(60)));
    let m = pipeline.stop();
    assert_eq!(
        (m.captured, m.decoded, m.decode_dropped),
        (20, 18, 0),
        "{m}"
    );
    let ahead = ahead.lock().unwrap().clone();
    assert_eq!(ahead.len(), total - 2);
    // While a window decodes, capture fills the queue and stops: `depth` frames ahead, never
    // one more held in capture itself. (Before capture waited for room ahead of grabbing, it
    // was `depth + 1` at every window.) The last windows see the source's end instead.
    assert!(ahead.iter().all(|&a| a <= depth), "{ahead:?}");
    assert!(
        ahead[..total - 2 - depth].iter().all(|&a| a == depth),
        "decode has to find the queue full: {ahead:?}"
    );
}
