//! The camera's optical blur: a Gaussian point-spread function over the image's linear signal,
//! applied after the scene is shaded and before the sensor adds its noise and quantises.
//!
//! Real lenses blur. A camera pixel then sees light from its neighbours' surfaces too, and at a
//! depth edge (a finger's outline over the table) it mixes two fringe signals that code
//! different projector coordinates: the mixed pixels the decoder must refuse. The rig shades one
//! ray per pixel, so without this stage it never shows them.
//!
//! The PSF is the lens's Gaussian of width `σ` (pixels of the rendered image) integrated over
//! each pixel's square footprint: separable, each weight the Gaussian's mean over a pixel
//! (`±⌈3σ⌉ + 1` pixels, normalised), run along rows and then along columns, the image's border
//! extended by its edge pixels. For `σ ≥ 1` its variance is `σ² + 1/12` px² (narrower lenses
//! leave most of the light in the centre pixel). The default `σ = 0.4`
//! ([`super::RigConfig::paper`]) is a lens of about 1.2 sensor pixels FWHM at the 2×–3× binning
//! of the rig's usual sizes; with the footprint the PSF is about 1.2 px FWHM, and a pixel next to
//! a depth edge takes 10.6 % of its light from the other side.

use rayon::prelude::*;

/// Samples per pixel of the numerical integral over its footprint.
const FOOTPRINT_SAMPLES: usize = 32;

/// The normalised kernel of a lens of width `sigma_px`, from −radius to +radius; `None` for no
/// blur.
pub fn kernel(sigma_px: f64) -> Option<Vec<f32>> {
    if !(sigma_px.is_finite() && sigma_px > 0.0) {
        return None;
    }
    let radius = (3.0 * sigma_px).ceil() as i64 + 1;
    let gauss = |t: f64| (-t * t / (2.0 * sigma_px * sigma_px)).exp();
    // The midpoint rule over [d − ½, d + ½].
    let weights: Vec<f64> = (-radius..=radius)
        .map(|d| {
            (0..FOOTPRINT_SAMPLES)
                .map(|k| gauss(d as f64 - 0.5 + (k as f64 + 0.5) / FOOTPRINT_SAMPLES as f64))
                .sum::<f64>()
        })
        .collect();
    let sum: f64 = weights.iter().sum();
    Some(weights.iter().map(|w| (w / sum) as f32).collect())
}

/// Blurs an interleaved image of `channels` planes (`width × height × channels` values) in
/// place with the separable `kernel`; `scratch` is resized and reused.
pub fn blur(
    image: &mut [f32],
    width: usize,
    height: usize,
    channels: usize,
    kernel: &[f32],
    scratch: &mut Vec<f32>,
) {
    let radius = kernel.len() / 2;
    let row_len = width * channels;
    scratch.resize(image.len(), 0.0);
    // Along rows: image → scratch.
    image
        .par_chunks(row_len)
        .zip(scratch.par_chunks_mut(row_len))
        .for_each(|(src, dst)| {
            for x in 0..width {
                for c in 0..channels {
                    let mut acc = 0.0;
                    for (k, &w) in kernel.iter().enumerate() {
                        let xs = (x + k).saturating_sub(radius).min(width - 1);
                        acc += w * src[xs * channels + c];
                    }
                    dst[x * channels + c] = acc;
                }
            }
        });
    // Along columns: scratch → image.
    let src: &[f32] = scratch;
    image
        .par_chunks_mut(row_len)
        .enumerate()
        .for_each(|(y, dst)| {
            dst.fill(0.0);
            for (k, &w) in kernel.iter().enumerate() {
                let ys = (y + k).saturating_sub(radius).min(height - 1);
                let row = &src[ys * row_len..(ys + 1) * row_len];
                for (d, s) in dst.iter_mut().zip(row) {
                    *d += w * s;
                }
            }
        });
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn the_kernel_is_normalised_and_has_the_width_asked_for() {
        assert!(kernel(0.0).is_none());
        assert!(kernel(f64::NAN).is_none());
        for sigma in [1.0, 1.5, 2.0] {
            let k = kernel(sigma).unwrap();
            let r = (k.len() / 2) as f64;
            let sum: f32 = k.iter().sum();
            let var: f64 = k
                .iter()
                .enumerate()
                .map(|(i, &w)| f64::from(w) * (i as f64 - r).powi(2))
                .sum();
            assert!((sum - 1.0).abs() < 1e-6);
            // The lens and the pixel's footprint: σ² + 1/12 (narrower: see the next test).
            let expected = sigma * sigma + 1.0 / 12.0;
            assert!(
                (var / expected - 1.0).abs() < 0.01,
                "σ {sigma}: {var} against {expected}"
            );
        }
    }

    #[test]
    fn a_blur_keeps_flat_images_and_spreads_a_step_by_its_width() {
        let (w, h) = (9, 5);
        let k = kernel(0.4).unwrap();
        let mut scratch = Vec::new();
        let mut flat = vec![7.0f32; w * h * 3];
        blur(&mut flat, w, h, 3, &k, &mut scratch);
        assert!(flat.iter().all(|&v| (v - 7.0).abs() < 1e-5));
        // A vertical step between columns 4 and 5, one channel.
        let mut step: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 5 { 0.0 } else { 1.0 })
            .collect();
        blur(&mut step, w, h, 1, &k, &mut scratch);
        let row = &step[2 * w..3 * w];
        // The pixel next to the edge on each side takes the other side's weight: the Gaussian's
        // mass from ½ to 1½ px, Φ(3.75) − Φ(1.25) = 10.6 %; two pixels away almost nothing.
        let side: f32 = k[k.len() / 2 + 1..].iter().sum();
        assert!((row[4] - side).abs() < 1e-6 && (row[5] - (1.0 - side)).abs() < 1e-6);
        assert!((side - 0.1056).abs() < 0.001, "{side}");
        assert!(row[3] < 1e-3 && row[6] > 0.999);
    }
}
