// Traversal of the bounding-volume hierarchy: twin of src/trace/bvh.rs.
//
// One traversal serves both queries (query.glsl). At a node the boxes of
// its (up to four) children are tested against the segment 0..q.t, four
// lanes at once (bvh_entries); the children the ray enters are ordered by
// where it enters them (lane order on a tie; a shadow feeler takes them
// in lane order), the nearest is walked first
// and the others are pushed, farthest first, with their entry distances,
// so that a closest-hit query drops one when it pops it if a hit nearer
// than that was found meanwhile. A leaf hands its primitives to
// query_prim. The stack has BVH_STACK_SIZE entries, which the build keeps
// enough (src/pack/bvh.rs, collapse). No loop runs inside a node visit
// (the ordering is a sorting network, the pushes straight-line code):
// llvmpipe counts every loop iteration against one budget (query.glsl).
#ifndef WHITTED_BVH_GLSL
#define WHITTED_BVH_GLSL

#include "precise.glsl"
#include "query.glsl"

// Where the ray enters each child's box within the segment 0..tmax (0
// from inside) in te, and which boxes it enters. Slabs, the near plane
// chosen by the sign of 1/d. The bounds are narrowed by comparisons, which
// ignore a NaN: a ray parallel to an axis whose origin lies on one of the
// box's planes (0·∞) counts as inside that slab. A parallel ray outside a
// slab gets t0 = +∞: a miss unless tmax is +∞ too, then a walk for
// nothing, never a wrong skip (src/trace/bvh.rs). `mix` with a bvec
// selects, it does no arithmetic.
bvec4 bvh_entries(BvhNode n, Ray ray, RayPre pre, float tmax, out vec4 te) {
    vec4 t0 = vec4(0.0);
    vec4 t1 = vec4(tmax);
    for (int i = 0; i < 3; i++) {
        float o = ray.o[i];
        float inv = pre.inv_d[i];
        vec4 near = inv >= 0.0 ? n.lo[i] : n.hi[i];
        vec4 far = inv >= 0.0 ? n.hi[i] : n.lo[i];
        PRECISE vec4 tn = (near - o) * inv;
        PRECISE vec4 tf = (far - o) * inv * BVH_EXIT_WIDEN;
        t0 = mix(t0, tn, greaterThan(tn, t0));
        t1 = mix(t1, tf, lessThan(tf, t1));
    }
    te = t0;
    return lessThanEqual(t0, t1);
}

// One comparator of the sorting network: (ta, ka) before (tb, kb) by t,
// then by key.
void bvh_order2(inout float ta, inout uint ka, inout float tb, inout uint kb) {
    bool swap = tb < ta || (tb == ta && kb < ka);
    float t = ta;
    uint k = ka;
    ta = swap ? tb : ta;
    ka = swap ? kb : ka;
    tb = swap ? t : tb;
    kb = swap ? k : kb;
}

// The link and count of child `slot` (node · BVH_WIDTH + lane), one
// word in the device's nodes (layout.glsl, bvh_children).
void bvh_child(uint slot, out uint link, out uint count) {
    uint child = bvh_children(slot / BVH_WIDTH)[slot % BVH_WIDTH];
    link = child & BVH_LINK_MASK;
    count = child >> BVH_COUNT_SHIFT;
}

// True when prim's cell range (the grid's, Prim.cell_lo/cell_hi) holds
// coordinate coord on axis (axis 3: none): the grid's previous cell
// listed it (grid.glsl, seen_before; Rust: trace::grid::seen_before).
bool listed_at(Prim prim, int axis, int coord) {
    if (axis > 2) {
        return false;
    }
    uint shift = 10u * uint(axis);
    int lo = int((prim.cell_lo >> shift) & 1023u);
    int hi = int((prim.cell_hi >> shift) & 1023u);
    return coord >= lo && coord <= hi;
}

// Walks the hierarchy whose root is node `root` for query q: every leaf
// whose box (and whose ancestors' boxes) the segment 0..q.t enters,
// nearer children first, until the query is done (q.done). A leaf's
// entries are link..link + count: the primitives themselves, or, when
// `nested` (a crowded grid cell's own BVH under the hybrid:
// src/pack/hybrid.rs), indices into refs, skipping a primitive the
// grid's previous cell (prev_axis, prev_coord) listed. Twin of
// trace::bvh::bvh_walk. (Loops end with `break`, never `return`: see
// grid.glsl.)
void bvh_walk(Ray ray, RayPre pre, inout Query q, uint root, bool nested, int prev_axis,
              int prev_coord) {
    uint nodes = g.flags.z;
    if (nodes == 0u) {
        return;
    }
    // The pushed children: node · BVH_WIDTH + lane, and entry distances.
    // A feeler's distances are all 0 (it keeps none, as on the CPU), so
    // its walk neither writes nor reads stack_t: q.shadow is a constant
    // in each inlined copy, and llvmpipe's private array, written and
    // read lane by lane at a varying index, is left out of the feelers'
    // walks (docs/profiling.md, "Feelers without entry distances").
    uint stack_slot[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    uint sp = 0u;
    // The current child: the root first; slot: 1 + its node * BVH_WIDTH
    // + lane (0 for the root), which names a leaf to the shadow cache.
    uint link = root;
    uint count = 0u;
    uint slot = 0u;
    float t = 0.0;
    // Two phases a round, each its own loop (the "while-while" of Aila
    // & Laine, 2009): node visits until the current child is a leaf to
    // test, then that leaf's primitives. llvmpipe runs its 8 lanes in
    // lock-step and both sides of every branch, masked: with one loop
    // whose step was a node visit or one primitive, every step ran both
    // the node's code and the primitive test's (for gears, a polygon's).
    // Now a node visit runs no primitive test and a test no node visit;
    // lanes wait at each phase's end for the others instead (SPD gears
    // 10 %, rings and balls 3 % less device time; docs/profiling.md).
    // The order of tests is the CPU's (which tests a leaf in an inner
    // loop), so every result and counter is the same. A node visit and a
    // primitive each count one step: each child becomes the current one
    // at most once and each primitive lies in one leaf, so a walk takes at
    // most BVH_WIDTH·nodes + 1 + the bounded primitives' count steps (the
    // bound keeps a NaN ray finite).
    uint max_steps = BVH_WIDTH * nodes + 1u + g.counts.x;
    bool ended = false;
    uint step = 0u;
    while (step < max_steps) {
        // Phase 1: node visits and pops until the current child is a leaf
        // to test (found) or the walk is over.
        bool found = false;
        for (; step < max_steps; step++) {
            if (count > 0u && t <= q.t) {
                found = true;
                break;
            }
            bool next = true;
            if (count == 0u && t <= q.t) {
                work_nodes += 1u;
                BvhNode n = bvh_node(link);
                vec4 te;
                bvec4 hit = bvh_entries(n, ray, pre, q.t, te);
                // Lanes entered (not empty ones) keep their distance and
                // key = lane; the others sort last (+∞, lane + 4).
                bvec4 real = notEqual(n.count | n.link, uvec4(0u));
                bvec4 enter = bvec4(uvec4(hit) & uvec4(real));
                uint m = uint(enter.x) + uint(enter.y) + uint(enter.z) + uint(enter.w);
                if (m > 0u) {
                    // A feeler takes them in lane order (all at distance
                    // 0: its segment never shrinks, so the order cannot
                    // save a test): the entered lanes' bits, lowest
                    // first, with no sorting network (lavapipe: gears
                    // 3 %, rings 1 % less device time). A closest-hit
                    // query sorts them by entry distance.
                    float s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
                    uint k0, k1, k2, k3;
                    if (q.shadow) {
                        uint bits = uint(enter.x) | uint(enter.y) << 1u |
                                    uint(enter.z) << 2u | uint(enter.w) << 3u;
                        k0 = uint(findLSB(bits));
                        bits &= bits - 1u;
                        k1 = uint(findLSB(bits));
                        bits &= bits - 1u;
                        k2 = uint(findLSB(bits));
                        bits &= bits - 1u;
                        k3 = uint(findLSB(bits));
                    } else {
                        float inf = uintBitsToFloat(0x7f800000u);
                        s0 = enter.x ? te.x : inf;
                        s1 = enter.y ? te.y : inf;
                        s2 = enter.z ? te.z : inf;
                        s3 = enter.w ? te.w : inf;
                        k0 = enter.x ? 0u : 4u;
                        k1 = enter.y ? 1u : 5u;
                        k2 = enter.z ? 2u : 6u;
                        k3 = enter.w ? 3u : 7u;
                        bvh_order2(s0, k0, s1, k1);
                        bvh_order2(s2, k2, s3, k3);
                        bvh_order2(s0, k0, s2, k2);
                        bvh_order2(s1, k1, s3, k3);
                        bvh_order2(s1, k1, s2, k2);
                    }
                    uint base = link * BVH_WIDTH;
                    if (m > 3u) {
                        stack_slot[sp] = base + k3;
                        if (!q.shadow) {
                            stack_t[sp] = s3;
                        }
                        sp += 1u;
                    }
                    if (m > 2u) {
                        stack_slot[sp] = base + k2;
                        if (!q.shadow) {
                            stack_t[sp] = s2;
                        }
                        sp += 1u;
                    }
                    if (m > 1u) {
                        stack_slot[sp] = base + k1;
                        if (!q.shadow) {
                            stack_t[sp] = s1;
                        }
                        sp += 1u;
                    }
                    work_stack = max(work_stack, sp);
                    link = n.link[k0];
                    count = n.count[k0];
                    slot = 1u + base + k0;
                    t = s0;
                    next = false;
                }
            }
            // The node entered no child, or the current child is a leaf
            // beyond q.t: the next pushed child.
            if (next) {
                if (sp == 0u) {
                    ended = true;
                    break;
                }
                sp -= 1u;
                slot = 1u + stack_slot[sp];
                bvh_child(stack_slot[sp], link, count);
                t = q.shadow ? 0.0 : stack_t[sp];
            }
        }
        if (!found) {
            break;
        }
        // Phase 2: the leaf's primitives. It was entered (t <= q.t then),
        // so it is finished even if a hit nearer than t is found
        // meanwhile.
        for (; count > 0u && step < max_steps; step++) {
            uint i = nested ? ref_at(link) : link;
            Prim prim = load_prim(i);
            if (!(nested && listed_at(prim, prev_axis, prev_coord)) &&
                query_prim_kinds(q, prim, i, ray, pre, BOUNDED_KINDS)) {
                if (SHADOW_CACHE && q.shadow && q.light < SHADOW_CACHE_LIGHTS &&
                    shadow_cache[shadow_slot(q.light)] == i + 1u) {
                    shadow_leaf[shadow_slot(q.light)] = slot;
                }
                ended = true;
                break;
            }
            link += 1u;
            count -= 1u;
        }
        // Done, or out of steps (count > 0: the bound, never reached by a
        // finite ray), or on to the next pushed child.
        if (ended || count > 0u) {
            break;
        }
        if (sp == 0u) {
            ended = true;
            break;
        }
        sp -= 1u;
        slot = 1u + stack_slot[sp];
        bvh_child(stack_slot[sp], link, count);
        t = q.shadow ? 0.0 : stack_t[sp];
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

// Whether the walk for a feeler (segment 0..tmax) would reach the leaf
// `slot` (1 + node * BVH_WIDTH + lane; 0: none): the leaf's box tested as
// the walk tests it. Every ancestor's box holds the leaf's in f32, and the
// slab arithmetic is monotone, so a feeler that enters the leaf's box
// entered theirs. The shadow cache asks this before it answers for a
// primitive of the BVH (accel.glsl, transmittance): an f32 test of a
// primitive far from the ray's origin may report a hit its boxes rule
// out. Twin of trace::bvh::bvh_leaf_admits (which also turns away the
// rays the CPU's walk turns away; here the walk takes them, as this does).
bool bvh_leaf_admits(uint slot, Ray ray, RayPre pre, float tmax) {
    if (slot == 0u || slot - 1u >= BVH_WIDTH * g.flags.z) {
        return false;
    }
    uint at = slot - 1u;
    vec4 te;
    bvec4 hit = bvh_entries(bvh_node(at / BVH_WIDTH), ray, pre, tmax, te);
    return hit[at % BVH_WIDTH];
}

// The unbounded primitives are the caller's (accel.glsl).
void bvh_traverse(Ray ray, RayPre pre, inout Query q) {
    bvh_walk(ray, pre, q, 0u, false, 3, -1);
}

#endif
