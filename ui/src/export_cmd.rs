//! `tremorscan export-bids`, `export-c3d` and `export`: one session's control-point
//! trajectories as Motion-BIDS or C3D (in the table frame, as `batch` writes them), and its
//! decoded windows as a PLY or float-TIFF sequence.
//!
//! The control points are the session's saved ones (`session.json`'s trial) plus `--point`. The
//! cloud sequence decodes the frames in order with one sliding decoder (so the motion model
//! sees the stream as the live pipeline does), starting far enough back that the window ending
//! at `--from` is the first written; each window's files are named after its last frame.

use crate::batch_cmd::software_version;
use crate::progress::Progress;
use crate::session_tracking::{track_session, Feedback, SessionTracks};
use crate::tremor_cmd::parse_point;
use crate::unwrap_args::UnwrapArgs;
use anyhow::{bail, ensure, Context, Result};
use std::path::{Path, PathBuf};
use tremorscan::decode::{DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::export::bids::{self, BidsName};
use tremorscan::export::{depth_mm, write_depth_tiff, write_ply};
use tremorscan::session::{Session, TrialJson};
use tremorscan::triangulate::{PointCloud, Triangulator};

/// The control points of an export.
#[derive(clap::Args, Debug, Clone)]
pub struct ExportPointArgs {
    /// A control point `U,V` added to the session's saved ones (repeat for more).
    #[arg(long = "point", value_parser = parse_point)]
    pub points: Vec<(f64, f64)>,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
    #[command(flatten)]
    pub mode: crate::session_tracking::PointModeArgs,
}

#[derive(clap::Args, Debug, Clone)]
pub struct ExportBidsArgs {
    /// Session folder.
    pub session: PathBuf,
    /// The BIDS dataset's root (created if missing; other trials in it are kept).
    #[arg(long)]
    pub bids_root: PathBuf,
    #[command(flatten)]
    pub points: ExportPointArgs,
}

#[derive(clap::Args, Debug, Clone)]
pub struct ExportC3dArgs {
    /// Session folder.
    pub session: PathBuf,
    /// The C3D file to write (`.c3d`).
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub points: ExportPointArgs,
}

#[derive(clap::Args, Debug, Clone)]
pub struct ExportArgs {
    /// Session folder.
    pub session: PathBuf,
    /// Write each window's point cloud as `cloud-FFFFFF.ply` in this folder.
    #[arg(long, required_unless_present = "depth_tiffs")]
    pub clouds: Option<PathBuf>,
    /// Write each window's depth map (mm, float, NaN where invalid) as `depth-FFFFFF.tiff` in
    /// this folder: a sequence Fiji opens as a stack.
    #[arg(long)]
    pub depth_tiffs: Option<PathBuf>,
    /// The first window to write, by its last frame (default: the first full window).
    #[arg(long)]
    pub from: Option<usize>,
    /// The last window to write, by its last frame (default: the session's last frame).
    #[arg(long)]
    pub to: Option<usize>,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
}

/// A session's control points: its saved ones, then those given with `--point`.
pub struct ControlPoints {
    pub names: Vec<String>,
    pub pixels: Vec<(f64, f64)>,
}

impl ControlPoints {
    /// The points of `trial` and `extra`; an error when there are none.
    pub fn of(trial: &TrialJson, extra: &[(f64, f64)]) -> Result<Self> {
        let mut names: Vec<String> = trial
            .control_points
            .iter()
            .map(|p| p.name.clone())
            .collect();
        let mut pixels: Vec<(f64, f64)> = trial.control_points.iter().map(|p| (p.u, p.v)).collect();
        for &(u, v) in extra {
            names.push(format!("point ({u}, {v})"));
            pixels.push((u, v));
        }
        ensure!(
            !pixels.is_empty(),
            "no control points: session.json's trial has none, and no --point was given"
        );
        Ok(Self { names, pixels })
    }
}

/// Opens and tracks a session for the trajectory exports.
fn tracked(
    session_dir: &Path,
    args: &ExportPointArgs,
) -> Result<(Session, TrialJson, Vec<String>, SessionTracks)> {
    let session = Session::open(session_dir)?;
    let trial = session.manifest.trial.clone().unwrap_or_default();
    let ControlPoints { names, pixels } = ControlPoints::of(&trial, &args.points)?;
    let decoding = args
        .unwrap
        .session_decoding(&session, DecodeParams::default())?;
    println!("decode: {}", decoding.describe());
    let tracks = track_session(
        &session,
        &pixels,
        args.mode.mode(),
        None,
        decoding.params,
        Feedback::ProgressBar,
    )?;
    Ok((session, trial, names, tracks))
}

pub fn run_export_bids(args: &ExportBidsArgs) -> Result<()> {
    let (_, trial, names, tracks) = tracked(&args.session, &args.points)?;
    let run = bids::next_free_run(&args.bids_root, &trial).map_err(anyhow::Error::msg)?;
    let name = BidsName::of(&trial, run).map_err(anyhow::Error::msg)?;
    let motion = tracks.motion(&names);
    let version = software_version();
    let file = bids::write_trial(&args.bids_root, &name, &trial, &motion, &version)?;
    bids::write_dataset_files(
        &args.bids_root,
        std::slice::from_ref(&name.subject),
        &version,
    )?;
    println!(
        "wrote {} ({} samples of {} points, {} frame)",
        file.display(),
        motion.samples(),
        motion.points.len(),
        motion.frame.name()
    );
    Ok(())
}

pub fn run_export_c3d(args: &ExportC3dArgs) -> Result<()> {
    let (_, _, names, tracks) = tracked(&args.session, &args.points)?;
    let motion = tracks.motion(&names);
    let frames = tremorscan::export::c3d::write_c3d(&args.out, &motion)?;
    println!(
        "wrote {} ({frames} frames of {} markers, {} frame)",
        args.out.display(),
        motion.points.len(),
        motion.frame.name()
    );
    Ok(())
}

pub fn run_export(args: &ExportArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let sequence = session.sequence()?;
    let len = sequence.entries.len();
    let count = session.frame_count();
    ensure!(
        count >= len,
        "the session has {count} frames, fewer than one window ({len})"
    );
    let from = args.from.unwrap_or(len - 1);
    let to = args.to.unwrap_or(count - 1);
    ensure!(
        from + 1 >= len && from <= to && to < count,
        "--from {from} --to {to}: windows end at frames {} to {} of this session",
        len - 1,
        count - 1
    );
    for dir in [&args.clouds, &args.depth_tiffs].into_iter().flatten() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let decoding = args
        .unwrap
        .session_decoding(&session, DecodeParams::default())?;
    println!("decode: {}", decoding.describe());
    let cross_talk = session
        .cross_talk()?
        .unwrap_or_else(tremorscan::color::CrossTalk::identity);
    let fps = session.frame_rate_hz();
    let mut decoder = SlidingDecoder::new(sequence, cross_talk, decoding.params)?
        .with_max_span((len as f64 - 0.5) / fps.max(1e-3));
    let triangulator = Triangulator::new(session.stereo_model()?)?;
    let mut cloud = PointCloud::default();
    // Start a few windows early so the motion model has the stream's past at `from`.
    let start = (from + 1 - len).saturating_sub(2 * len);
    let mut progress = Progress::new("exporting", to + 1 - start);
    let (mut written, mut refused) = (0usize, Vec::new());
    for i in start..=to {
        let frame = session.load_frame(i)?;
        let outcome = decoder.push(&frame)?;
        progress.step(i + 1 - start);
        if i < from {
            continue;
        }
        match outcome {
            WindowOutcome::Decoded(out) => triangulator.triangulate(out, &mut cloud)?,
            WindowOutcome::Filling { .. } => continue,
            _ => {
                refused.push(i);
                continue;
            }
        }
        if let Some(dir) = &args.clouds {
            write_ply(&dir.join(format!("cloud-{i:06}.ply")), &cloud)?;
        }
        if let Some(dir) = &args.depth_tiffs {
            write_depth_tiff(
                &dir.join(format!("depth-{i:06}.tiff")),
                cloud.width,
                cloud.height,
                &depth_mm(&cloud),
            )?;
        }
        written += 1;
    }
    progress.finish();
    if written == 0 {
        bail!("no window from frame {from} to {to} decoded");
    }
    println!(
        "wrote {written} windows (frames {from}–{to}){}",
        if refused.is_empty() {
            String::new()
        } else {
            format!(
                "; {} windows did not decode (their frames do not make a window) and have no files: {:?}",
                refused.len(),
                refused
            )
        }
    );
    Ok(())
}
