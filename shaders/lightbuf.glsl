// Shadow feelers through a light buffer: twin of src/trace/lightbuf.rs.
// The cube of directions around each light (src/pack/lightbuf.rs), each
// face's cells spread over its window: a feeler tests the unbounded
// primitives, then the primitives its direction's cell lists, nearest the
// light first, up to the depth of its own origin.
#ifndef WHITTED_LIGHTBUF_GLSL
#define WHITTED_LIGHTBUF_GLSL

#include "precise.glsl"
#include "query.glsl"

// No cell lists anything there: the feeler's direction lies outside its
// face's window (Rust: lightbuf::EMPTY).
const uint LB_EMPTY = 0xFFFFFFFFu;

// The shadow cache's leaf (shadow_leaf) of a blocker met through a light
// buffer: this bit and 1 + the reference's index in lb_refs' pairs (no
// BVH slot has it: bvh_leaf_admits turns it away). Rust: lightbuf::LB_LEAF.
const uint LB_LEAF = 0x80000000u;

// Whether the shadow cache may answer for its blocker, primitive i
// (cached with leaf), for a feeler in light buffer cell `cell` at depth
// m: an unbounded primitive always, a bounded one when it was met through
// a light buffer at a reference of this cell that the walk reaches (its
// depth not past m). Twin of trace::lightbuf::lightbuf_admits.
bool lightbuf_admits(uint i, uint leaf, uint cell, float m) {
    if (i >= g.counts.x && i < g.counts.y) {
        return true;
    }
    if (cell == LB_EMPTY || (leaf & LB_LEAF) == 0u || leaf == LB_LEAF) {
        return false;
    }
    uint k = (leaf & ~LB_LEAF) - 1u;
    return k >= lb_start_at(cell) && k < lb_start_at(cell + 1u) && lb_ref_at(2u * k) == i &&
           uintBitsToFloat(lb_ref_at(2u * k + 1u)) <= m;
}

// The index along a face's side of coordinate u under the face's window
// (origin o, sc cells per unit) at res cells; false more than a cell
// outside it (or an empty face, sc = 0).
bool lightbuf_index(float u, float o, float sc, uint res, out uint i) {
    PRECISE float x = (u - o) * sc;
    i = 0u;
    if (!(x >= -1.0 && x < float(res) + 1.0) || sc == 0.0) {
        return false;
    }
    i = min(uint(max(int(x), 0)), res - 1u);
    return true;
}

// The cell of light `light`'s buffer (resolution res) that direction c
// (from the light towards the feeler's origin) falls in (LB_EMPTY outside
// the face's window), and in m the depth of the feeler's origin along
// that face's axis; false when c has no dominant component (zero,
// infinite or NaN). The dominant axis is x on ties with y or z, then y on
// a tie with z.
bool lightbuf_cell(uint res, uint light, vec3 c, out uint cell, out float m) {
    float ax = abs(c.x);
    float ay = abs(c.y);
    float az = abs(c.z);
    uint axis;
    float u;
    float v;
    bool neg;
    if (ax >= ay && ax >= az) {
        axis = 0u;
        m = ax;
        u = c.y;
        v = c.z;
        neg = c.x < 0.0;
    } else if (ay >= az) {
        axis = 1u;
        m = ay;
        u = c.z;
        v = c.x;
        neg = c.y < 0.0;
    } else {
        axis = 2u;
        m = az;
        u = c.x;
        v = c.y;
        neg = c.z < 0.0;
    }
    cell = 0u;
    if (!(m > 0.0) || isinf(m)) {
        return false;
    }
    uint face = axis * 2u + (neg ? 1u : 0u);
    PRECISE float un = u / m;
    PRECISE float vn = v / m;
    // The face's window: after the cells' offsets, four words a face.
    uint w = g.counts.z * 6u * res * res + 1u + (light * 6u + face) * 4u;
    uint iu;
    uint iv;
    bool inu = lightbuf_index(un, uintBitsToFloat(lb_start_at(w)),
                              uintBitsToFloat(lb_start_at(w + 1u)), res, iu);
    bool inv = lightbuf_index(vn, uintBitsToFloat(lb_start_at(w + 2u)),
                              uintBitsToFloat(lb_start_at(w + 3u)), res, iv);
    cell = inu && inv ? ((light * 6u + face) * res + iv) * res + iu : LB_EMPTY;
    return true;
}

// Runs shadow query q over the unbounded primitives, then the primitives
// light buffer cell `cell` lists, nearest the light first (a pair a
// reference: the primitive, the bits of its least depth), up to the
// feeler's origin's depth m.
void lightbuf_traverse(Ray ray, RayPre pre, inout Query q, uint cell, float m) {
    query_unbounded(q, ray, pre);
    if (q.done || cell == LB_EMPTY) {
        return;
    }
    work_cells += 1u;
    uint start = lb_start_at(cell);
    uint end = lb_start_at(cell + 1u);
    uint k = start;
    bool deeper = false;
    for (; k < end; k++) {
        if (uintBitsToFloat(lb_ref_at(2u * k + 1u)) > m) {
            deeper = true;
            break;
        }
        uint r = lb_ref_at(2u * k);
        if (query_prim(q, load_prim(r), r, ray, pre)) {
            // The blocker's reference, for the shadow cache
            // (lightbuf_admits).
            if (SHADOW_CACHE && shadow_cache_on() && q.light < SHADOW_CACHE_LIGHTS &&
                shadow_cache[shadow_slot(q.light)] == r + 1u && k + 1u < LB_LEAF) {
                shadow_leaf[shadow_slot(q.light)] = LB_LEAF | (k + 1u);
            }
            break;
        }
    }
    if (!q.done && !deeper && k != end) {
        loops_cut += 1u;
    }
}

#endif
