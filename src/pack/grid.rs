//! Building the uniform voxel grid over the finite primitives.
//!
//! Resolution heuristic (documented in docs/method.md, "Voxel grid"): aim
//! for `GRID_DENSITY` cells per primitive up to a million cells, then a
//! million, then one cell per primitive (`target_cells`: C), cells as close
//! to cubes as the scene's extent allows: k = cbrt(C / V), n_i = round(e_i · k)
//! clamped to [1, GRID_MAX_DIM], where e_i are the extents of the bounds of
//! all finite primitives relative to the largest (each at least 1/1000 of
//! it, so flat scenes get a flat grid rather than a degenerate one, and
//! tiny or huge scenes neither underflow nor overflow) and V their product.
//!
//! A counting pass then counts the references that resolution makes,
//! exactly and in 64 bits, before anything is filed (O(N): a primitive's
//! references are the product of its cell range's sides). The heuristic
//! coarsens the grid while the references do not fit (the memory budget,
//! and `MAX_REFS` for the 32-bit offsets), and while they exceed
//! `REDUNDANT_REFS_PER_PRIM` per primitive without refining paying: when
//! primitives overlap so much that a finer grid only repeats the same
//! lists in more cells (a pile of identical spheres), the coarser grid
//! traces as fast in a fraction of the memory.

use super::layout::{cell_pack, cell_unpack, Prim};
use super::pages::Pages;
use crate::constants::{GRID_DENSITY, GRID_MAX_DIM, KIND_SPHERE, SKIP_MAX};
use rayon::prelude::*;

/// Most references a grid may hold: `cell_start` holds u32 offsets (the
/// shader's arrays are indexed in 32 bits).
pub const MAX_REFS: u64 = u32::MAX as u64;

/// References per primitive above which the heuristic asks whether a
/// coarser grid would do. Well-formed scenes stay below it with a factor
/// of two to spare (measured at the default density, docs/method.md: the
/// SPD scenes 1.6 to 8.7, 1 M random spheres 11.9, scenes/showcase.toml
/// 14.1; a primitive no larger than a cell is in at most 8 cells).
pub const REDUNDANT_REFS_PER_PRIM: u64 = 32;

/// Refining from the coarser grid must shorten the mean reference list
/// per cell to at most this share of it to be worth its cells.
const REFINE_GAIN: f64 = 0.75;

/// Bounds in camera-relative f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };
    pub fn union(&self, o: &Bounds) -> Bounds {
        let mut r = *self;
        for i in 0..3 {
            r.lo[i] = r.lo[i].min(o.lo[i]);
            r.hi[i] = r.hi[i].max(o.hi[i]);
        }
        r
    }
    pub fn extent(&self) -> [f64; 3] {
        [
            self.hi[0] - self.lo[0],
            self.hi[1] - self.lo[1],
            self.hi[2] - self.lo[2],
        ]
    }
    pub fn diagonal(&self) -> f64 {
        let e = self.extent();
        (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
    }
}

/// The grid: bounds, cells per axis, cell size, and the reference lists.
#[derive(Clone, Debug, Default)]
pub struct Grid {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub dims: [u32; 3],
    pub cell: [f32; 3],
    /// Per primitive: packed lowest and highest cell of its bounds.
    pub ranges: Vec<(u32, u32)>,
    /// `ncells + 1` offsets into `refs`, then the empty-space distances,
    /// one byte per cell, four to a word (see `skip_distances`).
    pub cell_start: Vec<u32>,
    pub refs: Vec<u32>,
    /// Per reference, its test-once bits (`Walk::bits`), written as it is
    /// filed.
    pub bits: Vec<u8>,
}

/// Which pass of the build a progress report is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Ordering the primitives in memory (`pack`'s Morton sort): reported
    /// when it starts and when it ends.
    Sort,
    /// Counting the references of a candidate resolution (there may be a
    /// few passes, each from 0).
    Count,
    /// Filing every primitive into its cells.
    File,
    /// Building the BVH (primitives placed in leaves so far).
    Bvh,
}

/// `progress(stage, done, total)`: primitives done in the current pass.
pub type Progress<'a> = &'a (dyn Fn(Stage, u64, u64) + Sync);

/// Primitives between two progress reports.
const PROGRESS_EVERY: usize = 1 << 16;
/// Primitives a parallel task of the counting pass takes at a time.
const PARALLEL_CHUNK: usize = 1 << 12;

/// Why no grid could be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// The smallest grid tried (the `--grid` asked for, or 1×1×1).
    pub dims: [u32; 3],
    pub cells: u64,
    /// Its references, counted exactly.
    pub refs: u64,
}

/// Cells of `dims`, in 64 bits.
pub fn cells_of(dims: [u32; 3]) -> u64 {
    dims[0] as u64 * dims[1] as u64 * dims[2] as u64
}

/// Cells a grid of `n` primitives aims at: `GRID_DENSITY` per primitive
/// up to `DENSE_CELLS_MAX` cells, then that many, and one per primitive
/// once there are more primitives than that (docs/method.md, "Voxel
/// grid"). Never fewer for more primitives.
pub fn target_cells(n: usize) -> f64 {
    let n = n.max(1) as f64;
    (GRID_DENSITY as f64 * n).min(DENSE_CELLS_MAX.max(n))
}

/// Cells beyond which a grid no longer aims at `GRID_DENSITY` per
/// primitive. With 1 M random spheres, 3 cells a primitive made 11.9 M
/// references (cell offsets, references and the walk's arrays about
/// 90 MB, nearly three times this machine's L3 cache), and one cell a
/// primitive rendered 7 % faster on the CPU and 11 % on lavapipe (6.8 M
/// references, 55 MB); at 500 k, 2 cells a primitive 2 % and 5 %;
/// at 200 k the CPU still gained from 1 cell a primitive but lavapipe lost
/// 8 %, and on smaller scenes lavapipe loses more (BENCHMARKS.md, "The
/// grid's density for large scenes").
pub const DENSE_CELLS_MAX: f64 = 1_000_000.0;

/// Cells per axis for `n` primitives inside `b`.
pub fn resolution(b: &Bounds, n: usize) -> [u32; 3] {
    let e = b.extent();
    let emax = e[0].max(e[1]).max(e[2]);
    if !(emax > 0.0 && emax.is_finite()) {
        return [1, 1, 1]; // all at one point (or beyond f64)
    }
    // Relative extents in [1e-3, 1]: their product cannot underflow.
    let r = e.map(|x| (x / emax).max(1e-3));
    let k = (target_cells(n) / (r[0] * r[1] * r[2])).cbrt();
    r.map(|x| ((x * k).round() as u32).clamp(1, GRID_MAX_DIM))
}

/// About `cells(dims) / 2` cells, the same shape: each side × 2^(−1/3).
pub fn coarser(dims: [u32; 3]) -> [u32; 3] {
    let f = 0.5f64.cbrt();
    let mut d = dims.map(|n| ((n as f64 * f).round() as u32).max(1));
    if d == dims {
        // rounding kept every side: shorten the longest
        let i = (0..3).max_by_key(|&i| dims[i]).unwrap_or(0);
        d[i] = (dims[i] - 1).max(1);
    }
    d
}

/// The grid's box in f32: the bounds padded so that primitives touching
/// them are strictly inside, by at least a few f32 steps of the
/// coordinates' magnitude on each axis (a tiny scene far from the camera
/// must not collapse to a box of zero width in f32).
pub(crate) fn grid_box(all: &Bounds) -> ([f32; 3], [f32; 3]) {
    let pad = all.diagonal().max(1e-30) * 1e-5;
    let mut lo = [0f32; 3];
    let mut hi = [0f32; 3];
    for i in 0..3 {
        let mag = all.lo[i].abs().max(all.hi[i].abs());
        let p = pad.max(4.0 * f32::EPSILON as f64 * mag);
        lo[i] = (all.lo[i] - p) as f32;
        hi[i] = (all.hi[i] + p) as f32;
    }
    (lo, hi)
}

/// At most this many cells on an axis of the box `lo..hi`: each cell at
/// least 8 f32 steps wide, so that cell boundaries stay distinct numbers.
pub(crate) fn f32_cap(lo: f32, hi: f32) -> u32 {
    let ulp = lo.abs().max(hi.abs()) as f64 * f32::EPSILON as f64;
    if ulp.is_nan() || ulp <= 0.0 {
        return GRID_MAX_DIM;
    }
    let n = ((hi as f64 - lo as f64) / (8.0 * ulp)).floor();
    if n.is_nan() {
        1
    } else {
        n.clamp(1.0, GRID_MAX_DIM as f64) as u32
    }
}

/// The grid's box and cell size for `dims`.
struct Layout {
    lo: [f32; 3],
    hi: [f32; 3],
    dims: [u32; 3],
    cell: [f32; 3],
}

impl Layout {
    fn new(lo: [f32; 3], hi: [f32; 3], dims: [u32; 3]) -> Layout {
        let cell = [0, 1, 2].map(|i| (hi[i] - lo[i]) / dims[i] as f32);
        Layout { lo, hi, dims, cell }
    }

    /// Packed lowest and highest cell of `b`'s bounds. They grow by a
    /// small margin so that a hit the DDA's rounding puts one cell over
    /// is still in that cell's list.
    #[inline]
    fn range(&self, b: &Bounds) -> (u32, u32) {
        let cell_of = |x: f64, i: usize| -> u32 {
            let c = ((x - self.lo[i] as f64) / self.cell[i] as f64).floor();
            (c.max(0.0) as u32).min(self.dims[i] - 1)
        };
        let margin = |i: usize| self.cell[i] as f64 * 1e-3;
        let l = [0, 1, 2].map(|i| cell_of(b.lo[i] - margin(i), i));
        let h = [0, 1, 2].map(|i| cell_of(b.hi[i] + margin(i), i));
        (cell_pack(l[0], l[1], l[2]), cell_pack(h[0], h[1], h[2]))
    }

    /// The counting pass: every primitive's cell range into `ranges`, and
    /// the references they make, exact in 64 bits. Stops early with `None`
    /// once the count passes `cap` (then `ranges` is incomplete). Each
    /// stretch of `PROGRESS_EVERY` primitives is counted in parallel
    /// (rayon), and reported once done, so progress only grows.
    fn count(
        &self,
        bounds: &[Bounds],
        cap: u64,
        ranges: &mut Vec<(u32, u32)>,
        progress: Progress,
    ) -> Option<u64> {
        ranges.clear();
        ranges.resize(bounds.len(), (0, 0));
        let n = bounds.len() as u64;
        let mut refs = 0u64;
        for (k, (bc, rc)) in bounds
            .chunks(PROGRESS_EVERY)
            .zip(ranges.chunks_mut(PROGRESS_EVERY))
            .enumerate()
        {
            progress(Stage::Count, (k * PROGRESS_EVERY) as u64, n);
            let made = bc
                .par_chunks(PARALLEL_CHUNK)
                .zip(rc.par_chunks_mut(PARALLEL_CHUNK))
                .map(|(b, r)| {
                    let mut made = 0u64;
                    for (b, r) in b.iter().zip(r) {
                        *r = self.range(b);
                        made = made.saturating_add(refs_of(*r));
                    }
                    made
                })
                .reduce(|| 0, u64::saturating_add);
            refs = refs.saturating_add(made);
            if refs > cap {
                return None;
            }
        }
        progress(Stage::Count, n, n);
        Some(refs)
    }
}

/// References a primitive with packed cell range `r` makes.
#[inline]
fn refs_of(r: (u32, u32)) -> u64 {
    let l = cell_unpack(r.0);
    let h = cell_unpack(r.1);
    (0..3).map(|i| (h[i] - l[i] + 1) as u64).product()
}

/// Files every primitive (by its bounds) into every cell they overlap.
///
/// `dims`: `--grid`, which is built as asked or refused; `None`: the
/// heuristic (module docs). `max_refs(cells)`: the most references a grid
/// of that many cells may hold within the memory budget. Refused (with
/// the smallest grid tried and its exact count) when even that does not
/// fit.
pub fn build(
    bounds: &[Bounds],
    dims: Option<[u32; 3]>,
    max_refs: &dyn Fn(u64) -> u64,
    progress: Progress,
) -> Result<Grid, Refusal> {
    if bounds.is_empty() {
        return Ok(Grid {
            dims: [1, 1, 1],
            cell_start: vec![0, 0],
            ..Grid::default()
        });
    }
    let all = bounds.iter().fold(Bounds::EMPTY, |a, b| a.union(b));
    let (lo, hi) = grid_box(&all);
    let n = bounds.len() as u64;
    let cap = |d: [u32; 3]| max_refs(cells_of(d)).min(MAX_REFS);
    let mut ranges = Vec::with_capacity(bounds.len());
    let layout = match dims {
        Some(d) => {
            let layout = Layout::new(lo, hi, d.map(|x| x.clamp(1, GRID_MAX_DIM)));
            let refs = layout
                .count(bounds, u64::MAX, &mut ranges, progress)
                .unwrap_or(u64::MAX);
            if refs > cap(layout.dims) {
                return Err(Refusal {
                    dims: layout.dims,
                    cells: cells_of(layout.dims),
                    refs,
                });
            }
            layout
        }
        None => {
            let target = resolution(&all, bounds.len());
            let fit = [0, 1, 2].map(|i| target[i].min(f32_cap(lo[i], hi[i])));
            choose(bounds, lo, hi, fit, n, &cap, &mut ranges, progress)?
        }
    };
    Ok(file(bounds, layout, ranges, progress))
}

/// The heuristic's descent from `dims` (module docs); leaves the chosen
/// grid's ranges in `ranges`.
#[allow(clippy::too_many_arguments)]
fn choose(
    bounds: &[Bounds],
    lo: [f32; 3],
    hi: [f32; 3],
    mut dims: [u32; 3],
    n: u64,
    cap: &dyn Fn([u32; 3]) -> u64,
    ranges: &mut Vec<(u32, u32)>,
    progress: Progress,
) -> Result<Layout, Refusal> {
    let redundant = n.saturating_mul(REDUNDANT_REFS_PER_PRIM);
    let mut other = Vec::new();
    // The count of `dims` when the previous step already made it.
    let mut known: Option<u64> = None;
    loop {
        let layout = Layout::new(lo, hi, dims);
        let refs = match known.take() {
            Some(r) => Some(r),
            None => layout.count(bounds, cap(dims), ranges, progress),
        };
        let last = dims == [1, 1, 1];
        match refs {
            None if last => {
                let refs = layout
                    .count(bounds, u64::MAX, ranges, progress)
                    .unwrap_or(u64::MAX);
                return Err(Refusal {
                    dims,
                    cells: 1,
                    refs,
                });
            }
            None => dims = coarser(dims),
            Some(r) if r == n.saturating_mul(cells_of(dims)) && !last => {
                // Every primitive is in every cell: the grid separates
                // nothing, and one cell does the same with N references.
                dims = [1, 1, 1];
            }
            Some(r) if r <= redundant || last => return Ok(layout),
            Some(r) => {
                // Does refining from the coarser grid shorten the lists
                // per cell enough? Count the coarser one until its count
                // shows it does (then keep `dims`).
                let c = coarser(dims);
                let cl = Layout::new(lo, hi, c);
                let enough = r as f64 * cells_of(c) as f64 / (REFINE_GAIN * cells_of(dims) as f64);
                let stop = if enough >= u64::MAX as f64 {
                    u64::MAX
                } else {
                    enough as u64
                };
                match cl.count(bounds, stop, &mut other, progress) {
                    None => return Ok(layout),
                    Some(r2) => {
                        std::mem::swap(ranges, &mut other);
                        known = Some(r2);
                        dims = c;
                    }
                }
            }
        }
    }
}

/// The filing pass: the counting sort into `cell_start`/`refs` (at most
/// `MAX_REFS`, so the 32-bit counts cannot wrap), then the empty-space
/// distances.
///
/// In parallel by slabs of cells along z, one per thread (rayon): a
/// slab's cells are a contiguous run of `cell_start`, and so of `refs`,
/// so each thread counts and files the parts of every primitive's range
/// that lie in its slab, into its own slices, in primitive order: the
/// lists are those of a serial filing, bit for bit, whatever the threads.
/// Every slab reads every range (a z test for most): two reads of 8
/// bytes per primitive and thread against the filing's writes.
fn file(bounds: &[Bounds], l: Layout, ranges: Vec<(u32, u32)>, progress: Progress) -> Grid {
    let dims = l.dims;
    let ncells = cells_of(dims) as usize;
    // Progress runs over both loops: 0..n counting, n..2n filing.
    let n = bounds.len() as u64;
    let plane = dims[0] as usize * dims[1] as usize;
    let nz = dims[2] as usize;
    let slabs = rayon::current_num_threads().clamp(1, nz);
    // Slab s holds the cells of z in z0[s]..z0[s + 1].
    let z0: Vec<usize> = (0..=slabs).map(|s| s * nz / slabs).collect();
    let cell_sizes: Vec<usize> = z0.windows(2).map(|w| (w[1] - w[0]) * plane).collect();
    // The part of range `r` in slab `s`, as (first z, last z), if any.
    let in_slab = |r: &(u32, u32), s: usize| -> Option<(u32, u32)> {
        let a = cell_unpack(r.0)[2].max(z0[s] as u32);
        let b = cell_unpack(r.1)[2].min(z0[s + 1] as u32 - 1);
        (a <= b).then_some((a, b))
    };
    // Calls `f` with each cell of range `r` whose z is in za..=zb (within
    // slab `s`), as an index from the slab's first cell, and with the
    // reference's test-once bits there (`Walk::bits`: on each axis a, bit
    // 2a when the range goes on below the cell, bit 2a + 1 above it).
    let for_cells =
        |r: &(u32, u32), s: usize, (za, zb): (u32, u32), f: &mut dyn FnMut(usize, u8)| {
            let l = cell_unpack(r.0);
            let h = cell_unpack(r.1);
            let base = z0[s] * plane;
            let on = |c: u32, a: usize| ((c > l[a]) as u8 | ((c < h[a]) as u8) << 1) << (2 * a);
            for z in za..=zb {
                let bz = on(z, 2);
                for y in l[1]..=h[1] {
                    let byz = bz | on(y, 1);
                    let row =
                        (y as usize + dims[1] as usize * z as usize) * dims[0] as usize - base;
                    for x in l[0]..=h[0] {
                        f(row + x as usize, byz | on(x, 0));
                    }
                }
            }
        };
    // The offsets, then the distances four to a word: allocated once.
    let mut counts = Vec::with_capacity(ncells + 1 + ncells.div_ceil(4));
    counts.resize(ncells + 1, 0u32);
    for (k, chunk) in ranges.chunks(PROGRESS_EVERY).enumerate() {
        progress(Stage::File, (k * PROGRESS_EVERY) as u64, 2 * n);
        split_sizes(&mut counts[1..], &cell_sizes)
            .into_par_iter()
            .enumerate()
            .for_each(|(s, mine)| {
                for r in chunk {
                    if let Some(zs) = in_slab(r, s) {
                        for_cells(r, s, zs, &mut |c, _| mine[c] += 1);
                    }
                }
            });
    }
    for i in 0..ncells {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut refs = vec![0u32; counts[ncells] as usize];
    let mut bits = vec![0u8; refs.len()];
    let ref_sizes: Vec<usize> = z0
        .windows(2)
        .map(|w| (counts[w[1] * plane] - counts[w[0] * plane]) as usize)
        .collect();
    for (k, chunk) in ranges.chunks(PROGRESS_EVERY).enumerate() {
        progress(Stage::File, n + (k * PROGRESS_EVERY) as u64, 2 * n);
        let first = (k * PROGRESS_EVERY) as u32;
        split_sizes(&mut fill[..ncells], &cell_sizes)
            .into_par_iter()
            .zip(split_sizes(&mut refs, &ref_sizes))
            .zip(split_sizes(&mut bits, &ref_sizes))
            .enumerate()
            .for_each(|(s, ((next, mine), my_bits))| {
                // `fill` holds offsets into the whole of `refs`.
                let base = counts[z0[s] * plane];
                for (j, r) in chunk.iter().enumerate() {
                    if let Some(zs) = in_slab(r, s) {
                        let p = first + j as u32;
                        for_cells(r, s, zs, &mut |c, b| {
                            let k = (next[c] - base) as usize;
                            mine[k] = p;
                            my_bits[k] = b;
                            next[c] += 1;
                        });
                    }
                }
            });
    }
    progress(Stage::File, 2 * n, 2 * n);
    drop(fill);
    let mut skip = skip_distances(&counts, dims);
    if !jumps_pay(&skip) {
        for s in &mut skip {
            *s = (*s).min(1);
        }
    }
    let mut cell_start = counts;
    cell_start.extend(skip.chunks(4).map(|c| {
        c.iter()
            .enumerate()
            .fold(0u32, |w, (i, &b)| w | (b as u32) << (8 * i))
    }));
    Grid {
        lo: l.lo,
        hi: l.hi,
        dims,
        cell: l.cell,
        ranges,
        cell_start,
        refs,
        bits,
    }
}

/// The CPU grid walk's own arrays (`trace::grid::grid_traverse`; not
/// uploaded: the shader reads its primitives' words through texel
/// fetches). With them the walk reads a primitive's 64-byte record only
/// to test a primitive that is not a sphere, or to take a hit: per
/// reference whether it was tested in the previous cell (written as the
/// grid files it), per sphere its test's inputs; `Packed::walk`
/// holds them for the plain grid (not the hybrid, whose references also
/// name nested trees), empty otherwise.
#[derive(Clone, Debug, Default)]
pub struct Walk {
    /// Per reference (parallel to `refs`), the test-once rule
    /// (`trace::grid::seen_before`) for each way the walk can have come
    /// into the cell: bit 2a is set when the primitive's cell range holds
    /// the cell below on axis a (a walk that stepped up along a tested it
    /// there), bit 2a + 1 when it holds the cell above.
    pub bits: Pages<u8>,
    /// Per grid primitive (the first `globals.counts.x`): a sphere's centre
    /// and r² (its record's first word, all its test reads), otherwise
    /// (0, 0, 0, −1); empty when none is a sphere.
    pub spheres: Pages<[f32; 4]>,
}

/// Bytes `Walk` keeps per reference and per grid primitive (the memory
/// budget counts them: `budget::Need`).
pub const WALK_REF_BYTES: u64 = 1;
pub const WALK_PRIM_BYTES: u64 = 16;

/// `Walk::spheres` for the grid's primitives `prims`: empty when none is
/// a sphere (the walk then reads every record to test it).
pub fn sphere_records(prims: &[Prim]) -> Vec<[f32; 4]> {
    if !prims.iter().any(|p| p.kind() == KIND_SPHERE) {
        return Vec::new();
    }
    prims
        .par_iter()
        .with_min_len(PARALLEL_CHUNK)
        .map(|p| {
            if p.kind() == KIND_SPHERE {
                p.a
            } else {
                [0.0, 0.0, 0.0, -1.0]
            }
        })
        .collect()
}

/// `v` cut into consecutive slices of the given lengths (which sum to at
/// most its length).
fn split_sizes<'a, T>(mut v: &'a mut [T], sizes: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(sizes.len());
    for &k in sizes {
        let (a, b) = std::mem::take(&mut v).split_at_mut(k);
        out.push(a);
        v = b;
    }
    out
}

/// A grid keeps its empty-space jumps only where at least this share of
/// its cells can start one (skip distance 2 or more); in a denser grid
/// every empty cell's distance is capped at 1, so the walks step through
/// it (`build`; docs/method.md, "Empty space"). A field of random
/// spheres has a few such cells in ten thousand, which its rays almost
/// never meet, while a SIMD device that runs both sides of every branch
/// (llvmpipe) paid the jump's code at every cell visit.
pub const JUMP_CELLS_MIN_SHARE: f64 = 0.01;

/// Whether a grid with these skip distances keeps its empty-space jumps:
/// at least `JUMP_CELLS_MIN_SHARE` of its cells can start one (distance 2
/// or more). Otherwise `build` caps every distance at 1 and no walk
/// jumps: the same hits, a few more cell steps in the rare empty cubes,
/// and the shader's jump compiles out (`gpu::layout_key`, bit 29).
pub fn jumps_pay(skip: &[u8]) -> bool {
    let starts = skip.iter().filter(|&&s| s >= 2).count();
    starts as f64 >= JUMP_CELLS_MIN_SHARE * skip.len() as f64
}

/// Empty-space distances ("proximity clouds", Cohen & Sheffer 1994): for
/// each cell, the chessboard distance in cells to the nearest cell that
/// lists a primitive, capped at `SKIP_MAX` (0 for a listed cell). Every
/// cell within distance k − 1 of a cell at distance k is empty, so a ray
/// may jump to where it leaves that cube of cells. Separable: a 1D pass
/// along each axis of d(x) = min over x' of max(|x − x'|, d_prev(x')).
pub fn skip_distances(cell_start: &[u32], dims: [u32; 3]) -> Vec<u8> {
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let cap = SKIP_MAX as usize;
    let mut d: Vec<u8> = (0..nx * ny * nz)
        .map(|c| {
            if cell_start[c] == cell_start[c + 1] {
                cap as u8
            } else {
                0
            }
        })
        .collect();
    let strides = [1, nx, nx * ny];
    for axis in 0..3 {
        let n = dims[axis] as usize;
        let stride = strides[axis];
        let mut line = vec![0u8; n];
        for base in 0..nx * ny * nz {
            // visit each line once, from its first cell
            if (base / stride) % n != 0 {
                continue;
            }
            for (i, v) in line.iter_mut().enumerate() {
                *v = d[base + i * stride];
            }
            for i in 0..n {
                // Outward from i: a cell r away gives at least r, so the
                // search stops once r reaches the best found (at once in a
                // listed cell, which most cells of a dense scene are).
                let mut best = line[i] as usize;
                let mut r = 1;
                while r < best {
                    if i >= r {
                        best = best.min((line[i - r] as usize).max(r));
                    }
                    if i + r < n {
                        best = best.min((line[i + r] as usize).max(r));
                    }
                    r += 1;
                }
                d[base + i * stride] = best as u8;
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jumps_pay_from_one_cell_in_a_hundred() {
        // 1 000 cells: 9 that can start a jump is under 1 %, 10 is not.
        let mut skip = vec![0u8; 1000];
        skip[..50].fill(1);
        skip[50..59].fill(2);
        assert!(!jumps_pay(&skip));
        skip[59] = 7;
        assert!(jumps_pay(&skip));
        assert!(jumps_pay(&[15; 8]), "an empty grid");
    }

    #[test]
    fn skip_distances_are_chessboard_distances_to_listed_cells() {
        let dims = [7u32, 5, 4];
        let n = 7 * 5 * 4;
        let listed = [(1usize, 1usize, 1usize), (6, 4, 3)];
        let idx = |x: usize, y: usize, z: usize| x + 7 * (y + 5 * z);
        let mut counts = vec![0u32; n + 1];
        for c in 0..n {
            let add = listed.iter().any(|&(x, y, z)| idx(x, y, z) == c) as u32;
            counts[c + 1] = counts[c] + add;
        }
        let d = skip_distances(&counts, dims);
        for z in 0..4usize {
            for y in 0..5usize {
                for x in 0..7usize {
                    let want = listed
                        .iter()
                        .map(|&(a, b, c)| x.abs_diff(a).max(y.abs_diff(b)).max(z.abs_diff(c)))
                        .min()
                        .unwrap();
                    assert_eq!(
                        d[idx(x, y, z)] as usize,
                        want.min(SKIP_MAX as usize),
                        "({x},{y},{z})"
                    );
                }
            }
        }
        // nothing listed at all: every cell at the cap
        let empty = vec![0u32; n + 1];
        assert!(skip_distances(&empty, dims)
            .iter()
            .all(|&v| v as u32 == SKIP_MAX));
    }

    /// Against brute force on larger grids, with distances past the cap.
    #[test]
    fn skip_distances_match_brute_force_past_the_cap() {
        let mut seed = 12345u32;
        for (dims, density) in [
            ([41u32, 3, 2], 0.02),
            ([23, 19, 11], 0.004),
            ([9, 40, 7], 0.01),
        ] {
            let [nx, ny, nz] = dims.map(|d| d as usize);
            let mut listed = Vec::new();
            let mut counts = vec![0u32; nx * ny * nz + 1];
            for c in 0..nx * ny * nz {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let add = ((seed >> 8) as f64 / (1u32 << 24) as f64) < density;
                if add {
                    listed.push((c % nx, (c / nx) % ny, c / (nx * ny)));
                }
                counts[c + 1] = counts[c] + add as u32;
            }
            let d = skip_distances(&counts, dims);
            for (c, &got) in d.iter().enumerate() {
                let (x, y, z) = (c % nx, (c / nx) % ny, c / (nx * ny));
                let want = listed
                    .iter()
                    .map(|&(a, b, e)| x.abs_diff(a).max(y.abs_diff(b)).max(z.abs_diff(e)))
                    .min()
                    .unwrap_or(usize::MAX)
                    .min(SKIP_MAX as usize);
                assert_eq!(got as usize, want, "{dims:?} ({x},{y},{z})");
            }
        }
    }

    #[test]
    fn resolution_follows_extent_and_count() {
        let b = Bounds {
            lo: [0.0; 3],
            hi: [4.0, 2.0, 1.0],
        };
        let d = resolution(&b, 1000);
        // 3000 cells over 8 units³: k = cbrt(375) ≈ 7.2 cells per unit.
        assert_eq!(d, [29, 14, 7]);
        let flat = Bounds {
            lo: [0.0; 3],
            hi: [10.0, 10.0, 0.0],
        };
        assert_eq!(resolution(&flat, 1_000_000)[2], 1);
    }

    #[test]
    fn large_grids_aim_at_fewer_cells_per_primitive() {
        // GRID_DENSITY a primitive up to a million cells, then a million,
        // then one a primitive; never fewer cells for more primitives.
        assert_eq!(target_cells(0), 3.0);
        assert_eq!(target_cells(20_000), 60_000.0);
        assert_eq!(target_cells(333_333), 999_999.0);
        assert_eq!(target_cells(500_000), 1e6);
        assert_eq!(target_cells(1_000_000), 1e6);
        assert_eq!(target_cells(4_000_000), 4e6);
        let mut last = 0.0;
        for n in (0..3_000_000).step_by(9_973) {
            assert!(target_cells(n) >= last, "{n}");
            last = target_cells(n);
        }
        let cube = Bounds {
            lo: [0.0; 3],
            hi: [1.0; 3],
        };
        assert_eq!(resolution(&cube, 100_000), [67, 67, 67]);
        assert_eq!(resolution(&cube, 500_000), [100, 100, 100]);
        assert_eq!(resolution(&cube, 1_000_000), [100, 100, 100]);
        assert_eq!(resolution(&cube, 8_000_000), [200, 200, 200]);
    }

    /// No budget, no progress.
    fn build_free(bounds: &[Bounds], dims: Option<[u32; 3]>) -> Result<Grid, Refusal> {
        build(bounds, dims, &|_| u64::MAX, &|_, _, _| {})
    }

    /// Every cell a primitive's range covers lists it, once; no other does.
    fn assert_filed(g: &Grid, n: usize) {
        let [nx, ny, nz] = g.dims.map(|d| d as usize);
        let mut listed = vec![0usize; n];
        for c in 0..nx * ny * nz {
            let (x, y, z) = (
                (c % nx) as u32,
                ((c / nx) % ny) as u32,
                (c / (nx * ny)) as u32,
            );
            let list = &g.refs[g.cell_start[c] as usize..g.cell_start[c + 1] as usize];
            assert!(
                list.windows(2).all(|w| w[0] < w[1]),
                "cell {c}: a list in primitive order"
            );
            for &p in list {
                let (l, h) = (
                    cell_unpack(g.ranges[p as usize].0),
                    cell_unpack(g.ranges[p as usize].1),
                );
                assert!(
                    (l[0]..=h[0]).contains(&x)
                        && (l[1]..=h[1]).contains(&y)
                        && (l[2]..=h[2]).contains(&z)
                );
                listed[p as usize] += 1;
            }
        }
        for (p, &k) in listed.iter().enumerate() {
            assert_eq!(k as u64, refs_of(g.ranges[p]), "primitive {p}");
        }
        assert_eq!(g.refs.len(), listed.iter().sum::<usize>());
    }

    fn cube(c: [f64; 3], r: f64) -> Bounds {
        Bounds {
            lo: c.map(|x| x - r),
            hi: c.map(|x| x + r),
        }
    }

    /// n small boxes scattered in [-1, 1]³ (like `gen::random_spheres`).
    fn scattered(n: usize) -> Vec<Bounds> {
        let mut rng = crate::gen::Rng::new(7);
        let r = 0.45 * 2.0 / (n as f64).cbrt();
        (0..n)
            .map(|_| cube([0, 1, 2].map(|_| rng.next_f64() * 2.0 - 1.0), r))
            .collect()
    }

    #[test]
    fn every_cell_a_primitive_overlaps_lists_it() {
        let bounds = vec![
            Bounds {
                lo: [0.0, 0.0, 0.0],
                hi: [1.0, 1.0, 1.0],
            },
            Bounds {
                lo: [0.5, 0.5, 0.5],
                hi: [3.0, 1.0, 2.0],
            },
        ];
        let g = build_free(&bounds, Some([3, 3, 3])).unwrap();
        assert_eq!(g.cell_start.len(), 28 + 7);
        let listed = |p: u32| {
            (0..27)
                .filter(|&c| {
                    g.refs[g.cell_start[c] as usize..g.cell_start[c + 1] as usize].contains(&p)
                })
                .count()
        };
        assert_eq!(listed(0), 2 * 3 * 2);
        assert_eq!(listed(1), 3 * 2 * 3);
        assert_filed(&g, 2);
    }

    /// Scattered primitives keep the density heuristic's grid: the
    /// counting pass finds them well under the redundancy threshold.
    #[test]
    fn scattered_primitives_keep_the_density_grid() {
        let b = scattered(20_000);
        let all = b.iter().fold(Bounds::EMPTY, |a, x| a.union(x));
        let g = build_free(&b, None).unwrap();
        assert_eq!(g.dims, resolution(&all, b.len()));
        let per = g.refs.len() as f64 / b.len() as f64;
        assert!(per > 4.0 && per < REDUNDANT_REFS_PER_PRIM as f64, "{per}");
        assert_filed(&g, b.len());
    }

    /// The pile of identical spheres: every primitive overlaps
    /// every cell of any grid, so the heuristic ends at one cell (one
    /// reference each) instead of N × 3N references.
    #[test]
    fn identical_primitives_get_one_cell() {
        let b = vec![cube([0.3, -2.0, 5.0], 0.5); 100_000];
        let all = b.iter().fold(Bounds::EMPTY, |a, x| a.union(x));
        assert!(
            cells_of(resolution(&all, b.len())) > 100_000,
            "the density target is fine"
        );
        let g = build_free(&b, None).unwrap();
        assert_eq!(g.dims, [1, 1, 1]);
        assert_eq!(g.refs.len(), b.len());
        assert_filed(&g, b.len());
    }

    /// A pile of identical primitives inside a scattered field: the pile
    /// sits in a few cells and the field keeps its grid.
    #[test]
    fn a_pile_inside_a_field_keeps_the_field_grid() {
        let mut b = scattered(20_000);
        b.extend(vec![cube([0.1, 0.2, 0.3], 0.01); 20_000]);
        let all = b.iter().fold(Bounds::EMPTY, |a, x| a.union(x));
        let g = build_free(&b, None).unwrap();
        assert_eq!(g.dims, resolution(&all, b.len()));
        assert_filed(&g, b.len());
    }

    /// Heavy but not total overlap (each box a tenth of the scene): the
    /// grid coarsens until refining would shorten the lists, and every
    /// primitive is still filed everywhere it reaches.
    #[test]
    fn overlapping_primitives_get_a_coarser_grid() {
        let mut rng = crate::gen::Rng::new(3);
        let b: Vec<Bounds> = (0..5000)
            .map(|_| cube([0, 1, 2].map(|_| rng.next_f64()), 0.1))
            .collect();
        let all = b.iter().fold(Bounds::EMPTY, |a, x| a.union(x));
        let target = resolution(&all, b.len());
        let g = build_free(&b, None).unwrap();
        assert!(cells_of(g.dims) < cells_of(target), "{:?}", g.dims);
        assert!(
            g.refs.len() as u64 <= REDUNDANT_REFS_PER_PRIM * b.len() as u64 || {
                // or refining from the next coarser grid paid
                let c = coarser(g.dims);
                let (lo, hi) = grid_box(&all);
                let r2 = Layout::new(lo, hi, c)
                    .count(&b, u64::MAX, &mut Vec::new(), &|_, _, _| {})
                    .unwrap();
                g.refs.len() as f64 / cells_of(g.dims) as f64
                    <= REFINE_GAIN * r2 as f64 / cells_of(c) as f64
            }
        );
        assert_filed(&g, b.len());
    }

    /// Radii of 1e-120 and 5e-324 (the smallest f64) far from the camera:
    /// no volume underflows to a 1023³ grid, and the f32 box keeps a
    /// width.
    #[test]
    fn tiny_extents_get_a_small_grid_with_a_width() {
        for r in [1e-120, 5e-324, 0.0] {
            for n in [1usize, 1000] {
                let b: Vec<Bounds> = (0..n)
                    .map(|i| cube([0.0, 10.0 + i as f64 * r, 0.0], r))
                    .collect();
                let g = build_free(&b, None).unwrap();
                // at most the flat-scene density (3 cells per primitive
                // over a 1/1000 thickness), nowhere near 1023³
                assert!(
                    cells_of(g.dims) <= 3000 * n as u64,
                    "r {r} n {n}: {:?}",
                    g.dims
                );
                assert!(g.refs.len() <= 8 * n, "r {r} n {n}: {}", g.refs.len());
                for i in 0..3 {
                    assert!(g.hi[i] > g.lo[i] && g.cell[i] > 0.0, "r {r}: {g:?}");
                }
                assert_filed(&g, n);
            }
        }
        let point = Bounds {
            lo: [1.0; 3],
            hi: [1.0; 3],
        };
        assert_eq!(resolution(&point, 1_000_000), [1, 1, 1]);
        let tiny = cube([0.0; 3], 1e-120);
        assert_eq!(resolution(&tiny, 1), [1, 1, 1]);
        assert_eq!(resolution(&tiny, 1000), [14, 14, 14]);
        let huge = cube([0.0; 3], 1e300);
        assert_eq!(resolution(&huge, 1000), [14, 14, 14]);
        let beyond = cube([0.0; 3], f64::MAX);
        assert_eq!(resolution(&beyond, 1000), [1, 1, 1]);
    }

    /// `--grid 1023x1023x1023` over five primitives that fill it: 5.35 G
    /// references, counted exactly (past u32) and refused, in O(N).
    #[test]
    fn an_explicit_grid_over_the_offsets_is_refused_with_its_count() {
        let b = vec![cube([0.0; 3], 1.0); 5];
        let r = build_free(&b, Some([1023; 3])).unwrap_err();
        let cells = 1023u64 * 1023 * 1023;
        assert_eq!(r.dims, [1023; 3]);
        assert_eq!(r.cells, cells);
        assert_eq!(r.refs, 5 * cells);
        // within the offsets but over a budget of 100 M references
        let r = build(&b[..2], Some([1023; 3]), &|_| 100_000_000, &|_, _, _| {}).unwrap_err();
        assert_eq!(r.refs, 2 * cells);
        // the same primitives under the heuristic: one cell
        assert_eq!(build_free(&b, None).unwrap().dims, [1, 1, 1]);
    }

    /// The budget lowers the heuristic's resolution until the references
    /// fit, and refuses only when one cell's (N) do not.
    #[test]
    fn the_budget_lowers_the_resolution() {
        let b = scattered(5000);
        let free = build_free(&b, None).unwrap();
        let limit = free.refs.len() as u64 / 2;
        let g = build(&b, None, &|_| limit, &|_, _, _| {}).unwrap();
        assert!(g.refs.len() as u64 <= limit);
        assert!(cells_of(g.dims) < cells_of(free.dims));
        assert_filed(&g, b.len());
        let r = build(&b, None, &|_| 4999, &|_, _, _| {}).unwrap_err();
        assert_eq!((r.dims, r.refs), ([1, 1, 1], 5000));
        assert!(build(&b, None, &|_| 5000, &|_, _, _| {}).is_ok());
    }

    /// The parallel passes give the serial grid: the same lists in the
    /// same order whatever the threads (slabs of 1, 3 and 7 along z,
    /// several progress stretches), each list in primitive order.
    #[test]
    fn the_grid_is_the_same_on_any_number_of_threads() {
        let b = scattered(150_000);
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| build(&b, None, &|_| u64::MAX, &|_, _, _| {}).unwrap())
        };
        let one = on(1);
        assert!(one.dims[2] >= 7);
        assert_filed(&one, b.len());
        for t in [3, 7] {
            let g = on(t);
            assert_eq!(g.dims, one.dims);
            assert_eq!(g.ranges, one.ranges, "{t} threads");
            assert_eq!(g.cell_start, one.cell_start, "{t} threads");
            assert_eq!(g.refs, one.refs, "{t} threads");
        }
    }

    #[test]
    fn progress_reaches_the_end_of_each_pass() {
        let b = scattered(200_000);
        let log = std::sync::Mutex::new(Vec::new());
        build(&b, None, &|_| u64::MAX, &|s, d, t| {
            log.lock().unwrap().push((s, d, t))
        })
        .unwrap();
        let log = log.into_inner().unwrap();
        for stage in [Stage::Count, Stage::File] {
            let mine: Vec<_> = log.iter().filter(|e| e.0 == stage).collect();
            assert!(mine.len() > 2, "{stage:?}");
            assert!(mine.iter().all(|e| e.1 <= e.2));
            assert!(mine.windows(2).all(|w| w[0].1 <= w[1].1));
            let last = mine.last().unwrap();
            assert_eq!(last.1, last.2);
        }
    }

    #[test]
    fn coarser_halves_the_cells_down_to_one() {
        let mut d = [1023u32, 1023, 1023];
        let mut steps = 0;
        while d != [1, 1, 1] {
            let c = coarser(d);
            assert!(cells_of(c) < cells_of(d));
            assert!(cells_of(c) * 4 >= cells_of(d), "{d:?} → {c:?}");
            d = c;
            steps += 1;
        }
        assert!(steps <= 40);
    }
}
