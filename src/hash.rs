//! SplitMix64, the counter-based mixer behind the rig's noise and the calibration's sampling.

/// Mixes `z + golden ratio increment` into 64 well-distributed bits (SplitMix64). Stepping `z`
/// by the increment and mixing each value gives the SplitMix64 sequence.
#[inline]
pub(crate) fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(SPLITMIX_INCREMENT);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The golden-ratio increment of SplitMix64.
pub(crate) const SPLITMIX_INCREMENT: u64 = 0x9E37_79B9_7F4A_7C15;
