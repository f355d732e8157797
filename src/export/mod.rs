//! Exports of a decoded and triangulated window: the valid points as binary little-endian PLY,
//! camera-frame depth as a 32-bit float TIFF (NaN where invalid), and the decoded scene colour as
//! PNG; and of a trial's control-point trajectories ([`motion`]) as Motion-BIDS ([`bids`]) and
//! C3D ([`c3d`]). Each writes to a temporary name and renames, so no half-written file is left
//! behind.
//!
//! The TIFF is baseline TIFF 6.0 with one uncompressed strip, 1 sample of 32-bit IEEE float per
//! pixel (SampleFormat 3), little-endian: readable by any TIFF library. [`read_depth_tiff`]
//! reads that exact layout back (for tests and tools), nothing else.

pub mod bids;
pub mod c3d;
pub mod motion;

pub use motion::{MotionFrame, PointTrack, TrialMotion};

use crate::triangulate::PointCloud;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Errors of writing or reading exported files.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {why}")]
    Format { path: PathBuf, why: String },
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> ExportError {
    let path = path.to_path_buf();
    move |source| ExportError::Io { path, source }
}

/// Writes `bytes` to `path` through a temporary file and a rename.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let mut file = std::fs::File::create(&tmp).map_err(io_error(&tmp))?;
    file.write_all(bytes).map_err(io_error(&tmp))?;
    file.sync_all().map_err(io_error(&tmp))?;
    std::fs::rename(&tmp, path).map_err(io_error(path))
}

/// The valid points of `cloud` as binary little-endian PLY: `x y z` (float, mm, camera frame)
/// and `red green blue` (uchar). Returns the number of points written.
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<usize, ExportError> {
    let valid: Vec<usize> = (0..cloud.point_in_camera_mm.len())
        .filter(|&i| cloud.point_in_camera_mm[i][2].is_finite())
        .collect();
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\ncomment tremorscan point cloud, camera frame, mm, t = {:.6} s\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        cloud.time_s,
        valid.len()
    )
    .into_bytes();
    bytes.reserve(valid.len() * 15);
    for &i in &valid {
        for c in cloud.point_in_camera_mm[i] {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
        bytes.extend_from_slice(&cloud.colour_rgb[i]);
    }
    write_atomic(path, &bytes)?;
    Ok(valid.len())
}

/// Camera-frame z (mm) of every slot of `cloud`, NaN where invalid, row-major.
pub fn depth_mm(cloud: &PointCloud) -> Vec<f32> {
    cloud
        .point_in_camera_mm
        .iter()
        .map(|p| if p[2].is_finite() { p[2] } else { f32::NAN })
        .collect()
}

const TIFF_ENTRIES: u16 = 10;

/// Writes `values` (`width`×`height`, row-major) as a 32-bit float gray TIFF.
pub fn write_depth_tiff(
    path: &Path,
    width: usize,
    height: usize,
    values: &[f32],
) -> Result<(), ExportError> {
    if values.len() != width * height || width == 0 || height == 0 {
        return Err(ExportError::Format {
            path: path.to_path_buf(),
            why: format!("{} values for a {width}×{height} image", values.len()),
        });
    }
    let data_len = (values.len() * 4) as u32;
    // Header (8) + IFD (2 + 12·n + 4), then the pixel strip.
    let ifd_at = 8u32;
    let data_at = ifd_at + 2 + 12 * u32::from(TIFF_ENTRIES) + 4;
    let mut b = Vec::with_capacity(data_at as usize + data_len as usize);
    b.extend_from_slice(b"II");
    b.extend_from_slice(&42u16.to_le_bytes());
    b.extend_from_slice(&ifd_at.to_le_bytes());
    b.extend_from_slice(&TIFF_ENTRIES.to_le_bytes());
    // (tag, type, count, value): type 3 = SHORT, 4 = LONG; entries sorted by tag.
    let entries: [(u16, u16, u32, u32); TIFF_ENTRIES as usize] = [
        (256, 4, 1, width as u32),  // ImageWidth
        (257, 4, 1, height as u32), // ImageLength
        (258, 3, 1, 32),            // BitsPerSample
        (259, 3, 1, 1),             // Compression: none
        (262, 3, 1, 1),             // Photometric: black is zero
        (273, 4, 1, data_at),       // StripOffsets
        (277, 3, 1, 1),             // SamplesPerPixel
        (278, 4, 1, height as u32), // RowsPerStrip
        (279, 4, 1, data_len),      // StripByteCounts
        (339, 3, 1, 3),             // SampleFormat: IEEE float
    ];
    for (tag, kind, count, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        // A SHORT sits in the first two bytes of the value field.
        b.extend_from_slice(&value.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes()); // no next IFD
    for v in values {
        b.extend_from_slice(&v.to_le_bytes());
    }
    write_atomic(path, &b)
}

/// Reads a TIFF written by [`write_depth_tiff`]: returns width, height and values.
pub fn read_depth_tiff(path: &Path) -> Result<(usize, usize, Vec<f32>), ExportError> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let bad = |why: &str| ExportError::Format {
        path: path.to_path_buf(),
        why: why.to_string(),
    };
    let u16_at = |o: usize| -> Option<u16> {
        Some(u16::from_le_bytes(bytes.get(o..o + 2)?.try_into().ok()?))
    };
    let u32_at = |o: usize| -> Option<u32> {
        Some(u32::from_le_bytes(bytes.get(o..o + 4)?.try_into().ok()?))
    };
    if bytes.get(0..4) != Some(b"II*\0".as_slice()) {
        return Err(bad("not a little-endian TIFF"));
    }
    let ifd = u32_at(4).ok_or_else(|| bad("truncated header"))? as usize;
    let n = u16_at(ifd).ok_or_else(|| bad("truncated directory"))? as usize;
    let (mut width, mut height, mut offset, mut count, mut bits, mut format) = (0, 0, 0, 0, 0, 0);
    for k in 0..n {
        let e = ifd + 2 + 12 * k;
        let tag = u16_at(e).ok_or_else(|| bad("truncated directory"))?;
        let kind = u16_at(e + 2).ok_or_else(|| bad("truncated directory"))?;
        let value = if kind == 3 {
            u32::from(u16_at(e + 8).ok_or_else(|| bad("truncated directory"))?)
        } else {
            u32_at(e + 8).ok_or_else(|| bad("truncated directory"))?
        } as usize;
        match tag {
            256 => width = value,
            257 => height = value,
            258 => bits = value,
            273 => offset = value,
            279 => count = value,
            339 => format = value,
            _ => {}
        }
    }
    if bits != 32 || format != 3 || count != width * height * 4 {
        return Err(bad("not a single-strip 32-bit float gray TIFF"));
    }
    let data = bytes
        .get(offset..offset + count)
        .ok_or_else(|| bad("pixel data runs past the end of the file"))?;
    let values = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((width, height, values))
}

/// Writes the decoded scene colour of `cloud` as an RGB PNG (black where invalid).
pub fn write_colour_png(path: &Path, cloud: &PointCloud) -> Result<(), ExportError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp.png");
    let tmp = PathBuf::from(tmp);
    let rgb: Vec<u8> = cloud.colour_rgb.iter().flatten().copied().collect();
    image::save_buffer(
        &tmp,
        &rgb,
        cloud.width as u32,
        cloud.height as u32,
        image::ColorType::Rgb8,
    )
    .map_err(|e| ExportError::Format {
        path: path.to_path_buf(),
        why: e.to_string(),
    })?;
    std::fs::rename(&tmp, path).map_err(io_error(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_tiff_round_trips_with_nan() {
        let path =
            std::env::temp_dir().join(format!("tremorscan-depth-{}.tiff", std::process::id()));
        let values: Vec<f32> = (0..12)
            .map(|i| {
                if i == 5 {
                    f32::NAN
                } else {
                    400.0 + i as f32 * 0.25
                }
            })
            .collect();
        write_depth_tiff(&path, 4, 3, &values).unwrap();
        let (w, h, back) = read_depth_tiff(&path).unwrap();
        assert_eq!((w, h), (4, 3));
        assert!(back[5].is_nan());
        assert_eq!(back[11], 402.75);
        assert_eq!(back.iter().filter(|v| v.is_finite()).count(), 11);
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn ply_holds_only_valid_points_in_binary() {
        let cloud = PointCloud {
            width: 2,
            height: 1,
            time_s: 0.5,
            point_in_camera_mm: vec![[1.0, 2.0, 480.0], [f32::NAN; 3]],
            colour_rgb: vec![[10, 20, 30], [0, 0, 0]],
            fringe_amplitude: vec![50.0, 0.0],
        };
        let path =
            std::env::temp_dir().join(format!("tremorscan-cloud-{}.ply", std::process::id()));
        assert_eq!(write_ply(&path, &cloud).unwrap(), 1);
        let bytes = std::fs::read(&path).unwrap();
        let header_end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
        assert!(header.contains("element vertex 1\n"));
        assert!(header.contains("format binary_little_endian 1.0"));
        let body = &bytes[header_end..];
        assert_eq!(body.len(), 15);
        assert_eq!(f32::from_le_bytes(body[8..12].try_into().unwrap()), 480.0);
        assert_eq!(&body[12..], &[10, 20, 30]);
        let _ = std::fs::remove_file(&path);
    }
}
