//! Compute kernels: shader module, specialization constants, descriptor set
//! layout, pool and set (all storage buffers, set 0), push constants, and
//! the pipeline cache persisted under the user's cache directory.

use super::context::{Context, VkCheck};
use super::memory::Buffer;
use super::GpuError;
use ash::vk;
use std::path::PathBuf;
use std::sync::Arc;

/// One compute pipeline with its layout and a single descriptor set.
pub struct Kernel {
    ctx: Arc<Context>,
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub(crate) set: vk::DescriptorSet,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
    bindings: Vec<u32>,
    pub(crate) push_size: u32,
    /// Some drivers (llvmpipe) compile a pipeline at its first dispatch;
    /// `Gpu` makes an empty one first so render timings exclude it.
    pub(crate) warmed: std::sync::atomic::AtomicBool,
}

impl Kernel {
    /// `spirv`: the module (bytes, as embedded); `bindings`: the storage
    /// buffer bindings of set 0; `push_size`: bytes of the push constant
    /// block; `spec`: (constant id, u32 value) pairs.
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        spirv: &[u8],
        bindings: &[u32],
        push_size: u32,
        spec: &[(u32, u32)],
    ) -> Result<Self, GpuError> {
        let code = ash::util::read_spv(&mut std::io::Cursor::new(spirv))
            .map_err(|e| GpuError::Shader(format!("{name}.spv: {e}")))?;
        let d = &ctx.device;
        let lb: Vec<_> = bindings
            .iter()
            .map(|&b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let mut k = Kernel {
            ctx: ctx.clone(),
            set_layout: vk::DescriptorSetLayout::null(),
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            bindings: bindings.to_vec(),
            push_size,
            warmed: Default::default(),
        };
        // Each step stores its handle in `k` at once, so an early return
        // drops `k` and destroys whatever was made.
        // SAFETY: valid create infos on a live device (this whole block).
        unsafe {
            k.set_layout = d
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&lb),
                    None,
                )
                .vk("vkCreateDescriptorSetLayout")?;
            let sizes = [vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(bindings.len() as u32)];
            k.pool = d
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(1)
                        .pool_sizes(&sizes),
                    None,
                )
                .vk("vkCreateDescriptorPool")?;
            let layouts = [k.set_layout];
            k.set = d
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(k.pool)
                        .set_layouts(&layouts),
                )
                .vk("vkAllocateDescriptorSets")?[0];
            let ranges = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
                .offset(0)
                .size(push_size)];
            let mut pli = vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts);
            if push_size > 0 {
                pli = pli.push_constant_ranges(&ranges);
            }
            k.layout = d
                .create_pipeline_layout(&pli, None)
                .vk("vkCreatePipelineLayout")?;
            let module = d
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None)
                .vk("vkCreateShaderModule")?;
            let entries: Vec<_> = spec
                .iter()
                .enumerate()
                .map(|(i, &(id, _))| vk::SpecializationMapEntry {
                    constant_id: id,
                    offset: (i * 4) as u32,
                    size: 4,
                })
                .collect();
            let data: Vec<u8> = spec.iter().flat_map(|&(_, v)| v.to_ne_bytes()).collect();
            let si = vk::SpecializationInfo::default()
                .map_entries(&entries)
                .data(&data);
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main")
                .specialization_info(&si);
            let ci = [vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(k.layout)];
            let cache = PipelineCache::open(ctx);
            let r = d.create_compute_pipelines(cache.handle, &ci, None);
            d.destroy_shader_module(module, None);
            cache.save();
            k.pipeline = r.map_err(|(_, result)| GpuError::Vulkan {
                call: "vkCreateComputePipelines",
                result,
            })?[0];
        }
        Ok(k)
    }

    /// Points binding `b` of the set at each buffer (whole range).
    pub fn bind(&self, buffers: &[(u32, &Buffer)]) -> Result<(), GpuError> {
        for (b, _) in buffers {
            if !self.bindings.contains(b) {
                return Err(GpuError::Internal(format!("kernel has no binding {b}")));
            }
        }
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|(_, buf)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(buf.buffer)
                    .offset(0)
                    .range(vk::WHOLE_SIZE)]
            })
            .collect();
        let writes: Vec<_> = buffers
            .iter()
            .zip(&infos)
            .map(|((b, _), info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(*b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: the set is not in use by pending work (every submission is
        // waited for) and the buffers are live.
        unsafe { self.ctx.device.update_descriptor_sets(&writes, &[]) };
        Ok(())
    }
}

impl Drop for Kernel {
    fn drop(&mut self) {
        // SAFETY: no pending work uses the pipeline (submissions are waited
        // for); reverse order of creation; null handles are ignored.
        unsafe {
            let d = &self.ctx.device;
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_pool(self.pool, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A `VkPipelineCache` loaded from and saved to
/// `$XDG_CACHE_HOME/whitted` (or `~/.cache/whitted`), one file per device.
/// Every failure (no cache dir, unreadable, stale, unwritable) just means
/// no cache.
struct PipelineCache<'a> {
    ctx: &'a Context,
    handle: vk::PipelineCache,
    path: Option<PathBuf>,
}

/// Where pipeline caches live.
pub fn cache_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("XDG_CACHE_HOME") {
        Some(x) if !x.is_empty() => PathBuf::from(x),
        _ => PathBuf::from(std::env::var_os("HOME")?).join(".cache"),
    };
    Some(base.join("whitted"))
}

impl<'a> PipelineCache<'a> {
    fn open(ctx: &'a Context) -> Self {
        let i = &ctx.info;
        let path = cache_dir().map(|d| {
            d.join(format!(
                "pipelines-{:04x}-{:04x}.bin",
                i.vendor_id, i.device_id
            ))
        });
        // Hand the driver only data whose header names this very device and
        // driver build (VkPipelineCacheHeaderVersionOne).
        let data = path
            .as_ref()
            .and_then(|p| std::fs::read(p).ok())
            .filter(|b| {
                b.len() >= 32
                    && u32::from_le_bytes(b[4..8].try_into().unwrap()) == 1
                    && u32::from_le_bytes(b[8..12].try_into().unwrap()) == i.vendor_id
                    && u32::from_le_bytes(b[12..16].try_into().unwrap()) == i.device_id
                    && b[16..32] == i.pipeline_cache_uuid
            })
            .unwrap_or_default();
        let ci = vk::PipelineCacheCreateInfo::default().initial_data(&data);
        // SAFETY: the initial data's header was checked against this device.
        let handle = unsafe { ctx.device.create_pipeline_cache(&ci, None) }
            .unwrap_or(vk::PipelineCache::null());
        PipelineCache { ctx, handle, path }
    }

    fn save(&self) {
        if self.handle == vk::PipelineCache::null() {
            return;
        }
        let Some(path) = &self.path else { return };
        // SAFETY: a live cache on a live device.
        let Ok(data) = (unsafe { self.ctx.device.get_pipeline_cache_data(self.handle) }) else {
            return;
        };
        if data.len() <= 32 {
            return;
        }
        let Some(dir) = path.parent() else { return };
        if std::fs::create_dir_all(dir).is_err() {
            return;
        }
        // Written atomically: concurrent processes never see half a file.
        if let Ok(mut tmp) = tempfile::NamedTempFile::new_in(dir) {
            if std::io::Write::write_all(&mut tmp, &data).is_ok() {
                let _ = tmp.persist(path);
            }
        }
    }
}

impl Drop for PipelineCache<'_> {
    fn drop(&mut self) {
        // SAFETY: pipeline creation with this cache has returned.
        unsafe { self.ctx.device.destroy_pipeline_cache(self.handle, None) };
    }
}
