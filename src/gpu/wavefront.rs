//! The wavefront kernel (`--kernel wavefront`): `shaders/wavefront.comp`'s
//! stages dispatched depth by depth over queues of rays, against the
//! megakernel (`render.comp`, one invocation walking a whole ray tree).
//! docs/gpu.md, "Megakernel and wavefront".
//!
//! Per tile: generate (the eye rays: the queue of depth 0); then per depth
//! extend (closest hits), shade (ambient term, feelers and spawned rays,
//! appended to the next queue and the feeler queue: compaction), shadow
//! (each feeler) and combine (each ray's contribution); last, resolve
//! (every sample's tree summed in the megakernel's order). Each ray is a
//! node of its eye ray's tree; the nodes of one tile stay until resolve.
//! The host reads the queue lengths after each shade; when a queue would
//! overflow, shade wrote nothing past it, and the host grows the buffers
//! (keeping what later stages read) and runs that shade again.

use super::dispatch::{self, Commands, Stage, Work};
use super::memory::Buffer;
use super::pipeline::Kernel;
use super::{
    kernel_bindings, mib, read_back, scene_spec, shaders, Gpu, GpuError, GpuOptions, Phases,
};
use crate::cpu::Frame;
use crate::pack::Packed;
use crate::trace::RayStats;
use std::sync::Arc;
use std::time::Instant;

/// Bytes of one queued ray, tree node, closest hit and shadow feeler
/// (wavefront.comp's WfRay, WfNode, WfHit, WfFeeler).
const RAY: u64 = 64;
const NODE: u64 = 48;
const HIT: u64 = 16;
const FEELER: u64 = 64;

/// Most eye rays one tile of the wavefront kernel starts with: all of a
/// tile's rays are queued at once (2^18 eye rays: 32 MiB of ray queue).
pub const MAX_TILE_RAYS: u64 = 1 << 18;

/// The push constants: tile (x0, y0, w, h), range (items, first queued
/// ray, first node, where spawned rays go), cap (room for spawned rays,
/// room for feelers, unused, unused).
type Push = [u32; 12];

/// The stages' kernels (build.rs builds wavefront.comp once per stage).
const STAGES: [(&str, &[u8]); 6] = [
    ("wavefront_generate", shaders::WF_GENERATE),
    ("wavefront_extend", shaders::WF_EXTEND),
    ("wavefront_shade", shaders::WF_SHADE),
    ("wavefront_shadow", shaders::WF_SHADOW),
    ("wavefront_combine", shaders::WF_COMBINE),
    ("wavefront_resolve", shaders::WF_RESOLVE),
];
const GENERATE: usize = 0;
const EXTEND: usize = 1;
const SHADE: usize = 2;
const SHADOW: usize = 3;
const COMBINE: usize = 4;
const RESOLVE: usize = 5;

/// The submissions' kinds, as `Frame::device_stages` names them: shadow
/// and combine go in one submission.
const STAGE_NAMES: [&str; 5] = ["generate", "extend", "shade", "shadow+combine", "resolve"];

/// The kind of a submission whose first stage is `stage`.
fn stage_kind(stage: usize) -> usize {
    match stage {
        GENERATE => 0,
        EXTEND => 1,
        SHADE => 2,
        SHADOW | COMBINE => 3,
        _ => 4,
    }
}

/// The kernels' bindings: the scene's, the output (7), the counters (8),
/// rays (9), nodes (10), hits (14), feelers (15), the queue lengths (16).
fn bindings() -> Vec<u32> {
    kernel_bindings(&[7, 8, 9, 10, 14, 15, 16])
}

/// The queues and their capacities (in rays, nodes, feelers). `rays`
/// holds two halves of `cap_rays`: depth k reads half k mod 2 and
/// spawns into the other.
struct Queues {
    rays: Buffer,
    nodes: Buffer,
    hits: Buffer,
    feelers: Buffer,
    cap_rays: u64,
    cap_nodes: u64,
    cap_feelers: u64,
}

impl Gpu {
    /// The size check every queue buffer passes: under the device's
    /// `maxStorageBufferRange`.
    fn queue_fits(&self, what: &str, bytes: u64) -> Result<(), GpuError> {
        let i = self.info();
        if bytes > i.max_storage_buffer_range {
            return Err(GpuError::Limits(format!(
                "the wavefront kernel's {what} need {}, over {}'s maxStorageBufferRange of {}: \
                 use a smaller --tile (a tile's rays are queued together) or --kernel mega",
                mib(bytes),
                i.name,
                mib(i.max_storage_buffer_range)
            )));
        }
        Ok(())
    }

    fn queues(&self, rays: u64, nodes: u64, feelers: u64) -> Result<Queues, GpuError> {
        self.queue_fits("queued rays", 2 * rays * RAY)?;
        self.queue_fits("ray tree nodes", nodes * NODE)?;
        self.queue_fits("shadow feelers", feelers * FEELER)?;
        let ctx = &self.ctx;
        Ok(Queues {
            rays: Buffer::device(ctx, "wavefront rays", 2 * rays * RAY)?,
            nodes: Buffer::device(ctx, "wavefront nodes", nodes * NODE)?,
            hits: Buffer::device(ctx, "wavefront hits", rays * HIT)?,
            feelers: Buffer::device(ctx, "wavefront feelers", feelers * FEELER)?,
            cap_rays: rays,
            cap_nodes: nodes,
            cap_feelers: feelers,
        })
    }

    /// Grows `q` to hold `rays` per half (keeping the `live` rays of half
    /// `half` and their hits), `nodes` nodes (keeping the first `keep`)
    /// and `feelers` feelers; each at least doubles when it grows. True
    /// when any grew (the kernels must be bound again).
    #[allow(clippy::too_many_arguments)]
    fn grow(
        &self,
        cmds: &Commands,
        q: &mut Queues,
        rays: u64,
        half: u64,
        live: u64,
        nodes: u64,
        keep: u64,
        feelers: u64,
    ) -> Result<bool, GpuError> {
        let grows = rays > q.cap_rays || nodes > q.cap_nodes || feelers > q.cap_feelers;
        if rays > q.cap_rays {
            let cap = rays.max(2 * q.cap_rays);
            self.queue_fits("queued rays", 2 * cap * RAY)?;
            let from = half * q.cap_rays * RAY;
            let to = half * cap * RAY;
            q.rays = q.rays.grown(
                cmds,
                "wavefront rays",
                2 * cap * RAY,
                &[(from, to, live * RAY)],
            )?;
            q.hits = q
                .hits
                .grown(cmds, "wavefront hits", cap * HIT, &[(0, 0, live * HIT)])?;
            log::debug!("wavefront: ray queues grown to {cap} rays");
            q.cap_rays = cap;
        }
        if nodes > q.cap_nodes {
            let cap = nodes.max(2 * q.cap_nodes);
            self.queue_fits("ray tree nodes", cap * NODE)?;
            q.nodes = q
                .nodes
                .grown(cmds, "wavefront nodes", cap * NODE, &[(0, 0, keep * NODE)])?;
            log::debug!("wavefront: tree nodes grown to {cap}");
            q.cap_nodes = cap;
        }
        if feelers > q.cap_feelers {
            let cap = feelers.max(2 * q.cap_feelers);
            self.queue_fits("shadow feelers", cap * FEELER)?;
            q.feelers = Buffer::device(&self.ctx, "wavefront feelers", cap * FEELER)?;
            log::debug!("wavefront: feeler queue grown to {cap}");
            q.cap_feelers = cap;
        }
        Ok(grows)
    }

    /// Workgroups for `n` items of `lanes` invocations each: a row, and
    /// more rows when one axis cannot hold them all. No items: none.
    fn item_groups(&self, n: u64, lanes: u32) -> Result<[u32; 3], GpuError> {
        if n == 0 {
            return Ok([0, 1, 1]);
        }
        let max = self.info().max_compute_work_group_count;
        let g = n.div_ceil(lanes as u64);
        let gx = g.min(max[0] as u64);
        let gy = g.div_ceil(gx);
        if gy > max[1] as u64 {
            return Err(GpuError::Limits(format!(
                "the wavefront kernel needs {g} workgroups in one dispatch, over what {} allows; \
                 use a smaller --tile",
                self.info().name
            )));
        }
        Ok([gx as u32, gy as u32, 1])
    }

    /// Renders with the wavefront kernel (`GpuOptions::kernel`); the
    /// same frame as `render_with`, by other dispatches.
    pub(super) fn render_wavefront(
        &self,
        packed: &Packed,
        opts: &GpuOptions,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Frame, GpuError> {
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        let lattice = self.lattice(packed, opts)?;
        let super::Lattice {
            lw,
            lh,
            corners,
            out_bytes,
            ..
        } = lattice;
        let g = &packed.globals;
        let mut phases = Phases::start();
        let [wx, wy] = opts.workgroup;
        let lanes = wx * wy;
        let [features, structure] = scene_spec(packed, opts);
        let spec = [(0, wx), (1, wy), features, structure];
        let binds = bindings();
        let kernels: Vec<Arc<Kernel>> = STAGES
            .iter()
            .map(|&(name, spirv)| {
                self.kernel(
                    name,
                    spirv,
                    &binds,
                    std::mem::size_of::<Push>() as u32,
                    &spec,
                )
            })
            .collect::<Result<_, _>>()?;
        phases.lap("pipeline");

        let cmds = Commands::new(&self.ctx)?;
        let scene = self.upload_scene(&cmds, packed, opts)?;
        let samples = Buffer::readback(&self.ctx, "samples", out_bytes)?;
        let counters = Buffer::readback(&self.ctx, "counters", super::COUNTERS_BYTES)?;
        let queue = Buffer::readback(&self.ctx, "wavefront queue lengths", 16)?;
        let spp = if corners { 1 } else { g.image[2] };
        let max_samples = dispatch::max_tile_samples(g.trace[0], g.counts[2], MAX_TILE_RAYS);
        let tiles = dispatch::tiles(lw, lh, opts.tile, spp, max_samples);
        let first = tiles
            .iter()
            .map(|t| t.w as u64 * t.h as u64 * spp as u64)
            .max()
            .unwrap_or(1);
        let lights = (g.counts[2] as u64).max(1);
        let mut q = self.queues(first, 2 * first, first * lights.min(4))?;
        let bind_all = |q: &Queues| -> Result<(), GpuError> {
            let mut b = scene.bindings();
            b.extend([
                (7, &samples),
                (8, &counters),
                (9, &q.rays),
                (10, &q.nodes),
                (14, &q.hits),
                (15, &q.feelers),
                (16, &queue),
            ]);
            kernels.iter().try_for_each(|k| k.bind(&b))
        };
        bind_all(&q)?;
        phases.lap("upload");

        let mut stats = RayStats::default();
        let mut work = crate::trace::query::Work::default();
        let mut device_seconds: Option<f64> = None;
        // Device seconds per submission kind (STAGE_NAMES).
        let mut per_stage = [0.0f64; 5];
        // One submission: its stages; its device time is added (to the
        // total and to its kind's), its counters returned.
        let submit = |work_item: Work,
                      zero_queue: bool,
                      stages: &[(usize, Push, u64)],
                      device_seconds: &mut Option<f64>,
                      per_stage: &mut [f64; 5]|
         -> Result<(RayStats, crate::trace::query::Work), GpuError> {
            let groups: Vec<[u32; 3]> = stages
                .iter()
                .map(|s| self.item_groups(s.2, lanes))
                .collect::<Result<_, _>>()?;
            let list: Vec<Stage> = stages
                .iter()
                .zip(&groups)
                .map(|(s, gr)| Stage {
                    kernel: &kernels[s.0],
                    push: bytemuck::bytes_of(&s.1),
                    groups: *gr,
                })
                .collect();
            let mut zero = vec![&counters];
            if zero_queue {
                zero.push(&queue);
            }
            cmds.run_once(work_item, |d, cmd| cmds.record_stages(d, cmd, &zero, &list))?;
            if let Some(s) = cmds.elapsed()? {
                *device_seconds.get_or_insert(0.0) += s;
                per_stage[stage_kind(stages[0].0)] += s;
            }
            let (s, wk, cut) = super::read_counts(&counters)?;
            if cut > 0 {
                return Err(self.loops_cut(packed, cut, 1));
            }
            Ok((s, wk))
        };
        let mut add = |c: (RayStats, crate::trace::query::Work)| {
            stats.add(&c.0);
            work.add(&c.1);
        };

        if !kernels[GENERATE]
            .warmed
            .swap(true, std::sync::atomic::Ordering::SeqCst)
        {
            // Every stage once over no items: the driver compiles them now.
            let none: Vec<(usize, Push, u64)> = (0..STAGES.len())
                .map(|k| (k, Push::default(), lanes as u64))
                .collect();
            submit(Work::Warmup, true, &none, &mut None, &mut [0.0; 5])?;
        }
        phases.lap("warm-up");

        let t0 = Instant::now();
        let u = |x: u64| x as u32;
        for (k, t) in tiles.iter().enumerate() {
            let item = Work::Tile {
                index: k,
                count: tiles.len(),
            };
            let tile = [t.x0, t.y0, t.w, t.h];
            let points = t.w as u64 * t.h as u64;
            let eye = points * spp as u64;
            if self.grow(&cmds, &mut q, eye, 0, 0, eye, 0, 0)? {
                bind_all(&q)?;
            }
            let push = |range: [u64; 4], cap: [u64; 2]| -> Push {
                [
                    tile[0],
                    tile[1],
                    tile[2],
                    tile[3],
                    u(range[0]),
                    u(range[1]),
                    u(range[2]),
                    u(range[3]),
                    u(cap[0]),
                    u(cap[1]),
                    0,
                    0,
                ]
            };
            let s = [(GENERATE, push([eye, 0, 0, 0], [0, 0]), eye)];
            add(submit(
                item,
                false,
                &s,
                &mut device_seconds,
                &mut per_stage,
            )?);
            // The queue of depth `depth`: n rays in half `half`, nodes from
            // base.
            let (mut base, mut n, mut half) = (0u64, eye, 0u64);
            while n > 0 {
                let at = |q: &Queues, h: u64| h * q.cap_rays;
                let p = push([n, at(&q, half), base, 0], [0, 0]);
                add(submit(
                    item,
                    false,
                    &[(EXTEND, p, n)],
                    &mut device_seconds,
                    &mut per_stage,
                )?);
                let (kids, feelers) = loop {
                    let room = q.cap_rays.min(q.cap_nodes - (base + n));
                    let p = push(
                        [n, at(&q, half), base, at(&q, 1 - half)],
                        [room, q.cap_feelers],
                    );
                    let counts = submit(
                        item,
                        true,
                        &[(SHADE, p, n)],
                        &mut device_seconds,
                        &mut per_stage,
                    )?;
                    let l: [u32; 4] = bytemuck::pod_read_unaligned(queue.read(16)?);
                    let (kids, feelers) = (l[0] as u64, l[1] as u64);
                    if kids <= room && feelers <= q.cap_feelers {
                        add(counts);
                        break (kids, feelers);
                    }
                    // Overflow: nothing past the room was written. Grow,
                    // keeping this depth's rays and hits and the nodes
                    // before it, and shade again.
                    let nodes = base + n + kids;
                    self.grow(&cmds, &mut q, kids.max(n), half, n, nodes, base, feelers)?;
                    bind_all(&q)?;
                };
                let p = push([feelers, 0, 0, 0], [0, 0]);
                let c = push([n, at(&q, half), base, 0], [0, 0]);
                let stages = [(SHADOW, p, feelers), (COMBINE, c, n)];
                add(submit(
                    item,
                    false,
                    &stages,
                    &mut device_seconds,
                    &mut per_stage,
                )?);
                base += n;
                n = kids;
                half = 1 - half;
            }
            let p = push([points, 0, 0, 0], [0, 0]);
            add(submit(
                item,
                false,
                &[(RESOLVE, p, points)],
                &mut device_seconds,
                &mut per_stage,
            )?);
            progress(k as u64 + 1, tiles.len() as u64);
        }
        phases.lap("dispatch");
        let frame = Frame {
            stats,
            work,
            device_seconds,
            device_stages: if device_seconds.is_some() {
                STAGE_NAMES.iter().copied().zip(per_stage).collect()
            } else {
                Vec::new()
            },
            ..Frame::default()
        };
        read_back(frame, &samples, &lattice, t0, phases)
    }
}
