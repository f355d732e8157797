//! Configuring a GenICam camera: which pixel format to stream (RGB8, or an 8-bit Bayer format to
//! demosaic), applying binning (checked against what the camera can do), region, exposure, gain
//! and trigger, checking the link's bandwidth, and reading the settings back. Each failure names
//! the setting and the camera.

use super::types::{CameraReadback, GenicamError, GenicamSettings, PixelChoice, TriggerChoice};
use crate::device::bayer::BayerPattern;
use aravis::prelude::*;

/// Maps an aravis error while setting `what` on camera `id`.
pub(super) fn setting_error<'a>(
    id: &'a str,
    what: &'static str,
) -> impl Fn(aravis::glib::Error) -> GenicamError + 'a {
    move |e| GenicamError::Setting {
        id: id.to_string(),
        what,
        detail: e.message().to_string(),
    }
}

/// The pixel format to stream and, for a Bayer format, its pattern.
pub(super) fn choose_format(
    camera: &aravis::Camera,
    id: &str,
    pixel: PixelChoice,
) -> Result<(String, Option<BayerPattern>), GenicamError> {
    let err = |what| setting_error(id, what);
    let offered: Vec<String> = camera
        .dup_available_pixel_formats_as_strings()
        .map_err(err("pixel format"))?
        .iter()
        .map(|s| s.to_string())
        .collect();
    let rgb_name = offered
        .iter()
        .find(|f| *f == "RGB8" || *f == "RGB8Packed")
        .cloned();
    let bayer_offered = offered
        .iter()
        .find_map(|f| BayerPattern::from_pixel_format_name(f));
    let (format_name, bayer) = match pixel {
        PixelChoice::Rgb8 => (rgb_name, None),
        PixelChoice::Bayer(p) => (
            offered
                .iter()
                .find(|f| *f == p.pixel_format_name())
                .cloned(),
            Some(p),
        ),
        PixelChoice::Auto => match (rgb_name, bayer_offered) {
            (Some(n), _) => (Some(n), None),
            (None, Some(p)) => (Some(p.pixel_format_name().to_string()), Some(p)),
            (None, None) => (None, None),
        },
    };
    let Some(format_name) = format_name else {
        return Err(GenicamError::NoColourFormat {
            id: id.to_string(),
            offered: offered.join(", "),
        });
    };
    Ok((format_name, bayer))
}

/// Sets the pixel format, binning, region, exposure, gain and trigger.
pub(super) fn apply(
    camera: &aravis::Camera,
    id: &str,
    settings: &GenicamSettings,
    format_name: &str,
) -> Result<(), GenicamError> {
    let err = |what| setting_error(id, what);
    camera
        .set_pixel_format_from_string(format_name)
        .map_err(err("pixel format"))?;
    if let Some(binning) = settings.binning {
        set_binning(camera, id, binning)?;
    }
    if let Some([x, y, w, h]) = settings.region {
        camera
            .set_region(x as i32, y as i32, w as i32, h as i32)
            .map_err(err("region"))?;
    }
    if let Some(us) = settings.exposure_micros {
        camera.set_exposure_time(us).map_err(err("exposure"))?;
    }
    if let Some(db) = settings.gain_db {
        camera.set_gain(db).map_err(err("gain"))?;
    }
    match &settings.trigger {
        TriggerChoice::FreeRun => {
            camera.clear_triggers().map_err(err("trigger off"))?;
            if let Some(fps) = settings.frame_rate_hz {
                camera.set_frame_rate(fps).map_err(err("frame rate"))?;
            }
        }
        TriggerChoice::Hardware { line } => {
            let offered: Vec<String> = camera
                .dup_available_trigger_sources()
                .map_err(err("trigger source"))?
                .iter()
                .map(|s| s.to_string())
                .collect();
            if !offered.contains(line) {
                return Err(GenicamError::NoTriggerLine {
                    id: id.to_string(),
                    line: line.clone(),
                    offered,
                });
            }
            camera.set_trigger(line).map_err(err("hardware trigger"))?;
        }
    }
    Ok(())
}

/// Sets `binning`×`binning`, after checking that the camera bins at all and by that factor.
/// Whether the camera shrinks its region with it is the camera's (the SFNC says its maximum
/// shrinks; aravis's fake camera keeps its region): the caller reads the region back for the
/// frame size.
fn set_binning(camera: &aravis::Camera, id: &str, binning: u32) -> Result<(), GenicamError> {
    let refuse = |detail: String| GenicamError::NoBinning {
        id: id.to_string(),
        binning,
        detail,
    };
    if !camera.is_binning_available().unwrap_or(false) {
        // 1×1 is what a camera without binning does anyway.
        return if binning == 1 {
            Ok(())
        } else {
            Err(refuse("it has no binning".to_string()))
        };
    }
    let factor = i32::try_from(binning).map_err(|_| refuse("too large".to_string()))?;
    for (axis, bounds) in [
        ("across", camera.x_binning_bounds()),
        ("down", camera.y_binning_bounds()),
    ] {
        let (low, high) = bounds.map_err(|e| refuse(e.message().to_string()))?;
        if !(low..=high).contains(&factor) {
            return Err(refuse(format!("it bins {low} to {high} {axis}")));
        }
    }
    camera
        .set_binning(factor, factor)
        .map_err(|e| refuse(e.message().to_string()))
}

/// USB3 Vision cameras state their link bandwidth; refuse a stream that cannot fit.
pub(super) fn check_bandwidth(
    camera: &aravis::Camera,
    id: &str,
    width: usize,
    height: usize,
    format: &str,
    fps: f64,
) -> Result<(), GenicamError> {
    if !camera.is_uv_device() || camera.uv_is_bandwidth_control_available().is_err() {
        return Ok(());
    }
    let Ok((_, max_bytes_s)) = camera.uv_get_bandwidth_bounds() else {
        return Ok(());
    };
    let bytes_per_pixel = if format.starts_with("Bayer") {
        1.0
    } else {
        3.0
    };
    let needed = width as f64 * height as f64 * bytes_per_pixel * fps;
    if needed > f64::from(max_bytes_s) {
        return Err(GenicamError::BandwidthTooLow {
            id: id.to_string(),
            available_mb_s: f64::from(max_bytes_s) / 1e6,
            needed_mb_s: needed / 1e6,
            width,
            height,
            format: format.to_string(),
            fps,
        });
    }
    Ok(())
}

/// Reads the settings back from the camera.
pub(super) fn readback(camera: &aravis::Camera, id: &str) -> Result<CameraReadback, GenicamError> {
    let err = |what| setting_error(id, what);
    let (x, y, w, h) = camera.region().map_err(err("region"))?;
    Ok(CameraReadback {
        pixel_format: camera
            .pixel_format_as_string()
            .map_err(err("pixel format"))?
            .to_string(),
        exposure_micros: camera.exposure_time().map_err(err("exposure"))?,
        gain_db: camera.gain().map_err(err("gain"))?,
        region: [x, y, w, h].map(|v| v.max(0) as usize),
        binning: match camera.is_binning_available() {
            Ok(true) => {
                let (dx, dy) = camera.binning().map_err(err("binning"))?;
                Some((dx.max(0) as u32, dy.max(0) as u32))
            }
            _ => None,
        },
        frame_rate_hz: camera.frame_rate().map_err(err("frame rate"))?,
        trigger_mode: camera
            .string("TriggerMode")
            .map_err(err("trigger mode"))?
            .to_string(),
    })
}
