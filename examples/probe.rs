use tremorscan::decode::*;
use tremorscan::rig::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let w: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(640);
    let h = w * 10 / 16;
    for sigma in [0.0, 1.0, 2.0, 3.0, 4.0] {
        let mut config = RigConfig::paper(w, h).unwrap();
        config.noise = NoiseModel::gaussian(sigma);
        if let Some(t) = config.scene.hand.as_mut() { t.tip_amplitude_mm = 0.0; t.hand_amplitude_mm = 0.0; }
        let seq = config.default_sequence().unwrap();
        let half = seq.period_px(65) / 2.0;
        let rig = VirtualRig::new(config, seq.clone()).unwrap();
        for method in [UnwrapMethod::ChebyshevPerPixel, UnwrapMethod::ChebyshevRobust] {
            for checks in [false, true] {
                let mut params = DecodeParams { unwrap: method, ..Default::default() };
                if !checks { params.max_rounding_residual = 0.5; params.max_disagreement_px = f32::INFINITY; params.smoothing.min_support = 0.0; }
                let mut dec = SlidingDecoder::new(seq.clone(), rig.config.cross_talk, params).unwrap();
                let mut frame = rig.blank_frame();
                let mut truth = GroundTruth::default();
                for i in 0..3 { rig.render(i, &mut frame, if i == 1 { Some(&mut truth) } else { None }).unwrap(); let _ = dec.push(&frame).unwrap(); }
                let out = dec.output().unwrap();
                let a = evaluate::compare(out, &truth, half);
                println!("sigma {sigma} {method:?} checks {checks}: lit {} valid {} unlit-valid {} fail {} ({:.3}%) rms {:.4} max {:.3} cov {:.3}", a.lit, a.valid, a.valid_unlit, a.unwrap_errors, 100.0*a.unwrap_error_rate(), a.rms_px, a.max_px, a.coverage());
            }
        }
    }
}
