//! The CPU backend: per-pixel entry, twin of `shaders/render.comp`.
//! Tiles of the image go to all cores (rayon); each sample's eye ray walks
//! its ray tree (`trace::tree`), and pixels average their samples.

use crate::constants::SAMPLING_CORNERS;
use crate::pack::Packed;
use crate::trace::grid::Work;
use crate::trace::math::{Ray, Real, V3};
use crate::trace::sample::{eye_dir, sample_pos};
use crate::trace::tree::trace_ray;
use crate::trace::{RayStats, SceneView};
use rayon::prelude::*;
use std::time::Instant;

/// Edge of a square tile, in pixels.
pub const TILE: u32 = 16;

/// A rendered image: linear RGB, row-major from the top-left, plus what it cost.
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
    pub stats: RayStats,
    pub work: Work,
    /// Seconds spent rendering (tracing only).
    pub seconds: f64,
    /// Seconds the device reported for its dispatches, when it has a clock.
    pub device_seconds: Option<f64>,
}

/// Renders on all cores of the current rayon pool, in f32 (the GPU's twin).
pub fn render(p: &Packed, progress: &(dyn Fn(u64, u64) + Sync)) -> Frame {
    render_as::<f32>(p, progress)
}

/// Renders with the tracer running in float type `F` (f64: the reference).
pub fn render_as<F: Real>(p: &Packed, progress: &(dyn Fn(u64, u64) + Sync)) -> Frame {
    let s = SceneView::new(p);
    let g = &p.globals;
    let (w, h) = (g.image[0], g.image[1]);
    let corners = g.image[3] == SAMPLING_CORNERS;
    // Corner sampling traces the (W+1)×(H+1) corner lattice, then resolves.
    let (sw, sh) = if corners { (w + 1, h + 1) } else { (w, h) };
    let t0 = Instant::now();
    let tiles_x = sw.div_ceil(TILE);
    let tiles_y = sh.div_ceil(TILE);
    let n_tiles = (tiles_x * tiles_y) as u64;
    let done = std::sync::atomic::AtomicU64::new(0);
    let tiles: Vec<(Vec<[f32; 3]>, RayStats, Work)> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let mut out = Vec::with_capacity((TILE * TILE) as usize);
            let mut stats = RayStats::default();
            let mut work = Work::default();
            for y in ty * TILE..((ty + 1) * TILE).min(sh) {
                for x in tx * TILE..((tx + 1) * TILE).min(sw) {
                    let c = if corners {
                        trace_sample::<F>(&s, x as f32, y as f32, &mut stats, &mut work)
                    } else {
                        render_pixel::<F>(&s, x, y, &mut stats, &mut work)
                    };
                    out.push(c);
                }
            }
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(d, n_tiles);
            (out, stats, work)
        })
        .collect();
    let mut samples = vec![[0f32; 3]; (sw * sh) as usize];
    let mut stats = RayStats::default();
    let mut work = Work::default();
    for (t, (out, st, wk)) in tiles.iter().enumerate() {
        let t = t as u32;
        let (tx, ty) = (t % tiles_x, t / tiles_x);
        let x0 = tx * TILE;
        let x1 = ((tx + 1) * TILE).min(sw);
        let mut i = 0;
        for y in ty * TILE..((ty + 1) * TILE).min(sh) {
            let row = (y * sw) as usize;
            samples[row + x0 as usize..row + x1 as usize]
                .copy_from_slice(&out[i..i + (x1 - x0) as usize]);
            i += (x1 - x0) as usize;
        }
        stats.add(st);
        work.tests += wk.tests;
        work.cells += wk.cells;
    }
    let pixels = if corners {
        resolve_corners(&samples, w, h)
    } else {
        samples
    };
    Frame {
        width: w,
        height: h,
        pixels,
        stats,
        work,
        seconds: t0.elapsed().as_secs_f64(),
        device_seconds: None,
    }
}

/// One eye ray through image position (x, y); counts it.
#[inline]
pub fn trace_sample<F: Real>(
    s: &SceneView,
    x: f32,
    y: f32,
    stats: &mut RayStats,
    work: &mut Work,
) -> [f32; 3] {
    stats.eye += 1;
    let d = eye_dir::<F>(s.globals, x, y);
    trace_ray(s, Ray { o: V3::zero(), d }, stats, work).to_f32()
}

/// The mean of a pixel's samples.
#[inline]
pub fn render_pixel<F: Real>(
    s: &SceneView,
    px: u32,
    py: u32,
    stats: &mut RayStats,
    work: &mut Work,
) -> [f32; 3] {
    let spp = s.globals.image[2];
    let mut sum = [0f32; 3];
    for k in 0..spp {
        let (x, y) = sample_pos(s.globals, px, py, k);
        let c = trace_sample::<F>(s, x, y, stats, work);
        for i in 0..3 {
            sum[i] += c[i];
        }
    }
    let inv = 1.0 / spp as f32;
    sum.map(|v| v * inv)
}

/// Each pixel is the mean of its four corners in the (W+1)×(H+1) lattice.
pub fn resolve_corners(c: &[[f32; 3]], w: u32, h: u32) -> Vec<[f32; 3]> {
    let sw = (w + 1) as usize;
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let (a, b, cc, d) = (
                c[y * sw + x],
                c[y * sw + x + 1],
                c[(y + 1) * sw + x],
                c[(y + 1) * sw + x + 1],
            );
            out.push([0, 1, 2].map(|i| ((a[i] + b[i]) + (cc[i] + d[i])) * 0.25));
        }
    }
    out
}
