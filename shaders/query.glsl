// The two questions a traversal answers, and what it does with each
// primitive it reaches: twin of src/trace/query.rs.
//
// Every acceleration structure has one traversal (grid_traverse,
// bvh_traverse, octree_traverse) that serves both queries: it hands each primitive to
// query_prim and bounds its walk by Query.t. For the closest hit t is the
// best hit so far and shrinks with every hit; for a shadow feeler (any
// hit, with the transmittance of every transparent blocker) it is the
// feeler's length and stays, and the walk stops once an opaque blocker has
// made the light zero (Query.done). (The Rust Work counters are not kept
// here; its shadow cache is.)
#ifndef WHITTED_QUERY_GLSL
#define WHITTED_QUERY_GLSL

#include "precise.glsl"
#include "intersect.glsl"

// Shadow cache (Rust: Work::shadow_cache): per level of the ray tree and
// per light (level * SHADOW_CACHE_LIGHTS + light), 1 + the index of the
// opaque primitive that last blocked a feeler to it from that level (0:
// none). It never changes a result; reset per invocation
// (shadow_cache_reset). shadow_level is the level feelers use now
// (Rust: Work::level, set by shadow_cache_at_depth). Beside each entry,
// shadow_leaf: the BVH leaf the walk met the blocker in, 1 + node *
// BVH_WIDTH + lane (0: none; Rust: Work::shadow_leaf), which
// transmittance checks before it answers (accel.glsl, cache_admits).
uint shadow_cache[SHADOW_CACHE_LEVELS * SHADOW_CACHE_LIGHTS];
uint shadow_leaf[SHADOW_CACHE_LEVELS * SHADOW_CACHE_LIGHTS];
uint shadow_level = 0u;

// lavapipe (llvmpipe 22.3) gives each SIMD group of invocations a budget
// of 65535 loop iterations for the whole shader, then silently runs every
// loop once (LP_MAX_TGSI_LOOP_ITERATIONS). Each traversal loop that ends
// without reaching its own end counts here; render.comp adds them up and
// the host refuses an image in which any loop was cut. (GPU only: the CPU
// has no such budget.)
uint loops_cut = 0u;

// Work counters, twins of trace::query::Work's (primitive tests, grid
// cells or octree leaves, BVH or octree interior nodes), counted at the same places; render.comp adds
// them up per subgroup and the host reads them into Frame::work.
uint work_tests = 0u;
uint work_cells = 0u;
uint work_nodes = 0u;
// Their shares: the eye rays' closest hits and the shadow feelers'
// (Work::eye, Work::shadow), credited around the same queries as on the
// CPU (Work::credit_eye, credit_shadow); and the deepest a structure walk's stack went
// (Work::stack).
uvec3 work_eye = uvec3(0u);
uvec3 work_shadow = uvec3(0u);
uint work_stack = 0u;

// The three counters as they stand (Work::totals).
uvec3 work_totals() {
    return uvec3(work_tests, work_cells, work_nodes);
}

void shadow_cache_reset() {
    for (uint i = 0u; i < SHADOW_CACHE_LEVELS * SHADOW_CACHE_LIGHTS; i++) {
        shadow_cache[i] = 0u;
        shadow_leaf[i] = 0u;
    }
    shadow_level = 0u;
}

// Feelers from now on are cast from the hit of a ray of `depth` (Rust:
// Work::at_depth).
void shadow_cache_at_depth(uint depth) {
    shadow_level = min(depth, SHADOW_CACHE_LEVELS - 1u);
}

// The shadow cache's slot for light (< SHADOW_CACHE_LIGHTS) at the
// current level.
uint shadow_slot(uint light) {
    return shadow_level * SHADOW_CACHE_LIGHTS + light;
}

// One query in progress.
struct Query {
    // Hits count only below this distance: the best hit so far (closest
    // hit), or the feeler's length (shadow).
    float t;
    // Any hit (a shadow feeler) rather than the closest.
    bool shadow;
    // Shadow: the light's slot in the shadow cache (>= SHADOW_CACHE_LIGHTS:
    // none).
    uint light;
    // Closest hit: the best hit and its primitive (found: any).
    bool found;
    Hit hit;
    uint prim;
    // Primitives are asked for hits below this: t until a hit is found
    // (and always for a feeler), then next_up of the best hit's distance,
    // so that a hit at the same distance (a tie) is seen.
    float bound;
    // Closest hit: the best hit's rank (prim_rank); a tie goes to the lower.
    uint rank;
    // Shadow: the product of the k_t of the blockers found so far.
    vec3 trans;
    // Shadow: an opaque blocker was found (the walk may stop).
    bool done;
    // Shadow: a blocker that lets light through counts only where its hit
    // lies in lo..hi (everywhere but under the octree, whose walk sets its
    // current leaf's stretch of the feeler: octree.glsl).
    float lo;
    float hi;
};

// The nearest hit below tmax.
Query query_closest(float tmax) {
    return Query(tmax, false, SHADOW_CACHE_LIGHTS, false, Hit(0.0, 0.0, 0.0), 0xFFFFFFFFu,
                 tmax, 0xFFFFFFFFu, vec3(1.0), false, -INF, INF);
}

// The light left at the end of a feeler of length dist towards light.
Query query_shadow(float dist, uint light) {
    return Query(dist, true, light, false, Hit(0.0, 0.0, 0.0), 0xFFFFFFFFu, dist, 0xFFFFFFFFu,
                 vec3(1.0), false, -INF, INF);
}

// Where primitive i stands when two are hit at the same distance: its
// index in the grid's packing order (Rust: trace::query::rank). Under the
// grid that is i; the BVH keeps it in cell_lo.
uint prim_rank(Prim prim, uint i) {
    return uses_accel(ACCEL_BVH) ? prim.cell_lo : i;
}

// The least float above t >= 0 (+INF stays): Rust's f32::next_up there.
float next_up(float t) {
    return t < INF ? uintBitsToFloat(floatBitsToUint(t) + 1u) : t;
}

// Tests prim (primitive i) for query q; true when the query is done (an
// opaque blocker for a feeler: nothing further can change the answer).
// Of two primitives hit at the same distance, the closest hit is the one
// of lower rank, whatever order the structure walks them in.
// `kinds`: the kinds prim can be (BOUNDED_KINDS in the walks).
bool query_prim_kinds(inout Query q, Prim prim, uint i, Ray ray, RayPre pre, uint kinds) {
    work_tests += 1u;
    Hit h;
    if (intersect_kinds(prim, ray, pre, q.bound, h, kinds)) {
        if (q.shadow) {
            // Without FEAT_REFRACT no material lets light through (every
            // k_t is 0): no read of the materials, a per-lane loop on
            // llvmpipe that every test ran, masked.
            vec3 kt = HAS_REFRACT ? material_at(prim_material(prim)).kt.xyz : vec3(0.0);
            if (max_elem(kt) > 0.0 && !(h.t >= q.lo && h.t < q.hi)) {
                return false;
            }
            PRECISE vec3 trans = q.trans * kt;
            q.trans = trans;
            if (shadow_cache_on() && max_elem(kt) <= 0.0 && q.light < SHADOW_CACHE_LIGHTS) {
                shadow_cache[shadow_slot(q.light)] = i + 1u;
                // The BVH's walk names the leaf (bvh.glsl, bvh_walk).
                shadow_leaf[shadow_slot(q.light)] = 0u;
            }
            if (max_elem(q.trans) <= 0.0) {
                q.done = true;
            }
        } else {
            // h.t <= q.t: nearer, or a tie.
            uint r = prim_rank(prim, i);
            if (h.t < q.t || r < q.rank) {
                q.t = h.t;
                q.bound = next_up(h.t);
                q.rank = r;
                q.found = true;
                q.hit = h;
                q.prim = i;
            }
        }
    }
    return q.done;
}

bool query_prim(inout Query q, Prim prim, uint i, Ray ray, RayPre pre) {
    return query_prim_kinds(q, prim, i, ray, pre, 0xFFFFFFFFu);
}

// Runs query q over the unbounded primitives (planes, unclipped quadrics,
// giants), which every ray and feeler tests before any walk; afterwards
// q.done says whether the query is done. (The loop ends with `break`:
// see grid.glsl.)
void query_unbounded(inout Query q, Ray ray, RayPre pre) {
    if (NO_UNBOUNDED) {
        return;
    }
    for (uint i = g.counts.x; i < g.counts.y; i++) {
        if (query_prim_kinds(q, load_prim(i), i, ray, pre, UNBOUNDED_KINDS)) {
            break;
        }
    }
}

#endif
