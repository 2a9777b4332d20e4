//! 3D-DDA (Amanatides & Woo) through the uniform voxel grid: twin of
//! `shaders/grid.glsl`.
//!
//! One traversal serves both queries (`query.rs`). The closest hit keeps
//! the best hit found so far across cells (a primitive's hit may lie
//! beyond the cell that referenced it) and stops once that hit lies
//! inside the current cell; a shadow feeler's length plays the part of
//! that hit. Each primitive is tested once per ray: its
//! references along a ray form one run of consecutive cells (it is filed
//! in every cell its bounds overlap, and cell indices are monotone along a
//! ray), so a primitive whose cell range holds the previous cell was
//! already tested there and is skipped.

use super::bvh::bvh_walk;
use super::intersect::RayPre;
use super::math::{Ray, Real};
use super::query::{query_indexed, query_prim, Query, Work};
use super::SceneView;
use crate::constants::{ACCEL_HYBRID, HYBRID_NODE};
use crate::pack::layout::Prim;

/// Traversal state: the current cell and where the ray leaves it on each
/// axis. Per-axis values are arrays so the axis can be a runtime index.
#[derive(Clone, Copy, Debug)]
pub struct Dda<F> {
    pub cell: [i32; 3],
    pub step: [i32; 3],
    /// Distance along the ray to the current cell's far boundary plane on
    /// each axis (∞ for an axis the ray does not move along).
    pub next: [F; 3],
    /// Where the ray segment inside the grid ends.
    pub t_end: F,
    /// The axis of the last step (3: none yet) and the cell coordinate on
    /// that axis before it: the previous cell differs from the current one
    /// only there.
    pub prev_axis: usize,
    pub prev_coord: i32,
    /// The ray's origin, direction and 1/direction, per axis.
    pub o: [F; 3],
    pub d: [F; 3],
    pub inv: [F; 3],
}

/// The plane `edge` cells from the box's lower corner on `axis`: a cell
/// boundary of the grid, or a lattice plane of the octree (which shares
/// the box and the cell size's place in `Globals`).
#[inline(always)]
pub fn lattice_plane<F: Real>(s: &SceneView, axis: usize, edge: i32) -> F {
    let g = s.globals;
    F::of(g.grid_min[axis]) + F::of(edge as f32) * F::of(g.grid_cell[axis])
}

/// The cell holding coordinate `x` on `axis`, kept within `lo..=hi` (a
/// NaN gives `lo`; `lo` ≥ 0): floor, then the clamp, by truncation on the
/// positive values left (no libm call without SSE4.1).
#[inline(always)]
pub fn lattice_cell<F: Real>(s: &SceneView, x: F, axis: usize, lo: i32, hi: i32) -> i32 {
    let g = s.globals;
    let c = (x - F::of(g.grid_min[axis])) / F::of(g.grid_cell[axis]);
    if c.is_nan() || c <= F::of(lo as f32) {
        lo
    } else if c >= F::of(hi as f32) {
        hi
    } else {
        c.trunc_i32()
    }
}

/// Distance to the far boundary of cell `dda.cell` on `axis`, computed
/// afresh from the cell index (no error accumulates along the ray).
#[inline(always)]
pub fn dda_boundary<F: Real>(s: &SceneView, dda: &Dda<F>, axis: usize) -> F {
    let edge = dda.cell[axis] + if dda.step[axis] > 0 { 1 } else { 0 };
    (lattice_plane::<F>(s, axis, edge) - dda.o[axis]) * dda.inv[axis]
}

/// The stretch t0..t1 of the segment 0..`tmax` of the ray (origin `o`,
/// direction `d`, 1/d `inv`, per axis) inside the structure's box
/// (`Globals::grid_min..grid_max`, which the grid and the octree share);
/// `None` when it misses the box.
#[inline(always)]
pub fn clip_to_box<F: Real>(
    s: &SceneView,
    o: &[F; 3],
    d: &[F; 3],
    inv: &[F; 3],
    tmax: F,
) -> Option<(F, F)> {
    let g = s.globals;
    let mut t0 = F::zero();
    let mut t1 = tmax;
    for i in 0..3 {
        let (lo, hi) = (F::of(g.grid_min[i]), F::of(g.grid_max[i]));
        if d[i] == F::zero() {
            if o[i] < lo || o[i] > hi {
                return None;
            }
            continue;
        }
        let ta = (lo - o[i]) * inv[i];
        let tb = (hi - o[i]) * inv[i];
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    // Not `t0 <= t1`: a NaN goes on, as before this was shared (the walks
    // bound their steps).
    if t0 > t1 {
        None
    } else {
        Some((t0, t1))
    }
}

/// Clips the ray to the grid; `None` when it misses the grid or the grid is empty.
#[inline(always)]
pub fn dda_setup<F: Real>(s: &SceneView, ray: &Ray<F>, pre: &RayPre<F>, tmax: F) -> Option<Dda<F>> {
    let g = s.globals;
    if g.grid_min[3] == 0.0 {
        return None;
    }
    let o = [ray.o.x, ray.o.y, ray.o.z];
    let d = [ray.d.x, ray.d.y, ray.d.z];
    let inv = [pre.inv_d.x, pre.inv_d.y, pre.inv_d.z];
    let (t0, t1) = clip_to_box(s, &o, &d, &inv, tmax)?;
    let mut dda = Dda {
        cell: [0; 3],
        step: [0; 3],
        next: [F::infinity(); 3],
        t_end: t1,
        prev_axis: 3,
        prev_coord: -1,
        o,
        d,
        inv,
    };
    for i in 0..3 {
        let n = g.grid_dims[i] as i32;
        dda.cell[i] = lattice_cell(s, o[i] + d[i] * t0, i, 0, n - 1);
        dda.step[i] = if d[i] > F::zero() {
            1
        } else if d[i] < F::zero() {
            -1
        } else {
            0
        };
        if dda.step[i] != 0 {
            dda.next[i] = dda_boundary(s, &dda, i);
        }
    }
    Some(dda)
}

/// Where the ray leaves the current cell, and across which axis.
#[inline(always)]
pub fn dda_exit<F: Real>(dda: &Dda<F>) -> (F, usize) {
    let n = dda.next;
    if n[0] <= n[1] && n[0] <= n[2] {
        (n[0], 0)
    } else if n[1] <= n[2] {
        (n[1], 1)
    } else {
        (n[2], 2)
    }
}

/// Moves to the next cell along `axis`; false when the ray leaves the grid.
#[inline(always)]
pub fn dda_advance<F: Real>(s: &SceneView, dda: &mut Dda<F>, axis: usize) -> bool {
    dda.prev_axis = axis;
    dda.prev_coord = dda.cell[axis];
    dda.cell[axis] += dda.step[axis];
    dda.next[axis] = dda_boundary(s, dda, axis);
    dda.cell[axis] >= 0 && dda.cell[axis] < s.globals.grid_dims[axis] as i32
}

/// Empty-space distance of cell `ci` (0: the cell lists primitives): the
/// bytes after the `ncells + 1` offsets in `cell_start`.
#[inline(always)]
pub fn cell_skip(s: &SceneView, ci: usize) -> u32 {
    let word = s.cell_start[s.globals.grid_dims[3] as usize + 1 + ci / 4];
    (word >> (8 * (ci % 4) as u32)) & 255
}

/// Where the ray leaves the empty cube of half-width `r` cells around the
/// current cell, and across which axis.
#[inline(always)]
pub fn dda_jump_exit<F: Real>(s: &SceneView, dda: &Dda<F>, r: i32) -> (F, usize) {
    let mut best = F::infinity();
    let mut axis = 0;
    for i in 0..3 {
        if dda.step[i] == 0 {
            continue;
        }
        let edge = if dda.step[i] > 0 {
            dda.cell[i] + r + 1
        } else {
            dda.cell[i] - r
        };
        let t = (lattice_plane::<F>(s, i, edge) - dda.o[i]) * dda.inv[i];
        if t < best {
            best = t;
            axis = i;
        }
    }
    (best, axis)
}

/// Jumps to the cell the ray enters at `t` (where it leaves the empty cube
/// of half-width `r` across `axis`). On the other axes the cell comes from
/// the point, kept inside the cube and never behind the current cell (cell
/// indices stay monotone along the ray, which the test-once rule needs).
/// No primitive was tested in the empty cell left, so none is skipped next.
/// False when the ray leaves the grid.
#[inline(always)]
pub fn dda_jump<F: Real>(s: &SceneView, dda: &mut Dda<F>, r: i32, t: F, axis: usize) -> bool {
    let g = s.globals;
    let mut inside = true;
    for i in 0..3 {
        if dda.step[i] == 0 {
            continue;
        }
        let c = if i == axis {
            dda.cell[i] + dda.step[i] * (r + 1)
        } else {
            let p = dda.o[i] + dda.d[i] * t;
            let f = ((p - F::of(g.grid_min[i])) / F::of(g.grid_cell[i])).floor();
            let (lo, hi) = if dda.step[i] > 0 {
                (dda.cell[i], dda.cell[i] + r)
            } else {
                (dda.cell[i] - r, dda.cell[i])
            };
            if f.is_nan() || f <= F::of(lo as f32) {
                lo
            } else if f >= F::of(hi as f32) {
                hi
            } else {
                f.to_f32() as i32
            }
        };
        dda.cell[i] = c;
        inside = inside && c >= 0 && c < g.grid_dims[i] as i32;
    }
    dda.prev_axis = 3;
    if inside {
        for i in 0..3 {
            if dda.step[i] != 0 {
                dda.next[i] = dda_boundary(s, dda, i);
            }
        }
    }
    inside
}

/// True when the primitive was already tested in the previous cell. It is
/// listed in the current cell, so its cell range holds the current cell;
/// the previous cell differs only on the last step's axis, so checking
/// that one coordinate suffices.
#[inline(always)]
pub fn seen_before<F>(prim: &Prim, dda: &Dda<F>) -> bool {
    if dda.prev_axis > 2 {
        return false;
    }
    let shift = 10 * dda.prev_axis as u32;
    let lo = ((prim.cell_lo >> shift) & 1023) as i32;
    let hi = ((prim.cell_hi >> shift) & 1023) as i32;
    dda.prev_coord >= lo && dda.prev_coord <= hi
}

/// A ray visits at most dims.x + dims.y + dims.z − 2 cells (each step moves
/// one axis one cell, monotonically); the loops stop there at the latest so
/// that a NaN ray cannot loop forever. Never reached by a finite ray.
#[inline(always)]
pub fn dda_max_cells(s: &SceneView) -> u32 {
    let d = s.globals.grid_dims;
    d[0] + d[1] + d[2]
}

#[inline(always)]
fn cell_index(s: &SceneView, c: [i32; 3]) -> usize {
    let d = s.globals.grid_dims;
    (c[0] as u32 + d[0] * (c[1] as u32 + d[1] * c[2] as u32)) as usize
}

/// Walks the grid for query `q` (`query.rs`): every primitive listed in
/// the cells the ray crosses, each once, until the query is done, the
/// ray leaves the grid, or `q.t` (the best hit so far, or the feeler's
/// length) lies inside the current cell. The unbounded primitives are
/// the caller's (`accel.rs`).
#[inline(always)]
pub fn grid_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
) {
    let Some(mut dda) = dda_setup(s, ray, pre, q.t) else {
        return;
    };
    for _ in 0..dda_max_cells(s) {
        work.cells += 1;
        let ci = cell_index(s, dda.cell);
        let (start, end) = (s.cell_start[ci] as usize, s.cell_start[ci + 1] as usize);
        // Only an empty cell's distance is read: one memory access less
        // per listed cell.
        let skip = if start == end {
            cell_skip(s, ci) as i32
        } else {
            0
        };
        if skip >= 2 {
            let (t_jump, axis) = dda_jump_exit(s, &dda, skip - 1);
            if q.t <= t_jump
                || t_jump >= dda.t_end
                || !dda_jump(s, &mut dda, skip - 1, t_jump, axis)
            {
                return;
            }
            continue;
        }
        let (t_exit, axis) = dda_exit(&dda);
        if !s.walk_bits.is_empty() {
            // The plain grid with its walk arrays (`pack::grid::Walk`): the
            // same tests in the same order as the loop below, without
            // reading a record to skip a primitive or to test a sphere.
            if walk_cell(s, q, ray, pre, work, &dda, start, end) {
                return;
            }
        } else {
            for &r in &s.refs[start..end] {
                if r & HYBRID_NODE != 0 && s.globals.flags[1] == ACCEL_HYBRID {
                    // A crowded cell's own BVH (`pack::hybrid`), its leaves'
                    // primitives skipped as the list's would be.
                    let seen = |e: u32| {
                        let i = s.refs[e as usize];
                        (!seen_before(&s.prims[i as usize], &dda)).then_some(i)
                    };
                    if bvh_walk(s, ray, pre, q, work, r & !HYBRID_NODE, seen) {
                        return;
                    }
                    continue;
                }
                let prim = &s.prims[r as usize];
                if seen_before(prim, &dda) {
                    continue;
                }
                if query_prim(s, q, prim, r, ray, pre, work) {
                    return;
                }
            }
        }
        if q.t <= t_exit || t_exit >= dda.t_end || !dda_advance(s, &mut dda, axis) {
            return;
        }
    }
}

/// One cell's references `start..end` for query `q`, through the walk
/// arrays (`SceneView::walk_bits`, `SceneView::spheres`): a reference
/// whose bit for the way the walk came in is set was tested in the
/// previous cell (`seen_before`, from the primitive's cell range); the
/// others go to `query_indexed` (a sphere tested from its 16-byte
/// record). True when the query is done. The shader has no such arrays: the same tests in the
/// same order (docs/architecture.md, "The CPU's own arrays").
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk_cell<F: Real>(
    s: &SceneView,
    q: &mut Query<F>,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    work: &mut Work,
    dda: &Dda<F>,
    start: usize,
    end: usize,
) -> bool {
    let came_by: u8 = if dda.prev_axis > 2 {
        0
    } else {
        1 << (2 * dda.prev_axis + (dda.step[dda.prev_axis] < 0) as usize)
    };
    for (&r, &b) in s.refs[start..end].iter().zip(&s.walk_bits[start..end]) {
        if b & came_by != 0 {
            continue;
        }
        if query_indexed(s, q, r, ray, pre, work) {
            return true;
        }
    }
    false
}
