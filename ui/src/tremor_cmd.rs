//! `tremorscan track` and `analyze`: control points tracked through every window of a session,
//! written as CSV, and their clinical tremor figures as JSON (the tracking itself is
//! `session_tracking`, the figures `point_analysis`).

use crate::point_analysis::{analyze_tracks, PointOutcome};
use crate::session_tracking::{track_session, Feedback, PointModeArgs, SessionTracks};
use crate::unwrap_args::UnwrapArgs;
use anyhow::{Context, Result};
use nalgebra::Vector3;
use std::io::Write;
use std::path::PathBuf;
use tremorscan::decode::{frames_averaged, DecodeParams};
use tremorscan::session::Session;
use tremorscan::tremor::{
    displacements, pixel_of, AnalysisOptions, DisplacementAxis, MissingSamples, PointMode,
    TrackSample,
};

/// The control points and the vertical axis, shared by `track` and `analyze`.
#[derive(clap::Args, Debug, Clone)]
pub struct ControlPointArgs {
    /// Control point as camera pixel `U,V` (repeat for more points).
    #[arg(long = "point", value_parser = parse_point, required_unless_present = "points_mm")]
    pub points: Vec<(f64, f64)>,
    /// Control point as a 3D point `X,Y,Z` in the camera frame, mm (repeat for more).
    #[arg(long = "point-mm", value_parser = parse_point_mm, allow_hyphen_values = true)]
    pub points_mm: Vec<[f64; 3]>,
    /// Vertical axis: `X,Y,Z` in the camera frame, or `table` for the fitted table normal
    /// (default: the camera's optical axis).
    #[arg(long, allow_hyphen_values = true)]
    pub vertical: Option<String>,
    #[command(flatten)]
    pub unwrap: UnwrapArgs,
    #[command(flatten)]
    pub mode: PointModeArgs,
    /// The direction displacements and figures are taken along: the vertical axis
    /// (`--vertical`), the principal axis of each point's band-passed 3D motion, or camera x,
    /// y or z.
    #[arg(long, value_enum, default_value_t = AxisArg::Vertical)]
    pub axis: AxisArg,
}

/// `--axis` values.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisArg {
    Vertical,
    Principal,
    X,
    Y,
    Z,
}

impl AxisArg {
    pub fn axis(self) -> DisplacementAxis {
        match self {
            AxisArg::Vertical => DisplacementAxis::Vertical,
            AxisArg::Principal => DisplacementAxis::Principal,
            AxisArg::X => DisplacementAxis::X,
            AxisArg::Y => DisplacementAxis::Y,
            AxisArg::Z => DisplacementAxis::Z,
        }
    }
}

#[derive(clap::Args, Debug, Clone)]
pub struct TrackArgs {
    /// Session folder (`cps-session/1`, see docs/formats.md).
    pub session: PathBuf,
    #[command(flatten)]
    pub control: ControlPointArgs,
    /// CSV output: time_s,frame,point,u,v,x_mm,y_mm,z_mm,displacement_mm,valid (u,v: the
    /// pixel measured at, which moves with the skin; empty where the point was lost).
    #[arg(long)]
    pub csv: PathBuf,
}

#[derive(clap::Args, Debug, Clone)]
pub struct AnalyzeArgs {
    /// Session folder (`cps-session/1`, see docs/formats.md).
    pub session: PathBuf,
    #[command(flatten)]
    pub control: ControlPointArgs,
    /// JSON output, one object per point.
    #[arg(long)]
    pub json: PathBuf,
    /// Also write the report figure (displacement and spectrum per point) as PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

pub fn parse_point(text: &str) -> Result<(f64, f64), String> {
    let (u, v) = text
        .split_once(',')
        .ok_or_else(|| format!("`{text}`: expected U,V"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<f64>()
            .map_err(|e| format!("`{text}`: {e}"))
    };
    Ok((parse(u)?, parse(v)?))
}

fn parse_point_mm(text: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<f64>()
                .map_err(|e| format!("`{text}`: {e}"))
        })
        .collect::<Result<_, _>>()?;
    <[f64; 3]>::try_from(v).map_err(|_| format!("`{text}`: expected X,Y,Z"))
}

/// The pixels of all control points: those given as pixels, then the 3D ones projected.
fn all_pixels(session: &Session, control: &ControlPointArgs) -> Result<Vec<(f64, f64)>> {
    let mut all = control.points.clone();
    if !control.points_mm.is_empty() {
        let camera = session.camera()?;
        for p in &control.points_mm {
            all.push(pixel_of(*p, &camera).with_context(|| {
                format!("point {:?} mm does not project into the camera image", p)
            })?);
        }
    }
    Ok(all)
}

/// One control point's samples and the unit axis its displacement is taken along, for
/// [`track_csv`].
pub struct TrackColumn<'a> {
    pub name: String,
    pub samples: &'a [TrackSample],
    pub axis: Vector3<f64>,
}

/// The track as CSV: one row per sample and point, displacement along the point's axis; empty
/// cells where the point was not measured.
pub fn track_csv(points: &[TrackColumn<'_>]) -> String {
    let mut out = String::from("time_s,frame,point,u,v,x_mm,y_mm,z_mm,displacement_mm,valid\n");
    let fmt = |v: f64| {
        if v.is_finite() {
            format!("{v:.4}")
        } else {
            String::new()
        }
    };
    for p in points {
        let d = displacements(p.samples, &p.axis);
        for (s, d) in p.samples.iter().zip(d) {
            let [x, y, z] = s.position_mm.map_or([f64::NAN; 3], |p| p);
            let (u, v) = s.pixel.unwrap_or((f64::NAN, f64::NAN));
            out.push_str(&format!(
                "{:.6},{},{},{},{},{},{},{},{},{}\n",
                s.time_s,
                s.frame,
                p.name.replace(',', " "),
                fmt(u),
                fmt(v),
                fmt(x),
                fmt(y),
                fmt(z),
                d.map_or(String::new(), fmt),
                u8::from(s.position_mm.is_some())
            ));
        }
    }
    out
}

/// How `session` is decoded for tracking, printed.
fn decoding_of(session: &Session, control: &ControlPointArgs) -> Result<DecodeParams> {
    let decoding = control
        .unwrap
        .session_decoding(session, DecodeParams::default())?;
    println!("decode: {}", decoding.describe());
    Ok(decoding.params)
}

pub fn run_track(args: &TrackArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let points = all_pixels(&session, &args.control)?;
    let params = decoding_of(&session, &args.control)?;
    let SessionTracks { tracks, axis, .. } = track_session(
        &session,
        &points,
        args.control.mode.mode(),
        args.control.vertical.as_deref(),
        params,
        Feedback::ProgressBar,
    )?;
    let named: Vec<TrackColumn<'_>> = tracks
        .iter()
        .enumerate()
        .map(|(k, track)| {
            let unit = args
                .control
                .axis
                .axis()
                .unit(&axis, track, &AnalysisOptions::default())
                .with_context(|| {
                    format!("point {k}: too little was measured for a principal axis")
                })?;
            Ok(TrackColumn {
                name: k.to_string(),
                samples: track,
                axis: unit,
            })
        })
        .collect::<Result<_>>()?;
    let out = track_csv(&named);
    for (k, (track, &(u, v))) in tracks.iter().zip(&points).enumerate() {
        let valid = track.iter().filter(|s| s.position_mm.is_some()).count();
        println!(
            "point {k} ({u}, {v}): {valid} of {} samples valid",
            track.len()
        );
    }
    std::fs::File::create(&args.csv)
        .and_then(|mut f| f.write_all(out.as_bytes()))
        .with_context(|| format!("writing {}", args.csv.display()))?;
    println!(
        "vertical axis ({:.4}, {:.4}, {:.4}); wrote {}",
        axis.x,
        axis.y,
        axis.z,
        args.csv.display()
    );
    Ok(())
}

pub fn run_analyze(args: &AnalyzeArgs) -> Result<()> {
    let session = Session::open(&args.session)?;
    let points = all_pixels(&session, &args.control)?;
    let params = decoding_of(&session, &args.control)?;
    let tracked = track_session(
        &session,
        &points,
        args.control.mode.mode(),
        args.control.vertical.as_deref(),
        params,
        Feedback::ProgressBar,
    )?;
    let names: Vec<String> = points
        .iter()
        .map(|(u, v)| format!("point ({u}, {v})"))
        .collect();
    let outcomes = analyze_tracks(
        frames_averaged(&session.sequence()?, &params),
        &tracked.tracks,
        &tracked.axis,
        &names,
        &points,
        args.control.axis.axis(),
    )?;
    for o in &outcomes {
        match &o.report {
            Ok(r) => println!(
                "{}: peak {} Hz, peak-to-peak {:.3} mm, RMS {:.3} mm, occupancy {:.0} %, MDS-UPDRS amplitude bin {}, {} % valid",
                o.name,
                r.peak_frequency_hz.map_or("none".to_string(), |f| format!("{f:.3}")),
                r.amplitude_peak_to_peak_mm,
                r.amplitude_rms_mm,
                100.0 * r.occupancy,
                r.updrs_amplitude_bin,
                (100.0 * r.valid_fraction).round()
            ),
            Err(why) => println!("{}: {why}", o.name),
        }
    }
    // Where a followed point's samples went missing, say why: the skin not found (a weak
    // match: docs/accuracy.md, the fingertip followed on the skin) or no depth under it.
    if args.control.mode.mode() == PointMode::FollowSkin {
        for (o, track) in outcomes.iter().zip(&tracked.tracks) {
            let m = MissingSamples::of(track);
            if m.not_found > 0 {
                println!(
                    "{}: {} (a point placed a little way in from the fingertip's rounded end follows better; --fixed-pixel measures at the pixel instead)",
                    o.name,
                    m.followed_summary()
                );
            }
        }
    }
    if let Some(png) = &args.png {
        let figures: Vec<_> = outcomes.iter().map(PointOutcome::figure).collect();
        crate::report_png::write_report(png, &figures)
            .with_context(|| format!("writing {}", png.display()))?;
        println!("wrote {}", png.display());
    }
    let objects: Vec<serde_json::Value> = outcomes.iter().map(|o| o.json(&tracked.axis)).collect();
    tremorscan::jsonfile::write_atomic(&args.json, &objects)?;
    println!("wrote {}", args.json.display());
    Ok(())
}
