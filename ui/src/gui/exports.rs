//! Exports from the live view: the current cloud as PLY, the control points' tracks as CSV, the
//! tremor report (PNG figure + JSON, the same files `tremorscan analyze` writes) and a screenshot
//! of the window. Each is a plain function of a path, so it is tested without dialogs; the
//! buttons ask for the path with rfd.

use crate::point_analysis::{analyze_tracks, PointOutcome};
use crate::tremor_cmd::{track_csv, TrackColumn};
use anyhow::{Context, Result};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use tremorscan::pipeline::CloudFrame;
use tremorscan::tremor::{DisplacementAxis, LiveTracker, TrackSample};

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

/// Every point's history as the analysis takes it ([`tremorscan::tremor::LivePoint::history`]).
fn histories(tracker: &LiveTracker) -> Vec<(String, Vec<TrackSample>)> {
    let window_frames = tracker.analysis.window_frames;
    tracker
        .points
        .iter()
        .map(|p| (p.name.clone(), p.history(window_frames)))
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
        .map(|(name, samples)| TrackColumn {
            name: name.clone(),
            samples,
            axis: Vector3::z(),
        })
        .collect();
    std::fs::write(path, track_csv(&columns))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "wrote the track of {} points to {}",
        columns.len(),
        path.display()
    ))
}

/// Writes the tremor report figure to `png` and its figures to the same name with `.json`, as
/// `tremorscan analyze` does (along the optical axis, the default vertical).
pub fn export_report(png: &Path, tracker: &LiveTracker) -> Result<String> {
    anyhow::ensure!(
        !tracker.points.is_empty(),
        "there are no control points to report on"
    );
    if let Some((p, why)) = tracker
        .points
        .iter()
        .find_map(|p| p.follow_error().map(|why| (p, why)))
    {
        anyhow::bail!("point {}: {why}", p.name);
    }
    let (names, tracks): (Vec<String>, Vec<Vec<TrackSample>>) =
        histories(tracker).into_iter().unzip();
    let pixels: Vec<(f64, f64)> = tracker.points.iter().map(|p| p.pixel).collect();
    let vertical = Vector3::z();
    let outcomes = analyze_tracks(
        tracker.analysis.window_frames,
        &tracks,
        &vertical,
        &names,
        &pixels,
        DisplacementAxis::Vertical,
    )?;
    let figures: Vec<_> = outcomes.iter().map(PointOutcome::figure).collect();
    crate::report_png::write_report(png, &figures)
        .with_context(|| format!("writing {}", png.display()))?;
    let json = png.with_extension("json");
    let objects: Vec<serde_json::Value> = outcomes.iter().map(|o| o.json(&vertical)).collect();
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

#[cfg(test)]
mod tests {
    use super::*;
    use tremorscan::triangulate::PointCloud;

    /// A tracker fed `seconds` of flat, untextured clouds at 121 Hz whose depth trembles by
    /// `amplitude_mm` at 5.3 Hz, its point at a fixed pixel (there is no texture to follow).
    fn trembling_tracker(seconds: f64, amplitude_mm: f64) -> LiveTracker {
        let mut t = LiveTracker::new(5.0);
        t.set_mode(tremorscan::tremor::PointMode::FixedPixel);
        t.add("index, tip", (4.0, 4.0));
        let (w, h) = (10, 10);
        for k in 0..(seconds * 121.0) as usize {
            let time_s = k as f64 / 121.0;
            let z = 500.0 + amplitude_mm * (std::f64::consts::TAU * 5.3 * time_s).sin();
            let cloud = PointCloud {
                width: w,
                height: h,
                time_s,
                point_in_camera_mm: vec![[0.0, 0.0, z as f32]; w * h],
                colour_rgb: vec![[200, 150, 120]; w * h],
                fringe_amplitude: vec![1.0; w * h],
            };
            t.update(&cloud, k);
        }
        t
    }

    fn flat(w: usize, h: usize) -> PointCloud {
        PointCloud {
            width: w,
            height: h,
            time_s: 0.0,
            point_in_camera_mm: vec![[0.0, 0.0, 500.0]; w * h],
            colour_rgb: vec![[0, 0, 0]; w * h],
            fringe_amplitude: vec![1.0; w * h],
        }
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("tremorscan-export-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch");
        dir
    }

    #[test]
    fn the_track_csv_has_a_row_per_sample_and_the_report_finds_the_tremor() {
        let dir = scratch("track");
        let tracker = trembling_tracker(4.0, 1.0);
        export_track(&dir.join("t.csv"), &tracker).expect("csv");
        let csv = std::fs::read_to_string(dir.join("t.csv")).expect("read");
        let rows: Vec<&str> = csv.lines().collect();
        assert!(rows[0].starts_with("time_s,frame,point,u,v,"));
        assert_eq!(rows.len() - 1, tracker.points[0].samples.len());
        // The comma in the name does not split the row.
        assert_eq!(rows[1].split(',').count(), rows[0].split(',').count());

        export_report(&dir.join("r.png"), &tracker).expect("report");
        assert!(dir.join("r.png").is_file());
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("r.json")).expect("json"))
                .expect("parse");
        let f = json[0]["peak_frequency_hz"].as_f64().expect("a peak");
        assert!((f - 5.3).abs() < 0.05, "peak {f}");
        assert_eq!(json[0]["name"], "index, tip");
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn exports_without_data_say_why() {
        let dir = scratch("empty");
        let empty = LiveTracker::new(5.0);
        let e = export_track(&dir.join("t.csv"), &empty).expect_err("no points");
        assert!(e.to_string().contains("no control points"));
        let e = export_cloud(&dir.join("c.ply"), None).expect_err("no cloud");
        assert!(e.to_string().contains("no decoded cloud"));
        // A point never measured (off the cloud) is refused with the reason, naming the point.
        let mut unmeasured = trembling_tracker(3.0, 1.0);
        let id = unmeasured.points[0].id;
        unmeasured.move_to(id, (50.0, 50.0));
        unmeasured.update(
            &PointCloud {
                time_s: 4.0,
                ..flat(10, 10)
            },
            0,
        );
        let e = export_report(&dir.join("r.png"), &unmeasured).expect_err("no samples");
        let text = format!("{e:#}");
        assert!(
            text.contains("index, tip") && text.contains("valid samples"),
            "{text}"
        );
        // A point following skin without texture: refused with the reason, not 0 mm.
        let mut plain = LiveTracker::new(5.0);
        plain.add("plain", (20.0, 20.0));
        plain.update(&flat(40, 40), 0);
        let e = export_report(&dir.join("r.png"), &plain).expect_err("no texture");
        let text = format!("{e:#}");
        assert!(text.contains("plain") && text.contains("texture"), "{text}");
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn a_screenshot_is_saved_as_a_png_of_the_same_pixels() {
        let dir = scratch("shot");
        let mut image = egui::ColorImage::new([3, 2], vec![egui::Color32::from_rgb(10, 20, 30); 6]);
        image.pixels[4] = egui::Color32::from_rgb(200, 0, 100);
        save_screenshot(&dir.join("s.png"), &image).expect("save");
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(dir.join("s.png")).expect("open"),
        ));
        let mut reader = decoder.read_info().expect("info");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("frame");
        assert_eq!((info.width, info.height), (3, 2));
        assert_eq!(&buf[16..20], &[200, 0, 100, 255]);
        let _ = std::fs::remove_dir_all(dir);
    }
}
