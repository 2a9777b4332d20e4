//! `whitted bench`: one command behind every speed figure (BENCHMARKS.md,
//! docs/spd.md). A suite of scenes, each rendered by `whitted render` in a
//! child process on every engine (the CPU mirror, the GPU when there is a
//! Vulkan device, POV-Ray 3.7 with `--vs povray`): a warm-up run of each,
//! then N runs interleaved engine by engine, so that a change in the
//! machine's load hits every engine alike. Per case and engine: median,
//! min and max of the wall time (the whole process, as a user waits for
//! it) and of the render time (tracing only, from `--stats`), Mrays/s over
//! every ray (eye, reflected, refracted and shadow rays), and peak memory.
//!
//! Peak memory is the process's high-water mark of resident memory
//! (VmHWM): whitted reports its own in `--stats`; POV-Ray's is read from
//! /proc while it runs (every 5 ms, so a peak in its last 5 ms is missed).

use crate::error::user;
use crate::scene::{Scene, Shape};
use anyhow::{anyhow, bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// One scene with the settings it is rendered at.
#[derive(Clone, Debug)]
pub struct Case {
    pub name: String,
    /// "spd", "example", "spheres", or a scaling family.
    pub family: String,
    pub scene: PathBuf,
    /// Settings flags for `whitted render` (also read for the POV export).
    pub args: Vec<String>,
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub min_weight: f32,
    pub sampling: crate::pack::Sampling,
    pub primitives: u64,
}

/// Who renders.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Engine {
    /// `whitted render --backend cpu|gpu [--accel A] [--shadows S]
    /// [--gpu-math M] [--kernel K] [--packet N]`.
    Whitted {
        backend: String,
        accel: Option<String>,
        shadows: Option<String>,
        /// The GPU kernel (None: the default, exact).
        gpu_math: Option<crate::gpu::GpuMath>,
        /// `--kernel` (None: the default, the megakernel).
        kernel: Option<crate::gpu::GpuKernel>,
        /// The CPU's packet width (None: `render`'s default).
        packet: Option<String>,
        label: String,
    },
    /// POV-Ray 3.7 on the scene exported by `whitted export`.
    PovRay,
}

impl Engine {
    pub fn label(&self) -> String {
        match self {
            Engine::Whitted { label, .. } => label.clone(),
            Engine::PovRay => "povray".into(),
        }
    }
}

/// One run's measurements.
#[derive(Clone, Debug, Default)]
pub struct Sample {
    pub wall: f64,
    pub render: Option<f64>,
    /// Reading the scene and building the packed data and the grid.
    pub prep: Option<f64>,
    /// Intersection tests and grid cells visited, per ray.
    pub tests_per_ray: Option<f64>,
    pub cells_per_ray: Option<f64>,
    /// BVH nodes visited per ray.
    pub nodes_per_ray: Option<f64>,
    /// The same split by the kind of ray (`--stats`' `work_by_ray`).
    pub by_ray: Option<ByRay>,
    pub rays: Option<u64>,
    pub peak: Option<u64>,
}

/// Work per ray of each kind, eye, secondary (reflected and refracted)
/// and shadow, as `--stats` reports it (`work_by_ray`); "steps" are the
/// cells and nodes visited together. And the deepest walk stack.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ByRay {
    pub tests: [f64; 3],
    pub steps: [f64; 3],
    pub deepest_stack: u64,
}

impl ByRay {
    /// From a `--stats` JSON; `None` when it has no `work_by_ray`.
    pub fn from_stats(j: &serde_json::Value) -> Option<ByRay> {
        let w = j.get("work_by_ray")?;
        let mut b = ByRay {
            deepest_stack: j["work"]["deepest_stack"].as_u64()?,
            ..ByRay::default()
        };
        for (k, kind) in ["eye", "secondary", "shadow"].iter().enumerate() {
            let per = &w[kind]["per_ray"];
            b.tests[k] = per["intersection_tests"].as_f64()?;
            b.steps[k] = per["cells_visited"].as_f64()? + per["nodes_visited"].as_f64()?;
        }
        Some(b)
    }
}

/// Median, minimum and maximum.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Summary {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Summary {
    pub fn of(v: &[f64]) -> Option<Summary> {
        if v.is_empty() {
            return None;
        }
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let n = s.len();
        let median = if n % 2 == 1 {
            s[n / 2]
        } else {
            0.5 * (s[n / 2 - 1] + s[n / 2])
        };
        Some(Summary {
            median,
            min: s[0],
            max: s[n - 1],
        })
    }
}

/// The result for one case on one engine.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub case: String,
    pub family: String,
    pub primitives: u64,
    pub width: u32,
    pub height: u32,
    pub engine: String,
    pub runs: usize,
    pub wall: Summary,
    pub render: Option<Summary>,
    /// Preprocessing: reading and building (the SPD reports it apart).
    pub prep: Option<Summary>,
    pub tests_per_ray: Option<f64>,
    pub cells_per_ray: Option<f64>,
    /// BVH nodes visited per ray.
    pub nodes_per_ray: Option<f64>,
    /// The work split by kind of ray.
    pub by_ray: Option<ByRay>,
    pub rays: Option<u64>,
    pub mrays_per_s: Option<f64>,
    pub peak_bytes: Option<u64>,
    /// POV-Ray's median wall time over this engine's (> 1: we are faster).
    pub povray_over_this: Option<f64>,
    /// This engine's image against POV-Ray's.
    pub psnr_vs_povray: Option<f64>,
    pub flip_vs_povray: Option<f64>,
}

/// A case an engine could not run: its first failure, after which its
/// other runs of that case are skipped (the other engines and cases go
/// on).
#[derive(Clone, Debug)]
pub struct Failure {
    pub case: Case,
    /// The engine's label.
    pub engine: String,
    /// What went wrong: the child's exit status and message.
    pub message: String,
}

/// How to run a suite.
#[derive(Clone, Debug)]
pub struct Plan {
    pub cases: Vec<Case>,
    pub engines: Vec<Engine>,
    pub runs: usize,
    pub warmup: usize,
    /// The `whitted` executable the children run.
    pub exe: PathBuf,
    /// Where scenes, images and stats go.
    pub work: PathBuf,
    /// POV-Ray's worker threads (+WT).
    pub povray_threads: usize,
}

/// Counts the primitives of a scene (mesh triangles one by one).
pub fn primitives(s: &Scene) -> u64 {
    s.objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Mesh(m) => m.triangles.len() as u64,
            _ => 1,
        })
        .sum()
}

/// The value of `--flag V` in `args`.
fn arg_value<'a>(args: &'a [String], flag: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
}

impl Case {
    /// A case for `scene` rendered with settings flags `args`; the size
    /// and depth for the POV-Ray export are read from the flags or the scene.
    pub fn new(name: &str, family: &str, scene_path: &Path, scene: &Scene, args: &[&str]) -> Case {
        let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        let num = |f: &str| arg_value(&args, f).and_then(|v| v.parse::<u32>().ok());
        let (mut width, mut height) = (scene.camera.width, scene.camera.height);
        if arg_value(&args, "--preset") == Some("spd") {
            (width, height) = (512, 512);
        }
        Case {
            name: name.into(),
            family: family.into(),
            scene: scene_path.to_path_buf(),
            width: num("--width").unwrap_or(width),
            height: num("--height").unwrap_or(height),
            max_depth: num("--max-depth").unwrap_or(
                if arg_value(&args, "--preset") == Some("spd") {
                    4
                } else {
                    5
                },
            ),
            min_weight: arg_value(&args, "--min-weight")
                .and_then(|v| v.parse().ok())
                .unwrap_or(if arg_value(&args, "--preset") == Some("spd") {
                    0.0
                } else {
                    1.0 / 256.0
                }),
            sampling: match arg_value(&args, "--sampling") {
                Some("corners") => crate::pack::Sampling::Corners,
                Some(_) => crate::pack::Sampling::Centers,
                None if arg_value(&args, "--preset") == Some("spd") => {
                    crate::pack::Sampling::Corners
                }
                None => crate::pack::Sampling::Centers,
            },
            primitives: primitives(scene),
            args,
        }
    }

    /// The same case at another image size (for quick runs).
    pub fn resized(mut self, w: u32, h: u32) -> Case {
        for (flag, v) in [("--width", w), ("--height", h)] {
            match self.args.iter().position(|a| a == flag) {
                Some(i) => self.args[i + 1] = v.to_string(),
                None => self.args.extend([flag.to_string(), v.to_string()]),
            }
        }
        self.width = w;
        self.height = h;
        self
    }
}

/// Runs a child to completion; its wall time and its peak memory.
///
/// The wall time ends when a blocking wait returns. The peak memory is
/// the child's high-water mark (VmHWM, which only grows), read by a
/// second thread every `POLL` until the child ends (whitted's own runs
/// report theirs exactly in their stats). An earlier version polled
/// every 5 ms from the waiting loop itself; on two cores that cost the
/// child about 8 % of its wall time (0.546 s against 0.503 s for the same
/// gears render), for POV-Ray and whitted alike.
fn timed(mut cmd: Command, what: &str) -> Result<(f64, Option<u64>, std::process::Output)> {
    const POLL: Duration = Duration::from_millis(25);
    cmd.stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let t0 = Instant::now();
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start {what}"))?;
    let pid = child.id();
    // Drain the pipes on threads so a chatty child never blocks.
    let mut out = child.stdout.take();
    let mut err = child.stderr.take();
    let t_out = std::thread::spawn(move || {
        let mut v = Vec::new();
        if let Some(o) = out.as_mut() {
            let _ = std::io::Read::read_to_end(o, &mut v);
        }
        v
    });
    let t_err = std::thread::spawn(move || {
        let mut v = Vec::new();
        if let Some(e) = err.as_mut() {
            let _ = std::io::Read::read_to_end(e, &mut v);
        }
        v
    });
    let (stop, stopped) = std::sync::mpsc::channel::<()>();
    let poller = std::thread::spawn(move || {
        let mut peak: Option<u64> = None;
        loop {
            if let Some(p) = crate::sys::peak_memory_of(pid) {
                peak = Some(peak.map_or(p, |q| q.max(p)));
            }
            match stopped.recv_timeout(POLL) {
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
                _ => return peak,
            }
        }
    });
    let status = child.wait();
    let wall = t0.elapsed().as_secs_f64();
    let _ = stop.send(());
    let peak = poller.join().unwrap_or(None);
    let status = status?;
    let output = std::process::Output {
        status,
        stdout: t_out.join().unwrap_or_default(),
        stderr: t_err.join().unwrap_or_default(),
    };
    Ok((wall, peak, output))
}

/// One run of `engine` on `case`, writing its image to `image`.
pub fn run_once(plan: &Plan, case: &Case, engine: &Engine, image: &Path) -> Result<Sample> {
    match engine {
        Engine::Whitted {
            backend,
            accel,
            shadows,
            gpu_math,
            kernel,
            packet,
            ..
        } => {
            let stats = image.with_extension("json");
            let mut cmd = Command::new(&plan.exe);
            cmd.args(["-q", "render"])
                .arg(&case.scene)
                .arg("-o")
                .arg(image)
                .args(["--encoding", "linear16"])
                .args(["--backend", backend])
                .args(accel.iter().flat_map(|a| ["--accel", a.as_str()]))
                .args(shadows.iter().flat_map(|s| ["--shadows", s.as_str()]))
                .args(gpu_math.iter().flat_map(|m| ["--gpu-math", m.name()]))
                .args(kernel.iter().flat_map(|k| ["--kernel", k.name()]))
                .args(packet.iter().flat_map(|p| ["--packet", p.as_str()]))
                .arg("--stats")
                .arg(&stats)
                .args(&case.args);
            let (wall, polled, out) = timed(cmd, "whitted")?;
            if !out.status.success() {
                bail!(
                    "{} on {}: whitted render failed ({}): {}",
                    engine.label(),
                    case.name,
                    out.status,
                    String::from_utf8_lossy(&out.stderr).trim()
                );
            }
            let j: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(&stats)
                    .with_context(|| format!("cannot read {}", stats.display()))?,
            )
            .with_context(|| format!("{}: not JSON", stats.display()))?;
            let rays = &j["rays"];
            let total: u64 = ["eye", "reflect", "refract", "shadow"]
                .iter()
                .map(|k| rays[k].as_u64().unwrap_or(0))
                .sum();
            Ok(Sample {
                wall,
                render: j["seconds"]["render"].as_f64(),
                prep: match (
                    j["seconds"]["load"].as_f64(),
                    j["seconds"]["build"].as_f64(),
                ) {
                    (Some(l), Some(b)) => Some(l + b),
                    _ => None,
                },
                tests_per_ray: j["work"]["intersection_tests"]
                    .as_u64()
                    .filter(|_| total > 0)
                    .map(|t| t as f64 / total as f64),
                cells_per_ray: j["work"]["cells_visited"]
                    .as_u64()
                    .filter(|_| total > 0)
                    .map(|c| c as f64 / total as f64),
                nodes_per_ray: j["work"]["nodes_visited"]
                    .as_u64()
                    .filter(|_| total > 0)
                    .map(|c| c as f64 / total as f64),
                by_ray: ByRay::from_stats(&j),
                rays: Some(total),
                peak: j["peak_memory_bytes"].as_u64().or(polled),
            })
        }
        Engine::PovRay => {
            let pov = plan.work.join(format!("{}.pov", slug(&case.name)));
            let opts = crate::povray::Options {
                width: case.width,
                height: case.height,
                threads: plan.povray_threads as u32,
                sampling: case.sampling,
            };
            let name = image
                .file_name()
                .and_then(|n| n.to_str())
                .ok_or_else(|| anyhow!("{}: not a plain file name", image.display()))?;
            let mut cmd = crate::povray::command(&pov, name, &opts);
            cmd.current_dir(&plan.work);
            let (wall, peak, out) = timed(cmd, "povray (is POV-Ray 3.7 installed?)")?;
            if !out.status.success() || !image.exists() {
                bail!(
                    "povray on {} failed ({}): {}",
                    case.name,
                    out.status,
                    String::from_utf8_lossy(&out.stderr)
                        .lines()
                        .rev()
                        .take(5)
                        .collect::<Vec<_>>()
                        .join(" | ")
                );
            }
            Ok(Sample {
                wall,
                render: None,
                prep: None,
                tests_per_ray: None,
                cells_per_ray: None,
                nodes_per_ray: None,
                by_ray: None,
                rays: None,
                peak,
            })
        }
    }
}

/// A file-name-safe version of a case name.
pub fn slug(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect()
}

/// Where an engine's image of a case goes: both engines write the linear
/// values as a 16-bit PNG (whitted `--encoding linear16`, POV-Ray
/// `+FN16 File_Gamma=1.0`: `povray::command`), the same output work on
/// both sides of the timing. (An .exr took whitted 14-19 ms more than the
/// PNG at 512², half of SPD tetra's render.)
fn image_path(plan: &Plan, case: &Case, engine: &Engine) -> PathBuf {
    plan.work.join(format!(
        "{}.{}.png",
        slug(&case.name),
        slug(&engine.label())
    ))
}

/// An image file as linear RGB clamped to [0, 1].
fn load_linear(p: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let img = image::open(p)
        .with_context(|| format!("cannot read {}", p.display()))?
        .to_rgb32f();
    let px = img
        .pixels()
        .map(|q| {
            q.0.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
        })
        .collect();
    Ok((img.width(), img.height(), px))
}

/// PSNR (linear values clamped to [0, 1], as tests/povray.rs) and mean
/// FLIP (on the 8-bit sRGB encodings) of `test` against `reference`.
pub fn image_difference(reference: &Path, test: &Path) -> Result<(f64, f64)> {
    let (w, h, a) = load_linear(reference)?;
    let (w2, h2, b) = load_linear(test)?;
    if (w, h) != (w2, h2) {
        bail!(
            "{} is {w}x{h} but {} is {w2}x{h2}",
            reference.display(),
            test.display()
        );
    }
    let psnr = crate::metrics::psnr(&a, &b);
    let srgb = |v: &[[f32; 3]]| -> Vec<u8> {
        v.iter()
            .flat_map(|c| c.map(|x| crate::output::to_u8(x, crate::output::Encoding::Srgb)))
            .collect()
    };
    let (_, flip) = crate::metrics::flip(&srgb(&a), &srgb(&b), w, h);
    Ok((psnr, flip))
}

/// Runs the plan; `progress(done, total)` after each run.
pub fn run(plan: &Plan, progress: &dyn Fn(u64, u64)) -> Result<(Vec<Row>, Vec<Failure>)> {
    let total = (plan.cases.len() * plan.engines.len() * (plan.runs + plan.warmup)) as u64;
    let mut done = 0u64;
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    let has_povray = plan.engines.contains(&Engine::PovRay);
    for case in &plan.cases {
        if has_povray {
            let scene = crate::scene::load(&case.scene).map_err(user)?;
            let pov = crate::export::to_pov(
                &scene,
                case.width,
                case.height,
                case.max_depth,
                case.min_weight,
            )?;
            let path = plan.work.join(format!("{}.pov", slug(&case.name)));
            std::fs::write(&path, pov)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let mut samples: Vec<Vec<Sample>> = vec![Vec::new(); plan.engines.len()];
        // An engine's first failure on this case (it is not run again on
        // it: a scene refused once is refused every time).
        let mut failed: Vec<Option<String>> = vec![None; plan.engines.len()];
        for k in 0..plan.warmup + plan.runs {
            for (e, engine) in plan.engines.iter().enumerate() {
                if failed[e].is_none() {
                    match run_once(plan, case, engine, &image_path(plan, case, engine)) {
                        Ok(s) if k >= plan.warmup => samples[e].push(s),
                        Ok(_) => {}
                        Err(err) => failed[e] = Some(format!("{err:#}")),
                    }
                }
                done += 1;
                progress(done, total);
            }
        }
        for (e, engine) in plan.engines.iter().enumerate() {
            if let Some(message) = failed[e].take() {
                samples[e].clear();
                failures.push(Failure {
                    case: case.clone(),
                    engine: engine.label(),
                    message,
                });
            }
        }
        let wall_of =
            |e: usize| Summary::of(&samples[e].iter().map(|s| s.wall).collect::<Vec<_>>());
        let pov_index = plan
            .engines
            .iter()
            .position(|e| *e == Engine::PovRay)
            .filter(|&p| !samples[p].is_empty());
        let pov_wall = pov_index.and_then(wall_of);
        for (e, engine) in plan.engines.iter().enumerate() {
            let s = &samples[e];
            if s.is_empty() {
                continue;
            }
            let wall = wall_of(e).ok_or_else(|| anyhow!("no runs"))?;
            let renders: Vec<f64> = s.iter().filter_map(|x| x.render).collect();
            let render = Summary::of(&renders);
            let preps: Vec<f64> = s.iter().filter_map(|x| x.prep).collect();
            let last = s.last();
            let rays = s.iter().filter_map(|x| x.rays).max();
            let (psnr, flip) = match (engine, pov_index) {
                (Engine::Whitted { .. }, Some(p)) => {
                    let (a, b) = image_difference(
                        &image_path(plan, case, &plan.engines[p]),
                        &image_path(plan, case, engine),
                    )?;
                    (Some(a), Some(b))
                }
                _ => (None, None),
            };
            rows.push(Row {
                case: case.name.clone(),
                family: case.family.clone(),
                primitives: case.primitives,
                width: case.width,
                height: case.height,
                engine: engine.label(),
                runs: s.len(),
                wall,
                render,
                prep: Summary::of(&preps),
                tests_per_ray: last.and_then(|x| x.tests_per_ray),
                cells_per_ray: last.and_then(|x| x.cells_per_ray),
                nodes_per_ray: last.and_then(|x| x.nodes_per_ray),
                by_ray: last.and_then(|x| x.by_ray),
                rays,
                mrays_per_s: match (rays, render) {
                    (Some(r), Some(t)) if t.median > 0.0 => Some(r as f64 / t.median / 1e6),
                    _ => None,
                },
                peak_bytes: s.iter().filter_map(|x| x.peak).max(),
                povray_over_this: match (engine, pov_wall) {
                    (Engine::Whitted { .. }, Some(p)) if wall.median > 0.0 => {
                        Some(p.median / wall.median)
                    }
                    _ => None,
                },
                psnr_vs_povray: psnr,
                flip_vs_povray: flip,
            });
        }
    }
    Ok((rows, failures))
}

/// The failures, a line each, for beneath the table.
pub fn failure_lines(failures: &[Failure]) -> String {
    failures
        .iter()
        .map(|f| format!("FAILED {} on {}: {}\n", f.engine, f.case.name, f.message))
        .collect()
}

fn opt<T>(v: Option<T>, f: impl Fn(T) -> String) -> String {
    v.map(f).unwrap_or_else(|| "-".into())
}

/// The results as a fixed-width table.
pub fn table(rows: &[Row]) -> String {
    let header = [
        "scene",
        "prims",
        "size",
        "engine",
        "wall s (min-max)",
        "prep s",
        "render s",
        "Mrays/s",
        "peak MB",
        "POV/this",
        "PSNR dB",
        "FLIP",
    ];
    let mut lines: Vec<Vec<String>> = vec![header.iter().map(|s| s.to_string()).collect()];
    for r in rows {
        lines.push(vec![
            r.case.clone(),
            r.primitives.to_string(),
            format!("{}x{}", r.width, r.height),
            r.engine.clone(),
            format!("{:.3} ({:.3}-{:.3})", r.wall.median, r.wall.min, r.wall.max),
            opt(r.prep, |s| format!("{:.3}", s.median)),
            opt(r.render, |s| format!("{:.3}", s.median)),
            opt(r.mrays_per_s, |m| format!("{m:.2}")),
            opt(r.peak_bytes, |b| format!("{:.0}", b as f64 / 1e6)),
            opt(r.povray_over_this, |x| format!("{x:.1}x")),
            opt(r.psnr_vs_povray, |x| format!("{x:.1}")),
            opt(r.flip_vs_povray, |x| format!("{x:.4}")),
        ]);
    }
    let widths: Vec<usize> = (0..header.len())
        .map(|c| {
            lines
                .iter()
                .map(|l| l[c].chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut out = String::new();
    for (i, l) in lines.iter().enumerate() {
        let cells: Vec<String> = l
            .iter()
            .enumerate()
            .map(|(c, s)| {
                if c < 4 {
                    format!("{s:<w$}", w = widths[c])
                } else {
                    format!("{s:>w$}", w = widths[c])
                }
            })
            .collect();
        out.push_str(cells.join("  ").trim_end());
        out.push('\n');
        if i == 0 {
            out.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
            out.push('\n');
        }
    }
    out
}

/// The CSV's columns (`csv`): one per `Row` field, then the failure.
const CSV_HEADER: [&str; 31] = [
    "scene",
    "family",
    "primitives",
    "width",
    "height",
    "engine",
    "runs",
    "wall_median_s",
    "wall_min_s",
    "wall_max_s",
    "prep_median_s",
    "render_median_s",
    "render_min_s",
    "render_max_s",
    "rays",
    "mrays_per_s",
    "peak_bytes",
    "povray_over_this",
    "psnr_vs_povray_db",
    "flip_vs_povray",
    "tests_per_ray",
    "cells_per_ray",
    "nodes_per_ray",
    "eye_tests_per_ray",
    "eye_steps_per_ray",
    "secondary_tests_per_ray",
    "secondary_steps_per_ray",
    "shadow_tests_per_ray",
    "shadow_steps_per_ray",
    "deepest_stack",
    "failed",
];

/// The results as CSV (one row per case and engine).
pub fn csv(rows: &[Row], failures: &[Failure]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(CSV_HEADER)?;
    let o = |v: Option<f64>| v.map(|x| format!("{x}")).unwrap_or_default();
    for r in rows {
        w.write_record([
            r.case.clone(),
            r.family.clone(),
            r.primitives.to_string(),
            r.width.to_string(),
            r.height.to_string(),
            r.engine.clone(),
            r.runs.to_string(),
            r.wall.median.to_string(),
            r.wall.min.to_string(),
            r.wall.max.to_string(),
            o(r.prep.map(|s| s.median)),
            o(r.render.map(|s| s.median)),
            o(r.render.map(|s| s.min)),
            o(r.render.map(|s| s.max)),
            r.rays.map(|x| x.to_string()).unwrap_or_default(),
            o(r.mrays_per_s),
            r.peak_bytes.map(|x| x.to_string()).unwrap_or_default(),
            o(r.povray_over_this),
            o(r.psnr_vs_povray),
            o(r.flip_vs_povray),
            o(r.tests_per_ray),
            o(r.cells_per_ray),
            o(r.nodes_per_ray),
            o(r.by_ray.map(|b| b.tests[0])),
            o(r.by_ray.map(|b| b.steps[0])),
            o(r.by_ray.map(|b| b.tests[1])),
            o(r.by_ray.map(|b| b.steps[1])),
            o(r.by_ray.map(|b| b.tests[2])),
            o(r.by_ray.map(|b| b.steps[2])),
            r.by_ray
                .map(|b| b.deepest_stack.to_string())
                .unwrap_or_default(),
            String::new(),
        ])?;
    }
    for f in failures {
        let c = &f.case;
        let mut rec = vec![
            c.name.clone(),
            c.family.clone(),
            c.primitives.to_string(),
            c.width.to_string(),
            c.height.to_string(),
            f.engine.clone(),
            "0".into(),
        ];
        rec.resize(CSV_HEADER.len() - 1, String::new());
        rec.push(f.message.clone());
        w.write_record(&rec)?;
    }
    Ok(String::from_utf8(
        w.into_inner().map_err(|e| anyhow!("{e}"))?,
    )?)
}

/// Median wall time per scene, one series per engine (log y).
pub fn suite_chart(rows: &[Row], title: &str) -> crate::plot::Chart {
    let mut cases: Vec<String> = Vec::new();
    for r in rows {
        if !cases.contains(&r.case) {
            cases.push(r.case.clone());
        }
    }
    let mut engines: Vec<String> = Vec::new();
    for r in rows {
        if !engines.contains(&r.engine) {
            engines.push(r.engine.clone());
        }
    }
    let series = engines
        .iter()
        .map(|e| {
            let pts = rows
                .iter()
                .filter(|r| &r.engine == e)
                .map(|r| {
                    let x = cases.iter().position(|c| *c == r.case).unwrap_or(0) as f64;
                    (x, r.wall.median)
                })
                .collect();
            let mut s = crate::plot::Series::new(e.clone(), pts);
            s.line = false;
            s
        })
        .collect();
    crate::plot::Chart {
        title: title.into(),
        x_label: "scene".into(),
        y_label: "median wall time (s)".into(),
        log_x: false,
        log_y: true,
        series,
        x_categories: cases,
    }
}

/// Scaling charts: time, rays and peak memory against primitives, one
/// series per family and engine, log axes; the fitted exponent of each
/// series in its name.
pub fn scaling_charts(rows: &[Row]) -> Vec<(String, crate::plot::Chart)> {
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in rows {
        let k = (r.family.clone(), r.engine.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    type Pick = fn(&Row) -> Option<f64>;
    let quantities: [(&str, &str, Pick); 4] = [
        ("render", "median render time (s)", |r| {
            r.render.map(|s| s.median)
        }),
        ("wall", "median wall time (s)", |r| Some(r.wall.median)),
        ("rays", "rays traced", |r| r.rays.map(|x| x as f64)),
        ("memory", "peak memory (MB)", |r| {
            r.peak_bytes.map(|b| b as f64 / 1e6)
        }),
    ];
    quantities
        .iter()
        .map(|(name, label, pick)| {
            let series = keys
                .iter()
                .map(|(fam, eng)| {
                    let pts: Vec<(f64, f64)> = rows
                        .iter()
                        .filter(|r| &r.family == fam && &r.engine == eng)
                        .filter_map(|r| pick(r).map(|y| (r.primitives as f64, y)))
                        .collect();
                    let slope = crate::plot::loglog_slope(&pts)
                        .map(|k| format!(" (∝ N^{k:.2})"))
                        .unwrap_or_default();
                    crate::plot::Series::new(format!("{fam}, {eng}{slope}"), pts)
                })
                .collect();
            (
                name.to_string(),
                crate::plot::Chart {
                    title: format!("{label} against primitive count"),
                    x_label: "primitives".into(),
                    y_label: label.to_string(),
                    log_x: true,
                    log_y: true,
                    series,
                    x_categories: vec![],
                },
            )
        })
        .collect()
}

/// One line per family and engine: the fitted exponent of render time,
/// wall time, rays and memory against primitive count, and the ratio of
/// the largest case's render time to the smallest's.
pub fn scaling_summary(rows: &[Row]) -> String {
    let mut out = String::new();
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in rows {
        let k = (r.family.clone(), r.engine.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (fam, eng) in keys {
        let rs: Vec<&Row> = rows
            .iter()
            .filter(|r| r.family == fam && r.engine == eng)
            .collect();
        let fit = |f: &dyn Fn(&Row) -> Option<f64>| {
            let pts: Vec<(f64, f64)> = rs
                .iter()
                .filter_map(|r| f(r).map(|y| (r.primitives as f64, y)))
                .collect();
            crate::plot::loglog_slope(&pts)
                .map(|k| format!("{k:.3}"))
                .unwrap_or_else(|| "-".into())
        };
        let first = rs.iter().min_by_key(|r| r.primitives);
        let last = rs.iter().max_by_key(|r| r.primitives);
        let ratio = match (first, last) {
            (Some(a), Some(b)) => match (a.render, b.render) {
                (Some(x), Some(y)) if x.median > 0.0 => format!(
                    "{:.2}x from {} to {} primitives",
                    y.median / x.median,
                    a.primitives,
                    b.primitives
                ),
                _ => "-".into(),
            },
            _ => "-".into(),
        };
        out.push_str(&format!(
            "{fam} on {eng}: render time ∝ N^{}, wall ∝ N^{}, rays ∝ N^{}, memory ∝ N^{}; render time {ratio}\n",
            fit(&|r| r.render.map(|s| s.median)),
            fit(&|r| Some(r.wall.median)),
            fit(&|r| r.rays.map(|x| x as f64)),
            fit(&|r| r.peak_bytes.map(|x| x as f64)),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries() {
        let s = Summary::of(&[3.0, 1.0, 2.0]).unwrap();
        assert_eq!((s.median, s.min, s.max), (2.0, 1.0, 3.0));
        assert_eq!(Summary::of(&[4.0, 1.0, 2.0, 3.0]).unwrap().median, 2.5);
        assert!(Summary::of(&[]).is_none());
    }

    #[test]
    fn case_reads_its_flags() {
        let s = crate::gen::random_spheres(10, 1);
        let c = Case::new(
            "x",
            "spheres",
            Path::new("x.nff"),
            &s,
            &["--width", "64", "--max-depth", "3"],
        );
        assert_eq!((c.width, c.max_depth, c.primitives), (64, 3, 11));
        let c = c.resized(8, 6);
        assert_eq!(arg_value(&c.args, "--width"), Some("8"));
        assert_eq!(arg_value(&c.args, "--height"), Some("6"));
        let spd = Case::new("b", "spd", Path::new("b.nff"), &s, &["--preset", "spd"]);
        assert_eq!(
            (spd.width, spd.height, spd.max_depth, spd.min_weight),
            (512, 512, 4, 0.0)
        );
    }

    #[test]
    fn table_and_csv_hold_every_row() {
        let row = Row {
            case: "balls".into(),
            family: "spd".into(),
            primitives: 7382,
            width: 512,
            height: 512,
            engine: "cpu".into(),
            runs: 3,
            wall: Summary {
                median: 0.3,
                min: 0.29,
                max: 0.31,
            },
            render: Summary::of(&[0.2]),
            prep: Summary::of(&[0.05]),
            tests_per_ray: Some(5.5),
            cells_per_ray: Some(9.0),
            nodes_per_ray: None,
            by_ray: Some(ByRay {
                tests: [2.5, 3.75, 1.25],
                steps: [0.5, 9.0, 3.5],
                deepest_stack: 13,
            }),
            rays: Some(1_000_000),
            mrays_per_s: Some(5.0),
            peak_bytes: Some(20_000_000),
            povray_over_this: Some(6.0),
            psnr_vs_povray: Some(30.0),
            flip_vs_povray: Some(0.05),
        };
        let t = table(std::slice::from_ref(&row));
        assert!(t.contains("balls") && t.contains("6.0x") && t.contains("0.300 (0.290-0.310)"));
        let failure = Failure {
            case: Case {
                name: "gears".into(),
                family: "spd".into(),
                scene: "gears.nff".into(),
                args: Vec::new(),
                width: 512,
                height: 512,
                max_depth: 4,
                min_weight: 0.0,
                sampling: crate::pack::Sampling::Corners,
                primitives: 9345,
            },
            engine: "gpu:llvmpipe".into(),
            message: "refused, say".into(),
        };
        let c = csv(&[row], std::slice::from_ref(&failure)).unwrap();
        assert_eq!(c.lines().count(), 3);
        let header_len = c.lines().next().unwrap().split(',').count();
        assert!(c
            .lines()
            .nth(1)
            .unwrap()
            .starts_with("balls,spd,7382,512,512,cpu,3,0.3,"));
        assert!(
            c.lines()
                .nth(1)
                .unwrap()
                .ends_with(",2.5,0.5,3.75,9,1.25,3.5,13,"),
            "{c}"
        );
        let last = c.lines().nth(2).unwrap();
        assert!(last.starts_with("gears,spd,9345,512,512,gpu:llvmpipe,0,"));
        assert!(last.ends_with(",refused, say") || last.ends_with(",\"refused, say\""));
        assert_eq!(
            csv::Reader::from_reader(c.as_bytes())
                .records()
                .map(|r| r.unwrap().len())
                .collect::<Vec<_>>(),
            [header_len, header_len]
        );
        assert_eq!(
            failure_lines(&[failure]),
            "FAILED gpu:llvmpipe on gears: refused, say\n"
        );
    }
}
