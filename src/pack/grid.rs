//! Building the uniform voxel grid over the finite primitives.
//!
//! Resolution heuristic (documented in docs/method.md): aim for
//! `GRID_DENSITY` cells per primitive, cells as close to cubes as the
//! scene's extent allows: k = cbrt(GRID_DENSITY · N / V), n_i = round(e_i · k)
//! clamped to [1, GRID_MAX_DIM], where e_i are the extents of the bounds of
//! all finite primitives (each at least 1/1000 of the largest, so flat
//! scenes get a flat grid rather than a degenerate one) and V their product.

use super::layout::cell_pack;
use crate::constants::{GRID_DENSITY, GRID_MAX_DIM, SKIP_MAX};

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
}

/// Cells per axis for `n` primitives inside `b`.
pub fn resolution(b: &Bounds, n: usize) -> [u32; 3] {
    let e = b.extent();
    let emax = e[0].max(e[1]).max(e[2]).max(f64::MIN_POSITIVE);
    let e = e.map(|x| x.max(emax * 1e-3));
    let volume = e[0] * e[1] * e[2];
    let k = (GRID_DENSITY as f64 * n.max(1) as f64 / volume).cbrt();
    e.map(|x| ((x * k).round() as u32).clamp(1, GRID_MAX_DIM))
}

/// Files every primitive (by its bounds) into every cell they overlap.
/// `dims` overrides the heuristic.
pub fn build(bounds: &[Bounds], dims: Option<[u32; 3]>) -> Grid {
    if bounds.is_empty() {
        return Grid {
            dims: [1, 1, 1],
            cell_start: vec![0, 0],
            ..Grid::default()
        };
    }
    let all = bounds.iter().fold(Bounds::EMPTY, |a, b| a.union(b));
    // Pad so that primitives touching the boundary are strictly inside.
    let pad = all.diagonal().max(1e-30) * 1e-5;
    let lo64 = all.lo.map(|x| x - pad);
    let hi64 = all.hi.map(|x| x + pad);
    let dims = dims
        .unwrap_or_else(|| resolution(&all, bounds.len()))
        .map(|d| d.clamp(1, GRID_MAX_DIM));
    let lo = lo64.map(|x| x as f32);
    let hi = hi64.map(|x| x as f32);
    let cell = [0, 1, 2].map(|i| (hi[i] - lo[i]) / dims[i] as f32);
    // A primitive's bounds grow by a small margin so that a hit the DDA's
    // rounding puts one cell over is still in that cell's list.
    let margin = [0, 1, 2].map(|i| cell[i] as f64 * 1e-3);
    let cell_of = |x: f64, i: usize| -> u32 {
        let c = ((x - lo[i] as f64) / cell[i] as f64).floor();
        (c.max(0.0) as u32).min(dims[i] - 1)
    };
    let ranges: Vec<(u32, u32)> = bounds
        .iter()
        .map(|b| {
            let l = [0, 1, 2].map(|i| cell_of(b.lo[i] - margin[i], i));
            let h = [0, 1, 2].map(|i| cell_of(b.hi[i] + margin[i], i));
            (cell_pack(l[0], l[1], l[2]), cell_pack(h[0], h[1], h[2]))
        })
        .collect();
    let ncells = dims[0] as usize * dims[1] as usize * dims[2] as usize;
    let mut counts = vec![0u32; ncells + 1];
    let for_cells = |r: &(u32, u32), f: &mut dyn FnMut(usize)| {
        let l = super::layout::cell_unpack(r.0);
        let h = super::layout::cell_unpack(r.1);
        for z in l[2]..=h[2] {
            for y in l[1]..=h[1] {
                let row = (y as usize + dims[1] as usize * z as usize) * dims[0] as usize;
                for x in l[0]..=h[0] {
                    f(row + x as usize);
                }
            }
        }
    };
    for r in &ranges {
        for_cells(r, &mut |c| counts[c + 1] += 1);
    }
    for i in 0..ncells {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut refs = vec![0u32; counts[ncells] as usize];
    for (p, r) in ranges.iter().enumerate() {
        for_cells(r, &mut |c| {
            refs[fill[c] as usize] = p as u32;
            fill[c] += 1;
        });
    }
    let skip = skip_distances(&counts, dims);
    let mut cell_start = counts;
    cell_start.extend(skip.chunks(4).map(|c| {
        c.iter()
            .enumerate()
            .fold(0u32, |w, (i, &b)| w | (b as u32) << (8 * i))
    }));
    Grid {
        lo,
        hi,
        dims,
        cell,
        ranges,
        cell_start,
        refs,
    }
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
        let g = build(&bounds, Some([3, 3, 3]));
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
    }
}
