//! The `whitted` command line.

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use whitted::cpu::Frame;
use whitted::gpu::{self, Gpu, GpuError, GpuOptions};
use whitted::metrics::{self, Tolerance};
use whitted::output::{self, Encoding};
use whitted::pack::{self, Packed, Sampling, Settings};
use whitted::{cpu, scene};

/// A recursive (Whitted-style) ray tracer: a Vulkan compute shader with a
/// CPU mirror of the same algorithm on the same data.
///
/// Exit codes: 0 success, 1 validation over tolerance, 2 bad input or
/// usage (the message names the file, line and column), 3 internal error.
#[derive(Parser)]
#[command(name = "whitted", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.toml native format or .nff) to a PNG, EXR or HDR file.
    ///
    /// Example: whitted render scenes/showcase.toml -o showcase.png --spp 4
    Render(RenderArgs),
    /// List the Vulkan devices and say which one each backend picks.
    ///
    /// For each device: its index (for --device), name, type, driver,
    /// maxStorageBufferRange (the largest array a scene may have),
    /// maxComputeWorkGroupInvocations, subgroup size and whether it has
    /// timestamps (for device timings).
    Devices(DevicesArgs),
    /// Render a scene on both backends (CPU mirror and GPU) and compare.
    ///
    /// Prints max and mean absolute error, RMSE, PSNR, mean FLIP (on the
    /// 8-bit sRGB images), the fraction of pixels over the per-pixel
    /// tolerance, and each ray count on both sides. Exits 1 when the
    /// images or ray counts are over tolerance (see docs/gpu.md), 0 when
    /// they agree. Uses the device --backend gpu would (lavapipe too).
    ///
    /// Example: whitted validate scenes/showcase.toml --width 160 --height 120 --diff diff.png
    Validate(ValidateArgs),
    /// Write a procedural scene (for benchmarks) as NFF: random spheres, or
    /// a sphereflake.
    ///
    /// Example: whitted generate --count 100000 -o spheres-100k.nff
    Generate(GenerateArgs),
    /// Convert a scene to POV-Ray 3.7 (.pov) or NFF (.nff), e.g. to time
    /// POV-Ray on the same scene (scripts/povray-compare.sh).
    Export(ExportArgs),
}

#[derive(Args)]
struct GenerateArgs {
    /// Spheres scattered in the cube [-1,1]³, radius 0.45 × their mean
    /// spacing, over a floor, lit by three lights (see src/gen.rs).
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u64).range(1..=50_000_000))]
    count: u64,
    /// Seed of the placement (same seed, same scene).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write a sphereflake of this level instead ((9^(L+1) − 1)/8 spheres
    /// over a floor; level 6 has 597 871).
    #[arg(long, value_name = "LEVEL", conflicts_with_all = ["count", "seed"], value_parser = clap::value_parser!(u32).range(0..=7))]
    sphereflake: Option<u32>,
    /// Output .nff file.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args)]
struct ExportArgs {
    /// Scene file (.toml or .nff).
    scene: PathBuf,
    /// Output: .pov (POV-Ray 3.7) or .nff.
    #[arg(short, long)]
    output: PathBuf,
    /// Image width written into the POV camera's aspect (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Generations of secondary rays (POV-Ray: max_trace_level = this + 1).
    #[arg(long, default_value_t = 5)]
    max_depth: u32,
    /// Adaptive depth cut-off (POV-Ray: adc_bailout).
    #[arg(long, default_value_t = 1.0 / 256.0, value_parser = parse_weight)]
    min_weight: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Backend {
    /// A real GPU when there is one, otherwise the CPU mirror.
    Auto,
    /// The CPU mirror (all cores).
    Cpu,
    /// The Vulkan compute shader.
    Gpu,
}

#[derive(Args, Clone)]
struct RenderOpts {
    /// Image width in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    height: Option<u32>,
    /// Generations of reflection/refraction (0 = local model only).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=whitted::constants::MAX_DEPTH_LIMIT as i64))]
    max_depth: u32,
    /// Adaptive depth control: a branch stops when its accumulated weight
    /// (largest channel) falls under this; 0 switches it off.
    #[arg(long, default_value_t = 1.0 / 256.0, value_parser = parse_weight)]
    min_weight: f32,
    /// Samples per pixel: stratified, jittered by a per-pixel hash
    /// (reproducible). 1 = the pixel centre.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4096))]
    spp: u32,
    /// Pixel centres (with --spp jitter), or SPD's (W+1)×(H+1) corner rays.
    #[arg(long, value_enum, default_value_t = Sampling::Centers)]
    sampling: Sampling,
    /// Override the voxel grid resolution, e.g. 64x64x32.
    #[arg(long, value_parser = parse_grid, value_name = "NXxNYxNZ")]
    grid: Option<[u32; 3]>,
    /// Worker threads for the CPU backend (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
}

#[derive(Args, Clone)]
struct GpuArgs {
    /// Vulkan device index (see `whitted devices`); default: the best one
    /// (discrete > integrated > virtual > CPU).
    #[arg(long, value_name = "N")]
    device: Option<usize>,
    /// Edge of a GPU dispatch tile in lattice samples: one submission per
    /// tile, so none runs long.
    #[arg(long, value_name = "N", default_value_t = gpu::DEFAULT_TILE,
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    tile: u32,
    /// GPU workgroup shape (specialization constants of the shader).
    #[arg(long, value_name = "WxH", default_value = "8x8", value_parser = parse_workgroup)]
    workgroup: [u32; 2],
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file: native TOML (see docs/scene-format.md) or NFF (.nff).
    scene: PathBuf,
    /// Output image: .png (8-bit), .exr or .hdr (linear floats).
    /// Default: the scene's name with .png, in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    opts: RenderOpts,
    /// Where to render: `auto` uses a real GPU (discrete, integrated or
    /// virtual) when there is one and otherwise the CPU mirror, saying why
    /// on stderr; `gpu` uses the chosen Vulkan device, CPU ones (lavapipe)
    /// included, and fails when there is none; `cpu` the CPU mirror.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    #[command(flatten)]
    gpu: GpuArgs,
    /// PNG encoding: sRGB, or the clamped linear values round(255·v).
    #[arg(long, value_enum, default_value_t = Encoding::Srgb)]
    encoding: Encoding,
    /// Write ray counts, timings and grid size as JSON.
    #[arg(long, value_name = "FILE.json")]
    stats: Option<PathBuf>,
    /// No progress bar and no notes on stderr.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args)]
struct DevicesArgs {
    /// Print the list as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ValidateArgs {
    /// Scene file: native TOML (see docs/scene-format.md) or NFF (.nff).
    scene: PathBuf,
    #[command(flatten)]
    opts: RenderOpts,
    #[command(flatten)]
    gpu: GpuArgs,
    /// Write an image of the per-pixel error (PNG): black where the
    /// backends agree; the per-pixel tolerance is the middle of the colour
    /// scale, brighter is over it.
    #[arg(long, value_name = "DIFF.png")]
    diff: Option<PathBuf>,
    /// Write the comparison as JSON.
    #[arg(long, value_name = "FILE.json")]
    json: Option<PathBuf>,
    /// Only the verdict line.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_workgroup(s: &str) -> Result<[u32; 2], String> {
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

fn parse_weight(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|e| format!("{e}"))?;
    if !v.is_finite() || !(0.0..=1.0).contains(&v) {
        return Err(format!("must be a number in [0, 1], got {s}"));
    }
    Ok(v)
}

fn parse_grid(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let max = whitted::constants::GRID_MAX_DIM;
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

/// An error that is the user's to fix (exit code 2).
#[derive(Debug)]
struct UserError(anyhow::Error);

impl std::fmt::Display for UserError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.0)
    }
}
impl std::error::Error for UserError {}

fn user(e: impl Into<anyhow::Error>) -> anyhow::Error {
    anyhow!(UserError(e.into()))
}

fn settings(o: &RenderOpts) -> Settings {
    Settings {
        width: o.width,
        height: o.height,
        max_depth: o.max_depth,
        min_weight: o.min_weight,
        spp: o.spp,
        sampling: o.sampling,
        grid: o.grid,
        ..Settings::default()
    }
}

fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::hidden();
    if !quiet {
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} rendering [{bar:40}] {percent}% {elapsed}/{duration}",
            )
            .unwrap()
            .progress_chars("=> "),
        );
    }
    bar
}

fn render(a: RenderArgs) -> Result<()> {
    let t_start = Instant::now();
    let out = match &a.output {
        Some(o) => o.clone(),
        None => PathBuf::from(format!(
            "{}.png",
            a.scene
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("out")
        )),
    };
    output::format_of(&out).map_err(user)?;
    let scene = scene::load(&a.scene).map_err(user)?;
    let t_load = t_start.elapsed().as_secs_f64();
    let t_build0 = Instant::now();
    let packed = pack::pack(&scene, &settings(&a.opts)).map_err(user)?;
    drop(scene);
    let t_build = t_build0.elapsed().as_secs_f64();

    let quiet = a.quiet;
    let bar = progress_bar(quiet);
    let started = Instant::now();
    let progress = |done: u64, total: u64| {
        if !quiet && bar.is_hidden() && started.elapsed().as_secs_f64() > 1.0 {
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        bar.set_length(total);
        bar.set_position(done);
    };
    let (backend, device, frame) = match choose_backend(a.backend, &a.gpu)? {
        Chosen::Gpu(g) => {
            let frame = g
                .render(&packed, &gpu_options(&a.gpu), &progress)
                .map_err(gpu_err)?;
            ("gpu", g.info().name.clone(), frame)
        }
        Chosen::Cpu(why) => {
            if let (Some(why), false) = (why, quiet) {
                eprintln!("note: rendering on the CPU mirror: {why}");
            }
            let frame = render_cpu(&packed, a.opts.threads, &progress)?;
            ("cpu", "CPU mirror".to_string(), frame)
        }
    };
    bar.finish_and_clear();
    output::write(&frame, &out, a.encoding).map_err(user)?;
    let total = t_start.elapsed().as_secs_f64();
    if let Some(path) = &a.stats {
        let json = serde_json::json!({
            "backend": backend,
            "device": device,
            "width": frame.width,
            "height": frame.height,
            "rays": frame.stats,
            "work": { "intersection_tests": frame.work.tests, "cells_visited": frame.work.cells },
            "seconds": {
                "load": t_load,
                "build": t_build,
                "render": frame.seconds,
                "gpu": frame.device_seconds,
                "total": total,
            },
            "grid": {
                "cells": packed.grid.cells,
                "refs": packed.grid.refs,
                "bytes": packed.grid.bytes,
                "build_seconds": packed.grid.seconds,
            },
        });
        write_atomic(path, serde_json::to_string_pretty(&json)?.as_bytes()).map_err(user)?;
    }
    if !a.quiet {
        eprintln!(
            "{}: {}x{} on {} in {:.3} s ({:.2} Mrays/s; grid {}x{}x{}, {} refs, built in {:.3} s)",
            out.display(),
            frame.width,
            frame.height,
            device,
            frame.seconds,
            frame.stats.total() as f64 / frame.seconds.max(1e-9) / 1e6,
            packed.grid.cells[0],
            packed.grid.cells[1],
            packed.grid.cells[2],
            packed.grid.refs,
            packed.grid.seconds,
        );
    }
    Ok(())
}

fn generate(a: GenerateArgs) -> Result<()> {
    let scene = match a.sphereflake {
        Some(level) => whitted::gen::sphereflake(level),
        None => whitted::gen::random_spheres(a.count as usize, a.seed),
    };
    let text = whitted::export::to_nff(&scene)?;
    write_atomic(&a.output, text.as_bytes()).map_err(user)
}

fn export(a: ExportArgs) -> Result<()> {
    let scene = scene::load(&a.scene).map_err(user)?;
    let ext = a.output.extension().and_then(|e| e.to_str()).unwrap_or("");
    let text = match ext {
        "pov" => whitted::export::to_pov(
            &scene,
            a.width.unwrap_or(scene.camera.width),
            a.height.unwrap_or(scene.camera.height),
            a.max_depth,
            a.min_weight,
        )?,
        "nff" => whitted::export::to_nff(&scene).map_err(user)?,
        _ => bail!(UserError(anyhow!(
            "{}: unknown export format (use .pov or .nff)",
            a.output.display()
        ))),
    };
    write_atomic(&a.output, text.as_bytes()).map_err(user)
}

fn gpu_options(g: &GpuArgs) -> GpuOptions {
    GpuOptions {
        device: g.device,
        real_gpu_only: false,
        tile: g.tile,
        workgroup: g.workgroup,
        staging: false,
    }
}

/// A GPU error: the user's to fix (exit 2) or internal (exit 3).
fn gpu_err(e: GpuError) -> anyhow::Error {
    if e.is_user_error() {
        user(anyhow!(e))
    } else {
        anyhow!(e)
    }
}

enum Chosen {
    Gpu(Gpu),
    /// The CPU mirror, and why when `auto` passed over a Vulkan device.
    Cpu(Option<String>),
}

/// `auto`: a real GPU, or `--device N` of any kind; otherwise the CPU
/// mirror with the reason. `gpu`: the chosen device or an error (exit 2).
fn choose_backend(b: Backend, g: &GpuArgs) -> Result<Chosen> {
    match b {
        Backend::Cpu => Ok(Chosen::Cpu(None)),
        Backend::Gpu => Ok(Chosen::Gpu(
            Gpu::new(&gpu_options(g)).map_err(|e| user(anyhow!("--backend gpu: {e}")))?,
        )),
        Backend::Auto => {
            let devices = match gpu::devices() {
                Ok(d) => d,
                Err(e) => return Ok(Chosen::Cpu(Some(e.to_string()))),
            };
            let pick = match g.device {
                Some(i) => gpu::choose(&devices, Some(i), false),
                None => gpu::choose(&devices, None, true),
            };
            match pick {
                Ok(i) => {
                    let opts = GpuOptions {
                        device: Some(i),
                        ..gpu_options(g)
                    };
                    match Gpu::new(&opts) {
                        Ok(gpu) => Ok(Chosen::Gpu(gpu)),
                        Err(e) if g.device.is_some() => Err(gpu_err(e)),
                        Err(e) => Ok(Chosen::Cpu(Some(format!(
                            "{} could not be opened ({e})",
                            devices[i].name
                        )))),
                    }
                }
                Err(e @ GpuError::BadIndex { .. }) | Err(e @ GpuError::Unusable(_))
                    if g.device.is_some() =>
                {
                    Err(gpu_err(e))
                }
                Err(_) => Ok(Chosen::Cpu(Some(auto_reason(&devices)))),
            }
        }
    }
}

/// Why `auto` passes over every Vulkan device.
fn auto_reason(devices: &[gpu::DeviceInfo]) -> String {
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

fn render_cpu(
    packed: &Packed,
    threads: Option<u32>,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Frame> {
    let pool = {
        let mut b = rayon::ThreadPoolBuilder::new();
        if let Some(n) = threads {
            b = b.num_threads(n as usize);
        }
        b.build().context("cannot start worker threads")?
    };
    Ok(pool.install(|| cpu::render(packed, progress)))
}

fn devices(a: DevicesArgs) -> Result<()> {
    let list = match gpu::devices() {
        Ok(l) => l,
        Err(e) => {
            if a.json {
                println!(
                    "{}",
                    serde_json::json!({ "devices": [], "error": e.to_string() })
                );
            } else {
                println!("{e}");
                println!("--backend auto renders on the CPU mirror; --backend gpu fails.");
            }
            return Ok(());
        }
    };
    let gpu_pick = gpu::choose(&list, None, false).ok();
    let auto_pick = gpu::choose(&list, None, true).ok();
    if a.json {
        let json = serde_json::json!({
            "devices": list,
            "gpu": gpu_pick,
            "auto": auto_pick,
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    if list.is_empty() {
        println!("no Vulkan device: the loader reports none");
    }
    for d in &list {
        println!("{}: {}", d.index, d.name);
        println!(
            "    type: {}; driver: {}; Vulkan {}",
            d.kind.name(),
            d.driver,
            d.api_version
        );
        println!(
            "    maxStorageBufferRange: {} bytes ({:.0} MiB); maxComputeWorkGroupInvocations: {}; \
             subgroup size: {}",
            d.max_storage_buffer_range,
            d.max_storage_buffer_range as f64 / 1048576.0,
            d.max_compute_work_group_invocations,
            d.subgroup_size
        );
        println!(
            "    timestamps: {}",
            if d.timestamps {
                format!("yes ({} ns per tick)", d.timestamp_period_ns)
            } else {
                "no".into()
            }
        );
        if let Some(why) = &d.unusable {
            println!("    unusable: {why}");
        }
    }
    match gpu_pick {
        Some(i) => println!("--backend gpu: device {i} ({})", list[i].name),
        None => println!("--backend gpu: no usable device (it fails)"),
    }
    match auto_pick {
        Some(i) => println!("--backend auto: device {i} ({})", list[i].name),
        None => println!("--backend auto: the CPU mirror ({})", auto_reason(&list)),
    }
    Ok(())
}

fn validate(a: ValidateArgs) -> Result<bool> {
    let scene = scene::load(&a.scene).map_err(user)?;
    let packed = pack::pack(&scene, &settings(&a.opts)).map_err(user)?;
    drop(scene);
    let g = Gpu::new(&gpu_options(&a.gpu)).map_err(|e| user(anyhow!("validate: {e}")))?;
    let gpu_frame = g
        .render(&packed, &gpu_options(&a.gpu), &|_, _| {})
        .map_err(gpu_err)?;
    let cpu_frame = render_cpu(&packed, a.opts.threads, &|_, _| {})?;
    let tol = Tolerance::default();
    let c = metrics::compare(&cpu_frame, &gpu_frame, &tol);
    if let Some(path) = &a.diff {
        output::format_of(path).map_err(user)?;
        let img = c.diff_image();
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .context("cannot encode the difference image")?;
        write_atomic(path, &bytes).map_err(user)?;
    }
    if let Some(path) = &a.json {
        let json = serde_json::json!({
            "scene": a.scene,
            "device": g.info().name,
            "comparison": c,
            "passed": c.passed(),
            "seconds": { "cpu": cpu_frame.seconds, "gpu_wall": gpu_frame.seconds, "gpu": gpu_frame.device_seconds },
        });
        write_atomic(path, serde_json::to_string_pretty(&json)?.as_bytes()).map_err(user)?;
    }
    if !a.quiet {
        println!(
            "{}: {}x{}, CPU mirror vs {}",
            a.scene.display(),
            c.width,
            c.height,
            g.info().name
        );
        println!("  max abs error    {:.3e}", c.max_abs);
        println!("  mean abs error   {:.3e}", c.mean_abs);
        println!("  RMSE             {:.3e}", c.rmse);
        println!("  PSNR             {:.1} dB", c.psnr);
        println!(
            "  mean FLIP        {:.5} (8-bit sRGB; limit {})",
            c.mean_flip, tol.mean_flip
        );
        println!(
            "  pixels over {:e} {} of {} ({:.3}%; limit {:.3}%)",
            tol.pixel,
            c.pixels_over,
            c.width as u64 * c.height as u64,
            c.fraction_over * 100.0,
            tol.fraction_over * 100.0
        );
        println!("  rays       {:>12} {:>12} {:>8}", "cpu", "gpu", "diff");
        for r in &c.rays {
            println!(
                "  {:<10} {:>12} {:>12} {:>+8}",
                r.kind,
                r.reference,
                r.test,
                r.diff()
            );
        }
        println!(
            "  time       cpu {:.3} s, gpu {:.3} s{}",
            cpu_frame.seconds,
            gpu_frame.seconds,
            gpu_frame
                .device_seconds
                .map(|s| format!(" (device {s:.3} s)"))
                .unwrap_or_default()
        );
    }
    if c.passed() {
        println!("PASS: the GPU matches the CPU mirror within tolerance");
    } else {
        println!("FAIL: {}", c.failures.join("; "));
    }
    Ok(c.passed())
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    output::write_atomically(path, |w| Ok(std::io::Write::write_all(w, bytes)?))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Render(a) => render(a),
        Command::Generate(a) => generate(a),
        Command::Export(a) => export(a),
        Command::Devices(a) => devices(a),
        Command::Validate(a) => match validate(a) {
            Ok(true) => Ok(()),
            Ok(false) => return ExitCode::from(1),
            Err(e) => Err(e),
        },
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if e.downcast_ref::<UserError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::from(3)
            }
        }
    }
}
