//! The tracer's two queries over the whole scene: twin of
//! `shaders/accel.glsl`. Each tests the unbounded primitives (planes,
//! unclipped quadrics, giants) and then walks the structure the packed
//! scene carries (`Globals::flags.y`): the grid (`grid.rs`), the BVH
//! (`bvh.rs`) or the octree (`octree.rs`), one traversal each serving
//! both queries (`query.rs`).

use super::bvh::{bvh_leaf_admits, bvh_traverse};
use super::grid::{clip_to_box, grid_traverse, lattice_plane};
use super::intersect::{intersect, Hit, RayPre};
use super::lightbuf::{lightbuf_admits, lightbuf_cell, lightbuf_traverse};
use super::math::{Ray, Real, V3};
use super::octree::{octree_traverse, octree_traverse_stack};
use super::query::{query_prim, query_unbounded, Query, Work};
use super::SceneView;
use crate::constants::{
    ACCEL_BVH, ACCEL_GRID, ACCEL_HYBRID, ACCEL_OCTREE, CACHE_HIT_MARGIN, OCTREE_WALK_STACK,
    SHADOW_CACHE_LIGHTS,
};
use crate::pack::layout::cell_unpack;

/// Runs query `q`: the unbounded primitives, then the structure in use.
#[inline(always)]
pub fn accel_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    work: &mut Work,
) {
    if query_unbounded(s, q, ray, pre, work) {
        return;
    }
    if s.globals.flags[1] == ACCEL_BVH {
        bvh_traverse(s, ray, pre, q, work);
    } else if s.globals.flags[1] == ACCEL_OCTREE {
        if s.globals.flags[2] == OCTREE_WALK_STACK {
            octree_traverse_stack(s, ray, pre, q, work);
        } else {
            octree_traverse(s, ray, pre, q, work);
        }
    } else {
        grid_traverse(s, ray, pre, q, work);
    }
}

/// The nearest hit along the ray with t < tmax: (hit, primitive index).
pub fn closest_hit<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
    work: &mut Work,
) -> Option<(Hit<F>, u32)> {
    let mut q = Query::closest(tmax);
    accel_traverse(s, ray, pre, &mut q, work);
    q.hit
}

/// Light reaching the end of a shadow feeler of length `dist`: every
/// primitive crossing it multiplies by its k_t (opaque ones give zero).
/// Shadow feelers are not refracted. `light` is the light the feeler goes
/// to (≥ the light count: none); it indexes the shadow cache (≥
/// `SHADOW_CACHE_LIGHTS`: none), whose primitive is tested first, and,
/// when the scene carries light buffers (`Globals::flags.w` > 0), the
/// light buffer whose cell lists the primitives to test (and which then
/// decides whether the cache may answer). A feeler whose origin is the
/// light's position walks the structure instead.
pub fn transmittance<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    dist: F,
    light: usize,
    work: &mut Work,
) -> V3<F> {
    let g = s.globals;
    let res = g.flags[3];
    let cell = if res > 0 && light < g.counts[2] as usize {
        lightbuf_cell(s, res, light as u32, ray.o - V3::of(&s.lights[light].pos))
    } else {
        None
    };
    let cached = if light < SHADOW_CACHE_LIGHTS as usize && s.shadow_cache() {
        *work.cached(light)
    } else {
        0
    };
    if cached != 0 {
        let leaf = *work.cached_leaf(light);
        // Through a light buffer the cache answers where the walk would
        // test its blocker: the feeler's cell lists it before the cut
        // (`lightbuf_admits`); the same test then gives the same answer.
        let admitted = match cell {
            Some((c, m)) => lightbuf_admits(s, cached - 1, leaf, c, m),
            None => cache_admits(s, cached - 1, leaf, ray, pre, dist),
        };
        if admitted {
            work.tests += 1;
            if let Some(h) = intersect(&s.prims[cached as usize - 1], s.extra, ray, pre, dist) {
                if cell.is_some() || cache_hit_listed(s, cached - 1, ray, h.t) {
                    return V3::zero();
                }
            }
        }
    }
    let mut q = Query::shadow(dist, light);
    match cell {
        Some((c, m)) => lightbuf_traverse(s, ray, pre, &mut q, c, m, work),
        None => accel_traverse(s, ray, pre, &mut q, work),
    }
    if q.done {
        V3::zero()
    } else {
        q.trans
    }
}

/// Whether the shadow cache may answer for its blocker, primitive `i`
/// (found in BVH leaf `leaf`, `Work::shadow_leaf`), for this feeler: it
/// must not find a blocker the walk would not test. Every walk tests the
/// unbounded primitives; under the BVH a bounded one only if the feeler
/// enters its leaf (`bvh::bvh_leaf_admits`). The grid, the octree and the
/// hybrid have no such test (their walks clip the feeler to their box and
/// step cells in f32): there the cache answers only for feelers that
/// start within their box grown by its largest extent on every side, so
/// that neither the cached test nor the walk's clipping works at
/// distances whose f32 error exceeds a cell, and whose segment the walks'
/// clipping to their box keeps (docs/method.md, "Shadow cache": the fuzz
/// corpus held a feeler from a giant sphere's surface, 5·10^16 away,
/// whose f32 test of the floor polygon reported a hit the grid's walk
/// never reaches; the nff target then a feeler that passed beside a
/// cylinder 10^5 times as long as wide, whose f32 test reported a hit
/// half a unit off its surface, outside the grid's box, which the feeler
/// missed). Twin: `cache_admits` in accel.glsl.
#[inline(always)]
pub fn cache_admits<F: Real>(
    s: &SceneView,
    i: u32,
    leaf: u32,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    dist: F,
) -> bool {
    let g = s.globals;
    if (g.counts[0]..g.counts[1]).contains(&i) {
        return true;
    }
    if g.flags[1] == ACCEL_BVH {
        return bvh_leaf_admits(s, leaf, ray, pre, dist);
    }
    // The grid, the octree and the hybrid: only feelers that start within
    // the structure's box grown by its largest extent on every side (a
    // NaN origin does not), and whose segment the walks' own clipping to
    // that box keeps (a feeler that misses it meets no bounded primitive
    // in any walk).
    let ext = (0..3).fold(0f32, |e, a| e.max(g.grid_max[a] - g.grid_min[a]));
    let near = (0..3).all(|a| {
        let o = ray.o.get(a);
        o >= F::of(g.grid_min[a] - ext) && o <= F::of(g.grid_max[a] + ext)
    });
    let o = [ray.o.x, ray.o.y, ray.o.z];
    let d = [ray.d.x, ray.d.y, ray.d.z];
    let inv = [pre.inv_d.x, pre.inv_d.y, pre.inv_d.z];
    // Under the hybrid a blocker met in a crowded cell's own BVH (`leaf`
    // > 0) also needs that tree's walk to reach its leaf.
    let nested = g.flags[1] == ACCEL_HYBRID && leaf > 0;
    near && g.grid_min[3] != 0.0
        && clip_to_box(s, &o, &d, &inv, dist).is_some()
        && (!nested || bvh_leaf_admits(s, leaf, ray, pre, dist))
}

/// Whether the shadow cache may answer with its blocker's hit at `t`
/// (primitive `i`, which `cache_admits` admitted): under the grid and the
/// hybrid, only when the hit lies inside the cells that list the blocker
/// by `CACHE_HIT_MARGIN` of a cell on every axis, where the walk, which
/// steps through every cell the feeler crosses, would test it too. The
/// f32 test of a long cone can report a hit far outside the cone (the
/// `pack` fuzz target: a cylinder 10^6 times as long as wide, whose test
/// reported a hit 70 units off its axis, in cells the walk visited and
/// that do not list it). Unbounded primitives, the BVH (`bvh_leaf_admits`)
/// and the octree answer as before. Twin: `cache_hit_listed` in
/// accel.glsl.
#[inline(always)]
pub fn cache_hit_listed<F: Real>(s: &SceneView, i: u32, ray: &Ray<F>, t: F) -> bool {
    let g = s.globals;
    if (g.counts[0]..g.counts[1]).contains(&i)
        || !(g.flags[1] == ACCEL_GRID || g.flags[1] == ACCEL_HYBRID)
    {
        return true;
    }
    let prim = &s.prims[i as usize];
    let (lo, hi) = (cell_unpack(prim.cell_lo), cell_unpack(prim.cell_hi));
    let o = [ray.o.x, ray.o.y, ray.o.z];
    let d = [ray.d.x, ray.d.y, ray.d.z];
    (0..3).all(|a| {
        let m = F::of(g.grid_cell[a] * CACHE_HIT_MARGIN);
        let p = o[a] + d[a] * t;
        p >= lattice_plane::<F>(s, a, lo[a] as i32) + m
            && p <= lattice_plane::<F>(s, a, hi[a] as i32 + 1) - m
    })
}

/// Brute force over every primitive, no structure: the reference the
/// structures must equal (tests).
pub fn closest_hit_brute<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<(Hit<F>, u32)> {
    let mut q = Query::closest(tmax);
    let mut work = Work::default();
    for (i, prim) in s.prims.iter().enumerate() {
        query_prim(s, &mut q, prim, i as u32, ray, pre, &mut work);
    }
    q.hit
}

/// Brute force for a feeler: every primitive, in index order.
pub fn transmittance_brute<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    dist: F,
) -> V3<F> {
    let mut q = Query::shadow(dist, SHADOW_CACHE_LIGHTS as usize);
    let mut work = Work::default();
    for (i, prim) in s.prims.iter().enumerate() {
        if query_prim(s, &mut q, prim, i as u32, ray, pre, &mut work) {
            return V3::zero();
        }
    }
    q.trans
}
