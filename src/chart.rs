//! Speed against accuracy (`whitted chart`): sweep each setting that trades
//! time for error, one at a time from the defaults, timing every point
//! (median of several runs after a warm-up) and measuring its error
//! against the scene's reference (`crate::reference`). docs/accuracy.md
//! explains the knobs, the two errors and how to read the chart.

use crate::bench::Summary;
use crate::cpu::Frame;
use crate::metrics::{Accuracy, STEP};
use crate::pack::{Accel, Counting, Packed, Sampling, Settings};
use crate::plot::{Chart, Series};
use crate::reference::{self, Cache, RefSettings};
use crate::run::{self, Precision};
use crate::scene::Scene;
use anyhow::{anyhow, Result};
use std::time::Instant;

/// A setting the chart sweeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Knob {
    /// --max-depth: 0, 1, 2, 3, 4, 5, 6, 8, 12, 16.
    MaxDepth,
    /// --min-weight (adaptive depth control): 1/4 ... 1/4096 and 0.
    MinWeight,
    /// --spp: 1, 2, 4, 8, 16, 32, 64.
    Spp,
    /// --sampling: centers, corners.
    Sampling,
    /// --precision: f32, f64 (CPU).
    Precision,
    /// The backend and shader variant: cpu, gpu, gpu-fast (the GPU ones
    /// when a Vulkan device can be opened).
    Backend,
    /// The grid's resolution: the heuristic's scaled by 1/4, 1/2, 1, 2 per
    /// axis.
    Grid,
    /// --accel: grid, bvh.
    Accel,
    /// --shadows: plain, lightbuffer.
    Shadows,
}

impl Knob {
    pub const ALL: [Knob; 9] = [
        Knob::MaxDepth,
        Knob::MinWeight,
        Knob::Spp,
        Knob::Sampling,
        Knob::Precision,
        Knob::Backend,
        Knob::Grid,
        Knob::Accel,
        Knob::Shadows,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Knob::MaxDepth => "max-depth",
            Knob::MinWeight => "min-weight",
            Knob::Spp => "spp",
            Knob::Sampling => "sampling",
            Knob::Precision => "precision",
            Knob::Backend => "backend",
            Knob::Grid => "grid",
            Knob::Accel => "accel",
            Knob::Shadows => "shadows",
        }
    }
}

/// Where a point renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Device {
    Cpu,
    /// The exact kernel (`--gpu-math exact`).
    Gpu,
    /// The fast kernel (`--gpu-math fast`).
    GpuFast,
}

/// One point's settings: the defaults with one knob moved.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Config {
    pub max_depth: u32,
    pub min_weight: f32,
    pub spp: u32,
    pub sampling: Sampling,
    pub precision: Precision,
    pub device: Device,
    /// The grid's scale per axis against the heuristic's (forces the grid).
    pub grid_scale: Option<f32>,
    pub accel: Accel,
    pub shadows: crate::pack::Shadows,
}

impl Default for Config {
    /// The defaults of `whitted render` on the CPU.
    fn default() -> Config {
        let s = Settings::default();
        Config {
            max_depth: s.max_depth,
            min_weight: s.min_weight,
            spp: s.spp,
            sampling: s.sampling,
            precision: Precision::F32,
            device: Device::Cpu,
            grid_scale: None,
            accel: s.accel,
            shadows: s.shadows,
        }
    }
}

/// What a chart run does.
#[derive(Clone, Debug)]
pub struct Plan {
    pub width: u32,
    pub height: u32,
    /// Timed runs per point (after one warm-up).
    pub runs: u32,
    pub knobs: Vec<Knob>,
    pub reference: RefSettings,
    pub cache: Cache,
    pub budget: crate::budget::Budget,
    pub threads: Option<u32>,
    pub gpu: crate::gpu::GpuOptions,
}

/// One measured point.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Point {
    pub knob: Knob,
    /// The knob's value as the command line writes it.
    pub value: String,
    pub config: Config,
    /// Pack (structure build included) plus render, seconds.
    pub seconds: Summary,
    /// Against the converged reference: what the user sees.
    pub error: Accuracy,
    /// Against a reference through the same samples (same spp and
    /// sampling, f64, full depth, no cut-off): the knob's own error,
    /// without the sampling error every 1-sample point shares.
    pub own_error: Accuracy,
    /// Rays traced (every kind), for Mrays/s.
    pub rays: u64,
    /// On the Pareto front: no other point is both as fast and as exact
    /// (RMSE against the reference) and better in one of them.
    pub pareto: bool,
}

/// The values a knob takes, each with its label.
pub fn values(knob: Knob, gpu: bool) -> Vec<(String, Config)> {
    let base = Config::default();
    let with = |label: String, f: &dyn Fn(&mut Config)| {
        let mut c = base.clone();
        f(&mut c);
        (label, c)
    };
    match knob {
        Knob::MaxDepth => [0u32, 1, 2, 3, 4, 5, 6, 8, 12, 16]
            .iter()
            .map(|&d| with(d.to_string(), &|c| c.max_depth = d))
            .collect(),
        Knob::MinWeight => [4u32, 16, 64, 256, 1024, 4096, 0]
            .iter()
            .map(|&n| {
                let (label, w) = if n == 0 {
                    ("0".to_string(), 0.0)
                } else {
                    (format!("1/{n}"), 1.0 / n as f32)
                };
                with(label, &|c| c.min_weight = w)
            })
            .collect(),
        Knob::Spp => [1u32, 2, 4, 8, 16, 32, 64]
            .iter()
            .map(|&n| with(n.to_string(), &|c| c.spp = n))
            .collect(),
        Knob::Sampling => vec![
            with("centers".into(), &|c| c.sampling = Sampling::Centers),
            with("corners".into(), &|c| c.sampling = Sampling::Corners),
        ],
        Knob::Precision => vec![
            with("f32".into(), &|c| c.precision = Precision::F32),
            with("f64".into(), &|c| c.precision = Precision::F64),
        ],
        Knob::Backend => {
            let mut v = vec![with("cpu".into(), &|c| c.device = Device::Cpu)];
            if gpu {
                v.push(with("gpu".into(), &|c| c.device = Device::Gpu));
                v.push(with("gpu-fast".into(), &|c| c.device = Device::GpuFast));
            }
            v
        }
        Knob::Grid => [0.25f32, 0.5, 1.0, 2.0]
            .iter()
            .map(|&s| {
                with(format!("x{s}"), &|c| {
                    c.grid_scale = Some(s);
                    c.accel = Accel::Grid;
                })
            })
            .collect(),
        Knob::Accel => vec![
            with("grid".into(), &|c| c.accel = Accel::Grid),
            with("bvh".into(), &|c| c.accel = Accel::Bvh),
            with("octree".into(), &|c| c.accel = Accel::Octree),
            with("hybrid".into(), &|c| c.accel = Accel::Hybrid),
        ],
        Knob::Shadows => vec![
            with("plain".into(), &|c| c.shadows = crate::pack::Shadows::Plain),
            with("lightbuffer".into(), &|c| {
                c.shadows = crate::pack::Shadows::LightBuffer
            }),
        ],
    }
}

impl Plan {
    /// The render settings of `c`; `heuristic`: the grid the default
    /// settings build (for `grid_scale`).
    fn settings(&self, c: &Config, heuristic: [u32; 3]) -> Settings {
        let grid = c.grid_scale.map(|s| {
            heuristic
                .map(|n| ((n as f32 * s).round() as u32).clamp(1, crate::constants::GRID_MAX_DIM))
        });
        Settings {
            width: Some(self.width),
            height: Some(self.height),
            max_depth: c.max_depth,
            min_weight: c.min_weight,
            spp: c.spp,
            sampling: c.sampling,
            grid,
            accel: c.accel,
            budget: self.budget,
            offset: None,
            shadows: c.shadows,
            octree: Default::default(),
            hybrid_cell: crate::pack::hybrid::DEFAULT_CELL,
        }
    }
}

/// Renders `c` once: (seconds for pack and render, frame).
fn once(
    plan: &Plan,
    scene: &Scene,
    c: &Config,
    heuristic: [u32; 3],
    gpu: Option<&crate::gpu::Gpu>,
) -> Result<(f64, Frame)> {
    let t = Instant::now();
    let packed: Packed = run::pack(scene, &plan.settings(c, heuristic), Counting::Traced)?;
    let frame = match (c.device, gpu) {
        (Device::Cpu, _) => run::render_cpu(
            &packed,
            plan.threads,
            c.precision,
            crate::cpu::DEFAULT_PACKET,
            &|_, _| {},
        )?,
        (Device::Gpu | Device::GpuFast, Some(g)) => {
            let math = if c.device == Device::GpuFast {
                crate::gpu::GpuMath::Fast
            } else {
                crate::gpu::GpuMath::Exact
            };
            let opts = crate::gpu::GpuOptions {
                math,
                ..plan.gpu.clone()
            };
            g.render(&packed, &opts, &|_, _| {})
                .map_err(run::gpu_error)?
        }
        (_, None) => return Err(anyhow!("no GPU for a GPU point")),
    };
    Ok((t.elapsed().as_secs_f64(), frame))
}

/// Measures every point of `plan` on `scene`; progress: (renders done,
/// renders). The GPU points are left out, with a note, when no Vulkan device
/// can be opened.
pub fn run(plan: &Plan, scene: &Scene, progress: &dyn Fn(u64, u64)) -> Result<Vec<Point>> {
    let gpu = if plan.knobs.contains(&Knob::Backend) {
        match crate::gpu::Gpu::new(&plan.gpu) {
            Ok(g) => Some(g),
            Err(e) => {
                log::info!("chart: no GPU points ({e})");
                None
            }
        }
    } else {
        None
    };
    let heuristic = {
        let s = plan.settings(
            &Config {
                accel: Accel::Grid,
                ..Config::default()
            },
            [1; 3],
        );
        run::pack(scene, &s, Counting::Traced)?.grid.cells
    };
    let converged = reference::get(
        scene,
        &plan.reference,
        &plan.cache,
        plan.budget,
        plan.threads,
        &|_, _| {},
    )?
    .frame;
    let todo: Vec<(Knob, String, Config)> = plan
        .knobs
        .iter()
        .flat_map(|&k| {
            values(k, gpu.is_some())
                .into_iter()
                .map(move |(l, c)| (k, l, c))
        })
        .collect();
    // The defaults appear in several series: each config is measured once.
    let mut configs: Vec<Config> = Vec::new();
    for (_, _, c) in &todo {
        if !configs.contains(c) {
            configs.push(c.clone());
        }
    }
    let steps = (configs.len() * (1 + plan.runs.max(1) as usize)) as u64;
    let mut step = 0u64;
    // The warm-up pass: each config's image and errors. References through
    // the same samples, per (spp, sampling), from the cache when there.
    let mut same: Vec<((u32, Sampling), Frame)> = Vec::new();
    let mut measured: Vec<(Accuracy, Accuracy, u64)> = Vec::new();
    for c in &configs {
        progress(step, steps);
        step += 1;
        let (_, first) = once(plan, scene, c, heuristic, gpu.as_ref())?;
        let key = (c.spp, c.sampling);
        if !same.iter().any(|s| s.0 == key) {
            let rs = RefSettings {
                spp: c.spp,
                sampling: c.sampling,
                ..plan.reference
            };
            let f = reference::get(
                scene,
                &rs,
                &plan.cache,
                plan.budget,
                plan.threads,
                &|_, _| {},
            )?;
            same.push((key, f.frame));
        }
        let own_ref = &same.iter().find(|s| s.0 == key).expect("just added").1;
        measured.push((
            Accuracy::of(&converged, &first),
            Accuracy::of(own_ref, &first),
            first.stats.total(),
        ));
    }
    // Timed runs, interleaved: round after round over every config, so
    // that the machine's drift spreads over all of them alike.
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); configs.len()];
    for _ in 0..plan.runs.max(1) {
        for (i, c) in configs.iter().enumerate() {
            progress(step, steps);
            step += 1;
            times[i].push(once(plan, scene, c, heuristic, gpu.as_ref())?.0);
        }
    }
    let mut points: Vec<Point> = todo
        .iter()
        .map(|(knob, value, c)| {
            let i = configs.iter().position(|x| x == c).expect("listed");
            let (error, own_error, rays) = measured[i];
            Point {
                knob: *knob,
                value: value.clone(),
                config: c.clone(),
                seconds: Summary::of(&times[i]).expect("at least one run"),
                error,
                own_error,
                rays,
                pareto: false,
            }
        })
        .collect();
    progress(steps, steps);
    mark_pareto(&mut points);
    Ok(points)
}

/// Marks the points no other point dominates (time and RMSE against the
/// converged reference, both lower is better). Equal configs measured once
/// count once.
pub fn mark_pareto(points: &mut [Point]) {
    let key: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.seconds.median, p.error.rmse))
        .collect();
    for (i, p) in points.iter_mut().enumerate() {
        let (t, e) = key[i];
        p.pareto = !key
            .iter()
            .any(|&(t2, e2)| t2 <= t && e2 <= e && (t2 < t || e2 < e));
    }
}

/// The cheapest point whose RMSE against the reference is within one
/// display step (1/255).
pub fn cheapest_within_step(points: &[Point]) -> Option<&Point> {
    points
        .iter()
        .filter(|p| p.error.rmse <= STEP)
        .min_by(|a, b| a.seconds.median.total_cmp(&b.seconds.median))
}

/// The chart: RMSE against time on log axes, one series per knob, the
/// Pareto front ringed, and the 1/255 line.
pub fn chart(points: &[Point], title: &str) -> Chart {
    let mut series = Vec::new();
    let mut knobs: Vec<Knob> = points.iter().map(|p| p.knob).collect();
    knobs.dedup();
    for k in knobs {
        let pts: Vec<&Point> = points.iter().filter(|p| p.knob == k).collect();
        let mut s = Series::new(
            k.name(),
            pts.iter()
                .map(|p| (p.seconds.median, p.error.rmse.max(1e-9)))
                .collect(),
        );
        s.marked = pts
            .iter()
            .enumerate()
            .filter(|(_, p)| p.pareto)
            .map(|(i, _)| i)
            .collect();
        series.push(s);
    }
    let (t0, t1) = points.iter().fold((f64::MAX, 0.0f64), |(a, b), p| {
        (a.min(p.seconds.median), b.max(p.seconds.median))
    });
    if t1 > 0.0 {
        let mut line = Series::new("1/255 (one display step)", vec![(t0, STEP), (t1, STEP)]);
        line.color = Some((0, 0, 0));
        series.push(line);
    }
    Chart {
        title: title.into(),
        x_label: "seconds (pack + render, median)".into(),
        y_label: "RMSE against the reference (linear)".into(),
        log_x: true,
        log_y: true,
        series,
        x_categories: Vec::new(),
    }
}

/// The points as CSV, one row each.
pub fn csv(points: &[Point]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "knob",
        "value",
        "seconds_median",
        "seconds_min",
        "seconds_max",
        "mrays_per_s",
        "rmse",
        "psnr_db",
        "mean_flip",
        "worst",
        "worst_x",
        "worst_y",
        "fraction_over_1_255",
        "own_rmse",
        "own_psnr_db",
        "pareto",
    ])?;
    for p in points {
        let e = &p.error;
        w.write_record([
            p.knob.name().to_string(),
            p.value.clone(),
            format!("{:.6}", p.seconds.median),
            format!("{:.6}", p.seconds.min),
            format!("{:.6}", p.seconds.max),
            format!("{:.3}", p.rays as f64 / p.seconds.median.max(1e-9) / 1e6),
            format!("{:.6e}", e.rmse),
            format!("{:.3}", e.psnr),
            format!("{:.6}", e.mean_flip),
            format!("{:.6}", e.worst),
            e.worst_x.to_string(),
            e.worst_y.to_string(),
            format!("{:.6}", e.fraction_over_step),
            format!("{:.6e}", p.own_error.rmse),
            format!("{:.3}", p.own_error.psnr),
            p.pareto.to_string(),
        ])?;
    }
    Ok(String::from_utf8(w.into_inner()?)?)
}

/// The points as a table for a terminal, by knob.
pub fn table(points: &[Point]) -> String {
    let mut s = format!(
        "{:<11} {:>8} {:>9} {:>8} {:>10} {:>8} {:>8} {:>7} {:>10}  pareto\n",
        "knob", "value", "seconds", "Mrays/s", "RMSE", "PSNR", "FLIP", ">1/255", "own RMSE"
    );
    for p in points {
        let e = &p.error;
        s += &format!(
            "{:<11} {:>8} {:>9.4} {:>8.2} {:>10.3e} {:>8.2} {:>8.4} {:>6.2}% {:>10.3e}  {}\n",
            p.knob.name(),
            p.value,
            p.seconds.median,
            p.rays as f64 / p.seconds.median.max(1e-9) / 1e6,
            e.rmse,
            e.psnr,
            e.mean_flip,
            e.fraction_over_step * 100.0,
            p.own_error.rmse,
            if p.pareto { "*" } else { "" }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(t: f64, e: f64) -> Point {
        Point {
            knob: Knob::Spp,
            value: String::new(),
            config: Config::default(),
            seconds: Summary {
                median: t,
                min: t,
                max: t,
            },
            error: Accuracy {
                rmse: e,
                ..Default::default()
            },
            own_error: Accuracy::default(),
            rays: 0,
            pareto: false,
        }
    }

    #[test]
    fn the_pareto_front_keeps_only_undominated_points() {
        let mut p = vec![
            point(1.0, 0.1),
            point(2.0, 0.05),
            point(2.0, 0.2),  // dominated by both above
            point(3.0, 0.05), // dominated by (2, 0.05)
            point(4.0, 0.001),
            point(1.0, 0.1), // a twin of the first: both stay
        ];
        mark_pareto(&mut p);
        let front: Vec<bool> = p.iter().map(|p| p.pareto).collect();
        assert_eq!(front, [true, true, false, false, true, true]);
        assert_eq!(cheapest_within_step(&p).unwrap().seconds.median, 4.0);
        p[4].error.rmse = 0.01;
        assert!(cheapest_within_step(&p).is_none());
    }

    #[test]
    fn every_knob_moves_one_setting_from_the_defaults() {
        for k in Knob::ALL {
            let v = values(k, true);
            assert!(v.len() >= 2, "{k:?}");
            for (label, c) in &v {
                let d = Config::default();
                let moved = [
                    c.max_depth != d.max_depth,
                    c.min_weight != d.min_weight,
                    c.spp != d.spp,
                    c.sampling != d.sampling,
                    c.precision != d.precision,
                    c.device != d.device,
                    c.grid_scale != d.grid_scale || c.accel != d.accel,
                    c.shadows != d.shadows,
                ]
                .iter()
                .filter(|&&m| m)
                .count();
                assert!(moved <= 1, "{k:?} {label}");
            }
            // The defaults are among the values (except for the grid,
            // which forces the grid structure).
            if k != Knob::Grid && k != Knob::Accel {
                assert!(v.iter().any(|(_, c)| *c == Config::default()), "{k:?}");
            }
        }
        assert_eq!(values(Knob::Backend, false).len(), 1);
        assert_eq!(values(Knob::Backend, true).len(), 3);
    }
}
