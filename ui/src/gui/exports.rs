//! Exports from the live view: the current cloud as PLY, the control points' tracks as CSV, the
//! tremor report (PNG figure + JSON, the same files `tremorscan analyze` writes) and a screenshot
//! of the window. Each is a plain function of a path, so it is tested without dialogs; the
//! buttons ask for the path with rfd.

use crate::tremor_cmd::{report_json, track_csv, TrackColumn};
use anyhow::{Context, Result};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use tremorscan::pipeline::CloudFrame;
use tremorscan::tremor::{AnalysisOptions, LiveTracker, TrackSample};

/// What the user asked to export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportKind {
    CloudPly,
    TrackCsv,
    ReportPng,
    Screenshot,
}

impl ExportKind {
    pub fn label(self) -> &'static str {
        match self {
            ExportKind::CloudPly => "Cloud (PLY)…",
            ExportKind::TrackCsv => "Track (CSV)…",
            ExportKind::ReportPng => "Tremor report (PNG + JSON)…",
            ExportKind::Screenshot => "Screenshot (PNG)…",
        }
    }

    fn default_name(self) -> &'static str {
        match self {
            ExportKind::CloudPly => "cloud.ply",
            ExportKind::TrackCsv => "track.csv",
            ExportKind::ReportPng => "tremor-report.png",
            ExportKind::Screenshot => "tremorscan-screenshot.png",
        }
    }

    fn extension(self) -> &'static str {
        match self {
            ExportKind::CloudPly => "ply",
            ExportKind::TrackCsv => "csv",
            ExportKind::ReportPng | ExportKind::Screenshot => "png",
        }
    }
}

/// Asks where to save, starting in `dir`.
pub fn ask_path(kind: ExportKind, dir: &Path) -> Option<PathBuf> {
    rfd::FileDialog::new()
        .set_title(kind.label().trim_end_matches('…'))
        .set_directory(dir)
        .set_file_name(kind.default_name())
        .add_filter(kind.extension(), &[kind.extension()])
        .save_file()
}

/// Writes the cloud's valid points; returns how many.
pub fn export_cloud(path: &Path, frame: Option<&CloudFrame>) -> Result<String> {
    let frame = frame.context("there is no decoded cloud yet")?;
    let n = tremorscan::export::write_ply(path, &frame.cloud)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!("wrote {n} points to {}", path.display()))
}

fn histories(tracker: &LiveTracker) -> Vec<(String, (f64, f64), Vec<TrackSample>)> {
    tracker
        .points
        .iter()
        .map(|p| (p.name.clone(), p.pixel, p.samples.iter().copied().collect()))
        .collect()
}

/// Writes every point's history as CSV (displacement along the optical axis).
pub fn export_track(path: &Path, tracker: &LiveTracker) -> Result<String> {
    anyhow::ensure!(
        !tracker.points.is_empty(),
        "there are no control points to export"
    );
    let h = histories(tracker);
    let columns: Vec<TrackColumn<'_>> = h
        .iter()
        .map(|(name, pixel, samples)| TrackColumn {
            name: name.clone(),
            pixel: *pixel,
            samples,
        })
        .collect();
    std::fs::write(path, track_csv(&columns, &Vector3::z()))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "wrote the track of {} points to {}",
        columns.len(),
        path.display()
    ))
}

/// Writes the tremor report figure to `png` and its figures to the same name with `.json`.
pub fn export_report(png: &Path, tracker: &LiveTracker) -> Result<String> {
    anyhow::ensure!(
        !tracker.points.is_empty(),
        "there are no control points to report on"
    );
    let axis = Vector3::z();
    let mut series = Vec::new();
    let mut objects = Vec::new();
    for p in &tracker.points {
        let (times, d) = p.displacement_series(&axis);
        let r = tremorscan::tremor::analyze(&times, &d, &AnalysisOptions::default())
            .with_context(|| format!("point {}", p.name))?;
        let mut object = report_json(p.pixel, &r, &axis);
        object["name"] = serde_json::Value::String(p.name.clone());
        objects.push(object);
        series.push((p.name.clone(), times, d, r));
    }
    let figures: Vec<crate::report_png::PointFigure<'_>> = series
        .iter()
        .map(|(label, times, d, r)| crate::report_png::PointFigure {
            label: label.clone(),
            times_s: times,
            displacement_mm: d,
            report: r,
        })
        .collect();
    crate::report_png::write_report(png, &figures)
        .with_context(|| format!("writing {}", png.display()))?;
    let json = png.with_extension("json");
    tremorscan::jsonfile::write_atomic(&json, &objects)?;
    Ok(format!("wrote {} and {}", png.display(), json.display()))
}

/// Saves a screenshot (RGBA pixels from egui) as PNG.
pub fn save_screenshot(path: &Path, image: &egui::ColorImage) -> Result<String> {
    let [w, h] = image.size;
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w as u32, h as u32);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .with_context(|| format!("writing {}", path.display()))?;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    writer
        .write_image_data(&bytes)
        .with_context(|| format!("writing {}", path.display()))?;
    writer
        .finish()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!("saved the screenshot to {}", path.display()))
}
