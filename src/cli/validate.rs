//! `whitted validate`: the same packed scene on the GPU and on the CPU
//! mirror, compared (docs/gpu.md).

use super::options::{GpuArgs, RenderOpts};
use super::Ui;
use crate::error::{user, EXIT_MISMATCH};
use crate::files::{self, Dest, Output};
use crate::gpu::Gpu;
use crate::metrics::{self, Tolerance};
use crate::run;
use anyhow::{anyhow, Context, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ValidateArgs {
    /// Scene file: native TOML (see docs/scene-format.md) or NFF (.nff).
    pub scene: PathBuf,
    #[command(flatten)]
    pub opts: RenderOpts,
    #[command(flatten)]
    pub gpu: GpuArgs,
    /// Write an image of the per-pixel error (PNG): black where the
    /// backends agree; the per-pixel tolerance is the middle of the colour
    /// scale, brighter is over it.
    #[arg(long, value_name = "DIFF.png")]
    pub diff: Option<PathBuf>,
    /// Write the comparison as JSON (`-` for standard output).
    #[arg(long, value_name = "FILE.json")]
    pub json: Option<PathBuf>,
}

pub fn run(a: ValidateArgs, ui: Ui) -> Result<u8> {
    let mut outputs = Vec::new();
    if let Some(p) = &a.diff {
        outputs.push(Output {
            flag: "--diff",
            path: p,
            extensions: &["png"],
            stdout: false,
        });
    }
    if let Some(p) = &a.json {
        outputs.push(Output {
            flag: "--json",
            path: p,
            extensions: &["json"],
            stdout: true,
        });
    }
    files::check_outputs(&outputs, &[&a.scene]).map_err(user)?;
    let scene = super::load_scene(ui, &a.scene)?;
    let bar = super::Bar::new(ui, "packing");
    let packed =
        run::pack_with_progress(&scene, &a.opts.settings(), a.opts.counting(), &|s, d, t| {
            bar.pack_stage(s, d, t)
        });
    bar.finish();
    let packed = packed?;
    drop(scene);
    let gopts = a.gpu.options();
    let g = Gpu::new(&gopts).map_err(|e| user(anyhow!("validate: {e}")))?;
    let gpu_frame = g
        .render(&packed, &gopts, &|_, _| {})
        .map_err(run::gpu_error)?;
    let cpu_frame = run::render_cpu(
        &packed,
        a.opts.threads,
        run::Precision::F32,
        a.opts.packet(),
        &|_, _| {},
    )?;
    let tol = Tolerance::for_kernel(g.info().kind, gopts.math);
    let c = metrics::compare(&cpu_frame, &gpu_frame, &tol);
    if let Some(path) = &a.diff {
        let img = c.diff_image();
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .context("cannot encode the difference image")?;
        files::write_bytes(&Dest::new(path), &bytes).map_err(user)?;
    }
    if let Some(path) = &a.json {
        let json = serde_json::json!({
            "scene": a.scene,
            "device": g.info().name,
            "gpu_math": gopts.math,
            "gpu_kernel": gopts.kernel,
            "comparison": c,
            // Where each side's walks went, per kind of ray (as render's
            // --stats; informational, not part of the verdict).
            "work_by_ray": {
                "cpu": super::render::work_by_ray(&cpu_frame.stats, &cpu_frame.work),
                "gpu": super::render::work_by_ray(&gpu_frame.stats, &gpu_frame.work),
            },
            "passed": c.passed(),
            "seconds": { "cpu": cpu_frame.seconds, "gpu_wall": gpu_frame.seconds, "gpu": gpu_frame.device_seconds },
        });
        files::write_bytes(
            &Dest::new(path),
            serde_json::to_string_pretty(&json)?.as_bytes(),
        )
        .map_err(user)?;
    }
    // With --json -, stdout carries the JSON alone.
    let to_stdout = a.json.as_deref() != Some(std::path::Path::new("-"));
    if !ui.quiet && to_stdout {
        println!(
            "{}: {}x{}, CPU mirror vs {} ({} arithmetic)",
            a.scene.display(),
            c.width,
            c.height,
            g.info().name,
            gopts.math.name()
        );
        println!("  max abs error    {:.3e}", c.max_abs);
        println!("  mean abs error   {:.3e}", c.mean_abs);
        println!("  RMSE             {:.3e}", c.rmse);
        println!("  PSNR             {:.1} dB", c.psnr);
        println!(
            "  mean FLIP        {:.5} (8-bit sRGB; limit {})",
            c.mean_flip, tol.mean_flip
        );
        println!(
            "  pixels over {:e} {} of {} ({:.3}%; limit {:.3}%)",
            tol.pixel,
            c.pixels_over,
            c.width as u64 * c.height as u64,
            c.fraction_over * 100.0,
            tol.fraction_over * 100.0
        );
        println!("  rays       {:>12} {:>12} {:>8}", "cpu", "gpu", "diff");
        for r in &c.rays {
            println!(
                "  {:<10} {:>12} {:>12} {:>+8}",
                r.kind,
                r.reference,
                r.test,
                r.diff()
            );
        }
        // The walks' work per kind of ray on each side (not part of the
        // verdict): tests, and cells and nodes together, per ray.
        println!(
            "  work/ray   {:>12} {:>12} {:>12} {:>12}",
            "cpu tests", "gpu tests", "cpu steps", "gpu steps"
        );
        // Per ray of kind k on a frame: (tests, cells + nodes).
        let per = |f: &crate::cpu::Frame, k: usize| {
            let (w, rays) = (f.work.by_kind()[k], f.stats.by_kind()[k].max(1) as f64);
            (w[0] as f64 / rays, (w[1] + w[2]) as f64 / rays)
        };
        for (k, kind) in ["eye", "secondary", "shadow"].iter().enumerate() {
            let (c, g) = (per(&cpu_frame, k), per(&gpu_frame, k));
            println!(
                "  {:<10} {:>12.3} {:>12.3} {:>12.3} {:>12.3}",
                kind, c.0, g.0, c.1, g.1
            );
        }
        println!(
            "  time       cpu {:.3} s, gpu {:.3} s{}",
            cpu_frame.seconds,
            gpu_frame.seconds,
            gpu_frame
                .device_seconds
                .map(|s| format!(" (device {s:.3} s)"))
                .unwrap_or_default()
        );
    }
    let verdict = if c.passed() {
        "PASS: the GPU matches the CPU mirror within tolerance".to_string()
    } else {
        format!("FAIL: {}", c.failures.join("; "))
    };
    if to_stdout {
        println!("{verdict}");
    } else {
        eprintln!("{verdict}");
    }
    Ok(if c.passed() { 0 } else { EXIT_MISMATCH })
}
