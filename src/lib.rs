//! whitted: a recursive (Whitted-style) ray tracer. The main path is a GLSL
//! compute shader dispatched through Vulkan (`gpu`); beside it runs a CPU
//! mirror of the same algorithm on the same packed data (`cpu`, `trace`).
//!
//! Data flow: `scene::load` → `pack::pack` → `cpu::render` | `gpu::render`
//! → `output::write`; `run::render` is the one entry every command and
//! test calls (docs/architecture.md).

pub mod bench;
pub mod budget;
pub mod chart;
pub mod cli;
pub mod constants;
pub mod cpu;
pub mod error;
pub mod export;
pub mod files;
pub mod fuzzing;
pub mod gen;
pub mod gpu;
pub mod metrics;
pub mod output;
pub mod pack;
pub mod plot;
pub mod povray;
pub mod profile;
pub mod reference;
pub mod run;
pub mod scene;
pub mod stability;
pub mod sys;
pub mod trace;

pub use run::{render, Backend, Precision, RenderOptions, Rendered};
