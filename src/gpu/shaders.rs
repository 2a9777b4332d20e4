//! The SPIR-V modules build.rs compiled from `shaders/*.comp` (SPIR-V 1.3,
//! Vulkan 1.1).

/// `shaders/render.comp`: the per-pixel entry (twin of `cpu.rs`), exact:
/// its arithmetic is `precise` (`shaders/precise.glsl`), so lavapipe
/// matches the CPU mirror bit for bit.
pub const RENDER: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/render.spv"));
/// `shaders/render.comp` compiled with `WHITTED_FAST_MATH`: no `precise`,
/// so the driver may reorder and fuse its float arithmetic
/// (`--gpu-math fast`).
pub const RENDER_FAST: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/render_fast.spv"));
/// `shaders/render.comp` with `WHITTED_LANES`: several lattice points an
/// invocation (`--lane-pixels`), exact and fast.
pub const RENDER_LANES: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/render_lanes.spv"));
pub const RENDER_LANES_FAST: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/render_lanes_fast.spv"));
/// `shaders/probe.comp`: test kernels running one function on many inputs
/// (always exact).
pub const PROBE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/probe.spv"));
/// `shaders/wavefront.comp`, one module per stage (`WF_STAGE`): the
/// wavefront kernel (`--kernel wavefront`, src/gpu/wavefront.rs).
pub const WF_GENERATE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_generate.spv"));
pub const WF_EXTEND: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_extend.spv"));
pub const WF_SHADE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_shade.spv"));
pub const WF_SHADOW: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_shadow.spv"));
pub const WF_COMBINE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_combine.spv"));
pub const WF_RESOLVE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/wavefront_resolve.spv"));
/// `shaders/calibration.comp`: a plain grid tracer for opaque sphere
/// fields, the yardstick the exact kernel is measured against on a device
/// (docs/profiling.md): `--kernel calibration`.
pub const CALIBRATION: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/calibration.spv"));
