//! `whitted stability`: the failure-mode studies (`crate::stability`).

use super::options::GpuArgs;
use super::{Bar, Ui};
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::stability::{self, Ctx};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct StabilityArgs {
    /// The report as Markdown (default: standard output).
    #[arg(short, long, value_name = "REPORT.md")]
    pub output: Option<PathBuf>,
    /// Run only these studies: offset, grazing, critical, structure,
    /// watertight, distance, scale, quadric, precision (default: all).
    #[arg(long, value_delimiter = ',', value_name = "STUDY,...")]
    pub only: Vec<String>,
    /// Every table cell as CSV (study, case, column, value).
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    /// Write the pictures (PNG) into this folder and link them from the
    /// report (relative to the report's folder when they are inside it).
    #[arg(long, value_name = "DIR")]
    pub pictures: Option<PathBuf>,
    /// CPU only, even when a Vulkan device could be opened.
    #[arg(long)]
    pub no_gpu: bool,
    /// Leave POV-Ray out of the distance study even when it is installed.
    #[arg(long)]
    pub no_povray: bool,
    #[command(flatten)]
    pub gpu: GpuArgs,
}

pub fn run(a: StabilityArgs, ui: Ui) -> Result<u8> {
    let outputs: Vec<Output> = [
        Output::optional("-o", &a.output, &["md"], true),
        Output::optional("--csv", &a.csv, &["csv"], true),
    ]
    .into_iter()
    .flatten()
    .collect();
    files::check_outputs(&outputs, &[]).map_err(user)?;
    if let Some(d) = &a.pictures {
        std::fs::create_dir_all(d)
            .map_err(|e| user(anyhow::anyhow!("--pictures {}: {e}", d.display())))?;
    }
    let gpu_options = a.gpu.options();
    let gpu = if a.no_gpu {
        None
    } else {
        match crate::gpu::Gpu::new(&gpu_options) {
            Ok(g) => {
                log::info!("GPU figures on {}", g.info().name);
                Some(g)
            }
            Err(e) => {
                log::info!("CPU figures only: {e}");
                None
            }
        }
    };
    let povray = !a.no_povray && crate::povray::available();
    let ctx = Ctx {
        gpu: gpu.as_ref(),
        gpu_options,
        povray,
    };
    let bar = Bar::new(ui, "studies");
    let reports = stability::run(&ctx, &a.only, &|d, n| bar.set(d, n));
    bar.finish();
    let reports = reports?;
    if let Some(d) = &a.pictures {
        for r in &reports {
            for (name, img) in &r.pictures {
                let mut bytes = Vec::new();
                img.write_to(
                    &mut std::io::Cursor::new(&mut bytes),
                    image::ImageFormat::Png,
                )?;
                files::write_bytes(&Dest::File(d.join(format!("{name}.png"))), &bytes)
                    .map_err(user)?;
            }
        }
    }
    let link = a.pictures.as_ref().map(|d| {
        let base = a
            .output
            .as_ref()
            .and_then(|o| o.parent())
            .filter(|p| !p.as_os_str().is_empty());
        match base.and_then(|b| d.strip_prefix(b).ok()) {
            Some(rel) => rel.display().to_string(),
            None => d.display().to_string(),
        }
    });
    let device = match &gpu {
        Some(g) => format!("GPU: {}", g.info().name),
        None => "no GPU".into(),
    };
    let mut command = String::from("whitted stability");
    if !a.only.is_empty() {
        command += &format!(" --only {}", a.only.join(","));
    }
    if let Some(p) = &a.pictures {
        command += &format!(" --pictures {}", p.display());
    }
    if let Some(o) = &a.output {
        command += &format!(" -o {}", o.display());
    }
    let machine = format!(
        "{} ({device}{})",
        crate::sys::machine(),
        if povray { ", POV-Ray 3.7" } else { "" }
    );
    let md = stability::markdown(&reports, &command, &machine, link.as_deref());
    match &a.output {
        Some(o) => files::write_bytes(&Dest::new(o), md.as_bytes()).map_err(user)?,
        None => print!("{md}"),
    }
    if let Some(c) = &a.csv {
        files::write_bytes(&Dest::new(c), stability::csv(&reports)?.as_bytes()).map_err(user)?;
    }
    Ok(0)
}
