//! `whitted profile`: dispatch shapes and phases on one device
//! (`crate::profile`, docs/profiling.md).

use super::options::{parse_workgroup, GpuArgs, RenderOpts};
use super::{Bar, Ui};
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::profile::{self, Saved};
use anyhow::{anyhow, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct ProfileArgs {
    /// Scene file (.toml, .nff).
    pub scene: PathBuf,
    /// Workgroup shapes to try (specialization constants).
    #[arg(long, value_delimiter = ',', value_parser = parse_workgroup, value_name = "WxH,...",
          default_value = "8x8,16x16,32x4,16x4,64x1,32x1,8x1,1x1")]
    pub workgroups: Vec<[u32; 2]>,
    /// Tile edges to try (lattice samples per side of one submission);
    /// `full`: one tile for the image (up to the per-submission cap).
    #[arg(long, value_delimiter = ',', value_parser = profile::parse_tile, value_name = "N,...",
          default_value = "64,128,256,1024,full")]
    pub tiles: Vec<u32>,
    /// GPU kernels to profile (comma-separated, e.g. mega,wavefront): every
    /// shape and tile once per kernel; default: the one --kernel names
    /// (mega). With --save the winner's kernel is stored too. `calibration`
    /// (a plain grid tracer for opaque sphere fields) shows the yardstick
    /// against the best of the others, and is never the one saved.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "KERNEL,...")]
    pub kernels: Vec<crate::gpu::GpuKernel>,
    /// Timed renders per combination, after one warm-up each.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Every combination as CSV.
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    /// A heat map of workgroup shape against tile size (.svg or .png):
    /// each cell its median time over the best one's.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Store the fastest shape for this device and driver in the cache
    /// folder; `render` then uses it whenever neither --workgroup nor --tile
    /// is given (and says so with -v).
    #[arg(long)]
    pub save: bool,
    #[command(flatten)]
    pub opts: RenderOpts,
    #[command(flatten)]
    pub gpu: GpuArgs,
}

pub fn run(a: ProfileArgs, ui: Ui) -> Result<u8> {
    let outputs: Vec<Output> = [
        Output::optional("--csv", &a.csv, &["csv"], true),
        Output::optional("--plot", &a.plot, &["svg", "png"], false),
    ]
    .into_iter()
    .flatten()
    .collect();
    files::check_outputs(&outputs, &[&a.scene]).map_err(user)?;
    if let Some(p) = &a.plot {
        crate::plot::ready("--plot", p).map_err(user)?;
    }
    let t = Instant::now();
    let scene = super::load_scene(ui, &a.scene)?;
    let load = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let packed = crate::run::pack(&scene, &a.opts.settings(), a.opts.counting())?;
    let pack = t.elapsed().as_secs_f64();
    drop(scene);
    let base = crate::gpu::GpuOptions {
        saved_shape: false,
        saved_kernel: false,
        ..a.gpu.options()
    };
    let kernels = if a.kernels.is_empty() {
        vec![base.kernel]
    } else {
        a.kernels.clone()
    };
    let t = Instant::now();
    let g = crate::gpu::Gpu::new(&base).map_err(|e| user(anyhow!("profile: {e}")))?;
    let open = t.elapsed().as_secs_f64();
    // Phases: the first render of the default shape pays for the pipeline
    // and its first compile; a second one shows the steady state.
    let cold = g
        .render(&packed, &base, &|_, _| {})
        .map_err(crate::run::gpu_error)?;
    let warm = g
        .render(&packed, &base, &|_, _| {})
        .map_err(crate::run::gpu_error)?;
    let t = Instant::now();
    let mut png = Vec::new();
    crate::output::encode(
        &warm,
        crate::output::Format::Png,
        crate::output::Encoding::Srgb,
        &mut png,
    )?;
    let output = t.elapsed().as_secs_f64();
    let bar = Bar::new(ui, "profiling");
    let rows = profile::run(
        &g,
        &packed,
        &base,
        &kernels,
        &a.workgroups,
        &a.tiles,
        a.repeat,
        &|d, n| bar.set(d, n),
    );
    bar.finish();
    let rows = rows?;
    let info = g.info();
    if !ui.quiet {
        println!(
            "{}: {}x{} on {} ({}), {} rays per render",
            a.scene.display(),
            warm.width,
            warm.height,
            info.name,
            info.driver,
            warm.stats.total()
        );
        println!(
            "\nphases (seconds; first render / second render of {}x{}, tile {}):",
            base.workgroup[0],
            base.workgroup[1],
            crate::gpu::tile_for(base.tile, info.kind)
        );
        println!("  {:<10} {:>9}", "load", format!("{load:.4}"));
        println!("  {:<10} {:>9}", "pack", format!("{pack:.4}"));
        println!("  {:<10} {:>9}", "device", format!("{open:.4}"));
        for ((name, c), (_, w)) in cold.phases.iter().zip(&warm.phases) {
            println!("  {name:<10} {c:>9.4} / {w:.4}");
        }
        if let (Some(c), Some(w)) = (cold.device_seconds, warm.device_seconds) {
            println!("  {:<10} {c:>9.4} / {w:.4} (device clock)", "gpu time");
        }
        // The wavefront's stages, each summed over tiles and depths.
        for ((name, c), (_, w)) in cold.device_stages.iter().zip(&warm.device_stages) {
            println!("    {name:<14} {c:>9.4} / {w:.4} (device clock)");
        }
        println!("  {:<10} {:>9}", "output", format!("{output:.4}"));
        println!("\n{}", profile::table(&rows));
    }
    if let Some(p) = &a.csv {
        files::write_bytes(&Dest::new(p), profile::csv(&rows)?.as_bytes()).map_err(user)?;
    }
    if let Some(p) = &a.plot {
        let title = format!(
            "{} on {}: time / best",
            a.scene.file_name().unwrap_or_default().to_string_lossy(),
            info.name
        );
        crate::plot::draw_heat_map(&profile::heat_map(&rows, &title), p).map_err(user)?;
    }
    if a.save {
        let best = rows.iter().find(|r| r.best).ok_or_else(|| {
            user(anyhow!(
                "--save: no shape of a kernel that renders the scene's image ran (the device \
                     refused them, or only --kernels calibration was asked, which is never saved)"
            ))
        })?;
        let saved = Saved {
            device: info.name.clone(),
            driver: info.driver.clone(),
            workgroup: best.workgroup,
            tile: best.tile,
            kernel: best.kernel,
            measured_by: format!("whitted profile {}", a.scene.display()),
        };
        let path = profile::save(info, &saved)?;
        if !ui.quiet {
            println!(
                "saved the {} kernel, {}x{}, tile {} for {} in {}",
                best.kernel.name(),
                best.workgroup[0],
                best.workgroup[1],
                best.tile_name(),
                info.name,
                path.display()
            );
        }
    }
    Ok(0)
}
