//! Building the uniform voxel grid over the finite primitives.
//!
//! Resolution heuristic (documented in docs/method.md): aim for
//! `GRID_DENSITY` cells per primitive, cells as close to cubes as the
//! scene's extent allows: k = cbrt(GRID_DENSITY · N / V), n_i = round(e_i · k)
//! clamped to [1, GRID_MAX_DIM], where e_i are the extents of the bounds of
//! all finite primitives (each at least 1/1000 of the largest, so flat
//! scenes get a flat grid rather than a degenerate one) and V their product.

use super::layout::cell_pack;
use crate::constants::{GRID_DENSITY, GRID_MAX_DIM};

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
    Grid {
        lo,
        hi,
        dims,
        cell,
        ranges,
        cell_start: counts,
        refs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(g.cell_start.len(), 28);
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
