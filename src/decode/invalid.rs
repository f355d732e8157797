//! Reasons a pixel is invalid (bits of `DecodeOutput::invalid`); `0` means valid. A pixel may
//! carry several.

/// The smallest per-frequency amplitude is below `min_amplitude`: shadow, black surface, or
/// outside the projector's field.
pub const LOW_AMPLITUDE: u16 = 1;
/// A sample of the window reached the saturation level.
pub const SATURATED: u16 = 2;
/// The coarse estimate lies near half a period from the fine solution (eq. 8 rounding margin).
pub const UNWRAP_MARGIN: u16 = 4;
/// The unwrapped maps of the different frequencies disagree beyond their predicted noise.
pub const DISAGREEMENT: u16 = 8;
/// Too few connected neighbours supported the robust coarse estimate.
pub const LOW_SUPPORT: u16 = 16;
/// The coordinate falls outside `[0, x_max)`.
pub const OUT_OF_RANGE: u16 = 32;
/// A connected neighbour's coordinate differs by more than half a fringe period; with the
/// motion model, also the pixel's own coordinate one or two windows earlier (`temporal`).
pub const ORDER_JUMP: u16 = 64;
/// The motion inside the window is more than the motion model explains (a frame's phase
/// turns by more than [`super::motion::MAX_TURN_RAD`], or the model is near singular).
pub const MOTION: u16 = 128;
/// At a depth edge the pixel mixes two surfaces ([`super::edges`]): it touches a jump
/// between neighbourhoods whose coordinates disagree, or, bordering pixels without a code,
/// it is off its neighbourhood's surface, lit only by the blur of that surface's light, or
/// faces another surface across a one-pixel gap.
pub const MIXED: u16 = 256;
/// The whole window was refused: most of its lit pixels broke the phase relation, as a
/// corrupted frame makes them ([`super::broken`]).
pub const BROKEN_WINDOW: u16 = 512;
