//! The tremor report figure (PNG, for a clinical note): per control point, the displacement over
//! time (s, mm) above its spectrum (Hz, mm²/Hz) with the 3–12 Hz band shaded, and the measured
//! figures in the title. Drawn with plotters on an in-memory bitmap; text in DejaVu Sans
//! (`assets/fonts`, embedded, so no system font is needed).

use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;
use tremorscan::tremor::coherence::{coherence_line, PairCoherence};
use tremorscan::tremor::TremorReport;

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the embedded report font is unreadable"));
    });
    result
}

/// One control point's series and figures.
pub struct PointFigure {
    pub label: String,
    pub times_s: Vec<f64>,
    pub displacement_mm: Vec<Option<f64>>,
    /// The figures, or why they are missing (too few valid samples).
    pub report: Result<TremorReport, String>,
    /// The coherence with each other point.
    pub coherence: Vec<PairCoherence>,
}

/// Writes the report for `points` to `path` (PNG, 1200 px wide, 500 px per point).
pub fn write_report(path: &Path, points: &[PointFigure]) -> Result<()> {
    register_font()?;
    let height = 500 * points.len().max(1) as u32;
    let mut pixels = vec![0u8; 1200 * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (1200, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        for (area, point) in root
            .split_evenly((points.len().max(1), 1))
            .iter()
            .zip(points)
        {
            draw_point(area, point).map_err(|e| anyhow!("{e}"))?;
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    image_save(path, &pixels, 1200, height)
}

fn image_save(path: &Path, rgb: &[u8], width: u32, height: u32) -> Result<()> {
    let frame =
        tremorscan::frame::Frame::from_data(width as usize, height as usize, 3, rgb.to_vec())?;
    // Written beside the target under a `.tmp.png` name and renamed, so an interrupted run
    // leaves no half-written report.
    let tmp = path.with_extension("tmp.png");
    tremorscan::session::frames::write_png(&tmp, &frame)?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))?;
    Ok(())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn draw_point(area: &Area<'_>, point: &PointFigure) -> Result<(), Box<dyn std::error::Error>> {
    let title = match &point.report {
        Ok(r) => format!(
            "{}: peak {}, peak-to-peak {:.2} mm, RMS {:.2} mm, MDS-UPDRS amplitude bin {}, {:.0} % valid",
            point.label,
            r.peak_frequency_hz
                .map_or("none".to_string(), |f| format!("{f:.2} Hz")),
            r.amplitude_peak_to_peak_mm,
            r.amplitude_rms_mm,
            r.updrs_amplitude_bin,
            100.0 * r.valid_fraction
        ),
        Err(why) => format!("{}: {why}", point.label),
    };
    let area = area.titled(&title, ("sans-serif", 18))?;
    let (top, bottom) = area.split_vertically(250);
    // Displacement over time; gaps are left open.
    let t0 = point.times_s.first().copied().unwrap_or(0.0);
    let t1 = point.times_s.last().copied().unwrap_or(1.0).max(t0 + 1e-3);
    let values: Vec<f64> = point.displacement_mm.iter().flatten().copied().collect();
    let span = values.iter().fold(0.1f64, |m, v| m.max(v.abs())) * 1.1;
    let mut chart = ChartBuilder::on(&top)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..(t1 - t0), -span..span)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("displacement (mm)")
        .label_style(("sans-serif", 14))
        .draw()?;
    let mut run: Vec<(f64, f64)> = Vec::new();
    for (t, d) in point.times_s.iter().zip(&point.displacement_mm) {
        match d {
            Some(d) => run.push((t - t0, *d)),
            None if !run.is_empty() => {
                chart.draw_series(LineSeries::new(std::mem::take(&mut run), &BLUE))?;
            }
            None => {}
        }
    }
    if !run.is_empty() {
        chart.draw_series(LineSeries::new(run, &BLUE))?;
    }
    // Spectrum up to 20 Hz with the tremor band shaded; none without figures.
    let Ok(r) = &point.report else {
        return Ok(());
    };
    let spectrum: Vec<(f64, f64)> = r
        .spectrum
        .frequency_hz
        .iter()
        .zip(&r.spectrum.density)
        .filter(|(f, _)| **f <= 20.0)
        .map(|(f, d)| (*f, *d))
        .collect();
    let max = spectrum.iter().fold(1e-6f64, |m, (_, d)| m.max(*d)) * 1.1;
    let mut chart = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..20.0, 0.0..max)?;
    chart
        .configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc("PSD (mm²/Hz)")
        .label_style(("sans-serif", 14))
        .draw()?;
    chart.draw_series(std::iter::once(Rectangle::new(
        [(3.0, 0.0), (12.0, max)],
        RGBColor(230, 236, 250).filled(),
    )))?;
    chart.draw_series(LineSeries::new(spectrum, &RED))?;
    let style = ("sans-serif", 15).into_text_style(&bottom);
    bottom.draw_text(&r.measures_line(), &style, (80, 12))?;
    if let Some(line) = coherence_line(&point.coherence) {
        bottom.draw_text(&line, &style, (80, 32))?;
    }
    Ok(())
}
