//! The point-cloud renderer: wgpu only, no egui. `shaders/point_cloud.wgsl` draws every point
//! as an instance, a screen-aligned square of a few pixels in the point's decoded colour.
//!
//! - [`PointVertex`] is one instance (16 bytes); [`PointUniforms`] the view (80 bytes). Both are
//!   `#[repr(C)]` and match the WGSL structs field for field.
//! - The vertex buffer grows to the largest cloud seen and is reused; only valid points are
//!   uploaded (the organised cloud's invalid slots are skipped on the CPU by [`pack_points`]).
//! - The pipeline draws into whatever pass it is given: the egui render pass in the app (with
//!   the app's depth buffer, so near points hide far ones), or a pass without depth in tests.

use bytemuck::{Pod, Zeroable};
use tremorscan::triangulate::PointCloud;

/// The shader source.
pub const SHADER_WGSL: &str = include_str!("../../../shaders/point_cloud.wgsl");

/// One point instance: position (camera frame, mm) and colour (RGBA, 8-bit).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PointVertex {
    pub point_in_world_mm: [f32; 3],
    pub colour_rgba: [u8; 4],
}

/// The view, as the shader's `PointUniforms`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PointUniforms {
    /// Column-major 4×4 matrix from world (camera frame, mm) to clip space.
    pub clip_from_world: [[f32; 4]; 4],
    pub viewport_px: [f32; 2],
    pub point_size_px: f32,
    pub padding: f32,
}

/// Writes the valid points of `cloud` into `out` (cleared first), every `stride`-th pixel in
/// each direction (1 = all). Returns the number written.
pub fn pack_points(cloud: &PointCloud, stride: usize, out: &mut Vec<PointVertex>) -> usize {
    out.clear();
    let stride = stride.max(1);
    for y in (0..cloud.height).step_by(stride) {
        for x in (0..cloud.width).step_by(stride) {
            let i = y * cloud.width + x;
            let p = cloud.point_in_camera_mm[i];
            if p.iter().all(|c| c.is_finite()) {
                let [r, g, b] = cloud.colour_rgb[i];
                out.push(PointVertex {
                    point_in_world_mm: p,
                    colour_rgba: [r, g, b, 255],
                });
            }
        }
    }
    out.len()
}

pub struct PointCloudRenderer {
    pipeline: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    vertices: Option<wgpu::Buffer>,
    count: u32,
    /// Which cloud (the caller's number) the vertex buffer holds.
    uploaded_window: Option<u64>,
}

impl PointCloudRenderer {
    /// A renderer drawing into `target_format`, testing and writing depth when `depth_format`
    /// is given.
    pub fn new(
        device: &wgpu::Device,
        target_format: wgpu::TextureFormat,
        depth_format: Option<wgpu::TextureFormat>,
    ) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("point_cloud.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER_WGSL.into()),
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("point uniforms"),
            size: std::mem::size_of::<PointUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("point uniforms"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("point uniforms"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("point cloud"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let instance_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<PointVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Unorm8x4],
        };
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("point cloud"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(instance_layout)],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: depth_format.map(|format| wgpu::DepthStencilState {
                format,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(target_format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self {
            pipeline,
            uniforms,
            bind_group,
            vertices: None,
            count: 0,
            uploaded_window: None,
        }
    }

    /// Uploads `points` (the cloud the caller numbers `window`), growing the vertex buffer when
    /// needed.
    pub fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        points: &[PointVertex],
        window: u64,
    ) {
        let bytes: &[u8] = bytemuck::cast_slice(points);
        let fits = self
            .vertices
            .as_ref()
            .is_some_and(|b| b.size() >= bytes.len() as u64);
        if !fits {
            self.vertices = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("points"),
                size: (bytes.len() as u64).max(16),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        if let Some(buffer) = &self.vertices {
            if !bytes.is_empty() {
                queue.write_buffer(buffer, 0, bytes);
            }
        }
        self.count = points.len() as u32;
        self.uploaded_window = Some(window);
    }

    /// The number of the cloud last uploaded.
    pub fn uploaded_window(&self) -> Option<u64> {
        self.uploaded_window
    }

    pub fn set_view(&self, queue: &wgpu::Queue, uniforms: &PointUniforms) {
        queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(uniforms));
    }

    /// Points uploaded last.
    pub fn point_count(&self) -> u32 {
        self.count
    }

    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        let Some(vertices) = &self.vertices else {
            return;
        };
        if self.count == 0 {
            return;
        }
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.draw(0..6, 0..self.count);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structs_match_the_wgsl_layout() {
        // WGSL: vec3<f32> + unorm8x4 packed in a 16-byte instance; uniforms mat4 + vec2 + 2 f32.
        assert_eq!(std::mem::size_of::<PointVertex>(), 16);
        assert_eq!(std::mem::size_of::<PointUniforms>(), 80);
    }

    #[test]
    fn packing_skips_invalid_points_and_honours_the_stride() {
        let mut cloud = PointCloud {
            width: 4,
            height: 2,
            time_s: 0.0,
            point_in_camera_mm: vec![[1.0, 2.0, 500.0]; 8],
            colour_rgb: vec![[10, 20, 30]; 8],
            fringe_amplitude: vec![1.0; 8],
        };
        cloud.point_in_camera_mm[1] = [f32::NAN; 3];
        let mut out = Vec::new();
        assert_eq!(pack_points(&cloud, 1, &mut out), 7);
        assert_eq!(out[0].colour_rgba, [10, 20, 30, 255]);
        // Stride 2: pixels (0,0) and (2,0) of the first row only.
        assert_eq!(pack_points(&cloud, 2, &mut out), 2);
    }
}
