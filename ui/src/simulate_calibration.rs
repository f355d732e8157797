//! `tremorscan simulate-calibration`: calibration sessions from the virtual rig, exactly as an
//! operator records them at a real rig: `colour/` (the ten Table 1 constant colours on a white
//! target) and `view-NN/` (a chessboard pose: room light with the projector dark, then the column
//! and the row coding patterns). The sessions carry no calibration: that is what they are for.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use tremorscan::calibrate::TABLE1_LEVELS;
use tremorscan::frame::Frame;
use tremorscan::pattern::{Axis, PatternSequence};
use tremorscan::rig::captures::{
    colour_target, render_capture, render_colour_captures, standard_poses,
};
use tremorscan::rig::RigConfig;
use tremorscan::session::manifest::{AxisJson, LensJson, PatternJson};
use tremorscan::session::{entries_json, write_session, Manifest, SessionEntry, SESSION_FORMAT};

#[derive(clap::Args, Debug, Clone)]
pub struct SimulateCalibrationArgs {
    /// Folder to create the sessions in.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 960)]
    pub width: usize,
    #[arg(long, default_value_t = 600)]
    pub height: usize,
    /// Board poses (at most 12).
    #[arg(long, default_value_t = 12)]
    pub views: usize,
}

fn manifest(config: &RigConfig, entries: &[SessionEntry], pattern: &PatternSequence) -> Manifest {
    let bare = |w, h| LensJson {
        width: w,
        height: h,
        k: None,
        dist: None,
    };
    Manifest {
        format: SESSION_FORMAT.to_string(),
        pattern: PatternJson {
            x_max: pattern.x_max,
            axis: AxisJson::from(pattern.axis),
            projector_bits: pattern.projector_bits,
            sequence: entries_json(entries, pattern.axis, pattern.x_max),
        },
        color: None,
        camera: bare(config.camera.width, config.camera.height),
        projector: bare(config.projector.width, config.projector.height),
        extrinsics: None,
        frames: Vec::new(),
        recording: None,
        trial: None,
        camera_noise_gray: None,
    }
}

fn write(dir: &Path, manifest: Manifest, frames: &[Frame]) -> Result<()> {
    write_session(dir, manifest, frames).with_context(|| format!("writing {}", dir.display()))
}

pub fn run(args: &SimulateCalibrationArgs) -> Result<()> {
    let config = RigConfig::paper(args.width, args.height).context("rig configuration")?;
    let columns = config.default_sequence()?;
    // Colour session.
    let colour_config = colour_target(&config, 3.0)?;
    let mut frames = render_colour_captures(&colour_config)?;
    for (i, f) in frames.iter_mut().enumerate() {
        f.pattern_index = i;
        f.time_s = i as f64 / config.fps;
    }
    let entries: Vec<SessionEntry> = TABLE1_LEVELS
        .iter()
        .map(|l| SessionEntry::Constant(l.map(f64::from)))
        .collect();
    let colour_dir = args.out.join("colour");
    write(&colour_dir, manifest(&config, &entries, &columns), &frames)?;
    println!("wrote {} (10 Table 1 captures)", colour_dir.display());
    // Geometric sessions, one per pose.
    let poses = standard_poses();
    for (k, board) in poses.into_iter().take(args.views).enumerate() {
        let (capture, _) = render_capture(&config, board, k as u64)?;
        let mut entries = vec![SessionEntry::Constant([0.0; 3])];
        entries.extend(SessionEntry::coding_entries(&capture.column_sequence));
        entries.extend(SessionEntry::coding_entries(&capture.row_sequence));
        let mut frames = vec![capture.ambient];
        frames.extend(capture.column_frames);
        frames.extend(capture.row_frames);
        for (i, f) in frames.iter_mut().enumerate() {
            f.pattern_index = i;
            f.time_s = i as f64 / config.fps;
        }
        let dir = args.out.join(format!("view-{k:02}"));
        debug_assert_eq!(capture.column_sequence.axis, Axis::Columns);
        write(
            &dir,
            manifest(&config, &entries, &capture.column_sequence),
            &frames,
        )?;
        println!("wrote {} (board pose {k})", dir.display());
    }
    Ok(())
}
