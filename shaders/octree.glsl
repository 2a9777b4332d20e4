// Traversal of the octree: twin of src/trace/octree.rs (which explains the
// method: from the leaf holding the ray's current lattice point, where
// the ray leaves it, and the leaf across that face, found by descending
// from the deepest node on the current leaf's path that holds it; a
// closest-hit query skips the primitives the previous leaf listed too; a
// transparent blocker counts only in the leaf its hit lies in).
//
// Nodes (src/pack/octree.rs) live in cell_start, two words each: an
// interior node's first child and OCTREE_INTERIOR, or a leaf's offset
// into refs and its length. g.grid_dims.x is the lattice's side, .w the
// node count.
#ifndef WHITTED_OCTREE_GLSL
#define WHITTED_OCTREE_GLSL

#include "precise.glsl"
#include "grid.glsl"
#include "query.glsl"

// The nodes from the root to the current leaf (Rust: the walk's `path`).
uint octree_path[OCTREE_MAX_LEVELS + 1u];

// The leaf holding lattice cell p, found from the node at `level` on
// octree_path (which must hold p) down: the leaf's level, with the nodes
// down to it on octree_path; its side (in lattice cells) in `size`. False
// when the descent was cut short (lavapipe's loop budget).
bool octree_leaf(ivec3 p, inout uint level, out int size) {
    uint node = octree_path[level];
    int half_side = int(g.grid_dims.x >> (level + 1u));
    while (half_side > 0 && cell_start_at(2u * node + 1u) == OCTREE_INTERIOR) {
        work_nodes += 1u;
        uint c = ((p.x & half_side) != 0 ? 1u : 0u) | ((p.y & half_side) != 0 ? 2u : 0u)
                 | ((p.z & half_side) != 0 ? 4u : 0u);
        node = cell_start_at(2u * node) + c;
        level += 1u;
        octree_path[level] = node;
        half_side >>= 1;
    }
    size = half_side == 0 ? 1 : 2 * half_side;
    return half_side == 0 || cell_start_at(2u * node + 1u) != OCTREE_INTERIOR;
}

// Where a ray crosses a lattice plane. (A function of plain values:
// glslang's `precise` propagation, inlined into the stack walk, traced
// every pending node's history and ran out of memory.)
float octree_plane_t(float plane, float o, float inv) {
    PRECISE float t = (plane - o) * inv;
    return t;
}

// The deepest level whose node holding lattice cell a also holds b (a !=
// b; Rust: octree_common_level): L - 1 - the highest differing bit.
uint octree_common_level(uint side, ivec3 a, ivec3 b) {
    uint diff = uint((a.x ^ b.x) | (a.y ^ b.y) | (a.z ^ b.z));
    return uint(max(findMSB(side) - 1 - findMSB(diff), 0));
}

// Runs query q over leaf node's primitives (Rust: octree_leaf_query):
// lo..hi is the leaf's stretch of the ray, prev_start..prev_end the list
// of the last leaf before it that listed any, whose primitives a
// closest-hit query tested already; that becomes this leaf's list if it
// has one.
void octree_leaf_query(inout Query q, Ray ray, RayPre pre, uint node, float lo, float hi,
                       inout uint prev_start, inout uint prev_end) {
    q.lo = lo;
    q.hi = hi;
    uint start = cell_start_at(2u * node);
    uint end = start + cell_start_at(2u * node + 1u);
    uint j = prev_start;
    uint j_end = prev_end;
    if (end > start) {
        prev_start = start;
        prev_end = end;
    }
    uint k = start;
    for (; k < end; k++) {
        uint r = ref_at(k);
        if (!q.shadow) {
            while (j < j_end && ref_at(j) < r) {
                j++;
            }
            if (j < j_end && ref_at(j) == r) {
                continue;
            }
        }
        if (query_prim_kinds(q, load_prim(r), r, ray, pre, BOUNDED_KINDS)) {
            break;
        }
    }
    if (!q.done && k != end) {
        loops_cut += 1u;
    }
}

// The ray's stretch t0..t1 inside the octree's box within 0..tmax; false
// when the octree is empty or the ray misses it (Rust: octree_ray).
bool octree_clip(Ray ray, RayPre pre, float tmax, out float t0, out float t1) {
    t0 = 0.0;
    t1 = 0.0;
    return g.grid_min.w != 0.0 && clip_to_box(ray.o, ray.d, pre.inv_d, tmax, t0, t1);
}

// Walks the octree for query q: every primitive listed in the leaves the
// ray crosses, in order along the ray, until the query is done, the ray
// leaves the octree, or q.t lies inside the current leaf. The unbounded
// primitives are the caller's (accel.glsl). (Loops end with `break`: see
// grid.glsl.)
void octree_traverse(Ray ray, RayPre pre, inout Query q) {
    float t0;
    float t1;
    if (!octree_clip(ray, pre, q.t, t0, t1)) {
        return;
    }
    vec3 o = ray.o;
    vec3 d = ray.d;
    vec3 inv = pre.inv_d;
    int side = int(g.grid_dims.x);
    ivec3 step_dir = ivec3(d.x > 0.0 ? 1 : (d.x < 0.0 ? -1 : 0),
                           d.y > 0.0 ? 1 : (d.y < 0.0 ? -1 : 0),
                           d.z > 0.0 ? 1 : (d.z < 0.0 ? -1 : 0));
    ivec3 p;
    for (int i = 0; i < 3; i++) {
        PRECISE float x = o[i] + d[i] * t0;
        p[i] = lattice_cell(x, i, 0, side - 1);
    }
    float lo_t = NEG_INF;
    octree_path[0] = 0u;
    uint level = 0u;
    // The list of the previous leaf that listed any.
    uint prev_start = 0u;
    uint prev_end = 0u;
    bool ended = false;
    for (uint visited = 0u; visited < g.grid_dims.w; visited++) {
        work_cells += 1u;
        uint leaf_level = level;
        int size;
        if (!octree_leaf(p, leaf_level, size)) {
            break;
        }
        uint node = octree_path[leaf_level];
        ivec3 org = p & ivec3(~(size - 1));
        float t_exit = INF;
        int axis = 0;
        for (int i = 0; i < 3; i++) {
            if (step_dir[i] == 0) {
                continue;
            }
            int edge = step_dir[i] > 0 ? org[i] + size : org[i];
            float t = octree_plane_t(lattice_plane(i, edge), o[i], inv[i]);
            if (t < t_exit) {
                t_exit = t;
                axis = i;
            }
        }
        int across = step_dir[axis] > 0 ? org[axis] + size : org[axis] - 1;
        bool last = t_exit >= t1 || across < 0 || across >= side;
        float hi_t = last ? INF : max(t_exit, lo_t);
        octree_leaf_query(q, ray, pre, node, lo_t, hi_t, prev_start, prev_end);
        if (q.done || q.t <= t_exit || last) {
            ended = true;
            break;
        }
        for (int i = 0; i < 3; i++) {
            if (i != axis && step_dir[i] != 0) {
                PRECISE float x = o[i] + d[i] * t_exit;
                p[i] = lattice_cell(x, i, org[i], org[i] + size - 1);
            }
        }
        ivec3 from = p;
        p[axis] = across;
        level = min(octree_common_level(uint(side), from, p), leaf_level);
        lo_t = hi_t;
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

// One pending node of the stack walk (Rust: Pending).
struct OctreePending {
    uint node;
    ivec3 org;
    uint level;
    float t_in;
    float t_out;
};

OctreePending octree_stack[OCTREE_STACK_SIZE];

OctreePending octree_child(OctreePending cur, uint base, int half_side, uint bits, float t_in,
                           float t_out) {
    ivec3 b = ivec3(int(bits & 1u), int((bits >> 1) & 1u), int((bits >> 2) & 1u));
    return OctreePending(base + bits, cur.org + half_side * b, cur.level + 1u, t_in, t_out);
}

// Walks the octree for query q top down with a stack (--octree-walk
// stack; Rust: octree_traverse_stack, which explains it): at an interior
// node the children the ray passes through, in order, from where it
// crosses the mid-planes; the first walked, the others pushed.
void octree_traverse_stack(Ray ray, RayPre pre, inout Query q) {
    float t0;
    float t1;
    if (!octree_clip(ray, pre, q.t, t0, t1)) {
        return;
    }
    vec3 o = ray.o;
    vec3 d = ray.d;
    vec3 inv = pre.inv_d;
    int side = int(g.grid_dims.x);
    uint sp = 0u;
    OctreePending cur = OctreePending(0u, ivec3(0), 0u, t0, t1);
    float lo_t = NEG_INF;
    uint prev_start = 0u;
    uint prev_end = 0u;
    bool ended = false;
    for (uint visited = 0u; visited < g.grid_dims.w; visited++) {
        uint node = cur.node;
        if (cell_start_at(2u * node + 1u) == OCTREE_INTERIOR) {
            work_nodes += 1u;
            int half_side = side >> (cur.level + 1u);
            vec3 tm = vec3(INF);
            uint bits = 0u;
            for (int i = 0; i < 3; i++) {
                float plane = lattice_plane(i, cur.org[i] + half_side);
                bool upper;
                if (d[i] == 0.0) {
                    upper = o[i] >= plane;
                } else {
                    tm[i] = octree_plane_t(plane, o[i], inv[i]);
                    upper = (tm[i] <= cur.t_in) == (d[i] > 0.0);
                }
                bits |= upper ? (1u << i) : 0u;
            }
            // The planes crossed inside the stretch, in order (the lower
            // axis on a tie): three compare-and-swaps, no loop.
            int a0 = 0;
            int a1 = 1;
            int a2 = 2;
            uint m = 0u;
            bvec3 crossed = bvec3(false);
            for (int i = 0; i < 3; i++) {
                crossed[i] = d[i] != 0.0 && tm[i] > cur.t_in && tm[i] < cur.t_out;
            }
            // Keys: the crossing distance, +INF for a plane not crossed
            // (sorted last; ties keep axis order).
            vec3 key = vec3(crossed.x ? tm.x : INF, crossed.y ? tm.y : INF,
                            crossed.z ? tm.z : INF);
            if (key[a1] < key[a0]) { int t = a0; a0 = a1; a1 = t; }
            if (key[a2] < key[a1]) { int t = a1; a1 = a2; a2 = t; }
            if (key[a1] < key[a0]) { int t = a0; a0 = a1; a1 = t; }
            m = uint(crossed.x) + uint(crossed.y) + uint(crossed.z);
            uint base = cell_start_at(2u * node);
            OctreePending seq[4];
            float t = cur.t_in;
            ivec3 ord = ivec3(a0, a1, a2);
            for (uint k = 0u; k < 3u; k++) {
                if (k < m) {
                    seq[k] = octree_child(cur, base, half_side, bits, t, tm[ord[k]]);
                    bits ^= 1u << ord[k];
                    t = tm[ord[k]];
                }
            }
            seq[m] = octree_child(cur, base, half_side, bits, t, cur.t_out);
            for (int k = 3; k >= 1; k--) {
                if (uint(k) <= m) {
                    octree_stack[sp] = seq[k];
                    sp++;
                }
            }
            work_stack = max(work_stack, sp);
            cur = seq[0];
            continue;
        }
        work_cells += 1u;
        bool last = cur.t_out >= t1;
        float hi_t = last ? INF : max(cur.t_out, lo_t);
        octree_leaf_query(q, ray, pre, node, lo_t, hi_t, prev_start, prev_end);
        if (q.done || q.t <= cur.t_out || last || sp == 0u) {
            ended = true;
            break;
        }
        lo_t = hi_t;
        sp--;
        cur = octree_stack[sp];
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

#endif
