//! Frame image files of a session: 8-bit PNG or BMP, RGB or gray, read into [`Frame`]s and
//! written as PNG.

use super::SessionError;
use crate::frame::Frame;
use image::{ColorType, DynamicImage, ImageReader};
use std::path::Path;

/// Reads an 8-bit gray or RGB image and checks its size.
pub fn read_frame(path: &Path, expected: (usize, usize)) -> Result<Frame, SessionError> {
    let bad = |why: String| SessionError::FrameImage {
        file: path.to_path_buf(),
        why,
    };
    if !path.is_file() {
        return Err(SessionError::MissingFrame {
            file: path.to_path_buf(),
        });
    }
    let reader = ImageReader::open(path)
        .map_err(|e| bad(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| bad(e.to_string()))?;
    match reader.format() {
        Some(image::ImageFormat::Png | image::ImageFormat::Bmp) => {}
        other => {
            return Err(bad(format!(
                "is {}, frames must be PNG or BMP",
                other.map_or("not an image".to_string(), |f| format!("{f:?}"))
            )))
        }
    }
    let image = reader.decode().map_err(|e| bad(e.to_string()))?;
    let (width, height) = (image.width() as usize, image.height() as usize);
    if (width, height) != expected {
        return Err(SessionError::FrameSize {
            file: path.to_path_buf(),
            width,
            height,
            expected_width: expected.0,
            expected_height: expected.1,
        });
    }
    let (channels, data) = match image {
        DynamicImage::ImageLuma8(g) => (1, g.into_raw()),
        DynamicImage::ImageRgb8(rgb) => (3, rgb.into_raw()),
        // BMP decodes 32-bit images as RGBA; an opaque alpha channel carries nothing.
        DynamicImage::ImageRgba8(rgba) if rgba.pixels().all(|p| p.0[3] == 255) => {
            (3, DynamicImage::ImageRgba8(rgba).to_rgb8().into_raw())
        }
        other => {
            return Err(bad(format!(
                "has pixel type {:?}; frames must be 8-bit gray or RGB",
                other.color()
            )))
        }
    };
    Frame::from_data(width, height, channels, data).map_err(|e| bad(e.to_string()))
}

/// Writes `frame` as an 8-bit PNG (gray or RGB).
pub fn write_png(path: &Path, frame: &Frame) -> Result<(), SessionError> {
    let color = if frame.channels == 1 {
        ColorType::L8
    } else {
        ColorType::Rgb8
    };
    image::save_buffer(
        path,
        &frame.data,
        frame.width as u32,
        frame.height as u32,
        color,
    )
    .map_err(|e| SessionError::FrameImage {
        file: path.to_path_buf(),
        why: e.to_string(),
    })
}
