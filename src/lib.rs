//! whitted: a recursive (Whitted-style) ray tracer. The main path is a GLSL
//! compute shader dispatched through Vulkan (`gpu`); beside it runs a CPU
//! mirror of the same algorithm on the same packed data (`cpu`, `trace`).
//!
//! Data flow: `scene::load` → `pack::pack` → `cpu::render` | `gpu::render`
//! → `output::write`.

pub mod budget;
pub mod constants;
pub mod cpu;
pub mod export;
pub mod gen;
pub mod gpu;
pub mod metrics;
pub mod output;
pub mod pack;
pub mod scene;
pub mod trace;
