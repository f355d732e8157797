//! How a session is decoded: the unwrap method that follows from its sequence (or the one a user
//! asks for, when the sequence can take it), and the camera noise the decode's tests assume,
//! stated by the session or measured from its frames.
//!
//! Every command that decodes a session, and the GUI's replay, builds its
//! [`DecodeParams`] here, so that a session from another phase-shift scanner (a multi-frequency
//! sequence with the unit frequency) decodes without options, and so that the noise level the
//! Chebyshev checks assume is the camera's, not a constant. The noise is measured by
//! [`crate::decode::noise`] over up to [`NOISE_WINDOWS`] windows spread evenly through the
//! session; a session with too few well-lit pixels for a figure keeps the configured level, and
//! says so.

use super::{Session, SessionError};
use crate::decode::noise::{noise_from_samples, window_noise_samples, NoiseResidual};
use crate::decode::{DecodeParams, UnwrapMethod, WindowSolver};

/// Windows the noise is measured over, spread evenly through the session.
pub const NOISE_WINDOWS: usize = 5;

/// Where the decode's camera noise level comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseSource {
    /// `camera_noise_gray` in `session.json`.
    Stated,
    /// The frames' residuals ([`crate::decode::noise`]).
    Measured {
        windows: usize,
        samples: usize,
        residual: NoiseResidual,
    },
    /// Too few well-lit pixels to measure, or a sequence with no residual to measure it by: the
    /// configured level.
    Configured { why: &'static str },
}

/// The decode settings of one session, and where they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionDecoding {
    pub params: DecodeParams,
    /// Whether the unwrap method was asked for (else it follows from the sequence).
    pub method_requested: bool,
    pub noise_source: NoiseSource,
}

impl SessionDecoding {
    /// The settings for `session`: `base` with the unwrap method resolved against the session's
    /// sequence (`requested`, or the sequence's own) and the session's camera noise.
    pub fn new(
        session: &Session,
        requested: Option<UnwrapMethod>,
        base: DecodeParams,
    ) -> Result<Self, SessionError> {
        let sequence = session.sequence()?;
        let (unwrap, method_requested) = UnwrapMethod::resolve(requested, &sequence)?;
        let mut params = DecodeParams { unwrap, ..base };
        let noise_source = match session.manifest.camera_noise_gray {
            Some(stated) => {
                params.camera_noise_gray = stated as f32;
                NoiseSource::Stated
            }
            None => match measure_camera_noise(session, &params)? {
                Measured::Level {
                    noise_gray,
                    windows,
                    samples,
                    residual,
                } => {
                    params.camera_noise_gray = noise_gray;
                    NoiseSource::Measured {
                        windows,
                        samples,
                        residual,
                    }
                }
                Measured::TooFew => NoiseSource::Configured {
                    why: "too few well-lit pixels to measure it",
                },
                Measured::NoResidual => NoiseSource::Configured {
                    why: "the sequence has no redundant observation to measure it by",
                },
            },
        };
        Ok(Self {
            params,
            method_requested,
            noise_source,
        })
    }

    /// One line for a report: the method and the noise level, with where each comes from.
    pub fn describe(&self) -> String {
        let method = if self.method_requested {
            "as requested"
        } else {
            "from the sequence"
        };
        let noise = match self.noise_source {
            NoiseSource::Stated => "stated by the session".to_string(),
            NoiseSource::Measured {
                windows,
                samples,
                residual,
            } => format!(
                "measured from the {} residual of {samples} well-lit pixels in {windows} window(s)",
                match residual {
                    NoiseResidual::Fit { .. } => "window fit's",
                    NoiseResidual::Chebyshev => "Chebyshev",
                }
            ),
            NoiseSource::Configured { why } => format!("the default: {why}"),
        };
        let used = if self.params.unwrap == UnwrapMethod::Temporal {
            "; the temporal unwrap does not test against it"
        } else {
            ""
        };
        format!(
            "unwrap {} ({method}), camera noise {:.2} gray levels ({noise}{used})",
            self.params.unwrap, self.params.camera_noise_gray
        )
    }
}

/// What [`measure_camera_noise`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    Level {
        noise_gray: f32,
        windows: usize,
        samples: usize,
        residual: NoiseResidual,
    },
    TooFew,
    NoResidual,
}

/// The camera noise of `session`'s frames, pooled over up to [`NOISE_WINDOWS`] windows spread
/// evenly through it (`params` give the amplitude and saturation limits of a usable pixel).
/// A window whose patterns do not make a solvable window, or one of whose frames cannot be
/// read, is skipped.
pub fn measure_camera_noise(
    session: &Session,
    params: &DecodeParams,
) -> Result<Measured, SessionError> {
    let sequence = session.sequence()?;
    let cross_talk = session
        .cross_talk()?
        .unwrap_or_else(crate::color::CrossTalk::identity);
    let len = sequence.entries.len();
    let count = session.frame_count();
    if count < len {
        return Ok(Measured::TooFew);
    }
    let last_ends = count - len;
    let windows = NOISE_WINDOWS.min(last_ends + 1);
    let mut samples = Vec::new();
    let mut used = 0;
    let mut residual = None;
    for k in 0..windows {
        // Window starts spread evenly from the first frame to the last full window.
        let start = if windows > 1 {
            k * last_ends / (windows - 1)
        } else {
            0
        };
        // A frame that cannot be read (a damaged record) costs its window, not the decode:
        // the frames the user asked for may be fine, and their own read reports the damage.
        let Ok(frames) = (start..start + len)
            .map(|i| session.load_frame(i))
            .collect::<Result<Vec<_>, _>>()
        else {
            continue;
        };
        let order: Vec<usize> = frames.iter().map(|f| f.pattern_index).collect();
        let Ok(solver) = WindowSolver::new(&sequence, &order, &cross_talk) else {
            continue;
        };
        let found = window_noise_samples(
            &solver,
            &frames,
            params.min_amplitude,
            params.saturation_level,
            &mut samples,
        );
        if found.is_some() {
            residual = found;
            used += 1;
        }
    }
    let Some(residual) = residual else {
        return Ok(Measured::NoResidual);
    };
    let n = samples.len();
    Ok(match noise_from_samples(&mut samples) {
        Some(noise_gray) => Measured::Level {
            noise_gray,
            windows: used,
            samples: n,
            residual,
        },
        None => Measured::TooFew,
    })
}
