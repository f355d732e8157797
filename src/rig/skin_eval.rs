//! A control point's 3D track against the material point it was placed on: how well the
//! product follows the skin, beside what a fixed pixel gives.
//!
//! The rig's frames are decoded window by window (the sliding window, every window),
//! triangulated with the rig's exact calibration, and a control point placed at the pixel where
//! one of the scene's tracked surface points ([`super::scene::POINT_NAMES`]) is seen in the first
//! window is measured in every window twice: following the skin ([`PointMode::FollowSkin`]) and at
//! the fixed pixel ([`PointMode::FixedPixel`]). The truth of each sample is that surface point
//! itself at the sample's time: a point of the skin, carried by the finger's flexion and the
//! hand's sway and roll.

use super::{RigError, Scene, VirtualRig};
use crate::decode::{frames_averaged, DecodeError, DecodeParams, SlidingDecoder, WindowOutcome};
use crate::tremor::{
    analyze, displacements, principal_axis, undo_window_mean, AnalysisOptions, ControlPoint,
    FollowOptions, PointMode, TextureImage, TrackOptions, TrackSample, TremorError, TremorReport,
};
use crate::triangulate::{PointCloud, TriangulateError, Triangulator};

/// Errors of the skin-tracking evaluation.
#[derive(Debug, thiserror::Error)]
pub enum SkinEvalError {
    #[error(transparent)]
    Rig(#[from] RigError),
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error(transparent)]
    Triangulate(#[from] TriangulateError),
    #[error("the rig has no surface point {0}")]
    NoPoint(usize),
    #[error("the surface point is outside the camera image")]
    NotSeen,
    #[error("no window decoded")]
    NothingDecoded,
}

/// One mode's track against the truth.
#[derive(Debug, Clone)]
pub struct TrackAgainstTruth {
    pub samples: Vec<TrackSample>,
    /// The material point at each sample's time, camera frame, mm.
    pub truth_mm: Vec<[f64; 3]>,
}

impl TrackAgainstTruth {
    /// Share of the samples with a position.
    pub fn valid_share(&self) -> f64 {
        let valid = self
            .samples
            .iter()
            .filter(|s| s.position_mm.is_some())
            .count();
        valid as f64 / self.samples.len().max(1) as f64
    }

    /// 3D distances of the valid samples from the truth, mm.
    pub fn errors_mm(&self) -> Vec<f64> {
        self.samples
            .iter()
            .zip(&self.truth_mm)
            .filter_map(|(s, t)| {
                s.position_mm
                    .map(|p| (0..3).map(|a| (p[a] - t[a]).powi(2)).sum::<f64>().sqrt())
            })
            .collect()
    }

    /// The tremor figures along each series' own principal axis: the track's (the decode
    /// window's averaging undone by `window_frames`, as `analyze` does) and the truth's.
    pub fn principal_figures(
        &self,
        window_frames: usize,
    ) -> (
        Result<TremorReport, TremorError>,
        Result<TremorReport, TremorError>,
    ) {
        let truth: Vec<TrackSample> = self
            .samples
            .iter()
            .zip(&self.truth_mm)
            .map(|(s, t)| TrackSample {
                position_mm: Some(*t),
                ..*s
            })
            .collect();
        let figures = |samples: &[TrackSample], window_frames: usize| {
            let options = AnalysisOptions {
                window_frames,
                ..AnalysisOptions::default()
            };
            let axis =
                principal_axis(samples, options.band_hz).ok_or(TremorError::TooFewValid {
                    why: "too little was measured for a principal axis".to_string(),
                })?;
            let times: Vec<f64> = samples.iter().map(|s| s.time_s).collect();
            analyze(&times, &displacements(samples, &axis), &options)
        };
        (figures(&self.samples, window_frames), figures(&truth, 1))
    }

    /// RMS of [`Self::errors_mm`], `None` without a valid sample.
    pub fn rms_mm(&self) -> Option<f64> {
        let e = self.errors_mm();
        (!e.is_empty()).then(|| (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt())
    }
}

/// Both tracks of one control point.
#[derive(Debug, Clone)]
pub struct SkinTracking {
    /// Where the point was placed, camera px.
    pub placed_at: (f64, f64),
    /// Following the skin, as `track` and `analyze` give it (the window's mean undone where
    /// the decode gives the centre time: `tremor::window_mean`).
    pub follow: TrackAgainstTruth,
    /// Following the skin, as matched in each window's offset image (before that step).
    pub follow_window_mean: TrackAgainstTruth,
    pub fixed: TrackAgainstTruth,
}

/// Decodes frames `0..frames` of `rig` and tracks surface point `point` both ways.
pub fn skin_tracking(
    rig: &VirtualRig,
    params: DecodeParams,
    frames: u64,
    point: usize,
) -> Result<SkinTracking, SkinEvalError> {
    let config = &rig.config;
    let scene = Scene::new(config.scene.clone());
    let window = rig.sequence.entries.len() as f64;
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), config.cross_talk, params)?
        .with_max_span((window - 0.5) / config.fps);
    let triangulator = Triangulator::new(rig.stereo_model())?;
    let mut cloud = PointCloud::default();
    let mut image = TextureImage::default();
    let mut frame = rig.blank_frame();
    let mut points: Option<[ControlPoint; 2]> = None;
    let (mut follow, mut fixed) = (Vec::new(), Vec::new());
    let mut truth = Vec::new();
    let mut placed_at = (0.0, 0.0);
    let track = TrackOptions::default();
    let options = FollowOptions::default();
    for i in 0..frames {
        rig.render(i, &mut frame, None)?;
        let centre_s = frame.time_s - (window - 1.0) / 2.0 / config.fps;
        let decoded = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => {
                triangulator.triangulate(out, &mut cloud)?;
                true
            }
            WindowOutcome::Filling { .. } => continue,
            _ => false,
        };
        let time_s = if decoded { cloud.time_s } else { centre_s };
        let material = *scene
            .at(time_s)
            .points
            .get(point)
            .ok_or(SkinEvalError::NoPoint(point))?;
        if !decoded {
            if points.is_some() {
                let missing = TrackSample::missing(time_s, i as usize);
                follow.push(missing);
                fixed.push(missing);
                truth.push([material.x, material.y, material.z]);
            }
            continue;
        }
        let [a, b] = match points.as_mut() {
            Some(p) => p,
            None => {
                placed_at = config
                    .camera
                    .project(&material)
                    .filter(|&(u, v)| config.camera.contains(u, v))
                    .ok_or(SkinEvalError::NotSeen)?;
                points.insert([
                    ControlPoint::new(placed_at, PointMode::FollowSkin),
                    ControlPoint::new(placed_at, PointMode::FixedPixel),
                ])
            }
        };
        image.fill_from(&cloud);
        follow.push(a.measure(&cloud, &image, i as usize, &track, &options));
        fixed.push(b.measure(&cloud, &image, i as usize, &track, &options));
        truth.push([material.x, material.y, material.z]);
    }
    if points.is_none() {
        return Err(SkinEvalError::NothingDecoded);
    }
    let as_matched = follow.clone();
    if frames_averaged(&rig.sequence, &params) == 1 {
        undo_window_mean(&mut follow);
    }
    Ok(SkinTracking {
        placed_at,
        follow: TrackAgainstTruth {
            samples: follow,
            truth_mm: truth.clone(),
        },
        follow_window_mean: TrackAgainstTruth {
            samples: as_matched,
            truth_mm: truth.clone(),
        },
        fixed: TrackAgainstTruth {
            samples: fixed,
            truth_mm: truth,
        },
    })
}
