use std::time::Instant;
use tremorscan::decode::*;
use tremorscan::rig::*;
fn main() {
    let w: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(1920);
    let h = w * 10 / 16;
    let config = RigConfig::paper(w, h).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let mut frames = vec![];
    for i in 0..3 { let mut f = rig.blank_frame(); let t = Instant::now(); rig.render(i, &mut f, None).unwrap(); println!("render {:.1} ms", t.elapsed().as_secs_f64()*1e3); frames.push(f); }
    let solver = WindowSolver::new(&seq, &[0,1,2], &rig.config.cross_talk).unwrap();
    let mut out = DecodeOutput::new(w, h, &solver);
    let refs: Vec<&tremorscan::frame::Frame> = frames.iter().collect();
    for _ in 0..30 {
        let t = Instant::now();
        decode_window(&solver, &refs, &DecodeParams::default(), Some(65), &mut out).unwrap();
        println!("decode {:.2} ms", t.elapsed().as_secs_f64()*1e3);
    }
    let p = DecodeParams { unwrap: UnwrapMethod::ChebyshevPerPixel, ..Default::default() };
    let t = Instant::now();
    decode_window(&solver, &refs, &p, Some(65), &mut out).unwrap();
    println!("decode per-pixel (no smoothing) {:.2} ms", t.elapsed().as_secs_f64()*1e3);
}
