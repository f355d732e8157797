//! Branch-light f32 approximations used in the per-pixel hot loops.
//!
//! `atan2` reduces to `atan(t)` with `t = min/max ∈ [0, 1]` and evaluates the degree-9 odd minimax
//! polynomial of Abramowitz & Stegun 4.4.47 (|error| ≤ 1e-5 rad), then restores the octant with
//! selects that the compiler turns into blends, so loops over rows vectorise.

use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// `atan2(y, x)` in `(−π, π]`, max error about 1e-5 rad. Returns 0 for `(0, 0)`.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let big = ax.max(ay);
    let small = ax.min(ay);
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
}
