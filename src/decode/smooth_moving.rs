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
//! pick different orders, the pixel is refused for the rounding margin ([`Agreement`],
//! `select_row`): two estimates of one coarse coordinate that contradict each other give no
//! depth, unless a third settles it. The refused pixel's wide coarse coordinate stays in the
//! first evidence plane (NaN at every other pixel), and the pixel's own recent past, an
//! estimate independent of both, may side with either
//! ([`super::temporal::settle_margin_from_recent`]).
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

use super::smooth::{smooth_unit_phasor, unit_angle, Planes};
use super::smooth_transport::{smooth_transported, Transport};
use super::unwrap::CpsMaps;
use super::{DecodeOutput, DecodeParams, SmoothingParams, WindowSolver};
use rayon::prelude::*;

/// Stage 2 of a window where something moves: the narrow average (`narrow`) for every pixel,
/// and the wide one at `wide_decay` per camera px for the moving pixels, as `check` decides.
/// Leaves in the first `width·height` values of `out.motion_evidence` the wide coarse
/// coordinate (projector px) of each pixel refused because the two contradict each other, NaN
/// at the others.
pub(crate) fn smooth_both(
    out: &mut DecodeOutput,
    narrow: &SmoothingParams,
    wide_decay: f32,
    check: &Agreement,
) {
    keep_unsmoothed(out);
    smooth_unit_phasor(out, narrow, Some(check.chebyshev_n));
    smooth_for_moving(out, wide_decay, check.chebyshev_n, check);
}

/// Whether any pixel has a velocity, so that the wide average would be taken somewhere.
pub(crate) fn any_moving(out: &DecodeOutput) -> bool {
    out.velocity_px_per_s.par_iter().any(|&v| v != 0.0)
}

/// Copies the unsmoothed unit phasor and support into the evidence planes, which the wide
/// average will sum. Call after the motion model's last step, before the narrow average.
fn keep_unsmoothed(out: &mut DecodeOutput) {
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
fn smooth_for_moving(out: &mut DecodeOutput, decay: f32, n: u32, check: &Agreement) {
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
    let (wide_re, rest) = out.motion_evidence.split_at_mut(pixels);
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
        .zip(wide_re.par_chunks_mut(w))
        .zip(wide_im.par_chunks(w))
        .zip(wide_support.par_chunks(w))
        .zip(out.smooth_tmp.par_chunks_mut(2 * w))
        .for_each(
            |(
                (((((((((re, im), support), flags), velocity), phase), amp), wre), wim), wsup),
                tmp,
            )| {
                let row = SelectRow {
                    narrow: [re, im, support],
                    flags,
                    velocity,
                    phase,
                    amplitude: amp,
                    wide_re: wre,
                    wide: [wim, wsup],
                    scratch: tmp,
                };
                select_row(check, row);
            },
        );
}

/// One row of the decision: the narrow phasor and support (replaced where the wide ones are
/// taken), the flags, the velocity, the row-planar phases and amplitudes, the wide sums and two
/// rows of scratch. The wide sum's real part is replaced by the wide coarse coordinate where
/// the pixel is refused, NaN elsewhere.
struct SelectRow<'a> {
    narrow: [&'a mut [f32]; 3],
    flags: &'a mut [u16],
    velocity: &'a [f32],
    phase: &'a [f32],
    amplitude: &'a [f32],
    wide_re: &'a mut [f32],
    /// The wide sum's imaginary part and support.
    wide: [&'a [f32]; 2],
    scratch: &'a mut [f32],
}

/// The decision of [`Agreement`] for a whole row, in loops without branches or calls so that
/// they vectorise: a moving pixel takes the wide phasor and support unless the narrow ones are
/// sure of other fringe orders, where it is flagged instead and keeps the wide coarse
/// coordinate for the recent past to weigh.
#[multiversion::multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx512dq+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
fn select_row(check: &Agreement, row: SelectRow<'_>) {
    let w = row.flags.len();
    let [re, im, support] = row.narrow;
    let (re, im, support) = (&mut re[..w], &mut im[..w], &mut support[..w]);
    let [wim, wsup] = row.wide;
    let (wre, wim, wsup) = (&mut row.wide_re[..w], &wim[..w], &wsup[..w]);
    let (flags, velocity) = (&mut row.flags[..w], &row.velocity[..w]);
    let (ph0, ph1, ph2) = (
        &row.phase[..w],
        &row.phase[w..2 * w],
        &row.phase[2 * w..3 * w],
    );
    let (am0, am1, am2) = (
        &row.amplitude[..w],
        &row.amplitude[w..2 * w],
        &row.amplitude[2 * w..3 * w],
    );
    let (narrow_px, wide_px) = row.scratch.split_at_mut(w);
    let wide_px = &mut wide_px[..w];
    for x in 0..w {
        narrow_px[x] = unit_angle(re[x], im[x]) * check.inv_f1;
        wide_px[x] = unit_angle(wre[x], wim[x]) * check.inv_f1;
    }
    for x in 0..w {
        let (phase, amplitude) = ([ph0[x], ph1[x], ph2[x]], [am0[x], am1[x], am2[x]]);
        let n = check.cps.unwrap(narrow_px[x], phase, amplitude);
        let v = check.cps.unwrap(wide_px[x], phase, amplitude);
        let sure = (n.residual <= check.max_rounding_residual) & (support[x] >= check.min_support);
        let differ = (v.combined - n.combined).abs() >= check.half_period_px;
        let moving = velocity[x] != 0.0;
        let refuse = moving & sure & differ;
        let take = moving & !refuse;
        re[x] = if take { wre[x] } else { re[x] };
        im[x] = if take { wim[x] } else { im[x] };
        support[x] = if take { wsup[x] } else { support[x] };
        flags[x] |= if refuse {
            super::invalid::UNWRAP_MARGIN
        } else {
            0
        };
        wre[x] = if refuse { wide_px[x] } else { f32::NAN };
    }
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
    /// The Chebyshev sequence's order (slot 0's frequency over the unit's).
    pub chebyshev_n: u32,
}

impl Agreement {
    /// The decision for windows of `solver` decoded with `params`, of a Chebyshev sequence of
    /// order `n`: the same maps, margin and support as the unwrap that follows.
    pub(crate) fn new(solver: &WindowSolver, params: &DecodeParams, n: u32) -> Self {
        let f = &solver.frequency_rad_per_px;
        Self {
            cps: CpsMaps::new(f, &solver.noise_gain),
            inv_f1: 1.0 / (f[0] / n as f32),
            max_rounding_residual: params.max_rounding_residual,
            min_support: params.smoothing.min_support,
            half_period_px: std::f32::consts::PI / f[0],
            chebyshev_n: n,
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
            chebyshev_n: n,
        }
    }

    #[test]
    fn a_sure_narrow_average_that_the_wide_one_contradicts_refuses_the_pixel() {
        let n = 65;
        let check = agreement(n);
        let f1 = std::f32::consts::PI / 912.0;
        let x_px = 400.3f32;
        let period_px = 2.0 * check.half_period_px;
        // Six pixels of one row, all at `x_px`: (narrow at, its support, wide at, velocity).
        let cases = [
            (x_px, 20.0, x_px + 0.2 * period_px, 50.0), // the same orders: the wide one
            (x_px, 20.0, x_px + period_px, 50.0),       // a period apart, narrow sure: neither
            (x_px + 0.45 * period_px, 20.0, x_px + period_px, 50.0), // narrow unsure: wide
            (x_px, 5.0, x_px + period_px, 50.0),        // narrow with little support: wide
            (x_px, 20.0, x_px + period_px, 0.0),        // still: the narrow one, unflagged
            (x_px, 20.0, x_px + period_px, -300.0),     // either sign of velocity
        ];
        let w = cases.len();
        let at = |x: f32| ((f1 * x).cos(), (f1 * x).sin());
        let mut narrow = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        let mut wide = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        let mut velocity = vec![0.0; w];
        for (i, &(nx, ns, wx, v)) in cases.iter().enumerate() {
            (narrow[0][i], narrow[1][i]) = at(nx);
            narrow[2][i] = ns;
            (wide[0][i], wide[1][i]) = at(wx);
            wide[2][i] = 60.0;
            velocity[i] = v;
        }
        let mut phase = vec![0.0; 3 * w];
        for (slot, k) in [n, n - 1, n - 2].into_iter().enumerate() {
            let fine = (k as f32 * f1 * x_px).rem_euclid(std::f32::consts::TAU);
            phase[slot * w..(slot + 1) * w].fill(fine);
        }
        let amplitude = vec![50.0; 3 * w];
        let mut flags = vec![0u16; w];
        let mut scratch = vec![0.0; 2 * w];
        let before = narrow.clone();
        let wide_before = wide.clone();
        let [re, im, support] = &mut narrow;
        let [wide_re, wide_im, wide_support] = &mut wide;
        select_row(
            &check,
            SelectRow {
                narrow: [re, im, support],
                flags: &mut flags,
                velocity: &velocity,
                phase: &phase,
                amplitude: &amplitude,
                wide_re,
                wide: [wide_im, wide_support],
                scratch: &mut scratch,
            },
        );
        let margin = crate::decode::invalid::UNWRAP_MARGIN;
        let took_wide = |i: usize| narrow[2][i] == 60.0 && narrow[0][i] == wide_before[0][i];
        let kept_narrow = |i: usize| (0..3).all(|p| narrow[p][i] == before[p][i]);
        assert!(took_wide(0) && flags[0] == 0);
        assert!(kept_narrow(1) && flags[1] == margin);
        assert!(took_wide(2) && flags[2] == 0);
        assert!(took_wide(3) && flags[3] == 0);
        assert!(kept_narrow(4) && flags[4] == 0);
        assert!(kept_narrow(5) && flags[5] == margin);
        // A refused pixel keeps the wide average's coarse coordinate for the recent past to
        // weigh (temporal::settle_margin_from_recent); no other pixel has one.
        for i in 0..w {
            if flags[i] == margin {
                let wide_px = cases[i].2;
                assert!((wide[0][i] - wide_px).abs() < 0.01, "{i}: {}", wide[0][i]);
            } else {
                assert!(wide[0][i].is_nan(), "{i}: {}", wide[0][i]);
            }
        }
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
