//! Tests of one Gauss–Newton step's kernel ([`super`]): a row corrects each pixel as it would
//! alone, and a second step that would break a pixel's consistent first correction keeps the
//! first.

use super::*;
use crate::color::CrossTalk;
use crate::decode::motion_evidence::gain2;
use crate::decode::WindowSolver;
use crate::pattern::{cps_rgb, Axis};

/// One row of every plane a step reads and writes, owned.
#[derive(Clone)]
struct Row {
    phase: [Vec<f32>; 3],
    amp: [Vec<f32>; 3],
    offset: [Vec<f32>; 3],
    /// `uu`, `uk`, `kk`, `ue`, `ke`, `count`.
    evidence: [Vec<f32>; 6],
    flags: Vec<u16>,
    velocity: Vec<f32>,
    brightness: Vec<f32>,
    acceleration: Vec<f32>,
    patch_velocity: Vec<f32>,
    patch_moving: Vec<u8>,
    lit_sum: Vec<f32>,
}

impl Row {
    /// `w` pixels of varied values: phases all round, weak and strong fringes, saturated
    /// pixels, patches whose evidence shows motion of either sign (some beyond the model's
    /// range) or none, and pixels corrected by a previous step or not.
    fn varied(w: usize) -> Self {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut row = Self {
            phase: Default::default(),
            amp: Default::default(),
            offset: Default::default(),
            evidence: Default::default(),
            flags: vec![],
            velocity: vec![],
            brightness: vec![],
            acceleration: vec![],
            patch_velocity: vec![],
            patch_moving: vec![],
            lit_sum: vec![],
        };
        for _ in 0..w {
            for slot in 0..3 {
                row.phase[slot].push(std::f32::consts::TAU * next());
                row.amp[slot].push(2.0 + 60.0 * next());
                row.offset[slot].push(20.0 + 120.0 * next());
            }
            // The patch's sums: strong or weak evidence for a velocity of ±330 px/s and a
            // brightness change of ±12/s.
            let (uu, kk): (f32, f32) = if next() < 0.5 {
                (0.1, 0.02)
            } else {
                (1e-3, 1e-4)
            };
            let (u, kappa) = (660.0 * (next() - 0.5), 24.0 * (next() - 0.5));
            let uk = 0.2 * (uu * kk).sqrt() * (next() - 0.5);
            let ue = uu * u + uk * kappa;
            let ke = uk * u + kk * kappa;
            let count = if next() < 0.1 {
                0.0
            } else {
                1.0 + 40.0 * next()
            };
            for (plane, value) in row.evidence.iter_mut().zip([uu, uk, kk, ue, ke, count]) {
                plane.push(value);
            }
            row.flags
                .push(if next() < 0.1 { invalid::SATURATED } else { 0 });
            let corrected = next() < 0.4;
            row.velocity.push(if corrected {
                400.0 * (next() - 0.5)
            } else {
                0.0
            });
            row.brightness.push(if corrected {
                10.0 * (next() - 0.5)
            } else {
                0.0
            });
            row.acceleration.push(0.0);
            row.patch_velocity.push(300.0 * (next() - 0.5));
            row.patch_moving.push(u8::from(next() < 0.5));
            // The previous window's lit offsets: near this one's (a brightness change the
            // model takes), far from it (one it does not), or none.
            let lit_now: f32 = (0..3)
                .map(|slot| row.offset[slot][row.offset[slot].len() - 1])
                .sum();
            row.lit_sum.push(match (3.0 * next()) as u32 {
                0 => lit_now * (1.0 + 0.1 * (next() - 0.5)),
                1 => lit_now * 3.0,
                _ => f32::NAN,
            });
        }
        row
    }

    /// Pixel `x` seen still at `coordinate_px` (its phases consistent: no Chebyshev residual),
    /// with fringe amplitude `amp` and offsets `offsets`.
    fn set_still(
        &mut self,
        basis: &MotionBasis,
        x: usize,
        coordinate_px: f32,
        amp: f32,
        offsets: [f32; 3],
    ) {
        for slot in 0..3 {
            self.phase[slot][x] =
                (basis.f_rad_per_px[slot] * coordinate_px).rem_euclid(std::f32::consts::TAU);
            self.amp[slot][x] = amp;
            self.offset[slot][x] = offsets[slot];
        }
    }

    /// Every plane, whole; `RowPlanes::block` cuts the pixels a call works on.
    fn planes(&mut self) -> RowPlanes<'_> {
        let [p0, p1, p2] = &mut self.phase;
        let [a0, a1, a2] = &mut self.amp;
        let [o0, o1, o2] = &mut self.offset;
        let [uu, uk, kk, ue, ke, count] = &mut self.evidence;
        RowPlanes {
            phase: [p0, p1, p2],
            amp: [a0, a1, a2],
            offset: [o0, o1, o2],
            uu,
            uk,
            kk,
            ue,
            ke,
            count,
            flags: &mut self.flags,
            velocity: &mut self.velocity,
            brightness: &mut self.brightness,
            acceleration: &mut self.acceleration,
            patch_velocity: &mut self.patch_velocity,
            patch_moving: &mut self.patch_moving,
            lit_sum: &mut self.lit_sum,
        }
    }

    /// Every value's bits, NaN included.
    fn bits(&self) -> Vec<u32> {
        let floats = self
            .phase
            .iter()
            .chain(&self.amp)
            .chain(&self.offset)
            .chain(&self.evidence)
            .chain([
                &self.velocity,
                &self.brightness,
                &self.acceleration,
                &self.patch_velocity,
                &self.lit_sum,
            ]);
        floats
            .flatten()
            .map(|v| v.to_bits())
            .chain(self.flags.iter().map(|&b| u32::from(b)))
            .chain(self.patch_moving.iter().map(|&b| u32::from(b)))
            .collect()
    }
}

#[test]
fn a_row_corrects_each_pixel_as_it_would_alone() {
    // The blocks, their marks and the gathered arrays are bookkeeping: each pixel's result
    // depends on its own planes only, so a row of 200 pixels (three full blocks and part of
    // a fourth) must come out bit for bit as its pixels corrected one at a time, each
    // alone in its block. Catches a plane not gathered or not copied back, a mark on the
    // wrong pixel, and an earlier block's entries leaking into a later one.
    let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
    let solver = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
    let basis = MotionBasis::new(&solver, [0.0, 1.0 / 121.0, 2.0 / 121.0]).unwrap();
    let w = 200;
    let input = Row::varied(w);
    for (kind, last) in [
        (StepKind::FromRest, false),
        (StepKind::Refine, false),
        (StepKind::FromRest, true),
        (StepKind::Refine, true),
    ] {
        let since_s = 1.0 / 121.0;
        let step = Step {
            basis: &basis,
            gain2: gain2(&solver),
            limit: 25.0 * 4.0,
            min_amplitude: 4.0,
            kind,
            last,
            prior_u: (2.0f32 / 400.0).powi(2),
            prior_k: (2.0f32 / 20.0).powi(2),
            inv_noise2: 0.25,
            inv_since: 1.0 / since_s,
            max_velocity_change: std::f32::consts::TAU * 8.0 * since_s * basis.max_velocity,
            shift_per_velocity_change: 0.5 * basis.mean_tau2_s2 / since_s,
            offset_brightness_weight: 0.5,
        };
        let mut whole = input.clone();
        correct_row(&step, whole.planes().block(0, w));
        let mut alone = input.clone();
        for x in 0..w {
            correct_row(&step, alone.planes().block(x, x + 1));
        }
        assert!(
            whole.bits() == alone.bits(),
            "{kind:?}, last {last}: the row differs from its pixels alone"
        );
        // Not vacuous: the step corrected some pixels and left others at rest.
        let corrected = (0..w).filter(|&x| whole.phase[0][x] != input.phase[0][x]);
        let corrected = corrected.count();
        assert!(
            (20..w - 20).contains(&corrected),
            "{kind:?}: {corrected} corrected"
        );
    }
}

/// The last, refining step of the paper's sequence at the rig's default noise, with no window
/// before it.
fn last_refining_step<'a>(basis: &'a MotionBasis, solver: &WindowSolver) -> Step<'a> {
    Step {
        basis,
        gain2: gain2(solver),
        limit: 25.0 * 4.0,
        min_amplitude: 4.0,
        kind: StepKind::Refine,
        last: true,
        prior_u: (2.0f32 / 400.0).powi(2),
        prior_k: (2.0f32 / 20.0).powi(2),
        inv_noise2: 0.25,
        inv_since: 0.0,
        max_velocity_change: 0.0,
        shift_per_velocity_change: 0.0,
        offset_brightness_weight: 0.0,
    }
}

#[test]
fn a_second_step_that_breaks_a_consistent_correction_keeps_the_first() {
    // Pixels the first step corrected at 150 px/s, their phasors now consistent (the
    // Chebyshev residual 0), whose patch's evidence then points far away (−450 px/s) or
    // near (180 px/s). Far: where the new correction would break the Chebyshev relation
    // (at most of these coordinates), the pixel keeps 150 px/s and stays valid. Near: the
    // step applies.
    let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
    let solver = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
    let basis = MotionBasis::new(&solver, [0.0, 1.0 / 121.0, 2.0 / 121.0]).unwrap();
    let step = last_refining_step(&basis, &solver);
    let w = 16;
    let mut row = Row::varied(w);
    for x in 0..w {
        row.set_still(&basis, x, 37.0 * x as f32 + 11.0, 150.0, [80.0; 3]);
        let target_px_per_s = if x % 2 == 0 { -450.0 } else { 180.0 };
        let (uu, kk) = (0.1, 0.02);
        let values = [uu, 0.0, kk, uu * target_px_per_s, 0.0, 10.0];
        for (plane, value) in row.evidence.iter_mut().zip(values) {
            plane[x] = value;
        }
        row.flags[x] = 0;
        row.velocity[x] = 150.0;
        row.brightness[x] = 0.0;
    }
    correct_row(&step, row.planes().block(0, w));
    let mut kept_first = 0;
    for x in 0..w {
        let (u, flags) = (row.velocity[x], row.flags[x]);
        // None is lost: a step that would break the pixel is refused.
        assert_eq!(flags, 0, "pixel {x}: flags {flags:#x}, velocity {u}");
        if x % 2 == 0 {
            // Far: the first correction kept, or (where the new one happens to keep the
            // relation, as at some coordinates it does) the new one.
            assert!(u == 150.0 || (u + 450.0).abs() < 1.0, "pixel {x}: {u}");
            kept_first += usize::from(u == 150.0);
        } else {
            assert!((u - 180.0).abs() < 1.0, "pixel {x}: {u}");
        }
    }
    assert!(
        kept_first >= w / 4,
        "{kept_first} kept their first correction"
    );
}

#[test]
fn a_moving_pixel_weighs_its_own_brightness_change_with_its_patch() {
    // Pixels at rest before the last step, whose patch shows 150 px/s and a brightness change
    // of 2/s, and whose lit offsets were lower in the window just before by what 12/s makes.
    // With the weight 0.4 each is corrected as its patch would correct it at 0.6·2 + 0.4·12 =
    // 6/s. Where the previous window's offsets are missing, or show a change beyond the model's
    // range, the patch's 2/s stays.
    let seq = cps_rgb(65, 912.0, Axis::Columns, 8).unwrap();
    let solver = WindowSolver::new(&seq, &[0, 1, 2], &CrossTalk::paper()).unwrap();
    let basis = MotionBasis::new(&solver, [0.0, 1.0 / 121.0, 2.0 / 121.0]).unwrap();
    let since_s = 1.0 / 121.0;
    let step = |weight: f32| Step {
        prior_u: 1e-9,
        prior_k: 1e-9,
        inv_since: 1.0 / since_s,
        offset_brightness_weight: weight,
        ..last_refining_step(&basis, &solver)
    };
    let w = 12;
    let row = |patch_kappa: f32, before: &dyn Fn(f32) -> f32| {
        let mut row = Row::varied(w);
        for x in 0..w {
            row.set_still(&basis, x, 53.0 * x as f32 + 7.0, 120.0, [90.0, 95.0, 100.0]);
            let (uu, kk) = (1e6, 1e6);
            let values = [uu, 0.0, kk, uu * 150.0, kk * patch_kappa, 10.0];
            for (plane, value) in row.evidence.iter_mut().zip(values) {
                plane[x] = value;
            }
            row.flags[x] = 0;
            row.velocity[x] = 0.0;
            row.brightness[x] = 0.0;
            let lit = basis.lit_offsets([row.offset[0][x], row.offset[1][x], row.offset[2][x]]);
            row.lit_sum[x] = before(lit[0] + lit[1] + lit[2]);
        }
        row
    };
    let run = |weight: f32, mut row: Row| {
        correct_row(&step(weight), row.planes().block(0, w));
        row
    };
    let measured = run(0.4, row(2.0, &|now| now * (1.0 - 12.0 * since_s)));
    let mixed = run(0.0, row(6.0, &|now| now * (1.0 - 12.0 * since_s)));
    let patch = run(0.0, row(2.0, &|_| f32::NAN));
    for x in 0..w {
        for slot in 0..3 {
            let (a, b) = (measured.phase[slot][x], mixed.phase[slot][x]);
            assert!(
                (a - b).abs() < 1e-4,
                "pixel {x}, slot {slot}: {a} against {b}"
            );
        }
        // Not vacuous: 6/s and 2/s correct the phases differently.
        let moved = (0..3).any(|slot| (mixed.phase[slot][x] - patch.phase[slot][x]).abs() > 1e-3);
        assert!(moved, "pixel {x}");
        assert_eq!(measured.flags[x], mixed.flags[x], "pixel {x}");
    }
    // The change is reported where the pixel is valid.
    let valid: Vec<usize> = (0..w).filter(|&x| measured.flags[x] == 0).collect();
    assert!(!valid.is_empty());
    for &x in &valid {
        assert!((measured.brightness[x] - 6.0).abs() < 1e-3, "pixel {x}");
    }
    // Without the previous window's offsets, or with a change beyond the model's range, the
    // patch's alone, to the bit.
    for before in [
        &(|_| f32::NAN) as &dyn Fn(f32) -> f32,
        &|now| 3.0 * now,
        &|_| 0.0,
    ] {
        let alone = run(0.4, row(2.0, before));
        assert!(alone.bits() == patch.bits());
    }
}
