//! The Vulkan instance, the debug messenger, device choice, the logical
//! device with one compute queue, and the memory allocator.
//!
//! `WHITTED_VALIDATION=1` enables `VK_LAYER_KHRONOS_validation` when it is
//! installed (`GpuOptions::sync_validation` adds synchronization
//! validation). The debug messenger is chained into instance creation, so
//! it also hears `vkCreateInstance` and `vkDestroyInstance`; every message
//! goes to the `log` crate under the target `vulkan` (docs/gpu.md, "Log
//! levels"), and every error is counted: tests assert the count stays zero.

use super::{Fault, GpuError};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{c_void, CStr};
use std::mem::ManuallyDrop;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

static ERRORS: AtomicU64 = AtomicU64::new(0);
static WARNINGS: AtomicU64 = AtomicU64::new(0);

/// Errors the debug messenger has reported in this process (validation
/// layer or driver). Tests assert this stays 0.
pub fn validation_errors() -> u64 {
    ERRORS.load(Ordering::SeqCst)
}

/// Warnings the debug messenger has reported in this process.
pub fn validation_warnings() -> u64 {
    WARNINGS.load(Ordering::SeqCst)
}

/// True when `WHITTED_VALIDATION=1` asks for the validation layer.
pub fn validation_requested() -> bool {
    std::env::var("WHITTED_VALIDATION").is_ok_and(|v| v == "1")
}

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// The `log` target of every message the debug messenger passes on.
pub const LOG_TARGET: &str = "vulkan";

/// The `log` level of a messenger message: errors are errors, validation
/// and performance warnings are warnings, general warnings (the loader's
/// notes about other drivers' ICDs) are information, info is info and
/// verbose is debug.
fn log_level(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
) -> log::Level {
    use vk::DebugUtilsMessageSeverityFlagsEXT as S;
    use vk::DebugUtilsMessageTypeFlagsEXT as T;
    if severity.contains(S::ERROR) {
        log::Level::Error
    } else if severity.contains(S::WARNING) {
        if types.intersects(T::VALIDATION | T::PERFORMANCE) {
            log::Level::Warn
        } else {
            log::Level::Info
        }
    } else if severity.contains(S::INFO) {
        log::Level::Info
    } else {
        log::Level::Debug
    }
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes a valid callback-data pointer (or null) whose
    // message is a NUL-terminated string living for the duration of the call.
    let msg = unsafe {
        data.as_ref()
            .and_then(|d| d.message_as_c_str())
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let level = log_level(severity, types);
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        ERRORS.fetch_add(1, Ordering::SeqCst);
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        WARNINGS.fetch_add(1, Ordering::SeqCst);
    }
    if log::max_level() == log::LevelFilter::Off {
        // No logger is installed (a library user who set none up): errors
        // still reach stderr, and warnings do when validation was asked for.
        if level == log::Level::Error || (level == log::Level::Warn && validation_requested()) {
            eprintln!("vulkan {}: {msg}", level.as_str().to_lowercase());
        }
    } else {
        log::log!(target: LOG_TARGET, level, "{msg}");
    }
    vk::FALSE
}

/// The severities the messenger asks for: warnings and errors always (they
/// are counted), info and verbose only when the logger would show them.
fn messenger_severities() -> vk::DebugUtilsMessageSeverityFlagsEXT {
    use vk::DebugUtilsMessageSeverityFlagsEXT as S;
    let mut s = S::WARNING | S::ERROR;
    if log::log_enabled!(target: LOG_TARGET, log::Level::Info) {
        s |= S::INFO;
    }
    if log::log_enabled!(target: LOG_TARGET, log::Level::Debug) {
        s |= S::VERBOSE;
    }
    s
}

/// What kind of device a Vulkan physical device is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceKind {
    Discrete,
    Integrated,
    Virtual,
    Cpu,
    Other,
}

impl DeviceKind {
    fn of(t: vk::PhysicalDeviceType) -> Self {
        match t {
            vk::PhysicalDeviceType::DISCRETE_GPU => DeviceKind::Discrete,
            vk::PhysicalDeviceType::INTEGRATED_GPU => DeviceKind::Integrated,
            vk::PhysicalDeviceType::VIRTUAL_GPU => DeviceKind::Virtual,
            vk::PhysicalDeviceType::CPU => DeviceKind::Cpu,
            _ => DeviceKind::Other,
        }
    }
    /// Preference: discrete > integrated > virtual > CPU > other.
    fn rank(self) -> u32 {
        match self {
            DeviceKind::Discrete => 4,
            DeviceKind::Integrated => 3,
            DeviceKind::Virtual => 2,
            DeviceKind::Cpu => 1,
            DeviceKind::Other => 0,
        }
    }
    /// A real GPU (what `--backend auto` renders on).
    pub fn is_gpu(self) -> bool {
        matches!(
            self,
            DeviceKind::Discrete | DeviceKind::Integrated | DeviceKind::Virtual
        )
    }
    pub fn name(self) -> &'static str {
        match self {
            DeviceKind::Discrete => "discrete GPU",
            DeviceKind::Integrated => "integrated GPU",
            DeviceKind::Virtual => "virtual GPU",
            DeviceKind::Cpu => "CPU",
            DeviceKind::Other => "other",
        }
    }
}

/// One Vulkan physical device and the limits the renderer cares about.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    /// Position in `vkEnumeratePhysicalDevices` (what `--device N` names).
    pub index: usize,
    pub name: String,
    pub kind: DeviceKind,
    /// Driver name and version string (VkPhysicalDeviceDriverProperties).
    pub driver: String,
    /// VkPhysicalDeviceProperties::driverVersion (vendor-encoded).
    pub driver_version: u32,
    /// VkPhysicalDeviceIDProperties::deviceUUID as 32 hex digits: the key of
    /// the saved dispatch shape (`whitted profile --save`).
    pub uuid: String,
    pub api_version: String,
    pub vendor_id: u32,
    pub device_id: u32,
    pub max_storage_buffer_range: u64,
    /// Texels a uniform texel buffer view may hold (the scene's arrays
    /// are read through such views: `GpuReads`).
    pub max_texel_buffer_elements: u64,
    pub max_compute_work_group_invocations: u32,
    pub max_compute_work_group_size: [u32; 3],
    pub max_compute_work_group_count: [u32; 3],
    pub max_push_constants_size: u32,
    pub subgroup_size: u32,
    /// The compute queue can write timestamps.
    pub timestamps: bool,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Bytes of the largest device-local heap.
    pub device_local_bytes: u64,
    /// Why the device cannot run the renderer, if it cannot.
    pub unusable: Option<String>,
    #[serde(skip)]
    pub(crate) queue_family: u32,
    #[serde(skip)]
    pub(crate) timestamp_mask: u64,
    #[serde(skip)]
    pub(crate) pipeline_cache_uuid: [u8; 16],
}

impl DeviceInfo {
    /// The device is llvmpipe (lavapipe), whose shaders stop every loop
    /// once a group of invocations has made `loops::LLVMPIPE_LOOP_BUDGET`
    /// iterations in all (docs/gpu.md, "lavapipe's loop budget").
    pub fn has_loop_budget(&self) -> bool {
        self.name.contains("llvmpipe") || self.driver.contains("llvmpipe")
    }
}

/// Result of a Vulkan call, with the call's name on failure.
pub(crate) trait VkCheck<T> {
    fn vk(self, call: &'static str) -> Result<T, GpuError>;
}

impl<T> VkCheck<T> for Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T, GpuError> {
        self.map_err(|result| GpuError::Vulkan { call, result })
    }
}

/// The loader, the instance and (when available) the debug messenger.
pub struct Instance {
    // Field order is irrelevant: Drop destroys explicitly, messenger first.
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub(crate) instance: ash::Instance,
    _entry: ash::Entry,
    /// The validation layer is enabled.
    pub validation: bool,
    /// Synchronization validation is on too.
    pub sync_validation: bool,
    /// Set when a device made from this instance hung: nothing is
    /// destroyed (docs/gpu.md, "Device faults").
    pub(crate) leak: bool,
}

impl Instance {
    /// A new instance; the validation layer when `WHITTED_VALIDATION=1` or
    /// `sync_validation` asks for it and it is installed, with
    /// synchronization validation when `sync_validation`.
    pub fn new(sync_validation: bool) -> Result<Self, GpuError> {
        // SAFETY: loading libvulkan runs its initialisers; the Entry keeps
        // the library loaded for as long as any handle made from it.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| {
            GpuError::NoDevice(format!("cannot load the Vulkan loader (libvulkan): {e}"))
        })?;
        // SAFETY: plain queries on a loaded entry.
        let version = unsafe { entry.try_enumerate_instance_version() }
            .vk("vkEnumerateInstanceVersion")?
            .unwrap_or(vk::API_VERSION_1_0);
        if version < vk::API_VERSION_1_1 {
            return Err(GpuError::NoDevice(format!(
                "the Vulkan loader supports only Vulkan {}; whitted needs 1.1",
                version_string(version)
            )));
        }
        // SAFETY: as above.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }.unwrap_or_default();
        // SAFETY: as above.
        let exts =
            unsafe { entry.enumerate_instance_extension_properties(None) }.unwrap_or_default();
        let has_layer = layers
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
        let has_debug = exts
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(ash::ext::debug_utils::NAME));
        let wanted = validation_requested() || sync_validation;
        let validation = wanted && has_layer;
        if wanted && !has_layer {
            log::warn!("validation was asked for but VK_LAYER_KHRONOS_validation is not installed");
        }
        // VkValidationFeaturesEXT needs VK_EXT_validation_features, which
        // the layer itself provides.
        let has_features = validation
            && sync_validation
            // SAFETY: as above; the layer is installed.
            && unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                .unwrap_or_default()
                .iter()
                .any(|e| {
                    e.extension_name_as_c_str() == Ok(ash::ext::validation_features::NAME)
                });
        if validation && sync_validation && !has_features {
            log::warn!(
                "synchronization validation was asked for but the validation layer lacks \
                 VK_EXT_validation_features"
            );
        }
        let app = vk::ApplicationInfo::default()
            .application_name(c"whitted")
            .application_version(1)
            .engine_name(c"whitted")
            .api_version(vk::API_VERSION_1_1);
        let layer_names = if validation {
            vec![VALIDATION_LAYER.as_ptr()]
        } else {
            vec![]
        };
        let mut ext_names = vec![];
        if has_debug {
            ext_names.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        if has_features {
            ext_names.push(ash::ext::validation_features::NAME.as_ptr());
        }
        // The same messenger description serves the one chained into
        // instance creation (messages from vkCreateInstance and
        // vkDestroyInstance) and the one made after it (everything else).
        let mut messenger = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(messenger_severities())
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback));
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layer_names)
            .enabled_extension_names(&ext_names);
        if has_debug {
            info = info.push_next(&mut messenger);
        }
        if has_features {
            info = info.push_next(&mut features);
        }
        // SAFETY: every pointer in `info` (and its pNext chain) refers to
        // locals that outlive the call; the chained structs belong to
        // extensions enabled in `info`; the callback is a 'static function
        // that only touches atomics and the logger.
        let instance = unsafe { entry.create_instance(&info, None) }.map_err(|r| match r {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => GpuError::NoDevice(
                "no Vulkan driver is installed (vkCreateInstance: ERROR_INCOMPATIBLE_DRIVER)".into(),
            ),
            vk::Result::ERROR_INITIALIZATION_FAILED => GpuError::NoDevice(
                "the Vulkan loader could not initialise (vkCreateInstance: ERROR_INITIALIZATION_FAILED)"
                    .into(),
            ),
            result => GpuError::Vulkan {
                call: "vkCreateInstance",
                result,
            },
        })?;
        let mut me = Instance {
            debug: None,
            instance,
            _entry: entry,
            validation,
            sync_validation: has_features,
            leak: false,
        };
        if has_debug {
            let du = ash::ext::debug_utils::Instance::new(&me._entry, &me.instance);
            // Unchained: the messenger made here must not point on to the
            // validation features.
            let ci = vk::DebugUtilsMessengerCreateInfoEXT {
                p_next: std::ptr::null(),
                ..messenger
            };
            // SAFETY: the instance enabled VK_EXT_debug_utils; the callback is
            // a 'static function that only touches atomics and the logger.
            match unsafe { du.create_debug_utils_messenger(&ci, None) } {
                Ok(m) => me.debug = Some((du, m)),
                Err(r) => log::warn!(
                    "no Vulkan debug messenger (vkCreateDebugUtilsMessengerEXT: {r}); \
                     validation messages are lost"
                ),
            }
        }
        Ok(me)
    }

    /// Every physical device, in enumeration order.
    pub fn devices(&self) -> Result<Vec<(vk::PhysicalDevice, DeviceInfo)>, GpuError> {
        // SAFETY: the instance is live.
        let pds = unsafe { self.instance.enumerate_physical_devices() }.map_err(|r| match r {
            vk::Result::ERROR_INITIALIZATION_FAILED => GpuError::NoDevice(
                "no Vulkan device (vkEnumeratePhysicalDevices: ERROR_INITIALIZATION_FAILED)".into(),
            ),
            result => GpuError::Vulkan {
                call: "vkEnumeratePhysicalDevices",
                result,
            },
        })?;
        Ok(pds
            .into_iter()
            .enumerate()
            .map(|(i, pd)| (pd, self.describe(i, pd)))
            .collect())
    }

    fn describe(&self, index: usize, pd: vk::PhysicalDevice) -> DeviceInfo {
        let inst = &self.instance;
        // SAFETY: `pd` came from this instance.
        let props = unsafe { inst.get_physical_device_properties(pd) };
        let api = props.api_version;
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut ids = vk::PhysicalDeviceIDProperties::default();
        let driver_known = api >= vk::API_VERSION_1_2;
        {
            let mut p2 = vk::PhysicalDeviceProperties2::default();
            if api >= vk::API_VERSION_1_1 {
                p2 = p2.push_next(&mut subgroup).push_next(&mut ids);
                if driver_known {
                    p2 = p2.push_next(&mut driver);
                }
                // SAFETY: Vulkan 1.1 core; the chain holds only structs the
                // device's API version knows.
                unsafe { inst.get_physical_device_properties2(pd, &mut p2) };
            }
        }
        // SAFETY: `pd` came from this instance.
        let families = unsafe { inst.get_physical_device_queue_family_properties(pd) };
        // SAFETY: as above.
        let mem = unsafe { inst.get_physical_device_memory_properties(pd) };
        let family = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE));
        let bits = family.map_or(0, |f| families[f].timestamp_valid_bits);
        let l = &props.limits;
        let device_local_bytes = mem.memory_heaps[..mem.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0);
        let subgroup_ok = subgroup
            .supported_stages
            .contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup
                .supported_operations
                .contains(vk::SubgroupFeatureFlags::BASIC | vk::SubgroupFeatureFlags::ARITHMETIC);
        let unusable = if api < vk::API_VERSION_1_1 {
            Some(format!("supports only Vulkan {}", version_string(api)))
        } else if family.is_none() {
            Some("has no compute queue".to_string())
        } else if !subgroup_ok {
            Some("lacks subgroup arithmetic in compute shaders".to_string())
        } else {
            None
        };
        let name = props
            .device_name_as_c_str()
            .map(|c| c.to_string_lossy().into_owned())
            .unwrap_or_default();
        let driver_s = if driver_known {
            let n = driver
                .driver_name_as_c_str()
                .map(|c| c.to_string_lossy().into_owned())
                .unwrap_or_default();
            let i = driver
                .driver_info_as_c_str()
                .map(|c| c.to_string_lossy().into_owned())
                .unwrap_or_default();
            format!("{n} {i}").trim().to_string()
        } else {
            format!("driver version {:#x}", props.driver_version)
        };
        DeviceInfo {
            index,
            name,
            kind: DeviceKind::of(props.device_type),
            driver: driver_s,
            driver_version: props.driver_version,
            uuid: ids.device_uuid.iter().map(|b| format!("{b:02x}")).collect(),
            api_version: version_string(api),
            vendor_id: props.vendor_id,
            device_id: props.device_id,
            max_storage_buffer_range: l.max_storage_buffer_range as u64,
            max_texel_buffer_elements: l.max_texel_buffer_elements as u64,
            max_compute_work_group_invocations: l.max_compute_work_group_invocations,
            max_compute_work_group_size: l.max_compute_work_group_size,
            max_compute_work_group_count: l.max_compute_work_group_count,
            max_push_constants_size: l.max_push_constants_size,
            subgroup_size: subgroup.subgroup_size,
            timestamps: bits > 0,
            timestamp_period_ns: l.timestamp_period,
            device_local_bytes,
            unusable,
            queue_family: family.unwrap_or(0) as u32,
            timestamp_mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
            pipeline_cache_uuid: props.pipeline_cache_uuid,
        }
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if self.leak {
            return;
        }
        // SAFETY: every object made from this instance (devices, messenger
        // last) is gone: Context drops its device before its Instance.
        unsafe {
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

fn version_string(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

/// Which device to use: `index` when given (it must be usable), otherwise
/// the best usable one (discrete > integrated > virtual > CPU), or, with
/// `real_gpu_only`, the best real GPU.
pub fn choose(
    devices: &[DeviceInfo],
    index: Option<usize>,
    real_gpu_only: bool,
) -> Result<usize, GpuError> {
    if devices.is_empty() {
        return Err(GpuError::NoDevice(
            "the Vulkan loader reports no device".into(),
        ));
    }
    if let Some(i) = index {
        let d = devices.get(i).ok_or(GpuError::BadIndex {
            index: i,
            count: devices.len(),
        })?;
        if let Some(why) = &d.unusable {
            return Err(GpuError::Unusable(format!("device {i} ({}) {why}", d.name)));
        }
        return Ok(i);
    }
    let best = devices
        .iter()
        .filter(|d| d.unusable.is_none())
        .filter(|d| !real_gpu_only || d.kind.is_gpu())
        .max_by_key(|d| (d.kind.rank(), std::cmp::Reverse(d.index)));
    match best {
        Some(d) => Ok(d.index),
        None if real_gpu_only => Err(GpuError::NoDevice(format!(
            "no GPU among the Vulkan devices ({})",
            devices
                .iter()
                .map(|d| format!("{}: {}", d.name, d.kind.name()))
                .collect::<Vec<_>>()
                .join(", ")
        ))),
        None => Err(GpuError::NoDevice(format!(
            "no usable Vulkan device ({})",
            devices
                .iter()
                .map(|d| format!("{} {}", d.name, d.unusable.as_deref().unwrap_or("")))
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// What a `Context` is opened with: `GpuOptions`' device-level fields with
/// the environment applied (`super::resolve`).
#[derive(Clone, Debug, Default)]
pub struct Settings {
    pub device: Option<usize>,
    pub real_gpu_only: bool,
    pub sync_validation: bool,
    /// The fault to inject, if any.
    pub fault: Option<Fault>,
    /// Longest wait for one submission.
    pub fence_timeout: Duration,
    /// Folder of the pipeline cache files; None: no cache.
    pub cache_dir: Option<PathBuf>,
}

/// The logical device, its compute queue and the allocator: everything a
/// render needs. Shared (`Arc`) by the buffers, kernels and command pools
/// made from it, so it outlives them all.
pub struct Context {
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) device: ash::Device,
    pub(crate) queue: vk::Queue,
    pub info: DeviceInfo,
    pub(crate) settings: Settings,
    /// The device failed (lost, or a submission timed out): the error,
    /// returned again to every later render or probe.
    pub(crate) failed: Mutex<Option<GpuError>>,
    /// A submission never finished: the device may still be running it,
    /// so no handle is destroyed (each Drop leaks; the process frees them
    /// at exit). Never set on a device that recovered.
    pub(crate) hung: AtomicBool,
    // Dropped after Context::drop has destroyed the device.
    pub(crate) instance: Instance,
}

impl Context {
    /// Opens the device `settings.device` names (see `choose`) on a fresh
    /// instance.
    pub fn new(settings: Settings) -> Result<Self, GpuError> {
        let instance = Instance::new(settings.sync_validation)?;
        let devices = instance.devices()?;
        let infos: Vec<DeviceInfo> = devices.iter().map(|(_, d)| d.clone()).collect();
        let i = choose(&infos, settings.device, settings.real_gpu_only)?;
        let (pd, info) = devices[i].clone();
        let prio = [1.0f32];
        let qinfo = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(info.queue_family)
            .queue_priorities(&prio)];
        let dinfo = vk::DeviceCreateInfo::default().queue_create_infos(&qinfo);
        // SAFETY: `pd` belongs to `instance`; `dinfo` points at live locals.
        let device =
            unsafe { instance.instance.create_device(pd, &dinfo, None) }.vk("vkCreateDevice")?;
        // SAFETY: the queue family and index were requested above.
        let queue = unsafe { device.get_device_queue(info.queue_family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.instance.clone(),
            device: device.clone(),
            physical_device: pd,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: gpu_allocator::AllocationSizes::new(16 << 20, 16 << 20),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: nothing was created from the device yet.
                unsafe { device.destroy_device(None) };
                return Err(GpuError::Memory {
                    what: "the allocator".into(),
                    msg: e.to_string(),
                });
            }
        };
        if let Some(f) = settings.fault {
            log::warn!(
                "injecting the device fault {} on {} (docs/gpu.md, \"Device faults\")",
                f.name(),
                info.name
            );
        }
        Ok(Context {
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            device,
            queue,
            info,
            settings,
            failed: Mutex::new(None),
            hung: AtomicBool::new(false),
            instance,
        })
    }

    /// `fault` is the one injected on this device.
    pub(crate) fn injects(&self, fault: Fault) -> bool {
        self.settings.fault == Some(fault)
    }

    /// The device's handles must be left alone (a submission never ended).
    pub(crate) fn is_hung(&self) -> bool {
        self.hung.load(Ordering::SeqCst)
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        if self.is_hung() {
            // Destroying a device, or freeing memory, that a submission may
            // still use is undefined; leaking them is not.
            self.instance.leak = true;
            return;
        }
        // SAFETY: every buffer, kernel and command pool holds an Arc to this
        // context, so none is alive; the allocator frees its memory blocks
        // before the device is destroyed. On a lost device vkDeviceWaitIdle
        // returns VK_ERROR_DEVICE_LOST at once, and destroying is allowed.
        unsafe {
            if let Err(r) = self.device.device_wait_idle() {
                log::debug!("vkDeviceWaitIdle while closing {}: {r}", self.info.name);
            }
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
        }
    }
}
