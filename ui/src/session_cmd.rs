//! `tremorscan simulate`, `decode` and `info`: sessions from the virtual rig, one decoded window
//! of a session exported as PLY / float TIFF / PNG, and a session's summary and validation.

use crate::progress::Progress;
use crate::unwrap_args::UnwrapArgs;
use anyhow::{bail, ensure, Context, Result};
use std::path::PathBuf;
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::export::{depth_mm, write_colour_png, write_depth_tiff, write_ply};
use tremorscan::pattern::PatternSequence;
use tremorscan::rig::{GroundTruth, RigConfig, Tremor, VirtualRig};
use tremorscan::session::frames::write_png;
use tremorscan::session::manifest::FrameJson;
use tremorscan::session::{Session, SessionEntry};
use tremorscan::triangulate::{PointCloud, Triangulator};

#[derive(clap::Args, Debug, Clone)]
pub struct SimulateArgs {
    /// Folder to write the session into (created; must not hold a session already).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 121)]
    pub frames: usize,
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 400)]
    pub height: usize,
    /// Tremor frequency, Hz.
    #[arg(long, default_value_t = 5.3)]
    pub tremor_hz: f64,
    /// Peak fingertip displacement along the optical axis, mm.
    #[arg(long, default_value_t = 2.0)]
    pub amplitude_mm: f64,
    /// Peak sideways sway of the whole hand (camera y), mm.
    #[arg(long, default_value_t = 0.0)]
    pub sway_mm: f64,
    /// Peak roll of the hand about the forearm axis (pronation–supination), degrees.
    #[arg(long, default_value_t = 0.0)]
    pub roll_deg: f64,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The camera lens's blur: σ of its Gaussian point-spread function, pixels of the image
    /// (0: every pixel sees its own ray only). Default: the rig's, 0.4.
    #[arg(long)]
    pub psf_px: Option<f64>,
    /// The projected sequence: this product's CPS-RGB (the default), CPS with gray images, or
    /// the multi-frequency phase shift other scanners record (`--periods`, `--steps`).
    #[arg(long, value_enum, default_value_t = PatternArg::CpsRgb)]
    pub pattern: PatternArg,
    /// With `--pattern phase-shift`: fringe periods across the projector's columns, one per
    /// frequency; the lowest must be 1 (the unit frequency) or less.
    #[arg(long, value_delimiter = ',', default_values_t = [16, 1])]
    pub periods: Vec<u32>,
    /// With `--pattern phase-shift`: equally spaced shifts per frequency.
    #[arg(long, default_value_t = 3)]
    pub steps: usize,
    /// Also write the exact depth of every frame as `truth/NNNNNN-depth.tiff` (mm, NaN off
    /// surfaces).
    #[arg(long)]
    pub truth: bool,
    /// The trial's subject id (writes the trial metadata into session.json).
    #[arg(long)]
    pub subject: Option<String>,
    /// The trial's hand (`left`, `right`).
    #[arg(long, default_value = "")]
    pub hand: String,
    /// The trial's condition (e.g. `rest`).
    #[arg(long, default_value = "")]
    pub condition: String,
    /// A saved control point `NAME=U,V` (repeat for more), as the GUI saves them.
    #[arg(long = "control-point", value_parser = parse_named_point)]
    pub control_points: Vec<tremorscan::session::manifest::ControlPointJson>,
}

fn parse_named_point(
    text: &str,
) -> Result<tremorscan::session::manifest::ControlPointJson, String> {
    let (name, pixel) = text
        .rsplit_once('=')
        .ok_or_else(|| format!("`{text}`: expected NAME=U,V"))?;
    let (u, v) = crate::tremor_cmd::parse_point(pixel)?;
    Ok(tremorscan::session::manifest::ControlPointJson {
        name: name.to_string(),
        u,
        v,
    })
}

/// The sequences `simulate` can project.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum PatternArg {
    /// Three colour images, frequencies n, n−1, n−2 in R, G, B (n = 65, 6-bit).
    CpsRgb,
    /// Seven gray images (CPS-gray, n = 65, 8-bit).
    CpsGray7,
    /// Nine gray images (CPS-gray, n = 65, 8-bit).
    CpsGray9,
    /// Gray multi-frequency phase shift (`--periods`, `--steps`; 8-bit).
    PhaseShift,
}

impl PatternArg {
    /// The sequence on a projector whose coded columns span `x_max`.
    fn sequence(self, args: &SimulateArgs, x_max: f64) -> Result<PatternSequence> {
        use tremorscan::pattern::{cps_gray, cps_rgb, multi_frequency, Axis, CpsGrayVariant};
        let sequence = match self {
            PatternArg::CpsRgb => cps_rgb(65, x_max, Axis::Columns, 6),
            PatternArg::CpsGray7 => cps_gray(65, CpsGrayVariant::Minimal7, x_max, Axis::Columns, 8),
            PatternArg::CpsGray9 => cps_gray(65, CpsGrayVariant::Full9, x_max, Axis::Columns, 8),
            PatternArg::PhaseShift => {
                // A period over the whole range is frequency index 2 (f = m·π/x_max).
                let ms: Vec<u32> = args.periods.iter().map(|p| 2 * p).collect();
                multi_frequency(&ms, args.steps, x_max, Axis::Columns, 8)
            }
        };
        sequence.with_context(|| format!("--pattern {self:?}"))
    }
}

pub fn run_simulate(args: &SimulateArgs) -> Result<()> {
    ensure!(args.frames > 0, "--frames must be at least 1");
    ensure!(
        args.tremor_hz.is_finite() && args.tremor_hz >= 0.0,
        "--tremor-hz must be ≥ 0"
    );
    ensure!(
        args.amplitude_mm.is_finite() && args.amplitude_mm >= 0.0,
        "--amplitude-mm must be ≥ 0"
    );
    ensure!(
        args.sway_mm.is_finite() && args.sway_mm >= 0.0,
        "--sway-mm must be ≥ 0"
    );
    ensure!(
        args.roll_deg.is_finite() && args.roll_deg >= 0.0,
        "--roll-deg must be ≥ 0"
    );
    ensure!(
        !args.out.join("session.json").exists(),
        "{} already holds a session; choose another folder",
        args.out.display()
    );
    let mut config = RigConfig::paper(args.width, args.height).context("rig configuration")?;
    config.seed = args.seed;
    if let Some(psf) = args.psf_px {
        ensure!(psf.is_finite() && psf >= 0.0, "--psf-px must be ≥ 0");
        config.camera_psf_sigma_px = psf;
    }
    if let Some(tremor) = config.scene.hand.as_mut() {
        *tremor = Tremor {
            frequency_hz: args.tremor_hz,
            tip_amplitude_mm: args.amplitude_mm,
            sway_amplitude_mm: args.sway_mm,
            roll_amplitude_deg: args.roll_deg,
            ..*tremor
        };
    }
    let seq = args.pattern.sequence(args, config.projector.width as f64)?;
    let rig = VirtualRig::new(config, seq)?;
    let frames_dir = args.out.join("frames");
    std::fs::create_dir_all(&frames_dir)
        .with_context(|| format!("creating {}", frames_dir.display()))?;
    if args.truth {
        std::fs::create_dir_all(args.out.join("truth"))?;
    }
    let mut manifest = rig.session_manifest();
    let mut frame = rig.blank_frame();
    let mut truth = GroundTruth::default();
    let mut progress = Progress::new("simulate", args.frames);
    for i in 0..args.frames {
        rig.render(i as u64, &mut frame, args.truth.then_some(&mut truth))?;
        let file = format!("frames/{i:06}.png");
        write_png(&args.out.join(&file), &frame)?;
        if args.truth {
            let path = args.out.join(format!("truth/{i:06}-depth.tiff"));
            write_depth_tiff(&path, rig.width(), rig.height(), &truth.depth_mm)?;
        }
        manifest.frames.push(FrameJson {
            file,
            time_s: frame.time_s,
            pattern_index: frame.pattern_index,
        });
        progress.step(i + 1);
    }
    progress.finish();
    if args.subject.is_some() || !args.control_points.is_empty() {
        manifest.trial = Some(tremorscan::session::TrialJson {
            subject_id: args.subject.clone().unwrap_or_default(),
            hand: args.hand.clone(),
            condition: args.condition.clone(),
            operator_notes: String::new(),
            date: tremorscan::calibrate::file::utc_now_iso8601(),
            control_points: args.control_points.clone(),
        });
    }
    tremorscan::jsonfile::write_atomic(&args.out.join("session.json"), &manifest)?;
    println!(
        "wrote {}: {} frames of {}×{} at {} FPS, tremor {} Hz, {} mm, sway {} mm, roll {}°",
        args.out.display(),
        args.frames,
        rig.width(),
        rig.height(),
        rig.config.fps,
        args.tremor_hz,
        args.amplitude_mm,
        args.sway_mm,
        args.roll_deg
    );
    Ok(())
}

#[derive(clap::Args, Debug, Clone)]
pub struct DecodeArgs {
    /// Session folder (`cps-session/1`, see docs/formats.md).
    pub session: PathBuf,
    /// The frame that ends the window to decode.
    #[arg(long)]
    pub frame: usize,
    /// Binary PLY of the valid points (mm, camera frame, with colour).
    #[arg(long)]
    pub ply: Option<PathBuf>,
    /// 32-bit float TIFF of camera-frame z in mm, NaN where invalid.
    #[arg(long)]
    pub depth: Option<PathBuf>,
    /// PNG of the decoded scene colour.
    #[arg(long)]
    pub color: Option<PathBuf>,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
}

/// Decodes the window of `session` ending at frame `last` with `params` and triangulates it.
pub fn decode_window(session: &Session, last: usize, params: DecodeParams) -> Result<PointCloud> {
    let sequence = session.sequence()?;
    let len = sequence.entries.len();
    ensure!(
        last < session.frame_count(),
        "frame {last} does not exist (the session has {} frames)",
        session.frame_count()
    );
    ensure!(
        last + 1 >= len,
        "frame {last}: a window needs {len} frames, so the first one ends at frame {}",
        len - 1
    );
    let cross_talk = session
        .cross_talk()?
        .unwrap_or_else(tremorscan::color::CrossTalk::identity);
    let mut decoder = SlidingDecoder::new(sequence, cross_talk, params)?;
    let mut decoded = false;
    for index in last + 1 - len..=last {
        let frame = session.load_frame(index)?;
        match decoder.push(&frame)? {
            WindowOutcome::Decoded(_) => decoded = true,
            WindowOutcome::Filling { .. } => {}
            WindowOutcome::Unsolvable { order } => bail!(
                "the window ending at frame {last} shows patterns {order:?}, which do not make a solvable window"
            ),
            WindowOutcome::TooSpread { span_s, max_span_s } => bail!(
                "the window ending at frame {last} spans {span_s:.4} s, more than {max_span_s:.4} s"
            ),
        }
    }
    let out = decoder
        .output()
        .filter(|_| decoded)
        .context("the window did not decode")?;
    if let Some(refusal) = &out.refused {
        let whole = refusal.rows.len() == out.height;
        let which = if whole {
            "its lit pixels".to_string()
        } else {
            format!(
                "the lit pixels on rows {}–{}",
                refusal.rows.start,
                refusal.rows.end - 1
            )
        };
        bail!(
            "the window ending at frame {last} was refused: {:.0} % of {which} break the phase relation, as a corrupted frame makes them (the neighbouring windows may decode)",
            100.0 * refusal.share
        );
    }
    let triangulator = Triangulator::new(session.stereo_model()?)?;
    let mut cloud = PointCloud::default();
    triangulator.triangulate(out, &mut cloud)?;
    Ok(cloud)
}

pub fn run_decode(args: &DecodeArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let decoding = args
        .unwrap
        .session_decoding(&session, DecodeParams::default())?;
    println!("decode: {}", decoding.describe());
    let cloud = decode_window(&session, args.frame, decoding.params)?;
    let valid = cloud.valid_count();
    let mut depths: Vec<f32> = depth_mm(&cloud)
        .into_iter()
        .filter(|d| d.is_finite())
        .collect();
    depths.sort_by(f32::total_cmp);
    println!(
        "frame {}: window at t = {:.4} s, {valid} valid points ({:.1} % of {}×{}), median depth {:.1} mm",
        args.frame,
        cloud.time_s,
        100.0 * valid as f64 / (cloud.width * cloud.height) as f64,
        cloud.width,
        cloud.height,
        depths.get(depths.len() / 2).copied().unwrap_or(f32::NAN)
    );
    if let Some(path) = &args.ply {
        let n = write_ply(path, &cloud)?;
        println!("wrote {} ({n} points)", path.display());
    }
    if let Some(path) = &args.depth {
        write_depth_tiff(path, cloud.width, cloud.height, &depth_mm(&cloud))?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &args.color {
        write_colour_png(path, &cloud)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

#[derive(clap::Args, Debug, Clone)]
pub struct InfoArgs {
    /// Session folder (`cps-session/1`, see docs/formats.md).
    pub session: PathBuf,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
}

pub fn run_info(args: &InfoArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let m = &session.manifest;
    let (w, h) = session.camera_size();
    println!("session {}", args.session.display());
    println!("  format     {}", m.format);
    println!(
        "  camera     {w}×{h}{}",
        if m.camera.k.is_some() {
            ""
        } else {
            " (not calibrated)"
        }
    );
    println!("  projector  {}×{}", m.projector.width, m.projector.height);
    let coding = session
        .entries
        .iter()
        .filter(|e| matches!(e, SessionEntry::Coding { .. }))
        .count();
    println!(
        "  pattern    {} entries ({coding} coding, {} constant), axis {:?}, {} bit",
        session.entries.len(),
        session.entries.len() - coding,
        m.pattern.axis,
        m.pattern.projector_bits
    );
    if let Some(c) = &session.container {
        println!(
            "  recording  {} ({} complete frames{})",
            c.path.display(),
            c.records.len(),
            c.cut_off
                .as_ref()
                .map_or(String::new(), |why| format!("; cut off: {why}"))
        );
    }
    if let Some(t) = &m.trial {
        println!(
            "  trial      subject {:?}, hand {:?}, condition {:?}, {} control point(s); notes: {:?}",
            t.subject_id,
            t.hand,
            t.condition,
            t.control_points.len(),
            t.operator_notes
        );
    }
    let times: Vec<f64> = m.frames.iter().map(|f| f.time_s).collect();
    let span = times.last().copied().unwrap_or(0.0) - times.first().copied().unwrap_or(0.0);
    let rate = if span > 0.0 {
        (times.len() - 1) as f64 / span
    } else {
        0.0
    };
    println!(
        "  frames     {} over {span:.3} s ({rate:.1} FPS)",
        m.frames.len()
    );
    let backwards = times.windows(2).filter(|t| t[1] <= t[0]).count();
    if backwards > 0 {
        println!("  warning: {backwards} frame(s) not later than the one before");
    }
    let measurement = session
        .stereo_model()
        .map(|_| ())
        .and(session.sequence().map(|_| ()));
    match &measurement {
        Ok(()) => {
            println!("  use        measurement (calibrated, one coding axis)");
            // A sequence no method can unwrap is reported, not fatal: the frames are still
            // checked below.
            match args
                .unwrap
                .session_decoding(&session, DecodeParams::default())
            {
                Ok(decoding) => println!("  decode     {}", decoding.describe()),
                Err(e) => println!("  decode     impossible: {e:#}"),
            }
        }
        Err(e) => println!("  use        calibration only: {e}"),
    }
    let mut progress = Progress::new("checking frames", m.frames.len());
    for i in 0..m.frames.len() {
        session.load_frame(i)?;
        progress.step(i + 1);
    }
    progress.finish();
    println!("verdict: VALID ({} frames read)", m.frames.len());
    Ok(())
}
