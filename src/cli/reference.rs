//! `whitted reference`: render (or fetch from the cache) a scene's
//! reference image: f64, many stratified samples, the deepest tree, no
//! adaptive cut-off (`crate::reference`).

use super::options::SizeOpts;
use super::{Bar, Ui};
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::reference::{self, Cache, RefSettings};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReferenceArgs {
    /// Scene file (.toml, .nff).
    pub scene: PathBuf,
    /// Also write the reference here: .exr or .hdr (linear floats), .png
    /// (8-bit sRGB).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub size: SizeOpts,
    /// Stratified, jittered samples per pixel.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub spp: u32,
    /// Generations of reflection and refraction [default: the tracer's
    /// limit, 16].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=crate::constants::MAX_DEPTH_LIMIT as i64))]
    pub max_depth: Option<u32>,
    /// The reference cache folder (default: $XDG_CACHE_HOME/whitted/references
    /// or ~/.cache/whitted/references); `off`: neither read nor written.
    /// Entries are keyed by a hash of the scene's content and these
    /// settings, so an edited scene never gets a stale reference.
    #[arg(long, value_name = "DIR|off")]
    pub cache: Option<PathBuf>,
    /// Render again even when the cache has it (and replace it).
    #[arg(long)]
    pub force: bool,
    /// Memory the run may use (see `whitted render --help`).
    #[arg(long, value_name = "SIZE", value_parser = crate::budget::Budget::parse)]
    pub memory_limit: Option<crate::budget::Budget>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

/// The cache a `--cache` option names.
pub fn cache_of(opt: &Option<PathBuf>) -> Cache {
    match opt {
        None => Cache::Default,
        Some(p) if p.as_os_str() == "off" => Cache::Off,
        Some(p) => Cache::Dir(p.clone()),
    }
}

/// The reference's size: the options', else the scene's.
pub fn ref_settings(
    scene: &crate::scene::Scene,
    size: &SizeOpts,
    spp: u32,
    max_depth: Option<u32>,
) -> RefSettings {
    let mut rs = RefSettings::new(
        size.width.unwrap_or(scene.camera.width),
        size.height.unwrap_or(scene.camera.height),
    );
    rs.spp = spp;
    if let Some(d) = max_depth {
        rs.max_depth = d;
    }
    rs
}

pub fn run(a: ReferenceArgs, ui: Ui) -> Result<u8> {
    let outputs: Vec<Output> = Output::optional("-o", &a.output, &["exr", "hdr", "png"], false)
        .into_iter()
        .collect();
    files::check_outputs(&outputs, &[&a.scene]).map_err(user)?;
    let scene = super::load_scene(ui, &a.scene)?;
    let rs = ref_settings(&scene, &a.size, a.spp, a.max_depth);
    let cache = cache_of(&a.cache);
    let budget = a.memory_limit.unwrap_or_else(crate::budget::Budget::system);
    if a.force {
        if let Some(d) = cache.dir() {
            let _ = std::fs::remove_file(d.join(format!("{}.exr", reference::key(&scene, &rs))));
        }
    }
    let bar = Bar::new(ui, "reference");
    let t = std::time::Instant::now();
    let r = reference::get(&scene, &rs, &cache, budget, a.threads, &|d, n| {
        bar.set(d, n)
    });
    bar.finish();
    let r = r?;
    if let Some(o) = &a.output {
        crate::output::write_to(&r.frame, &Dest::new(o), crate::output::Encoding::Srgb)
            .map_err(user)?;
    }
    if !ui.quiet {
        let from = match (&r.path, r.cached) {
            (Some(p), true) => format!("from the cache, {}", p.display()),
            (Some(p), false) => format!(
                "rendered in {:.2} s, cached as {}",
                t.elapsed().as_secs_f64(),
                p.display()
            ),
            (None, _) => format!("rendered in {:.2} s, not cached", t.elapsed().as_secs_f64()),
        };
        eprintln!(
            "reference {}x{}, {} spp, depth {}, f64: {from}",
            rs.width, rs.height, rs.spp, rs.max_depth
        );
    }
    Ok(0)
}
