//! `tremorscan record` and `replay`: the threaded pipeline headless. `record` runs the virtual rig
//! live and records a trial; `replay` plays a session through capture, decode and triangulation.
//! Both print the pipeline's metrics and the process's resident memory once a second and at the
//! end.

use crate::gpu_decode::{start_pipeline, DecoderChoice};
use crate::unwrap_args::UnwrapArgs;
use anyhow::{Context, Result};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tremorscan::color::CrossTalk;
use tremorscan::decode::{DecodeParams, MotionParams};
use tremorscan::device::{Camera, Pacing, ReplayCamera, VirtualCamera};
use tremorscan::pattern::PatternSequence;
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig, PipelineEvent};
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan::session::{Session, TrialJson};
use tremorscan::triangulate::StereoModel;

/// Prints new events; returns false if one of them is a failure.
fn report_events(pipeline: &Pipeline) -> bool {
    let mut fine = true;
    for event in pipeline.events() {
        match &event {
            PipelineEvent::SourceEnded { frames } => println!("source ended after {frames} frames"),
            PipelineEvent::SourceFailed(e) => {
                fine = false;
                println!("camera failed: {e}");
            }
            PipelineEvent::DecodeFailed(e) => println!("decode failed on a window: {e}"),
            PipelineEvent::RecordingOverrun { recorded } => println!(
                "RECORDING STOPPED: the disk could not keep up; {recorded} frames were recorded and are readable"
            ),
            PipelineEvent::RecordingStopped(Ok(s)) => println!(
                "recording finished: {} frames, {:.1} MB",
                s.frames,
                s.bytes as f64 / 1e6
            ),
            PipelineEvent::RecordingStopped(Err(e)) => {
                fine = false;
                println!("RECORDING FAILED: {e}; the frames written before stay readable");
            }
        }
    }
    fine
}

/// " | resident 430.1 MB (peak 441.0 MB)" for the progress lines: a long run shows whether memory
/// stays flat. Empty where the system does not report it.
fn resident_memory() -> String {
    tremorscan::memory::ResidentMemory::now().map_or_else(String::new, |m| {
        format!(
            " | resident {:.1} MB (peak {:.1} MB)",
            m.resident_bytes as f64 / 1e6,
            m.peak_bytes as f64 / 1e6
        )
    })
}

/// Runs until the source ends or `seconds` of wall time pass, printing metrics each second.
fn run_for(pipeline: &Pipeline, seconds: Option<f64>) -> bool {
    let start = Instant::now();
    let mut fine = true;
    let mut last_print = Instant::now();
    while pipeline.is_running() {
        if seconds.is_some_and(|s| start.elapsed().as_secs_f64() >= s) {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
        fine &= report_events(pipeline);
        if last_print.elapsed() >= Duration::from_secs(1) {
            last_print = Instant::now();
            println!("{}{}", pipeline.metrics(), resident_memory());
        }
    }
    fine
}

/// Starts the pipeline with its decode on `decoder`, and says where the decode runs.
fn start(
    decoder: DecoderChoice,
    camera: Box<dyn Camera>,
    sequence: PatternSequence,
    cross_talk: CrossTalk,
    stereo: StereoModel,
    config: PipelineConfig,
) -> Result<Pipeline> {
    let (pipeline, why_cpu) =
        start_pipeline(decoder, camera, sequence, cross_talk, stereo, config)?;
    if let Some(why) = why_cpu {
        println!("{why}");
    }
    println!("decode: {}", pipeline.decoder_name());
    Ok(pipeline)
}

#[derive(clap::Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Session folder (`cps-session/1`, see docs/formats.md).
    pub session: PathBuf,
    /// Play at the recorded frame rate instead of as fast as possible.
    #[arg(long)]
    pub recorded_rate: bool,
    /// Behave like the live view: keep the newest frames and drop what decode cannot take
    /// (default: lossless, every window decoded).
    #[arg(long)]
    pub real_time: bool,
    /// Where the decode runs: `auto` takes a hardware GPU when there is one.
    #[arg(long, value_enum, default_value_t = DecoderChoice::Auto)]
    pub decoder: DecoderChoice,
    #[arg(long, value_enum, default_value_t = MotionChoice::Linear)]
    pub motion: MotionChoice,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
}

/// The motion model inside the window (`--motion`).
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionChoice {
    /// One velocity and brightness change per patch, corrected inside the window.
    Linear,
    /// The paper's still window.
    Off,
}

impl MotionChoice {
    /// The decode parameters with this motion model.
    pub fn decode_params(self) -> DecodeParams {
        let motion = match self {
            MotionChoice::Linear => MotionParams::default(),
            MotionChoice::Off => MotionParams::off(),
        };
        DecodeParams {
            motion,
            ..DecodeParams::default()
        }
    }
}

pub fn run_replay(args: &ReplayArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    if let Some(cut) = session.container.as_ref().and_then(|c| c.cut_off.as_ref()) {
        println!(
            "note: the recording was cut off ({cut}); replaying its {} complete frames",
            session.frame_count()
        );
    }
    let sequence = session.sequence()?;
    let cross_talk = session
        .cross_talk()?
        .unwrap_or_else(tremorscan::color::CrossTalk::identity);
    let stereo = session.stereo_model()?;
    let decoding = args
        .unwrap
        .session_decoding(&session, args.motion.decode_params())?;
    println!("{}", decoding.describe());
    let pacing = if args.recorded_rate {
        Pacing::Recorded
    } else {
        Pacing::AsFastAsPossible
    };
    let config = PipelineConfig {
        decode_policy: if args.real_time {
            DecodePolicy::RealTime
        } else {
            DecodePolicy::Lossless
        },
        // Lossless, capture waits for decode: one frame waiting keeps both busy (reading a
        // frame takes a fraction of a window), and every further one only adds its wait to the
        // latency. Real time keeps the default's margin for the camera's jitter.
        decode_queue: if args.real_time {
            PipelineConfig::default().decode_queue
        } else {
            1
        },
        display: false,
        decode_params: decoding.params,
        ..PipelineConfig::default()
    };
    let camera = ReplayCamera::new(session, pacing);
    let started = Instant::now();
    let pipeline = start(
        args.decoder,
        Box::new(camera),
        sequence,
        cross_talk,
        stereo,
        config,
    )?;
    let fine = run_for(&pipeline, None);
    let wall = started.elapsed().as_secs_f64();
    let fine = fine & report_events(&pipeline);
    let m = pipeline.stop();
    println!("{m}{}", resident_memory());
    println!(
        "replayed {} frames into {} windows in {wall:.2} s ({:.1} windows/s)",
        m.captured,
        m.decoded,
        m.decoded as f64 / wall
    );
    anyhow::ensure!(fine, "the replay did not complete (see above)");
    Ok(())
}

#[derive(clap::Args, Debug, Clone)]
pub struct RecordArgs {
    /// Session folder to record into (created).
    #[arg(long)]
    pub out: PathBuf,
    /// Wall-clock duration, seconds.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 400)]
    pub height: usize,
    #[arg(long, default_value = "")]
    pub subject: String,
    /// `left` or `right`.
    #[arg(long, default_value = "")]
    pub hand: String,
    #[arg(long, default_value = "")]
    pub condition: String,
    #[arg(long, default_value = "")]
    pub notes: String,
    /// Where the decode runs: `auto` takes a hardware GPU when there is one.
    #[arg(long, value_enum, default_value_t = DecoderChoice::Auto)]
    pub decoder: DecoderChoice,
    #[arg(long, value_enum, default_value_t = MotionChoice::Linear)]
    pub motion: MotionChoice,
}

pub fn run_record(args: &RecordArgs) -> Result<()> {
    anyhow::ensure!(
        args.seconds > 0.0 && args.seconds.is_finite(),
        "--seconds must be positive"
    );
    let config = RigConfig::paper(args.width, args.height).context("rig configuration")?;
    let rig = VirtualRig::new(config.clone(), config.default_sequence()?)?;
    let manifest = rig.session_manifest();
    let (sequence, cross_talk, stereo) = (
        rig.sequence.clone(),
        rig.config.cross_talk,
        rig.stereo_model(),
    );
    let camera = VirtualCamera::new(rig, Pacing::Recorded);
    let pipeline = start(
        args.decoder,
        Box::new(camera),
        sequence,
        cross_talk,
        stereo,
        PipelineConfig {
            display: false,
            decode_params: args.motion.decode_params(),
            ..PipelineConfig::default()
        },
    )?;
    let trial = TrialJson {
        subject_id: args.subject.clone(),
        hand: args.hand.clone(),
        condition: args.condition.clone(),
        operator_notes: args.notes.clone(),
        date: tremorscan::calibrate::file::utc_now_iso8601(),
        control_points: Vec::new(),
    };
    pipeline.start_recording(&args.out, manifest, trial)?;
    println!(
        "recording {} for {} s from {} (Ctrl-C keeps every complete frame)",
        args.out.display(),
        args.seconds,
        pipeline.camera_name()
    );
    let mut fine = run_for(&pipeline, Some(args.seconds));
    // The outcome is reported once, as the recorder's event, just below.
    let _ = pipeline.stop_recording();
    fine &= report_events(&pipeline);
    let m = pipeline.stop();
    println!("{m}{}", resident_memory());
    anyhow::ensure!(fine, "the recording did not complete (see above)");
    Ok(())
}
