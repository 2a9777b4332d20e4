//! Traversal of the bounding-volume hierarchy: twin of `shaders/bvh.glsl`.
//!
//! One traversal serves both queries (`query.rs`). At a node the boxes of
//! its (up to four) children are tested against the segment 0..`q.t`
//! with four-wide arithmetic (`bvh_entries`); the children the ray enters
//! are ordered by where it enters them (lane order on a tie), the nearest
//! is walked first and the others are pushed, farthest first, with their
//! entry distances, so that a closest-hit query drops one when it pops it
//! if a hit nearer than that was found meanwhile; a shadow feeler takes
//! them in lane order and keeps no distances. A leaf hands its
//! primitives to `query_prim`. The stack has `BVH_STACK_SIZE` entries,
//! which the build keeps enough (`pack::bvh::collapse`).

use super::intersect::RayPre;
use super::math::{Ray, Real};
use super::query::{query_prim, Query, Work};
use super::SceneView;
use crate::constants::{BVH_EXIT_WIDEN, BVH_STACK_SIZE, BVH_WIDTH, SHADOW_CACHE_LIGHTS};
use crate::pack::layout::BvhNode;

const W: usize = BVH_WIDTH as usize;

/// Where the ray enters each child's box within the segment 0..`tmax`
/// (0 from inside), and whether it enters it at all. Slabs, the near
/// plane chosen by the sign of 1/d, the four lanes side by side (the
/// compiler turns the lane loops into vector instructions). The bounds
/// are narrowed by comparisons (`tn > t0`), which ignore a NaN: a ray
/// parallel to an axis (1/d = ±∞) whose origin lies on one of the box's
/// planes (0·∞) counts as inside that slab, as it is. A parallel ray
/// outside a slab gets t0 = +∞, a miss unless `tmax` is +∞ too; then the
/// box is entered "at +∞" and walked for nothing, never wrongly skipped.
/// An empty lane (lo = +∞, hi = −∞) is missed by every ray without a NaN
/// (the walk turns such rays away first). The lanes entered as bits of
/// a mask.
#[inline(always)]
pub fn bvh_entries<F: Real>(n: &BvhNode, ray: &Ray<F>, pre: &RayPre<F>, tmax: F) -> ([F; W], u32) {
    let mut t0 = [F::zero(); W];
    let mut t1 = [tmax; W];
    for i in 0..3 {
        let o = ray.o.get(i);
        let inv = pre.inv_d.get(i);
        let near = &n.bounds[pre.near[i]][i];
        let far = &n.bounds[1 - pre.near[i]][i];
        for k in 0..W {
            let tn = (F::of(near[k]) - o) * inv;
            let tf = (F::of(far[k]) - o) * inv * F::of(BVH_EXIT_WIDEN);
            if tn > t0[k] {
                t0[k] = tn;
            }
            if tf < t1[k] {
                t1[k] = tf;
            }
        }
    }
    let mut mask = 0;
    for k in 0..W {
        mask |= ((t0[k] <= t1[k]) as u32) << k;
    }
    (t0, mask)
}

/// A ray with a NaN, or from an infinite origin (∞ − ∞ is a NaN in the
/// slabs), is the only kind that can enter an empty lane. It has no
/// meaningful answer (from an infinite origin it meets no bounded
/// primitive; a NaN compares false, so a box test may take it as inside
/// a slab), and the grid's walk gives up on it too: the walk turns it
/// away, so no lane needs checking (tests/accel.rs,
/// `rays_from_non_finite_origins_end_and_meet_nothing`). The shader
/// checks the lanes instead: a GPU compiler may assume no NaN. 1/d may
/// be infinite.
#[inline(always)]
fn turned_away<F: Real>(ray: &Ray<F>, pre: &RayPre<F>) -> bool {
    (0..3).any(|i| !ray.o.get(i).is_finite() || pre.inv_d.get(i).is_nan())
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
    bvh_walk(s, ray, pre, q, work, 0, Some);
}

/// Walks the hierarchy whose root is node `root` (under the hybrid, a
/// crowded grid cell's own: `pack::hybrid`) for query `q`. A leaf's
/// entries are `link..link + count`; `prim(entry)` gives the primitive
/// to test for one, or `None` to skip it (the BVH: the entry is the
/// primitive; the hybrid's: `refs[entry]`, unless the grid's previous
/// cell listed it). Returns true when the query is done.
#[inline(always)]
pub fn bvh_walk<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
    root: u32,
    prim: impl Fn(u32) -> Option<u32>,
) -> bool {
    let nodes = s.globals.flags[2];
    if nodes == 0 {
        return false;
    }
    if turned_away(ray, pre) {
        return false;
    }
    // The pushed children: node · BVH_WIDTH + lane, and entry distances
    // (a feeler's pushes store W − 1 slots, some beyond the last pushed).
    let mut stack_slot = [0u32; BVH_STACK_SIZE as usize + W];
    let mut stack_t = [F::zero(); BVH_STACK_SIZE as usize];
    let mut sp = 0usize;
    // The current child: the root first; `slot`: 1 + its node · W +
    // lane (0 for the root), which names a leaf to the shadow cache.
    let mut link = root;
    let mut count = 0u32;
    let mut slot = 0u32;
    let mut t = F::zero();
    // Each child becomes the current one at most once, so a walk takes at
    // most BVH_WIDTH·nodes + 1 steps (the bound keeps a NaN ray finite).
    for _ in 0..W as u64 * nodes as u64 + 1 {
        // A feeler's segment never shrinks: every child it entered is
        // still worth walking, so it keeps no entry distances.
        if q.shadow || t <= q.t {
            if count > 0 {
                for entry in link..link + count {
                    let Some(i) = prim(entry) else {
                        continue;
                    };
                    if query_prim(s, q, &s.prims[i as usize], i, ray, pre, work) {
                        if q.shadow
                            && q.light < SHADOW_CACHE_LIGHTS as usize
                            && *work.cached(q.light) == i + 1
                        {
                            *work.cached_leaf(q.light) = slot;
                        }
                        return true;
                    }
                }
            } else {
                work.nodes += 1;
                let Some(node) = s.bvh.get(link as usize) else {
                    return false;
                };
                let (te, mut mask) = bvh_entries(node, ray, pre, q.t);
                if q.shadow && mask != 0 {
                    // A feeler takes the lanes entered in lane order (its
                    // segment never shrinks, so no order saves it a test):
                    // the lowest now, the others pushed, the highest
                    // deepest, a store each whether entered or not rather
                    // than a branch each (SPD rings 2-4 % faster, others level;
                    // BENCHMARKS.md).
                    let k = mask.trailing_zeros() as usize;
                    let rest = mask & (mask - 1);
                    for j in (1..W).rev() {
                        stack_slot[sp] = link * BVH_WIDTH + j as u32;
                        sp += ((rest >> j) & 1) as usize;
                    }
                    work.stack_at(sp);
                    slot = 1 + link * BVH_WIDTH + k as u32;
                    count = node.count[k];
                    link = node.link[k];
                    continue;
                }
                if mask.is_power_of_two() {
                    // One child entered (the commonest case).
                    let k = mask.trailing_zeros() as usize;
                    slot = 1 + link * BVH_WIDTH + k as u32;
                    count = node.count[k];
                    link = node.link[k];
                    t = te[k];
                    continue;
                }
                if mask != 0 {
                    // The lanes entered, nearest first, lane order on a
                    // tie: the order the shader's sorting network gives
                    // (bvh.glsl, which must not loop here); an insertion
                    // sort over the mask's bits is cheaper on the CPU,
                    // where most nodes have one or two children entered.
                    let mut order = [0usize; W];
                    let mut m = 0;
                    while mask != 0 {
                        let k = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let mut j = m;
                        while j > 0 && te[k] < te[order[j - 1]] {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = k;
                        m += 1;
                    }
                    for j in (1..m).rev() {
                        stack_slot[sp] = link * BVH_WIDTH + order[j] as u32;
                        stack_t[sp] = te[order[j]];
                        sp += 1;
                    }
                    work.stack_at(sp);
                    let k = order[0];
                    slot = 1 + link * BVH_WIDTH + k as u32;
                    count = node.count[k];
                    link = node.link[k];
                    t = te[k];
                    continue;
                }
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        slot = 1 + stack_slot[sp];
        let at = stack_slot[sp] as usize;
        let n = &s.bvh[at / W];
        link = n.link[at % W];
        count = n.count[at % W];
        t = stack_t[sp];
    }
    false
}

/// Whether the walk for a feeler (segment 0..`tmax`) would reach the
/// leaf `slot` (1 + node · `BVH_WIDTH` + lane; 0: none): the rays the walk
/// turns away never, else the leaf's box tested as the walk tests it.
/// Every ancestor's box holds the leaf's in f32, and the slab arithmetic
/// is monotone in the planes, so a feeler that enters the leaf's box
/// enters theirs: the walk reaches the leaf and tests what it lists. The
/// shadow cache asks this before it answers for a primitive of the BVH
/// (`accel::transmittance`), so that it never finds a blocker the walk
/// would not (an f32 test of a primitive far from the ray's origin may
/// report a hit its boxes rule out). Twin: `bvh_leaf_admits` in
/// bvh.glsl (whose walk takes the rays this one turns away, and so does
/// its check).
#[inline(always)]
pub fn bvh_leaf_admits<F: Real>(
    s: &SceneView,
    slot: u32,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> bool {
    if slot == 0 || turned_away(ray, pre) {
        return false;
    }
    let at = (slot - 1) as usize;
    match s.bvh.get(at / W) {
        Some(node) => bvh_entries(node, ray, pre, tmax).1 & (1 << (at % W)) != 0,
        None => false,
    }
}
