//! Buffers through gpu-allocator: scene upload (mapped directly when the
//! device-local memory is host-visible and coherent, through a staging
//! buffer otherwise), and host-visible output buffers for readback.

use super::context::{Context, VkCheck};
use super::dispatch::Commands;
use super::GpuError;
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

/// Smallest buffer made: an empty array still binds a valid buffer.
pub const MIN_BUFFER: u64 = 16;

/// One `VkBuffer` and its memory.
pub struct Buffer {
    ctx: Arc<Context>,
    pub(crate) buffer: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
}

impl Buffer {
    /// A buffer of at least `size` bytes (rounded up to 16).
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self, GpuError> {
        let size = size.max(MIN_BUFFER).next_multiple_of(16);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let d = &ctx.device;
        // SAFETY: valid create info on a live device.
        let buffer = unsafe { d.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        // SAFETY: `buffer` was just created on this device.
        let requirements = unsafe { d.get_buffer_memory_requirements(buffer) };
        let alloc = ctx
            .allocator
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            });
        let allocation = match alloc {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer is unused and unbound.
                unsafe { d.destroy_buffer(buffer, None) };
                return Err(GpuError::Memory {
                    what: format!("{name} ({})", super::mib(size)),
                    msg: e.to_string(),
                });
            }
        };
        let me = Buffer {
            ctx: ctx.clone(),
            buffer,
            allocation: Some(allocation),
            size,
        };
        let a = me.allocation.as_ref().unwrap();
        // SAFETY: the allocation satisfies the buffer's requirements and is
        // bound once.
        unsafe { d.bind_buffer_memory(buffer, a.memory(), a.offset()) }.vk("vkBindBufferMemory")?;
        Ok(me)
    }

    /// The host's view of the memory when it is host-visible and coherent
    /// (no flush or invalidate needed).
    fn coherent_slice(&self) -> Option<&[u8]> {
        let a = self.allocation.as_ref()?;
        if !a
            .memory_properties()
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
        {
            return None;
        }
        a.mapped_slice()
    }

    fn coherent_slice_mut(&mut self) -> Option<&mut [u8]> {
        let a = self.allocation.as_mut()?;
        if !a
            .memory_properties()
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
        {
            return None;
        }
        a.mapped_slice_mut()
    }

    /// Writes `data` at the start of a host-visible buffer.
    pub fn write(&mut self, data: &[u8]) -> Result<(), GpuError> {
        let s = self
            .coherent_slice_mut()
            .ok_or_else(|| GpuError::Internal("write to a buffer the host cannot see".into()))?;
        s[..data.len()].copy_from_slice(data);
        Ok(())
    }

    /// The first `len` bytes of a host-visible buffer (call after the
    /// fence of the work that wrote it, whose command buffer ends with a
    /// shader-write → host-read barrier).
    pub fn read(&self, len: usize) -> Result<&[u8], GpuError> {
        let s = self
            .coherent_slice()
            .ok_or_else(|| GpuError::Internal("read from a buffer the host cannot see".into()))?;
        Ok(&s[..len])
    }

    /// A device-local storage buffer holding `data`: written in place when
    /// the memory is host-visible (integrated GPUs, lavapipe, resizable
    /// BAR), copied from a staging buffer otherwise, or always with
    /// `staged` (so that lavapipe tests the path discrete GPUs take).
    pub fn upload(
        ctx: &Arc<Context>,
        cmds: &Commands,
        name: &str,
        data: &[u8],
        staged: bool,
    ) -> Result<Self, GpuError> {
        let mut buf = Buffer::new(
            ctx,
            name,
            data.len() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        if !staged {
            if let Some(s) = buf.coherent_slice_mut() {
                s[..data.len()].copy_from_slice(data);
                return Ok(buf);
            }
        }
        if data.is_empty() {
            return Ok(buf);
        }
        let mut staging = Buffer::new(
            ctx,
            &format!("{name} (staging)"),
            data.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        staging.write(data)?;
        let size = data.len() as u64;
        cmds.run_once(|d, cmd| {
            let region = [vk::BufferCopy::default().size(size)];
            // SAFETY: both buffers are live, large enough, and not in use.
            unsafe { d.cmd_copy_buffer(cmd, staging.buffer, buf.buffer, &region) };
            let barrier = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::SHADER_READ)];
            // SAFETY: a global barrier in a recording command buffer.
            unsafe {
                d.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::DependencyFlags::empty(),
                    &barrier,
                    &[],
                    &[],
                )
            };
        })?;
        Ok(buf)
    }

    /// A host-readable storage buffer the shader writes (output, counters).
    pub fn readback(ctx: &Arc<Context>, name: &str, size: u64) -> Result<Self, GpuError> {
        Buffer::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )
    }

    /// A host-written storage buffer the shader reads (probe inputs).
    pub fn host_input(ctx: &Arc<Context>, name: &str, data: &[u8]) -> Result<Self, GpuError> {
        let mut b = Buffer::new(
            ctx,
            name,
            data.len() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        b.write(data)?;
        Ok(b)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: every submission that used this buffer was waited for
        // (each submit waits on its fence); buffer before its memory.
        unsafe { self.ctx.device.destroy_buffer(self.buffer, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self
                .ctx
                .allocator
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .free(a);
        }
    }
}
