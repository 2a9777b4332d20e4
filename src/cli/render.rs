//! `whitted render`: a scene to an image file (or standard output).

use super::options::{GpuArgs, RenderOpts};
use super::{Bar, Ui};
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::output::{self, Encoding};
use crate::run::{self, Backend, RenderOptions};
use anyhow::Result;
use clap::Args;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene file: native TOML (see docs/scene-format.md) or NFF (.nff).
    pub scene: PathBuf,
    /// Output image: .png (8-bit), .exr or .hdr (linear floats); `-` writes
    /// PNG to standard output. Default: the scene's name with .png, in the
    /// current directory.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub opts: RenderOpts,
    /// Where to render: `auto` uses a real GPU (discrete, integrated or
    /// virtual) when there is one and otherwise the CPU mirror, saying why
    /// on stderr, and finishes on the CPU mirror if the GPU fails; `gpu`
    /// uses the chosen Vulkan device, CPU ones (lavapipe) included, and
    /// fails when there is none (exit 2) or when it fails (exit 4); `cpu`
    /// the CPU mirror.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// The CPU tracer's float type: f32 is the GPU's twin (bit for bit on
    /// lavapipe), f64 the reference's arithmetic (CPU only; with --backend
    /// auto it renders on the CPU). The scene's packed data stay f32.
    #[arg(long, value_enum, default_value_t = run::Precision::F32)]
    pub precision: run::Precision,
    #[command(flatten)]
    pub gpu: GpuArgs,
    /// PNG encoding: sRGB, the clamped linear values round(255·v), or
    /// those at 16 bits, round(65535·v) (linear16).
    #[arg(long, value_enum, default_value_t = Encoding::Srgb)]
    pub encoding: Encoding,
    /// Write ray counts, work counters, timings and grid size as JSON.
    #[arg(long, value_name = "FILE.json")]
    pub stats: Option<PathBuf>,
}

/// The image path `render` writes: `-o`, or the scene's stem with .png.
pub fn output_path(a: &RenderArgs) -> PathBuf {
    match &a.output {
        Some(o) => o.clone(),
        None => PathBuf::from(format!(
            "{}.png",
            a.scene
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("out")
        )),
    }
}

pub fn run(a: RenderArgs, ui: Ui) -> Result<u8> {
    let t_start = Instant::now();
    let out = output_path(&a);
    let dest = Dest::new(&out);
    let mut outputs = vec![Output {
        flag: "-o",
        path: &out,
        extensions: &["png", "exr", "hdr"],
        stdout: true,
    }];
    if let Some(s) = &a.stats {
        outputs.push(Output {
            flag: "--stats",
            path: s,
            extensions: &["json"],
            stdout: true,
        });
    }
    files::check_outputs(&outputs, &[&a.scene]).map_err(user)?;
    if dest == Dest::Stdout && std::io::stdout().is_terminal() {
        return Err(user(anyhow::anyhow!(
            "-o -: standard output is a terminal; redirect it to a file or a program"
        )));
    }
    if a.backend == Backend::Cpu && a.gpu.gpu_math == crate::gpu::GpuMath::Fast {
        log::warn!("--gpu-math fast has no effect with --backend cpu");
    }
    let other_kernel = a.gpu.kernel.filter(|&k| k != crate::gpu::GpuKernel::Mega);
    if let Some(k) = other_kernel.filter(|_| a.backend == Backend::Cpu) {
        log::warn!("--kernel {} has no effect with --backend cpu", k.name());
    }
    // Surveying the Vulkan devices for `auto` overlaps reading and packing.
    let mut survey = run::DeviceSurvey::start(a.backend, a.precision, a.gpu.device);
    let scene = super::load_scene(ui, &a.scene)?;
    let t_load = t_start.elapsed().as_secs_f64();
    log::debug!("loaded {} in {t_load:.3} s", a.scene.display());
    let opts = RenderOptions {
        settings: a.opts.settings(),
        backend: a.backend,
        gpu: a.gpu.options(),
        threads: a.opts.threads,
        counting: a.opts.counting(),
        precision: a.precision,
        packet: a.opts.packet(),
    };
    let t_pack = Instant::now();
    let bar = Bar::new(ui, "packing");
    let packed = run::pack_with_progress(&scene, &opts.settings, opts.counting, &|s, d, t| {
        bar.pack_stage(s, d, t)
    });
    bar.finish();
    let packed = packed?;
    drop(scene);
    let t_build = t_pack.elapsed().as_secs_f64();
    log::debug!("packed in {t_build:.3} s");
    let bar = Bar::new(ui, "rendering");
    let r = run::render_packed_surveyed(&packed, &opts, &mut survey, &|d, t| bar.set(d, t));
    bar.finish();
    let mut r = r?;
    r.pack_seconds = t_build;
    if let Some(s) = r.frame.device_seconds {
        log::debug!("device time {s:.3} s ({} arithmetic)", opts.gpu.math.name());
    }
    let frame = &r.frame;
    output::write_to(frame, &dest, a.encoding).map_err(user)?;
    let total = t_start.elapsed().as_secs_f64();
    if let Some(path) = &a.stats {
        let rays = frame.stats.total().max(1) as f64;
        let per_ray = |n: u64| n as f64 / rays;
        let json = serde_json::json!({
            "backend": r.used,
            "precision": if r.used == run::Used::Cpu { Some(a.precision) } else { None },
            "device": r.device,
            "gpu_math": (r.used == run::Used::Gpu).then_some(opts.gpu.math),
            "gpu_kernel": r.kernel,
            "width": frame.width,
            "height": frame.height,
            "rays": frame.stats,
            "counting": packed.counting(),
            "work": {
                "intersection_tests": frame.work.tests,
                "cells_visited": frame.work.cells,
                "nodes_visited": frame.work.nodes,
                // The most children a BVH walk (or the octree's stack
                // walk) held pushed at once.
                "deepest_stack": frame.work.stack,
            },
            // The same split by the kind of ray that asked: the eye rays'
            // closest hits, the reflected and refracted rays' (secondary),
            // the shadow feelers'; totals and per ray of that kind.
            "work_by_ray": work_by_ray(&frame.stats, &frame.work),
            // The same over every ray counted (eye, reflected, refracted,
            // feelers): what one ray costs the structure.
            "work_per_ray": {
                "intersection_tests": per_ray(frame.work.tests),
                "cells_visited": per_ray(frame.work.cells),
                "nodes_visited": per_ray(frame.work.nodes),
            },
            "accel": packed.accel,
            "seconds": {
                "load": t_load,
                "build": t_build,
                "render": frame.seconds,
                "gpu": frame.device_seconds,
                // The wavefront kernel's stages (empty otherwise).
                "gpu_stages": frame
                    .device_stages
                    .iter()
                    .map(|(k, v)| (k.to_string(), serde_json::json!(v)))
                    .collect::<serde_json::Map<_, _>>(),
                "total": total,
            },
            "peak_memory_bytes": crate::sys::peak_memory(),
            "grid": {
                "cells": packed.grid.cells,
                "refs": packed.grid.refs,
                "bytes": packed.grid.bytes,
                "build_seconds": packed.grid.seconds,
                "duplicates": packed.grid.duplicates,
            },
            "shadows": if packed.globals.flags[3] > 0 { "lightbuffer" } else { "plain" },
            "light_buffer": packed.lightbuf,
        });
        files::write_bytes(
            &Dest::new(path),
            serde_json::to_string_pretty(&json)?.as_bytes(),
        )
        .map_err(user)?;
    }
    if !ui.quiet {
        let accel = &packed.accel;
        let structure = match accel.structure {
            crate::pack::Accel::Bvh => format!(
                "BVH of {} nodes, depth {}, built in {:.3} s",
                accel.nodes, accel.depth, accel.build_seconds
            ),
            crate::pack::Accel::Octree => format!(
                "octree of {} nodes, {} leaves, depth {}, built in {:.3} s",
                accel.nodes, accel.leaves, accel.depth, accel.build_seconds
            ),
            crate::pack::Accel::Hybrid => format!(
                "hybrid: grid {}x{}x{}, crowded cells' BVHs of {} nodes, built in {:.3} s",
                packed.grid.cells[0],
                packed.grid.cells[1],
                packed.grid.cells[2],
                accel.nodes,
                accel.build_seconds
            ),
            _ => format!(
                "grid {}x{}x{}, {} refs, built in {:.3} s",
                packed.grid.cells[0],
                packed.grid.cells[1],
                packed.grid.cells[2],
                packed.grid.refs,
                packed.grid.seconds,
            ),
        };
        eprintln!(
            "{}: {}x{} on {} in {:.3} s ({:.2} Mrays/s; {structure})",
            dest.display(),
            frame.width,
            frame.height,
            r.device,
            frame.seconds,
            frame.stats.total() as f64 / frame.seconds.max(1e-9) / 1e6,
        );
    }
    Ok(0)
}

/// `--stats`' `work_by_ray`: the work counters of each kind of ray (eye,
/// secondary: reflected and refracted, shadow), in all and per ray of
/// that kind (`Work::by_kind`).
pub(crate) fn work_by_ray(
    stats: &crate::trace::RayStats,
    w: &crate::trace::query::Work,
) -> serde_json::Value {
    let (work, rays) = (w.by_kind(), stats.by_kind());
    let kind = |k: usize| {
        let (c, rays) = (work[k], rays[k]);
        let per = |n: u64| n as f64 / rays.max(1) as f64;
        serde_json::json!({
            "rays": rays,
            "intersection_tests": c[0],
            "cells_visited": c[1],
            "nodes_visited": c[2],
            "per_ray": {
                "intersection_tests": per(c[0]),
                "cells_visited": per(c[1]),
                "nodes_visited": per(c[2]),
            },
        })
    };
    serde_json::json!({
        "eye": kind(0),
        "secondary": kind(1),
        "shadow": kind(2),
    })
}
