//! 3D-DDA (Amanatides & Woo) through the uniform voxel grid: twin of
//! `shaders/grid.glsl`.
//!
//! Closest hit keeps the best hit found so far across cells (a primitive's
//! hit may lie beyond the cell that referenced it) and stops once that hit
//! lies inside the current cell. Each primitive is tested once per ray: its
//! references along a ray form one run of consecutive cells (it is filed
//! in every cell its bounds overlap, and cell indices are monotone along a
//! ray), so a primitive whose cell range holds the previous cell was
//! already tested there and is skipped.

use super::intersect::{intersect, Hit, RayPre};
use super::math::{Ray, Real, V3};
use super::SceneView;
use crate::pack::layout::{cell_unpack, Prim};

/// Traversal state: the current cell and where the ray leaves it.
#[derive(Clone, Copy, Debug)]
pub struct Dda<F> {
    pub cell: [i32; 3],
    pub step: [i32; 3],
    /// Where the ray segment inside the grid ends.
    pub t_end: F,
    /// Cell being left last (−1: none yet).
    pub prev: [i32; 3],
}

/// Clips the ray to the grid; `None` when it misses the grid or the grid is empty.
pub fn dda_setup<F: Real>(s: &SceneView, ray: &Ray<F>, pre: &RayPre<F>, tmax: F) -> Option<Dda<F>> {
    let g = s.globals;
    if g.grid_min[3] == 0.0 {
        return None;
    }
    let lo = V3::<F>::of(&g.grid_min);
    let hi = V3::<F>::of(&g.grid_max);
    let mut t0 = F::zero();
    let mut t1 = tmax;
    for i in 0..3 {
        let o = ray.o.get(i);
        if ray.d.get(i) == F::zero() {
            if o < lo.get(i) || o > hi.get(i) {
                return None;
            }
            continue;
        }
        let inv = pre.inv_d.get(i);
        let ta = (lo.get(i) - o) * inv;
        let tb = (hi.get(i) - o) * inv;
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    if t0 > t1 {
        return None;
    }
    let cs = V3::<F>::of(&g.grid_cell);
    let p = ray.o + ray.d * t0;
    let mut cell = [0i32; 3];
    let mut step = [0i32; 3];
    for i in 0..3 {
        let n = g.grid_dims[i] as i32;
        let c = ((p.get(i) - lo.get(i)) / cs.get(i)).floor();
        let c = if c.is_nan() { 0 } else { c.to_f32() as i32 };
        cell[i] = c.clamp(0, n - 1);
        let d = ray.d.get(i);
        step[i] = if d > F::zero() {
            1
        } else if d < F::zero() {
            -1
        } else {
            0
        };
    }
    Some(Dda {
        cell,
        step,
        t_end: t1,
        prev: [-1, -1, -1],
    })
}

/// Distance along the ray to the far boundary of the current cell on each
/// axis, computed afresh from the cell index (no accumulated error).
#[inline(always)]
pub fn dda_exit<F: Real>(s: &SceneView, ray: &Ray<F>, pre: &RayPre<F>, dda: &Dda<F>) -> (F, usize) {
    let g = s.globals;
    let mut best = F::infinity();
    let mut axis = 0;
    for i in 0..3 {
        if dda.step[i] == 0 {
            continue;
        }
        let edge = dda.cell[i] + if dda.step[i] > 0 { 1 } else { 0 };
        let plane = F::of(g.grid_min[i]) + F::of(edge as f32) * F::of(g.grid_cell[i]);
        let t = (plane - ray.o.get(i)) * pre.inv_d.get(i);
        if t < best {
            best = t;
            axis = i;
        }
    }
    (best, axis)
}

/// Moves to the next cell along `axis`; false when the ray leaves the grid.
#[inline(always)]
pub fn dda_advance<F: Real>(s: &SceneView, dda: &mut Dda<F>, axis: usize) -> bool {
    dda.prev = dda.cell;
    dda.cell[axis] += dda.step[axis];
    dda.cell[axis] >= 0 && dda.cell[axis] < s.globals.grid_dims[axis] as i32
}

/// True when the primitive was already tested in the previous cell.
#[inline(always)]
pub fn seen_before(prim: &Prim, prev: [i32; 3]) -> bool {
    if prev[0] < 0 {
        return false;
    }
    let lo = cell_unpack(prim.cell_lo);
    let hi = cell_unpack(prim.cell_hi);
    (0..3).all(|i| prev[i] >= lo[i] as i32 && prev[i] <= hi[i] as i32)
}

#[inline(always)]
fn cell_index(s: &SceneView, c: [i32; 3]) -> usize {
    let d = s.globals.grid_dims;
    (c[0] as u32 + d[0] * (c[1] as u32 + d[1] * c[2] as u32)) as usize
}

/// Counters of intersection work, for tests and profiling.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    pub tests: u64,
    pub cells: u64,
}

/// The nearest hit along the ray with t < tmax: (hit, primitive index).
pub fn closest_hit<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
    work: &mut Work,
) -> Option<(Hit<F>, u32)> {
    let g = s.globals;
    let mut best_t = tmax;
    let mut best: Option<(Hit<F>, u32)> = None;
    for i in g.counts[0]..g.counts[1] {
        work.tests += 1;
        if let Some(h) = intersect(&s.prims[i as usize], s.extra, ray, pre, best_t) {
            best_t = h.t;
            best = Some((h, i));
        }
    }
    let Some(mut dda) = dda_setup(s, ray, pre, best_t) else {
        return best;
    };
    loop {
        work.cells += 1;
        let (t_exit, axis) = dda_exit(s, ray, pre, &dda);
        let ci = cell_index(s, dda.cell);
        let (start, end) = (s.cell_start[ci] as usize, s.cell_start[ci + 1] as usize);
        for &r in &s.refs[start..end] {
            let prim = &s.prims[r as usize];
            if seen_before(prim, dda.prev) {
                continue;
            }
            work.tests += 1;
            if let Some(h) = intersect(prim, s.extra, ray, pre, best_t) {
                best_t = h.t;
                best = Some((h, r));
            }
        }
        if best_t <= t_exit || t_exit >= dda.t_end {
            return best;
        }
        if !dda_advance(s, &mut dda, axis) {
            return best;
        }
    }
}

/// Light reaching the end of a shadow feeler of length `dist`: every
/// primitive crossing it multiplies by its k_t (opaque ones give zero).
/// Shadow feelers are not refracted.
pub fn transmittance<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    dist: F,
    work: &mut Work,
) -> V3<F> {
    let g = s.globals;
    let mut trans = V3::splat(F::one());
    for i in g.counts[0]..g.counts[1] {
        let prim = &s.prims[i as usize];
        work.tests += 1;
        if intersect(prim, s.extra, ray, pre, dist).is_some() {
            trans = trans.mul(V3::of(&s.materials[prim.material() as usize].kt));
            if trans.max_elem() <= F::zero() {
                return V3::zero();
            }
        }
    }
    let Some(mut dda) = dda_setup(s, ray, pre, dist) else {
        return trans;
    };
    loop {
        work.cells += 1;
        let (t_exit, axis) = dda_exit(s, ray, pre, &dda);
        let ci = cell_index(s, dda.cell);
        let (start, end) = (s.cell_start[ci] as usize, s.cell_start[ci + 1] as usize);
        for &r in &s.refs[start..end] {
            let prim = &s.prims[r as usize];
            if seen_before(prim, dda.prev) {
                continue;
            }
            work.tests += 1;
            if intersect(prim, s.extra, ray, pre, dist).is_some() {
                trans = trans.mul(V3::of(&s.materials[prim.material() as usize].kt));
                if trans.max_elem() <= F::zero() {
                    return V3::zero();
                }
            }
        }
        if t_exit >= dda.t_end || !dda_advance(s, &mut dda, axis) {
            return trans;
        }
    }
}

/// Brute force over every primitive: the reference the grid must equal.
pub fn closest_hit_brute<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<(Hit<F>, u32)> {
    let mut best_t = tmax;
    let mut best = None;
    for (i, prim) in s.prims.iter().enumerate() {
        if let Some(h) = intersect(prim, s.extra, ray, pre, best_t) {
            best_t = h.t;
            best = Some((h, i as u32));
        }
    }
    best
}
