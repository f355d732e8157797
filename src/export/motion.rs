//! The control points' trajectories of one trial, as the study exports take them: one position
//! per decoded window (or none where the point was not measured), at the camera's frame rate,
//! in a named coordinate frame.
//!
//! Positions are kept as measured; a sample that was not measured stays `None` and each format
//! writes it as that format's missing value (`n/a` in Motion-BIDS, a negative residual in C3D,
//! an empty cell in CSV). Nothing is interpolated.

/// The frame the positions are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionFrame {
    /// The camera frame: `x` along image rows, `y` down the image, `z` along the optical axis.
    Camera,
    /// The table frame of [`crate::tremor::TableFrame`]: origin where the optical axis meets
    /// the table, `z` up out of the table.
    Table,
}

impl MotionFrame {
    /// The frame's name as the exports write it.
    pub fn name(self) -> &'static str {
        match self {
            MotionFrame::Camera => "camera",
            MotionFrame::Table => "table",
        }
    }

    /// One sentence on the axes, for the exports' descriptions.
    pub fn description(self) -> &'static str {
        match self {
            MotionFrame::Camera => {
                "camera frame: x along the image rows, y down the image, z along the optical axis away from the camera"
            }
            MotionFrame::Table => {
                "table frame: origin where the camera's optical axis meets the fitted table plane, z up out of the table, x the camera's x axis projected onto the table, y = z × x"
            }
        }
    }
}

/// One control point's positions, mm, one per sample of [`TrialMotion::times_s`].
#[derive(Debug, Clone, PartialEq)]
pub struct PointTrack {
    pub name: String,
    pub positions_mm: Vec<Option<[f64; 3]>>,
}

/// The tracked control points of one trial.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialMotion {
    /// The nominal sampling rate: the camera's frame rate, Hz.
    pub sampling_hz: f64,
    /// Each sample's time (the decoded window's centre), s.
    pub times_s: Vec<f64>,
    pub points: Vec<PointTrack>,
    pub frame: MotionFrame,
}

impl TrialMotion {
    /// The number of samples.
    pub fn samples(&self) -> usize {
        self.times_s.len()
    }

    /// The time from the first sample to one period after the last, s (0 without samples).
    pub fn duration_s(&self) -> f64 {
        match (self.times_s.first(), self.times_s.last()) {
            (Some(a), Some(b)) if self.sampling_hz > 0.0 => b - a + 1.0 / self.sampling_hz,
            _ => 0.0,
        }
    }

    /// `Err` naming the problem when the samples and points do not fit together.
    pub fn check(&self) -> Result<(), String> {
        if !(self.sampling_hz.is_finite() && self.sampling_hz > 0.0) {
            return Err(format!(
                "sampling rate {} Hz is not positive",
                self.sampling_hz
            ));
        }
        if self.points.is_empty() {
            return Err("no control points to export".into());
        }
        for p in &self.points {
            if p.positions_mm.len() != self.times_s.len() {
                return Err(format!(
                    "point `{}` has {} positions for {} samples",
                    p.name,
                    p.positions_mm.len(),
                    self.times_s.len()
                ));
            }
        }
        Ok(())
    }
}
