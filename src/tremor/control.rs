//! A control point as the product measures it, window after window: following the skin it was
//! placed on (the default) or at a fixed camera pixel (today's behaviour before skin
//! following, kept for comparison and for surfaces without texture).
//!
//! Following: the first cloud the point sees gives its template ([`SkinFollower::new`]); every
//! later one moves the pixel with the skin ([`SkinFollower::follow`]), and the 3D position is
//! read at the sub-pixel match ([`locate_subpixel`]). A window where the patch is not found is
//! an invalid sample. A point whose skin shows too little texture keeps the reason
//! ([`ControlPoint::error`]) and measures nothing: it is never silently turned into a fixed
//! pixel. Fixed pixel: [`super::locate`] at the pixel, as before.

use super::follow::{locate_subpixel, FollowError, FollowOptions, SkinFollower, TextureImage};
use super::track::{locate, TrackOptions, TrackSample};
use crate::triangulate::PointCloud;

/// How a control point moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PointMode {
    /// It follows the skin patch it was placed on.
    #[default]
    FollowSkin,
    /// It stays at its camera pixel.
    FixedPixel,
}

/// One control point's state between windows.
#[derive(Debug, Clone)]
pub struct ControlPoint {
    /// Where the point was placed, camera px.
    pub placed_at: (f64, f64),
    pub mode: PointMode,
    follower: Option<SkinFollower>,
    error: Option<FollowError>,
}

impl ControlPoint {
    pub fn new(placed_at: (f64, f64), mode: PointMode) -> Self {
        Self {
            placed_at,
            mode,
            follower: None,
            error: None,
        }
    }

    /// Why the point cannot follow the skin (it then measures nothing), if so.
    pub fn error(&self) -> Option<&FollowError> {
        self.error.as_ref()
    }

    /// The pixel the point is at now: its last match (or where it was lost), else where it
    /// was placed.
    pub fn pixel(&self) -> (f64, f64) {
        self.follower
            .as_ref()
            .map_or(self.placed_at, SkinFollower::pixel)
    }

    /// Measures the point in `cloud` (whose luminance is `image`, filled by the caller once per
    /// cloud for all points), the window ending at source frame `frame`. A followed point's
    /// sample keeps the surface's slope at the match, for [`super::undo_window_mean`].
    pub fn measure(
        &mut self,
        cloud: &PointCloud,
        image: &TextureImage,
        frame: usize,
        track: &TrackOptions,
        follow: &FollowOptions,
    ) -> TrackSample {
        let (pixel, located) = match self.mode {
            PointMode::FixedPixel => (
                Some(self.placed_at),
                locate(cloud, self.placed_at, track).map(|p| (p, None)),
            ),
            PointMode::FollowSkin => {
                let matched = match (&mut self.follower, &self.error) {
                    (_, Some(_)) => None,
                    (Some(f), None) => f.follow(image),
                    (None, None) => match SkinFollower::new(image, self.placed_at, *follow) {
                        Ok(f) => {
                            self.follower = Some(f);
                            Some(self.placed_at)
                        }
                        Err(e) => {
                            self.error = Some(e);
                            None
                        }
                    },
                };
                let located = matched
                    .and_then(|p| locate_subpixel(cloud, p, track))
                    .map(|(p, slope)| (p, Some(slope)));
                (matched, located)
            }
        };
        TrackSample {
            time_s: cloud.time_s,
            frame,
            pixel,
            position_mm: located.map(|(p, _)| p),
            slope_mm_per_px: located.and_then(|(_, slope)| slope),
        }
    }
}
