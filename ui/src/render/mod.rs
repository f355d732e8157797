//! GPU renderers, one per primitive, each with its WGSL in `shaders/` beside the `#[repr(C)]`
//! structs that feed it. They depend on wgpu only, not on egui ([`crate::gui`] bridges them).

pub mod orbit;
pub mod point_cloud;
