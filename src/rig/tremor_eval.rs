//! Tremor figures at a fingertip control point against the rig's truth: what `tremorscan
//! analyze` would report for the trembling hand, beside what it should report.
//!
//! The rig's frames `0..frames` are decoded by the sliding window (every window), triangulated
//! with the rig's exact calibration and tracked at the index fingertip's pixel at rest, as
//! `tremorscan analyze --point U,V` does ([`crate::tremor::locate`], displacement along the
//! optical axis). The truth is the surface seen along that pixel's ray at each sample's instant
//! (what a fixed-pixel track measures; following the skin is another matter), through the same
//! analysis without the decode window's compensation. Samples where the ray leaves the skin
//! (a large tremor carries the fingertip off its pixel) are missing in the truth too.

use super::{RigError, Scene, VirtualRig};
use crate::decode::{frames_averaged, DecodeError, DecodeParams, SlidingDecoder, WindowOutcome};
use crate::rig::scene::Material;
use crate::tremor::{
    analyze, displacements, locate, AnalysisOptions, TrackOptions, TrackSample, TremorError,
    TremorReport,
};
use crate::triangulate::{PointCloud, TriangulateError, Triangulator};
use nalgebra::Vector3;

/// Errors of the fingertip evaluation (the analysis's own refusals are results, not errors).
#[derive(Debug, thiserror::Error)]
pub enum TremorEvalError {
    #[error(transparent)]
    Rig(#[from] RigError),
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error(transparent)]
    Triangulate(#[from] TriangulateError),
    #[error("the rig has no hand, so there is no fingertip to track")]
    NoHand,
    #[error("the index fingertip at rest is outside the camera image")]
    TipNotSeen,
}

/// The measured and the true analysis at the fingertip's pixel.
#[derive(Debug)]
pub struct FingertipTremor {
    /// The control point, camera px.
    pub pixel: (f64, f64),
    /// What the decoder's track gives: figures, or why there are none.
    pub measured: Result<TremorReport, TremorError>,
    /// What the rig's truth at the same instants gives.
    pub truth: Result<TremorReport, TremorError>,
}

impl FingertipTremor {
    /// Measured peak-to-peak relative to the truth's, less one (`None` without both figures).
    pub fn peak_to_peak_error(&self) -> Option<f64> {
        let (m, t) = (self.measured.as_ref().ok()?, self.truth.as_ref().ok()?);
        (t.amplitude_peak_to_peak_mm > 0.0)
            .then(|| m.amplitude_peak_to_peak_mm / t.amplitude_peak_to_peak_mm - 1.0)
    }

    /// Measured peak frequency less the truth's, Hz (`None` without both peaks).
    pub fn frequency_error_hz(&self) -> Option<f64> {
        let m = self.measured.as_ref().ok()?.peak_frequency_hz?;
        let t = self.truth.as_ref().ok()?.peak_frequency_hz?;
        Some(m - t)
    }
}

/// Decodes frames `0..frames` of `rig` with `params` and analyses the index fingertip's pixel.
pub fn fingertip_tremor(
    rig: &VirtualRig,
    params: DecodeParams,
    frames: u64,
) -> Result<FingertipTremor, TremorEvalError> {
    let config = &rig.config;
    let scene = Scene::new(config.scene.clone());
    let tip = *scene
        .at(0.0)
        .points
        .first()
        .ok_or(TremorEvalError::NoHand)?;
    let pixel = config
        .camera
        .project(&tip)
        .filter(|&(u, v)| config.camera.contains(u, v))
        .ok_or(TremorEvalError::TipNotSeen)?;
    let window = rig.sequence.entries.len() as f64;
    let mut decoder = SlidingDecoder::new(rig.sequence.clone(), config.cross_talk, params)?
        .with_max_span((window - 0.5) / config.fps);
    let triangulator = Triangulator::new(rig.stereo_model())?;
    let mut cloud = PointCloud::default();
    let mut frame = rig.blank_frame();
    let mut samples = Vec::new();
    for i in 0..frames {
        rig.render(i, &mut frame, None)?;
        let centre_s = frame.time_s - (window - 1.0) / 2.0 / config.fps;
        let position_mm = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => {
                triangulator.triangulate(out, &mut cloud)?;
                locate(&cloud, pixel, &TrackOptions::default())
            }
            WindowOutcome::Filling { .. } => continue,
            _ => None,
        };
        samples.push(TrackSample {
            time_s: if position_mm.is_some() {
                cloud.time_s
            } else {
                centre_s
            },
            frame: i as usize,
            pixel: Some(pixel),
            position_mm,
            slope_mm_per_px: None,
        });
    }
    let ray = config
        .camera
        .ray(pixel.0, pixel.1)
        .map_err(RigError::from)?;
    let truth: Vec<TrackSample> = samples
        .iter()
        .map(|s| {
            let hit = scene
                .at(s.time_s)
                .intersect(&Vector3::zeros(), &ray, pixel)
                .filter(|h| h.material == Material::Skin);
            TrackSample {
                position_mm: hit.map(|h| {
                    let p = ray * h.distance_mm;
                    [p.x, p.y, p.z]
                }),
                ..*s
            }
        })
        .collect();
    Ok(FingertipTremor {
        pixel,
        measured: analysis(&samples, frames_averaged(&rig.sequence, &params)),
        truth: analysis(&truth, 1),
    })
}

/// The analysis along the optical axis; `window_frames` is the decode window the samples
/// average over (1 for exact truth).
fn analysis(samples: &[TrackSample], window_frames: usize) -> Result<TremorReport, TremorError> {
    let times: Vec<f64> = samples.iter().map(|s| s.time_s).collect();
    let displacement_mm = displacements(samples, &Vector3::z());
    let options = AnalysisOptions {
        window_frames,
        ..AnalysisOptions::default()
    };
    analyze(&times, &displacement_mm, &options)
}
