//! The CPU backend: per-pixel entry, twin of `shaders/render.comp`.
//! Tiles of the image go to all cores (rayon); each sample's eye ray walks
//! its ray tree (`trace::tree`), and pixels average their samples.

use crate::constants::{ACCEL_BVH, FEAT_TRIANGLE, SAMPLING_CORNERS};
use crate::pack::Packed;
use crate::trace::intersect::RayPre;
use crate::trace::math::{Ray, Real, V3};
use crate::trace::packet::closest_hit_packet;
use crate::trace::query::Work;
use crate::trace::sample::{eye_dir, sample_pos};
use crate::trace::tree::{trace_ray, trace_ray_from};
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
    /// Wall seconds of each phase of a GPU render, in order (upload,
    /// pipeline, warm-up, dispatch, readback); empty for the CPU.
    pub phases: Vec<(&'static str, f64)>,
    /// Device seconds of each stage of the wavefront kernel, summed over
    /// tiles and depths (generate, extend, shade, shadow and combine,
    /// resolve); empty for the megakernel (one stage) and the CPU.
    pub device_stages: Vec<(&'static str, f64)>,
}

/// The packet width `render` traces eye rays in by default (`--packet`;
/// docs/method.md, "Packets of rays"; BENCHMARKS.md: whole SPD renders
/// 0-17 % faster than with single rays under the BVH).
pub const DEFAULT_PACKET: u32 = 8;

/// Renders on all cores of the current rayon pool, in f32 (the GPU's twin).
pub fn render(p: &Packed, progress: &(dyn Fn(u64, u64) + Sync)) -> Frame {
    render_as::<f32>(p, progress)
}

/// What tiles return besides their samples, which they write into the
/// lattice: what they cost (summed over a band of tiles, then the image).
pub type BandResult = (RayStats, Work);

/// Renders with the tracer running in float type `F` (f64: the
/// reference), one ray at a time as the shader walks them (so the work
/// counters compare with the GPU's).
pub fn render_as<F: Real>(p: &Packed, progress: &(dyn Fn(u64, u64) + Sync)) -> Frame {
    render_packets::<F>(p, 1, progress)
}

/// Renders in float type `F` with eye rays traced in packets of `packet`
/// (1, 4 or 8; any other width: 1) where the structure is the BVH (the
/// only one packets walk: `trace::packet`): the same image and ray
/// counts whatever the width; a packet's node visit counts once.
/// Pixel, sample and tile counts are 64-bit: a 65536 × 65536 image has
/// 2³² pixels and a (W+1)×(H+1) corner lattice more.
pub fn render_packets<F: Real>(
    p: &Packed,
    packet: u32,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Frame {
    let s = SceneView::new(p);
    let g = &p.globals;
    let packet = if g.flags[1] == ACCEL_BVH { packet } else { 1 };
    let (w, h) = (g.image[0], g.image[1]);
    let corners = g.image[3] == SAMPLING_CORNERS;
    // Corner sampling traces the (W+1)×(H+1) corner lattice, then resolves.
    let c = corners as u64;
    let (sw, sh) = (w as u64 + c, h as u64 + c);
    let t0 = Instant::now();
    let tile = TILE as u64;
    // At most 4097² tiles (65537 / 16 per side).
    let tiles_x = sw.div_ceil(tile);
    let tiles_y = sh.div_ceil(tile);
    let n_tiles = tiles_x * tiles_y;
    let done = std::sync::atomic::AtomicU64::new(0);
    // Each tile writes its samples straight into its rows of the lattice
    // (the lattice split into bands of one row of tiles, each band's rows
    // into the tiles' stretches), so no per-tile buffers outlive their
    // tile to be assembled afterwards (at 512², 3 MB of fresh pages and a
    // copy). The tiles are rendered in parallel, each from its own
    // scratch (`Work`: the shadow cache), so images and counters do not
    // depend on the scheduling; bands and tiles are handed out one at a
    // time (`with_max_len(1)`): the default split into a few large ranges
    // left a core idle where the cost is uneven across the image (SPD
    // mount's render used 133 % of two cores, now 180 %).
    let mut samples = vec![[0f32; 3]; (sw * sh) as usize];
    let none = || (RayStats::default(), Work::default());
    let add = |(mut st, mut wk): BandResult, (st2, wk2): BandResult| {
        st.add(&st2);
        wk.add(&wk2);
        (st, wk)
    };
    let (stats, work) = samples
        .par_chunks_mut((tile * sw) as usize)
        .with_max_len(1)
        .enumerate()
        .map(|(ty, band)| {
            let mut rows: Vec<Vec<&mut [[f32; 3]]>> = (0..tiles_x)
                .map(|_| Vec::with_capacity(TILE as usize))
                .collect();
            for row in band.chunks_mut(sw as usize) {
                for (tx, seg) in row.chunks_mut(TILE as usize).enumerate() {
                    rows[tx].push(seg);
                }
            }
            rows.into_par_iter()
                .with_max_len(1)
                .enumerate()
                .map(|(tx, segs)| {
                    let (xs, ys) = tile_rect(ty as u64 * tiles_x + tx as u64, tiles_x, sw, sh);
                    let width = (xs.end - xs.start) as usize;
                    let mut out = Vec::with_capacity((TILE * TILE) as usize);
                    let mut stats = RayStats::default();
                    let mut work = Work::default();
                    match packet {
                        4 => tile_packets::<F, 4>(
                            &s, xs, ys, corners, &mut out, &mut stats, &mut work,
                        ),
                        8 => tile_packets::<F, 8>(
                            &s, xs, ys, corners, &mut out, &mut stats, &mut work,
                        ),
                        _ => {
                            // x < sw ≤ W + 1 with W a u32: the lattice's last
                            // column is W itself (corners), so `as u32` is exact.
                            for y in ys {
                                for x in xs.clone() {
                                    let c = if corners {
                                        trace_sample::<F>(
                                            &s, x as f32, y as f32, &mut stats, &mut work,
                                        )
                                    } else {
                                        render_pixel::<F>(
                                            &s, x as u32, y as u32, &mut stats, &mut work,
                                        )
                                    };
                                    out.push(c);
                                }
                            }
                        }
                    }
                    for (seg, row) in segs.into_iter().zip(out.chunks(width)) {
                        seg.copy_from_slice(row);
                    }
                    let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                    progress(d, n_tiles);
                    (stats, work)
                })
                .reduce(none, add)
        })
        .reduce(none, add);
    let pixels = if corners {
        resolve_corners_in_place(samples, w, h)
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
        phases: Vec::new(),
        device_stages: Vec::new(),
    }
}

/// The columns and rows of tile `t` (row-major, `tiles_x` to a row) of an
/// `sw × sh` lattice cut into `TILE × TILE` tiles.
pub fn tile_rect(
    t: u64,
    tiles_x: u64,
    sw: u64,
    sh: u64,
) -> (std::ops::Range<u64>, std::ops::Range<u64>) {
    let tile = TILE as u64;
    let (tx, ty) = (t % tiles_x, t / tiles_x);
    (
        tx * tile..((tx + 1) * tile).min(sw),
        ty * tile..((ty + 1) * tile).min(sh),
    )
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

/// One tile's samples traced in packets of `P`, pushed to `out` row by
/// row as the single-ray loop pushes them. A packet takes the samples of
/// a block of pixels (2 × 2 for 4 lanes, 4 × 2 for 8), pixel by pixel,
/// each pixel's samples in order; a pixel's samples are summed in the
/// single ray's order, so the image is the same bit for bit.
fn tile_packets<F: Real, const P: usize>(
    s: &SceneView,
    xs: std::ops::Range<u64>,
    ys: std::ops::Range<u64>,
    corners: bool,
    out: &mut Vec<[f32; 3]>,
    stats: &mut RayStats,
    work: &mut Work,
) {
    let g = s.globals;
    let spp = if corners { 1 } else { g.image[2] as usize };
    let (bw, bh) = if P >= 8 { (4, 2) } else { (2, 2) };
    let (tw, th) = ((xs.end - xs.start) as usize, (ys.end - ys.start) as usize);
    // Each sample's place (pixel of the tile, sample) and image position.
    let mut order = Vec::with_capacity(tw * th * spp);
    for by in (0..th).step_by(bh) {
        for bx in (0..tw).step_by(bw) {
            for y in by..(by + bh).min(th) {
                for x in bx..(bx + bw).min(tw) {
                    let (px, py) = (xs.start + x as u64, ys.start + y as u64);
                    for k in 0..spp {
                        let pos = if corners {
                            (px as f32, py as f32)
                        } else {
                            sample_pos(g, px as u32, py as u32, k as u32)
                        };
                        order.push(((y * tw + x) * spp + k, pos));
                    }
                }
            }
        }
    }
    let mut colors = vec![[0f32; 3]; tw * th * spp];
    for chunk in order.chunks(P) {
        let c = trace_packet::<F, P>(s, chunk, stats, work);
        for (j, (at, _)) in chunk.iter().enumerate() {
            colors[*at] = c[j];
        }
    }
    if corners {
        out.extend_from_slice(&colors);
        return;
    }
    let inv = 1.0 / spp as f32;
    for px in colors.chunks(spp) {
        let mut sum = [0f32; 3];
        for c in px {
            for i in 0..3 {
                sum[i] += c[i];
            }
        }
        out.push(sum.map(|v| v * inv));
    }
}

/// Up to `P` eye rays through `samples`' image positions traced as a
/// packet: their closest hits together, then each ray's tree on its own
/// (`trace_ray_from`). Counts the eye rays. (Their eye hits' feelers go
/// one by one: as packets they win nothing; BENCHMARKS.md.)
fn trace_packet<F: Real, const P: usize>(
    s: &SceneView,
    samples: &[(usize, (f32, f32))],
    stats: &mut RayStats,
    work: &mut Work,
) -> [[f32; 3]; P] {
    let g = s.globals;
    let n = samples.len();
    stats.eye += n as u64;
    // Lanes past the samples repeat the first ray (their answers unused).
    let mut rays = [Ray {
        o: V3::zero(),
        d: V3::zero(),
    }; P];
    for j in 0..P {
        let (x, y) = samples[if j < n { j } else { 0 }].1;
        rays[j].d = eye_dir::<F>(g, x, y);
    }
    let pres = rays.map(|r| RayPre::new(r.d, s.has(FEAT_TRIANGLE)));
    let before = work.totals();
    let hits = closest_hit_packet(s, &rays, &pres, F::infinity(), work);
    work.credit_eye(before);
    let mut out = [[0f32; 3]; P];
    for j in 0..n {
        out[j] = match hits[j] {
            // A missed eye ray's tree is the background alone (weight 1, no
            // medium): what `trace_ray_from` would return, without the call
            // (SPD tetra's eye rays miss four times in five).
            None => V3::<F>::of(&g.background).to_f32(),
            hit => trace_ray_from(s, rays[j], Some(hit), stats, work).to_f32(),
        };
    }
    out
}

/// Each pixel is the mean of its four corners in the (W+1)×(H+1) lattice,
/// computed in the lattice's own memory: pixel (x, y) is written
/// at y·W + x, below every corner it or a later pixel reads (y·(W+1) + x
/// and beyond), so a forward pass never overwrites a corner it still
/// needs; the W·H pixels then fill the front. Saves a frame's worth of
/// fresh pages (3 MB at 512², about 750 page faults).
pub fn resolve_corners_in_place(mut c: Vec<[f32; 3]>, w: u32, h: u32) -> Vec<[f32; 3]> {
    let (w, h) = (w as usize, h as usize);
    let sw = w + 1;
    for y in 0..h {
        for x in 0..w {
            let (a, b, cc, d) = (
                c[y * sw + x],
                c[y * sw + x + 1],
                c[(y + 1) * sw + x],
                c[(y + 1) * sw + x + 1],
            );
            c[y * w + x] = [0, 1, 2].map(|i| ((a[i] + b[i]) + (cc[i] + d[i])) * 0.25);
        }
    }
    c.truncate(w * h);
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest corner lattice (65537², past u32::MAX samples): its
    /// tiles cover it exactly, counted in 64 bits.
    #[test]
    fn tiles_cover_the_largest_lattice() {
        let (sw, sh) = (65537u64, 65537u64);
        let tiles_x = sw.div_ceil(TILE as u64);
        let n = tiles_x * sh.div_ceil(TILE as u64);
        assert!(sw * sh > u32::MAX as u64);
        let area = |t: u64| {
            let (xs, ys) = tile_rect(t, tiles_x, sw, sh);
            (xs.end - xs.start) * (ys.end - ys.start)
        };
        // every full row of tiles has the same area, so check one row
        // and the last, and the last tile's far corner
        let row: u64 = (0..tiles_x).map(area).sum();
        let last_row: u64 = (n - tiles_x..n).map(area).sum();
        assert_eq!(row, sw * TILE as u64);
        assert_eq!(row * (n / tiles_x - 1) + last_row, sw * sh);
        let (xs, ys) = tile_rect(n - 1, tiles_x, sw, sh);
        assert_eq!((xs.end, ys.end), (sw, sh));
        assert_eq!((xs.start, ys.start), (65536, 65536));
    }

    #[test]
    fn corners_resolve_at_their_lattice() {
        let (w, h) = (3u32, 2u32);
        let lattice: Vec<[f32; 3]> = (0..(w + 1) * (h + 1)).map(|i| [i as f32; 3]).collect();
        let px = resolve_corners_in_place(lattice, w, h);
        assert_eq!(px.len(), 6);
        // pixel (1, 1): corners 5, 6, 9, 10 of the 4-wide lattice
        assert_eq!(px[4], [7.5; 3]);
    }

    /// Resolving in place reads no corner it has overwritten: every pixel
    /// equals the mean of its corners in a copy, on lattices of several
    /// shapes with distinct values.
    #[test]
    fn corners_resolve_in_place_as_from_a_copy() {
        for (w, h) in [(1u32, 1u32), (1, 5), (7, 1), (5, 4), (16, 9)] {
            let sw = w as usize + 1;
            let lattice: Vec<[f32; 3]> = (0..sw * (h as usize + 1))
                .map(|i| [i as f32, (i * i % 97) as f32, -(i as f32) * 0.5])
                .collect();
            let px = resolve_corners_in_place(lattice.clone(), w, h);
            assert_eq!(px.len(), (w * h) as usize);
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let c = |i: usize| lattice[i];
                    let (a, b) = (c(y * sw + x), c(y * sw + x + 1));
                    let (cc, d) = (c((y + 1) * sw + x), c((y + 1) * sw + x + 1));
                    let want = [0, 1, 2].map(|i| ((a[i] + b[i]) + (cc[i] + d[i])) * 0.25);
                    assert_eq!(px[y * w as usize + x], want, "{w}x{h} pixel ({x}, {y})");
                }
            }
        }
    }
}
