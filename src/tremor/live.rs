//! Control points tracked live: every cloud the pipeline produces updates each point's history
//! (the last [`LiveTracker::history_s`] seconds of scene time), from which the GUI draws the
//! displacement plot and the tremor panel.
//!
//! A point is placed at a camera pixel and, by default, follows the skin it was placed on
//! ([`super::control`]); in fixed-pixel mode it stays at the pixel, as in [`super::track`].
//! Dragging it places it anew and starts its history anew. When scene time goes backwards (a
//! replay was sought back) every history is cleared and every point placed anew at its pixel,
//! so a series never mixes two passes.

use super::analysis::{analyze, AnalysisOptions, TremorReport};
use super::control::{ControlPoint, PointMode};
use super::follow::{FollowOptions, TextureImage};
use super::track::{displacements, TrackOptions, TrackSample};
use super::window_mean::undo_window_mean;
use super::TremorError;
use crate::triangulate::PointCloud;
use nalgebra::Vector3;
use std::collections::VecDeque;

/// One control point and its recent samples.
#[derive(Debug, Clone)]
pub struct LivePoint {
    /// Stable identity (names can change).
    pub id: u64,
    pub name: String,
    /// Camera pixel the point was placed at, (u, v).
    pub pixel: (f64, f64),
    pub samples: VecDeque<TrackSample>,
    control: ControlPoint,
}

impl LivePoint {
    /// The pixel the point is at now (it moves with the skin when following it).
    pub fn current_pixel(&self) -> (f64, f64) {
        self.control.pixel()
    }

    /// Why the point measures nothing, when its skin shows too little texture to follow.
    pub fn follow_error(&self) -> Option<String> {
        self.control.error().map(ToString::to_string)
    }

    /// The history for analysis: as measured, and where the decode gives the window's centre
    /// time (`window_frames` 1) a followed point moved there too ([`undo_window_mean`]; the
    /// newest six samples stay as measured until their neighbours arrive).
    pub fn history(&self, window_frames: usize) -> Vec<TrackSample> {
        let mut samples: Vec<TrackSample> = self.samples.iter().copied().collect();
        if window_frames == 1 {
            undo_window_mean(&mut samples);
        }
        samples
    }

    /// Times (s) and displacements along `axis` (mm, relative to the median position; `None`
    /// where the point was not measured) of [`Self::history`].
    pub fn displacement_series(
        &self,
        axis: &Vector3<f64>,
        window_frames: usize,
    ) -> (Vec<f64>, Vec<Option<f64>>) {
        let samples = self.history(window_frames);
        let times = samples.iter().map(|s| s.time_s).collect();
        (times, displacements(&samples, axis))
    }

    /// The tremor figures of the history.
    pub fn analyze(
        &self,
        axis: &Vector3<f64>,
        options: &AnalysisOptions,
    ) -> Result<TremorReport, TremorError> {
        let (times, d) = self.displacement_series(axis, options.window_frames);
        analyze(&times, &d, options)
    }

    /// The newest measured position, camera frame, mm.
    pub fn latest_position_mm(&self) -> Option<[f64; 3]> {
        self.samples.back().and_then(|s| s.position_mm)
    }
}

/// The tracked control points.
#[derive(Debug, Clone)]
pub struct LiveTracker {
    pub points: Vec<LivePoint>,
    /// Scene seconds of history kept per point.
    pub history_s: f64,
    pub options: TrackOptions,
    pub follow: FollowOptions,
    /// Whether new points follow the skin or stay at their pixel ([`LiveTracker::set_mode`]).
    mode: PointMode,
    image: TextureImage,
    /// How the figures of the points are computed; its `window_frames` is the source's
    /// ([`crate::pipeline::Pipeline::frames_averaged`]).
    pub analysis: AnalysisOptions,
    /// Clouds seen so far.
    pub clouds_seen: u64,
    next_id: u64,
    last_time_s: Option<f64>,
}

impl LiveTracker {
    pub fn new(history_s: f64) -> Self {
        Self {
            points: Vec::new(),
            history_s,
            options: TrackOptions::default(),
            follow: FollowOptions::default(),
            mode: PointMode::default(),
            image: TextureImage::default(),
            analysis: AnalysisOptions::default(),
            clouds_seen: 0,
            next_id: 1,
            last_time_s: None,
        }
    }

    /// Adds a point at camera pixel `pixel`; returns its id.
    pub fn add(&mut self, name: impl Into<String>, pixel: (f64, f64)) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        self.points.push(LivePoint {
            id,
            name: name.into(),
            pixel,
            samples: VecDeque::new(),
            control: ControlPoint::new(pixel, self.mode),
        });
        id
    }

    pub fn mode(&self) -> PointMode {
        self.mode
    }

    /// Follows the skin or stays at fixed pixels: every point is placed anew at its pixel and
    /// its history restarts.
    pub fn set_mode(&mut self, mode: PointMode) {
        if mode != self.mode {
            self.mode = mode;
            self.clear_history();
        }
    }

    pub fn remove(&mut self, id: u64) -> bool {
        let before = self.points.len();
        self.points.retain(|p| p.id != id);
        self.points.len() != before
    }

    pub fn get(&self, id: u64) -> Option<&LivePoint> {
        self.points.iter().find(|p| p.id == id)
    }

    /// Moves a point to a new pixel; its history restarts (it is a different surface point).
    pub fn move_to(&mut self, id: u64, pixel: (f64, f64)) {
        if let Some(p) = self.points.iter_mut().find(|p| p.id == id) {
            p.pixel = pixel;
            p.samples.clear();
            p.control = ControlPoint::new(pixel, self.mode);
        }
    }

    pub fn rename(&mut self, id: u64, name: impl Into<String>) {
        if let Some(p) = self.points.iter_mut().find(|p| p.id == id) {
            p.name = name.into();
        }
    }

    /// Forgets every history (not the points).
    pub fn clear_history(&mut self) {
        for p in &mut self.points {
            p.samples.clear();
            p.control = ControlPoint::new(p.pixel, self.mode);
        }
        self.last_time_s = None;
    }

    /// Measures every point in `cloud` (the window ending at source frame `frame`).
    pub fn update(&mut self, cloud: &PointCloud, frame: usize) {
        self.clouds_seen += 1;
        if self.last_time_s.is_some_and(|t| cloud.time_s < t) {
            self.clear_history();
        }
        self.last_time_s = Some(cloud.time_s);
        let oldest_kept = cloud.time_s - self.history_s;
        if self.mode == PointMode::FollowSkin && !self.points.is_empty() {
            self.image.fill_from(cloud);
        }
        for p in &mut self.points {
            let sample = p
                .control
                .measure(cloud, &self.image, frame, &self.options, &self.follow);
            p.samples.push_back(sample);
            while p.samples.front().is_some_and(|s| s.time_s < oldest_kept) {
                p.samples.pop_front();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat_cloud(time_s: f64, z_mm: f32) -> PointCloud {
        let (w, h) = (20, 10);
        PointCloud {
            width: w,
            height: h,
            time_s,
            point_in_camera_mm: vec![[0.0, 0.0, z_mm]; w * h],
            colour_rgb: vec![[0, 0, 0]; w * h],
            fringe_amplitude: vec![1.0; w * h],
        }
    }

    #[test]
    fn keeps_the_history_window_and_measures_each_point() {
        let mut t = LiveTracker::new(1.0);
        t.set_mode(PointMode::FixedPixel);
        let a = t.add("a", (5.0, 5.0));
        let outside = t.add("outside", (50.0, 5.0));
        for k in 0..300 {
            t.update(&flat_cloud(k as f64 / 121.0, 500.0 + k as f32), k);
        }
        let pa = t.get(a).expect("point a");
        // 1 s at 121 Hz: samples from t − 1 s to t inclusive.
        assert_eq!(pa.samples.len(), 122);
        assert_eq!(pa.latest_position_mm(), Some([0.0, 0.0, 799.0]));
        let po = t.get(outside).expect("point outside");
        assert!(po.samples.iter().all(|s| s.position_mm.is_none()));
    }

    #[test]
    fn time_going_back_and_moving_a_point_restart_histories() {
        let mut t = LiveTracker::new(5.0);
        t.set_mode(PointMode::FixedPixel);
        let a = t.add("a", (5.0, 5.0));
        let b = t.add("b", (6.0, 5.0));
        for k in 0..10 {
            t.update(&flat_cloud(1.0 + k as f64 * 0.01, 500.0), k);
        }
        t.move_to(b, (7.0, 5.0));
        assert_eq!(t.get(a).map(|p| p.samples.len()), Some(10));
        assert_eq!(t.get(b).map(|p| p.samples.len()), Some(0));
        t.update(&flat_cloud(0.5, 500.0), 0);
        assert_eq!(t.get(a).map(|p| p.samples.len()), Some(1));
        t.rename(a, "index tip");
        assert_eq!(t.get(a).map(|p| p.name.as_str()), Some("index tip"));
        assert!(t.remove(a));
        assert!(!t.remove(a));
    }
}
