//! Branch-light f32 approximations used in the per-pixel hot loops.
//!
//! `atan2` reduces to `atan(t)` with `t = min/max ∈ [0, 1]` and evaluates the degree-9 odd minimax
//! polynomial of Abramowitz & Stegun 4.4.47 (|error| ≤ 1e-5 rad), then restores the octant with
//! selects that the compiler turns into blends, so loops over rows vectorise.
//!
//! [`whole_to_byte`] narrows `f32` to `u8` without Rust's saturating `as` cast, which LLVM
//! compiles to a scalar conversion per lane on x86 (about seven instructions each) and which
//! therefore kept whole loops from vectorising.
//!
//! [`sin_cos_small`] is the Taylor series of sine and cosine to degree 11 and 12 (truncation
//! below 6·10⁻⁸ for |x| ≤ π/2); [`sin_cos_phase`] extends it to a phase in `[0, 2π)` through the
//! half angle of `x − π` (two products, no branch).
//!
//! [`max_or_second`] and [`min_or_second`] are `max`/`min` as one x86 instruction. Rust's
//! `f32::max` ignores a NaN operand (IEEE maxNum), which x86 vector code implements with a compare
//! and a blend around each `maxps`; where a NaN operand cannot occur, or where taking the second
//! operand is what the caller wants, these save the two extra instructions.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// `a` if `a > b`, else `b` (so `b` when either is NaN): x86's `maxps`.
#[inline(always)]
pub fn max_or_second(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `a` if `a < b`, else `b` (so `b` when either is NaN): x86's `minps`.
#[inline(always)]
pub fn min_or_second(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `atan2(y, x)` in `(−π, π]`, max error about 1e-5 rad. Returns 0 for `(0, 0)`; unspecified
/// for NaN.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let big = max_or_second(ax, ay);
    let small = min_or_second(ax, ay);
    let t = if big > 0.0 { small / big } else { 0.0 };
    let t2 = t * t;
    let p = t
        * (0.999_866
            + t2 * (-0.330_299_5 + t2 * (0.180_141 + t2 * (-0.085_133 + t2 * 0.020_835_1))));
    let r = if ay > ax { FRAC_PI_2 - p } else { p };
    let r = if x < 0.0 { PI - r } else { r };
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// `atan2(y, x)` mapped to `[0, 2π)`.
#[inline]
pub fn phase_0_tau(y: f32, x: f32) -> f32 {
    let a = atan2(y, x);
    if a < 0.0 {
        a + TAU
    } else {
        a
    }
}

/// The byte of a whole number `v` in `[0, 255]`, for values such as sums of flag bits.
///
/// Adding 2²³ moves `v` into the mantissa's low bits exactly (the sum's exponent fixes one unit
/// per bit), so the low byte of the bit pattern is `v`: a float add, a bit cast and a truncation,
/// which all vectorise. Other inputs give an unspecified byte; use [`colour_byte`] for those.
#[inline(always)]
pub fn whole_to_byte(v: f32) -> u8 {
    const TWO_POW_23: f32 = 8_388_608.0;
    // Truncation to the low byte is the intent.
    (v + TWO_POW_23).to_bits() as u8
}

/// The validity flags of a whole number `v` in `[0, 65535]` (a sum of flag bits), as
/// [`whole_to_byte`] but keeping the low 16 bits.
#[inline(always)]
pub fn whole_to_flags(v: f32) -> u16 {
    const TWO_POW_23: f32 = 8_388_608.0;
    // Truncation to the low 16 bits is the intent.
    (v + TWO_POW_23).to_bits() as u16
}

/// `v` clamped to `[0, 255]` and truncated toward zero, as a byte; NaN gives 0. Equal to
/// `v.clamp(0.0, 255.0) as u8` for every input, but vectorises (see [`whole_to_byte`]).
#[inline(always)]
#[allow(
    clippy::manual_clamp,
    reason = "`clamp` keeps NaN; `max` maps it to 0, as the cast this replaces does"
)]
pub fn colour_byte(v: f32) -> u8 {
    whole_to_byte(v.max(0.0).min(255.0).floor())
}

/// `(sin x, cos x)` for `|x| ≤ π/2`, within about 1e-7.
#[inline(always)]
pub fn sin_cos_small(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let s = x
        * (1.0
            + x2 * (-1.0 / 6.0
                + x2 * (1.0 / 120.0
                    + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0 - x2 / 39_916_800.0)))));
    let c = 1.0
        + x2 * (-0.5
            + x2 * (1.0 / 24.0
                + x2 * (-1.0 / 720.0
                    + x2 * (1.0 / 40_320.0 + x2 * (-1.0 / 3_628_800.0 + x2 / 479_001_600.0)))));
    (s, c)
}

/// `(sin x, cos x)` for a phase `x ∈ [0, 2π)`, within about 3e-7: with `y = (x − π)/2`,
/// `sin x = −2·sin y·cos y` and `cos x = 2·sin²y − 1`.
#[inline(always)]
pub fn sin_cos_phase(x: f32) -> (f32, f32) {
    let (s, c) = sin_cos_small(0.5 * (x - PI));
    (-2.0 * s * c, 2.0 * s * s - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_error_below_2e_5_everywhere() {
        let mut worst = 0f32;
        for i in 0..20_000 {
            let angle = -PI + TAU * (i as f32 + 0.5) / 20_000.0;
            for r in [1e-3f32, 1.0, 250.0] {
                let (y, x) = (r * angle.sin(), r * angle.cos());
                let err = (atan2(y, x) - y.atan2(x)).abs();
                let err = err.min((err - TAU).abs());
                worst = worst.max(err);
            }
        }
        assert!(worst < 2e-5, "worst error {worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!((phase_0_tau(-1.0, 1.0) - 7.0 * PI / 4.0).abs() < 2e-5);
    }

    #[test]
    fn max_and_min_take_the_second_operand_on_nan() {
        assert_eq!(max_or_second(2.0, -1.0), 2.0);
        assert_eq!(max_or_second(-1.0, 2.0), 2.0);
        assert_eq!(min_or_second(2.0, -1.0), -1.0);
        assert_eq!(min_or_second(-1.0, 2.0), -1.0);
        assert_eq!(max_or_second(f32::NAN, 3.0), 3.0);
        assert!(max_or_second(3.0, f32::NAN).is_nan());
        assert_eq!(min_or_second(f32::NAN, 3.0), 3.0);
        assert!(min_or_second(3.0, f32::NAN).is_nan());
    }

    #[test]
    fn byte_conversions_equal_the_saturating_cast() {
        for v in 0..=255u8 {
            assert_eq!(whole_to_byte(f32::from(v)), v);
        }
        // Floats 0.001 apart across and around the byte range, the limits and special values.
        let mut values = vec![
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
            -0.0,
            1e-30,
            255.999_98,
            256.0,
            1e9,
        ];
        values.extend((-2_000..270_000).map(|i| i as f32 * 1e-3));
        for v in values {
            assert_eq!(colour_byte(v), v.clamp(0.0, 255.0) as u8, "{v}");
        }
    }

    #[test]
    fn sine_and_cosine_match_libm() {
        let mut worst = 0f64;
        for i in 0..=20_000 {
            let x = (i as f64 / 20_000.0) * std::f64::consts::TAU * 0.999_999;
            let (s, c) = sin_cos_phase(x as f32);
            worst = worst
                .max((f64::from(s) - x.sin()).abs())
                .max((f64::from(c) - x.cos()).abs());
            let small = (i as f64 / 10_000.0 - 1.0) * std::f64::consts::FRAC_PI_2;
            let (s, c) = sin_cos_small(small as f32);
            worst = worst
                .max((f64::from(s) - small.sin()).abs())
                .max((f64::from(c) - small.cos()).abs());
        }
        // f32 rounding of the argument (6e-8 · x) and of the products, and the truncation.
        assert!(worst < 1e-6, "worst {worst}");
    }
}
