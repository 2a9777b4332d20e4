//! `whitted chart`: speed against accuracy for one scene (`crate::chart`).

use super::options::{GpuArgs, SizeOpts};
use super::{Bar, Ui};
use crate::chart::{self, Knob, Plan};
use crate::error::user;
use crate::files::{self, Dest, Output};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ChartArgs {
    /// Scene file (.toml, .nff).
    pub scene: PathBuf,
    /// The chart: error against time on log axes, one series per knob, the
    /// Pareto front ringed (.svg or .png).
    #[arg(short, long, value_name = "CHART.svg")]
    pub output: PathBuf,
    /// Also draw it as PNG here.
    #[arg(long, value_name = "FILE.png")]
    pub png: Option<PathBuf>,
    /// Every point as CSV: times, Mrays/s, both errors, Pareto flag.
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    #[command(flatten)]
    pub size: SizeOpts,
    /// The knobs to sweep, each from the defaults of `whitted render`
    /// (default: all; `backend` adds GPU points when a Vulkan device,
    /// lavapipe included, can be opened).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub knobs: Option<Vec<Knob>>,
    /// Timed runs per point, after one warm-up; the chart shows the median.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Samples per pixel of the reference (f64, depth 16, no cut-off):
    /// 256 (16 × 16 strata), well past the sweep's 64 (8 × 8), whose
    /// samples it would otherwise share.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub reference_spp: u32,
    /// The reference cache (see `whitted reference --help`).
    #[arg(long, value_name = "DIR|off")]
    pub cache: Option<PathBuf>,
    /// Memory the run may use (see `whitted render --help`).
    #[arg(long, value_name = "SIZE", value_parser = crate::budget::Budget::parse)]
    pub memory_limit: Option<crate::budget::Budget>,
    /// Worker threads for the CPU points (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    #[command(flatten)]
    pub gpu: GpuArgs,
}

pub fn run(a: ChartArgs, ui: Ui) -> Result<u8> {
    let mut outputs = vec![Output {
        flag: "-o",
        path: &a.output,
        extensions: &["svg", "png"],
        stdout: false,
    }];
    outputs.extend(Output::optional("--png", &a.png, &["png"], false));
    outputs.extend(Output::optional("--csv", &a.csv, &["csv"], true));
    files::check_outputs(&outputs, &[&a.scene]).map_err(user)?;
    crate::plot::ready("-o", &a.output).map_err(user)?;
    let scene = super::load_scene(ui, &a.scene)?;
    let mut reference = super::reference::ref_settings(&scene, &a.size, a.reference_spp, None);
    reference.sampling = crate::pack::Sampling::Centers;
    let plan = Plan {
        width: reference.width,
        height: reference.height,
        runs: a.runs,
        knobs: a.knobs.clone().unwrap_or_else(|| Knob::ALL.to_vec()),
        reference,
        cache: super::reference::cache_of(&a.cache),
        budget: a.memory_limit.unwrap_or_else(crate::budget::Budget::system),
        threads: a.threads,
        gpu: a.gpu.options(),
    };
    let bar = Bar::new(ui, "chart");
    bar.stage("reference");
    let points = chart::run(&plan, &scene, &|d, n| {
        bar.stage("points");
        bar.set(d, n)
    });
    bar.finish();
    let points = points?;
    let name = a
        .scene
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let title = format!(
        "{name}, {}x{}: error against time (reference: f64, {} spp, depth {})",
        plan.width, plan.height, plan.reference.spp, plan.reference.max_depth
    );
    let c = chart::chart(&points, &title);
    crate::plot::draw(&c, &a.output).map_err(user)?;
    if let Some(p) = &a.png {
        crate::plot::draw(&c, p).map_err(user)?;
    }
    if let Some(p) = &a.csv {
        files::write_bytes(&Dest::new(p), chart::csv(&points)?.as_bytes()).map_err(user)?;
    }
    if !ui.quiet {
        eprint!("{}", chart::table(&points));
        match chart::cheapest_within_step(&points) {
            Some(p) => eprintln!(
                "cheapest within 1/255 (RMSE): {} = {} in {:.3} s",
                p.knob.name(),
                p.value,
                p.seconds.median
            ),
            None => eprintln!(
                "no point is within 1/255 (RMSE) of the reference: raise --spp with the \
                 other settings at their cheapest"
            ),
        }
        eprintln!("wrote {}", a.output.display());
    }
    Ok(0)
}
