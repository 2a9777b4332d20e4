// Traversal of the bounding-volume hierarchy: twin of src/trace/bvh.rs.
//
// One traversal serves both queries (query.glsl). At an interior node both
// children's boxes are tested against the segment 0..q.t; the nearer child
// (by where the ray enters its box) is walked first and the other is
// pushed with its entry distance, so that a closest-hit query drops it
// when it pops it if a hit nearer than that was found meanwhile. A leaf
// hands its primitives to query_prim. The stack has BVH_STACK_SIZE
// entries, which the build's depth bound keeps enough (src/pack/bvh.rs).
#ifndef WHITTED_BVH_GLSL
#define WHITTED_BVH_GLSL

#include "precise.glsl"
#include "query.glsl"

// Where the ray enters the child's box within the segment 0..tmax (0 from
// inside) in t; false when it misses it. Slabs, the near plane chosen by
// the sign of 1/d. The bounds are narrowed by comparisons, which ignore a
// NaN: a ray parallel to an axis whose origin lies on one of the box's
// planes (0·∞) counts as inside that slab. A parallel ray outside a slab
// gets t0 = +∞: a miss unless tmax is +∞ too, then a walk for nothing,
// never a wrong skip (src/trace/bvh.rs).
bool bvh_entry(BvhChild c, Ray ray, RayPre pre, float tmax, out float t) {
    float t0 = 0.0;
    float t1 = tmax;
    for (int i = 0; i < 3; i++) {
        float o = ray.o[i];
        float inv = pre.inv_d[i];
        float near = inv >= 0.0 ? c.lo[i] : c.hi[i];
        float far = inv >= 0.0 ? c.hi[i] : c.lo[i];
        PRECISE float tn = (near - o) * inv;
        PRECISE float tf = (far - o) * inv;
        if (tn > t0) {
            t0 = tn;
        }
        if (tf < t1) {
            t1 = tf;
        }
    }
    t = t0;
    return t0 <= t1;
}

// Walks the hierarchy for query q: every leaf whose box (and whose
// ancestors' boxes) the segment 0..q.t enters, nearer children first,
// until the query is done. The unbounded primitives are the caller's
// (accel.glsl). (Loops end with `break`, never `return`: see grid.glsl.)
void bvh_traverse(Ray ray, RayPre pre, inout Query q) {
    uint nodes = g.flags.z;
    if (nodes == 0u) {
        return;
    }
    // The pushed children: their entries' indices and entry distances.
    uint stack_slot[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    uint sp = 0u;
    // The current child: the root (interior node 0) first.
    uint link = 0u;
    uint count = 0u;
    float t = 0.0;
    // Each child entry becomes the current one at most once, so a walk
    // takes at most 2·nodes + 1 steps (the bound keeps a NaN ray finite).
    uint max_steps = 2u * nodes + 1u;
    bool ended = false;
    for (uint step = 0u; step < max_steps; step++) {
        if (t <= q.t) {
            if (count > 0u) {
                uint end = link + count;
                uint i = link;
                for (; i < end; i++) {
                    if (query_prim(q, prims[i], i, ray, pre)) {
                        break;
                    }
                }
                if (q.done) {
                    ended = true;
                    break;
                }
                if (i != end) {
                    loops_cut += 1u;
                }
            } else {
                work_nodes += 1u;
                uint k = 2u * link;
                BvhChild c0 = bvh[k];
                BvhChild c1 = bvh[k + 1u];
                float t0;
                float t1;
                bool h0 = bvh_entry(c0, ray, pre, q.t, t0);
                bool h1 = bvh_entry(c1, ray, pre, q.t, t1);
                if (h0 || h1) {
                    if (h0 && h1) {
                        // Nearer first (the first child on a tie); the
                        // other waits on the stack.
                        bool second = t1 < t0;
                        stack_slot[sp] = second ? k : k + 1u;
                        stack_t[sp] = second ? t0 : t1;
                        sp += 1u;
                        h0 = !second;
                    }
                    link = h0 ? c0.link : c1.link;
                    count = h0 ? c0.count : c1.count;
                    t = h0 ? t0 : t1;
                    continue;
                }
            }
        }
        if (sp == 0u) {
            ended = true;
            break;
        }
        sp -= 1u;
        BvhChild c = bvh[stack_slot[sp]];
        link = c.link;
        count = c.count;
        t = stack_t[sp];
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

#endif
