//! Tremor measurement: control points tracked in the organised cloud at a fixed pixel
//! ([`track`]) or following the skin ([`follow`], [`control`]; the decode window's mean undone
//! offline in [`window_mean`]), the
//! table's plane and frame ([`table`]), spectral tools
//! ([`spectrum`]), the clinical figures of a displacement series ([`analysis`]) and points
//! tracked live for the GUI ([`live`]).

pub mod analysis;
pub mod axes;
pub mod coherence;
pub mod control;
pub mod follow;
pub mod live;
pub mod measures;
pub mod spectrum;
pub mod table;
pub mod texture;
pub mod track;
pub mod window_mean;

pub use analysis::{analyze, AnalysisOptions, TremorReport};
pub use axes::{principal_axis, summed_spectrum_peak, DisplacementAxis};
pub use control::{ControlPoint, PointMode};
pub use follow::{locate_subpixel, FollowError, FollowOptions, SkinFollower, TextureImage};
pub use live::{LivePoint, LiveTracker};
pub use table::{fit_table_normal, fit_table_plane, TableFrame, TablePlane};
pub use track::{
    displacements, locate, pixel_of, MissingSamples, SurfaceSlope, TrackOptions, TrackSample,
    VerticalAxis,
};
pub use window_mean::undo_window_mean;

/// Errors of tremor analysis.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TremorError {
    #[error("{times} time stamps but {values} values")]
    Lengths { times: usize, values: usize },
    #[error(
        "only {valid} valid samples; the analysis needs at least 4 (is the point on the hand?)"
    )]
    TooFewSamples { valid: usize },
    /// Too little of the record was measured for honest figures: rather no figure than one
    /// made from gaps.
    #[error("figures missing: {why}")]
    TooFewValid { why: String },
    #[error("the record is {duration_s:.2} s long, too short for a spectrum")]
    TooShort { duration_s: f64 },
    #[error(
        "samples come at {rate_hz:.1} Hz, too slow for the {band_hi_hz} Hz band (at least {needed_hz} Hz is needed)"
    )]
    RateTooLow {
        rate_hz: f64,
        band_hi_hz: f64,
        needed_hz: f64,
    },
}
