//! The GPU decode (`shaders/decode.wgsl`) against the CPU decoder, on whatever adapter wgpu finds
//! (Mesa's lavapipe on the CI machine, which has no GPU): window by window through the sliding
//! decoder (the GPU keeps frames and uploads only the new one), through the threaded pipeline,
//! and its refusals and its fall-back to the CPU.
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;
mod gpu_compare;

use gpu_compare::compare;
use std::time::Duration;
use tremorscan::decode::backend::Window;
use tremorscan::decode::{
    check_window, motion_noise, DecodeBackend, DecodeOutput, DecodeParams, MotionModel,
    MotionParams, SlidingDecoder, UnwrapMethod, WindowOutcome, WindowSolver,
};
use tremorscan::device::{Pacing, ReplayCamera};
use tremorscan::frame::Frame;
use tremorscan::pattern::{cps_gray, Axis, CpsGrayVariant};
use tremorscan::pipeline::{DecodePolicy, Pipeline, PipelineConfig};
use tremorscan::rig::{NoiseModel, RigConfig, VirtualRig};
use tremorscan::session::{write_session, Session};
use tremorscan_ui::gpu_decode::{
    backend_for, DecoderChoice, GpuBackend, GpuContext, GpuDecoder, TimestampUse,
};

/// The still window (the paper's decode, without the motion model).
fn still() -> DecodeParams {
    DecodeParams {
        motion: MotionParams::off(),
        ..DecodeParams::default()
    }
}

fn rig(width: usize, height: usize) -> VirtualRig {
    rig_with(RigConfig::paper(width, height).unwrap())
}

fn rig_with(config: RigConfig) -> VirtualRig {
    let seq = config.default_sequence().unwrap();
    VirtualRig::new(config, seq).unwrap()
}

/// Frames `first..first + count` of `rig`, with camera noise.
fn frames(rig: &VirtualRig, first: u64, count: u64) -> Vec<Frame> {
    (first..first + count)
        .map(|i| {
            let mut f = rig.blank_frame();
            rig.render(i, &mut f, None).unwrap();
            f
        })
        .collect()
}

fn gpu_backend(rig: &VirtualRig) -> GpuBackend {
    let ctx = GpuContext::new().unwrap();
    eprintln!("adapter: {}", ctx.adapter);
    GpuBackend::new(ctx, &rig.sequence, &still()).unwrap()
}

/// Streams `count` frames from `first` through a CPU and a GPU sliding decoder; compares every
/// window. The orders turn (0 1 2, 1 2 0, 2 0 1), and from the second window on the GPU receives
/// only the new frame: a wrong slot or pseudo-inverse would scramble the result.
fn compare_stream(width: usize, height: usize, first: u64, count: u64) {
    compare_stream_with(width, height, first, count, still());
}

/// [`compare_stream`] with `params`.
fn compare_stream_with(width: usize, height: usize, first: u64, count: u64, params: DecodeParams) {
    compare_rig_stream(&rig(width, height), first, count, params);
}

/// [`compare_stream`] on `rig` with `params`.
fn compare_rig_stream(rig: &VirtualRig, first: u64, count: u64, params: DecodeParams) {
    let indices: Vec<u64> = (first..first + count).collect();
    let windows = compare_rig_frames(rig, &indices, params);
    assert_eq!(windows as u64, count - 2);
}

/// The rig's frames `indices`, in that order, through a CPU and a GPU sliding decoder; compares
/// every window both decoded and returns how many.
fn compare_rig_frames(rig: &VirtualRig, indices: &[u64], params: DecodeParams) -> usize {
    let stream = indices.iter().map(|&i| frames(rig, i, 1).remove(0));
    compare_frames(rig, stream, params).0
}

/// `stream` (frames of `rig`'s sequence) through a CPU and a GPU sliding decoder; compares
/// every window both decoded, and asserts that they refuse the same windows whole. Returns how
/// many windows were compared and how many of them both refused.
fn compare_frames(
    rig: &VirtualRig,
    stream: impl Iterator<Item = Frame>,
    params: DecodeParams,
) -> (usize, usize) {
    let new = || SlidingDecoder::new(rig.sequence.clone(), rig.config.cross_talk, params).unwrap();
    let mut cpu = new();
    // Timestamps wherever the adapter has them (lavapipe does), so their read-out is tested too.
    let ctx = GpuContext::open(TimestampUse::Always).unwrap();
    let timestamps = ctx.timestamps;
    let backend = GpuBackend::new(ctx, &rig.sequence, &params).unwrap();
    let mut gpu = new().with_backend(Box::new(backend));
    assert!(
        gpu.backend_name().starts_with("GPU"),
        "{}",
        gpu.backend_name()
    );
    let (mut windows, mut refused) = (0, 0);
    for frame in stream {
        let a = match cpu.push(&frame).unwrap() {
            WindowOutcome::Decoded(out) => Some(out.clone()),
            _ => None,
        };
        let b = match gpu.push(&frame).unwrap() {
            WindowOutcome::Decoded(b) => Some(b),
            _ => None,
        };
        let (a, b) = match (a, b) {
            (Some(a), Some(b)) => (a, b),
            (None, None) => continue,
            _ => panic!("only one of them decoded"),
        };
        assert_eq!(a.time_s, b.time_s);
        // The compute pass by the GPU's clock lies inside the whole round trip timed by the host.
        let t = b.timings;
        assert_eq!(t.device_ms.is_some(), timestamps);
        if let Some(device_ms) = t.device_ms {
            assert!(device_ms > 0.0 && device_ms <= t.solve_ms, "{t:?}");
        }
        windows += 1;
        assert_eq!(
            a.refused.as_ref().map(|r| &r.rows),
            b.refused.as_ref().map(|r| &r.rows)
        );
        if a.refused.is_some() {
            let broken = tremorscan::decode::invalid::BROKEN_WINDOW;
            assert!(b.invalid.iter().all(|f| f & broken != 0));
            assert!(b.coordinate_px.iter().all(|c| c.is_nan()));
            refused += 1;
            continue;
        }
        let follows = windows > 1 && params.motion.predicted_start;
        compare(&a, b, params.motion.model != MotionModel::Off, follows);
    }
    (windows, refused)
}

#[test]
fn gpu_decode_matches_the_cpu_decoder_window_by_window() {
    compare_stream(640, 400, 0, 6);
    // A size that is no multiple of the workgroups, whose frames need padding to whole words,
    // and a stream starting on another pattern.
    compare_stream(333, 207, 4, 5);
}

#[test]
fn the_gpu_carries_the_unit_phasor_along_the_fine_phase_as_the_cpu_does() {
    // The transported sum at a decay whose recursions need a longer warm-up than 0.7's
    // (114 px): without the turn on the GPU, 852 of 256,000 pixels' validity differed in the
    // first window.
    let mut params = still();
    params.smoothing.transport = true;
    params.smoothing.decay = 0.85;
    compare_stream_with(640, 400, 0, 4, params);
}

#[test]
fn the_gpu_models_motion_inside_the_window_as_the_cpu_does() {
    // The default decode (the motion model, two Gauss–Newton steps, the noise measured from the
    // window, the acceleration from the previous window, the temporal references) on a hand in
    // a 10 mm tremor swaying 4 mm sideways, over six windows, so that the links between windows
    // are compared too: the stream's state lives on the GPU between windows.
    compare_rig_stream(&swaying_hand(640, 400), 0, 8, DecodeParams::default());
    // A size that is no multiple of the workgroups (nor of the noise grid's step), a stream
    // starting on another pattern, and a camera noisier than the decode is told (σ = 4 against
    // 2), so that the significance test takes the level the window's grid shows.
    let mut config = RigConfig::paper(333, 207).unwrap();
    config.noise = NoiseModel::gaussian(4.0);
    config.scene.hand.as_mut().unwrap().tip_amplitude_mm = 10.0;
    compare_rig_stream(&rig_with(config), 4, 5, DecodeParams::default());
}

#[test]
fn the_gpu_and_the_cpu_agree_where_the_sums_reach_further() {
    // Above 640 px wide the edge-aware sums' decays are raised to the power 640/width
    // (`DecodeParams::reach_scale`), and the warm-up their recursions need grows with them: at
    // 960 px the velocity's 0.8 becomes 0.862, whose halo is 124 rows. The CPU's vertical blocks
    // warmed up on 48 rows whatever the decay until stop 44, dropping up to 0.862⁴⁸ ≈ 8·10⁻⁴ of a
    // sum at every block boundary where the GPU's segments were exact.
    compare_rig_stream(&swaying_hand(960, 600), 0, 4, DecodeParams::default());
}

/// The rig's hand in a 10 mm tremor at the fingertip, swaying 4 mm sideways.
fn swaying_hand(width: usize, height: usize) -> VirtualRig {
    let mut config = RigConfig::paper(width, height).unwrap();
    let hand = config.scene.hand.as_mut().unwrap();
    hand.tip_amplitude_mm = 10.0;
    hand.sway_amplitude_mm = 4.0;
    rig_with(config)
}

#[test]
fn the_gpu_measures_the_final_noise_on_the_whole_grid() {
    // The host's mixed-pixel stage takes the noise the final planes show, measured on the
    // device's grid. A tall image's grid has more values than its image has pixels in eight rows:
    // dispatched as the image (as it once was), the last two thirds of the grid kept the stage-1
    // values, which a hand moving 10 mm raises (16 pixels' validity then differed, within the
    // comparison's allowance, so the level is compared here).
    let mut config = RigConfig::paper(320, 960).unwrap();
    config.noise = NoiseModel::gaussian(4.0);
    config.scene.hand.as_mut().unwrap().tip_amplitude_mm = 10.0;
    let rig = rig_with(config);
    let params = DecodeParams::default();
    let window = frames(&rig, 0, 3);
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let mut cpu = DecodeOutput::new(320, 960, &solver);
    tremorscan::decode::decode_window(&solver, &window, &params, solver_n(), &mut cpu).unwrap();
    // The CPU measured it before marking mixed pixels.
    for flags in &mut cpu.invalid {
        *flags &= !tremorscan::decode::invalid::MIXED;
    }
    let expected = motion_noise::residual_noise_gray(&solver, &cpu, &mut Vec::new()).unwrap();
    let ctx = GpuContext::new().unwrap();
    let mut gpu = GpuDecoder::new(&ctx, 320, 960, &solver, &params).unwrap();
    let mut out = DecodeOutput::new(320, 960, &solver);
    check_window(&solver, &window, &params, solver_n(), &mut out).unwrap();
    gpu.decode(&view(&solver, &refs(&window), &params), &mut out)
        .unwrap();
    let measured = gpu.final_noise_gray().unwrap();
    eprintln!("final noise: CPU {expected}, GPU {measured}");
    assert!(
        (measured - expected).abs() <= 1e-4 * expected,
        "GPU {measured} against CPU {expected}"
    );
}

#[test]
fn after_dropped_frames_the_gpu_links_windows_as_the_cpu_does() {
    // Three frames lost mid-stream (the pattern cycle kept): the windows around the gap are not
    // consecutive, so neither decoder may take an acceleration or a temporal reference across
    // it, and both must pick the links up again after it.
    let mut config = RigConfig::paper(320, 200).unwrap();
    config.scene.hand.as_mut().unwrap().tip_amplitude_mm = 10.0;
    let rig = rig_with(config);
    let indices: Vec<u64> = (0..5).chain(8..13).collect();
    let windows = compare_rig_frames(&rig, &indices, DecodeParams::default());
    assert!(windows >= 4, "{windows} windows compared");
}

#[test]
fn a_corrupted_frame_refuses_the_same_windows_on_the_gpu_and_the_cpu() {
    // Frame 4's red channel from the pattern a quarter period on, on every row and on a tenth
    // of them: the three windows holding it are refused whole (decode/broken.rs), and both
    // decoders restart the links after them.
    let mut config = RigConfig::paper(320, 200).unwrap();
    config.scene.hand.as_mut().unwrap().tip_amplitude_mm = 10.0;
    let rig = rig_with(config);
    let quarter = std::f64::consts::FRAC_PI_2;
    for rows in [0..200, 90..110] {
        let stream = (0..10).map(|i| {
            let mut frame = rig.blank_frame();
            let shift_rad = if i == 4 { quarter } else { 0.0 };
            rig.render_with_shifted_red_on_rows(i, shift_rad, rows.clone(), &mut frame)
                .unwrap();
            frame
        });
        let counts = compare_frames(&rig, stream, DecodeParams::default());
        assert_eq!(counts, (8, 3), "rows {rows:?}");
    }
}

#[test]
fn a_pipeline_runs_on_the_gpu_backend() {
    let rig = rig(320, 200);
    let dir = common::scratch("gpu-pipeline");
    write_session(&dir, rig.session_manifest(), &frames(&rig, 0, 9)).unwrap();
    let session = Session::open(&dir).unwrap();
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        consumer_queue: 16,
        display: false,
        // The default decode, the motion model with it.
        decode_params: DecodeParams::default(),
        ..PipelineConfig::default()
    };
    let camera = ReplayCamera::new(session.clone(), Pacing::AsFastAsPossible);
    let ctx = GpuContext::new().unwrap();
    let backend = GpuBackend::new(ctx, &rig.sequence, &config.decode_params).unwrap();
    let pipeline = Pipeline::start_with_backend(
        Box::new(camera),
        session.sequence().unwrap(),
        session.cross_talk().unwrap().unwrap(),
        session.stereo_model().unwrap(),
        config,
        Box::new(backend),
    )
    .unwrap();
    assert!(pipeline.decoder_name().starts_with("GPU"));
    assert!(pipeline.wait_for_end(Duration::from_secs(60)));
    let mut clouds = 0;
    while let Some(cloud) = pipeline.next_for_consumer() {
        // As the CPU pipeline's test: the hand decodes over most of the image at 320×200
        // (95.5–95.7 % there).
        assert!(cloud.cloud.valid_count() * 4 > 320 * 200 * 3);
        clouds += 1;
    }
    let (metrics, events) = pipeline.stop_with_events();
    assert_eq!(clouds, 7, "{events:?}");
    assert_eq!(metrics.decoded, 7);
    assert!(events
        .iter()
        .all(|e| !matches!(e, tremorscan::pipeline::PipelineEvent::DecodeFailed(_))));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_gpu_refuses_what_it_cannot_decode() {
    let rig = rig(160, 100);
    let ctx = GpuContext::new().unwrap();
    let per_pixel = DecodeParams {
        unwrap: UnwrapMethod::ChebyshevPerPixel,
        ..still()
    };
    let err = GpuBackend::new(ctx, &rig.sequence, &per_pixel).unwrap_err();
    assert!(err.to_string().contains("robust"), "{err}");
    let gray = cps_gray(65, CpsGrayVariant::Full9, 912.0, Axis::Columns, 8).unwrap();
    let err = GpuBackend::new(GpuContext::new().unwrap(), &gray, &still()).unwrap_err();
    assert!(err.to_string().contains("CPS-RGB"), "{err}");
    // `auto` never picks a software adapter; `gpu` refuses a gray sequence with the reason.
    let (auto, _) = backend_for(DecoderChoice::Auto, &rig.sequence, &still()).unwrap();
    let ctx = GpuContext::new().unwrap();
    assert_eq!(
        auto.name().starts_with("GPU"),
        !ctx.is_software,
        "{}",
        auto.name()
    );
    let err = backend_for(DecoderChoice::Gpu, &gray, &still())
        .err()
        .unwrap();
    assert!(
        format!("{err:#}").contains("the GPU decoder was asked for"),
        "{err:#}"
    );

    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let err = GpuDecoder::new(&ctx, 160, 100, &solver, &per_pixel)
        .err()
        .unwrap();
    assert!(err.to_string().contains("robust"), "{err}");
    let params = still();
    let mut gpu = GpuDecoder::new(&ctx, 160, 100, &solver, &params).unwrap();
    let window = frames(&rig, 0, 3);
    let mut out = DecodeOutput::new(160, 100, &solver);
    // Frames out of the solver's order.
    let shuffled = [window[1].clone(), window[2].clone(), window[0].clone()];
    let err = gpu
        .decode(&view(&solver, &refs(&shuffled), &params), &mut out)
        .unwrap_err();
    assert!(err.to_string().contains("expects"), "{err}");
    // Frames of another size.
    let small = frames(
        &VirtualRig::new(RigConfig::paper(80, 64).unwrap(), rig.sequence.clone()).unwrap(),
        0,
        3,
    );
    let err = gpu
        .decode(&view(&solver, &refs(&small), &params), &mut out)
        .unwrap_err();
    assert!(err.to_string().contains("80×64"), "{err}");
}

/// `n` of the paper rig's sequence.
fn solver_n() -> Option<u32> {
    RigConfig::paper(64, 64)
        .unwrap()
        .default_sequence()
        .unwrap()
        .chebyshev_n()
}

/// The frames of a window as the decoder hands them to a backend.
fn refs(frames: &[Frame]) -> Vec<&Frame> {
    frames.iter().collect()
}

fn view<'a>(
    solver: &'a WindowSolver,
    frames: &'a [&'a Frame],
    params: &'a DecodeParams,
) -> Window<'a> {
    Window {
        solver,
        frames,
        new_frames: 3,
        params,
        chebyshev_n: solver_n(),
    }
}

#[test]
fn a_failing_gpu_reports_once_and_the_decode_goes_on_on_the_cpu() {
    let rig = rig(160, 100);
    let params = still();
    let mut backend = gpu_backend(&rig);
    let window = frames(&rig, 0, 3);
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    // An output of another size than the frames: the GPU decoder is set up for the output and
    // refuses the frames, as it would fail on a lost device.
    let mut wrong = DecodeOutput::new(80, 50, &solver);
    let err = backend
        .decode(&view(&solver, &refs(&window), &params), &mut wrong)
        .unwrap_err();
    assert!(err.to_string().contains("decoded on the CPU"), "{err}");
    assert!(
        backend.name().contains("after the GPU failed"),
        "{}",
        backend.name()
    );
    // The next window decodes, on the CPU, exactly as the CPU decoder does.
    let mut out = DecodeOutput::new(160, 100, &solver);
    check_window(&solver, &window, &params, solver_n(), &mut out).unwrap();
    backend
        .decode(&view(&solver, &refs(&window), &params), &mut out)
        .unwrap();
    let mut cpu = DecodeOutput::new(160, 100, &solver);
    tremorscan::decode::decode_window(&solver, &window, &params, solver_n(), &mut cpu).unwrap();
    assert_eq!(out.invalid, cpu.invalid);
    assert!(out
        .coordinate_px
        .iter()
        .zip(&cpu.coordinate_px)
        .all(|(a, b)| a == b || (a.is_nan() && b.is_nan())));
}

#[test]
fn a_device_error_is_returned_not_a_panic() {
    let rig = rig(160, 100);
    let ctx = GpuContext::new().unwrap();
    let params = still();
    let solver = WindowSolver::new(&rig.sequence, &[0, 1, 2], &rig.config.cross_talk).unwrap();
    let mut gpu = GpuDecoder::new(&ctx, 160, 100, &solver, &params).unwrap();
    let _buffer = invalid_buffer(&ctx);
    let error = ctx.take_error();
    assert!(error.is_some(), "no error kept");
    assert!(ctx.take_error().is_none(), "taken twice");
    // An error during a window comes back as that window's error.
    let window = frames(&rig, 0, 3);
    let mut out = DecodeOutput::new(160, 100, &solver);
    let _buffer = invalid_buffer(&ctx);
    let err = gpu
        .decode(&view(&solver, &refs(&window), &params), &mut out)
        .unwrap_err();
    assert!(err.to_string().contains("reported an error"), "{err}");
    gpu.decode(&view(&solver, &refs(&window), &params), &mut out)
        .unwrap();
}

/// A buffer mapped for reading and used as storage at once: invalid, so the device reports a
/// validation error, which wgpu's default handler would turn into a panic of the decode thread.
fn invalid_buffer(ctx: &GpuContext) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("invalid on purpose"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

#[test]
fn a_pipeline_whose_gpu_fails_goes_on_on_the_cpu_and_says_so() {
    let rig = rig(320, 200);
    let dir = common::scratch("gpu-fails");
    write_session(&dir, rig.session_manifest(), &frames(&rig, 0, 9)).unwrap();
    let session = Session::open(&dir).unwrap();
    // The device reports an error before the decoder is set up: the first window fails.
    let ctx = GpuContext::new().unwrap();
    let _buffer = invalid_buffer(&ctx);
    let backend = GpuBackend::new(ctx, &rig.sequence, &still()).unwrap();
    let config = PipelineConfig {
        decode_policy: DecodePolicy::Lossless,
        consumer_queue: 16,
        display: false,
        ..PipelineConfig::default()
    };
    let pipeline = Pipeline::start_with_backend(
        Box::new(ReplayCamera::new(session.clone(), Pacing::AsFastAsPossible)),
        session.sequence().unwrap(),
        session.cross_talk().unwrap().unwrap(),
        session.stereo_model().unwrap(),
        config,
        Box::new(backend),
    )
    .unwrap();
    assert!(pipeline.wait_for_end(Duration::from_secs(60)));
    let mut clouds = 0;
    while let Some(cloud) = pipeline.next_for_consumer() {
        assert!(cloud.cloud.valid_count() * 4 > 320 * 200 * 3);
        clouds += 1;
    }
    let name = pipeline.decoder_name();
    assert!(
        name.starts_with("CPU") && name.contains("after the GPU failed"),
        "{name}"
    );
    let (_, events) = pipeline.stop_with_events();
    let failures: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            tremorscan::pipeline::PipelineEvent::DecodeFailed(m) => Some(m),
            _ => None,
        })
        .collect();
    assert_eq!(failures.len(), 1, "{events:?}");
    assert!(
        failures[0].contains("decoded on the CPU"),
        "{}",
        failures[0]
    );
    // Windows end at frames 2–8. The first fails; the pipeline then starts a fresh window
    // (frames 3–5), so frames 5–8 give the 4 clouds, decoded on the CPU.
    assert_eq!(clouds, 4);
    let _ = std::fs::remove_dir_all(&dir);
}
