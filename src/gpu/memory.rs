//! Buffers through gpu-allocator: scene upload (mapped directly when the
//! device-local memory is host-visible and coherent, through a staging
//! buffer otherwise), and host-visible output buffers for readback.

use super::context::{Context, VkCheck};
use super::dispatch::{Commands, Work};
use super::{Fault, GpuError};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::{AllocationError, MemoryLocation};
use std::sync::Arc;

/// Smallest buffer made: an empty array still binds a valid buffer.
pub const MIN_BUFFER: u64 = 16;

/// `size` for a message: bytes, KiB, MiB or GiB.
fn bytes(size: u64) -> String {
    match size {
        0..1024 => format!("{size} bytes"),
        1024..0x10_0000 => format!("{:.1} KiB", size as f64 / 1024.0),
        0x10_0000..0x4000_0000 => super::mib(size),
        _ => format!("{:.2} GiB", size as f64 / (1u64 << 30) as f64),
    }
}

/// One `VkBuffer` and its memory.
pub struct Buffer {
    ctx: Arc<Context>,
    pub(crate) buffer: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
    /// A view of the buffer as texels (R32G32B32A32_UINT or R32_UINT), for
    /// the shaders' texel-buffer bindings (`texel_binding` in mod.rs);
    /// null until `add_texel_view`.
    pub(crate) view: vk::BufferView,
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
        // The injected memory faults hit the first readback buffer (the
        // output), after the scene's buffers exist, so that their cleanup
        // runs too.
        let readback = location == MemoryLocation::GpuToCpu;
        let created = if readback && ctx.injects(Fault::OutOfHostMemory) {
            Err(vk::Result::ERROR_OUT_OF_HOST_MEMORY)
        } else {
            // SAFETY: valid create info on a live device.
            unsafe { d.create_buffer(&info, None) }
        };
        let buffer = created.vk("vkCreateBuffer")?;
        // SAFETY: `buffer` was just created on this device.
        let requirements = unsafe { d.get_buffer_memory_requirements(buffer) };
        let alloc = if readback && ctx.injects(Fault::OutOfDeviceMemory) {
            Err(AllocationError::OutOfMemory)
        } else {
            ctx.allocator
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
        };
        let allocation = match alloc {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer is unused and unbound.
                unsafe { d.destroy_buffer(buffer, None) };
                let what = format!("{name} ({})", bytes(size));
                return Err(match e {
                    AllocationError::OutOfMemory => GpuError::OutOfDeviceMemory {
                        device: ctx.info.name.clone(),
                        what,
                    },
                    e => GpuError::Memory {
                        what,
                        msg: e.to_string(),
                    },
                });
            }
        };
        let me = Buffer {
            ctx: ctx.clone(),
            buffer,
            allocation: Some(allocation),
            size,
            view: vk::BufferView::null(),
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
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST,
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
        let region = [vk::BufferCopy::default().size(data.len() as u64)];
        cmds.run_once(Work::Upload(name), |d, cmd| {
            record_copy(
                d,
                cmd,
                &staging,
                &buf,
                &region,
                vk::AccessFlags::SHADER_READ,
            )
        })?;
        Ok(buf)
    }

    /// Makes `view`: the buffer as texels of `format` (R32G32B32A32_UINT
    /// or R32_UINT), at most `max_texels` of them (maxTexelBufferElements:
    /// a longer array is read as a storage buffer, `GpuReads::fitting`,
    /// and its view only keeps the binding valid). Only for buffers made
    /// by `upload`.
    pub fn add_texel_view(&mut self, format: vk::Format, max_texels: u64) -> Result<(), GpuError> {
        let texel = if format == vk::Format::R32_UINT {
            4
        } else {
            16
        };
        let range = (self.size / texel).min(max_texels).max(1) * texel;
        let info = vk::BufferViewCreateInfo::default()
            .buffer(self.buffer)
            .format(format)
            .offset(0)
            .range(range);
        // SAFETY: the buffer is live and was made with UNIFORM_TEXEL_BUFFER
        // usage (`upload`); the range lies inside it (its size is a
        // multiple of 16 and at least 16) and holds at most `max_texels`.
        self.view =
            unsafe { self.ctx.device.create_buffer_view(&info, None) }.vk("vkCreateBufferView")?;
        Ok(())
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

    /// A device-local storage buffer the shaders alone read and write
    /// (the wavefront kernel's queues), which may be copied from and to.
    pub fn device(ctx: &Arc<Context>, name: &str, size: u64) -> Result<Self, GpuError> {
        Buffer::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )
    }

    /// A larger `device` buffer of `size` bytes holding `regions` of this
    /// one, each (from, to, bytes), copied on the device.
    pub fn grown(
        &self,
        cmds: &Commands,
        name: &str,
        size: u64,
        regions: &[(u64, u64, u64)],
    ) -> Result<Self, GpuError> {
        let new = Buffer::device(&self.ctx, name, size)?;
        let copies: Vec<vk::BufferCopy> = regions
            .iter()
            .filter(|r| r.2 > 0)
            .map(|&(from, to, bytes)| {
                vk::BufferCopy::default()
                    .src_offset(from)
                    .dst_offset(to)
                    .size(bytes)
            })
            .collect();
        if copies.is_empty() {
            return Ok(new);
        }
        cmds.run_once(Work::Upload(name), |d, cmd| {
            record_copy(
                d,
                cmd,
                self,
                &new,
                &copies,
                vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
            )
        })?;
        Ok(new)
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
        if self.ctx.is_hung() {
            // A submission that may use it never ended: leak it.
            std::mem::forget(self.allocation.take());
            return;
        }
        // SAFETY: every submission that used this buffer was waited for
        // (each submit waits on its fence); view, then buffer, then its
        // memory; a null view is ignored.
        unsafe {
            self.ctx.device.destroy_buffer_view(self.view, None);
            self.ctx.device.destroy_buffer(self.buffer, None)
        };
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

/// Records copies of `regions` from `src` to `dst`, then a barrier that
/// makes them visible to compute shaders with `access`. The caller keeps
/// both buffers live and idle until the submission ends, and every region
/// lies inside both.
fn record_copy(
    d: &ash::Device,
    cmd: vk::CommandBuffer,
    src: &Buffer,
    dst: &Buffer,
    regions: &[vk::BufferCopy],
    access: vk::AccessFlags,
) {
    // SAFETY: both buffers are live and not in use, the regions inside
    // both (the caller's contract), and `cmd` is recording.
    unsafe { d.cmd_copy_buffer(cmd, src.buffer, dst.buffer, regions) };
    let barrier = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(access)];
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
}

#[cfg(test)]
mod tests {
    #[test]
    fn sizes_read_in_the_right_unit() {
        assert_eq!(super::bytes(16), "16 bytes");
        assert_eq!(super::bytes(6912), "6.8 KiB");
        assert_eq!(super::bytes(3 << 20), "3.0 MiB");
        assert_eq!(super::bytes(5 << 30), "5.00 GiB");
    }
}
