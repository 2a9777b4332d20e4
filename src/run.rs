//! The library's entry for a render, which every command and the tests
//! call: pack the scene, choose a backend, render, and on `auto` fall back
//! to the CPU mirror when the GPU cannot be had or fails. The CLI
//! (`src/cli/`) only adds argument parsing, output checks and reports.
//!
//! ```no_run
//! # fn main() -> anyhow::Result<()> {
//! let scene = whitted::scene::load(std::path::Path::new("scenes/showcase.toml"))?;
//! let r = whitted::render(&scene, &whitted::RenderOptions::default())?;
//! whitted::output::write(&r.frame, std::path::Path::new("out.png"), Default::default())?;
//! # Ok(()) }
//! ```

use crate::cpu::{self, Frame};
use crate::error::{device, user};
use crate::gpu::{self, Gpu, GpuError, GpuOptions};
use crate::pack::{self, Counting, Packed, Settings};
use crate::scene::Scene;
use anyhow::{anyhow, Context, Result};
use std::time::Instant;

/// Where to render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// A real GPU when there is one, otherwise the CPU mirror.
    #[default]
    Auto,
    /// The CPU mirror (all cores).
    Cpu,
    /// The Vulkan compute shader on the chosen device (lavapipe included).
    Gpu,
}

/// The CPU tracer's number type (the GPU always runs f32). The packed
/// scene stays f32 either way: f64 measures the error of the tracer's
/// arithmetic, not of the scene's storage (docs/accuracy.md, "Precision").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// The GPU's twin, bit for bit on lavapipe.
    #[default]
    F32,
    /// The reference's arithmetic: about 1.5 to 2x the time of f32.
    F64,
}

impl Precision {
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// Everything a render needs besides the scene.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    pub settings: Settings,
    pub backend: Backend,
    pub gpu: GpuOptions,
    /// Worker threads for the CPU mirror (None: all cores).
    pub threads: Option<u32>,
    /// How rays are counted (`--preset spd` counts as the SPD does).
    pub counting: Counting,
    /// The CPU tracer's float type; f64 renders on the CPU only.
    pub precision: Precision,
    /// The CPU's packet width (`cpu::render_packets`).
    pub packet: u32,
}

/// Which backend rendered a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Used {
    Cpu,
    Gpu,
}

impl Used {
    pub fn name(self) -> &'static str {
        match self {
            Used::Cpu => "cpu",
            Used::Gpu => "gpu",
        }
    }
}

/// A rendered frame and where and how it was made.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub frame: Frame,
    pub used: Used,
    /// The device's name ("CPU mirror" for the CPU).
    pub device: String,
    /// Seconds spent packing (grid build included).
    pub pack_seconds: f64,
    pub grid: pack::GridInfo,
    /// The GPU kernel that rendered it (the saved profile's when the user
    /// named none); None on the CPU.
    pub kernel: Option<crate::gpu::GpuKernel>,
}

/// A progress callback: (done, total) units of work.
pub type Progress<'a> = &'a (dyn Fn(u64, u64) + Sync);

/// Packs `scene` for `settings`, counting rays as `counting` says;
/// problems with the scene or the settings, and a run over the memory
/// budget, are the user's (exit 2).
pub fn pack(scene: &Scene, settings: &Settings, counting: Counting) -> Result<Packed> {
    pack_with_progress(scene, settings, counting, &|_, _, _| {})
}

/// [`pack`] reporting each stage of the grid build (`pack::Stage`).
pub fn pack_with_progress(
    scene: &Scene,
    settings: &Settings,
    counting: Counting,
    progress: pack::Progress,
) -> Result<Packed> {
    let mut p = pack::pack_with_progress(scene, settings, progress).map_err(user)?;
    p.set_counting(counting);
    Ok(p)
}

/// Renders `scene`: packs it, then [`render_packed`].
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<Rendered> {
    render_with_progress(scene, opts, &|_, _| {})
}

/// [`render`] reporting progress.
pub fn render_with_progress(
    scene: &Scene,
    opts: &RenderOptions,
    progress: Progress,
) -> Result<Rendered> {
    let t0 = Instant::now();
    let packed = pack(scene, &opts.settings, opts.counting)?;
    let pack_seconds = t0.elapsed().as_secs_f64();
    let mut r = render_packed(&packed, opts, progress)?;
    r.pack_seconds = pack_seconds;
    Ok(r)
}

/// What `auto` learns before choosing: the Vulkan devices, or that this
/// machine has no GPU to survey.
enum Surveyed {
    Devices(Result<Vec<gpu::DeviceInfo>, GpuError>),
    /// No GPU device file (`gpu_device_files`): only CPU implementations
    /// of Vulkan (lavapipe), which `auto` passes over, could answer.
    NoGpu,
}

/// Why `auto` renders on the CPU mirror of a machine without a GPU
/// device file.
pub const NO_GPU_FILE: &str = "no GPU here (no GPU device file such as /dev/dri/renderD*, \
     /dev/nvidia*, /dev/dxg, /dev/kgsl* or /dev/mali*); --backend gpu uses a CPU Vulkan \
     device such as lavapipe";

/// The device files through which a Vulkan driver reaches a GPU on Linux,
/// found under `dev` (normally /dev): DRM nodes (Mesa's drivers, AMD,
/// Intel, virtio-gpu, Arm and Apple GPUs), NVIDIA's, WSL's `dxg`, and
/// Android's Adreno (`kgsl`) and Mali nodes. Empty: no GPU can answer a
/// survey, only a CPU implementation such as lavapipe.
pub fn gpu_device_files(dev: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let gpu_name = |n: &str| {
        n.starts_with("nvidia") || n == "dxg" || n.starts_with("kgsl") || n.starts_with("mali")
    };
    for (dir, drm) in [(dev.to_path_buf(), false), (dev.join("dri"), true)] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name();
            let n = name.to_string_lossy();
            if (drm && (n.starts_with("renderD") || n.starts_with("card")))
                || (!drm && gpu_name(&n))
            {
                out.push(e.path());
            }
        }
    }
    out.sort();
    out
}

/// Surveys the Vulkan devices for `auto` (device index `device` asked
/// for, or none), skipping the survey where it can only find CPU devices
/// that `auto` would pass over: on Linux, with no GPU device file and no
/// driver named through the Vulkan loader's environment. Loading the
/// drivers is most of the cost of a survey (some 30 ms with Mesa's four,
/// as long as rendering SPD tetra).
fn survey_now(device: Option<usize>) -> Surveyed {
    if device.is_none() && no_gpu_here() {
        return Surveyed::NoGpu;
    }
    Surveyed::Devices(gpu::devices())
}

/// True where no survey can find a GPU: on Linux, no GPU device file
/// under /dev and no driver named through the Vulkan loader's
/// environment (`VK_ICD_FILENAMES`, `VK_DRIVER_FILES`,
/// `VK_ADD_DRIVER_FILES`).
pub fn no_gpu_here() -> bool {
    let steered = ["VK_ICD_FILENAMES", "VK_DRIVER_FILES", "VK_ADD_DRIVER_FILES"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    cfg!(target_os = "linux")
        && !steered
        && gpu_device_files(std::path::Path::new("/dev")).is_empty()
}

/// `auto`'s survey of the Vulkan devices, begun on a thread of its own
/// before the scene is read, so that loading the drivers overlaps reading
/// and packing the scene instead of following them (`survey_now`).
/// Dropping it waits for the thread: no driver is left half-loaded while
/// the process exits.
pub struct DeviceSurvey(Option<std::thread::JoinHandle<Surveyed>>);

impl DeviceSurvey {
    /// Starts the survey when `auto` will want it (f32 on `auto`; device
    /// index `device` asked for, or none); a survey that cannot start
    /// leaves the question to `choose`.
    pub fn start(backend: Backend, precision: Precision, device: Option<usize>) -> Self {
        if backend != Backend::Auto || precision != Precision::F32 {
            return DeviceSurvey(None);
        }
        DeviceSurvey(
            std::thread::Builder::new()
                .name("device survey".into())
                .spawn(move || survey_now(device))
                .ok(),
        )
    }

    /// No survey: `choose` makes its own when it needs one.
    pub fn none() -> Self {
        DeviceSurvey(None)
    }

    /// The survey's answer, waiting for it; None when none was started.
    fn take(&mut self) -> Option<Surveyed> {
        let h = self.0.take()?;
        Some(h.join().unwrap_or_else(|_| {
            Surveyed::Devices(Err(GpuError::Unusable("the device survey failed".into())))
        }))
    }
}

impl Drop for DeviceSurvey {
    fn drop(&mut self) {
        if let Some(h) = self.0.take() {
            let _ = h.join();
        }
    }
}

/// Renders packed data on the backend `opts` asks for. `auto` renders on a
/// real GPU when there is one and on the CPU mirror otherwise, saying why
/// (log level info); when the GPU fails during the render, `auto` finishes
/// on the CPU mirror (log level warn) and `gpu` fails with exit code 4.
pub fn render_packed(
    packed: &Packed,
    opts: &RenderOptions,
    progress: Progress,
) -> Result<Rendered> {
    render_packed_surveyed(packed, opts, &mut DeviceSurvey::none(), progress)
}

/// [`render_packed`] with `auto`'s device survey already under way.
pub fn render_packed_surveyed(
    packed: &Packed,
    opts: &RenderOptions,
    survey: &mut DeviceSurvey,
    progress: Progress,
) -> Result<Rendered> {
    let done = |frame: Frame, used: Used, device: String| Rendered {
        frame,
        used,
        device,
        pack_seconds: 0.0,
        grid: packed.grid.clone(),
        kernel: None,
    };
    match choose(opts, survey)? {
        Chosen::Gpu(g) => {
            let gopts = crate::profile::apply_saved(g.info(), &opts.gpu);
            match g.render(packed, &gopts, progress) {
                Ok(frame) => Ok(Rendered {
                    kernel: Some(gopts.kernel),
                    ..done(frame, Used::Gpu, g.info().name.clone())
                }),
                Err(e) if opts.backend == Backend::Auto && is_device_fault(&e) => {
                    log::warn!("{e}; finishing the render on the CPU mirror");
                    drop(g);
                    let frame =
                        render_cpu(packed, opts.threads, opts.precision, opts.packet, progress)?;
                    Ok(done(frame, Used::Cpu, "CPU mirror".into()))
                }
                Err(e) => Err(gpu_error(e)),
            }
        }
        Chosen::Cpu(why) => {
            if let Some(why) = why {
                log::info!("rendering on the CPU mirror: {why}");
            }
            let frame = render_cpu(packed, opts.threads, opts.precision, opts.packet, progress)?;
            Ok(done(frame, Used::Cpu, "CPU mirror".into()))
        }
    }
}

/// A failure of the device itself (not of the scene or the options): the
/// device's own faults (`GpuError::is_device_fault`: lost, out of memory,
/// timed out, kernel refused) and any other failed Vulkan call.
pub fn is_device_fault(e: &GpuError) -> bool {
    e.is_device_fault() || matches!(e, GpuError::Vulkan { .. } | GpuError::Memory { .. })
}

/// A GPU error with its exit class: the user's (2), the device's (4) or
/// internal (3).
pub fn gpu_error(e: GpuError) -> anyhow::Error {
    if e.is_user_error() {
        user(e)
    } else if is_device_fault(&e) {
        device(e)
    } else {
        anyhow!(e)
    }
}

/// Renders on the CPU mirror with `threads` workers (None: all cores) in
/// float type `precision`, in packets of `packet` rays.
pub fn render_cpu(
    packed: &Packed,
    threads: Option<u32>,
    precision: Precision,
    packet: u32,
    progress: Progress,
) -> Result<Frame> {
    let render = || match precision {
        Precision::F32 => cpu::render_packets::<f32>(packed, packet, progress),
        Precision::F64 => cpu::render_packets::<f64>(packed, packet, progress),
    };
    // All cores: rayon's global pool, already started by the build, rather
    // than a second pool of as many threads.
    let Some(n) = threads else {
        return Ok(render());
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n as usize)
        .build()
        .context("cannot start worker threads")?;
    Ok(pool.install(render))
}

enum Chosen {
    Gpu(Gpu),
    /// The CPU mirror, and why when `auto` passed over a Vulkan device.
    Cpu(Option<String>),
}

/// `auto`: a real GPU, or `--device N` of any kind; otherwise the CPU
/// mirror with the reason. `gpu`: the chosen device or an error (exit 2).
fn choose(opts: &RenderOptions, survey: &mut DeviceSurvey) -> Result<Chosen> {
    let g = &opts.gpu;
    if opts.precision == Precision::F64 {
        return match opts.backend {
            Backend::Gpu => Err(user(anyhow!(
                "--precision f64 renders on the CPU only (the shader computes in f32); \
                 use --backend cpu or auto"
            ))),
            Backend::Auto => Ok(Chosen::Cpu(Some(
                "--precision f64 renders on the CPU only (the shader computes in f32)".into(),
            ))),
            Backend::Cpu => Ok(Chosen::Cpu(None)),
        };
    }
    match opts.backend {
        Backend::Cpu => Ok(Chosen::Cpu(None)),
        Backend::Gpu => Ok(Chosen::Gpu(
            Gpu::new(g).map_err(|e| user(anyhow!("--backend gpu: {e}")))?,
        )),
        Backend::Auto => {
            let devices = match survey.take().unwrap_or_else(|| survey_now(g.device)) {
                Surveyed::NoGpu => return Ok(Chosen::Cpu(Some(NO_GPU_FILE.into()))),
                Surveyed::Devices(Ok(d)) => d,
                Surveyed::Devices(Err(e)) => return Ok(Chosen::Cpu(Some(e.to_string()))),
            };
            let pick = match g.device {
                Some(i) => gpu::choose(&devices, Some(i), false),
                None => gpu::choose(&devices, None, true),
            };
            match pick {
                Ok(i) => {
                    let o = GpuOptions {
                        device: Some(i),
                        ..g.clone()
                    };
                    match Gpu::new(&o) {
                        Ok(gpu) => Ok(Chosen::Gpu(gpu)),
                        Err(e) if g.device.is_some() => Err(gpu_error(e)),
                        Err(e) => Ok(Chosen::Cpu(Some(format!(
                            "{} could not be opened ({e})",
                            devices[i].name
                        )))),
                    }
                }
                Err(e @ GpuError::BadIndex { .. }) | Err(e @ GpuError::Unusable(_))
                    if g.device.is_some() =>
                {
                    Err(gpu_error(e))
                }
                Err(_) => Ok(Chosen::Cpu(Some(auto_reason(&devices)))),
            }
        }
    }
}

/// Why `auto` passes over every Vulkan device.
pub fn auto_reason(devices: &[gpu::DeviceInfo]) -> String {
    if devices.is_empty() {
        return "no Vulkan device".into();
    }
    let cpu: Vec<&gpu::DeviceInfo> = devices
        .iter()
        .filter(|d| d.kind == gpu::DeviceKind::Cpu)
        .collect();
    if let Some(d) = cpu.first() {
        return format!(
            "the only Vulkan device is {} (a CPU device: lavapipe is for validation, \
             5 to 10x slower than the mirror here, see BENCHMARKS.md); --backend gpu uses it anyway",
            d.name
        );
    }
    format!(
        "no usable GPU ({})",
        devices
            .iter()
            .map(|d| format!(
                "{}: {}",
                d.name,
                d.unusable.as_deref().unwrap_or("not a GPU")
            ))
            .collect::<Vec<_>>()
            .join("; ")
    )
}

#[cfg(test)]
mod tests {
    use super::gpu_device_files;

    /// The GPU device files are found by name, in /dev and /dev/dri; other
    /// device files (a terminal, DRM's control directory) are not GPUs.
    #[test]
    fn gpu_device_files_are_found_by_name() {
        let d = tempfile::tempdir().unwrap();
        let touch = |p: &str| {
            let p = d.path().join(p);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        };
        touch("tty0");
        touch("dri/by-path/pci-0000:00:02.0-render");
        assert!(gpu_device_files(d.path()).is_empty());
        touch("dri/renderD128");
        touch("nvidia0");
        touch("kgsl-3d0");
        let found: Vec<String> = gpu_device_files(d.path())
            .iter()
            .map(|p| p.strip_prefix(d.path()).unwrap().display().to_string())
            .collect();
        assert_eq!(found, ["dri/renderD128", "kgsl-3d0", "nvidia0"]);
        // No /dev at all: nothing.
        assert!(gpu_device_files(&d.path().join("absent")).is_empty());
    }
}
