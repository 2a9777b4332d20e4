//! `whitted generate`: procedural scenes for benchmarks, written as NFF:
//! the SPD's seven scenes at any size factor, random spheres, sphereflakes.

use super::Ui;
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::gen::spd::{self, SpdScene};
use anyhow::{anyhow, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
#[command(after_long_help = spd_help())]
pub struct GenerateArgs {
    /// One of the SPD's seven scenes (balls, gears, mount, rings, teapot,
    /// tetra, tree; see below and docs/spd.md). Without it: random spheres
    /// (--count, --seed) or a sphereflake (--sphereflake).
    #[arg(value_name = "NAME", value_parser = parse_spd)]
    pub name: Option<SpdScene>,
    /// The SPD size factor (default: the SPD program's: balls 4, gears 4,
    /// mount 6, rings 7, teapot 6, tetra 6, tree 11; the SPD's published
    /// teapot statistics are for size 12).
    #[arg(long, requires = "name", value_parser = clap::value_parser!(u32).range(1..=64))]
    pub size: Option<u32>,
    /// Spheres scattered in the cube [-1,1]³, radius 0.45 × their mean
    /// spacing, over a floor, lit by three lights (see src/gen/mod.rs)
    /// [default: 10000].
    #[arg(long, conflicts_with = "name", value_parser = clap::value_parser!(u64).range(1..=50_000_000))]
    pub count: Option<u64>,
    /// Seed of the random spheres' placement (same seed, same scene).
    #[arg(long, default_value_t = 1, conflicts_with = "name")]
    pub seed: u64,
    /// Write a sphereflake of this level instead ((9^(L+1) − 1)/8 spheres
    /// over a floor; level 6 has 597 871).
    #[arg(long, value_name = "LEVEL", conflicts_with_all = ["count", "name"], value_parser = clap::value_parser!(u32).range(0..=7))]
    pub sphereflake: Option<u32>,
    /// Output .nff file (`-` for standard output).
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_spd(s: &str) -> Result<SpdScene, String> {
    s.parse::<SpdScene>().map_err(|e| e.to_string())
}

fn spd_help() -> String {
    let mut s = String::from("The SPD scenes:\n");
    for sc in SpdScene::ALL {
        s.push_str(&format!(
            "  {:<7} (default size {:>2}) {}\n",
            sc.name(),
            sc.default_size(),
            sc.about()
        ));
    }
    s
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
    let scene = match (a.name, a.sphereflake) {
        (Some(name), _) => spd::generate(name, a.size).map_err(|e| user(anyhow!(e)))?,
        (None, Some(level)) => crate::gen::sphereflake(level),
        (None, None) => crate::gen::random_spheres(a.count.unwrap_or(10_000) as usize, a.seed),
    };
    let text = crate::export::to_nff(&scene)?;
    files::write_bytes(&Dest::new(&a.output), text.as_bytes()).map_err(user)?;
    Ok(0)
}
