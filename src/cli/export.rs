//! `whitted export`: a scene as POV-Ray 3.7 (.pov) or NFF (.nff) text.

use super::options::parse_weight;
use super::Ui;
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::scene;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    /// Scene file (.toml or .nff).
    pub scene: PathBuf,
    /// Output: .pov (POV-Ray 3.7) or .nff; `-` writes POV-Ray text to
    /// standard output.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Image width written into the POV camera's aspect (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub height: Option<u32>,
    /// Generations of secondary rays (POV-Ray: max_trace_level = this + 1).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=crate::constants::MAX_DEPTH_LIMIT as i64))]
    pub max_depth: u32,
    /// Adaptive depth cut-off (POV-Ray: adc_bailout).
    #[arg(long, default_value_t = 1.0 / 256.0, value_parser = parse_weight)]
    pub min_weight: f32,
}

pub fn run(a: ExportArgs, _ui: Ui) -> Result<u8> {
    files::check_outputs(
        &[Output {
            flag: "-o",
            path: &a.output,
            extensions: &["pov", "nff"],
            stdout: true,
        }],
        &[&a.scene],
    )
    .map_err(user)?;
    let scene = scene::load(&a.scene).map_err(user)?;
    let dest = Dest::new(&a.output);
    let text = match files::extension(&a.output).as_deref() {
        Some("nff") => crate::export::to_nff(&scene).map_err(user)?,
        _ => crate::export::to_pov(
            &scene,
            a.width.unwrap_or(scene.camera.width),
            a.height.unwrap_or(scene.camera.height),
            a.max_depth,
            a.min_weight,
        )
        .map_err(user)?,
    };
    files::write_bytes(&dest, text.as_bytes()).map_err(user)?;
    Ok(0)
}
