//! The `whitted` command line.

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use whitted::output::{self, Encoding};
use whitted::pack::{self, Sampling, Settings};
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
    /// Write a procedural scene (for benchmarks) as NFF.
    ///
    /// Example: whitted generate --count 100000 -o spheres-100k.nff
    Generate(GenerateArgs),
    /// Convert a scene to POV-Ray 3.7 (.pov) or NFF (.nff), e.g. to time
    /// POV-Ray on the same scene (scripts/povray-compare.sh).
    Export(ExportArgs),
}

#[derive(Args)]
struct GenerateArgs {
    /// Spheres scattered in the cube [-1,1]³, radius 0.3 × their mean
    /// spacing, over a floor, lit by three lights (see src/gen.rs).
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u64).range(1..=50_000_000))]
    count: u64,
    /// Seed of the placement (same seed, same scene).
    #[arg(long, default_value_t = 1)]
    seed: u64,
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
    /// Where to render.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
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
    let packed = pack::pack(&scene, &settings(&a.opts));
    drop(scene);
    let t_build = t_build0.elapsed().as_secs_f64();

    let (backend, device) = match a.opts.backend {
        Backend::Gpu => bail!(UserError(anyhow!(
            "--backend gpu: the Vulkan backend is not available in this build"
        ))),
        Backend::Auto | Backend::Cpu => ("cpu", "CPU mirror".to_string()),
    };
    let pool = {
        let mut b = rayon::ThreadPoolBuilder::new();
        if let Some(n) = a.opts.threads {
            b = b.num_threads(n as usize);
        }
        b.build().context("cannot start worker threads")?
    };
    let bar = progress_bar(a.quiet);
    let started = Instant::now();
    let quiet = a.quiet;
    let frame = pool.install(|| {
        cpu::render(&packed, &|done, total| {
            if !quiet && bar.is_hidden() && started.elapsed().as_secs_f64() > 1.0 {
                bar.set_length(total);
                bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            }
            bar.set_length(total);
            bar.set_position(done);
        })
    });
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
    let scene = whitted::gen::random_spheres(a.count as usize, a.seed);
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

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::NamedTempFile::new_in(dir).with_context(|| {
        format!(
            "{}: cannot create a file in {}",
            path.display(),
            dir.display()
        )
    })?;
    std::io::Write::write_all(&mut tmp, bytes)?;
    tmp.persist(path)
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Render(a) => render(a),
        Command::Generate(a) => generate(a),
        Command::Export(a) => export(a),
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
