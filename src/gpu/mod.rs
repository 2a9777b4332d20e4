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
pub mod memory;
pub mod pipeline;
pub mod probe;
pub mod shaders;

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
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What can go wrong on the GPU path.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No loader, no driver, no device (or no real GPU when one is required).
    #[error("no Vulkan device: {0}")]
    NoDevice(String),
    #[error("--device {index}: there are only {count} Vulkan devices (0 to {}; see `whitted devices`)", count - 1)]
    BadIndex { index: usize, count: usize },
    #[error("{0}")]
    Unusable(String),
    /// The scene or the options exceed what the device can do.
    #[error("{0}")]
    Limits(String),
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
    /// The driver stopped shader loops early (llvmpipe's per-shader loop
    /// budget of 65535 iterations): the image would be silently wrong.
    #[error(
        "{device} cut {loops} shader loops short (llvmpipe stops every loop after 65535 iterations \
         per group of invocations), so this image would be wrong; use --backend cpu, fewer lights, \
         a smaller --max-depth or a smaller --workgroup"
    )]
    LoopsCut { device: String, loops: u32 },
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
                | GpuError::Memory { .. }
                | GpuError::LoopsCut { .. }
        )
    }
}

pub(crate) fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

/// Default edge of a dispatch tile, in lattice samples.
pub const DEFAULT_TILE: u32 = 256;
/// Default workgroup shape (specialization constants 0 and 1).
pub const DEFAULT_WORKGROUP: [u32; 2] = [8, 8];
/// Most eye rays one tile traces: keeps every submission short. Deep
/// trees and many lights lower it further (`dispatch::max_tile_samples`)
/// so the shader's 32-bit ray counters cannot wrap within a tile.
pub const MAX_TILE_SAMPLES: u64 = 1 << 20;

/// How to run on the GPU.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GpuOptions {
    /// `--device N`: index in `devices()`; None: the best usable device.
    pub device: Option<usize>,
    /// Refuse CPU (software) Vulkan devices unless `device` names one.
    pub real_gpu_only: bool,
    /// Edge of a tile in lattice samples.
    pub tile: u32,
    /// Workgroup width and height.
    pub workgroup: [u32; 2],
    /// Upload the scene through a staging buffer even where device-local
    /// memory is host-visible: the path a discrete GPU takes, tested on
    /// lavapipe (whose memory is all host-visible).
    pub staging: bool,
}

impl Default for GpuOptions {
    fn default() -> Self {
        GpuOptions {
            device: None,
            real_gpu_only: false,
            tile: DEFAULT_TILE,
            workgroup: DEFAULT_WORKGROUP,
            staging: false,
        }
    }
}

/// Every Vulkan device; `Err(NoDevice)` when there is no loader or driver.
pub fn devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let inst = context::Instance::new()?;
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

/// The packed arrays on the device: bindings 0–6.
struct SceneBuffers {
    bufs: Vec<Buffer>,
}

impl SceneBuffers {
    fn bindings(&self) -> Vec<(u32, &Buffer)> {
        self.bufs
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, b))
            .collect()
    }
}

/// render.comp's push constants: the tile (x0, y0, w, h), then the
/// workgroup order's stride and three unused words.
type RenderPush = [u32; 8];
/// probe.comp's push constants: mode, item count, two unused words.
type ProbePush = [u32; 4];

/// Kernels by (name, specialization constants 0..=2).
type KernelCache = Mutex<HashMap<(&'static str, [u32; 3]), Arc<Kernel>>>;

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
    /// Opens the device `opts` chooses.
    pub fn new(opts: &GpuOptions) -> Result<Self, GpuError> {
        let ctx = Arc::new(Context::new(opts.device, opts.real_gpu_only)?);
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

    fn kernel(
        &self,
        name: &'static str,
        spirv: &[u8],
        bindings: &[u32],
        push_size: u32,
        spec: &[(u32, u32)],
    ) -> Result<Arc<Kernel>, GpuError> {
        let mut key = [0u32; 3];
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
    fn check_fits(&self, packed: &Packed, out_samples: u64) -> Result<(), GpuError> {
        let i = &self.ctx.info;
        let arrays = crate::budget::gpu_buffers(packed, out_samples);
        for (name, bytes) in arrays {
            if bytes > i.max_storage_buffer_range {
                let hint = match name {
                    "output samples" => "render a smaller image",
                    "cell_start" | "refs" => "choose a coarser --grid",
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

    fn upload_scene(
        &self,
        cmds: &Commands,
        p: &Packed,
        staged: bool,
    ) -> Result<SceneBuffers, GpuError> {
        let b = |name: &str, bytes: &[u8]| Buffer::upload(&self.ctx, cmds, name, bytes, staged);
        Ok(SceneBuffers {
            bufs: vec![
                b("globals", bytemuck::bytes_of(&p.globals))?,
                b("prims", bytemuck::cast_slice(&p.prims))?,
                b("extra", bytemuck::cast_slice(&p.extra))?,
                b("materials", bytemuck::cast_slice(&p.materials))?,
                b("lights", bytemuck::cast_slice(&p.lights))?,
                b("cell_start", bytemuck::cast_slice(&p.cell_start))?,
                b("refs", bytemuck::cast_slice(&p.refs))?,
            ],
        })
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

    /// Renders with `shaders/render.comp`, tile by tile; `progress(done,
    /// total)` after each tile.
    pub fn render(
        &self,
        packed: &Packed,
        opts: &GpuOptions,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Frame, GpuError> {
        self.render_with(shaders::RENDER, "render", packed, opts, progress)
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
        self.check_workgroup(opts)?;
        let g = &packed.globals;
        let (w, h) = (g.image[0], g.image[1]);
        let corners = g.image[3] == SAMPLING_CORNERS;
        let (lw, lh) = if corners { (w + 1, h + 1) } else { (w, h) };
        let n = lw as u64 * lh as u64;
        let out_bytes = n * 16;
        self.check_fits(packed, n)?;
        let kernel = self.kernel(
            name,
            spirv,
            &[0, 1, 2, 3, 4, 5, 6, 7, 8],
            std::mem::size_of::<RenderPush>() as u32,
            &[
                (0, opts.workgroup[0]),
                (1, opts.workgroup[1]),
                (2, g.trace[1]),
            ],
        )?;
        let cmds = Commands::new(&self.ctx)?;
        let scene = self.upload_scene(&cmds, packed, opts.staging)?;
        let samples = Buffer::readback(&self.ctx, "samples", out_bytes)?;
        let counters = Buffer::readback(&self.ctx, "counters", 32)?;
        let mut binds = scene.bindings();
        binds.push((7, &samples));
        binds.push((8, &counters));
        kernel.bind(&binds)?;

        if !kernel
            .warmed
            .swap(true, std::sync::atomic::Ordering::SeqCst)
        {
            // An empty tile: every invocation is out of range, nothing is
            // traced or counted, but the driver compiles the pipeline now
            // rather than inside the first timed tile.
            cmds.run_once(|d, cmd| {
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
        let spp = if corners { 1 } else { g.image[2] };
        let max_samples = dispatch::max_tile_samples(g.trace[0], g.counts[2], MAX_TILE_SAMPLES);
        let tiles = dispatch::tiles(lw, lh, opts.tile, spp, max_samples);
        let t0 = Instant::now();
        let mut stats = RayStats::default();
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
            cmds.run_once(|d, cmd| {
                cmds.record_dispatch(
                    d,
                    cmd,
                    &kernel,
                    bytemuck::bytes_of(&push),
                    groups,
                    Some(&counters),
                )
            })?;
            let c: [u32; 8] = bytemuck::pod_read_unaligned(counters.read(32)?);
            if c[5] > 0 {
                return Err(GpuError::LoopsCut {
                    device: self.info().name.clone(),
                    loops: c[5],
                });
            }
            stats.add(&RayStats {
                eye: c[0] as u64,
                eye_hit: c[1] as u64,
                reflect: c[2] as u64,
                refract: c[3] as u64,
                shadow: c[4] as u64,
            });
            if let Some(s) = cmds.elapsed()? {
                *device_seconds.get_or_insert(0.0) += s;
            }
            progress(k as u64 + 1, tiles.len() as u64);
        }
        let raw = samples.read(out_bytes as usize)?;
        let lattice: Vec<[f32; 3]> = raw
            .chunks_exact(16)
            .map(|c| {
                let v: [f32; 4] = bytemuck::pod_read_unaligned(c);
                [v[0], v[1], v[2]]
            })
            .collect();
        let pixels = if corners {
            cpu::resolve_corners(&lattice, w, h)
        } else {
            lattice
        };
        Ok(Frame {
            width: w,
            height: h,
            pixels,
            stats,
            work: Default::default(),
            seconds: t0.elapsed().as_secs_f64(),
            device_seconds,
        })
    }

    /// Runs probe kernel `mode` of `shaders/probe.comp` on every item.
    pub fn probe(
        &self,
        packed: &Packed,
        mode: ProbeMode,
        items: &[ProbeItem],
    ) -> Result<Vec<ProbeResult>, GpuError> {
        self.probe_with("probe", shaders::PROBE, packed, mode, items)
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
        self.check_fits(packed, 0)?;
        let kernel = self.kernel(
            name,
            spirv,
            &[0, 1, 2, 3, 4, 5, 6, 9, 10],
            std::mem::size_of::<ProbePush>() as u32,
            &[],
        )?;
        let cmds = Commands::new(&self.ctx)?;
        let scene = self.upload_scene(&cmds, packed, false)?;
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
                "{count} probe items need {groups} workgroups; the device allows {}",
                self.ctx.info.max_compute_work_group_count[0]
            )));
        }
        let push: ProbePush = [mode as u32, count, 0, 0];
        cmds.run_once(|d, cmd| {
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
