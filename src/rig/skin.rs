//! The skin's texture: what a camera sees of creases, pores and the blood under it, which is
//! what lets a tracker follow a patch of skin rather than a pixel.
//!
//! Real skin seen at about 0.4 mm per pixel shows a faint, irregular brightness pattern, a few
//! per cent deep, at scales of one to several millimetres. The rig prints such a pattern into
//! the skin's albedo: a sum of plane waves with incommensurate directions and wavelengths of
//! 1.6–7 mm, evaluated at the hit's position on the hand *at rest* (each part's `rest_from_hand`),
//! so the texture is carried by the skin as the fingers flex and the hand sways and rolls. It is
//! smooth (no feature finer than the lens resolves) and has no dominant direction, so a tracker
//! cannot lock onto one fringe of it.

use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Plane waves: direction (unnormalised), wavelength mm, phase rad, weight.
const WAVES: [([f64; 3], f64, f64, f64); 8] = [
    ([1.0, 0.31, 0.12], 6.9, 0.4, 1.0),
    ([-0.27, 1.0, 0.45], 5.3, 2.1, 0.9),
    ([0.62, -0.78, 0.2], 4.1, 4.0, 0.8),
    ([0.18, 0.52, 1.0], 3.7, 1.3, 0.7),
    ([-0.91, -0.35, 0.6], 2.9, 5.2, 0.6),
    ([0.44, 0.9, -0.7], 2.3, 0.9, 0.5),
    ([0.83, -0.12, -0.55], 1.9, 3.3, 0.4),
    ([-0.5, 0.66, -0.31], 1.6, 2.7, 0.35),
];

/// The skin's relative albedo at `rest_point_mm` (the point on the hand at rest, mm):
/// `1 + contrast·n` with `n` a fixed pattern of zero mean and unit RMS, clamped to stay
/// positive. `contrast` 0 is uniform skin.
pub fn skin_texture(rest_point_mm: &V3, contrast: f64) -> f64 {
    if contrast == 0.0 {
        return 1.0;
    }
    let mut sum = 0.0;
    let mut power = 0.0;
    for (direction, wavelength_mm, phase, weight) in WAVES {
        let d = V3::from(direction).normalize();
        sum +=
            weight * (std::f64::consts::TAU * d.dot(rest_point_mm) / wavelength_mm + phase).sin();
        power += 0.5 * weight * weight;
    }
    (1.0 + contrast * sum / power.sqrt()).max(0.05)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_texture_has_the_set_contrast_and_no_mean() {
        let (mut sum, mut sum_sq, mut n) = (0.0, 0.0, 0.0);
        for i in 0..60 {
            for j in 0..60 {
                let p = V3::new(
                    f64::from(i) * 0.37,
                    f64::from(j) * 0.41,
                    3.0 + 0.1 * f64::from(i),
                );
                let a = skin_texture(&p, 0.1) - 1.0;
                sum += a;
                sum_sq += a * a;
                n += 1.0;
            }
        }
        let (mean, rms) = (sum / n, (sum_sq / n).sqrt());
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((rms - 0.1).abs() < 0.02, "rms {rms}");
        assert_eq!(skin_texture(&V3::new(1.0, 2.0, 3.0), 0.0), 1.0);
    }
}
