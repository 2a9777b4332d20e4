//! Options shared by `render` and `validate`, and their parsers.

use crate::gpu::{self, GpuMath, GpuOptions, PipelineCache};
use crate::pack::{Accel, Counting, Preset, Sampling, Settings, Shadows};
use clap::Args;
use std::path::PathBuf;
use std::time::Duration;

/// The image size (`render`, `validate`, `export`).
#[derive(Args, Clone, Debug)]
pub struct SizeOpts {
    /// Image width in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub height: Option<u32>,
}

/// How deep the ray tree goes (`render`, `validate`, `export`).
#[derive(Args, Clone, Debug)]
pub struct DepthOpts {
    /// Generations of reflection/refraction (0 = local model only)
    /// [default: 5; --preset spd: 4].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=crate::constants::MAX_DEPTH_LIMIT as i64))]
    pub max_depth: Option<u32>,
    /// Adaptive depth control: a branch stops when its accumulated weight
    /// (largest channel) falls under this; 0 switches it off
    /// [default: 1/256 = 0.00390625; --preset spd: 0].
    #[arg(long, value_parser = parse_weight)]
    pub min_weight: Option<f32>,
}

impl DepthOpts {
    /// The depth and weight asked for, over `base`'s.
    pub fn resolve(&self, base: &Settings) -> (u32, f32) {
        (
            self.max_depth.unwrap_or(base.max_depth),
            self.min_weight.unwrap_or(base.min_weight),
        )
    }
}

#[derive(Args, Clone, Debug)]
pub struct RenderOpts {
    /// A named set of settings (docs/spd.md); options given beside it
    /// override it.
    #[arg(long, value_enum)]
    pub preset: Option<Preset>,
    /// How the statistics count rays [default: traced; --preset spd: spd].
    /// The image is the same either way, bit for bit; `spd` traces more
    /// rays where a surface lets light through and does not reflect
    /// (their closest hits are found for the counts alone: on SPD gears a
    /// quarter of the wall time), so `--preset spd --counting traced`
    /// renders the SPD's image without paying for its statistics
    /// (docs/spd.md).
    #[arg(long = "counting", value_enum, value_name = "COUNTING")]
    pub count_as: Option<Counting>,
    #[command(flatten)]
    pub size: SizeOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
    /// Samples per pixel: stratified, jittered by a per-pixel hash
    /// (reproducible). 1 = the pixel centre [default: 1].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub spp: Option<u32>,
    /// Pixel centres (with --spp jitter), or SPD's (W+1)×(H+1) corner rays
    /// [default: centers; --preset spd: corners].
    #[arg(long, value_enum)]
    pub sampling: Option<Sampling>,
    /// Override the voxel grid resolution, e.g. 64x64x32.
    #[arg(long, value_parser = parse_grid, value_name = "NXxNYxNZ")]
    pub grid: Option<[u32; 3]>,
    /// The acceleration structure: the uniform voxel grid, a
    /// bounding-volume hierarchy (surface-area heuristic), an octree
    /// (subdivided where primitives crowd), the hybrid (the grid, whose
    /// crowded cells hold a small BVH each), or one chosen per scene by
    /// the rule in docs/method.md [default: auto; with --grid: grid].
    #[arg(long, value_enum)]
    pub accel: Option<Accel>,
    /// Octree: a node listing at most this many primitives is a leaf
    /// [default: 8].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub octree_leaf: Option<u32>,
    /// Octree: the deepest level, the root at 0; the lattice of the
    /// deepest level has 2^N cells per axis, fewer where f32 coordinates
    /// cannot tell them apart [default: 12].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=16))]
    pub octree_levels: Option<u32>,
    /// Octree: how rays walk it: leaf to leaf from exit points
    /// (neighbour, the lecture's method), or top down with a stack, the
    /// children in order along the ray (stack). Same images [default:
    /// neighbour].
    #[arg(long, value_enum)]
    pub octree_walk: Option<crate::pack::octree::Walk>,
    /// Hybrid: a grid cell listing more than this many primitives holds
    /// a BVH over them [default: 8].
    #[arg(long, value_name = "N")]
    pub hybrid_cell: Option<u32>,
    /// How shadow feelers find their blockers: through the acceleration
    /// structure like every ray (plain), or through a light buffer per
    /// light, a direction cube whose cells list the primitives a feeler
    /// in that direction can meet (lightbuffer; built at pack time, falls
    /// back to plain when over the memory budget). Both give the same
    /// image, bit for bit; which is faster depends on the scene
    /// (docs/method.md, "Light buffers") [default: plain].
    #[arg(long, value_enum)]
    pub shadows: Option<Shadows>,
    /// Memory the run may use: a size (512M, 4GiB, 1.5G; K/M/G/T are
    /// powers of 1024, KB/MB/GB/TB of 1000) or a share of physical memory
    /// (75%). A run whose estimate is over it is refused before anything
    /// large is allocated (exit 2). Default: 50% of physical memory
    /// (docs/budget.md).
    #[arg(long, value_name = "SIZE", value_parser = crate::budget::Budget::parse)]
    pub memory_limit: Option<crate::budget::Budget>,
    /// Worker threads for the CPU backend (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// The CPU backend traces eye rays in packets of this many (1: one by
    /// one) where the structure is the BVH; the image is the same bit for
    /// bit. `--stats` then counts a packet's visit to a node once
    /// (docs/method.md, "Packets of rays") [default: 8].
    #[arg(long, value_parser = ["1", "4", "8"])]
    pub packet: Option<String>,
}

impl RenderOpts {
    /// The CPU's packet width (`--packet`).
    pub fn packet(&self) -> u32 {
        self.packet
            .as_deref()
            .and_then(|p| p.parse().ok())
            .unwrap_or(crate::cpu::DEFAULT_PACKET)
    }

    /// The preset's settings (or the defaults) with every option given
    /// over them.
    pub fn settings(&self) -> Settings {
        let base = self.preset.map(Preset::settings).unwrap_or_default();
        let (max_depth, min_weight) = self.depth.resolve(&base);
        Settings {
            width: self.size.width.or(base.width),
            height: self.size.height.or(base.height),
            max_depth,
            min_weight,
            spp: self.spp.unwrap_or(base.spp),
            sampling: self.sampling.unwrap_or(base.sampling),
            grid: self.grid.or(base.grid),
            accel: self.accel.unwrap_or(base.accel),
            budget: self.memory_limit.unwrap_or(base.budget),
            offset: None,
            shadows: self.shadows.unwrap_or(base.shadows),
            octree: crate::pack::octree::Params {
                max_leaf: self.octree_leaf.unwrap_or(base.octree.max_leaf),
                max_levels: self.octree_levels.unwrap_or(base.octree.max_levels),
                walk: self.octree_walk.unwrap_or(base.octree.walk),
            },
            hybrid_cell: self.hybrid_cell.unwrap_or(base.hybrid_cell),
        }
    }

    /// How rays are counted: as `--counting` says, else as the preset
    /// says, else as traced.
    pub fn counting(&self) -> Counting {
        let c = self
            .count_as
            .or(self.preset.map(Preset::counting))
            .unwrap_or_default();
        if c == Counting::Spd && self.settings().min_weight > 0.0 {
            log::warn!(
                "SPD counting with --min-weight above 0: adaptive cut-off drops rays the SPD \
                 counts, so the ray statistics are not the SPD's"
            );
        }
        c
    }
}

#[derive(Args, Clone, Debug)]
pub struct GpuArgs {
    /// Vulkan device index (see `whitted devices`); default: the best one
    /// (discrete > integrated > virtual > CPU).
    #[arg(long, value_name = "N")]
    pub device: Option<usize>,
    /// Edge of a GPU dispatch tile in lattice samples: one submission per
    /// tile, so none runs long [default: 256 on a CPU Vulkan device such as
    /// lavapipe, 1024 on a GPU, or the shape `whitted profile --save` stored
    /// for the device when neither this nor --workgroup is given; -v says
    /// so].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub tile: Option<u32>,
    /// GPU workgroup shape (specialization constants of the shader)
    /// [default: 8x8, or the saved shape as for --tile].
    #[arg(long, value_name = "WxH", value_parser = parse_workgroup)]
    pub workgroup: Option<[u32; 2]>,
    /// Where compiled GPU pipelines are cached (default: the
    /// WHITTED_PIPELINE_CACHE variable, else $XDG_CACHE_HOME/whitted or
    /// ~/.cache/whitted); `off`: no cache. A bad cache never fails a render.
    #[arg(long, value_name = "DIR|off")]
    pub pipeline_cache: Option<PathBuf>,
    /// Longest wait for one GPU tile before the device is treated as hung
    /// (exit 4, or the CPU mirror with --backend auto) [default: 600].
    /// Each tile is at most 2^20 eye rays; on a slow device use a smaller
    /// --tile rather than a longer wait.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub fence_timeout: Option<Duration>,
    /// The GPU kernel's float arithmetic: the CPU mirror's order, or
    /// reordered and fused by the driver.
    ///
    /// `exact` keeps the CPU mirror's order of operations, nothing
    /// reordered or fused (lavapipe matches the mirror bit for bit).
    /// `fast` lets the driver reorder and fuse (multiply-add) the float
    /// arithmetic: faster on some devices, and the image then differs from
    /// the CPU mirror's in the last bits. `validate` checks the exact
    /// kernel unless given `fast` (then the fast one, within the tolerance
    /// a hardware GPU gets). See docs/gpu.md, "Exact and fast shader
    /// arithmetic".
    #[arg(long, value_enum, value_name = "MATH", default_value_t = GpuMath::Exact)]
    pub gpu_math: GpuMath,
    /// How the primitives lie in the GPU's buffer: an array of 64-byte
    /// structures, or a structure of arrays (each 16-byte field of every
    /// primitive together). The same image; the speed is the device's
    /// (docs/profiling.md, "Memory layout of the primitives").
    #[arg(long, value_enum, value_name = "LAYOUT", default_value_t = gpu::PrimLayout::Aos)]
    pub prim_layout: gpu::PrimLayout,
    /// How the grid's cells lie in the GPU's buffer: `pairs` (start and
    /// count per cell, a single reference inline, the skip in the pair:
    /// one load per cell; offsets instead where pairs would not fit the
    /// device) or `offsets` (as packed: an offset per cell into the
    /// reference list, a skip byte per cell beside them). The same image;
    /// grid and hybrid only (docs/profiling.md, "The grid's cell lists").
    #[arg(long, value_enum, value_name = "LAYOUT", default_value_t = gpu::CellLayout::Pairs)]
    pub cell_layout: gpu::CellLayout,
    /// How the GPU reads the scene's arrays: `texel`, through uniform
    /// texel buffer views (storage buffers where an array is longer than
    /// the device's maxTexelBufferElements), or `storage`, as storage
    /// buffers. The same image; the speed is the device's (docs/
    /// profiling.md, "Texel reads").
    #[arg(long, value_enum, value_name = "READS", default_value_t = gpu::GpuReads::Texel)]
    pub reads: gpu::GpuReads,
    /// Whether the GPU tests the opaque primitive that last blocked a
    /// feeler to a light before walking the structure (the shadow cache
    /// the CPU mirror always keeps): `auto` is off on a CPU Vulkan device
    /// such as lavapipe, where it costs more than it saves, on elsewhere.
    /// The same image; only the work counters change (docs/profiling.md,
    /// "The shadow cache on lavapipe").
    #[arg(long, value_enum, value_name = "WHEN", default_value_t = gpu::GpuShadowCache::Auto)]
    pub shadow_cache: gpu::GpuShadowCache,
    /// How the GPU walks the ray tree: `mega`, one invocation per pixel
    /// walking its whole tree (one dispatch per tile), or `wavefront`,
    /// queues of rays processed stage by stage (generate, closest hit,
    /// shade and spawn, shadow, combine, resolve: several dispatches per
    /// depth, the queues compacted). The same image; exact arithmetic
    /// only for the wavefront (docs/gpu.md, "Megakernel and wavefront").
    /// `calibration`: not the scene's image but the yardstick, a plain
    /// grid tracer for fields of opaque spheres that traces the same rays
    /// (other scenes are refused; docs/profiling.md).
    /// [default: mega, or the kernel `whitted profile --kernels ... --save`
    /// stored for the device; -v says so]
    #[arg(long, value_enum, value_name = "KERNEL")]
    pub kernel: Option<gpu::GpuKernel>,
    /// Lattice points one invocation of the megakernel renders (1 to 64)
    /// [default: 2 on a CPU Vulkan device such as lavapipe, 1 on a GPU]:
    /// above 1, an invocation whose sample's ray tree ends starts its next
    /// sample in the same loop instead of waiting for its neighbours'
    /// deeper trees. The same image (docs/profiling.md, "Persistent
    /// lanes"); lavapipe's loop budget is then shared by those points.
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=gpu::MAX_LANE_PIXELS as i64))]
    pub lane_pixels: Option<u32>,
}

impl GpuArgs {
    pub fn options(&self) -> GpuOptions {
        GpuOptions {
            device: self.device,
            real_gpu_only: false,
            tile: self.tile.unwrap_or(0),
            workgroup: self.workgroup.unwrap_or(gpu::DEFAULT_WORKGROUP),
            saved_shape: self.tile.is_none() && self.workgroup.is_none(),
            staging: false,
            pipeline_cache: match &self.pipeline_cache {
                None => PipelineCache::Default,
                Some(p) if p.as_os_str() == "off" => PipelineCache::Off,
                Some(p) => PipelineCache::Dir(p.clone()),
            },
            fence_timeout: self.fence_timeout,
            math: self.gpu_math,
            prim_layout: self.prim_layout,
            cell_layout: self.cell_layout,
            reads: self.reads,
            shadow_cache: self.shadow_cache,
            kernel: self.kernel.unwrap_or_default(),
            saved_kernel: self.kernel.is_none(),
            lane_pixels: self.lane_pixels.unwrap_or(0),
            ..Default::default()
        }
    }
}

pub fn parse_workgroup(s: &str) -> Result<[u32; 2], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let bad = || format!("expected WxH such as 8x8 (each 1 to 1024), got '{s}'");
    if parts.len() != 2 {
        return Err(bad());
    }
    let mut out = [0u32; 2];
    for (i, p) in parts.iter().enumerate() {
        out[i] = p
            .parse()
            .ok()
            .filter(|n| (1..=1024).contains(n))
            .ok_or_else(bad)?;
    }
    Ok(out)
}

pub fn parse_seconds(s: &str) -> Result<Duration, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("must be a number of seconds, got '{s}'"))?;
    if !v.is_finite() || v <= 0.0 || v > 1e6 {
        return Err(format!("must be in (0, 1000000] seconds, got {s}"));
    }
    Ok(Duration::from_secs_f64(v))
}

pub fn parse_weight(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("must be a number in [0, 1], got '{s}'"))?;
    if !v.is_finite() || !(0.0..=1.0).contains(&v) {
        return Err(format!("must be a number in [0, 1], got {s}"));
    }
    Ok(v)
}

pub fn parse_grid(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let max = crate::constants::GRID_MAX_DIM;
    if parts.len() != 3 {
        return Err(format!("expected NXxNYxNZ such as 64x64x32, got '{s}'"));
    }
    let mut out = [0u32; 3];
    for (i, p) in parts.iter().enumerate() {
        out[i] = p
            .parse()
            .ok()
            .filter(|&n| (1..=max).contains(&n))
            .ok_or_else(|| format!("'{p}' in '{s}' is not a whole number from 1 to {max}"))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_take_good_values_and_refuse_the_rest() {
        assert_eq!(parse_workgroup("16x4"), Ok([16, 4]));
        assert!(parse_workgroup("0x4").is_err());
        assert!(parse_workgroup("8").is_err());
        assert_eq!(parse_grid("1x2x1023"), Ok([1, 2, 1023]));
        assert!(parse_grid("1x2x1024").unwrap_err().contains("1 to 1023"));
        assert!(parse_grid("18446744073709551616x1x1").is_err());
        assert_eq!(parse_weight("0"), Ok(0.0));
        assert!(parse_weight("1.5").is_err());
        assert!(parse_weight("nan").is_err());
        assert!(parse_weight("x").unwrap_err().contains("'x'"));
    }
}
