// The tracer's two queries over the whole scene: twin of
// src/trace/accel.rs. Each tests the unbounded primitives (planes,
// unclipped quadrics, giants) and then walks the structure the packed
// scene carries (g.flags.y; STRUCTURE in layout.glsl): the grid (grid.glsl), the BVH (bvh.glsl) or
// the octree (octree.glsl), one traversal each serving both queries
// (query.glsl).
#ifndef WHITTED_ACCEL_GLSL
#define WHITTED_ACCEL_GLSL

#include "grid.glsl"
#include "bvh.glsl"
#include "octree.glsl"
#include "lightbuf.glsl"

// Runs query q: the unbounded primitives, then the structure in use.
void accel_traverse(Ray ray, RayPre pre, inout Query q) {
    query_unbounded(q, ray, pre);
    if (q.done) {
        return;
    }
    if (uses_accel(ACCEL_BVH)) {
        bvh_traverse(ray, pre, q);
    } else if (uses_accel(ACCEL_OCTREE)) {
        if (uses_octree_walk(OCTREE_WALK_STACK)) {
            octree_traverse_stack(ray, pre, q);
        } else {
            octree_traverse(ray, pre, q);
        }
    } else {
        grid_traverse(ray, pre, q);
    }
}

// The nearest hit along the ray with t < tmax: the hit and the primitive
// index.
bool closest_hit(Ray ray, RayPre pre, float tmax, out Hit best, out uint best_prim) {
    Query q = query_closest(tmax);
    accel_traverse(ray, pre, q);
    best = q.hit;
    best_prim = q.prim;
    return q.found;
}

// Whether the shadow cache may answer with primitive i (met in BVH leaf
// `leaf`, shadow_leaf) for this feeler: it must not find a blocker the
// walk would not test. Every walk tests the unbounded primitives; under
// the BVH a bounded one only if the feeler enters its leaf
// (bvh_leaf_admits); under the grid, the octree and the hybrid only for a
// feeler that starts within their box grown by its largest extent on
// every side and whose segment the walks' clipping to the box keeps.
// Twin of trace::accel::cache_admits.
bool cache_admits(uint i, uint leaf, Ray ray, RayPre pre, float dist) {
    if (i >= g.counts.x && i < g.counts.y) {
        return true;
    }
    if (uses_accel(ACCEL_BVH)) {
        return bvh_leaf_admits(leaf, ray, pre, dist);
    }
    PRECISE vec3 span = g.grid_max.xyz - g.grid_min.xyz;
    float ext = max(max(max(0.0, span.x), span.y), span.z);
    PRECISE vec3 lo = g.grid_min.xyz - ext;
    PRECISE vec3 hi = g.grid_max.xyz + ext;
    float t0;
    float t1;
    // Under the hybrid a blocker met in a crowded cell's own BVH (leaf >
    // 0) also needs that tree's walk to reach its leaf.
    bool nested = uses_accel(ACCEL_HYBRID) && leaf > 0u;
    return all(greaterThanEqual(ray.o, lo)) && all(lessThanEqual(ray.o, hi)) &&
           g.grid_min.w != 0.0 && clip_to_box(ray.o, ray.d, pre.inv_d, dist, t0, t1) &&
           (!nested || bvh_leaf_admits(leaf, ray, pre, dist));
}

// Whether the shadow cache may answer with its blocker's hit at t: under
// the grid and the hybrid only inside the cells that list it by
// CACHE_HIT_MARGIN of a cell on every axis. Twin of
// trace::accel::cache_hit_listed.
bool cache_hit_listed(uint i, Ray ray, float t) {
    if ((i >= g.counts.x && i < g.counts.y) ||
        !(uses_accel(ACCEL_GRID) || uses_accel(ACCEL_HYBRID))) {
        return true;
    }
    Prim prim = load_prim(i);
    bool inside = true;
    for (int a = 0; a < 3; a++) {
        uint shift = 10u * uint(a);
        int lo = int((prim.cell_lo >> shift) & 1023u);
        int hi = int((prim.cell_hi >> shift) & 1023u);
        float m = g.grid_cell[a] * CACHE_HIT_MARGIN;
        PRECISE float p = ray.o[a] + ray.d[a] * t;
        PRECISE float below = lattice_plane(a, lo) + m;
        PRECISE float above = lattice_plane(a, hi + 1) - m;
        inside = inside && p >= below && p <= above;
    }
    return inside;
}

// Light reaching the end of a shadow feeler of length dist: every primitive
// crossing it multiplies by its k_t (opaque ones give zero). Shadow feelers
// are not refracted. `light` is the light the feeler goes to (>= the light
// count: none); it indexes the shadow cache (>= SHADOW_CACHE_LIGHTS: none),
// whose primitive is tested first, and, when the scene carries light
// buffers (g.flags.w > 0), the light buffer whose cell lists the primitives
// to test. A feeler whose origin is the light's position walks the
// structure instead.
vec3 transmittance(Ray ray, RayPre pre, float dist, uint light) {
    uint res = g.flags.w;
    uint cell = 0u;
    float depth = 0.0;
    bool use_lb = false;
    if (uses_light_buffers() && res > 0u && light < g.counts.z) {
        PRECISE vec3 c = ray.o - light_at(light).pos.xyz;
        use_lb = lightbuf_cell(res, light, c, cell, depth);
    }
    uint cached = shadow_cache_on() && light < SHADOW_CACHE_LIGHTS ? shadow_cache[shadow_slot(light)] : 0u;
    if (SHADOW_CACHE && cached != 0u) {
        uint leaf = shadow_leaf[shadow_slot(light)];
        // Through a light buffer the cache answers where the walk would
        // test its blocker (lightbuf_admits); the same test then gives
        // the same answer.
        bool admitted = use_lb ? lightbuf_admits(cached - 1u, leaf, cell, depth)
                               : cache_admits(cached - 1u, leaf, ray, pre, dist);
        if (admitted) {
            work_tests += 1u;
            Hit hc;
            if (intersect(load_prim(cached - 1u), ray, pre, dist, hc) &&
                (use_lb || cache_hit_listed(cached - 1u, ray, hc.t))) {
                return vec3(0.0);
            }
        }
    }
    Query q = query_shadow(dist, light);
    if (use_lb) {
        lightbuf_traverse(ray, pre, q, cell, depth);
    } else {
        accel_traverse(ray, pre, q);
    }
    return q.done ? vec3(0.0) : q.trans;
}

#endif
