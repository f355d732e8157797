//! Every WGSL file in `shaders/` parses and validates with naga (the compiler wgpu uses), and
//! the point shader's structs have the sizes the `#[repr(C)]` Rust structs have.

use std::path::PathBuf;

fn shaders() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("shaders folder")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    files.sort();
    files
}

/// The decode shader's files are one module (`decode.wgsl`, then its motion model's and its
/// stream's parts): each is validated as the application compiles them, together.
const DECODE_PARTS: [&str; 3] = ["decode.wgsl", "decode_motion.wgsl", "decode_stream.wgsl"];

fn validate(path: &PathBuf) -> naga::Module {
    let is_decode_part = path
        .file_name()
        .is_some_and(|name| DECODE_PARTS.iter().any(|part| name == *part));
    let source = if is_decode_part {
        tremorscan_ui::gpu_decode::SHADER_WGSL.to_string()
    } else {
        std::fs::read_to_string(path).expect("read shader")
    };
    let module = naga::front::wgsl::parse_str(&source)
        .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
    module
}

#[test]
fn every_shader_validates() {
    let files = shaders();
    assert!(!files.is_empty(), "no shaders found");
    for path in &files {
        validate(path);
    }
}

#[test]
fn the_point_shader_matches_its_rust_structs() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shaders/point_cloud.wgsl");
    let module = validate(&path);
    let layouter = {
        let mut l = naga::proc::Layouter::default();
        l.update(module.to_ctx()).expect("layout");
        l
    };
    let uniforms = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("PointUniforms"))
        .map(|(h, _)| h)
        .expect("PointUniforms in the shader");
    assert_eq!(
        layouter[uniforms].size as usize,
        std::mem::size_of::<tremorscan_ui::render::point_cloud::PointUniforms>()
    );
    for entry in ["vs_main", "fs_main"] {
        assert!(
            module.entry_points.iter().any(|e| e.name == entry),
            "entry point {entry}"
        );
    }
}

#[test]
fn the_decode_shader_matches_its_rust_struct() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shaders/decode.wgsl");
    let module = validate(&path);
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Params"))
        .expect("Params in the shader");
    assert_eq!(
        layouter[handle].size as usize,
        std::mem::size_of::<tremorscan_ui::gpu_decode::DecodeUniform>()
    );
    // Member offsets too: a reordered field would keep the size and scramble the values.
    let naga::TypeInner::Struct { members, .. } = &ty.inner else {
        panic!("Params is not a struct");
    };
    let offset = |name: &str| {
        members
            .iter()
            .find(|m| m.name.as_deref() == Some(name))
            .map(|m| m.offset as usize)
            .unwrap_or_else(|| panic!("member {name}"))
    };
    use std::mem::offset_of;
    use tremorscan_ui::gpu_decode::DecodeUniform as U;
    assert_eq!(offset("first_slot"), offset_of!(U, first_slot));
    assert_eq!(offset("freq"), offset_of!(U, freq));
    assert_eq!(offset("gain"), offset_of!(U, gain));
    assert_eq!(offset("x_max"), offset_of!(U, x_max));
    assert_eq!(offset("half_period_px"), offset_of!(U, half_period_px));
    assert_eq!(offset("unit_per_fine"), offset_of!(U, unit_per_fine));
    assert_eq!(offset("halo"), offset_of!(U, halo));
    use tremorscan_ui::gpu_decode::{MODEL_WINDOW_OFFSET, MOTION_STAGES, STAGES};
    for entry in STAGES.iter().chain(&MOTION_STAGES) {
        assert!(
            module.entry_points.iter().any(|e| e.name == *entry),
            "entry point {entry}"
        );
    }
    let constant = |name: &str| {
        let (_, c) = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{name} in the shader"));
        match module.global_expressions[c.init] {
            naga::Expression::Literal(naga::Literal::U32(v)) => v as usize,
            ref other => panic!("{name} is {other:?}"),
        }
    };
    // The host dispatches one invocation per segment of the recursions: the same length.
    assert_eq!(
        constant("SEGMENT"),
        tremorscan_ui::gpu_decode::RECURSION_SEGMENT as usize
    );
    // The model buffer: the library's packed basis, then the window's values from M_ON on.
    let packed = tremorscan::decode::MotionBasis::PACKED_WORDS;
    assert_eq!(constant("M_MIN_SHIFT"), packed - 2);
    assert_eq!(constant("M_BIAS_NOISE2"), packed - 1);
    assert_eq!(constant("M_ON"), MODEL_WINDOW_OFFSET);
    assert_eq!(constant("M_CHECK_TIME"), MODEL_WINDOW_OFFSET + 11);
    assert_eq!(constant("M_WIDE_UNIT_PER_FINE"), MODEL_WINDOW_OFFSET + 14);
}
