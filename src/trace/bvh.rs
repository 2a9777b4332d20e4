//! Traversal of the bounding-volume hierarchy: twin of `shaders/bvh.glsl`.
//!
//! One traversal serves both queries (`query.rs`). At an interior node
//! both children's boxes are tested against the segment 0..`q.t`; the
//! nearer child (by where the ray enters its box) is walked first and the
//! other is pushed with its entry distance, so that a closest-hit query
//! drops it when it pops it if a hit nearer than that was found
//! meanwhile. A leaf hands its primitives to `query_prim`. The stack has
//! `BVH_STACK_SIZE` entries, which the build's depth bound keeps enough
//! (`pack::bvh`).

use super::intersect::RayPre;
use super::math::{Ray, Real};
use super::query::{query_prim, Query, Work};
use super::SceneView;
use crate::constants::BVH_STACK_SIZE;
use crate::pack::layout::BvhChild;

/// Where the ray enters the child's box within the segment 0..`tmax`
/// (0 from inside), or `None` when it misses it. Slabs, the near plane
/// chosen by the sign of 1/d. The bounds are narrowed by comparisons
/// (`tn > t0`), which ignore a NaN: a ray parallel to an axis (1/d = ±∞)
/// whose origin lies on one of the box's planes (0·∞) counts as inside
/// that slab, as it is. A parallel ray outside a slab gets t0 = +∞, a
/// miss unless `tmax` is +∞ too; then the box is entered "at +∞" and
/// walked for nothing, never wrongly skipped.
#[inline(always)]
pub fn bvh_entry<F: Real>(c: &BvhChild, ray: &Ray<F>, pre: &RayPre<F>, tmax: F) -> Option<F> {
    let mut t0 = F::zero();
    let mut t1 = tmax;
    for i in 0..3 {
        let o = ray.o.get(i);
        let inv = pre.inv_d.get(i);
        let (near, far) = if inv >= F::zero() {
            (F::of(c.lo[i]), F::of(c.hi[i]))
        } else {
            (F::of(c.hi[i]), F::of(c.lo[i]))
        };
        let tn = (near - o) * inv;
        let tf = (far - o) * inv;
        if tn > t0 {
            t0 = tn;
        }
        if tf < t1 {
            t1 = tf;
        }
    }
    if t0 <= t1 {
        Some(t0)
    } else {
        None
    }
}

/// Walks the hierarchy for query `q`: every leaf whose box (and whose
/// ancestors' boxes) the segment 0..`q.t` enters, nearer children first,
/// until the query is done. The unbounded primitives are the caller's
/// (`accel.rs`).
#[inline(always)]
pub fn bvh_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
) {
    let nodes = s.globals.flags[2];
    if nodes == 0 {
        return;
    }
    // The pushed children: their entries' indices and entry distances.
    let mut stack_slot = [0u32; BVH_STACK_SIZE as usize];
    let mut stack_t = [F::zero(); BVH_STACK_SIZE as usize];
    let mut sp = 0usize;
    // The current child: the root (interior node 0) first.
    let mut link = 0u32;
    let mut count = 0u32;
    let mut t = F::zero();
    // Each child entry becomes the current one at most once, so a walk
    // takes at most 2·nodes + 1 steps (the bound keeps a NaN ray finite).
    for _ in 0..2 * nodes as u64 + 1 {
        if t <= q.t {
            if count > 0 {
                let first = link as usize;
                for (k, prim) in s.prims[first..first + count as usize].iter().enumerate() {
                    if query_prim(s, q, prim, link + k as u32, ray, pre, work) {
                        return;
                    }
                }
            } else {
                work.nodes += 1;
                let k = 2 * link as usize;
                let [c0, c1] = &s.bvh[k..k + 2] else {
                    return;
                };
                let e0 = bvh_entry(c0, ray, pre, q.t);
                let e1 = bvh_entry(c1, ray, pre, q.t);
                let next = match (e0, e1) {
                    (Some(t0), Some(t1)) => {
                        // Nearer first (the first child on a tie); the
                        // other waits on the stack.
                        let (near, tn, far, tf) = if t1 < t0 {
                            (c1, t1, k, t0)
                        } else {
                            (c0, t0, k + 1, t1)
                        };
                        stack_slot[sp] = far as u32;
                        stack_t[sp] = tf;
                        sp += 1;
                        Some((near, tn))
                    }
                    (Some(t0), None) => Some((c0, t0)),
                    (None, Some(t1)) => Some((c1, t1)),
                    (None, None) => None,
                };
                if let Some((c, tc)) = next {
                    link = c.link;
                    count = c.count;
                    t = tc;
                    continue;
                }
            }
        }
        if sp == 0 {
            return;
        }
        sp -= 1;
        let c = &s.bvh[stack_slot[sp] as usize];
        link = c.link;
        count = c.count;
        t = stack_t[sp];
    }
}
