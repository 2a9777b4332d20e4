//! Dispatch shapes (`whitted profile`, docs/profiling.md): every workgroup
//! shape × tile size on one device, a warm-up pass, then interleaved
//! rounds; device time from timestamp queries and the wall time of the
//! same renders; the phases of one render; and the best shape saved per
//! device for `render` to use.

use crate::bench::Summary;
use crate::cpu::Frame;
use crate::gpu::{DeviceInfo, Gpu, GpuKernel, GpuMath, GpuOptions};
use crate::pack::Packed;
use anyhow::{anyhow, Context, Result};
use std::path::PathBuf;

/// A tile edge that covers any image (the largest `--tile`): one
/// submission per image, up to the per-submission sample cap.
pub const FULL_TILE: u32 = 16384;

/// One combination's measurements.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// The megakernel or the wavefront kernel (`--kernels`).
    pub kernel: GpuKernel,
    pub workgroup: [u32; 2],
    /// The tile edge; `FULL_TILE` for `full`.
    pub tile: u32,
    /// Device seconds (timestamp queries) per render; None without a clock.
    pub device: Option<Summary>,
    /// Wall seconds of the same renders (`Frame::seconds`).
    pub wall: Summary,
    /// Every ray, shadow rays included.
    pub rays: u64,
    /// Why the device refused the shape, if it did.
    pub refused: Option<String>,
    /// The fastest combination (by median device time, or wall time
    /// without a clock).
    pub best: bool,
}

impl Row {
    /// The time the table sorts by.
    pub fn key(&self) -> f64 {
        self.device.map_or(self.wall.median, |d| d.median)
    }
    pub fn tile_name(&self) -> String {
        if self.tile == FULL_TILE {
            "full".into()
        } else {
            self.tile.to_string()
        }
    }
}

/// Renders `packed` with every combination of kernel, workgroup shape and
/// tile: one warm-up render each (it also compiles each shape's
/// pipeline), then `repeat` rounds over all of them. A combination the
/// device (or the kernel) refuses is a row with the reason, not an error.
/// Every image must equal the first one bit for bit (neither a dispatch
/// shape nor the kernel ever changes a pixel), else the run fails.
#[allow(clippy::too_many_arguments)]
pub fn run(
    g: &Gpu,
    packed: &Packed,
    base: &GpuOptions,
    kernels: &[GpuKernel],
    workgroups: &[[u32; 2]],
    tiles: &[u32],
    repeat: u32,
    progress: &dyn Fn(u64, u64),
) -> Result<Vec<Row>> {
    let combos: Vec<(GpuKernel, [u32; 2], u32)> = kernels
        .iter()
        .flat_map(|&k| {
            workgroups
                .iter()
                .flat_map(move |&w| tiles.iter().map(move |&t| (k, w, t)))
        })
        .collect();
    let total = (combos.len() * (1 + repeat.max(1) as usize)) as u64;
    let mut step = 0u64;
    // The first image of the scene's kernels and of the calibration
    // kernel (its own pixels): every other combination must equal its own.
    let mut first: [Option<Frame>; 2] = [None, None];
    let mut refused: Vec<Option<String>> = Vec::new();
    let mut rays = Vec::new();
    let opts = |k: GpuKernel, w: [u32; 2], t: u32| GpuOptions {
        kernel: k,
        workgroup: w,
        tile: t,
        ..base.clone()
    };
    for &(k, w, t) in &combos {
        progress(step, total);
        step += 1;
        match g.render(packed, &opts(k, w, t), &|_, _| {}) {
            Ok(f) => {
                let class = (k == GpuKernel::Calibration) as usize;
                if let Some(f0) = &first[class] {
                    let same = f0
                        .pixels
                        .iter()
                        .flatten()
                        .zip(f.pixels.iter().flatten())
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    if !same || f0.stats != f.stats {
                        return Err(anyhow!(
                            "{} kernel, workgroup {}x{}, tile {t}: the image or the ray counts \
                             differ from the first combination's: neither a dispatch shape nor \
                             the kernel may change a pixel",
                            k.name(),
                            w[0],
                            w[1]
                        ));
                    }
                }
                rays.push(f.stats.total());
                first[class].get_or_insert(f);
                refused.push(None);
            }
            Err(e) if e.is_user_error() => {
                rays.push(0);
                refused.push(Some(e.to_string()));
            }
            Err(e) => return Err(crate::run::gpu_error(e)),
        }
    }
    let mut device: Vec<Vec<f64>> = vec![Vec::new(); combos.len()];
    let mut wall: Vec<Vec<f64>> = vec![Vec::new(); combos.len()];
    for _ in 0..repeat.max(1) {
        for (i, &(k, w, t)) in combos.iter().enumerate() {
            progress(step, total);
            step += 1;
            if refused[i].is_some() {
                continue;
            }
            let f = g
                .render(packed, &opts(k, w, t), &|_, _| {})
                .map_err(crate::run::gpu_error)?;
            if let Some(d) = f.device_seconds {
                device[i].push(d);
            }
            wall[i].push(f.seconds);
        }
    }
    progress(total, total);
    let mut rows: Vec<Row> = combos
        .iter()
        .enumerate()
        .map(|(i, &(k, w, t))| Row {
            kernel: k,
            workgroup: w,
            tile: t,
            device: Summary::of(&device[i]),
            wall: Summary::of(&wall[i]).unwrap_or_default(),
            rays: rays[i],
            refused: refused[i].clone(),
            best: false,
        })
        .collect();
    rows.sort_by(|a, b| {
        (a.refused.is_some(), a.key())
            .partial_cmp(&(b.refused.is_some(), b.key()))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    // The best of the kernels that render the scene's image (the
    // calibration kernel's rows show their time against it).
    if let Some(r) = rows
        .iter_mut()
        .find(|r| r.refused.is_none() && r.kernel != GpuKernel::Calibration)
    {
        r.best = true;
    }
    Ok(rows)
}

/// The table for a terminal, fastest first.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:>19} {:>6} {:>10} {:>10} {:>10} {:>10} {:>9}\n",
        "kernel workgroup", "tile", "device med", "min", "max", "wall med", "Mrays/s"
    );
    let best = rows.iter().find(|r| r.best).map(|r| r.key());
    for r in rows {
        let wg = format!(
            "{:>9} {}x{}",
            r.kernel.name(),
            r.workgroup[0],
            r.workgroup[1]
        );
        if let Some(why) = &r.refused {
            s += &format!("{wg:>19} {:>6}  refused: {why}\n", r.tile_name());
            continue;
        }
        let (m, lo, hi) = r
            .device
            .map_or((f64::NAN, f64::NAN, f64::NAN), |d| (d.median, d.min, d.max));
        s += &format!(
            "{wg:>19} {:>6} {m:>10.4} {lo:>10.4} {hi:>10.4} {:>10.4} {:>9.2}{}\n",
            r.tile_name(),
            r.wall.median,
            r.rays as f64 / r.key().max(1e-12) / 1e6,
            match (r.best, best) {
                (true, _) => "  best".to_string(),
                (false, Some(b)) => format!("  {:.2}x", r.key() / b),
                _ => String::new(),
            }
        );
    }
    s
}

/// The rows as CSV.
pub fn csv(rows: &[Row]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "kernel",
        "workgroup",
        "tile",
        "device_median_s",
        "device_min_s",
        "device_max_s",
        "wall_median_s",
        "rays",
        "mrays_per_s",
        "best",
        "refused",
    ])?;
    for r in rows {
        let d = |f: fn(&Summary) -> f64| {
            r.device
                .as_ref()
                .map_or(String::new(), |s| format!("{:.6}", f(s)))
        };
        w.write_record([
            r.kernel.name().to_string(),
            format!("{}x{}", r.workgroup[0], r.workgroup[1]),
            r.tile_name(),
            d(|s| s.median),
            d(|s| s.min),
            d(|s| s.max),
            format!("{:.6}", r.wall.median),
            r.rays.to_string(),
            if r.refused.is_some() {
                String::new()
            } else {
                format!("{:.3}", r.rays as f64 / r.key().max(1e-12) / 1e6)
            },
            r.best.to_string(),
            r.refused.clone().unwrap_or_default(),
        ])?;
    }
    Ok(String::from_utf8(w.into_inner()?)?)
}

/// The heat map: workgroup shapes down (per kernel when there are
/// several), tile sizes across, each cell the median time relative to the
/// best.
pub fn heat_map(rows: &[Row], title: &str) -> crate::plot::HeatMap {
    let mut wgs: Vec<(GpuKernel, [u32; 2])> = Vec::new();
    let mut tiles: Vec<u32> = Vec::new();
    for r in rows {
        if !wgs.contains(&(r.kernel, r.workgroup)) {
            wgs.push((r.kernel, r.workgroup));
        }
        if !tiles.contains(&r.tile) {
            tiles.push(r.tile);
        }
    }
    wgs.sort_by_key(|&(k, w)| (k as u8, w[0] * w[1], w[0]));
    let several = wgs.iter().any(|&(k, _)| k != wgs[0].0);
    tiles.sort();
    let best = rows.iter().find(|r| r.best).map_or(1.0, |r| r.key());
    let cells = wgs
        .iter()
        .map(|&(k, w)| {
            tiles
                .iter()
                .map(|t| {
                    rows.iter()
                        .find(|r| {
                            r.kernel == k && r.workgroup == w && r.tile == *t && r.refused.is_none()
                        })
                        .map(|r| r.key() / best)
                })
                .collect()
        })
        .collect();
    crate::plot::HeatMap {
        title: title.into(),
        rows: wgs
            .iter()
            .map(|&(k, w)| {
                if several {
                    format!("{} {}x{}", k.name(), w[0], w[1])
                } else {
                    format!("{}x{}", w[0], w[1])
                }
            })
            .collect(),
        columns: tiles
            .iter()
            .map(|&t| {
                if t == FULL_TILE {
                    "full".into()
                } else {
                    t.to_string()
                }
            })
            .collect(),
        row_label: "workgroup".into(),
        column_label: "tile edge (samples)".into(),
        values: cells,
        value_label: "time / best".into(),
    }
}

// ------------------------------------------------------------ saved shapes

/// A saved best shape for one device and driver.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Saved {
    pub device: String,
    pub driver: String,
    pub workgroup: [u32; 2],
    pub tile: u32,
    /// The kernel that won (files saved before kernels were profiled have
    /// none: the megakernel).
    #[serde(default)]
    pub kernel: GpuKernel,
    /// The command that measured it.
    pub measured_by: String,
}

/// The file of `info`'s saved shape: one per device UUID and driver
/// version, in the cache folder (`$XDG_CACHE_HOME/whitted/profiles` or
/// `~/.cache/whitted/profiles`).
pub fn saved_path(info: &DeviceInfo) -> Option<PathBuf> {
    crate::gpu::pipeline::cache_dir().map(|d| {
        d.join("profiles")
            .join(format!("{}-{:08x}.json", info.uuid, info.driver_version))
    })
}

/// Saves `saved` for `info`; returns the file.
pub fn save(info: &DeviceInfo, saved: &Saved) -> Result<PathBuf> {
    let p = saved_path(info).context("no cache folder (neither XDG_CACHE_HOME nor HOME is set)")?;
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).with_context(|| format!("{}", d.display()))?;
    }
    crate::files::write_bytes(
        &crate::files::Dest::File(p.clone()),
        serde_json::to_string_pretty(saved)?.as_bytes(),
    )?;
    Ok(p)
}

/// The saved shape of `info`, if one was saved and can be read (a bad
/// file is ignored with a warning: it never fails a render).
pub fn load(info: &DeviceInfo) -> Option<(Saved, PathBuf)> {
    let p = saved_path(info)?;
    let text = std::fs::read_to_string(&p).ok()?;
    match serde_json::from_str::<Saved>(&text) {
        Ok(s)
            if s.workgroup.iter().all(|&n| (1..=1024).contains(&n))
                && (1..=FULL_TILE).contains(&s.tile) =>
        {
            Some((s, p))
        }
        _ => {
            log::warn!("{}: not a saved dispatch shape; ignored", p.display());
            None
        }
    }
}

/// The options a render uses: the saved shape for this device when the
/// user gave neither `--workgroup` nor `--tile` (`opts.saved_shape`), and
/// the saved kernel when the user gave no `--kernel` (`opts.saved_kernel`)
/// and the arithmetic is exact (the wavefront has no fast one).
pub fn apply_saved(info: &DeviceInfo, opts: &GpuOptions) -> GpuOptions {
    if !opts.saved_shape && !opts.saved_kernel {
        return opts.clone();
    }
    let Some((s, p)) = load(info) else {
        return opts.clone();
    };
    let mut out = opts.clone();
    if opts.saved_shape {
        log::debug!(
            "dispatch shape {}x{}, tile {} from {} (whitted profile --save)",
            s.workgroup[0],
            s.workgroup[1],
            s.tile,
            p.display()
        );
        out.workgroup = s.workgroup;
        out.tile = s.tile;
    }
    // Never the calibration kernel (a hand-edited file): not the image.
    if opts.saved_kernel
        && s.kernel != GpuKernel::Calibration
        && (s.kernel == GpuKernel::Mega || opts.math == GpuMath::Exact)
    {
        log::debug!(
            "the {} kernel from {} (whitted profile --save)",
            s.kernel.name(),
            p.display()
        );
        out.kernel = s.kernel;
    }
    out
}

/// Parses a tile list entry: a number or `full`.
pub fn parse_tile(s: &str) -> Result<u32, String> {
    if s == "full" {
        return Ok(FULL_TILE);
    }
    s.parse::<u32>()
        .ok()
        .filter(|n| (1..=FULL_TILE).contains(n))
        .ok_or_else(|| format!("expected a tile edge from 1 to {FULL_TILE} or `full`, got '{s}'"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_parse_and_refuse() {
        assert_eq!(parse_tile("full"), Ok(FULL_TILE));
        assert_eq!(parse_tile("64"), Ok(64));
        assert!(parse_tile("0").is_err());
        assert!(parse_tile("x").is_err());
    }

    #[test]
    fn the_table_marks_the_best_and_ratios() {
        let row = |w: u32, t: f64| Row {
            kernel: GpuKernel::Mega,
            workgroup: [w, 1],
            tile: 64,
            device: Some(Summary {
                median: t,
                min: t,
                max: t,
            }),
            wall: Summary::default(),
            rays: 1_000_000,
            refused: None,
            best: false,
        };
        let mut rows = vec![row(8, 0.5), row(16, 1.0)];
        rows[0].best = true;
        let t = table(&rows);
        assert!(t.contains("best"), "{t}");
        assert!(t.contains("2.00x"), "{t}");
        let h = heat_map(&rows, "t");
        assert_eq!(h.values, vec![vec![Some(1.0)], vec![Some(2.0)]]);
    }
}
