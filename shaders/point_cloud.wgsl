// Point-cloud renderer: every point is an instance drawn as a screen-aligned square of
// `point_size_px` pixels (two triangles, six vertices), in the point's decoded colour.
// Paired with `PointUniforms` and `PointVertex` in ui/src/render/point_cloud.rs.

struct PointUniforms {
    // World (camera frame, mm) to clip space.
    clip_from_world: mat4x4<f32>,
    // Size of the viewport, physical pixels.
    viewport_px: vec2<f32>,
    point_size_px: f32,
    _padding: f32,
};

@group(0) @binding(0) var<uniform> uniforms: PointUniforms;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) colour: vec4<f32>,
};

@vertex
fn vs_main(
    @builtin(vertex_index) corner: u32,
    @location(0) point_in_world_mm: vec3<f32>,
    @location(1) colour: vec4<f32>,
) -> VertexOut {
    var out: VertexOut;
    // Corners of the square, two triangles (a function variable, so it can be indexed at run time).
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let clip = uniforms.clip_from_world * vec4<f32>(point_in_world_mm, 1.0);
    // Offsets in normalised device units, scaled by w so they stay constant on screen.
    let half_size_ndc = uniforms.point_size_px / uniforms.viewport_px;
    let offset = corners[corner % 6u] * half_size_ndc * clip.w;
    out.clip = vec4<f32>(clip.xy + offset, clip.zw);
    out.colour = colour;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return in.colour;
}
