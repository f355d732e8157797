//! The decode stage runs its parallel work on a worker pool of its own, so other parallel work in
//! the process (the virtual rig rendering the next frame on the capture thread, an analysis in
//! the GUI) cannot hold it up. Its own binary: the test occupies rayon's process-wide pool, which
//! would slow down every other test of a shared binary.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use common::{rig, scratch};

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tremorscan::device::{Pacing, ReplayCamera};
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig};
use tremorscan::session::{write_session, Session};

/// Every thread of rayon's process-wide pool, busy until this is dropped or `deadline` has
/// passed (then [`GlobalPoolHeld::expired`]): a decode that waits for the pool makes the test
/// fail, not hang.
struct GlobalPoolHeld {
    release: Arc<AtomicBool>,
    expired: Arc<AtomicBool>,
}

impl GlobalPoolHeld {
    fn new(deadline: Duration) -> Self {
        let threads = rayon::current_num_threads();
        let release = Arc::new(AtomicBool::new(false));
        let expired = Arc::new(AtomicBool::new(false));
        let started = Arc::new(AtomicUsize::new(0));
        for _ in 0..threads {
            let (release, started) = (Arc::clone(&release), Arc::clone(&started));
            rayon::spawn(move || {
                started.fetch_add(1, Ordering::SeqCst);
                while !release.load(Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(1));
                }
            });
        }
        // Each worker holds one task and takes no other until released.
        while started.load(Ordering::SeqCst) < threads {
            std::thread::sleep(Duration::from_millis(1));
        }
        let (watch_release, watch_expired) = (Arc::clone(&release), Arc::clone(&expired));
        std::thread::spawn(move || {
            let start = Instant::now();
            while !watch_release.load(Ordering::SeqCst) {
                if start.elapsed() > deadline {
                    watch_expired.store(true, Ordering::SeqCst);
                    watch_release.store(true, Ordering::SeqCst);
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        Self { release, expired }
    }

    fn expired(&self) -> bool {
        self.expired.load(Ordering::SeqCst)
    }
}

impl Drop for GlobalPoolHeld {
    fn drop(&mut self) {
        self.release.store(true, Ordering::SeqCst);
    }
}

#[test]
fn the_decode_keeps_going_while_the_process_wide_pool_is_busy() {
    let rig = rig(160, 100);
    let frames = common::rendered(&rig, 0..9);
    let dir = scratch("workers");
    write_session(&dir, rig.session_manifest(), &frames).unwrap();
    let session = Session::open(&dir).unwrap();
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        ..PipelineConfig::default()
    };

    // Seven 160×100 windows take milliseconds; a decode that needed the busy pool would wait
    // until the deadline.
    let held = GlobalPoolHeld::new(Duration::from_secs(30));
    let pipeline = Pipeline::start(
        Box::new(ReplayCamera::new(session, Pacing::AsFastAsPossible)),
        rig.sequence.clone(),
        rig.config.cross_talk,
        rig.stereo_model(),
        config,
    )
    .unwrap();
    let ended = pipeline.wait_for_end(Duration::from_secs(60));
    let expired = held.expired();
    drop(held);
    let m = pipeline.stop();
    assert!(
        ended && !expired,
        "the replay waited for rayon's busy pool (ended {ended}, {} windows)",
        m.decoded
    );
    assert_eq!((m.decoded, m.decode_dropped), (7, 0));
}
