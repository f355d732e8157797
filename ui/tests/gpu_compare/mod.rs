//! The comparison of one window's GPU result with the CPU's, shared by `gpu_decode`'s tests:
//! coordinates within 10⁻³ projector px, amplitude and colour within the linear solve's
//! rounding (times the motion model's largest amplification), and validity or the motion
//! model's decision differing on at most one pixel in 10⁴ (ties of a test at its threshold).

use tremorscan::decode::DecodeOutput;

/// The differences of one window's GPU result from the CPU's, asserted within bounds.
/// `motion`: the decode had the motion model; `follows`: its steps may have started from the
/// stream's previous window (`MotionParams::predicted_start`).
pub fn compare(cpu: &DecodeOutput, gpu: &DecodeOutput, motion: bool, follows: bool) {
    let n = cpu.width * cpu.height;
    let (mut worst, mut both, mut validity_differs) = (0f32, 0usize, 0usize);
    // The linear solve's bound on amplitude and colour (below), times the model's largest
    // amplification on a pixel it explains (1/det, det ≥ 0.4: `motion::MIN_DET`).
    // A window whose steps started from the previous window's patch velocities also inherits
    // that window's differences: its start differs by the rounding of the previous sums, and
    // the two steps from there do not converge to the last bit. Measured on the CPU (960×600,
    // the swaying hand, four frames): a start 10⁻⁵ off (relative) moved the valid pixels'
    // amplitudes by up to 4.3·10⁻⁵ and their coordinates by 1.8·10⁻⁴ px; GPU against CPU, the
    // second window's amplitudes differed by up to 2.0·10⁻⁴, and 117 pixels' coordinates by
    // more than 2.5·10⁻⁴ px, at most 7.9·10⁻⁴ px, all in one patch moving at −290 px/s. A
    // pixel corrected on one side and not the other differs by percents (2.7 % measured,
    // below), so such windows are held to 10⁻³.
    let level_bound = match (motion, follows) {
        (false, _) => 1e-5,
        (true, false) => 1e-5 / 0.4,
        (true, true) => 1e-3,
    };
    let level_differs = |p: usize| {
        let (y, x) = (p / cpu.width, p % cpu.width);
        (0..3).any(|f| {
            let k = y * 3 * cpu.width + f * cpu.width + x;
            let (a, b) = (cpu.amplitude[k], gpu.amplitude[k]);
            (a - b).abs() / a.abs().max(1.0) > level_bound
        })
    };
    // With the model, a pixel valid on both whose amplitudes differ beyond rounding was
    // corrected on one side and not the other, which we take to be a patch's significance
    // within rounding of its threshold in an earlier step (not traced on the GPU). Measured once (since the evidence at rest lost its noise
    // bias, stop 43): one pixel of 256,000, 0.033 px and 2.7 % of its amplitude apart, both
    // ending at rest. Counted with the validity differences below, not as a coordinate error.
    // The acceleration is taken only where the last step's test finds the patch moving (or it
    // moved a window before). Where the pixel was corrected in the first step, a tie of that
    // test in the last one leaves amplitudes and velocity alone and moves the coordinate by the
    // acceleration's shift, `a·mean(τ²)/2` (at 960×600 at the 10⁻³ level: one pixel, 0.084 px,
    // amplitudes within rounding). The GPU does not read back the acceleration, so it shows on
    // the CPU's side: the CPU took none at a moving pixel, or the two differ by the CPU's shift.
    let mean_tau2_s2 = 2.0 / 3.0 / 121.0f32.powi(2);
    let acceleration_tie = |p: usize, difference: f32| {
        let (v, a) = (cpu.velocity_px_per_s[p], cpu.acceleration_px_per_s2[p]);
        let shift = 0.5 * a * mean_tau2_s2;
        (v != 0.0 && a == 0.0) || (difference.abs() - shift.abs()).abs() <= 1e-3
    };
    let mut decision_differs = 0usize;
    for p in 0..n {
        let (c, g) = (cpu.coordinate_px[p], gpu.coordinate_px[p]);
        assert_eq!(g.is_nan(), gpu.invalid[p] != 0, "pixel {p}");
        if (cpu.invalid[p] == 0) != (gpu.invalid[p] == 0) {
            validity_differs += 1;
            continue;
        }
        let tie = |p| (c - g).abs() > 1e-3 && acceleration_tie(p, c - g);
        if motion && c.is_finite() && (level_differs(p) || tie(p)) {
            decision_differs += 1;
            continue;
        }
        if c.is_finite() {
            worst = worst.max((c - g).abs());
            both += 1;
        }
    }
    // Amplitude and colour come straight from the window's linear solve: the same linear map on
    // both, rounded differently (the GPU multiplies by M⁺ with fused multiply–adds, the CPU
    // applies its two factors, closed form then unmixing): a few ulps of values up to a few
    // hundred gray levels, 2–5·10⁻⁶ measured. The motion model corrects them through the inverse
    // of its response, which amplifies those ulps by up to 1/det, 2.5× where it explains the
    // pixel and without bound where it does not: measured up to 4·10⁻³ on a pixel refused for
    // `MOTION`, 2·10⁻⁵–1·10⁻⁴ on a few refused for their support or their fringe orders. With
    // the model, the pixels valid on both are compared (the cloud's colours).
    let mut worst_level = 0f32;
    let w = cpu.width;
    let compared =
        |p: usize| !motion || (cpu.invalid[p] == 0 && gpu.invalid[p] == 0 && !level_differs(p));
    for p in (0..n).filter(|&p| compared(p)) {
        let (y, x) = (p / w, p % w);
        for f in 0..3 {
            let k = y * 3 * w + f * w + x;
            for (a, b) in [
                (cpu.amplitude[k], gpu.amplitude[k]),
                (cpu.colour[k], gpu.colour[k]),
            ] {
                worst_level = worst_level.max((a - b).abs() / a.abs().max(1.0));
            }
        }
    }
    eprintln!(
        "{}×{}: {both} valid on both, worst coordinate difference {worst:.2e} px, \
         worst amplitude/colour difference {worst_level:.1e} (relative), validity differs on \
         {validity_differs} of {n} pixels, the model's decision on {decision_differs}",
        cpu.width, cpu.height
    );
    // The bound. Both paths use the same polynomial atan2; the differences are f32
    // rounding (of the solve as above, the CPU's blocked vertical recursion): a few ulps of
    // coordinates up to about 900 px, 2.4e-4 px measured.
    assert!(worst <= 1e-3, "worst difference {worst} px");
    assert!(
        worst_level <= level_bound,
        "amplitude/colour differ by {worst_level}"
    );
    assert!(both > n / 4, "only {both} valid pixels");
    // Validity can only differ where a test statistic lies within rounding of its threshold:
    // a handful of pixels, not a pattern. One in 10⁴ is far above that and far below any
    // systematic difference (a wrong check would flip thousands).
    assert!(
        (validity_differs + decision_differs) * 10_000 <= n,
        "validity differs on {validity_differs} pixels, the model's decision on {decision_differs}"
    );
}
