//! `tremorscan calibrate-color`, `calibrate-geometric` and `import-calibration`: the
//! calibrations run headless over recorded `cps-session/1` folders, each printing a summary
//! with a verdict and failing (non-zero exit, one-line cause) when it cannot deliver.

use anyhow::{bail, ensure, Context, Result};
use std::path::PathBuf;
use tremorscan::calibrate::{
    calibrate_colour, calibrate_geometric, import_opencv, observe_capture, BoardSpec,
    CalibrationCapture, CalibrationFile, ColourFile, ColourOptions, GeometricOptions,
    LocalFitOptions, Roi, ViewObservation, TABLE1_LEVELS,
};
use tremorscan::color::CrossTalk;
use tremorscan::geometry::LensModel;
use tremorscan::pattern::Axis;
use tremorscan::session::manifest::{ColorJson, ExtrinsicsJson, LensJson, PatternJson};
use tremorscan::session::{Session, SessionEntry};

#[derive(clap::Args, Debug, Clone)]
pub struct CalibrateColorArgs {
    /// Session holding the ten Table 1 captures (constant entries) of a white target.
    pub session: PathBuf,
    /// Output colour file (JSON: A, b, rms_residual).
    #[arg(long)]
    pub out: PathBuf,
    /// Region of interest `x,y,w,h` in camera pixels (default: a centred square a tenth of the
    /// image's shorter side).
    #[arg(long, value_delimiter = ',', num_args = 4)]
    pub roi: Option<Vec<usize>>,
}

pub fn run_color(args: &CalibrateColorArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let mut captures = Vec::with_capacity(TABLE1_LEVELS.len());
    for levels in TABLE1_LEVELS {
        let wanted = levels.map(f64::from);
        let frame_index = session
            .manifest
            .frames
            .iter()
            .position(|f| session.entries[f.pattern_index] == SessionEntry::Constant(wanted))
            .with_context(|| {
                format!("no frame shows the constant colour {levels:?}; Table 1 needs all ten")
            })?;
        captures.push(session.load_frame(frame_index)?);
    }
    let (w, h) = session.camera_size();
    let roi = match &args.roi {
        Some(r) => Roi {
            x: r[0],
            y: r[1],
            width: r[2],
            height: r[3],
        },
        None => {
            let side = (w.min(h) / 10).max(4);
            Roi {
                x: (w - side) / 2,
                y: (h - side) / 2,
                width: side,
                height: side,
            }
        }
    };
    let options = ColourOptions {
        roi,
        samples: 10_000,
        saturation_level: 250,
        seed: 1,
    };
    let result = calibrate_colour(&captures, &options).context("colour calibration")?;
    let a = result.cross_talk.a;
    println!("colour calibration of {}", args.session.display());
    println!("  region of interest  {roi:?}");
    for r in 0..3 {
        println!(
            "  A[{r}] = [{:8.4} {:8.4} {:8.4}]    b[{r}] = {:6.2}",
            a[(r, 0)],
            a[(r, 1)],
            a[(r, 2)],
            result.cross_talk.b_gray[r]
        );
    }
    println!("  residual RMS        {:.3} gray", result.residual_rms_gray);
    for warning in &result.warnings {
        println!("  warning: {warning}");
    }
    ColourFile::new(&result.cross_talk, result.residual_rms_gray).save(&args.out)?;
    if result.warnings.is_empty() {
        println!("verdict: GOOD; written to {}", args.out.display());
    } else {
        println!(
            "verdict: USABLE WITH {} WARNING(S), see above; written to {}",
            result.warnings.len(),
            args.out.display()
        );
    }
    Ok(())
}

#[derive(clap::Args, Debug, Clone)]
pub struct CalibrateGeometricArgs {
    /// One session per board pose: a constant black entry (room light, projector dark) and the
    /// column and row coding entries.
    #[arg(required = true)]
    pub sessions: Vec<PathBuf>,
    /// Inner corners of the board, `COLSxROWS` (e.g. 9x6).
    #[arg(long)]
    pub board: String,
    /// Square size, mm.
    #[arg(long)]
    pub square_mm: f64,
    /// Output calibration file.
    #[arg(long)]
    pub out: PathBuf,
    /// Colour file from `calibrate-color` (otherwise the sessions' own `color`, else none).
    #[arg(long)]
    pub color: Option<PathBuf>,
    /// Views to leave out, by their position among SESSIONS (0 = first), comma separated.
    #[arg(long, value_delimiter = ',')]
    pub drop: Vec<usize>,
    /// Text naming the rig, stored in the file.
    #[arg(long, default_value = "unnamed rig")]
    pub rig: String,
}

fn parse_board(text: &str, square_mm: f64) -> Result<BoardSpec> {
    let (c, r) = text
        .split_once(['x', 'X'])
        .with_context(|| format!("--board {text}: expected COLSxROWS, e.g. 9x6"))?;
    let cols: usize = c
        .trim()
        .parse()
        .with_context(|| format!("--board {text}"))?;
    let rows: usize = r
        .trim()
        .parse()
        .with_context(|| format!("--board {text}"))?;
    ensure!(
        cols >= 2 && rows >= 2,
        "--board {text}: needs at least 2x2 inner corners"
    );
    ensure!(
        square_mm > 0.0 && square_mm.is_finite(),
        "--square-mm must be positive"
    );
    Ok(BoardSpec {
        cols,
        rows,
        square_mm,
    })
}

/// The capture of one pose session: the black constant frame and one frame per coding entry.
fn capture_of(session: &Session) -> Result<CalibrationCapture> {
    let first_frame_of = |entry: usize| {
        session
            .manifest
            .frames
            .iter()
            .position(|f| f.pattern_index == entry)
    };
    let black = session
        .entries
        .iter()
        .position(|e| *e == SessionEntry::Constant([0.0; 3]))
        .and_then(first_frame_of)
        .context("no frame with the projector dark (constant [0, 0, 0]) for the board image")?;
    let frames_of = |axis: Axis| -> Result<_> {
        let (sequence, indices) = session.coding_sequence(axis)?;
        let frames = indices
            .iter()
            .enumerate()
            .map(|(position, &i)| {
                let f = first_frame_of(i)
                    .with_context(|| format!("no frame shows pattern.sequence[{i}]"))?;
                let mut frame = session.load_frame(f)?;
                // Index within this axis's own sequence.
                frame.pattern_index = position;
                Ok(frame)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((sequence, frames))
    };
    let (column_sequence, column_frames) = frames_of(Axis::Columns)?;
    let (row_sequence, row_frames) = frames_of(Axis::Rows)?;
    Ok(CalibrationCapture {
        ambient: session.load_frame(black)?,
        column_sequence,
        column_frames,
        row_sequence,
        row_frames,
    })
}

pub fn run_geometric(args: &CalibrateGeometricArgs) -> Result<()> {
    let board = parse_board(&args.board, args.square_mm)?;
    let sessions = args
        .sessions
        .iter()
        .map(|p| Session::open(p).with_context(|| format!("opening {}", p.display())))
        .collect::<Result<Vec<_>>>()?;
    let (camera_size, projector_size) = (sessions[0].camera_size(), sessions[0].projector_size());
    for (s, path) in sessions.iter().zip(&args.sessions) {
        ensure!(
            s.camera_size() == camera_size && s.projector_size() == projector_size,
            "{}: camera or projector size differs from the first session",
            path.display()
        );
    }
    let cross_talk: CrossTalk = match &args.color {
        Some(path) => ColourFile::load(path)?.1,
        None => match sessions[0].cross_talk()? {
            Some(c) => c,
            None => {
                println!("note: no colour calibration given (--color); decoding without cross-talk correction");
                CrossTalk::identity()
            }
        },
    };
    println!(
        "geometric calibration: {} views, board {}x{} of {} mm",
        sessions.len(),
        board.cols,
        board.rows,
        board.square_mm
    );
    // A view that cannot be used is reported and left out, as if dropped.
    let mut observations = Vec::with_capacity(sessions.len());
    let mut excluded = args.drop.clone();
    for (k, (session, path)) in sessions.iter().zip(&args.sessions).enumerate() {
        let seen = capture_of(session).and_then(|capture| {
            Ok(observe_capture(
                k,
                &capture,
                &board,
                cross_talk,
                &LocalFitOptions::default(),
            )?)
        });
        match seen {
            Ok(o) => observations.push(o),
            Err(e) => {
                println!("  view {k:2} {}: skipped: {e:#}", path.display());
                observations.push(ViewObservation {
                    camera_px: Vec::new(),
                    projector_px: Vec::new(),
                });
                excluded.push(k);
            }
        }
    }
    excluded.sort_unstable();
    excluded.dedup();
    let options = GeometricOptions {
        excluded_views: excluded,
        ..GeometricOptions::default()
    };
    let calib = calibrate_geometric(&board, &observations, camera_size, projector_size, &options)?;
    println!("  view  camera RMS px  projector RMS px  projector corners");
    for v in &calib.views {
        println!(
            "  {:4}  {:13.3}  {:16.3}  {:17}",
            v.view, v.camera_rms_px, v.projector_rms_px, v.projector_corners
        );
    }
    let u = calib.uncertainty;
    let show = |name: &str, lens: &LensModel, sigma: [f64; 4]| {
        let k = lens.intrinsics;
        let d = lens.distortion;
        println!(
            "  {name:9} fx {:.2} ± {:.2}  fy {:.2} ± {:.2}  cx {:.2} ± {:.2}  cy {:.2} ± {:.2}  dist [{:.4} {:.4} {:.5} {:.5} {:.4}]",
            k.fx, sigma[0], k.fy, sigma[1], k.cx, sigma[2], k.cy, sigma[3], d.k1, d.k2, d.p1, d.p2, d.k3
        );
    };
    show("camera", &calib.camera, u.camera);
    show("projector", &calib.projector, u.projector);
    println!(
        "  baseline {:.3} ± {:.3} mm; RMS camera {:.3} px, projector {:.3} px; {} outlier observation(s) dropped",
        calib.baseline_mm(),
        u.baseline_mm,
        calib.camera_rms_px,
        calib.projector_rms_px,
        calib.dropped_observations
    );
    let worst = calib.camera_rms_px.max(calib.projector_rms_px);
    if worst > 1.0 {
        bail!(
            "reprojection RMS {worst:.2} px is above 1 px: the calibration is not usable (drop the worst views with --drop, or recapture)"
        );
    }
    let pattern = sessions[0]
        .coding_sequence(Axis::Columns)
        .ok()
        .map(|(seq, _)| PatternJson::from_sequence(&seq));
    let file = CalibrationFile::from_geometric(&calib, Some(&cross_talk), &args.rig, pattern);
    file.save(&args.out)?;
    let verdict = if worst < 0.3 { "GOOD" } else { "ACCEPTABLE" };
    println!(
        "verdict: {verdict} (RMS {worst:.3} px); written to {}",
        args.out.display()
    );
    Ok(())
}

#[derive(clap::Args, Debug, Clone)]
pub struct ImportCalibrationArgs {
    /// OpenCV FileStorage file (YAML or XML) with camera, projector and stereo matrices.
    pub file: PathBuf,
    /// Camera image size `WxH` (FileStorage files do not carry it).
    #[arg(long)]
    pub camera_size: String,
    /// Projector size `WxH`.
    #[arg(long, default_value = "912x1140")]
    pub projector_size: String,
    #[arg(long)]
    pub out: PathBuf,
}

fn parse_size(text: &str) -> Result<(usize, usize)> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .with_context(|| format!("size {text}: expected WxH"))?;
    Ok((w.trim().parse()?, h.trim().parse()?))
}

pub fn run_import(args: &ImportCalibrationArgs) -> Result<()> {
    let calib = import_opencv(
        &args.file,
        parse_size(&args.camera_size)?,
        parse_size(&args.projector_size)?,
    )?;
    let file = CalibrationFile {
        format: tremorscan::calibrate::CALIBRATION_FORMAT.to_string(),
        created_utc: tremorscan::calibrate::file::utc_now_iso8601(),
        rig: format!("imported from {}", args.file.display()),
        pattern: None,
        camera: LensJson::from_lens(&calib.camera),
        projector: LensJson::from_lens(&calib.projector),
        extrinsics: ExtrinsicsJson::from_pose(&calib.projector_from_camera),
        color: calib.cross_talk.as_ref().map(ColorJson::from_cross_talk),
        rms: None,
    };
    file.save(&args.out)?;
    println!(
        "imported {}: camera fx {:.2}, projector fx {:.2}, baseline {:.2} mm; written to {}",
        args.file.display(),
        calib.camera.intrinsics.fx,
        calib.projector.intrinsics.fx,
        calib.projector_from_camera.inverse().translation_mm.norm(),
        args.out.display()
    );
    Ok(())
}
