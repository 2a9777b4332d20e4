//! Compute kernels: shader module, specialization constants, descriptor set
//! layout, pool and set (set 0: storage buffers, uniform texel buffers from
//! binding 20 on), push constants, and
//! the pipeline cache persisted in a folder (`GpuOptions::pipeline_cache`;
//! by default under the user's cache directory).

use super::context::{Context, VkCheck};
use super::memory::Buffer;
use super::{Fault, GpuError};
use ash::vk;
use std::path::PathBuf;
use std::sync::Arc;

/// Bindings from 20 on are uniform texel buffers (`layout.glsl`: scene
/// arrays read as texels, `TEXELS`); the others storage buffers.
pub const FIRST_TEXEL_BINDING: u32 = 20;

fn is_texel(b: u32) -> bool {
    b >= FIRST_TEXEL_BINDING
}

fn descriptor_type(b: u32) -> vk::DescriptorType {
    if is_texel(b) {
        vk::DescriptorType::UNIFORM_TEXEL_BUFFER
    } else {
        vk::DescriptorType::STORAGE_BUFFER
    }
}

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
                    .descriptor_type(descriptor_type(b))
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
            let texels = bindings.iter().filter(|&&b| is_texel(b)).count() as u32;
            let sizes = [
                vk::DescriptorPoolSize::default()
                    .ty(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count((bindings.len() as u32 - texels).max(1)),
                vk::DescriptorPoolSize::default()
                    .ty(vk::DescriptorType::UNIFORM_TEXEL_BUFFER)
                    .descriptor_count(texels.max(1)),
            ];
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
            let cache = CacheFile::open(ctx);
            let r = if ctx.injects(Fault::PipelineRefused) {
                Err((vec![], vk::Result::ERROR_UNKNOWN))
            } else {
                d.create_compute_pipelines(cache.handle, &ci, None)
            };
            d.destroy_shader_module(module, None);
            k.pipeline = r.map_err(|(_, result)| match result {
                // Out of memory is the device's state, not the kernel's.
                vk::Result::ERROR_OUT_OF_HOST_MEMORY | vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => {
                    GpuError::Vulkan {
                        call: "vkCreateComputePipelines",
                        result,
                    }
                }
                result => GpuError::PipelineRefused {
                    device: ctx.info.name.clone(),
                    kernel: name.to_string(),
                    result,
                },
            })?[0];
            cache.save();
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
        for (b, buf) in buffers {
            if is_texel(*b) && buf.view == vk::BufferView::null() {
                return Err(GpuError::Internal(format!(
                    "binding {b} needs a texel view"
                )));
            }
        }
        let views: Vec<[vk::BufferView; 1]> = buffers.iter().map(|(_, buf)| [buf.view]).collect();
        let writes: Vec<_> = buffers
            .iter()
            .zip(&infos)
            .zip(&views)
            .map(|(((b, _), info), view)| {
                let w = vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(*b)
                    .descriptor_type(descriptor_type(*b));
                if is_texel(*b) {
                    w.texel_buffer_view(view)
                } else {
                    w.buffer_info(info)
                }
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
        if self.ctx.is_hung() {
            return;
        }
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

/// A `VkPipelineCache` loaded from and saved to a file in the cache
/// folder (`context::Settings::cache_dir`), one file per vendor and device.
/// Every kernel (render, render_fast, probe) shares the file: the driver
/// keys each pipeline in it by a hash of the whole pipeline, SPIR-V module
/// and specialization constants included, so two modules never collide.
/// A missing, stale, corrupt or unwritable file never fails a render: it
/// means no cache, with a warning through `log` where something is wrong
/// (docs/gpu.md, "Pipeline cache").
struct CacheFile<'a> {
    ctx: &'a Context,
    handle: vk::PipelineCache,
    path: Option<PathBuf>,
}

/// The default folder of the pipeline cache: `$XDG_CACHE_HOME/whitted`, or
/// `~/.cache/whitted`.
pub fn cache_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("XDG_CACHE_HOME") {
        Some(x) if !x.is_empty() => PathBuf::from(x),
        _ => PathBuf::from(std::env::var_os("HOME")?).join(".cache"),
    };
    Some(base.join("whitted"))
}

/// The cache file of device `info` in folder `dir`.
pub fn cache_file(dir: &std::path::Path, info: &super::DeviceInfo) -> PathBuf {
    dir.join(format!(
        "pipelines-{:04x}-{:04x}.bin",
        info.vendor_id, info.device_id
    ))
}

/// Bytes of VkPipelineCacheHeaderVersionOne.
const HEADER: usize = 32;

/// Why `data` is no cache for this device, if it is not one. A file
/// written by another driver build is normal after an update (no reason to
/// warn); anything else is corruption.
fn check_header(data: &[u8], i: &super::DeviceInfo) -> Result<(), (log::Level, &'static str)> {
    let word = |k: usize| u32::from_le_bytes(data[k..k + 4].try_into().unwrap());
    if data.len() < HEADER {
        return Err((log::Level::Warn, "shorter than its header"));
    }
    if word(0) as usize != HEADER || word(4) != 1 {
        return Err((log::Level::Warn, "not a Vulkan pipeline cache (bad header)"));
    }
    if word(8) != i.vendor_id || word(12) != i.device_id || data[16..32] != i.pipeline_cache_uuid {
        return Err((
            log::Level::Info,
            "written by another device or driver build",
        ));
    }
    Ok(())
}

/// The contents of cache file `path` if it is a cache of device `i`;
/// empty (with a message through `log` saying why) otherwise.
fn load(path: &std::path::Path, i: &super::DeviceInfo) -> Vec<u8> {
    match std::fs::read(path) {
        Ok(b) => match check_header(&b, i) {
            Ok(()) => b,
            Err((level, why)) => {
                log::log!(level, "pipeline cache {} ignored: {why}", path.display());
                Vec::new()
            }
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => {
            log::warn!("pipeline cache {} unreadable: {e}", path.display());
            Vec::new()
        }
    }
}

impl<'a> CacheFile<'a> {
    fn open(ctx: &'a Context) -> Self {
        let i = &ctx.info;
        let path = ctx.settings.cache_dir.as_deref().map(|d| cache_file(d, i));
        // Hand the driver only data whose header names this very device and
        // driver build (VkPipelineCacheHeaderVersionOne).
        let data = path.as_deref().map(|p| load(p, i)).unwrap_or_default();
        let ci = vk::PipelineCacheCreateInfo::default().initial_data(&data);
        // SAFETY: the initial data's header was checked against this device.
        let handle = match unsafe { ctx.device.create_pipeline_cache(&ci, None) } {
            Ok(h) => h,
            Err(r) => {
                log::warn!("no pipeline cache (vkCreatePipelineCache: {r})");
                vk::PipelineCache::null()
            }
        };
        CacheFile { ctx, handle, path }
    }

    /// Writes the cache back when the driver put anything past the header
    /// in it (lavapipe never does); a failure is a warning.
    fn save(&self) {
        if self.handle == vk::PipelineCache::null() {
            return;
        }
        let Some(path) = &self.path else { return };
        // SAFETY: a live cache on a live device.
        let data = match unsafe { self.ctx.device.get_pipeline_cache_data(self.handle) } {
            Ok(d) => d,
            Err(r) => {
                log::warn!("pipeline cache not saved (vkGetPipelineCacheData: {r})");
                return;
            }
        };
        if data.len() <= HEADER {
            return;
        }
        if let Err(e) = write_atomic(path, &data) {
            log::warn!("pipeline cache {} not saved: {e}", path.display());
        }
    }
}

/// Writes through a temporary file in the same folder (made if missing),
/// renamed over `path`: concurrent processes never see half a file.
fn write_atomic(path: &std::path::Path, data: &[u8]) -> std::io::Result<()> {
    let dir = path
        .parent()
        .ok_or_else(|| std::io::Error::other("no parent folder"))?;
    std::fs::create_dir_all(dir)?;
    let mut tmp = tempfile::NamedTempFile::new_in(dir)?;
    std::io::Write::write_all(&mut tmp, data)?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

impl Drop for CacheFile<'_> {
    fn drop(&mut self) {
        // SAFETY: pipeline creation with this cache has returned.
        unsafe { self.ctx.device.destroy_pipeline_cache(self.handle, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::{DeviceInfo, DeviceKind};

    fn device() -> DeviceInfo {
        DeviceInfo {
            index: 0,
            name: "test device".into(),
            kind: DeviceKind::Cpu,
            driver: String::new(),
            driver_version: 1,
            uuid: "00".repeat(16),
            api_version: "1.3.0".into(),
            vendor_id: 0x10005,
            device_id: 7,
            max_storage_buffer_range: 0,
            max_texel_buffer_elements: 0,
            max_compute_work_group_invocations: 0,
            max_compute_work_group_size: [0; 3],
            max_compute_work_group_count: [0; 3],
            max_push_constants_size: 0,
            subgroup_size: 0,
            timestamps: false,
            timestamp_period_ns: 0.0,
            device_local_bytes: 0,
            unusable: None,
            queue_family: 0,
            timestamp_mask: 0,
            pipeline_cache_uuid: [9; 16],
        }
    }

    fn header(i: &DeviceInfo) -> Vec<u8> {
        let mut h = Vec::new();
        for w in [HEADER as u32, 1, i.vendor_id, i.device_id] {
            h.extend_from_slice(&w.to_le_bytes());
        }
        h.extend_from_slice(&i.pipeline_cache_uuid);
        h
    }

    #[test]
    fn only_this_devices_cache_is_loaded() {
        let i = device();
        let dir = tempfile::tempdir().unwrap();
        let path = cache_file(dir.path(), &i);
        assert!(load(&path, &i).is_empty(), "missing file");
        let mut good = header(&i);
        good.extend_from_slice(b"driver data");
        std::fs::write(&path, &good).unwrap();
        assert_eq!(load(&path, &i), good);
        for (bad, level) in [
            (b"garbage".to_vec(), log::Level::Warn),
            (vec![0u8; 64], log::Level::Warn),
            (
                {
                    let mut other = good.clone();
                    other[16] ^= 1; // another driver build's UUID
                    other
                },
                log::Level::Info,
            ),
        ] {
            assert_eq!(check_header(&bad, &i).unwrap_err().0, level);
            std::fs::write(&path, &bad).unwrap();
            assert!(load(&path, &i).is_empty());
        }
        // A folder where the file should be: unreadable, still no failure.
        std::fs::remove_file(&path).unwrap();
        std::fs::create_dir(&path).unwrap();
        assert!(load(&path, &i).is_empty());
    }

    #[test]
    fn an_unwritable_cache_is_an_error_to_log_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a file");
        std::fs::write(&file, b"x").unwrap();
        // Its folder would have to be inside a regular file.
        assert!(write_atomic(&file.join("sub").join("c.bin"), b"data").is_err());
        let ok = dir.path().join("new").join("c.bin");
        write_atomic(&ok, b"data").unwrap();
        assert_eq!(std::fs::read(&ok).unwrap(), b"data");
    }
}
