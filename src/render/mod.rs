//! GPU rendering with wgpu (feature `render`).
