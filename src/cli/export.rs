//! `whitted export`: a scene as POV-Ray 3.7 (.pov) or NFF (.nff) text.

use super::options::{DepthOpts, SizeOpts};
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
    /// The image size written into the POV camera's aspect and the depth
    /// (POV-Ray: max_trace_level = max depth + 1, adc_bailout = min weight).
    #[command(flatten)]
    pub size: SizeOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
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
            a.size.width.unwrap_or(scene.camera.width),
            a.size.height.unwrap_or(scene.camera.height),
            a.depth.max_depth,
            a.depth.min_weight,
        )
        .map_err(user)?,
    };
    files::write_bytes(&dest, text.as_bytes()).map_err(user)?;
    Ok(0)
}
