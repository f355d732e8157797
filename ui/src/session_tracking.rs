//! Control points tracked through a session, as `track`, `analyze`, `batch` and the exports
//! need them: the session decoded window by window with one sliding decoder (so the motion
//! model sees the stream), each window triangulated, and each point measured in the organised
//! cloud as a `tremor::ControlPoint`: following the skin it was placed on in the first decoded
//! window (the default), or at its fixed pixel (`--fixed-pixel`). Once the session is done, a
//! followed track is moved from the decode window's mean to its centre time
//! (`tremor::window_mean`). A point whose skin shows too little texture to follow is an error
//! that names it. A window that does not decode is an invalid sample of every point, never a
//! skipped one, so the samples stay one per window. The table plane is fitted in the first
//! decoded window: it gives the vertical axis when asked for (`table`) and the table frame the
//! exports use.

use crate::progress::Progress;
use anyhow::{bail, Context, Result};
use nalgebra::Vector3;
use tremorscan::decode::{frames_averaged, DecodeParams, SlidingDecoder, WindowOutcome};
use tremorscan::export::{MotionFrame, PointTrack, TrialMotion};
use tremorscan::session::Session;
use tremorscan::tremor::{
    fit_table_plane, undo_window_mean, ControlPoint, FollowOptions, PointMode, TableFrame,
    TablePlane, TextureImage, TrackOptions, TrackSample,
};
use tremorscan::triangulate::{PointCloud, Triangulator};

/// How tracking reports: a progress bar on the terminal, or nothing, stopping as soon as `stop`
/// is set (a batch interrupted with Ctrl-C).
#[derive(Clone, Copy)]
pub enum Feedback<'a> {
    ProgressBar,
    Quiet {
        stop: &'a std::sync::atomic::AtomicBool,
    },
}

/// The control points tracked through a session.
pub struct SessionTracks {
    /// Per point: its samples, one per window (refused windows included, as invalid samples).
    pub tracks: Vec<Vec<TrackSample>>,
    /// The unit vertical axis the displacements are taken along.
    pub axis: Vector3<f64>,
    /// The table's plane, fitted in the first decoded window.
    pub table: Option<TablePlane>,
    /// The camera's frame rate, Hz.
    pub frame_rate_hz: f64,
}

impl SessionTracks {
    /// The tracks as a trial's motion for the exports: in the table frame when the table was
    /// found, else in the camera frame. `names` has one name per point.
    pub fn motion(&self, names: &[String]) -> TrialMotion {
        let table = self.table.as_ref().and_then(TableFrame::on);
        let times_s = self
            .tracks
            .first()
            .map(|t| t.iter().map(|s| s.time_s).collect())
            .unwrap_or_default();
        let points = self
            .tracks
            .iter()
            .zip(names)
            .map(|(track, name)| PointTrack {
                name: name.clone(),
                positions_mm: track
                    .iter()
                    .map(|s| {
                        s.position_mm
                            .map(|p| table.as_ref().map_or(p, |f| f.table_from_camera(p)))
                    })
                    .collect(),
            })
            .collect();
        TrialMotion {
            sampling_hz: self.frame_rate_hz,
            times_s,
            points,
            frame: if table.is_some() {
                MotionFrame::Table
            } else {
                MotionFrame::Camera
            },
        }
    }
}

/// `--fixed-pixel`, shared by the commands that track control points.
#[derive(clap::Args, Debug, Clone, Copy, Default)]
pub struct PointModeArgs {
    /// Keep each control point at its camera pixel (the surface passing it), instead of
    /// following the skin it was placed on.
    #[arg(long)]
    pub fixed_pixel: bool,
}

impl PointModeArgs {
    pub fn mode(self) -> PointMode {
        if self.fixed_pixel {
            PointMode::FixedPixel
        } else {
            PointMode::FollowSkin
        }
    }
}

/// Tracks `points` (placed at these pixels, moving as `mode` says) through every window of
/// `session` decoded with `params`; `vertical` as `--vertical` takes it. `feedback`: a progress
/// bar, or quiet with a stop flag (a batch).
pub fn track_session(
    session: &Session,
    points: &[(f64, f64)],
    mode: PointMode,
    vertical: Option<&str>,
    params: DecodeParams,
    feedback: Feedback<'_>,
) -> Result<SessionTracks> {
    let sequence = session.sequence()?;
    let (w, h) = session.camera_size();
    for &(u, v) in points {
        if !(u >= 0.0 && v >= 0.0 && u < w as f64 && v < h as f64) {
            bail!("point {u},{v} lies outside the {w}×{h} camera image");
        }
    }
    let fps = session.frame_rate_hz();
    let cross_talk = session
        .cross_talk()?
        .unwrap_or_else(tremorscan::color::CrossTalk::identity);
    let window = sequence.entries.len() as f64;
    // Where the decode gives the depth at the window's centre time, a followed point's lateral
    // position is moved there too (`tremor::window_mean`).
    let undo_mean = mode == PointMode::FollowSkin && frames_averaged(&sequence, &params) == 1;
    let mut decoder = SlidingDecoder::new(sequence, cross_talk, params)?
        .with_max_span((window - 0.5) / fps.max(1e-3));
    let triangulator = Triangulator::new(session.stereo_model()?)?;
    let mut cloud = PointCloud::default();
    let mut tracks = vec![Vec::new(); points.len()];
    let mut controls: Vec<ControlPoint> =
        points.iter().map(|&p| ControlPoint::new(p, mode)).collect();
    let mut image = TextureImage::default();
    let (track_options, follow_options) = (TrackOptions::default(), FollowOptions::default());
    let mut axis = match vertical {
        None => Some(Vector3::z()),
        Some("table") => None,
        Some(text) => {
            let v: Vec<f64> = text
                .split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--vertical {text}: expected X,Y,Z or `table`"))?;
            let v = (v.len() == 3)
                .then(|| Vector3::new(v[0], v[1], v[2]))
                .and_then(|v| v.try_normalize(1e-12))
                .with_context(|| format!("--vertical {text}: needs three numbers, not all 0"))?;
            Some(v)
        }
    };
    let mut table = None;
    let mut progress = matches!(feedback, Feedback::ProgressBar)
        .then(|| Progress::new("tracking", session.frame_count()));
    for i in 0..session.frame_count() {
        if let Feedback::Quiet { stop } = feedback {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                bail!("interrupted");
            }
        }
        let frame = session.load_frame(i)?;
        let centre_s = frame.time_s - (window - 1.0) / 2.0 / fps.max(1e-3);
        let decoded = match decoder.push(&frame)? {
            WindowOutcome::Decoded(out) => {
                triangulator.triangulate(out, &mut cloud)?;
                true
            }
            WindowOutcome::Filling { .. } => continue,
            _ => false,
        };
        if decoded && table.is_none() {
            table = fit_table_plane(&cloud);
            if axis.is_none() {
                axis = table.map(|t| t.normal);
            }
        }
        if decoded && mode == PointMode::FollowSkin {
            image.fill_from(&cloud);
        }
        for (k, (track, control)) in tracks.iter_mut().zip(&mut controls).enumerate() {
            track.push(if decoded {
                control.measure(&cloud, &image, i, &track_options, &follow_options)
            } else {
                TrackSample::missing(centre_s, i)
            });
            if let Some(e) = control.error() {
                bail!("point {k}: {e} (--fixed-pixel)");
            }
        }
        if let Some(p) = progress.as_mut() {
            p.step(i + 1);
        }
    }
    if let Some(p) = progress.as_mut() {
        p.finish();
    }
    if undo_mean {
        tracks.iter_mut().for_each(|t| undo_window_mean(t));
    }
    let axis = axis.context("no window decoded, so no table plane could be fitted")?;
    Ok(SessionTracks {
        tracks,
        axis,
        table,
        frame_rate_hz: fps,
    })
}
