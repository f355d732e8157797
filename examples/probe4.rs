use tremorscan::decode::*;
use tremorscan::rig::*;
fn main() {
    let config = RigConfig::paper(640, 400).unwrap();
    let seq = config.default_sequence().unwrap();
    let rig = VirtualRig::new(config, seq.clone()).unwrap();
    let mut dec = SlidingDecoder::new(seq.clone(), rig.config.cross_talk, DecodeParams::default()).unwrap();
    let mut frame = rig.blank_frame();
    let mut truths = vec![];
    for i in 87..90u64 { let mut t = GroundTruth::default(); rig.render(i, &mut frame, Some(&mut t)).unwrap(); truths.push(t); let _ = dec.push(&frame).unwrap(); }
    let out = dec.output().unwrap();
    let (mut edge, mut inner) = (0, 0);
    let w = 640;
    for i in 0..out.coordinate_px.len() {
        let t = truths[1].coordinate_px[i];
        if out.invalid[i] == 0 && t.is_finite() && (out.coordinate_px[i] - t).abs() > 14.0 {
            let consistent = truths.iter().all(|tr| tr.surface[i] == truths[1].surface[i] && (tr.coordinate_px[i] - t).abs() < 1.0);
            if consistent { inner += 1; if inner < 6 { println!("inner px ({},{}) dec {} truth {} coarse {} surf {} amp {} {} {}", i%w, i/w, out.coordinate_px[i], t, out.coarse_px[i], truths[1].surface[i], out.amplitude_at(0,i%w,i/w), out.amplitude_at(1,i%w,i/w), out.amplitude_at(2,i%w,i/w)); } } else { edge += 1; }
        }
    }
    println!("edge {edge} inner {inner}");
    let mut ppm = format!("P6 640 400 255\n").into_bytes();
    for i in 0..out.coordinate_px.len() {
        let t = truths[1].coordinate_px[i];
        let px: [u8;3] = if out.invalid[i] != 0 { [0,0,80] } else if t.is_finite() && (out.coordinate_px[i] - t).abs() > 14.0 { [255,0,0] } else if truths[1].surface[i] == 2 { [200,150,120] } else { [120,120,120] };
        ppm.extend_from_slice(&px);
    }
    std::fs::write("/tmp/err.ppm", ppm).unwrap();
}
