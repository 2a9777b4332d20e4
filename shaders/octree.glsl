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
    while (half_side > 0 && cell_start[2u * node + 1u] == OCTREE_INTERIOR) {
        work_nodes += 1u;
        uint c = ((p.x & half_side) != 0 ? 1u : 0u) | ((p.y & half_side) != 0 ? 2u : 0u)
                 | ((p.z & half_side) != 0 ? 4u : 0u);
        node = cell_start[2u * node] + c;
        level += 1u;
        octree_path[level] = node;
        half_side >>= 1;
    }
    size = half_side == 0 ? 1 : 2 * half_side;
    return half_side == 0 || cell_start[2u * node + 1u] != OCTREE_INTERIOR;
}

// The deepest level whose node holding lattice cell a also holds b (a !=
// b; Rust: octree_common_level): L - 1 - the highest differing bit.
uint octree_common_level(uint side, ivec3 a, ivec3 b) {
    uint diff = uint((a.x ^ b.x) | (a.y ^ b.y) | (a.z ^ b.z));
    return uint(max(findMSB(side) - 1 - findMSB(diff), 0));
}

// The lattice cell holding coordinate x on axis, kept within lo..hi (a
// NaN gives lo).
int octree_lattice_cell(float x, int axis, int lo, int hi) {
    PRECISE float c = (x - g.grid_min[axis]) / g.grid_cell[axis];
    if (isnan(c) || c <= float(lo)) {
        return lo;
    } else if (c >= float(hi)) {
        return hi;
    }
    return int(c);
}

// Walks the octree for query q: every primitive listed in the leaves the
// ray crosses, in order along the ray, until the query is done, the ray
// leaves the octree, or q.t lies inside the current leaf. The unbounded
// primitives are the caller's (accel.glsl). (Loops end with `break`: see
// grid.glsl.)
void octree_traverse(Ray ray, RayPre pre, inout Query q) {
    if (g.grid_min.w == 0.0) {
        return;
    }
    vec3 o = ray.o;
    vec3 d = ray.d;
    vec3 inv = pre.inv_d;
    float t0;
    float t1;
    if (!clip_to_box(o, d, inv, q.t, t0, t1)) {
        return;
    }
    int side = int(g.grid_dims.x);
    ivec3 step_dir = ivec3(d.x > 0.0 ? 1 : (d.x < 0.0 ? -1 : 0),
                           d.y > 0.0 ? 1 : (d.y < 0.0 ? -1 : 0),
                           d.z > 0.0 ? 1 : (d.z < 0.0 ? -1 : 0));
    ivec3 p;
    for (int i = 0; i < 3; i++) {
        PRECISE float x = o[i] + d[i] * t0;
        p[i] = octree_lattice_cell(x, i, 0, side - 1);
    }
    float lo_t = NEG_INF;
    octree_path[0] = 0u;
    uint level = 0u;
    // The previous leaf's list.
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
            PRECISE float plane = g.grid_min[i] + float(edge) * g.grid_cell[i];
            PRECISE float t = (plane - o[i]) * inv[i];
            if (t < t_exit) {
                t_exit = t;
                axis = i;
            }
        }
        int across = step_dir[axis] > 0 ? org[axis] + size : org[axis] - 1;
        bool last = t_exit >= t1 || across < 0 || across >= side;
        float hi_t = last ? INF : max(t_exit, lo_t);
        q.lo = lo_t;
        q.hi = hi_t;
        uint start = cell_start[2u * node];
        uint end = start + cell_start[2u * node + 1u];
        uint j = prev_start;
        uint k = start;
        for (; k < end; k++) {
            uint r = refs[k];
            // Listed in the previous leaf too (both lists ascend): a
            // closest-hit query tested it there.
            if (!q.shadow) {
                while (j < prev_end && refs[j] < r) {
                    j++;
                }
                if (j < prev_end && refs[j] == r) {
                    continue;
                }
            }
            if (query_prim(q, prims[r], r, ray, pre)) {
                break;
            }
        }
        prev_start = start;
        prev_end = end;
        if (!q.done && k != end) {
            loops_cut += 1u;
        }
        if (q.done || q.t <= t_exit || last) {
            ended = true;
            break;
        }
        for (int i = 0; i < 3; i++) {
            if (i != axis && step_dir[i] != 0) {
                PRECISE float x = o[i] + d[i] * t_exit;
                p[i] = octree_lattice_cell(x, i, org[i], org[i] + size - 1);
            }
        }
        ivec3 prev = p;
        p[axis] = across;
        level = min(octree_common_level(uint(side), prev, p), leaf_level);
        lo_t = hi_t;
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

#endif
