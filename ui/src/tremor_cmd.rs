//! `tremorscan track` and `analyze`: control points tracked through every window of a session,
//! written as CSV, and their clinical tremor figures as JSON (the tracking itself is
//! `session_tracking`).

use crate::session_tracking::{track_session, Feedback, PointModeArgs, SessionTracks};
use crate::unwrap_args::UnwrapArgs;
use anyhow::{Context, Result};
use nalgebra::Vector3;
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use tremorscan::decode::{frames_averaged, DecodeParams};
use tremorscan::session::Session;
use tremorscan::tremor::measures::{coherence, COHERENCE_BAND_HZ};
use tremorscan::tremor::spectrum::resample;
use tremorscan::tremor::{
    analyze, displacements, pixel_of, principal_axis, summed_spectrum_peak, AnalysisOptions,
    DisplacementAxis, TrackSample, TremorError, TremorReport,
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

/// The JSON object of one point's tremor figures.
pub fn report_json(pixel: (f64, f64), r: &TremorReport, axis: &Vector3<f64>) -> serde_json::Value {
    json!({
        "pixel": [pixel.0, pixel.1],
        "valid_fraction": r.valid_fraction,
        "longest_gap_s": r.longest_gap_s,
        "duration_s": r.duration_s,
        "peak_frequency_hz": r.peak_frequency_hz,
        "peaks_hz": r.peaks_hz,
        "amplitude_peak_to_peak_mm": r.amplitude_peak_to_peak_mm,
        "amplitude_peak_to_peak_cm": r.amplitude_peak_to_peak_mm / 10.0,
        "amplitude_rms_mm": r.amplitude_rms_mm,
        "band_power_3_12": r.band_power_mm2,
        "band_power_4_6": r.narrow_band_power_mm2,
        "occupancy": r.occupancy,
        "frequency_stability": r.frequency_stability_hz,
        "updrs_amplitude_bin": r.updrs_amplitude_bin,
        "tetras_amplitude_rating": r.tetras_amplitude_rating,
        "tremor_stability_index_hz": r.tremor_stability_index_hz,
        "half_power_bandwidth_hz": r.half_power_bandwidth_hz,
        "harmonic_relative_power": r.harmonic_relative_power,
        "frequency_bands": r.frequency_bands,
        "vertical_axis": [axis.x, axis.y, axis.z],
        "spectrum": {
            "frequency_hz": r.spectrum.frequency_hz,
            "psd_mm2_per_hz": r.spectrum.density,
        },
    })
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

/// One control point's analysis.
pub struct PointOutcome {
    pub name: String,
    pub pixel: (f64, f64),
    pub times_s: Vec<f64>,
    /// Along `axis`.
    pub displacement_mm: Vec<Option<f64>>,
    /// Which axis the displacement and figures are along, and its unit vector (camera frame).
    pub axis_name: &'static str,
    pub axis: Vector3<f64>,
    /// The principal axis of the band-passed 3D motion (`None`: too little measured).
    pub principal_axis: Option<Vector3<f64>>,
    /// The peak of the summed 3-axis spectrum, Hz.
    pub spectrum_3d_peak_hz: Option<f64>,
    /// Coherence with each other point: name, at this point's peak, mean over 2–12 Hz.
    pub coherence: Vec<(String, Option<f64>, Option<f64>)>,
    /// The figures, or why they are missing (too little was measured).
    pub report: Result<TremorReport, String>,
}

impl PointOutcome {
    /// The JSON object `analyze` writes for this point; `vertical` is the vertical axis.
    pub fn json(&self, vertical: &Vector3<f64>) -> serde_json::Value {
        let (u, v) = self.pixel;
        let mut object = match &self.report {
            Ok(r) => report_json(self.pixel, r, vertical),
            Err(why) => json!({ "pixel": [u, v], "figures_missing": why }),
        };
        let vector = |a: &Vector3<f64>| json!([a.x, a.y, a.z]);
        object["name"] = json!(self.name);
        object["displacement_axis"] = json!({ "name": self.axis_name, "unit": vector(&self.axis) });
        object["principal_axis"] = self.principal_axis.as_ref().map_or(json!(null), vector);
        object["spectrum_3d_peak_hz"] = json!(self.spectrum_3d_peak_hz);
        object["coherence"] = self
            .coherence
            .iter()
            .map(|(other, at_peak, mean)| {
                json!({ "with": other, "at_peak": at_peak, "mean_2_12_hz": mean })
            })
            .collect();
        object
    }

    /// The point's panel in the report figure.
    pub fn figure(&self) -> crate::report_png::PointFigure {
        crate::report_png::PointFigure {
            label: self.name.clone(),
            times_s: self.times_s.clone(),
            displacement_mm: self.displacement_mm.clone(),
            report: self.report.clone(),
        }
    }
}

/// The displacement series of two points on one uniform grid, and its rate.
fn common_grid(
    times_s: &[f64],
    a: &[Option<f64>],
    b: &[Option<f64>],
) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    let (x, y) = (resample(times_s, a)?, resample(times_s, b)?);
    (x.valid_fraction >= 0.5 && y.valid_fraction >= 0.5).then_some((x.values, y.values, x.rate_hz))
}

/// The tremor figures of every tracked point along `axis`. A point with too little measured
/// gets the reason instead of figures; any other analysis failure is an error naming the point.
pub fn analyze_tracks(
    sequence_frames_averaged: usize,
    tracked: &SessionTracks,
    names: &[String],
    pixels: &[(f64, f64)],
    axis: DisplacementAxis,
) -> Result<Vec<PointOutcome>> {
    // The analysis undoes the averaging that the decode leaves.
    let options = AnalysisOptions {
        window_frames: sequence_frames_averaged,
        ..AnalysisOptions::default()
    };
    let mut outcomes = Vec::new();
    for ((track, name), &pixel) in tracked.tracks.iter().zip(names).zip(pixels) {
        let times_s: Vec<f64> = track.iter().map(|s| s.time_s).collect();
        let principal = principal_axis(track, options.band_hz);
        let unit = match axis {
            DisplacementAxis::Principal => principal,
            other => other.unit(&tracked.axis, track, &options),
        };
        let (displacement_mm, report) = match unit {
            Some(unit) => {
                let d = displacements(track, &unit);
                let report = match analyze(&times_s, &d, &options) {
                    Ok(r) => Ok(r),
                    // Too little was measured at this point: say so, keep the others' figures.
                    Err(e @ TremorError::TooFewValid { .. }) => Err(e.to_string()),
                    Err(e) => return Err(e).with_context(|| format!("point `{name}`")),
                };
                (d, report)
            }
            None => (
                vec![None; track.len()],
                Err("figures missing: too little was measured for a principal axis".to_string()),
            ),
        };
        outcomes.push(PointOutcome {
            name: name.clone(),
            pixel,
            times_s,
            displacement_mm,
            axis_name: axis.name(),
            axis: unit.unwrap_or(tracked.axis),
            principal_axis: principal,
            spectrum_3d_peak_hz: summed_spectrum_peak(track, &options),
            coherence: Vec::new(),
            report,
        });
    }
    // Coherence of every pair, on the displacements each point's figures use.
    for i in 0..outcomes.len() {
        for j in 0..outcomes.len() {
            if i == j {
                continue;
            }
            let (a, b) = (&outcomes[i], &outcomes[j]);
            // Segments of 2 s, or shorter for a short record so that it still gives the four
            // segments a coherence needs (0.8 s for a 2 s record: 1.25 Hz resolution).
            let c = common_grid(&a.times_s, &a.displacement_mm, &b.displacement_mm).and_then(
                |(x, y, rate_hz)| {
                    let segment = (2.0 * rate_hz).min(0.4 * x.len() as f64).round() as usize;
                    coherence(&x, &y, rate_hz, segment)
                },
            );
            let peak = a.report.as_ref().ok().and_then(|r| r.peak_frequency_hz);
            let entry = (
                b.name.clone(),
                c.as_ref().zip(peak).and_then(|(c, f)| c.at(f)),
                c.as_ref().and_then(|c| c.band_mean(COHERENCE_BAND_HZ)),
            );
            outcomes[i].coherence.push(entry);
        }
    }
    Ok(outcomes)
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
        &tracked,
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
