//! Traversal of the octree: twin of `shaders/octree.glsl`.
//!
//! The lecture's method: from the leaf holding the ray's current point,
//! find where the ray leaves it, and the leaf on the other side of that
//! face by descending the tree to the point just across it. The
//! point is a cell of the deepest level's lattice (`pack::octree`), so
//! "just across" is exact: one lattice cell past the face on the axis the
//! ray leaves by, and on the other axes the cell the exit point lies in,
//! kept inside the leaf's face. No nudged float point, no leaf skipped.
//!
//! The descent to the next leaf starts at the deepest node on the path
//! to the current one that holds the next point (the highest bit in
//! which the two lattice cells differ says which), not at the root.
//!
//! One traversal serves both queries (`query.rs`). The closest hit keeps
//! the best hit across leaves and stops once it lies inside the current
//! leaf, as in the grid. A primitive listed in several leaves may be
//! tested in each. For a closest hit that changes nothing (the same hit,
//! the same rank), and the walk skips a primitive the previous leaf
//! listed too (leaf lists ascend, so one merge pass finds them). A feeler
//! would multiply a transparent blocker's k_t once per leaf, so the walk
//! gives the query the leaf's stretch of the feeler
//! (`Query::lo`, `hi`) and a transparent blocker counts only in the leaf
//! its hit lies in. The stretches follow one another (each starts where
//! the last ended, the first at −∞, the last ends at +∞), so every hit
//! lies in exactly one.

use super::grid::{clip_to_box, lattice_cell, lattice_plane};
use super::intersect::RayPre;
use super::math::{Ray, Real};
use super::query::{query_prim, Query, Work};
use super::SceneView;
use crate::constants::{OCTREE_INTERIOR, OCTREE_MAX_LEVELS, OCTREE_STACK_SIZE};

/// The leaf holding lattice cell `p`, found from the node at `level` on
/// `path` (which must hold `p`) down: the leaf's level, with the nodes
/// down to it on `path`, and its side in lattice cells (its origin is `p`
/// with the bits below the side cleared).
#[inline(always)]
pub fn octree_leaf(
    s: &SceneView,
    p: [i32; 3],
    path: &mut [u32; OCTREE_MAX_LEVELS as usize + 1],
    mut level: usize,
    work: &mut Work,
) -> (usize, i32) {
    let mut node = path[level] as usize;
    let mut half = (s.globals.grid_dims[0] >> (level + 1)) as i32;
    while half > 0 && s.cell_start[2 * node + 1] == OCTREE_INTERIOR {
        work.nodes += 1;
        let c = ((p[0] & half) != 0) as usize
            | (((p[1] & half) != 0) as usize) << 1
            | (((p[2] & half) != 0) as usize) << 2;
        node = s.cell_start[2 * node] as usize + c;
        level += 1;
        path[level] = node as u32;
        half >>= 1;
    }
    (level, if half == 0 { 1 } else { 2 * half })
}

/// The deepest level whose node holding lattice cell `a` also holds `b`
/// (`a` ≠ `b`): the nodes at level l share the bits of their cells from
/// bit L − l up (L the lattice's levels, `side` = 2^L).
#[inline(always)]
pub fn octree_common_level(side: u32, a: [i32; 3], b: [i32; 3]) -> usize {
    let diff = ((a[0] ^ b[0]) | (a[1] ^ b[1]) | (a[2] ^ b[2])) as u32;
    // side = 2^L: L − 1 − (the highest differing bit).
    (diff.leading_zeros() as i32 - side.leading_zeros() as i32 - 1).max(0) as usize
}

/// Runs query `q` over leaf `node`'s primitives, which both walks reach in
/// order along the ray: `stretch` is the leaf's stretch of the ray
/// (`Query::lo`, `hi`), `prev` the list (offset, length) of the last leaf
/// before it that listed any, whose primitives a closest-hit query
/// tested already (both lists ascend: one merge pass finds them); `prev`
/// becomes this leaf's list if it has one. True when the query is done.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn octree_leaf_query<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    node: usize,
    stretch: (F, F),
    prev: &mut (u32, u32),
    work: &mut Work,
) -> bool {
    (q.lo, q.hi) = stretch;
    let (start, count) = (s.cell_start[2 * node], s.cell_start[2 * node + 1]);
    let (mut j, prev_end) = (prev.0, prev.0 + prev.1);
    if count > 0 {
        *prev = (start, count);
    }
    for k in start..start + count {
        let r = s.refs[k as usize];
        if !q.shadow {
            while j < prev_end && s.refs[j as usize] < r {
                j += 1;
            }
            if j < prev_end && s.refs[j as usize] == r {
                continue;
            }
        }
        if query_prim(s, q, &s.prims[r as usize], r, ray, pre, work) {
            return true;
        }
    }
    false
}

/// A ray's origin, direction and 1/direction per axis, and its stretch
/// t0..t1 inside the octree's box.
struct OctreeRay<F> {
    o: [F; 3],
    d: [F; 3],
    inv: [F; 3],
    t0: F,
    t1: F,
}

/// The ray as both walks take it, clipped to the box within 0..`tmax`;
/// `None` when the octree is empty or the ray misses it.
#[inline(always)]
fn octree_ray<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<OctreeRay<F>> {
    if s.globals.grid_min[3] == 0.0 {
        return None;
    }
    let o = [ray.o.x, ray.o.y, ray.o.z];
    let d = [ray.d.x, ray.d.y, ray.d.z];
    let inv = [pre.inv_d.x, pre.inv_d.y, pre.inv_d.z];
    let (t0, t1) = clip_to_box(s, &o, &d, &inv, tmax)?;
    Some(OctreeRay { o, d, inv, t0, t1 })
}

/// Walks the octree for query `q`: every primitive listed in the leaves
/// the ray crosses, in order along the ray, until the query is done, the
/// ray leaves the octree, or `q.t` lies inside the current leaf. The
/// unbounded primitives are the caller's (`accel.rs`).
#[inline(always)]
pub fn octree_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
) {
    let g = s.globals;
    let Some(OctreeRay { o, d, inv, t0, t1 }) = octree_ray(s, ray, pre, q.t) else {
        return;
    };
    let side = g.grid_dims[0] as i32;
    let step = d.map(|x| {
        if x > F::zero() {
            1
        } else if x < F::zero() {
            -1
        } else {
            0
        }
    });
    let mut p = [0i32; 3];
    for i in 0..3 {
        p[i] = lattice_cell(s, o[i] + d[i] * t0, i, 0, side - 1);
    }
    let mut lo = F::neg_infinity();
    // The nodes from the root to the current leaf: the next leaf is
    // found from the deepest of them that holds the next point, not from
    // the root (about a third of the descents on SPD rings).
    let mut path = [0u32; OCTREE_MAX_LEVELS as usize + 1];
    let mut level = 0usize;
    // The list of the previous leaf that listed any (offset, length).
    let mut prev = (0u32, 0u32);
    // Each step enters another leaf, so a walk takes at most one step per
    // leaf (the bound keeps a NaN ray finite).
    for _ in 0..g.grid_dims[3] {
        work.cells += 1;
        let (leaf_level, size) = octree_leaf(s, p, &mut path, level, work);
        let node = path[leaf_level] as usize;
        let org = p.map(|c| c & !(size - 1));
        // Where the ray leaves the leaf, and across which axis (the lower
        // axis on a tie, as the grid's dda_exit).
        let mut t_exit = F::infinity();
        let mut axis = 0;
        for i in 0..3 {
            if step[i] == 0 {
                continue;
            }
            let edge = if step[i] > 0 { org[i] + size } else { org[i] };
            let t = (lattice_plane::<F>(s, i, edge) - o[i]) * inv[i];
            if t < t_exit {
                t_exit = t;
                axis = i;
            }
        }
        let across = if step[axis] > 0 {
            org[axis] + size
        } else {
            org[axis] - 1
        };
        let last = t_exit >= t1 || across < 0 || across >= side;
        let hi = if last { F::infinity() } else { t_exit.max(lo) };
        if octree_leaf_query(s, ray, pre, q, node, (lo, hi), &mut prev, work)
            || q.t <= t_exit
            || last
        {
            return;
        }
        for i in 0..3 {
            if i != axis && step[i] != 0 {
                p[i] = lattice_cell(s, o[i] + d[i] * t_exit, i, org[i], org[i] + size - 1);
            }
        }
        let from = p;
        p[axis] = across;
        level = octree_common_level(side as u32, from, p).min(leaf_level);
        lo = hi;
    }
}

/// One pending node of the stack walk: its node, lattice origin and level,
/// and the stretch of the ray inside it.
#[derive(Clone, Copy, Debug)]
struct Pending<F> {
    node: u32,
    org: [i32; 3],
    level: u32,
    t_in: F,
    t_out: F,
}

/// Walks the octree for query `q` as `octree_traverse` does, but top down
/// with a stack (`--octree-walk stack`): at an interior node the ray's
/// stretch in it is cut where it crosses the three mid-planes, which
/// gives the (up to four) children it passes through in order along the
/// ray (Revelles, Ureña and Lastra's parametric traversal: the child
/// entered first, then one flipped bit per plane crossed); the first is
/// walked, the others pushed. Leaves come in the same order as from the
/// neighbour walk, with the same stretches, so both queries and the
/// transparent blockers' rule work alike.
#[inline(always)]
pub fn octree_traverse_stack<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
) {
    let g = s.globals;
    let Some(OctreeRay { o, d, inv, t0, t1 }) = octree_ray(s, ray, pre, q.t) else {
        return;
    };
    let side = g.grid_dims[0] as i32;
    let mut stack = [Pending {
        node: 0,
        org: [0; 3],
        level: 0,
        t_in: F::zero(),
        t_out: F::zero(),
    }; OCTREE_STACK_SIZE as usize];
    let mut sp = 0usize;
    let mut cur = Pending {
        node: 0,
        org: [0; 3],
        level: 0,
        t_in: t0,
        t_out: t1,
    };
    let mut lo = F::neg_infinity();
    let mut prev = (0u32, 0u32);
    // Each node is taken up once (the bound keeps a NaN ray finite).
    for _ in 0..g.grid_dims[3] {
        let node = cur.node as usize;
        if s.cell_start[2 * node + 1] == OCTREE_INTERIOR {
            work.nodes += 1;
            let half = side >> (cur.level + 1);
            // Where the ray crosses each mid-plane, and the half it is in
            // where it enters the node (the far one of a plane crossed by
            // then; for an axis it does not move along, its side).
            let mut tm = [F::infinity(); 3];
            let mut bits = 0usize;
            for i in 0..3 {
                let plane: F = lattice_plane(s, i, cur.org[i] + half);
                let upper = if d[i] == F::zero() {
                    o[i] >= plane
                } else {
                    tm[i] = (plane - o[i]) * inv[i];
                    (tm[i] <= cur.t_in) == (d[i] > F::zero())
                };
                bits |= (upper as usize) << i;
            }
            // The planes crossed inside the stretch, in order along the
            // ray (the lower axis on a tie).
            let mut order = [0usize; 3];
            let mut m = 0;
            for i in 0..3 {
                if d[i] != F::zero() && tm[i] > cur.t_in && tm[i] < cur.t_out {
                    let mut j = m;
                    while j > 0 && tm[i] < tm[order[j - 1]] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = i;
                    m += 1;
                }
            }
            // The children in order: child k from the k-th crossing (the
            // entry for k = 0) to the next (the node's exit for the last).
            let base = s.cell_start[2 * node];
            let child = |bits: usize, t_in: F, t_out: F| Pending {
                node: base + bits as u32,
                org: [0, 1, 2].map(|a| cur.org[a] + half * ((bits >> a) & 1) as i32),
                level: cur.level + 1,
                t_in,
                t_out,
            };
            let mut seq = [cur; 4];
            let mut t = cur.t_in;
            for k in 0..m {
                seq[k] = child(bits, t, tm[order[k]]);
                bits ^= 1 << order[k];
                t = tm[order[k]];
            }
            seq[m] = child(bits, t, cur.t_out);
            for k in (1..=m).rev() {
                stack[sp] = seq[k];
                sp += 1;
            }
            work.stack_at(sp);
            cur = seq[0];
            continue;
        }
        work.cells += 1;
        let last = cur.t_out >= t1;
        let hi = if last {
            F::infinity()
        } else {
            cur.t_out.max(lo)
        };
        if octree_leaf_query(s, ray, pre, q, node, (lo, hi), &mut prev, work)
            || q.t <= cur.t_out
            || last
            || sp == 0
        {
            return;
        }
        lo = hi;
        sp -= 1;
        cur = stack[sp];
    }
}
