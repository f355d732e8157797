//! The GPU decode (`shaders/decode.wgsl`) against the CPU decoder, on whatever adapter wgpu finds
//! (Mesa's lavapipe on the CI machine, which has no GPU).
#![allow(clippy::unwrap_used, reason = "tests")]

use tremorscan::decode::{decode_window, DecodeOutput, DecodeParams, UnwrapMethod, WindowSolver};
use tremorscan::frame::Frame;
use tremorscan::rig::{RigConfig, VirtualRig};
use tremorscan_ui::gpu_decode::{GpuContext, GpuDecoder};

/// Renders frames `first..first + 3` of the paper rig at `width`×`height`, with camera noise.
fn window(width: usize, height: usize, first: u64) -> (VirtualRig, Vec<Frame>) {
    let config = RigConfig::paper(width, height).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq).unwrap();
    let frames = (first..first + 3)
        .map(|i| {
            let mut f = rig.blank_frame();
            rig.render(i, &mut f, None).unwrap();
            f
        })
        .collect();
    (rig, frames)
}

fn compare(ctx: &GpuContext, width: usize, height: usize, first: u64) {
    let (rig, frames) = window(width, height, first);
    let order: Vec<usize> = frames.iter().map(|f| f.pattern_index).collect();
    let solver = WindowSolver::new(&rig.sequence, &order, &rig.config.cross_talk).unwrap();
    let params = DecodeParams::default();
    let n = rig.sequence.chebyshev_n().unwrap();
    let mut cpu = DecodeOutput::new(width, height, &solver);
    decode_window(&solver, &frames, &params, Some(n), &mut cpu).unwrap();
    let mut gpu = GpuDecoder::new(ctx, width, height, &solver, &params, n).unwrap();
    let (mut coordinate, mut invalid) = (Vec::new(), Vec::new());
    gpu.decode(
        [&frames[0], &frames[1], &frames[2]],
        &mut coordinate,
        &mut invalid,
    )
    .unwrap();
    let (mut worst, mut both, mut validity_differs) = (0f32, 0usize, 0usize);
    for p in 0..width * height {
        let (c, g) = (cpu.coordinate_px[p], coordinate[p]);
        assert_eq!(g.is_nan(), invalid[p] != 0, "pixel {p}");
        if (cpu.invalid[p] == 0) != (invalid[p] == 0) {
            validity_differs += 1;
            continue;
        }
        if c.is_finite() {
            worst = worst.max((c - g).abs());
            both += 1;
        }
    }
    eprintln!(
        "{width}×{height}: {both} valid on both, worst difference {worst:.2e} px, \
         validity differs on {validity_differs} of {} pixels",
        width * height
    );
    // The bound. Both paths use the same polynomial atan2 and the same order of
    // operations; the differences are f32 rounding (fused multiply–adds on the GPU, the CPU's
    // blocked vertical recursion), about 1e-5 px.
    assert!(worst <= 1e-3, "worst difference {worst} px");
    assert!(both > width * height / 4, "only {both} valid pixels");
    // Validity can only differ where a test statistic lies within rounding of its threshold:
    // a handful of pixels, not a pattern. One in 10⁴ is far above that and far below any
    // systematic difference (a wrong check would flip thousands).
    assert!(
        validity_differs * 10_000 <= width * height,
        "validity differs on {validity_differs} pixels"
    );
}

#[test]
fn gpu_decode_matches_the_cpu_decoder() {
    let ctx = GpuContext::new().unwrap();
    eprintln!("adapter: {}", ctx.adapter);
    compare(&ctx, 640, 400, 0);
    // A size that is no multiple of the workgroups, whose frames need padding to whole words,
    // and a window starting on another pattern.
    compare(&ctx, 333, 207, 4);
}

#[test]
fn gpu_decoder_refuses_what_it_cannot_decode() {
    let ctx = GpuContext::new().unwrap();
    let (rig, frames) = window(160, 100, 0);
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let per_pixel = DecodeParams {
        unwrap: UnwrapMethod::ChebyshevPerPixel,
        ..DecodeParams::default()
    };
    let err = GpuDecoder::new(&ctx, 160, 100, &solver, &per_pixel, 65)
        .err()
        .unwrap();
    assert!(err.to_string().contains("robust"), "{err}");
    let mut gpu = GpuDecoder::new(&ctx, 160, 100, &solver, &DecodeParams::default(), 65).unwrap();
    let (mut c, mut i) = (Vec::new(), Vec::new());
    let err = gpu
        .decode([&frames[1], &frames[2], &frames[0]], &mut c, &mut i)
        .unwrap_err();
    assert!(err.to_string().contains("expects"), "{err}");
    let (_, small) = window(80, 64, 0);
    let err = gpu
        .decode([&small[0], &small[1], &small[2]], &mut c, &mut i)
        .unwrap_err();
    assert!(err.to_string().contains("80×64"), "{err}");
}
