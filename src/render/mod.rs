//! The 3D viewport: wgpu pipelines (created once, kept in egui_wgpu's callback resources) and
//! the per-frame callback that draws a scene into an offscreen colour + depth target and blits
//! it into egui's pass. Knows nothing of the editor's panels.
//!
//! GPU-free parts ([`camera`], [`mesh_data`]) are tested without a window.

pub mod camera;
pub mod colormap;
pub mod mesh_data;
mod viewport;

pub use camera::OrbitCamera;
pub use mesh_data::{GpuVertex, MeshData};
pub use viewport::{DrawStyle, MarkerInstance, SceneItem, ViewportCallback, ViewportRenderer};

/// The viewport's WGSL (validated by naga in tests).
pub const MESH_SHADER: &str = include_str!("../../shaders/mesh.wgsl");
/// Full-screen copy of the offscreen target into egui's pass.
pub const BLIT_SHADER: &str = include_str!("../../shaders/blit.wgsl");
