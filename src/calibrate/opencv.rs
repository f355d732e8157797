//! Import of OpenCV FileStorage calibration files (YAML `%YAML:1.0` with `!!opencv-matrix`
//! nodes, or XML `<opencv_storage>` with `type_id="opencv-matrix"` nodes), as written by common
//! projector–camera calibration tools.
//!
//! Only top-level matrices and numbers are read. Names accepted, first match wins:
//! camera `Kc`, `cam_K`, `K1`, `camera_matrix`; camera distortion `kc`, `cam_kc`, `D1`,
//! `dist_coeffs`; projector `Kp`, `proj_K`, `K2`; projector distortion `kp`, `proj_kc`, `D2`;
//! rotation `Rp`, `R`; translation `Tp`, `T`. R and T map camera to projector coordinates
//! (`X_p = R·X_c + T`, OpenCV's `stereoCalibrate` convention) and T is taken in millimetres.
//! FileStorage carries no image sizes, so the caller gives them.

use super::file::{Calibration, FileError};
use crate::geometry::Pose;
use crate::session::manifest::{ExtrinsicsJson, LensJson};
use std::collections::BTreeMap;
use std::path::Path;

/// A matrix read from the file, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct CvMatrix {
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
}

impl CvMatrix {
    fn scalar(x: f64) -> Self {
        Self {
            rows: 1,
            cols: 1,
            data: vec![x],
        }
    }
}

/// Parses a FileStorage text (YAML or XML) into its top-level matrices; a plain number counts
/// as a 1×1 matrix.
pub fn parse_file_storage(text: &str) -> Result<BTreeMap<String, CvMatrix>, (usize, String)> {
    let trimmed = text.trim_start();
    if trimmed.starts_with("<?xml") || trimmed.starts_with("<opencv_storage") {
        parse_xml(text)
    } else if trimmed.starts_with("%YAML") {
        parse_yaml(text)
    } else {
        Err((
            1,
            "neither OpenCV YAML (%YAML:1.0) nor XML (<opencv_storage>)".into(),
        ))
    }
}

fn number(token: &str, line: usize) -> Result<f64, (usize, String)> {
    let t = token.trim();
    t.parse::<f64>()
        .map_err(|_| (line, format!("`{t}` is not a number")))
}

fn finish(
    name: &str,
    rows: Option<usize>,
    cols: Option<usize>,
    data: Vec<f64>,
    line: usize,
) -> Result<CvMatrix, (usize, String)> {
    let (Some(rows), Some(cols)) = (rows, cols) else {
        return Err((line, format!("matrix {name} lacks rows or cols")));
    };
    if rows * cols != data.len() {
        return Err((
            line,
            format!(
                "matrix {name} is {rows}×{cols} but holds {} values",
                data.len()
            ),
        ));
    }
    Ok(CvMatrix { rows, cols, data })
}

fn parse_yaml(text: &str) -> Result<BTreeMap<String, CvMatrix>, (usize, String)> {
    let mut out = BTreeMap::new();
    let lines: Vec<&str> = text.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        i += 1;
        if line.starts_with('%')
            || line.starts_with("---")
            || line.trim().is_empty()
            || line.starts_with(' ')
            || line.starts_with('#')
        {
            continue;
        }
        let Some((name, value)) = line.split_once(':') else {
            return Err((i, format!("expected `name: value`, got `{line}`")));
        };
        let (name, value) = (name.trim().to_string(), value.trim());
        if value.starts_with("!!opencv-matrix") {
            let start = i;
            let (mut rows, mut cols, mut data) = (None, None, Vec::new());
            while i < lines.len() && lines[i].starts_with(' ') {
                let Some((key, v)) = lines[i].trim().split_once(':') else {
                    return Err((i + 1, format!("expected `key: value` in matrix {name}")));
                };
                i += 1;
                match key.trim() {
                    "rows" => rows = Some(number(v, i)? as usize),
                    "cols" => cols = Some(number(v, i)? as usize),
                    "data" => {
                        let data_line = i;
                        let mut body = v.to_string();
                        while !body.contains(']') && i < lines.len() {
                            body.push(' ');
                            body.push_str(lines[i]);
                            i += 1;
                        }
                        let inner = body
                            .trim()
                            .strip_prefix('[')
                            .and_then(|b| b.split(']').next())
                            .ok_or((i, format!("data of matrix {name} is not a [ ... ] list")))?;
                        for token in inner.split(',').filter(|t| !t.trim().is_empty()) {
                            data.push(number(token, data_line)?);
                        }
                    }
                    _ => {}
                }
            }
            out.insert(name.clone(), finish(&name, rows, cols, data, start)?);
        } else if let Ok(x) = value.parse::<f64>() {
            out.insert(name, CvMatrix::scalar(x));
        }
    }
    Ok(out)
}

fn parse_xml(text: &str) -> Result<BTreeMap<String, CvMatrix>, (usize, String)> {
    let line_of = |pos: usize| text[..pos].matches('\n').count() + 1;
    let body_start = text
        .find("<opencv_storage>")
        .ok_or((1, "no <opencv_storage> element".to_string()))?
        + "<opencv_storage>".len();
    let mut out = BTreeMap::new();
    let mut pos = body_start;
    while let Some(open) = text[pos..].find('<').map(|o| o + pos) {
        let close = text[open..]
            .find('>')
            .map(|c| c + open)
            .ok_or((line_of(open), "unclosed tag".to_string()))?;
        let tag = &text[open + 1..close];
        if tag.starts_with("/opencv_storage") {
            break;
        }
        if tag.starts_with('!') || tag.starts_with('?') {
            pos = close + 1;
            continue;
        }
        let name = tag
            .split_whitespace()
            .next()
            .unwrap_or_default()
            .to_string();
        let end_tag = format!("</{name}>");
        let end = text[close..]
            .find(&end_tag)
            .map(|e| e + close)
            .ok_or((line_of(open), format!("<{name}> is never closed")))?;
        let inner = &text[close + 1..end];
        let child = |child: &str| -> Option<&str> {
            let s = inner.find(&format!("<{child}>"))? + child.len() + 2;
            let e = inner[s..].find(&format!("</{child}>"))? + s;
            Some(&inner[s..e])
        };
        if tag.contains("opencv-matrix") {
            let line = line_of(open);
            let rows = child("rows")
                .map(|r| number(r, line))
                .transpose()?
                .map(|r| r as usize);
            let cols = child("cols")
                .map(|c| number(c, line))
                .transpose()?
                .map(|c| c as usize);
            let data = child("data")
                .ok_or((line, format!("matrix {name} has no <data>")))?
                .split_whitespace()
                .map(|t| number(t, line))
                .collect::<Result<Vec<_>, _>>()?;
            out.insert(name.clone(), finish(&name, rows, cols, data, line)?);
        } else if let Ok(x) = inner.trim().parse::<f64>() {
            out.insert(name, CvMatrix::scalar(x));
        }
        pos = end + end_tag.len();
    }
    Ok(out)
}

fn pick<'a>(m: &'a BTreeMap<String, CvMatrix>, names: &[&str]) -> Result<&'a CvMatrix, String> {
    names
        .iter()
        .find_map(|n| m.get(*n))
        .ok_or_else(|| format!("no matrix named {}", names.join(" or ")))
}

/// Reads an OpenCV calibration file for a camera and projector of the given sizes.
pub fn import_opencv(
    path: &Path,
    camera_size: (usize, usize),
    projector_size: (usize, usize),
) -> Result<Calibration, FileError> {
    let text = std::fs::read_to_string(path).map_err(|source| FileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let matrices = parse_file_storage(&text).map_err(|(line, why)| FileError::OpenCv {
        path: path.to_path_buf(),
        line,
        why,
    })?;
    let content = |why: String| FileError::OpenCvContent {
        path: path.to_path_buf(),
        why,
    };
    let shaped = |names: &[&str], rows: usize, cols: usize| -> Result<Vec<f64>, FileError> {
        let m = pick(&matrices, names).map_err(content)?;
        if m.rows * m.cols != rows * cols {
            return Err(content(format!(
                "{} is {}×{}, expected {rows}×{cols}",
                names[0], m.rows, m.cols
            )));
        }
        Ok(m.data.clone())
    };
    let lens = |k_names: &[&str],
                d_names: &[&str],
                size: (usize, usize),
                what: &str|
     -> Result<LensJson, FileError> {
        let k = shaped(k_names, 3, 3)?;
        let d = pick(&matrices, d_names).map_err(content)?;
        let json = LensJson {
            width: size.0,
            height: size.1,
            k: Some([[k[0], k[1], k[2]], [k[3], k[4], k[5]], [k[6], k[7], k[8]]]),
            dist: Some(
                d.data
                    .iter()
                    .copied()
                    .chain(std::iter::repeat(0.0))
                    .take(d.data.len().max(4))
                    .collect(),
            ),
        };
        // Longer OpenCV models (8, 12, 14 terms) are accepted only when the extra terms are 0.
        let mut json = json;
        if let Some(dist) = json.dist.as_mut() {
            if dist.len() > 5 {
                if dist[5..].iter().any(|&x| x != 0.0) {
                    return Err(content(format!(
                        "{} has {} distortion terms; only k1 k2 p1 p2 k3 are supported",
                        d_names[0],
                        dist.len()
                    )));
                }
                dist.truncate(5);
            }
        }
        json.to_lens(what).map_err(|e| content(e.to_string()))?;
        Ok(json)
    };
    let camera = lens(
        &["Kc", "cam_K", "K1", "camera_matrix"],
        &["kc", "cam_kc", "D1", "dist_coeffs"],
        camera_size,
        "camera",
    )?;
    let projector = lens(
        &["Kp", "proj_K", "K2"],
        &["kp", "proj_kc", "D2"],
        projector_size,
        "projector",
    )?;
    let r = shaped(&["Rp", "R"], 3, 3)?;
    let t = shaped(&["Tp", "T"], 3, 1)?;
    let extrinsics = ExtrinsicsJson {
        r: [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
        t_mm: [t[0], t[1], t[2]],
    };
    let pose: Pose = extrinsics
        .to_pose("R")
        .map_err(|e| content(e.to_string()))?;
    Ok(Calibration {
        camera: camera
            .to_lens("camera")
            .map_err(|e| content(e.to_string()))?,
        projector: projector
            .to_lens("projector")
            .map_err(|e| content(e.to_string()))?,
        projector_from_camera: pose,
        cross_talk: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const YAML: &str = "%YAML:1.0\n---\nKc: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1625., 0., 481., 0., 1625.5,\n       297.75, 0., 0., 1. ]\nkc: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ -0.08, 0.05, 4.0e-04, -3.0e-04, 0. ]\ncam_error: 0.12\n";

    #[test]
    fn yaml_matrices_and_scalars_are_read() {
        let m = parse_file_storage(YAML).unwrap();
        assert_eq!(m["Kc"].rows, 3);
        assert_eq!(m["Kc"].data[4], 1625.5);
        assert_eq!(m["Kc"].data[5], 297.75);
        assert_eq!(m["kc"].data, vec![-0.08, 0.05, 4.0e-4, -3.0e-4, 0.0]);
        assert_eq!(m["cam_error"].data, vec![0.12]);
    }

    #[test]
    fn xml_matrices_are_read() {
        let xml = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<Kp type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    1380. 0. 455.5 0. 1380. 575.\n    0. 0. 1.</data></Kp>\n<proj_error>0.2</proj_error>\n</opencv_storage>\n";
        let m = parse_file_storage(xml).unwrap();
        assert_eq!(m["Kp"].data[2], 455.5);
        assert_eq!(m["Kp"].data.len(), 9);
        assert_eq!(m["proj_error"].data, vec![0.2]);
    }

    #[test]
    fn malformed_files_name_the_line() {
        let bad = YAML.replace("1625.5", "16x5");
        let (line, why) = parse_file_storage(&bad).unwrap_err();
        assert_eq!(line, 7, "{why}");
        assert!(why.contains("16x5"), "{why}");
        let short = YAML.replace("cols: 5", "cols: 6");
        let (_, why) = parse_file_storage(&short).unwrap_err();
        assert!(why.contains("kc is 1×6 but holds 5 values"), "{why}");
        assert!(parse_file_storage("hello").is_err());
    }
}
