//! `whitted export`: a scene as POV-Ray 3.7 (.pov) or NFF (.nff) text.

use super::options::{DepthOpts, SizeOpts};
use super::Ui;
use crate::error::user;
use crate::files::{self, Dest, Output};
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
    /// Settings as `render --preset` takes them (the size, depth and
    /// cut-off written into the .pov file; POV-Ray has no corner sampling
    /// setting in the scene: `whitted bench` passes it on the command line).
    #[arg(long, value_enum)]
    pub preset: Option<crate::pack::Preset>,
    /// The image size written into the POV camera's aspect and the depth
    /// (POV-Ray: max_trace_level = max depth + 1, adc_bailout = min weight).
    #[command(flatten)]
    pub size: SizeOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
}

pub fn run(a: ExportArgs, ui: Ui) -> Result<u8> {
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
    let scene = super::load_scene(ui, &a.scene)?;
    let dest = Dest::new(&a.output);
    let base = a
        .preset
        .map(crate::pack::Preset::settings)
        .unwrap_or_default();
    let (max_depth, min_weight) = a.depth.resolve(&base);
    let text = match files::extension(&a.output).as_deref() {
        Some("nff") => crate::export::to_nff(&scene).map_err(user)?,
        _ => crate::export::to_pov(
            &scene,
            a.size.width.or(base.width).unwrap_or(scene.camera.width),
            a.size.height.or(base.height).unwrap_or(scene.camera.height),
            max_depth,
            min_weight,
        )
        .map_err(user)?,
    };
    files::write_bytes(&dest, text.as_bytes()).map_err(user)?;
    Ok(0)
}
