//! Shadow feelers through a light buffer: twin of `shaders/lightbuf.glsl`.
//! The cube of directions around each light (`pack::lightbuf`): a feeler
//! tests the unbounded primitives, then the primitives its direction's
//! cell lists.

use super::intersect::RayPre;
use super::math::{Ray, Real, V3};
use super::query::{query_prim, query_unbounded, Query, Work};
use super::SceneView;
use crate::constants::SHADOW_CACHE_LIGHTS;

/// No cell lists anything there: the feeler's direction lies outside its
/// face's window.
pub const EMPTY: u32 = u32::MAX;

/// The shadow cache's leaf (`Work::shadow_leaf`) of a blocker met
/// through a light buffer: this bit and 1 + the reference's index in
/// `lb_refs`' pairs (no BVH slot has it: `bvh_leaf_admits` turns it away).
/// Twin: `LB_LEAF` in lightbuf.glsl.
pub const LB_LEAF: u32 = 1 << 31;

/// Whether the shadow cache may answer for its blocker, primitive `i`
/// (cached with `leaf`), for a feeler in light buffer cell `cell` at
/// depth `m`: an unbounded primitive always (the walk tests them first),
/// a bounded one when it was met through a light buffer at a reference
/// of this cell that the walk reaches (its depth not past `m`), so that
/// the cached test is one the walk would make.
#[inline(always)]
pub fn lightbuf_admits<F: Real>(s: &SceneView, i: u32, leaf: u32, cell: u32, m: F) -> bool {
    let g = s.globals;
    if (g.counts[0]..g.counts[1]).contains(&i) {
        return true;
    }
    if cell == EMPTY || leaf & LB_LEAF == 0 || leaf == LB_LEAF {
        return false;
    }
    let k = (leaf & !LB_LEAF) - 1;
    let start = s.lb_start[cell as usize];
    let end = s.lb_start[cell as usize + 1];
    k >= start
        && k < end
        && s.lb_refs[2 * k as usize] == i
        && F::of(f32::from_bits(s.lb_refs[2 * k as usize + 1])) <= m
}

/// The index along a face's side of coordinate `u` under the face's window
/// (origin `o`, `s` cells per unit) at `res` cells; `None` more than a cell
/// outside it (or an empty face, `s` = 0).
#[inline(always)]
pub fn lightbuf_index<F: Real>(u: F, o: f32, sc: f32, res: u32) -> Option<u32> {
    let x = (u - F::of(o)) * F::of(sc);
    if !(x >= -F::one() && x < F::of(res as f32) + F::one()) || sc == 0.0 {
        return None;
    }
    let i = x.trunc_i32().max(0) as u32;
    Some(i.min(res - 1))
}

/// The cell of light `light`'s buffer (resolution `res`) that direction
/// `c` (from the light towards the feeler's origin) falls in, and the
/// depth of the feeler's origin along that face's axis; `None` when `c`
/// has no dominant component (zero, infinite or NaN). The cell is
/// `EMPTY` outside the face's window. The dominant axis is x on ties with
/// y or z, then y on a tie with z.
#[inline(always)]
pub fn lightbuf_cell<F: Real>(s: &SceneView, res: u32, light: u32, c: V3<F>) -> Option<(u32, F)> {
    let ax = c.x.abs();
    let ay = c.y.abs();
    let az = c.z.abs();
    let axis: u32;
    let m: F;
    let u: F;
    let v: F;
    let neg: bool;
    if ax >= ay && ax >= az {
        axis = 0;
        m = ax;
        u = c.y;
        v = c.z;
        neg = c.x < F::zero();
    } else if ay >= az {
        axis = 1;
        m = ay;
        u = c.z;
        v = c.x;
        neg = c.y < F::zero();
    } else {
        axis = 2;
        m = az;
        u = c.x;
        v = c.y;
        neg = c.z < F::zero();
    }
    if !(m > F::zero() && m < F::infinity()) {
        return None;
    }
    let face = axis * 2 + neg as u32;
    // The face's window: after the cells' offsets, four words a face.
    let ncells = crate::pack::lightbuf::cells(s.globals.counts[2] as usize, res) as usize;
    let w = ncells + 1 + ((light * 6 + face) * 4) as usize;
    let f = |k: usize| f32::from_bits(s.lb_start[w + k]);
    let cell = match (
        lightbuf_index(u / m, f(0), f(1), res),
        lightbuf_index(v / m, f(2), f(3), res),
    ) {
        (Some(iu), Some(iv)) => ((light * 6 + face) * res + iv) * res + iu,
        _ => EMPTY,
    };
    Some((cell, m))
}

/// Runs shadow query `q` over the unbounded primitives, then the
/// primitives light buffer cell `cell` lists, nearest the light first,
/// up to the feeler's origin's depth `m`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn lightbuf_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    cell: u32,
    m: F,
    work: &mut Work,
) {
    if query_unbounded(s, q, ray, pre, work) {
        return;
    }
    if cell == EMPTY {
        return;
    }
    work.cells += 1;
    let start = s.lb_start[cell as usize];
    let end = s.lb_start[cell as usize + 1];
    for k in start..end {
        let d0 = f32::from_bits(s.lb_refs[2 * k as usize + 1]);
        if F::of(d0) > m {
            return;
        }
        let r = s.lb_refs[2 * k as usize];
        if query_prim(s, q, &s.prims[r as usize], r, ray, pre, work) {
            // The blocker's reference, for the shadow cache
            // (`lightbuf_admits`).
            if q.light < SHADOW_CACHE_LIGHTS as usize
                && s.shadow_cache()
                && *work.cached(q.light) == r + 1
                && k + 1 < LB_LEAF
            {
                *work.cached_leaf(q.light) = LB_LEAF | (k + 1);
            }
            return;
        }
    }
}
