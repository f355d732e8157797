//! Stage 2 for the skin that moves: a second, wider average of the unit phasor, carried along
//! the fine phase, gives the coarse coordinate of every pixel the motion model found moving
//! ([`super::MotionParams::moving_unit_decay`]); still pixels keep the narrow plain average.
//!
//! **Why two averages.** The coarse coordinate only has to pick the fringe order, and on a
//! moving surface its unit phase is the weakest link: it carries the coordinate 10.35 times
//! more coarsely than a fine phase, and the ripple that an imperfect velocity leaves in it (on
//! the flanks of a finger swaying sideways the velocity steepens towards the outline faster
//! than any patch follows) moves it by tenths of a period. A wider average removes that ripple,
//! and carried along the fine phase ([`super::smooth_transport`]) it is not biased by the
//! coordinate's gradient or curvature however wide it is. On still skin, though, the wider
//! average costs what docs/accuracy.md (Motion, stop 37) measured: behind a soft lens it keeps
//! more of the outlines' mixed pixels, and in a window with a corrupted frame it rounds more of
//! the pixels a shared bias pulls together, which the narrow, noisy average refused for the
//! rounding margin by chance. Both are still scenes, where the model finds no velocity; so the
//! wide average is taken exactly where the model's velocity is not zero (a patch whose motion
//! beat the noise, [`super::motion`]), and a still scene decodes bit for bit as with one
//! average.
//!
//! **Where they disagree, neither.** A wide average is also more often confidently wrong where
//! an error is shared by a whole region (the corrupted frame above). On the moving fingertip
//! of a 10 mm tremor, the first window of a stream (no past to check it against) put the whole
//! fingertip one fringe period (31 mm) off with the wide average where the narrow one was right
//! and sure, and the temporal check then refused the next four windows against that wrong
//! reference: the fingertip's peak-to-peak came out 30 % high. So a moving pixel takes the wide
//! average only where the narrow one is unsure (its rounding residual beyond the margin, or too
//! little support) or picks the same fringe orders; where the narrow one is sure and the two
//! pick different orders, the pixel is refused for the rounding margin ([`Agreement`]): two
//! estimates of one coarse coordinate that contradict each other give no depth.
//!
//! **How.** Before the narrow average overwrites the unit phasor and its support, they are
//! copied into the motion model's evidence planes, which its last step has finished with
//! (no memory is added). The narrow average runs as before; the wide one runs over the copy
//! with the same links; then each moving pixel is decided. The decision is per pixel, after
//! both sums, so neither sum depends on which pixels move.
//!
//! Measured on the rig's motion sweep (640×400, 10 mm tremor with 4 mm of sway): 90.4 % of the
//! moving skin kept with 0.75 % gross errors with the narrow average alone; 96.3 % and 0.37 %
//! with the wide one at every moving pixel (decay 0.95); 94.9 % and 0.21 % with the decision.
//! Every figure in docs/accuracy.md.

use super::smooth::{unit_angle, Planes};
use super::smooth_transport::{smooth_transported, Transport};
use super::unwrap::CpsMaps;
use super::DecodeOutput;
use rayon::prelude::*;

/// Whether any pixel has a velocity, so that the wide average would be taken somewhere.
pub(crate) fn any_moving(out: &DecodeOutput) -> bool {
    out.velocity_px_per_s.par_iter().any(|&v| v != 0.0)
}

/// Copies the unsmoothed unit phasor and support into the evidence planes, which the wide
/// average will sum. Call after the motion model's last step, before the narrow average.
pub(crate) fn keep_unsmoothed(out: &mut DecodeOutput) {
    let n = out.width * out.height;
    let (re, rest) = out.motion_evidence.split_at_mut(n);
    let (im, support) = rest.split_at_mut(n);
    re.copy_from_slice(&out.unit_re[..n]);
    im.copy_from_slice(&out.unit_im[..n]);
    support[..n].copy_from_slice(&out.support[..n]);
}

/// Sums the copy [`keep_unsmoothed`] made with `decay` per camera px, carried along the fine
/// phase of a Chebyshev sequence of order `n` (over the links the narrow average used), and
/// gives every pixel with a velocity the wide phasor and support, or refuses it where the two
/// averages disagree ([`Agreement`]).
pub(crate) fn smooth_for_moving(out: &mut DecodeOutput, decay: f32, n: u32, check: &Agreement) {
    let (w, h) = (out.width, out.height);
    let pixels = w * h;
    let (re, rest) = out.motion_evidence.split_at_mut(pixels);
    let (im, support) = rest.split_at_mut(pixels);
    let mut planes = Planes {
        planes: [re, im, &mut support[..pixels]],
        w,
        h,
        connect: &out.connect,
        tmp: &mut out.smooth_tmp,
        band_scratch: &mut out.band_scratch,
        band_scratch_len: out.band_scratch_len,
        vertical_state: &mut out.vertical_state,
    };
    let transport = Transport {
        phase_rad: &out.phase_rad,
        unit_per_fine: 1.0 / n.max(1) as f32,
    };
    smooth_transported(&mut planes, decay, transport);
    let (wide_re, rest) = out.motion_evidence.split_at(pixels);
    let (wide_im, wide_support) = rest.split_at(pixels);
    let nf = out.frequencies;
    out.unit_re
        .par_chunks_mut(w)
        .zip(out.unit_im.par_chunks_mut(w))
        .zip(out.support.par_chunks_mut(w))
        .zip(out.invalid.par_chunks_mut(w))
        .zip(out.velocity_px_per_s.par_chunks(w))
        .zip(out.phase_rad.par_chunks(w * nf))
        .zip(out.amplitude.par_chunks(w * nf))
        .zip(wide_re.par_chunks(w))
        .zip(wide_im.par_chunks(w))
        .zip(wide_support.par_chunks(w))
        .for_each(
            |(((((((((re, im), support), flags), velocity), phase), amp), wre), wim), wsup)| {
                for x in 0..re.len() {
                    if velocity[x] == 0.0 {
                        continue;
                    }
                    let ph = [phase[x], phase[w + x], phase[2 * w + x]];
                    let am = [amp[x], amp[w + x], amp[2 * w + x]];
                    let narrow = (re[x], im[x], support[x]);
                    match check.choose(narrow, (wre[x], wim[x], wsup[x]), ph, am) {
                        Choice::Wide => {
                            re[x] = wre[x];
                            im[x] = wim[x];
                            support[x] = wsup[x];
                        }
                        Choice::Neither => flags[x] |= super::invalid::UNWRAP_MARGIN,
                    }
                }
            },
        );
}

/// What decides between the two averages at a moving pixel: the wide one, unless the narrow
/// one is sure of its fringe orders (within the rounding margin, with its support) and the
/// wide one's are different, where the pixel is refused.
pub(crate) struct Agreement {
    pub cps: CpsMaps,
    /// 1/f₁: the unit angle to projector px.
    pub inv_f1: f32,
    pub max_rounding_residual: f32,
    pub min_support: f32,
    /// Half the finest fringe period, projector px.
    pub half_period_px: f32,
}

/// The coarse coordinate a moving pixel takes.
enum Choice {
    Wide,
    /// The two averages pick different fringe orders and the narrow one is sure of its own:
    /// the pixel is refused for the rounding margin rather than given either.
    Neither,
}

impl Agreement {
    fn choose(
        &self,
        narrow: (f32, f32, f32),
        wide: (f32, f32, f32),
        phase: [f32; 3],
        amplitude: [f32; 3],
    ) -> Choice {
        let n = self.cps.unwrap(
            unit_angle(narrow.0, narrow.1) * self.inv_f1,
            phase,
            amplitude,
        );
        let confident = n.residual <= self.max_rounding_residual && narrow.2 >= self.min_support;
        if !confident {
            return Choice::Wide;
        }
        let v = self
            .cps
            .unwrap(unit_angle(wide.0, wide.1) * self.inv_f1, phase, amplitude);
        if (v.combined - n.combined).abs() < self.half_period_px {
            Choice::Wide
        } else {
            Choice::Neither
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::solver::WindowSolver;
    use crate::pattern::{cps_rgb, Axis};

    fn output(w: usize, h: usize) -> DecodeOutput {
        let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
        let cross_talk = crate::color::CrossTalk::identity();
        let solver = WindowSolver::new(&seq, &[0, 1, 2], &cross_talk).unwrap();
        DecodeOutput::new(w, h, &solver)
    }

    /// A linear coordinate along the rows, every pixel linked: unit phasor, support 1 and the
    /// fine phase (slot 0) of frequency `n` times the unit's.
    fn ramp(out: &mut DecodeOutput, n: u32) {
        let (w, h) = (out.width, out.height);
        for y in 0..h {
            for x in 0..w {
                let unit = 0.01 * x as f32 + 0.3;
                let i = y * w + x;
                out.unit_re[i] = unit.cos();
                out.unit_im[i] = unit.sin();
                out.support[i] = 1.0;
                let fine = (n as f32 * unit).rem_euclid(std::f32::consts::TAU);
                out.phase_rad[3 * w * y + x] = fine;
            }
        }
        out.connect
            .fill(crate::decode::connect::RIGHT | crate::decode::connect::DOWN);
    }

    /// The decision of the rig's CPS-RGB frequencies (`k·π/912`, k = n, n−1, n−2).
    fn agreement(n: u32) -> Agreement {
        let f1 = std::f32::consts::PI / 912.0;
        let f = [n as f32 * f1, (n - 1) as f32 * f1, (n - 2) as f32 * f1];
        Agreement {
            cps: CpsMaps::new(&f, &[1.0, 1.0, 1.0]),
            inv_f1: 1.0 / (f[0] / n as f32),
            max_rounding_residual: 0.25,
            min_support: 15.0,
            half_period_px: std::f32::consts::PI / f[0],
        }
    }

    #[test]
    fn a_sure_narrow_average_that_the_wide_one_contradicts_refuses_the_pixel() {
        let n = 65;
        let check = agreement(n);
        let f1 = std::f32::consts::PI / 912.0;
        let x_px = 400.3f32;
        let phase =
            [n, n - 1, n - 2].map(|k| (k as f32 * f1 * x_px).rem_euclid(std::f32::consts::TAU));
        let amplitude = [50.0; 3];
        let phasor = |x: f32, support: f32| ((f1 * x).cos(), (f1 * x).sin(), support);
        let period_px = 2.0 * check.half_period_px;
        let sure = phasor(x_px, 20.0);
        // The same fringe orders: the wide average is taken.
        let agrees = check.choose(sure, phasor(x_px + 0.2 * period_px, 60.0), phase, amplitude);
        assert!(matches!(agrees, Choice::Wide));
        // A period apart, with the narrow one sure: neither.
        let contradicts = check.choose(sure, phasor(x_px + period_px, 60.0), phase, amplitude);
        assert!(matches!(contradicts, Choice::Neither));
        // The narrow one unsure (a rounding residual near ½, or too little support): the wide.
        let unsure = phasor(x_px + 0.45 * period_px, 20.0);
        let rescued = check.choose(unsure, phasor(x_px + period_px, 60.0), phase, amplitude);
        assert!(matches!(rescued, Choice::Wide));
        let thin = phasor(x_px, 5.0);
        let rescued = check.choose(thin, phasor(x_px + period_px, 60.0), phase, amplitude);
        assert!(matches!(rescued, Choice::Wide));
    }

    #[test]
    fn still_pixels_keep_the_narrow_sum_and_moving_ones_take_the_wide_one() {
        let (w, h, n) = (48, 20, 65);
        let mut out = output(w, h);
        ramp(&mut out, n);
        out.velocity_px_per_s.fill(0.0);
        let moving = 5 * w + 20;
        out.velocity_px_per_s[moving] = 120.0;
        keep_unsmoothed(&mut out);
        // The narrow average stands in as a known value that the wide one must not touch.
        let narrow = |i: usize| (i as f32 * 1e-3, -(i as f32) * 1e-3, 7.0);
        for i in 0..w * h {
            (out.unit_re[i], out.unit_im[i], out.support[i]) = narrow(i);
        }
        smooth_for_moving(&mut out, 0.9, n, &agreement(n));
        for i in (0..w * h).filter(|&i| i != moving) {
            assert_eq!((out.unit_re[i], out.unit_im[i], out.support[i]), narrow(i));
        }
        // The moving pixel's wide sum: the transport aligns every term to its own unit angle,
        // so the sum's angle is the pixel's, and its support that of a wide neighbourhood.
        let angle = out.unit_im[moving].atan2(out.unit_re[moving]);
        let own = 0.01 * 20.0 + 0.3;
        assert!((angle - own).abs() < 1e-4, "angle {angle}, own {own}");
        assert!(
            out.support[moving] > 20.0,
            "support {}",
            out.support[moving]
        );
    }

    #[test]
    fn at_the_end_of_a_row_the_wide_sum_is_not_pulled_towards_its_neighbours() {
        // One-sided, a plain sum's angle would be its neighbourhood's mean (0.09 rad below the
        // pixel's at this decay and slope); carried along the fine phase it is the pixel's own.
        let (w, h, n) = (48, 20, 65);
        let mut out = output(w, h);
        ramp(&mut out, n);
        let edge = 5 * w + (w - 1);
        out.velocity_px_per_s.fill(0.0);
        out.velocity_px_per_s[edge] = -80.0;
        keep_unsmoothed(&mut out);
        smooth_for_moving(&mut out, 0.9, n, &agreement(n));
        let angle = out.unit_im[edge].atan2(out.unit_re[edge]);
        let own = 0.01 * (w - 1) as f32 + 0.3;
        assert!((angle - own).abs() < 1e-4, "{angle} against {own}");
    }
}
