use super::*;

#[test]
fn the_gpu_refuses_what_its_shader_does_not_implement() {
    let cps_rgb = (3, 9, 9);
    assert_eq!(unsupported(cps_rgb, &DecodeParams::default()), None);
    let mut params = DecodeParams::default();
    params.motion.advected_brightness = true;
    let why = unsupported(cps_rgb, &params).unwrap_or_default();
    assert!(why.contains("advected_brightness"), "{why}");
    params.motion.advected_brightness = false;
    params.motion.block_px = 2;
    assert!(unsupported(cps_rgb, &params).is_some());
}
