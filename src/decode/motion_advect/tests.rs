use super::*;

/// A deterministic spread of values in `[-1, 1)`.
fn spread(k: usize) -> f32 {
    ((k as f32 * 0.618_034).fract() * 2.0) - 1.0
}

/// The normal equations of `e = D_u·u + D_κ·(κ₀ + v·g)` summed over `pixels` (each
/// `(D_u, D_κ, g)`, unit weights, no noise), with the step's priors.
fn patch_of(
    pixels: &[(f32, f32, [f32; 2])],
    truth: (f32, f32, [f32; 2]),
    priors: [f32; 3],
) -> Patch {
    let (u, kappa0, v) = truth;
    let mut p = Patch {
        a: priors[0],
        b: 0.0,
        c: priors[1],
        ru: 0.0,
        rk: 0.0,
        coupling: [0.0; 4],
        image: [priors[2], 0.0, priors[2]],
        rv: [0.0; 2],
    };
    for &(du, dk, g) in pixels {
        let e = du * u + dk * (kappa0 + v[0] * g[0] + v[1] * g[1]);
        p.a += du * du;
        p.b += du * dk;
        p.c += dk * dk;
        p.ru += du * e;
        p.rk += dk * e;
        p.coupling[0] += du * dk * g[0];
        p.coupling[1] += du * dk * g[1];
        p.coupling[2] += dk * dk * g[0];
        p.coupling[3] += dk * dk * g[1];
        p.image[0] += dk * dk * g[0] * g[0];
        p.image[1] += dk * dk * g[0] * g[1];
        p.image[2] += dk * dk * g[1] * g[1];
        p.rv[0] += dk * e * g[0];
        p.rv[1] += dk * e * g[1];
    }
    p
}

fn pixels(count: usize) -> Vec<(f32, f32, [f32; 2])> {
    (0..count)
        .map(|k| {
            (
                0.002 * spread(3 * k),
                0.05 * spread(3 * k + 1),
                [0.2 * spread(5 * k + 2), 0.2 * spread(7 * k + 3)],
            )
        })
        .collect()
}

#[test]
fn a_patch_whose_light_slides_gives_each_pixel_its_own_brightness_change() {
    let pixels = pixels(60);
    let truth = (300.0, 4.0, [60.0, -90.0]);
    let patch = patch_of(&pixels, truth, [1e-9; 3]);
    // The patch's one brightness change (the 2×2 solution) misses the pixels' spread.
    let det = patch.a * patch.c - patch.b * patch.b;
    let one_kappa = (patch.a * patch.rk - patch.b * patch.ru) / det;
    let mut worst_one = 0.0f32;
    for (du, dk, g) in &pixels {
        let own = truth.1 + truth.2[0] * g[0] + truth.2[1] * g[1];
        worst_one = worst_one.max((one_kappa - own).abs());
        let (u, kappa, taken) = patch.advected(1e6, *g);
        assert!(taken, "pixel {du} {dk} {g:?}");
        assert!((u - truth.0).abs() < 0.05, "u {u} against {}", truth.0);
        assert!((kappa - own).abs() < 0.01, "κ {kappa} against {own}");
    }
    assert!(worst_one > 10.0, "{worst_one}");
}

#[test]
fn the_schur_solution_is_that_of_the_whole_system() {
    // With priors and data the model does not fit exactly, the 2×2 blocks solve the 4×4 normal
    // equations.
    let pixels = pixels(40);
    let mut patch = patch_of(&pixels, (120.0, -6.0, [20.0, 35.0]), [0.3, 0.2, 0.1]);
    patch.ru += 0.01;
    patch.rk -= 0.2;
    patch.rv[1] += 0.05;
    let m = nalgebra::Matrix4::new(
        patch.a,
        patch.b,
        patch.coupling[0],
        patch.coupling[1],
        patch.b,
        patch.c,
        patch.coupling[2],
        patch.coupling[3],
        patch.coupling[0],
        patch.coupling[2],
        patch.image[0],
        patch.image[1],
        patch.coupling[1],
        patch.coupling[3],
        patch.image[1],
        patch.image[2],
    )
    .cast::<f64>();
    let r = nalgebra::Vector4::new(patch.ru, patch.rk, patch.rv[0], patch.rv[1]).cast::<f64>();
    let x = m.lu().solve(&r).unwrap();
    let g = [0.1f32, -0.15];
    let (u, kappa, taken) = patch.advected(1e6, g);
    assert!(taken);
    let kappa_whole = x[1] + x[2] * f64::from(g[0]) + x[3] * f64::from(g[1]);
    assert!(
        (f64::from(u) - x[0]).abs() < 1e-3 * x[0].abs().max(1.0),
        "{u} against {}",
        x[0]
    );
    assert!(
        (f64::from(kappa) - kappa_whole).abs() < 1e-3 * kappa_whole.abs().max(1.0),
        "{kappa} against {kappa_whole}"
    );
}

#[test]
fn a_patch_whose_motion_is_not_significant_is_not_taken() {
    let pixels = pixels(60);
    // The noise variance makes a χ² of about 0.02 of the significance level.
    let patch = patch_of(&pixels, (30.0, 0.5, [5.0, 5.0]), [1e-9; 3]);
    let det = patch.a * patch.c - patch.b * patch.b;
    let (u2, k2) = (
        (patch.c * patch.ru - patch.b * patch.rk) / det,
        (patch.a * patch.rk - patch.b * patch.ru) / det,
    );
    let chi2 = patch.a * u2 * u2 + 2.0 * patch.b * u2 * k2 + patch.c * k2 * k2;
    let inv_noise2 = 0.02 * MOTION_SIGNIFICANCE / chi2;
    assert!(!patch.advected(inv_noise2, [0.1, 0.1]).2);
    assert!(patch.advected(100.0 * inv_noise2, [0.1, 0.1]).2);
}

#[test]
fn the_lit_gradient_follows_the_links() {
    // ln L rising by 0.05 per pixel along x and 0.02 along y; the link between x = 2 and 3 cut.
    let w = 6;
    let lit = |x: usize, y: usize| (0.05 * x as f32 + 0.02 * y as f32).exp() * 100.0;
    let rows: Vec<Vec<f32>> = (0..3)
        .map(|y| (0..w).map(|x| lit(x, y)).collect())
        .collect();
    let mut links = vec![RIGHT | DOWN; w];
    links[2] = DOWN;
    links[w - 1] = DOWN;
    let (mut gx, mut gy) = (vec![0.0; w], vec![0.0; w]);
    gradient_row(
        [&rows[0], &rows[1], &rows[2]],
        [&vec![DOWN; w], &links],
        [true, true],
        [&mut gx, &mut gy],
    );
    for x in 0..w {
        // 2·(b − a)/(b + a) per step is tanh of half the log step: within 0.1 % at 0.05.
        assert!((gx[x] - 0.05).abs() < 1e-4, "x {x}: {}", gx[x]);
        assert!((gy[x] - 0.02).abs() < 1e-4, "x {x}: {}", gy[x]);
    }
    // The first row (no row above: its stand-in's links are not followed) and the last (the
    // same below) take one-sided differences.
    gradient_row(
        [&rows[1], &rows[1], &rows[2]],
        [&vec![DOWN; w], &links],
        [false, true],
        [&mut gx, &mut gy],
    );
    assert!(gy.iter().all(|g| (g - 0.02).abs() < 1e-4), "{gy:?}");
    // Without any link a pixel has no gradient.
    gradient_row(
        [&rows[0], &rows[1], &rows[2]],
        [&vec![DOWN; w], &[0u8; 6]],
        [false, false],
        [&mut gx, &mut gy],
    );
    assert!(gx.iter().chain(&gy).all(|&g| g == 0.0), "{gx:?} {gy:?}");
    // Beside a dark pixel (no positive sum) the differences across it are not taken.
    let mut dark = rows[1].clone();
    dark[4] = 0.0;
    gradient_row(
        [&rows[0], &dark, &rows[2]],
        [&vec![DOWN; w], &[RIGHT; 6]],
        [false, false],
        [&mut gx, &mut gy],
    );
    assert_eq!((gx[3], gx[5]), (0.0, 0.0), "{gx:?}");
    assert!((gx[1] - 0.05).abs() < 1e-4, "{gx:?}");
}
