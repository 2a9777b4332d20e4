//! `whitted generate`: procedural scenes for benchmarks, written as NFF.

use super::Ui;
use crate::error::user;
use crate::files::{self, Dest, Output};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct GenerateArgs {
    /// Spheres scattered in the cube [-1,1]³, radius 0.45 × their mean
    /// spacing, over a floor, lit by three lights (see src/gen/mod.rs).
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u64).range(1..=50_000_000))]
    pub count: u64,
    /// Seed of the placement (same seed, same scene).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write a sphereflake of this level instead ((9^(L+1) − 1)/8 spheres
    /// over a floor; level 6 has 597 871).
    #[arg(long, value_name = "LEVEL", conflicts_with_all = ["count", "seed"], value_parser = clap::value_parser!(u32).range(0..=7))]
    pub sphereflake: Option<u32>,
    /// Output .nff file (`-` for standard output).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(a: GenerateArgs, _ui: Ui) -> Result<u8> {
    files::check_outputs(
        &[Output {
            flag: "-o",
            path: &a.output,
            extensions: &["nff"],
            stdout: true,
        }],
        &[],
    )
    .map_err(user)?;
    let scene = match a.sphereflake {
        Some(level) => crate::gen::sphereflake(level),
        None => crate::gen::random_spheres(a.count as usize, a.seed),
    };
    let text = crate::export::to_nff(&scene)?;
    files::write_bytes(&Dest::new(&a.output), text.as_bytes()).map_err(user)?;
    Ok(0)
}
