//! The Vulkan backend: `shaders/render.comp` dispatched through ash on the
//! packed arrays, bit for bit the buffers the CPU mirror reads.
//!
//! One file per concept: `context` (instance, messenger, device choice,
//! queue, allocator), `memory` (buffers, upload, readback), `pipeline`
//! (kernels, descriptors, push and specialization constants, pipeline
//! cache), `dispatch` (command buffers, tiles, timestamps, fences),
//! `probe` (test kernels). `unsafe` lives only here.

pub mod context;
pub mod dispatch;
pub mod loops;
pub mod memory;
pub mod pipeline;
pub mod probe;
pub mod shaders;
pub mod wavefront;

pub use context::{validation_errors, validation_warnings, DeviceInfo, DeviceKind};
pub use probe::{ProbeItem, ProbeMode, ProbeResult};

use crate::constants::SAMPLING_CORNERS;
use crate::cpu::{self, Frame};
use crate::pack::Packed;
use crate::trace::RayStats;
use ash::vk;
use context::Context;
use dispatch::Commands;
use memory::Buffer;
use pipeline::Kernel;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What can go wrong on the GPU path. `is_user_error` and
/// `is_device_fault` sort the variants for the CLI's exit codes (2 and 4;
/// anything else is internal, 3).
#[derive(Clone, Debug, thiserror::Error)]
pub enum GpuError {
    /// No loader, no driver, no device (or no real GPU when one is required).
    #[error("no Vulkan device: {0}")]
    NoDevice(String),
    #[error("--device {index}: {}", bad_index(*count))]
    BadIndex { index: usize, count: usize },
    #[error("{0}")]
    Unusable(String),
    /// The scene or the options exceed what the device can do.
    #[error("{0}")]
    Limits(String),
    /// A setting from the environment is malformed (WHITTED_GPU_FAULT,
    /// WHITTED_FENCE_TIMEOUT, WHITTED_PIPELINE_CACHE, WHITTED_RENDER_SPV).
    #[error("{0}")]
    Setting(String),
    #[error("shader: {0}")]
    Shader(String),
    #[error("{call} failed: {result}")]
    Vulkan {
        call: &'static str,
        result: vk::Result,
    },
    #[error("GPU memory allocation failed for {what}: {msg}")]
    Memory { what: String, msg: String },
    #[error("internal error: {0}")]
    Internal(String),
    /// VK_ERROR_DEVICE_LOST: the driver reset the device (a crash, a hung
    /// shader, a watchdog). The device is not used again.
    #[error(
        "{device} was lost during {call} (VK_ERROR_DEVICE_LOST: the driver reset it); \
         the render was not finished"
    )]
    DeviceLost { device: String, call: &'static str },
    /// The device's memory ran out (VK_ERROR_OUT_OF_DEVICE_MEMORY, or
    /// gpu-allocator found no room) although the scene passed the limits
    /// check: another program holds the memory.
    #[error("{device} ran out of device memory allocating {what}")]
    OutOfDeviceMemory { device: String, what: String },
    /// VK_ERROR_OUT_OF_HOST_MEMORY: the driver could not allocate host
    /// memory.
    #[error("the Vulkan driver of {device} ran out of host memory in {call}")]
    OutOfHostMemory { device: String, call: &'static str },
    /// A submission's fence did not signal within the fence timeout. The
    /// device is not used again.
    #[error(
        "{device} did not finish {what} within the fence timeout of {} (the device is \
         treated as hung; a smaller --tile shortens each submission)",
        seconds(*timeout)
    )]
    Timeout {
        device: String,
        what: String,
        timeout: Duration,
    },
    /// vkCreateComputePipelines failed: the driver cannot build the kernel.
    #[error("the driver of {device} refused to build the {kernel} kernel (vkCreateComputePipelines: {result:?})")]
    PipelineRefused {
        device: String,
        kernel: String,
        result: vk::Result,
    },
    /// The driver stopped shader loops early (llvmpipe's per-shader loop
    /// budget, `loops::LLVMPIPE_LOOP_BUDGET`): the image would be silently
    /// wrong. `cause` names what drives the loops (`loops::LoopLoad`).
    #[error(
        "{device} cut {} short (llvmpipe stops every loop after {} iterations per group of \
         invocations), so this image would be wrong; the likely cause is {cause}; {remedy}, \
         or use --backend cpu",
        plural(*loops as u64, "shader loop", "shader loops"),
        loops::BUDGET_TEXT
    )]
    LoopsCut {
        device: String,
        loops: u32,
        cause: String,
        remedy: String,
    },
    /// Refused before dispatching: the host traced an eye ray whose loops
    /// alone exceed llvmpipe's budget (`loops::certain_cut`).
    #[error(
        "{device} would cut this render's shader loops short: llvmpipe allows {} loop \
         iterations per group of invocations, and the eye ray of {at} alone needs at least {}, \
         most of them for {cause}; {remedy}, or use --backend cpu",
        loops::BUDGET_TEXT,
        loops::thousands(*iterations)
    )]
    LoopsWouldBeCut {
        device: String,
        at: String,
        iterations: u64,
        cause: String,
        remedy: String,
    },
}

/// "there is only 1 Vulkan device (0)", "there are only 3 Vulkan devices
/// (0 to 2)".
fn bad_index(count: usize) -> String {
    match count {
        0 => "there is no Vulkan device (see `whitted devices`)".into(),
        1 => "there is only 1 Vulkan device (index 0; see `whitted devices`)".into(),
        n => format!(
            "there are only {n} Vulkan devices (indices 0 to {}; see `whitted devices`)",
            n - 1
        ),
    }
}

/// "1 shader loop", "3 shader loops".
pub(crate) fn plural(n: u64, one: &str, many: &str) -> String {
    format!(
        "{} {}",
        loops::thousands(n),
        if n == 1 { one } else { many }
    )
}

fn seconds(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s == s.trunc() {
        plural(s as u64, "second", "seconds")
    } else {
        format!("{s} seconds")
    }
}

impl GpuError {
    /// The user can fix it (another device, a smaller scene or image, other
    /// options): the CLI exits with 2.
    pub fn is_user_error(&self) -> bool {
        matches!(
            self,
            GpuError::NoDevice(_)
                | GpuError::BadIndex { .. }
                | GpuError::Unusable(_)
                | GpuError::Limits(_)
                | GpuError::Setting(_)
                | GpuError::Memory { .. }
                | GpuError::LoopsCut { .. }
                | GpuError::LoopsWouldBeCut { .. }
        )
    }

    /// The device failed while rendering: lost, out of device or host
    /// memory, timed out, or its driver refused the kernel. `--backend
    /// auto` finishes such a render on the CPU mirror (`Gpu::render_or`);
    /// `--backend gpu` exits with 4.
    pub fn is_device_fault(&self) -> bool {
        matches!(
            self,
            GpuError::DeviceLost { .. }
                | GpuError::OutOfDeviceMemory { .. }
                | GpuError::OutOfHostMemory { .. }
                | GpuError::Timeout { .. }
                | GpuError::PipelineRefused { .. }
        )
    }

    /// The device must not be used again after this error.
    fn ends_the_device(&self) -> bool {
        matches!(self, GpuError::DeviceLost { .. } | GpuError::Timeout { .. })
    }

    /// A failed Vulkan call as the device fault it is, if it is one.
    fn classify(self, device: &str) -> GpuError {
        let device = device.to_string();
        match self {
            GpuError::Vulkan { call, result } => match result {
                vk::Result::ERROR_DEVICE_LOST => GpuError::DeviceLost { device, call },
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => GpuError::OutOfDeviceMemory {
                    device,
                    what: format!("memory for {call}"),
                },
                vk::Result::ERROR_OUT_OF_HOST_MEMORY => GpuError::OutOfHostMemory { device, call },
                _ => GpuError::Vulkan { call, result },
            },
            e => e,
        }
    }
}

pub(crate) fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

/// Default edge of a dispatch tile on a CPU Vulkan device, in lattice
/// samples (`tile_for`).
pub const DEFAULT_TILE: u32 = 256;
/// Default edge of a dispatch tile on a GPU: one tile of 2^20 lattice
/// samples, the most `MAX_TILE_SAMPLES` lets one submission hold.
pub const DEFAULT_GPU_TILE: u32 = 1024;

/// The tile edge for `asked`, or for 0 by the device's class: 256 on a CPU
/// device (lavapipe: the shape changes nothing there, and small tiles keep
/// each submission short and the progress bar moving), 1024 on a GPU
/// (on an NVIDIA H200, 20 000 spheres at 1024x768: 2.9x less device time
/// than 256, which leaves most of the chip idle between submissions;
/// docs/profiling.md, "A real GPU: NVIDIA H200").
pub fn tile_for(asked: u32, kind: DeviceKind) -> u32 {
    match (asked, kind) {
        (0, DeviceKind::Cpu) => DEFAULT_TILE,
        (0, _) => DEFAULT_GPU_TILE,
        (t, _) => t,
    }
}

/// The most lattice points `--lane-pixels` gives one invocation.
pub const MAX_LANE_PIXELS: u32 = 64;

/// The lattice points one invocation renders: `asked`, or for 0 by the
/// device's class: 2 on a CPU device (lavapipe: 2-22 % less device time
/// on 7 of 9 scenes and 0.6 s less pipeline creation a process,
/// docs/profiling.md, "Persistent lanes"), 1 elsewhere until measured on
/// a GPU.
pub fn lane_pixels_for(asked: u32, kind: DeviceKind) -> u32 {
    match (asked, kind) {
        (0, DeviceKind::Cpu) => 2,
        (0, _) => 1,
        (k, _) => k.min(MAX_LANE_PIXELS),
    }
}
/// Default workgroup shape (specialization constants 0 and 1).
pub const DEFAULT_WORKGROUP: [u32; 2] = [8, 8];
/// Most eye rays one tile traces: keeps every submission short. Deep
/// trees and many lights lower it further (`dispatch::max_tile_samples`)
/// so the shader's 32-bit ray counters cannot wrap within a tile.
pub const MAX_TILE_SAMPLES: u64 = 1 << 20;
/// Longest wait for one submission (one tile) when neither
/// `GpuOptions::fence_timeout` nor `WHITTED_FENCE_TIMEOUT` says otherwise.
/// Tiles keep each submission to at most `MAX_TILE_SAMPLES` eye rays, and
/// a real GPU's driver reports a hung shader as a lost device within
/// seconds (its watchdog); the timeout catches what neither does, and is
/// long so that a slow CPU device finishing a heavy tile is never cut off
/// (docs/gpu.md, "Device faults").
pub const DEFAULT_FENCE_TIMEOUT: Duration = Duration::from_secs(600);

/// Environment variable naming a device fault to inject (test only).
pub const FAULT_ENV: &str = "WHITTED_GPU_FAULT";
/// Environment variable: the fence timeout in seconds.
pub const FENCE_TIMEOUT_ENV: &str = "WHITTED_FENCE_TIMEOUT";
/// Environment variable: `off`, or the folder of the pipeline cache.
pub const PIPELINE_CACHE_ENV: &str = "WHITTED_PIPELINE_CACHE";

/// A device fault to inject, for tests (`GpuOptions::fault`, or the
/// environment variable `WHITTED_GPU_FAULT=device-lost` and so on). Each
/// makes the real call site fail as a driver would, so the real error
/// path and its cleanup run (docs/gpu.md, "Device faults").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// The first submission's vkWaitForFences returns
    /// VK_ERROR_DEVICE_LOST (after the real wait).
    DeviceLost,
    /// The allocation of the first readback buffer (the render's output)
    /// fails as gpu-allocator's does when the device memory is full.
    OutOfDeviceMemory,
    /// vkCreateBuffer of the first readback buffer returns
    /// VK_ERROR_OUT_OF_HOST_MEMORY.
    OutOfHostMemory,
    /// The first submission waits on an event the host sets only after
    /// its fence wait has timed out (so the device really is busy, and
    /// then recovers).
    FenceNeverSignals,
    /// vkCreateComputePipelines returns VK_ERROR_UNKNOWN.
    PipelineRefused,
}

impl Fault {
    pub const ALL: [Fault; 5] = [
        Fault::DeviceLost,
        Fault::OutOfDeviceMemory,
        Fault::OutOfHostMemory,
        Fault::FenceNeverSignals,
        Fault::PipelineRefused,
    ];

    /// The name `WHITTED_GPU_FAULT` takes.
    pub fn name(self) -> &'static str {
        match self {
            Fault::DeviceLost => "device-lost",
            Fault::OutOfDeviceMemory => "out-of-device-memory",
            Fault::OutOfHostMemory => "out-of-host-memory",
            Fault::FenceNeverSignals => "fence-never-signals",
            Fault::PipelineRefused => "pipeline-refused",
        }
    }
}

impl std::str::FromStr for Fault {
    type Err = GpuError;
    fn from_str(s: &str) -> Result<Self, GpuError> {
        Fault::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                GpuError::Setting(format!(
                    "{FAULT_ENV}={s}: not a fault; one of {}",
                    Fault::ALL.map(Fault::name).join(", ")
                ))
            })
    }
}

/// Where compiled pipelines are cached between runs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum PipelineCache {
    /// `WHITTED_PIPELINE_CACHE` (`off` or a folder) when set, otherwise
    /// `$XDG_CACHE_HOME/whitted` or `~/.cache/whitted`.
    #[default]
    Default,
    /// No cache: every run compiles its pipelines.
    Off,
    /// This folder (made when missing).
    Dir(PathBuf),
}

/// How the primitives lie in the GPU's buffer (`--prim-layout`;
/// docs/profiling.md, "Memory layout of the primitives"). The CPU mirror
/// reads its own array of structures either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PrimLayout {
    /// Array of structures: primitive i's 64 bytes together (its header,
    /// then a, b, c), as `pack::layout::Prim`.
    #[default]
    Aos,
    /// Structure of arrays: every header, then every a, every b, every c
    /// (16 bytes each), so that lanes reading one field of neighbouring
    /// primitives read neighbouring words.
    Soa,
}

impl PrimLayout {
    /// The name `--prim-layout` takes.
    pub fn name(self) -> &'static str {
        match self {
            PrimLayout::Aos => "aos",
            PrimLayout::Soa => "soa",
        }
    }

    /// The primitives' bytes as the shader reads them in this layout
    /// (`load_prim`, shaders/layout.glsl).
    pub fn bytes(self, prims: &[crate::pack::layout::Prim]) -> std::borrow::Cow<'_, [u8]> {
        match self {
            PrimLayout::Aos => std::borrow::Cow::Borrowed(bytemuck::cast_slice(prims)),
            PrimLayout::Soa => {
                let mut out = Vec::with_capacity(std::mem::size_of_val(prims));
                for field in 0..4 {
                    for p in prims {
                        let words: &[u8; 64] = bytemuck::cast_ref(p);
                        out.extend_from_slice(&words[field * 16..field * 16 + 16]);
                    }
                }
                std::borrow::Cow::Owned(out)
            }
        }
    }
}

/// How the grid's cells lie in the GPU's `cell_start` buffer
/// (`--cell-layout`; docs/profiling.md, "The grid's cell lists"). The
/// CPU mirror reads the packed offsets either way; structures other than
/// the grid and the hybrid ignore it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CellLayout {
    /// As packed: ncells + 1 offsets into refs, then a skip byte per cell.
    Offsets,
    /// Two words per cell: (start, count), the one reference inline when
    /// count is 1, (skip, 0) for an empty cell: one load per cell visit.
    /// The default: 2-6 % less device time on lavapipe under the grid
    /// (docs/profiling.md). Offsets where pairs would not fit the
    /// device's buffer range.
    #[default]
    Pairs,
}

impl CellLayout {
    /// Whether `p`'s structure reads cells in this layout (the grid and
    /// the hybrid's top grid under `Pairs`).
    pub fn applies(self, p: &crate::pack::Packed) -> bool {
        let accel = p.globals.flags[1] & 15;
        self == CellLayout::Pairs
            && (accel == crate::constants::ACCEL_GRID || accel == crate::constants::ACCEL_HYBRID)
    }

    /// `cell_start` as the shader reads it (`grid_traverse`,
    /// shaders/grid.glsl).
    pub fn words(self, p: &crate::pack::Packed) -> std::borrow::Cow<'_, [u32]> {
        if !self.applies(p) {
            return std::borrow::Cow::Borrowed(&p.cell_start);
        }
        let n = p.globals.grid_dims[3] as usize;
        let skip = |ci: usize| (p.cell_start[n + 1 + ci / 4] >> (8 * (ci % 4))) & 255;
        let mut out = Vec::with_capacity(2 * n);
        for ci in 0..n {
            let (start, end) = (p.cell_start[ci], p.cell_start[ci + 1]);
            out.extend_from_slice(&match end - start {
                0 => [skip(ci), 0],
                1 => [p.refs[start as usize], 1],
                count => [start, count],
            });
        }
        std::borrow::Cow::Owned(out)
    }

    /// The layout to use on a device whose buffers hold at most `range`
    /// bytes: pairs take 8 bytes a cell against the offsets' 5, so where
    /// only the offsets fit, the offsets (the same image).
    pub fn fitting(self, p: &crate::pack::Packed, range: u64) -> CellLayout {
        if self == CellLayout::Pairs && self.bytes(p) > range {
            CellLayout::Offsets
        } else {
            self
        }
    }

    /// Bytes of `cell_start` on the device.
    pub fn bytes(self, p: &crate::pack::Packed) -> u64 {
        if self.applies(p) {
            8 * p.globals.grid_dims[3] as u64
        } else {
            4 * p.cell_start.len() as u64
        }
    }
}

/// How the kernels read the scene's arrays (`--reads`; docs/profiling.md,
/// "Texel reads"): the same buffers, the same values bit for bit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GpuReads {
    /// Every array but the globals (the primitives, `extra`, the
    /// materials, the lights, the cell and reference lists, the BVH, the
    /// light buffers' lists) through uniform texel buffer views (bindings
    /// 20 to 28): on lavapipe 15-30 % less device time for the first
    /// four arrays read so, then 6-25 % less again for the others
    /// (docs/profiling.md, "Every array as texels"). The default;
    /// storage buffers where one of them has more texels than the
    /// device's maxTexelBufferElements.
    #[default]
    Texel,
    /// Every array as a storage buffer (bindings 1 to 6, 11 to 13).
    Storage,
}

impl GpuReads {
    /// The reads to use on a device whose texel views hold at most
    /// `max_texels` texels: storage buffers when one of `p`'s arrays
    /// read as texels (`texel_binding`) has more, with the cells in
    /// layout `cells`.
    pub fn fitting(self, p: &crate::pack::Packed, cells: CellLayout, max_texels: u64) -> GpuReads {
        let texels = [
            std::mem::size_of_val(p.prims.as_slice()) as u64 / 16,
            cells.bytes(p) / 4,
            p.refs.len() as u64,
            std::mem::size_of_val(p.bvh.as_slice()) as u64 / 16,
            std::mem::size_of_val(p.extra.as_slice()) as u64 / 16,
            std::mem::size_of_val(p.materials.as_slice()) as u64 / 16,
            std::mem::size_of_val(p.lights.as_slice()) as u64 / 16,
            p.lb_start.len() as u64,
            p.lb_refs.len() as u64,
        ];
        if self == GpuReads::Texel && texels.iter().any(|&t| t > max_texels) {
            GpuReads::Storage
        } else {
            self
        }
    }
}

/// Whether the kernels keep the shadow cache (`--shadow-cache`;
/// docs/profiling.md, "The shadow cache on lavapipe"): the opaque
/// primitive that last blocked a feeler to each light, tested before the
/// feeler's walk. It never changes a pixel, only the work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GpuShadowCache {
    /// Off on a CPU Vulkan device (lavapipe: its 8 lanes run the cached
    /// primitive's test, masked, before every feeler's walk, and walk on
    /// unless all 8 were answered: 2-7 % more device time with it), on
    /// elsewhere.
    #[default]
    Auto,
    /// Test the cached blocker first (as the CPU mirror always does).
    On,
    /// No cache: every feeler walks the structure.
    Off,
}

impl GpuShadowCache {
    /// Auto settled for a device of `kind`: On or Off.
    pub fn for_device(self, kind: DeviceKind) -> GpuShadowCache {
        match (self, kind) {
            (GpuShadowCache::Auto, DeviceKind::Cpu) => GpuShadowCache::Off,
            (GpuShadowCache::Auto, _) => GpuShadowCache::On,
            (c, _) => c,
        }
    }
}

/// The render kernel's float arithmetic (`--gpu-math`; docs/gpu.md,
/// "Exact and fast shader arithmetic").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GpuMath {
    /// Every operation whose order matters is `precise`, in the CPU
    /// mirror's order: a CPU Vulkan device (lavapipe) matches the mirror
    /// bit for bit.
    #[default]
    Exact,
    /// The same shader without `precise`: the driver may reorder and fuse
    /// float arithmetic; the image differs from the mirror's in the last
    /// bits.
    Fast,
}

impl GpuMath {
    /// The name `--gpu-math` takes.
    pub fn name(self) -> &'static str {
        match self {
            GpuMath::Exact => "exact",
            GpuMath::Fast => "fast",
        }
    }

    /// The render kernel's name (the SPIR-V file build.rs wrote, the key
    /// of `Gpu`'s kernels) and module.
    /// `lanes`: the module that renders several lattice points an
    /// invocation (`--lane-pixels` above 1).
    fn render_kernel(self, lanes: bool) -> (&'static str, &'static [u8]) {
        match (self, lanes) {
            (GpuMath::Exact, false) => ("render", shaders::RENDER),
            (GpuMath::Fast, false) => ("render_fast", shaders::RENDER_FAST),
            (GpuMath::Exact, true) => ("render_lanes", shaders::RENDER_LANES),
            (GpuMath::Fast, true) => ("render_lanes_fast", shaders::RENDER_LANES_FAST),
        }
    }
}

/// How the render kernel walks the ray tree (`--kernel`; docs/gpu.md,
/// "Megakernel and wavefront"). The same image either way.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum GpuKernel {
    /// One invocation per lattice point walks its whole ray tree
    /// (`shaders/render.comp`).
    #[default]
    Mega,
    /// Queues of rays processed stage by stage, one dispatch per stage
    /// and depth (`shaders/wavefront.comp`; exact arithmetic only).
    Wavefront,
    /// Not the scene's image: the plain grid tracer
    /// (`shaders/calibration.comp`) the megakernel is measured against
    /// (docs/profiling.md, "A plain grid tracer as the yardstick"). The
    /// same rays on fields of opaque spheres under the grid, other
    /// pixels; other scenes are refused (`calibration_refusal`).
    Calibration,
}

impl GpuKernel {
    /// The name `--kernel` takes.
    pub fn name(self) -> &'static str {
        match self {
            GpuKernel::Mega => "mega",
            GpuKernel::Wavefront => "wavefront",
            GpuKernel::Calibration => "calibration",
        }
    }
}

/// Why the calibration kernel cannot render `packed`, or `None` when it
/// can: it models the grid, bounded spheres, reflection and light falloff
/// only (`supported` in shaders/calibration.comp, which paints any other
/// scene magenta).
pub fn calibration_refusal(packed: &Packed) -> Option<String> {
    use crate::constants::{
        ACCEL_GRID, FEAT_FALLOFF, FEAT_REFLECT, FEAT_SPHERE, FLAG_SPD_COUNTING,
    };
    let g = &packed.globals;
    let extra = g.trace[1] & !(FEAT_SPHERE | FEAT_REFLECT | FEAT_FALLOFF);
    if g.flags[1] != ACCEL_GRID {
        Some("it walks the grid only: add --accel grid".into())
    } else if g.counts[0] != g.counts[1] {
        Some("the scene has unbounded primitives (planes, unclipped quadrics or giants such as a floor)".into())
    } else if extra != 0 {
        // FEAT_* bit k, by name.
        const NAMES: [&str; 13] = [
            "spheres",
            "planes",
            "triangles",
            "polygons",
            "boxes",
            "quadrics",
            "cones",
            "reflection",
            "refraction",
            "absorption",
            "transmission highlights",
            "light falloff",
            "smooth normals",
        ];
        let other: Vec<&str> = (0..NAMES.len())
            .filter(|&k| extra & (1 << k) != 0)
            .map(|k| NAMES[k])
            .collect();
        Some(format!(
            "it models spheres, reflection and light falloff only, and the scene has {}",
            if other.is_empty() {
                format!("features {extra:#x}")
            } else {
                other.join(", ")
            }
        ))
    } else if g.flags[0] & FLAG_SPD_COUNTING != 0 {
        Some("it does not count rays the SPD's way: drop --preset spd".into())
    } else {
        None
    }
}

/// Bytes of a kernel's counters buffer (`shaders/counts.glsl`: 25 words).
pub(crate) const COUNTERS_BYTES: u64 = 25 * 4;

/// Ray counts, work counters and cut loops from a kernel's counters
/// buffer (`shaders/counts.glsl`).
fn read_counts(counters: &Buffer) -> Result<(RayStats, crate::trace::query::Work, u32), GpuError> {
    let c: [u32; 25] = bytemuck::pod_read_unaligned(counters.read(COUNTERS_BYTES as usize)?);
    let wide = |at: usize| c[at] as u64 | (c[at + 1] as u64) << 32;
    let work = crate::trace::query::Work {
        tests: wide(6),
        cells: wide(8),
        nodes: wide(10),
        eye: [wide(12), wide(14), wide(16)],
        shadow: [wide(18), wide(20), wide(22)],
        stack: c[24],
        ..Default::default()
    };
    let stats = RayStats {
        eye: c[0] as u64,
        eye_hit: c[1] as u64,
        reflect: c[2] as u64,
        refract: c[3] as u64,
        shadow: c[4] as u64,
    };
    Ok((stats, work, c[5]))
}

/// The variable naming a megakernel variant (`render_variant`).
const RENDER_SPV: &str = "WHITTED_RENDER_SPV";

/// `WHITTED_RENDER_SPV=FILE`: a SPIR-V module to render with instead of
/// the built-in kernel (either `--gpu-math`), for trying a variant of
/// the shader without rebuilding (docs/profiling.md, "Trying a kernel
/// variant"): a copy of `shaders/` edited and compiled with
/// glslangValidator, with the same bindings, push and specialization
/// constants. Unset or empty: None; otherwise the file as it is shown,
/// and its bytes. An unreadable file or one that is not SPIR-V is a
/// setting error (exit 2).
pub fn render_variant() -> Result<Option<(String, Vec<u8>)>, GpuError> {
    let Some(path) = std::env::var_os(RENDER_SPV).filter(|v| !v.is_empty()) else {
        return Ok(None);
    };
    let shown = std::path::Path::new(&path).display().to_string();
    let bytes = std::fs::read(&path)
        .map_err(|e| GpuError::Setting(format!("{RENDER_SPV}={shown}: cannot read it: {e}")))?;
    if bytes.len() < 20 || bytes.len() % 4 != 0 || bytes[..4] != 0x0723_0203u32.to_le_bytes() {
        return Err(GpuError::Setting(format!(
            "{RENDER_SPV}={shown}: not a SPIR-V module (little-endian, starting with 0x07230203)"
        )));
    }
    Ok(Some((shown, bytes)))
}

/// How to run on the GPU. `device`, `real_gpu_only`, `sync_validation`,
/// `fault`, `fence_timeout` and `pipeline_cache` are read when the device
/// is opened (`Gpu::new`); `tile`, `workgroup`, `staging` and `math` by
/// each render.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GpuOptions {
    /// `--device N`: index in `devices()`; None: the best usable device.
    pub device: Option<usize>,
    /// Refuse CPU (software) Vulkan devices unless `device` names one.
    pub real_gpu_only: bool,
    /// Edge of a tile in lattice samples; 0: by the device's class
    /// (`tile_for`).
    pub tile: u32,
    /// Workgroup width and height.
    pub workgroup: [u32; 2],
    /// Upload the scene through a staging buffer even where device-local
    /// memory is host-visible: the path a discrete GPU takes, tested on
    /// lavapipe (whose memory is all host-visible).
    pub staging: bool,
    /// Turn on the validation layer (when installed) with synchronization
    /// validation.
    pub sync_validation: bool,
    /// A device fault to inject (tests). None: `WHITTED_GPU_FAULT` when set.
    pub fault: Option<Fault>,
    /// Longest wait for one submission. None: `WHITTED_FENCE_TIMEOUT`
    /// seconds when set, otherwise `DEFAULT_FENCE_TIMEOUT`.
    pub fence_timeout: Option<Duration>,
    /// Where compiled pipelines are cached.
    pub pipeline_cache: PipelineCache,
    /// Which render kernel: exact (`precise`, the default) or fast.
    pub math: GpuMath,
    /// How the primitives lie in the device's buffer.
    pub prim_layout: PrimLayout,
    /// How the grid's cells lie in the device's buffer.
    pub cell_layout: CellLayout,
    /// The megakernel or the wavefront kernel.
    pub kernel: GpuKernel,
    /// How the kernels read the scene's arrays.
    pub reads: GpuReads,
    /// Whether the kernels keep the shadow cache (Auto: by the device's
    /// class, settled by `Gpu::resolved`).
    pub shadow_cache: GpuShadowCache,
    /// Lattice points one invocation of the megakernel renders, each
    /// sample started inside one ray loop (`LANE_PIXELS`, render.comp;
    /// 1..=`MAX_LANE_PIXELS`; the wavefront ignores it). 0: by the
    /// device's class (`lane_pixels_for`).
    pub lane_pixels: u32,
    /// Neither `--workgroup` nor `--tile` was given: `render` may use the
    /// shape `whitted profile --save` stored for the device
    /// (`profile::apply_saved`).
    pub saved_shape: bool,
    /// No `--kernel` was given: `render` may use the kernel `whitted
    /// profile --save` stored for the device.
    pub saved_kernel: bool,
}

impl Default for GpuOptions {
    fn default() -> Self {
        GpuOptions {
            device: None,
            real_gpu_only: false,
            tile: 0,
            workgroup: DEFAULT_WORKGROUP,
            staging: false,
            sync_validation: false,
            fault: None,
            fence_timeout: None,
            pipeline_cache: PipelineCache::Default,
            saved_shape: false,
            saved_kernel: false,
            math: GpuMath::Exact,
            prim_layout: PrimLayout::Aos,
            cell_layout: CellLayout::Pairs,
            lane_pixels: 0,
            kernel: GpuKernel::Mega,
            reads: GpuReads::Texel,
            shadow_cache: GpuShadowCache::Auto,
        }
    }
}

/// `opts`' device-level settings with the environment applied.
fn resolve(opts: &GpuOptions) -> Result<context::Settings, GpuError> {
    let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
    let fault = match (opts.fault, env(FAULT_ENV)) {
        (Some(f), _) => Some(f),
        (None, Some(v)) => Some(v.parse()?),
        (None, None) => None,
    };
    let fence_timeout = match (opts.fence_timeout, env(FENCE_TIMEOUT_ENV)) {
        (Some(t), _) => t,
        (None, Some(v)) => v
            .parse::<f64>()
            .ok()
            .filter(|s| s.is_finite() && *s > 0.0 && *s < 1e9)
            .map(Duration::from_secs_f64)
            .ok_or_else(|| {
                GpuError::Setting(format!(
                    "{FENCE_TIMEOUT_ENV}={v}: expected a positive number of seconds"
                ))
            })?,
        (None, None) => DEFAULT_FENCE_TIMEOUT,
    };
    if fence_timeout.is_zero() {
        return Err(GpuError::Setting(
            "the fence timeout must be positive".into(),
        ));
    }
    let cache_dir = match &opts.pipeline_cache {
        PipelineCache::Off => None,
        PipelineCache::Dir(d) => Some(d.clone()),
        PipelineCache::Default => match env(PIPELINE_CACHE_ENV) {
            Some(v) if v == "off" => None,
            Some(v) => Some(PathBuf::from(v)),
            None => pipeline::cache_dir(),
        },
    };
    Ok(context::Settings {
        device: opts.device,
        real_gpu_only: opts.real_gpu_only,
        sync_validation: opts.sync_validation,
        fault,
        fence_timeout,
        cache_dir,
    })
}

/// Every Vulkan device; `Err(NoDevice)` when there is no loader or driver.
pub fn devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let inst = context::Instance::new(false)?;
    Ok(inst.devices()?.into_iter().map(|(_, d)| d).collect())
}

/// The device `render` would open for these options.
pub fn choose(
    devices: &[DeviceInfo],
    index: Option<usize>,
    real_gpu_only: bool,
) -> Result<usize, GpuError> {
    context::choose(devices, index, real_gpu_only)
}

/// Renders `packed` on the GPU (a fresh device; see `Gpu` to reuse one).
pub fn render(packed: &Packed, opts: &GpuOptions) -> Result<Frame, GpuError> {
    Gpu::new(opts)?.render(packed, opts, &|_, _| {})
}

/// Runs probe kernel `mode` on `items` (a fresh device).
pub fn probe(
    packed: &Packed,
    mode: ProbeMode,
    items: &[ProbeItem],
) -> Result<Vec<ProbeResult>, GpuError> {
    Gpu::new(&GpuOptions::default())?.probe(packed, mode, items)
}

/// The BVH as the kernels read it (binding 11): each node's `link[k]`
/// holds child k's link in its low `BVH_COUNT_SHIFT` bits and its count
/// above them, and `count` is zero, so that a node visit reads 7 of the
/// node's 8 texels and a pop 1 instead of 2 (lavapipe: 2-7 % less device
/// time on the SPD scenes; docs/profiling.md, "One word per child"). The
/// CPU mirror walks the packed nodes as they are. A link that does not
/// fit (over 2^28 nodes or primitives, far past any memory budget) is
/// refused.
pub fn bvh_for_gpu(
    nodes: &[crate::pack::layout::BvhNode],
) -> Result<Vec<crate::pack::layout::BvhNode>, GpuError> {
    use crate::constants::{BVH_COUNT_SHIFT, BVH_WIDTH};
    const MAX_COUNT: u32 = 1 << (32 - BVH_COUNT_SHIFT);
    // Every leaf's count fits above the link.
    const _: () = assert!((crate::pack::bvh::MAX_LEAF as u32) < MAX_COUNT);
    let limit = 1u32 << BVH_COUNT_SHIFT;
    nodes
        .iter()
        .map(|n| {
            let mut g = *n;
            for k in 0..BVH_WIDTH as usize {
                if n.link[k] >= limit || n.count[k] >= MAX_COUNT {
                    return Err(GpuError::Limits(format!(
                        "a BVH child links to {} with {} primitives: the GPU's nodes hold links \
                         below {limit} and counts below {MAX_COUNT}",
                        n.link[k], n.count[k]
                    )));
                }
                g.link[k] = n.link[k] | n.count[k] << BVH_COUNT_SHIFT;
                g.count[k] = 0;
            }
            Ok(g)
        })
        .collect()
}

/// The packed arrays on the device: bindings 0–6, 11 (the BVH), 12 and 13
/// (the light buffers).
struct SceneBuffers {
    bufs: Vec<(u32, Buffer)>,
}

/// The texel-buffer binding (`layout.glsl`, `TEXELS`) that reads scene
/// binding `b` again, and its texel format: the primitives (1) and the
/// BVH (11) in 16-byte texels, the cell and reference lists (5, 6) in
/// 4-byte ones. The other arrays were slower on lavapipe read as texels
/// (docs/profiling.md, "Texel reads") and are only storage buffers.
fn texel_binding(b: u32) -> Option<(u32, vk::Format)> {
    Some(match b {
        1 => (20, vk::Format::R32G32B32A32_UINT),
        2 => (26, vk::Format::R32G32B32A32_UINT),
        3 => (24, vk::Format::R32G32B32A32_UINT),
        4 => (25, vk::Format::R32G32B32A32_UINT),
        5 => (21, vk::Format::R32_UINT),
        6 => (22, vk::Format::R32_UINT),
        11 => (23, vk::Format::R32G32B32A32_UINT),
        12 => (27, vk::Format::R32_UINT),
        13 => (28, vk::Format::R32_UINT),
        _ => return None,
    })
}

/// A kernel's bindings: the scene's, their texel views
/// (`texel_binding`), then the kernel's own `own`.
fn kernel_bindings(own: &[u32]) -> Vec<u32> {
    let texels = SCENE_BINDINGS
        .into_iter()
        .filter_map(|b| texel_binding(b).map(|(t, _)| t));
    SCENE_BINDINGS
        .into_iter()
        .chain(texels)
        .chain(own.iter().copied())
        .collect()
}

/// The scene's bindings (`layout.glsl`); 7 to 10 are the kernels' own.
const SCENE_BINDINGS: [u32; 10] = [0, 1, 2, 3, 4, 5, 6, 11, 12, 13];

impl SceneBuffers {
    fn bindings(&self) -> Vec<(u32, &Buffer)> {
        let mut v: Vec<(u32, &Buffer)> = self.bufs.iter().map(|(i, b)| (*i, b)).collect();
        for (i, b) in &self.bufs {
            if let Some((t, _)) = texel_binding(*i) {
                v.push((t, b));
            }
        }
        v
    }
}

/// render.comp's push constants: the tile (x0, y0, w, h), then the
/// workgroup order's stride and three unused words.
type RenderPush = [u32; 8];
/// probe.comp's push constants: mode, item count, two unused words.
type ProbePush = [u32; 4];

/// Kernels by (name: `render`, `render_fast`, `render_variant` or `probe`, specialization
/// constants 0..=4): the exact and the fast render kernels never share one.
type KernelCache = Mutex<HashMap<(&'static str, [u32; 5]), Arc<Kernel>>>;

/// Specialization constant 3 of `render.comp` (`STRUCTURE`,
/// shaders/layout.glsl) for a scene packed with `flags`
/// (`Globals::flags`): bits 0-3 the structure (`ACCEL_*`), bits 4-7 the
/// octree's walk, bit 8 light buffers; bit 9 the primitives' layout
/// (`PRIMS_SOA`: set by `render_with` for `PrimLayout::Soa`). The walks
/// the scene does not use then compile out, which llvmpipe would
/// otherwise run, masked, on every query (docs/profiling.md).
pub fn structure_key(flags: [u32; 4]) -> u32 {
    let accel = flags[1] & 15;
    let walk = if accel == crate::constants::ACCEL_OCTREE {
        flags[2] & 15
    } else {
        0
    };
    let light_buffers = u32::from(flags[3] > 0);
    accel | walk << 4 | light_buffers << 8
}

/// Bits 9 to 29 of specialization constant 3 (shaders/layout.glsl):
/// `PRIMS_SOA` and `CELLS_PAIRS` (the primitives' layout and the grid
/// cells' for `p`), `TEXELS` (the reads), `BOUNDED_KINDS`, bit 19 no
/// shadow cache (`opts.shadow_cache` Off; Auto counts as On here:
/// `Gpu::resolved` settles it first) and bit 20 no unbounded primitives
/// (`NO_UNBOUNDED`: `query_unbounded` compiles out), bit 21 every polygon
/// convex (`CONVEX_POLYGONS`: `convex_polygons`), bits 22-28 the unbounded
/// primitives' kinds (`UNBOUNDED_KINDS`: `unbounded_kinds`), bit 29 no
/// cell of the grid to jump from (`NO_JUMPS`: `grid_jumps`).
pub fn layout_key(opts: &GpuOptions, p: &crate::pack::Packed) -> u32 {
    let prims = match opts.prim_layout {
        PrimLayout::Aos => 0,
        PrimLayout::Soa => 1 << 9,
    };
    prims
        | u32::from(opts.cell_layout.applies(p)) << 10
        | u32::from(opts.reads == GpuReads::Texel) << 11
        | bounded_kinds(p) << 12
        | u32::from(opts.shadow_cache == GpuShadowCache::Off) << 19
        | u32::from(p.globals.counts[0] >= p.globals.counts[1]) << 20
        | u32::from(convex_polygons(p)) << 21
        | unbounded_kinds(p) << 22
        | u32::from(!grid_jumps(p)) << 29
}

/// Whether the scene's grid (under the grid or the hybrid) has a cell a
/// walk may jump from (skip distance 2 or more; `pack::grid::jumps_pay`
/// caps a dense grid's at 1). Without one, bit 29 of specialization
/// constant 3 (`NO_JUMPS` in shaders/layout.glsl) compiles the jump out.
pub fn grid_jumps(p: &crate::pack::Packed) -> bool {
    let accel = p.globals.flags[1] & 15;
    if accel != crate::constants::ACCEL_GRID && accel != crate::constants::ACCEL_HYBRID {
        return false;
    }
    // The skip bytes, four to a word after the ncells + 1 offsets (the
    // last word's unused bytes are 0): a byte of 2 or more has a bit
    // above its lowest.
    let n = p.globals.grid_dims[3] as usize;
    let skips = p.cell_start.get(n + 1..).unwrap_or(&[]);
    skips.iter().any(|w| w & 0xFEFE_FEFE != 0)
}

/// Bit 21 of specialization constant 3 (`CONVEX_POLYGONS` in
/// shaders/layout.glsl): every polygon of the scene is convex, so none
/// has edge bands or cells (`pack::polygon`) and the shader's polygon
/// test compiles to its convex loop alone. True for a scene without
/// polygons too.
pub fn convex_polygons(p: &crate::pack::Packed) -> bool {
    p.prims
        .iter()
        .filter(|q| q.kind() == crate::constants::KIND_POLYGON)
        .all(|q| q.b[2] != 0.0 && q.c[3] == 0.0)
}

/// Specialization constants 2 and 3 of every kernel that walks a scene
/// (render, wavefront stages, probe): the scene's kinds and features
/// (`FEATURES`) and its structure with `opts`' layouts (`STRUCTURE`), so
/// that a driver compiles only the code `packed` runs.
pub fn scene_spec(packed: &crate::pack::Packed, opts: &GpuOptions) -> [(u32, u32); 2] {
    let g = &packed.globals;
    [
        (2, g.trace[1]),
        (3, structure_key(g.flags) | layout_key(opts, packed)),
    ]
}

/// Bits 12-18 of specialization constant 3 (`BOUNDED_KINDS` in
/// shaders/layout.glsl): the kinds of the primitives the structure holds
/// (the first `counts[0]`), bit k for `KIND` k, so that the walks compile
/// only those kinds' intersection tests.
pub fn bounded_kinds(p: &crate::pack::Packed) -> u32 {
    let n = (p.globals.counts[0] as usize).min(p.prims.len());
    crate::pack::layout::Prim::kind_bits(&p.prims[..n]) & 127
}

/// Bits 22-28 of specialization constant 3 (`UNBOUNDED_KINDS` in
/// shaders/layout.glsl): the kinds of the unbounded primitives (`counts[0]`
/// to `counts[1]`), which `query_unbounded` tests with only those kinds'
/// code.
pub fn unbounded_kinds(p: &crate::pack::Packed) -> u32 {
    let n = p.prims.len();
    let lo = (p.globals.counts[0] as usize).min(n);
    let hi = (p.globals.counts[1] as usize).clamp(lo, n);
    crate::pack::layout::Prim::kind_bits(&p.prims[lo..hi]) & 127
}

/// A render's image size and sample lattice (`Gpu::lattice`): pixels w×h,
/// lattice lw×lh (one more each way under corner sampling), the output
/// buffer's bytes.
#[derive(Clone, Copy)]
struct Lattice {
    w: u32,
    h: u32,
    lw: u32,
    lh: u32,
    corners: bool,
    out_bytes: u64,
}

/// The wall time of a render's phases, in order, each timed from the end
/// of the one before (`Frame::phases`).
struct Phases {
    list: Vec<(&'static str, f64)>,
    clock: Instant,
}

impl Phases {
    fn start() -> Phases {
        Phases {
            list: Vec::new(),
            clock: Instant::now(),
        }
    }

    /// Ends phase `what` now.
    fn lap(&mut self, what: &'static str) {
        self.list.push((what, self.clock.elapsed().as_secs_f64()));
        self.clock = Instant::now();
    }
}

/// Ends a kernel's render: reads its output lattice (`vec4 samples[]`,
/// binding 7) into `frame`'s pixels, each sample's rgb, the corners
/// resolved to pixels under corner sampling; the render's seconds from
/// `t0` (the readback included), and its phases, the readback the last.
fn read_back(
    mut frame: Frame,
    samples: &Buffer,
    at: &Lattice,
    t0: Instant,
    mut phases: Phases,
) -> Result<Frame, GpuError> {
    let lattice: Vec<[f32; 3]> = samples
        .read(at.out_bytes as usize)?
        .chunks_exact(16)
        .map(|c| {
            let v: [f32; 4] = bytemuck::pod_read_unaligned(c);
            [v[0], v[1], v[2]]
        })
        .collect();
    frame.pixels = if at.corners {
        cpu::resolve_corners_in_place(lattice, at.w, at.h)
    } else {
        lattice
    };
    (frame.width, frame.height) = (at.w, at.h);
    frame.seconds = t0.elapsed().as_secs_f64();
    phases.lap("readback");
    frame.phases = phases.list;
    Ok(frame)
}

/// An open device with its kernels, reusable across renders and probes.
pub struct Gpu {
    /// Held through each render or probe: descriptor sets and the queue
    /// need external synchronisation.
    busy: Mutex<()>,
    // Kernels hold Arc<Context>; the context goes when the last of them does.
    kernels: KernelCache,
    ctx: Arc<Context>,
}

impl Gpu {
    /// Opens the device `opts` chooses, with its device-level settings
    /// (see `GpuOptions`).
    pub fn new(opts: &GpuOptions) -> Result<Self, GpuError> {
        let ctx = Arc::new(Context::new(resolve(opts)?)?);
        Ok(Gpu {
            busy: Mutex::new(()),
            kernels: Mutex::new(HashMap::new()),
            ctx,
        })
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.ctx.info
    }

    /// The validation layer is on for this device.
    pub fn validation(&self) -> bool {
        self.ctx.instance.validation
    }

    /// Synchronization validation is on for this device.
    pub fn sync_validation(&self) -> bool {
        self.ctx.instance.sync_validation
    }

    /// The folder of the pipeline cache in use (None: no cache).
    pub fn pipeline_cache_dir(&self) -> Option<&std::path::Path> {
        self.ctx.settings.cache_dir.as_deref()
    }

    /// The fault that ended this device (a loss or a timeout), if one
    /// did: every later render or probe returns it again.
    pub fn failed(&self) -> Option<GpuError> {
        self.ctx
            .failed
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// The fence timeout in force.
    pub fn fence_timeout(&self) -> Duration {
        self.ctx.settings.fence_timeout
    }

    /// Runs `f` on the device unless an earlier fault ended it; classifies
    /// its error, and ends the device after a loss or a timeout.
    fn guarded<T>(&self, f: impl FnOnce() -> Result<T, GpuError>) -> Result<T, GpuError> {
        let failed = || self.ctx.failed.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(e) = &*failed() {
            return Err(e.clone());
        }
        let r = f().map_err(|e| e.classify(&self.ctx.info.name));
        if let Err(e) = &r {
            if e.ends_the_device() {
                log::debug!("{} is not used again after: {e}", self.ctx.info.name);
                failed().get_or_insert_with(|| e.clone());
            }
        }
        r
    }

    /// What `--backend auto` does: renders on this device, and when the
    /// device fails (`GpuError::is_device_fault`) renders with `fallback`
    /// (the CPU mirror) instead and returns the fault beside the frame, so
    /// that the caller can say, in one line, that the CPU mirror finished
    /// the render and why. Any other error is returned as it is.
    pub fn render_or(
        &self,
        packed: &Packed,
        opts: &GpuOptions,
        progress: &dyn Fn(u64, u64),
        fallback: impl FnOnce() -> Frame,
    ) -> Result<(Frame, Option<GpuError>), GpuError> {
        match self.render(packed, opts, progress) {
            Ok(f) => Ok((f, None)),
            Err(e) if e.is_device_fault() => {
                log::info!("{e}; rendering on the CPU mirror instead");
                Ok((fallback(), Some(e)))
            }
            Err(e) => Err(e),
        }
    }

    fn kernel(
        &self,
        name: &'static str,
        spirv: &[u8],
        bindings: &[u32],
        push_size: u32,
        spec: &[(u32, u32)],
    ) -> Result<Arc<Kernel>, GpuError> {
        let mut key = [0u32; 5];
        for &(id, v) in spec {
            key[id as usize] = v;
        }
        let mut map = self.kernels.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(k) = map.get(&(name, key)) {
            return Ok(k.clone());
        }
        let k = Arc::new(Kernel::new(
            &self.ctx, name, spirv, bindings, push_size, spec,
        )?);
        map.insert((name, key), k.clone());
        Ok(k)
    }

    /// Refuses, with the reason, what the device cannot hold: an array over
    /// `maxStorageBufferRange`, or more memory than its largest heap.
    fn check_fits(
        &self,
        packed: &Packed,
        out_samples: u64,
        cells: CellLayout,
    ) -> Result<(), GpuError> {
        let i = &self.ctx.info;
        let mut arrays = crate::budget::gpu_buffers(packed, out_samples);
        for a in arrays.iter_mut().filter(|a| a.0 == "cell_start") {
            a.1 = cells.bytes(packed);
        }
        for (name, bytes) in arrays {
            if bytes > i.max_storage_buffer_range {
                let hint = match name {
                    "output samples" => "render a smaller image",
                    "cell_start" | "refs" => "choose a coarser --grid or --accel bvh",
                    "lb_start" | "lb_refs" => "use --shadows plain",
                    _ => "simplify the scene",
                };
                return Err(GpuError::Limits(format!(
                    "the scene does not fit {}: its {name} buffer is {}, over the device's \
                     maxStorageBufferRange of {}; {hint}, or use --backend cpu",
                    i.name,
                    mib(bytes),
                    mib(i.max_storage_buffer_range)
                )));
            }
        }
        let total: u64 = arrays.iter().map(|a| a.1).sum();
        if i.device_local_bytes > 0 && total > i.device_local_bytes / 10 * 9 {
            return Err(GpuError::Limits(format!(
                "the scene needs {} of buffers, more than {} can hold ({} device-local memory)",
                mib(total),
                i.name,
                mib(i.device_local_bytes)
            )));
        }
        Ok(())
    }

    /// `opts` with what depends on the device settled: the lattice points
    /// an invocation renders (`lane_pixels_for`), and the grid's cells as
    /// offsets where pairs would not fit the device's buffer range
    /// (`CellLayout::fitting`; the same image).
    fn resolved(&self, packed: &Packed, opts: &GpuOptions) -> GpuOptions {
        let range = self.ctx.info.max_storage_buffer_range;
        let cell_layout = opts.cell_layout.fitting(packed, range);
        if cell_layout != opts.cell_layout {
            log::debug!(
                "the grid's cells as offsets: as pairs they would be {}, over {}",
                mib(CellLayout::Pairs.bytes(packed)),
                mib(range)
            );
        }
        let max_texels = self.ctx.info.max_texel_buffer_elements;
        let reads = opts.reads.fitting(packed, cell_layout, max_texels);
        if reads != opts.reads {
            log::debug!(
                "the scene's arrays read as storage buffers: one has more than {max_texels} texels"
            );
        }
        let shadow_cache = opts.shadow_cache.for_device(self.info().kind);
        if opts.shadow_cache == GpuShadowCache::Auto {
            log::debug!(
                "shadow cache {} on this device (--shadow-cache auto)",
                if shadow_cache == GpuShadowCache::On {
                    "on"
                } else {
                    "off"
                }
            );
        }
        GpuOptions {
            cell_layout,
            reads,
            lane_pixels: lane_pixels_for(opts.lane_pixels, self.info().kind),
            tile: tile_for(opts.tile, self.info().kind),
            shadow_cache,
            ..opts.clone()
        }
    }

    /// The output lattice of a render of `packed`, after the checks every
    /// render kernel needs: the workgroup shape, the buffers against the
    /// device's limits, llvmpipe's loop budget.
    fn lattice(&self, packed: &Packed, opts: &GpuOptions) -> Result<Lattice, GpuError> {
        self.check_workgroup(opts)?;
        let g = &packed.globals;
        let (w, h) = (g.image[0], g.image[1]);
        let corners = g.image[3] == SAMPLING_CORNERS;
        let (lw, lh) = if corners { (w + 1, h + 1) } else { (w, h) };
        let n = lw as u64 * lh as u64;
        self.check_fits(packed, n, opts.cell_layout)?;
        self.check_loops(packed)?;
        Ok(Lattice {
            w,
            h,
            lw,
            lh,
            corners,
            out_bytes: n * 16,
        })
    }

    fn upload_scene(
        &self,
        cmds: &Commands,
        p: &Packed,
        opts: &GpuOptions,
    ) -> Result<SceneBuffers, GpuError> {
        let b =
            |name: &str, bytes: &[u8]| Buffer::upload(&self.ctx, cmds, name, bytes, opts.staging);
        let bufs = vec![
            b("globals", bytemuck::bytes_of(&p.globals))?,
            b("prims", &opts.prim_layout.bytes(&p.prims))?,
            b("extra", bytemuck::cast_slice(&p.extra))?,
            b("materials", bytemuck::cast_slice(&p.materials))?,
            b("lights", bytemuck::cast_slice(&p.lights))?,
            b(
                "cell_start",
                bytemuck::cast_slice(&opts.cell_layout.words(p)),
            )?,
            b("refs", bytemuck::cast_slice(&p.refs))?,
            b("bvh", bytemuck::cast_slice(&bvh_for_gpu(&p.bvh)?))?,
            b("lb_start", bytemuck::cast_slice(&p.lb_start))?,
            b("lb_refs", bytemuck::cast_slice(&p.lb_refs))?,
        ];
        let mut bufs: Vec<(u32, Buffer)> = SCENE_BINDINGS.into_iter().zip(bufs).collect();
        let max_texels = self.ctx.info.max_texel_buffer_elements;
        for (i, b) in &mut bufs {
            if let Some((_, format)) = texel_binding(*i) {
                b.add_texel_view(format, max_texels)?;
            }
        }
        Ok(SceneBuffers { bufs })
    }

    /// On a device with llvmpipe's loop budget, refuses a render in which
    /// the host can see that some invocation's loops must exceed it.
    fn check_loops(&self, packed: &Packed) -> Result<(), GpuError> {
        if !self.info().has_loop_budget() {
            return Ok(());
        }
        match loops::certain_cut(packed) {
            Some(c) => Err(GpuError::LoopsWouldBeCut {
                device: self.info().name.clone(),
                at: c.at(),
                iterations: c.iterations,
                cause: c.driver.describe(),
                remedy: c.driver.remedy().into(),
            }),
            None => Ok(()),
        }
    }

    /// The error for `loops` cut loops, naming what drives them; with
    /// `lane_pixels` > 1 points per invocation, fewer is the first remedy.
    fn loops_cut(&self, packed: &Packed, loops: u32, lane_pixels: u32) -> GpuError {
        let driver = loops::LoopLoad::of(packed).largest();
        let remedy = if lane_pixels > 1 {
            format!(
                "use --lane-pixels 1 (each invocation rendered {lane_pixels} lattice points), {}",
                driver.remedy()
            )
        } else {
            driver.remedy().into()
        };
        GpuError::LoopsCut {
            device: self.info().name.clone(),
            loops,
            cause: driver.describe(),
            remedy,
        }
    }

    fn check_workgroup(&self, opts: &GpuOptions) -> Result<(), GpuError> {
        let i = &self.ctx.info;
        let [wx, wy] = opts.workgroup;
        if wx == 0
            || wy == 0
            || wx > i.max_compute_work_group_size[0]
            || wy > i.max_compute_work_group_size[1]
            || (wx as u64 * wy as u64) > i.max_compute_work_group_invocations as u64
        {
            return Err(GpuError::Limits(format!(
                "--workgroup {wx}x{wy}: {} allows at most {}x{} and {} invocations per workgroup",
                i.name,
                i.max_compute_work_group_size[0],
                i.max_compute_work_group_size[1],
                i.max_compute_work_group_invocations
            )));
        }
        if opts.tile == 0 {
            return Err(GpuError::Limits("--tile must be at least 1".into()));
        }
        let gx = opts.tile.div_ceil(wx);
        if gx > i.max_compute_work_group_count[0] || gx > i.max_compute_work_group_count[1] {
            return Err(GpuError::Limits(format!(
                "--tile {}: {} workgroups per axis, over {}'s limit of {}",
                opts.tile, gx, i.name, i.max_compute_work_group_count[0]
            )));
        }
        Ok(())
    }

    /// Renders with `shaders/render.comp` (the exact or the fast kernel,
    /// `opts.math`), tile by tile; `progress(done, total)` after each tile.
    pub fn render(
        &self,
        packed: &Packed,
        opts: &GpuOptions,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Frame, GpuError> {
        let by_device = opts.lane_pixels == 0;
        let opts = &self.resolved(packed, opts);
        if opts.kernel == GpuKernel::Wavefront && opts.math != GpuMath::Exact {
            return Err(GpuError::Setting(
                "--kernel wavefront has only the exact arithmetic: drop --gpu-math fast".into(),
            ));
        }
        if opts.kernel == GpuKernel::Calibration {
            if let Some(why) = calibration_refusal(packed) {
                return Err(GpuError::Setting(format!(
                    "--kernel calibration cannot render this scene: {why}"
                )));
            }
        }
        // The variable replaces the megakernel's module only.
        if opts.kernel != GpuKernel::Mega
            && std::env::var_os(RENDER_SPV).is_some_and(|v| !v.is_empty())
        {
            let why = match opts.kernel {
                GpuKernel::Wavefront => "runs its own stages",
                _ => "is another kernel",
            };
            return Err(GpuError::Setting(format!(
                "{RENDER_SPV} replaces the megakernel, and --kernel {} {why}: unset the \
                 variable or use --kernel mega",
                opts.kernel.name()
            )));
        }
        if opts.kernel == GpuKernel::Wavefront {
            return self.guarded(|| self.render_wavefront(packed, opts, progress));
        }
        if opts.kernel == GpuKernel::Calibration {
            // One lattice point an invocation; no arithmetic variants.
            let opts = GpuOptions {
                lane_pixels: 1,
                ..opts.clone()
            };
            return self.guarded(|| {
                self.render_with(shaders::CALIBRATION, "calibration", packed, &opts, progress)
            });
        }
        if let Some((shown, variant)) = render_variant()? {
            // The built-in kernel at more than one point an invocation is
            // `render_lanes` (WHITTED_LANES): a variant compiled without
            // it renders the same image 1.3-1.6 times slower on lavapipe,
            // which is no measure of the variant (docs/profiling.md).
            let (builtin, _) = opts.math.render_kernel(opts.lane_pixels > 1);
            log::info!(
                "rendering with the kernel in {shown} ({RENDER_SPV}) at {} lattice point(s) \
                 an invocation (--lane-pixels), where the built-in kernel is {builtin}.spv{}",
                opts.lane_pixels,
                if opts.lane_pixels > 1 {
                    ": compile the variant with -DWHITTED_LANES=1 to compare like with like"
                } else {
                    ""
                }
            );
            return self
                .guarded(|| self.render_with(&variant, "render_variant", packed, opts, progress));
        }
        let mega = |opts: &GpuOptions| {
            let (name, spirv) = opts.math.render_kernel(opts.lane_pixels > 1);
            self.guarded(|| self.render_with(spirv, name, packed, opts, progress))
        };
        match mega(opts) {
            // An invocation rendering K points makes about K times the
            // loop iterations of one, against the same budget: a scene
            // within it at one point per invocation renders, not fails,
            // when K was the device's default rather than asked for.
            Err(GpuError::LoopsCut { device, cause, .. }) if by_device && opts.lane_pixels > 1 => {
                log::info!(
                    "{device} cut shader loops short at {} lattice points per invocation, \
                     likely for {cause}: rendering again with one (--lane-pixels 1)",
                    opts.lane_pixels
                );
                mega(&GpuOptions {
                    lane_pixels: 1,
                    ..opts.clone()
                })
            }
            r => r,
        }
    }

    fn render_with(
        &self,
        spirv: &[u8],
        name: &'static str,
        packed: &Packed,
        opts: &GpuOptions,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Frame, GpuError> {
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        let lattice = self.lattice(packed, opts)?;
        let Lattice {
            lw,
            lh,
            corners,
            out_bytes,
            ..
        } = lattice;
        let g = &packed.globals;
        let mut phases = Phases::start();
        let kernel = self.kernel(
            name,
            spirv,
            // The samples (7), the counters (8).
            &kernel_bindings(&[7, 8]),
            std::mem::size_of::<RenderPush>() as u32,
            &{
                let [features, structure] = scene_spec(packed, opts);
                [
                    (0, opts.workgroup[0]),
                    (1, opts.workgroup[1]),
                    features,
                    structure,
                    (4, opts.lane_pixels),
                ]
            },
        )?;
        phases.lap("pipeline");
        let cmds = Commands::new(&self.ctx)?;
        let scene = self.upload_scene(&cmds, packed, opts)?;
        let samples = Buffer::readback(&self.ctx, "samples", out_bytes)?;
        let counters = Buffer::readback(&self.ctx, "counters", COUNTERS_BYTES)?;
        let mut binds = scene.bindings();
        binds.push((7, &samples));
        binds.push((8, &counters));
        kernel.bind(&binds)?;
        phases.lap("upload");

        if !kernel
            .warmed
            .swap(true, std::sync::atomic::Ordering::SeqCst)
        {
            // An empty tile: every invocation is out of range, nothing is
            // traced or counted, but the driver compiles the pipeline now
            // rather than inside the first timed tile.
            cmds.run_once(dispatch::Work::Warmup, |d, cmd| {
                cmds.record_dispatch(
                    d,
                    cmd,
                    &kernel,
                    bytemuck::bytes_of(&RenderPush::default()),
                    [1, 1, 1],
                    Some(&counters),
                )
            })?;
        }
        phases.lap("warm-up");
        let spp = if corners { 1 } else { g.image[2] };
        let max_samples = dispatch::max_tile_samples(g.trace[0], g.counts[2], MAX_TILE_SAMPLES);
        let tiles = dispatch::tiles(lw, lh, opts.tile, spp, max_samples);
        let t0 = Instant::now();
        let mut stats = RayStats::default();
        let mut work = crate::trace::query::Work::default();
        let mut device_seconds: Option<f64> = None;
        let [wx, wy] = opts.workgroup;
        // A CPU driver's threads take contiguous blocks of workgroups:
        // scatter them (dispatch::scatter_stride).
        let scatter = self.info().kind == DeviceKind::Cpu;
        for (k, t) in tiles.iter().enumerate() {
            let groups = [t.w.div_ceil(wx), t.h.div_ceil(wy), 1];
            let stride = if scatter {
                dispatch::scatter_stride(groups[0] * groups[1])
            } else {
                1
            };
            let push: RenderPush = [t.x0, t.y0, t.w, t.h, stride, 0, 0, 0];
            cmds.run_once(
                dispatch::Work::Tile {
                    index: k,
                    count: tiles.len(),
                },
                |d, cmd| {
                    cmds.record_dispatch(
                        d,
                        cmd,
                        &kernel,
                        bytemuck::bytes_of(&push),
                        groups,
                        Some(&counters),
                    )
                },
            )?;
            let (s, wk, cut) = read_counts(&counters)?;
            if cut > 0 {
                return Err(self.loops_cut(packed, cut, opts.lane_pixels));
            }
            work.add(&wk);
            stats.add(&s);
            if let Some(s) = cmds.elapsed()? {
                *device_seconds.get_or_insert(0.0) += s;
            }
            progress(k as u64 + 1, tiles.len() as u64);
        }
        phases.lap("dispatch");
        let frame = Frame {
            stats,
            work,
            device_seconds,
            ..Frame::default()
        };
        read_back(frame, &samples, &lattice, t0, phases)
    }

    /// Runs probe kernel `mode` of `shaders/probe.comp` on every item.
    pub fn probe(
        &self,
        packed: &Packed,
        mode: ProbeMode,
        items: &[ProbeItem],
    ) -> Result<Vec<ProbeResult>, GpuError> {
        self.guarded(|| self.probe_with("probe", shaders::PROBE, packed, mode, items))
    }

    fn probe_with(
        &self,
        name: &'static str,
        spirv: &[u8],
        packed: &Packed,
        mode: ProbeMode,
        items: &[ProbeItem],
    ) -> Result<Vec<ProbeResult>, GpuError> {
        if items.is_empty() {
            return Ok(Vec::new());
        }
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        self.check_fits(packed, 0, CellLayout::Offsets)?;
        // The primitives as structures, the cells as offsets, storage
        // reads, the shadow cache on: the layouts as packed.
        let layouts = GpuOptions {
            prim_layout: PrimLayout::Aos,
            cell_layout: CellLayout::Offsets,
            reads: GpuReads::Storage,
            shadow_cache: GpuShadowCache::On,
            ..GpuOptions::default()
        };
        let kernel = self.kernel(
            name,
            spirv,
            // The items (9), the results (10).
            &kernel_bindings(&[9, 10]),
            std::mem::size_of::<ProbePush>() as u32,
            // Specialized for the scene as the render kernels are, so that
            // the probe tests the code a render runs (the scene's kinds and
            // features, its structure's walk), and the driver compiles only
            // that. Unspecialized (every walk and kind), no probe finished
            // within 30 s on an NVIDIA H200 (docs/profiling.md).
            &scene_spec(packed, &layouts),
        )?;
        let cmds = Commands::new(&self.ctx)?;
        let scene = self.upload_scene(&cmds, packed, &layouts)?;
        let input = Buffer::host_input(&self.ctx, "probe items", bytemuck::cast_slice(items))?;
        let out_len = std::mem::size_of_val(items);
        let output = Buffer::readback(&self.ctx, "probe results", out_len as u64)?;
        let mut binds = scene.bindings();
        binds.push((9, &input));
        binds.push((10, &output));
        kernel.bind(&binds)?;
        let count = items.len() as u32;
        let groups = count.div_ceil(probe::PROBE_LOCAL_SIZE);
        if groups > self.ctx.info.max_compute_work_group_count[0] {
            return Err(GpuError::Limits(format!(
                "{} need {}; the device allows {}",
                plural(count as u64, "probe item", "probe items"),
                plural(groups as u64, "workgroup", "workgroups"),
                self.ctx.info.max_compute_work_group_count[0]
            )));
        }
        let push: ProbePush = [mode as u32, count, 0, 0];
        cmds.run_once(dispatch::Work::Probe, |d, cmd| {
            cmds.record_dispatch(
                d,
                cmd,
                &kernel,
                bytemuck::bytes_of(&push),
                [groups, 1, 1],
                None,
            )
        })?;
        Ok(output
            .read(out_len)?
            .chunks_exact(std::mem::size_of::<ProbeResult>())
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_counts_read_as_english() {
        let e = |count| GpuError::BadIndex { index: 5, count }.to_string();
        assert_eq!(
            e(1),
            "--device 5: there is only 1 Vulkan device (index 0; see `whitted devices`)"
        );
        assert_eq!(
            e(3),
            "--device 5: there are only 3 Vulkan devices (indices 0 to 2; see `whitted devices`)"
        );
        assert!(e(0).contains("there is no Vulkan device"), "{}", e(0));
        assert_eq!(plural(1, "loop", "loops"), "1 loop");
        assert_eq!(plural(20_000, "light", "lights"), "20 000 lights");
        assert_eq!(seconds(Duration::from_secs(1)), "1 second");
        assert_eq!(seconds(Duration::from_millis(1500)), "1.5 seconds");
    }

    #[test]
    fn the_default_tile_and_lane_pixels_follow_the_device_class() {
        for kind in [
            DeviceKind::Discrete,
            DeviceKind::Integrated,
            DeviceKind::Virtual,
        ] {
            assert_eq!(tile_for(0, kind), DEFAULT_GPU_TILE, "{kind:?}");
            assert_eq!(lane_pixels_for(0, kind), 1, "{kind:?}");
        }
        assert_eq!(tile_for(0, DeviceKind::Cpu), DEFAULT_TILE);
        assert_eq!(lane_pixels_for(0, DeviceKind::Cpu), 2);
        // What the user asks for stands on every device.
        assert_eq!(tile_for(64, DeviceKind::Discrete), 64);
        assert_eq!(tile_for(4096, DeviceKind::Cpu), 4096);
        // One GPU tile is the most one submission may hold.
        assert_eq!(
            u64::from(DEFAULT_GPU_TILE) * u64::from(DEFAULT_GPU_TILE),
            MAX_TILE_SAMPLES
        );
    }

    #[test]
    fn faults_parse_by_name_and_sort_into_device_faults() {
        for f in Fault::ALL {
            assert_eq!(f.name().parse::<Fault>().unwrap(), f);
        }
        let e = "device-found".parse::<Fault>().unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("device-lost"),
            "{e}"
        );
        let lost = GpuError::Vulkan {
            call: "vkQueueSubmit",
            result: vk::Result::ERROR_DEVICE_LOST,
        }
        .classify("dev");
        assert!(matches!(lost, GpuError::DeviceLost { .. }) && lost.is_device_fault());
        assert!(lost.ends_the_device());
        let oom = GpuError::Vulkan {
            call: "vkAllocateCommandBuffers",
            result: vk::Result::ERROR_OUT_OF_DEVICE_MEMORY,
        }
        .classify("dev");
        assert!(oom.is_device_fault() && !oom.ends_the_device(), "{oom:?}");
        let host = GpuError::Vulkan {
            call: "vkCreateFence",
            result: vk::Result::ERROR_OUT_OF_HOST_MEMORY,
        }
        .classify("dev");
        assert!(matches!(host, GpuError::OutOfHostMemory { .. }), "{host:?}");
        let other = GpuError::Vulkan {
            call: "vkCreateFence",
            result: vk::Result::ERROR_UNKNOWN,
        }
        .classify("dev");
        assert!(!other.is_device_fault() && !other.is_user_error());
    }

    #[test]
    fn structure_keys_tell_every_walk_apart_and_ignore_the_bvh_node_count() {
        use crate::constants::*;
        // flags: [counting, accel, BVH nodes or octree walk, light-buffer resolution]
        let cases = [
            [0, ACCEL_GRID, 0, 0],
            [0, ACCEL_BVH, 0, 0],
            [0, ACCEL_OCTREE, OCTREE_WALK_NEIGHBOUR, 0],
            [0, ACCEL_OCTREE, OCTREE_WALK_STACK, 0],
            [0, ACCEL_GRID, 0, 16],
            [0, ACCEL_BVH, 0, 32],
            [0, ACCEL_OCTREE, OCTREE_WALK_STACK, 8],
        ];
        let keys: Vec<u32> = cases.iter().map(|&f| structure_key(f)).collect();
        for i in 0..keys.len() {
            for j in 0..i {
                assert_ne!(keys[i], keys[j], "{:?} and {:?}", cases[i], cases[j]);
            }
            // Never the shader's "decide at run time" default.
            assert_ne!(keys[i], u32::MAX);
        }
        // The BVH's node count (flags[2]) and the counting flags are not part of it.
        assert_eq!(structure_key([1, ACCEL_BVH, 3938, 0]), keys[1]);
        assert_eq!(structure_key([0, ACCEL_GRID, 0, 1]), keys[4]);
    }
}
