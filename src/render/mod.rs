//! wgpu rendering.
