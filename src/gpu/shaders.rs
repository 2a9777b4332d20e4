//! The SPIR-V modules build.rs compiled from `shaders/*.comp` (SPIR-V 1.3,
//! Vulkan 1.1).

/// `shaders/render.comp`: the per-pixel entry (twin of `cpu.rs`).
pub const RENDER: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/render.spv"));
/// `shaders/probe.comp`: test kernels running one function on many inputs.
pub const PROBE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/probe.spv"));
