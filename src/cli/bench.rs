//! `whitted bench`: the suite, the engines, the table, CSV and plots
//! (the measuring itself is `crate::bench`).

use super::{Bar, Ui};
use crate::bench::{self, Case, Engine, Plan};
use crate::error::user;
use crate::files::{self, Dest, Output};
use crate::gen;
use crate::gen::spd::{self, SpdScene};
use crate::gpu::{GpuKernel, GpuMath};
use crate::scene::Scene;
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};

/// Which scenes the suite holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Suite {
    /// The SPD's seven scenes (generated at --size) under --preset spd,
    /// counting the rays traced (--counting traced: the image's rays, not
    /// the SPD's statistics).
    Spd,
    /// The example scenes in --scenes (default `scenes/`) at their own size.
    Examples,
    /// 20 000 random spheres (`whitted generate --count 20000`), 1024x768, depth 5.
    Spheres,
}

#[derive(Args)]
pub struct BenchArgs {
    /// Scene groups to run (comma-separated); default: all of them.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub suite: Vec<Suite>,
    /// SPD size factor for the SPD scenes (default: each scene's own, as
    /// `whitted generate NAME`).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub size: Option<u32>,
    /// Instead of the suite: SPD balls of size 1 to 6 (--preset spd) and random
    /// spheres from 1 k to 1 M, to see how time, rays and memory grow with
    /// the primitive count (fitted exponents printed; --plot draws them).
    #[arg(long, conflicts_with = "suite")]
    pub scaling: bool,
    /// Timed runs per case and engine (after the warm-up).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Untimed runs per case and engine first.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=100))]
    pub warmup: u32,
    /// whitted backends to time (comma-separated): default every one this
    /// machine has (the CPU mirror, and the GPU when there is a Vulkan
    /// device, lavapipe included). `auto` is `render`'s default: a real
    /// GPU when there is one, otherwise the CPU mirror, its wall time
    /// including the survey of the Vulkan devices that decides.
    #[arg(long, value_delimiter = ',', value_parser = ["cpu", "gpu", "auto"])]
    pub backends: Vec<String>,
    /// Acceleration structures to time (comma-separated): every backend
    /// once per structure, labelled e.g. cpu/bvh; default: `auto`'s choice
    /// only (docs/method.md, "Choosing the structure").
    #[arg(long, value_delimiter = ',', value_parser = ["grid", "bvh", "octree", "hybrid", "auto"])]
    pub accel: Vec<String>,
    /// Shadow methods to time (comma-separated, e.g. plain,lightbuffer):
    /// every backend (and structure) once per method, labelled e.g.
    /// cpu/lightbuffer; default: plain only (`render --shadows`, and
    /// docs/method.md, "Light buffers").
    #[arg(long, value_delimiter = ',', value_parser = ["plain", "lightbuffer"])]
    pub shadows: Vec<String>,
    /// GPU kernels to time (comma-separated, e.g. exact,fast): the gpu
    /// backend once per kernel, the fast one labelled e.g.
    /// gpu:llvmpipe/fast; default: exact only (`render --gpu-math`).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub gpu_math: Vec<crate::gpu::GpuMath>,
    /// GPU kernels to time (comma-separated, e.g. mega,wavefront): the gpu
    /// backend once per kernel, the wavefront labelled e.g.
    /// gpu:llvmpipe/wavefront; default: mega only (`render --kernel`).
    /// The wavefront has only the exact arithmetic: with --gpu-math fast
    /// that pair is not run. `calibration` (labelled .../calibration) is
    /// the plain grid tracer for opaque sphere fields (docs/profiling.md);
    /// it fails on other scenes.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub kernels: Vec<crate::gpu::GpuKernel>,
    /// CPU packet widths to time (comma-separated, e.g. 1,8): the cpu and
    /// auto backends once per width, labelled e.g. cpu/p8; default:
    /// `render`'s (`render --packet`; docs/method.md, "Packets of rays").
    #[arg(long, value_delimiter = ',', value_parser = ["1", "4", "8"])]
    pub packet: Vec<String>,
    /// Also render each scene with POV-Ray 3.7 (exported by `whitted
    /// export`, same size and depth, all cores, no anti-aliasing: pixel
    /// centres, or the corner rays of --preset spd),
    /// interleaved with ours, and report the time ratio and the image
    /// difference (PSNR, mean FLIP).
    #[arg(long, value_name = "povray", value_parser = ["povray"])]
    pub vs: Option<String>,
    /// Render every case at this size instead (quick checks; figures at
    /// other sizes are not the suite's).
    #[arg(long, value_name = "WxH", value_parser = super::options::parse_workgroup)]
    pub resolution: Option<[u32; 2]>,
    /// Only the cases whose names contain one of these (comma-separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Where the example scenes are.
    #[arg(long, default_value = "scenes")]
    pub scenes: PathBuf,
    /// Write the results as CSV.
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    /// Draw the results (.svg or .png); with --scaling, FILE is render time
    /// and FILE-wall, FILE-rays, FILE-memory beside it.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Keep the generated scenes, images and stats in this directory
    /// (default: a temporary directory, removed afterwards).
    #[arg(long, value_name = "DIR")]
    pub keep: Option<PathBuf>,
}

/// What an SPD case renders with: the SPD's procedure (`--preset spd`:
/// 512², corner rays, depth 4, no cut-off) and the rays the image needs.
/// The preset's own counting (`--counting spd`) also traces, for the SPD's
/// statistics alone, zero-weight reflection rays where a surface lets
/// light through and does not reflect; they change no pixel, POV-Ray traces
/// none of them, and on gears they were a quarter of the wall time
/// (docs/spd.md, "Timings"). A bench times the image.
const SPD_ARGS: &[&str] = &["--preset", "spd", "--counting", "traced"];

/// Writes `scene` as NFF into `dir` and returns its path.
fn write_scene(dir: &Path, name: &str, scene: &Scene) -> Result<PathBuf> {
    let p = dir.join(format!("{}.nff", bench::slug(name)));
    let text = crate::export::to_nff(scene)?;
    std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    Ok(p)
}

fn suite_cases(a: &BenchArgs, dir: &Path) -> Result<Vec<Case>> {
    let suites = if a.suite.is_empty() {
        Suite::value_variants().to_vec()
    } else {
        a.suite.clone()
    };
    let mut cases = Vec::new();
    for s in suites {
        match s {
            Suite::Spd => {
                for sc in SpdScene::ALL {
                    let scene = spd::generate(sc, a.size).map_err(|e| user(anyhow!(e)))?;
                    let size = a.size.unwrap_or(sc.default_size());
                    let name = format!("{}-{size}", sc.name());
                    let p = write_scene(dir, &name, &scene)?;
                    cases.push(Case::new(&name, "spd", &p, &scene, SPD_ARGS));
                }
            }
            Suite::Examples => {
                if !a.scenes.is_dir() {
                    log::warn!(
                        "{}: no such directory; the example scenes are skipped (--scenes)",
                        a.scenes.display()
                    );
                    continue;
                }
                let mut files: Vec<PathBuf> = std::fs::read_dir(&a.scenes)
                    .with_context(|| format!("cannot list {}", a.scenes.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| matches!(files::extension(p).as_deref(), Some("toml" | "nff")))
                    .collect();
                files.sort();
                for f in files {
                    let scene = crate::scene::load(&f).map_err(user)?;
                    let name = f
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    cases.push(Case::new(&name, "example", &f, &scene, &[]));
                }
            }
            Suite::Spheres => {
                let scene = gen::random_spheres(20_000, 1);
                let p = write_scene(dir, "spheres-20k", &scene)?;
                cases.push(Case::new(
                    "spheres-20k",
                    "spheres",
                    &p,
                    &scene,
                    &["--width", "1024", "--height", "768", "--max-depth", "5"],
                ));
            }
        }
    }
    Ok(cases)
}

fn scaling_cases(dir: &Path) -> Result<Vec<Case>> {
    let mut cases = Vec::new();
    for level in 1..=6 {
        let scene = gen::sphereflake(level);
        let name = format!("sphereflake-{level}");
        let p = write_scene(dir, &name, &scene)?;
        cases.push(Case::new(
            &name,
            "sphereflake",
            &p,
            &scene,
            &[
                "--width",
                "512",
                "--height",
                "512",
                "--sampling",
                "corners",
                "--max-depth",
                "4",
                "--min-weight",
                "0",
            ],
        ));
    }
    for n in [1_000usize, 10_000, 100_000, 1_000_000] {
        let scene = gen::random_spheres(n, 1);
        let name = format!("spheres-{n}");
        let p = write_scene(dir, &name, &scene)?;
        cases.push(Case::new(
            &name,
            "spheres",
            &p,
            &scene,
            &["--width", "512", "--height", "384", "--max-depth", "5"],
        ));
    }
    Ok(cases)
}

/// The whitted backends to time.
fn engines(a: &BenchArgs) -> Result<Vec<Engine>> {
    let gpu_name = crate::gpu::devices().ok().and_then(|l| {
        crate::gpu::choose(&l, None, false)
            .ok()
            .map(|i| l[i].name.clone())
    });
    let wanted: Vec<String> = if a.backends.is_empty() {
        let mut v = vec!["cpu".to_string()];
        if gpu_name.is_some() {
            v.push("gpu".into());
        }
        v
    } else {
        a.backends.clone()
    };
    if !a.gpu_math.is_empty() && !wanted.iter().any(|b| b == "gpu") {
        bail!(user(anyhow!(
            "--gpu-math times the gpu backend's kernels, and it is not among --backends"
        )));
    }
    if !a.kernels.is_empty() && !wanted.iter().any(|b| b == "gpu") {
        bail!(user(anyhow!(
            "--kernels times the gpu backend's kernels, and it is not among --backends"
        )));
    }
    let kernels = if a.kernels.is_empty() {
        vec![GpuKernel::Mega]
    } else {
        a.kernels.clone()
    };
    let maths = if a.gpu_math.is_empty() {
        vec![GpuMath::Exact]
    } else {
        a.gpu_math.clone()
    };
    let mut out = Vec::new();
    for b in wanted {
        let (base, maths, kernels): (String, &[GpuMath], &[GpuKernel]) = if b == "gpu" {
            let name = gpu_name.as_deref().ok_or_else(|| {
                user(anyhow!(
                    "--backends gpu: there is no usable Vulkan device (see `whitted devices`)"
                ))
            })?;
            (
                format!("gpu:{}", name.split_whitespace().next().unwrap_or("gpu")),
                &maths,
                &kernels,
            )
        } else {
            (b.clone(), &[GpuMath::Exact], &[GpuKernel::Mega])
        };
        let pairs = maths
            .iter()
            .flat_map(|&m| kernels.iter().map(move |&k| (m, k)));
        // Only the megakernel has fast arithmetic (`render` refuses the
        // wavefront's; the calibration kernel has no `precise` to drop).
        for (math, kernel) in pairs.filter(|&(m, k)| !(m == GpuMath::Fast && k != GpuKernel::Mega))
        {
            // The exact megakernel keeps the plain label (the default, as before).
            let mut label = match math {
                GpuMath::Exact => base.clone(),
                GpuMath::Fast => format!("{base}/fast"),
            };
            if kernel != GpuKernel::Mega {
                label = format!("{label}/{}", kernel.name());
            }
            let gpu_math = (b == "gpu").then_some(math);
            let gpu_kernel = (b == "gpu" && kernel != GpuKernel::Mega).then_some(kernel);
            let accels: Vec<Option<&String>> = if a.accel.is_empty() {
                vec![None]
            } else {
                a.accel.iter().map(Some).collect()
            };
            let shadows: Vec<Option<&String>> = if a.shadows.is_empty() {
                vec![None]
            } else {
                a.shadows.iter().map(Some).collect()
            };
            // Packets are the CPU's: the GPU runs once whatever the widths.
            let packets: Vec<Option<&String>> = if a.packet.is_empty() || b == "gpu" {
                vec![None]
            } else {
                a.packet.iter().map(Some).collect()
            };
            for accel in &accels {
                for sh in &shadows {
                    for pk in &packets {
                        let mut l = label.clone();
                        for part in [accel, sh].into_iter().flatten() {
                            l = format!("{l}/{part}");
                        }
                        if let Some(w) = pk {
                            l = format!("{l}/p{w}");
                        }
                        out.push(Engine::Whitted {
                            backend: b.clone(),
                            accel: accel.cloned(),
                            shadows: sh.cloned(),
                            gpu_math,
                            kernel: gpu_kernel,
                            packet: pk.cloned(),
                            label: l,
                        });
                    }
                }
            }
        }
    }
    if a.vs.is_some() {
        let ok = std::process::Command::new("povray")
            .arg("--version")
            .output()
            .is_ok();
        if !ok {
            bail!(user(anyhow!(
                "--vs povray: `povray` is not installed or not on PATH (Debian: apt-get install povray)"
            )));
        }
        out.push(Engine::PovRay);
    }
    Ok(out)
}

pub fn run(a: BenchArgs, ui: Ui) -> Result<u8> {
    let mut outputs = Vec::new();
    if let Some(p) = &a.csv {
        outputs.push(Output {
            flag: "--csv",
            path: p,
            extensions: &["csv"],
            stdout: true,
        });
    }
    if let Some(p) = &a.plot {
        outputs.push(Output {
            flag: "--plot",
            path: p,
            extensions: &["svg", "png"],
            stdout: false,
        });
    }
    files::check_outputs(&outputs, &[]).map_err(user)?;
    if let Some(p) = &a.plot {
        crate::plot::ready("--plot", p).map_err(user)?;
    }
    let engines = engines(&a)?;
    let tmp;
    let work = match &a.keep {
        Some(d) => {
            std::fs::create_dir_all(d)
                .map_err(|e| user(anyhow!("--keep {}: cannot create it: {e}", d.display())))?;
            d.clone()
        }
        None => {
            tmp = tempfile::Builder::new()
                .prefix("whitted-bench-")
                .tempdir()
                .context("cannot create a temporary directory")?;
            tmp.path().to_path_buf()
        }
    };
    let mut cases = if a.scaling {
        scaling_cases(&work)?
    } else {
        suite_cases(&a, &work)?
    };
    if !a.only.is_empty() {
        cases.retain(|c| a.only.iter().any(|o| c.name.contains(o.as_str())));
    }
    if let Some([w, h]) = a.resolution {
        cases = cases.into_iter().map(|c| c.resized(w, h)).collect();
    }
    if cases.is_empty() {
        bail!(user(anyhow!(
            "no case to run (see --suite, --only, --scenes)"
        )));
    }
    let plan = Plan {
        cases,
        engines,
        runs: a.runs as usize,
        warmup: a.warmup as usize,
        exe: std::env::current_exe().context("cannot find the whitted executable")?,
        work,
        povray_threads: crate::sys::cores(),
    };
    if !ui.quiet {
        eprintln!(
            "whitted bench: {} cases x {} engines, {} warm-up + {} runs each, on {}",
            plan.cases.len(),
            plan.engines.len(),
            plan.warmup,
            plan.runs,
            crate::sys::machine()
        );
    }
    let bar = Bar::new(ui, "benchmarking");
    let rows = bench::run(&plan, &|d, t| bar.set(d, t));
    bar.finish();
    let (rows, failures) = rows?;
    print!("{}", bench::table(&rows));
    print!("{}", bench::failure_lines(&failures));
    if a.scaling {
        print!("{}", bench::scaling_summary(&rows));
    }
    if let Some(p) = &a.csv {
        files::write_bytes(&Dest::new(p), bench::csv(&rows, &failures)?.as_bytes())
            .map_err(user)?;
    }
    if let Some(p) = &a.plot {
        if a.scaling {
            for (name, chart) in bench::scaling_charts(&rows) {
                let path = if name == "render" {
                    p.clone()
                } else {
                    let stem = p
                        .file_stem()
                        .map(|s| s.to_string_lossy())
                        .unwrap_or_default();
                    let ext = files::extension(p).unwrap_or_default();
                    p.with_file_name(format!("{stem}-{name}.{ext}"))
                };
                crate::plot::draw(&chart, &path)?;
            }
        } else {
            let title = format!("whitted bench on {}", crate::sys::machine());
            crate::plot::draw(&bench::suite_chart(&rows, &title), p)?;
        }
    }
    Ok(if failures.is_empty() { 0 } else { 1 })
}
