//! Command buffers, fences and timestamps; the tiled render dispatch.
//!
//! The sample lattice is cut into tiles; each tile is one submission
//! (zero the counters, dispatch, read them back), so no submission runs
//! long enough to trip a driver watchdog and 32-bit counters cannot wrap.
//! Every fence is waited for with the fence timeout (docs/gpu.md, "Device
//! faults").

use super::context::{Context, VkCheck};
use super::memory::Buffer;
use super::pipeline::Kernel;
use super::{Fault, GpuError};
use ash::vk;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// After a fence wait times out, how much longer to wait (at most) for the
/// submission to end before its handles are given up as in use forever.
const GRACE: Duration = Duration::from_secs(5);

/// What a submission does: names it in messages, and picks its timeout
/// and whether an injected fault hits it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Work<'a> {
    /// A staging copy of the named scene array.
    Upload(&'a str),
    /// The empty dispatch after which a driver that compiles a pipeline at
    /// its first use (llvmpipe) has done so. How long a compile takes is
    /// not the tiles' to bound, so this waits at least
    /// `DEFAULT_FENCE_TIMEOUT` whatever the fence timeout.
    Warmup,
    /// Tile `index` (from 0) of `count`.
    Tile { index: usize, count: usize },
    /// A probe kernel's dispatch.
    Probe,
}

impl std::fmt::Display for Work<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Work::Upload(name) => write!(f, "the upload of {name}"),
            Work::Warmup => write!(f, "the pipeline warm-up"),
            Work::Tile { index, count } => write!(f, "tile {} of {count}", index + 1),
            Work::Probe => write!(f, "the probe dispatch"),
        }
    }
}

/// One dispatch of a submission (`Commands::record_stages`).
pub struct Stage<'a> {
    pub kernel: &'a Kernel,
    /// The push constants (`kernel.push_size` bytes).
    pub push: &'a [u8],
    pub groups: [u32; 3],
}

/// One command pool, one primary command buffer, a fence and (when the
/// queue has timestamps) a two-entry query pool.
pub struct Commands {
    ctx: Arc<Context>,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    queries: vk::QueryPool,
    /// `Fault::FenceNeverSignals`: the event the first dispatch waits on.
    hang: vk::Event,
    /// Tile and probe dispatches submitted so far.
    dispatches: AtomicU32,
}

impl Commands {
    pub fn new(ctx: &Arc<Context>) -> Result<Self, GpuError> {
        let d = &ctx.device;
        let mut c = Commands {
            ctx: ctx.clone(),
            pool: vk::CommandPool::null(),
            cmd: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            queries: vk::QueryPool::null(),
            hang: vk::Event::null(),
            dispatches: AtomicU32::new(0),
        };
        // SAFETY: valid create infos on a live device; each handle is stored
        // at once so Drop releases it on an early return.
        unsafe {
            c.pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(ctx.info.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .vk("vkCreateCommandPool")?;
            c.cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(c.pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .vk("vkAllocateCommandBuffers")?[0];
            c.fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .vk("vkCreateFence")?;
            if ctx.info.timestamps {
                c.queries = d
                    .create_query_pool(
                        &vk::QueryPoolCreateInfo::default()
                            .query_type(vk::QueryType::TIMESTAMP)
                            .query_count(2),
                        None,
                    )
                    .vk("vkCreateQueryPool")?;
            }
            if ctx.injects(Fault::FenceNeverSignals) {
                c.hang = d
                    .create_event(&vk::EventCreateInfo::default(), None)
                    .vk("vkCreateEvent")?;
            }
        }
        Ok(c)
    }

    /// Waits for the fence at most `t`.
    fn wait(&self, t: Duration) -> Result<(), vk::Result> {
        let ns = u64::try_from(t.as_nanos()).unwrap_or(u64::MAX);
        // SAFETY: the fence is live and belongs to this device.
        unsafe { self.ctx.device.wait_for_fences(&[self.fence], true, ns) }
    }

    /// Records `f` into the command buffer, submits it and waits for it
    /// at most the fence timeout (see `Work::Warmup`). After a timeout the
    /// work is given `GRACE` more to end; if it does not, the device is
    /// marked hung and no handle of it is destroyed again. Injected
    /// faults (`Fault::DeviceLost`, `Fault::FenceNeverSignals`) hit the
    /// first tile or probe dispatch.
    pub fn run_once(
        &self,
        work: Work,
        f: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<(), GpuError> {
        let d = &self.ctx.device;
        let first = matches!(work, Work::Tile { .. } | Work::Probe)
            && self.dispatches.fetch_add(1, Ordering::SeqCst) == 0;
        let hang = first && self.hang != vk::Event::null();
        // SAFETY: the command buffer is idle (the previous submission was
        // waited for) and is recorded and submitted here; the event (if
        // any) is unsignalled, and only the host sets it.
        unsafe {
            d.reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())
                .vk("vkResetCommandBuffer")?;
            d.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .vk("vkBeginCommandBuffer")?;
            if hang {
                // Fault::FenceNeverSignals: everything after this waits for
                // the host, which sets the event only once the fence wait
                // below has timed out.
                d.cmd_wait_events(
                    self.cmd,
                    &[self.hang],
                    vk::PipelineStageFlags::HOST,
                    vk::PipelineStageFlags::ALL_COMMANDS,
                    &[],
                    &[],
                    &[],
                );
            }
            f(d, self.cmd);
            d.end_command_buffer(self.cmd).vk("vkEndCommandBuffer")?;
            let cmds = [self.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            d.reset_fences(&[self.fence]).vk("vkResetFences")?;
            d.queue_submit(self.ctx.queue, &submit, self.fence)
                .vk("vkQueueSubmit")?;
        }
        let mut timeout = self.ctx.settings.fence_timeout;
        if work == Work::Warmup {
            timeout = timeout.max(super::DEFAULT_FENCE_TIMEOUT);
        }
        match self.wait(timeout) {
            // Fault::DeviceLost: the wait's result as a lost device gives it.
            Ok(()) if first && self.ctx.injects(Fault::DeviceLost) => {
                Err::<(), _>(vk::Result::ERROR_DEVICE_LOST).vk("vkWaitForFences")
            }
            Ok(()) => Ok(()),
            Err(vk::Result::TIMEOUT) => {
                if hang {
                    // The injected hang ends late, as a slow device would.
                    // SAFETY: a host-settable event of this device.
                    unsafe { d.set_event(self.hang) }.vk("vkSetEvent")?;
                }
                match self.wait(timeout.min(GRACE)) {
                    Ok(()) => log::debug!(
                        "{}: {work} finished after the fence timeout",
                        self.ctx.info.name
                    ),
                    Err(r) => {
                        self.ctx.hung.store(true, Ordering::SeqCst);
                        log::error!(
                            "{}: {work} never finished (vkWaitForFences: {r}); its Vulkan \
                             objects are left for the process exit to free",
                            self.ctx.info.name
                        );
                    }
                }
                Err(GpuError::Timeout {
                    device: self.ctx.info.name.clone(),
                    what: work.to_string(),
                    timeout,
                })
            }
            Err(result) => Err(result).vk("vkWaitForFences"),
        }
    }

    /// Records a compute dispatch of `groups` between two timestamps:
    /// zero `counters`, barrier, dispatch, barrier to host reads.
    pub fn record_dispatch(
        &self,
        d: &ash::Device,
        cmd: vk::CommandBuffer,
        kernel: &Kernel,
        push: &[u8],
        groups: [u32; 3],
        counters: Option<&Buffer>,
    ) {
        let zero: Vec<&Buffer> = counters.into_iter().collect();
        self.record_stages(
            d,
            cmd,
            &zero,
            &[Stage {
                kernel,
                push,
                groups,
            }],
        );
    }

    /// Records `stages` in order between two timestamps: zero every buffer
    /// of `zero`, then each stage after a barrier that makes what came
    /// before it visible (a stage with no workgroups is left out), and
    /// last a barrier to host reads.
    pub fn record_stages(
        &self,
        d: &ash::Device,
        cmd: vk::CommandBuffer,
        zero: &[&Buffer],
        stages: &[Stage],
    ) {
        let timed = self.queries != vk::QueryPool::null();
        let compute_barrier = |src: vk::AccessFlags, src_stage: vk::PipelineStageFlags| {
            let b = [vk::MemoryBarrier::default()
                .src_access_mask(src)
                .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)];
            // SAFETY: a global barrier in a recording command buffer.
            unsafe {
                d.cmd_pipeline_barrier(
                    cmd,
                    src_stage,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::DependencyFlags::empty(),
                    &b,
                    &[],
                    &[],
                )
            };
        };
        // SAFETY: `cmd` is recording; every handle is live and owned by
        // this device; the barriers order the fills before the first
        // shader, each shader before the next, and the last before the
        // host's reads after the fence.
        unsafe {
            if timed {
                d.cmd_reset_query_pool(cmd, self.queries, 0, 2);
            }
            for c in zero {
                d.cmd_fill_buffer(cmd, c.buffer, 0, vk::WHOLE_SIZE, 0);
            }
            if !zero.is_empty() {
                compute_barrier(
                    vk::AccessFlags::TRANSFER_WRITE,
                    vk::PipelineStageFlags::TRANSFER,
                );
            }
            if timed {
                d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, self.queries, 0);
            }
            let mut first = true;
            for s in stages {
                debug_assert_eq!(s.push.len() as u32, s.kernel.push_size);
                if s.groups.contains(&0) {
                    continue;
                }
                if !first {
                    compute_barrier(
                        vk::AccessFlags::SHADER_WRITE,
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                    );
                }
                first = false;
                let k = s.kernel;
                d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, k.pipeline);
                d.cmd_bind_descriptor_sets(
                    cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    k.layout,
                    0,
                    &[k.set],
                    &[],
                );
                if !s.push.is_empty() {
                    d.cmd_push_constants(cmd, k.layout, vk::ShaderStageFlags::COMPUTE, 0, s.push);
                }
                d.cmd_dispatch(cmd, s.groups[0], s.groups[1], s.groups[2]);
            }
            if timed {
                d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.queries, 1);
            }
            let b = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &b,
                &[],
                &[],
            );
        }
    }

    /// Seconds between the two timestamps of the last dispatch, if the
    /// queue has timestamps.
    pub fn elapsed(&self) -> Result<Option<f64>, GpuError> {
        if self.queries == vk::QueryPool::null() {
            return Ok(None);
        }
        let mut t = [0u64; 2];
        // SAFETY: both queries were written by the submission just waited for.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.queries,
                0,
                &mut t,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        let mask = self.ctx.info.timestamp_mask;
        let ticks = (t[1] & mask).wrapping_sub(t[0] & mask) & mask;
        Ok(Some(
            ticks as f64 * self.ctx.info.timestamp_period_ns as f64 * 1e-9,
        ))
    }
}

impl Drop for Commands {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return;
        }
        // SAFETY: every submission was waited for (or the device is lost,
        // where destroying is allowed); the pool frees its command buffer;
        // null handles are ignored.
        unsafe {
            let d = &self.ctx.device;
            d.destroy_event(self.hang, None);
            d.destroy_query_pool(self.queries, None);
            d.destroy_fence(self.fence, None);
            d.destroy_command_pool(self.pool, None);
        }
    }
}

/// One rectangle of the sample lattice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
}

/// Cuts a `lw × lh` lattice into tiles of at most `tile × tile` samples,
/// row by row; tiles shrink (rows first, then width) so one tile traces at
/// most `max_samples` eye rays (each pixel of a centre lattice traces
/// `spp`), or one row of one pixel where a single pixel's samples exceed it.
pub fn tiles(lw: u32, lh: u32, tile: u32, spp: u32, max_samples: u64) -> Vec<Tile> {
    let spp = spp.max(1) as u64;
    let width_cap = (max_samples / spp).max(1);
    let tw = (tile.clamp(1, lw.max(1)) as u64).min(width_cap) as u32;
    let rows_cap = (max_samples / (tw as u64 * spp)).max(1);
    let th = (tile as u64).min(rows_cap).clamp(1, lh.max(1) as u64) as u32;
    let mut out = Vec::new();
    let mut y = 0;
    while y < lh {
        let h = th.min(lh - y);
        let mut x = 0;
        while x < lw {
            let w = tw.min(lw - x);
            out.push(Tile { x0: x, y0: y, w, h });
            x += w;
        }
        y += h;
    }
    out
}

/// Most eye rays one tile may trace so that none of the shader's 32-bit
/// ray counters can wrap within it: an eye ray's tree has at most
/// 2^(depth+1) − 1 rays, each casting at most one feeler per light, so a
/// sample adds at most (2^(depth+1) − 1) · max(lights, 1) to a counter.
/// Never more than `cap` (keeps submissions short), never less than 1.
pub fn max_tile_samples(max_depth: u32, lights: u32, cap: u64) -> u64 {
    let tree = (1u64 << (max_depth.min(62) + 1)) - 1;
    let per_sample = tree.saturating_mul(lights.max(1) as u64);
    (u32::MAX as u64 / per_sample).clamp(1, cap.max(1))
}

/// The order in which a dispatch of `n` workgroups visits its tile:
/// workgroup k (in the order the driver hands them out) renders group
/// (k · stride) mod n. A CPU driver (lavapipe) gives each of its threads
/// one contiguous block of workgroups, so in plain order one thread gets
/// the sky and idles while another gets the objects; a stride near the
/// golden section of n spreads every block over the whole tile. The
/// stride is coprime to n (so the map is a permutation) and at most
/// 65 535 (so the shader's 32-bit product cannot wrap); 1 is the plain
/// order, which a GPU's own scheduler needs no help with.
pub fn scatter_stride(n: u32) -> u32 {
    if n <= 2 || n > 65_536 {
        return 1;
    }
    let mut s = ((n as f64 * 0.618_033_988_75) as u32).max(1);
    while gcd(s, n) != 1 {
        s += 1;
    }
    s
}

fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scatter_is_a_permutation_that_spreads_each_half() {
        for n in (1..=600).chain([1024, 4096, 65_535, 65_536, 65_537, 1 << 20]) {
            let s = scatter_stride(n);
            let mut seen = vec![false; n as usize];
            for k in 0..n as u64 {
                let p = (k * s as u64 % n as u64) as usize;
                assert!(!seen[p], "n {n} stride {s}: {p} twice");
                seen[p] = true;
                // What the shader computes must not wrap in 32 bits.
                assert!(k * (s as u64) < 1 << 32 || s == 1);
            }
            if (64..=65_536).contains(&n) {
                // The first half of the workgroups covers both halves of
                // the tile about equally.
                let low = (0..n / 2).filter(|&k| (k as u64 * s as u64 % n as u64) < n as u64 / 2);
                let frac = low.count() as f64 / (n / 2) as f64;
                assert!((0.35..0.65).contains(&frac), "n {n} stride {s}: {frac}");
            }
        }
    }

    #[test]
    fn tiles_cover_the_lattice_once() {
        for &(lw, lh, t, spp) in &[
            (1, 1, 64, 1),
            (65, 33, 16, 1),
            (640, 480, 256, 64),
            (7, 300, 5, 3),
        ] {
            let ts = tiles(lw, lh, t, spp, 1 << 16);
            let mut seen = vec![0u8; (lw * lh) as usize];
            for tl in &ts {
                assert!(tl.w >= 1 && tl.h >= 1 && tl.w <= t && tl.h <= t);
                assert!(tl.w as u64 * tl.h as u64 * spp as u64 <= (1 << 16));
                for y in tl.y0..tl.y0 + tl.h {
                    for x in tl.x0..tl.x0 + tl.w {
                        seen[(y * lw + x) as usize] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&s| s == 1), "{lw}x{lh} tile {t}");
        }
    }

    /// At the options' limits no tile traces more eye rays than asked,
    /// and the tile count is exact in 64 bits.
    #[test]
    fn tiles_at_the_limits_of_the_options() {
        // 4096 spp, --tile 16384: the width shrinks too (256 × 4096 = 2^20).
        let ts = tiles(65536, 2, 16384, 4096, 1 << 20);
        assert!(ts.iter().all(|t| t.w as u64 * t.h as u64 * 4096 <= 1 << 20));
        assert_eq!(ts.len(), 65536 / 256 * 2);
        // a single pixel's samples over the cap: one pixel per tile
        let ts = tiles(3, 2, 256, 4096, 1000);
        assert_eq!(ts.len(), 6);
        assert!(ts.iter().all(|t| t.w == 1 && t.h == 1));
        // the largest corner lattice in default tiles
        let n = 65537u64.div_ceil(256);
        let ts = tiles(65537, 65537, 256, 1, 1 << 20);
        assert_eq!(ts.len() as u64, n * n);
        let covered: u64 = ts.iter().map(|t| t.w as u64 * t.h as u64).sum();
        assert_eq!(covered, 65537 * 65537);
    }

    #[test]
    fn tile_samples_keep_counters_from_wrapping() {
        for depth in 0..=crate::constants::MAX_DEPTH_LIMIT {
            for lights in [0u32, 1, 3, 8, 1000, 100_000, u32::MAX] {
                let m = max_tile_samples(depth, lights, 1 << 20);
                assert!((1..=1 << 20).contains(&m));
                let per = ((1u64 << (depth + 1)) - 1) * lights.max(1) as u64;
                // m samples cannot wrap, unless one sample alone could
                assert!(m as u128 * per as u128 <= u32::MAX as u128 || m == 1);
            }
        }
        // the defaults (depth 5, a few lights) keep the full cap
        assert_eq!(max_tile_samples(5, 3, 1 << 20), 1 << 20);
        assert_eq!(
            max_tile_samples(16, 8, 1 << 20),
            u32::MAX as u64 / (131_071 * 8)
        );
    }
}
