// 3D-DDA (Amanatides & Woo) through the uniform voxel grid: twin of
// src/trace/grid.rs.
//
// One traversal serves both queries (query.glsl). The closest hit keeps
// the best hit found so far across cells (a primitive's hit may lie beyond
// the cell that referenced it) and stops once that hit lies inside the
// current cell; a shadow feeler's length plays the part of that hit. Each
// primitive is tested once per ray: a primitive whose cell range holds the
// previous cell was already tested there and is skipped.
#ifndef WHITTED_GRID_GLSL
#define WHITTED_GRID_GLSL

#include "precise.glsl"
#include "query.glsl"
#include "bvh.glsl"

// Traversal state: the current cell and where the ray leaves it on each
// axis.
struct Dda {
    ivec3 cell;
    ivec3 step;
    // Distance along the ray to the current cell's far boundary plane on
    // each axis (INF for an axis the ray does not move along).
    vec3 next;
    float t_end; // where the ray segment inside the grid ends
    // The axis of the last step (3: none yet) and the cell coordinate on
    // that axis before it: the previous cell differs from the current one
    // only there.
    int prev_axis;
    int prev_coord;
    // The ray's origin, direction and 1/direction, per axis.
    vec3 o;
    vec3 d;
    vec3 inv;
};

// The plane `edge` cells from the box's lower corner on axis: a cell
// boundary of the grid, or a lattice plane of the octree (Rust:
// lattice_plane).
float lattice_plane(int axis, int edge) {
    PRECISE float plane = g.grid_min[axis] + float(edge) * g.grid_cell[axis];
    return plane;
}

// The cell holding coordinate x on axis, kept within lo..hi (a NaN gives
// lo; lo >= 0): on the positive values left after the clamp, int() is
// floor (Rust: lattice_cell).
int lattice_cell(float x, int axis, int lo, int hi) {
    PRECISE float c = (x - g.grid_min[axis]) / g.grid_cell[axis];
    if (isnan(c) || c <= float(lo)) {
        return lo;
    } else if (c >= float(hi)) {
        return hi;
    }
    return int(c);
}

// Distance to the far boundary of cell dda.cell on axis, computed afresh
// from the cell index (no error accumulates along the ray).
float dda_boundary(Dda dda, int axis) {
    int edge = dda.cell[axis] + (dda.step[axis] > 0 ? 1 : 0);
    PRECISE float t = (lattice_plane(axis, edge) - dda.o[axis]) * dda.inv[axis];
    return t;
}

// The stretch t0..t1 of the segment 0..tmax of the ray inside the
// structure's box (g.grid_min..grid_max, which the grid and the octree
// share); false when it misses the box (Rust: clip_to_box).
bool clip_to_box(vec3 o, vec3 d, vec3 inv, float tmax, out float t0, out float t1) {
    t0 = 0.0;
    t1 = tmax;
    bool missed = false;
    for (int i = 0; i < 3; i++) {
        float lo = g.grid_min[i];
        float hi = g.grid_max[i];
        if (d[i] == 0.0) {
            if (o[i] < lo || o[i] > hi) {
                missed = true;
            }
            continue;
        }
        PRECISE float ta = (lo - o[i]) * inv[i];
        PRECISE float tb = (hi - o[i]) * inv[i];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return !missed && !(t0 > t1);
}

// Clips the ray to the grid; false when it misses the grid or the grid is empty.
bool dda_setup(Ray ray, RayPre pre, float tmax, out Dda dda) {
    if (g.grid_min.w == 0.0) {
        return false;
    }
    vec3 o = ray.o;
    vec3 d = ray.d;
    vec3 inv = pre.inv_d;
    float t0;
    float t1;
    if (!clip_to_box(o, d, inv, tmax, t0, t1)) {
        return false;
    }
    dda.cell = ivec3(0);
    dda.step = ivec3(0);
    dda.next = vec3(INF);
    dda.t_end = t1;
    dda.prev_axis = 3;
    dda.prev_coord = -1;
    dda.o = o;
    dda.d = d;
    dda.inv = inv;
    for (int i = 0; i < 3; i++) {
        int n = int(g.grid_dims[i]);
        PRECISE float p = o[i] + d[i] * t0;
        dda.cell[i] = lattice_cell(p, i, 0, n - 1);
        dda.step[i] = d[i] > 0.0 ? 1 : (d[i] < 0.0 ? -1 : 0);
        if (dda.step[i] != 0) {
            dda.next[i] = dda_boundary(dda, i);
        }
    }
    return true;
}

// Where the ray leaves the current cell; the axis it crosses in `axis`.
float dda_exit(Dda dda, out int axis) {
    vec3 n = dda.next;
    if (n.x <= n.y && n.x <= n.z) {
        axis = 0;
        return n.x;
    } else if (n.y <= n.z) {
        axis = 1;
        return n.y;
    }
    axis = 2;
    return n.z;
}

// Moves to the next cell along axis; false when the ray leaves the grid.
bool dda_advance(inout Dda dda, int axis) {
    dda.prev_axis = axis;
    dda.prev_coord = dda.cell[axis];
    dda.cell[axis] += dda.step[axis];
    dda.next[axis] = dda_boundary(dda, axis);
    return dda.cell[axis] >= 0 && dda.cell[axis] < int(g.grid_dims[axis]);
}

// Empty-space distance of cell ci (0: the cell lists primitives): the bytes
// after the ncells + 1 offsets in cell_start.
uint cell_skip(uint ci) {
    uint word = cell_start_at(g.grid_dims.w + 1u + ci / 4u);
    return (word >> (8u * (ci % 4u))) & 255u;
}

// Where the ray leaves the empty cube of half-width r cells around the
// current cell; the axis it crosses in `axis`.
float dda_jump_exit(Dda dda, int r, out int axis) {
    float best = INF;
    axis = 0;
    for (int i = 0; i < 3; i++) {
        if (dda.step[i] == 0) {
            continue;
        }
        int edge = dda.step[i] > 0 ? dda.cell[i] + r + 1 : dda.cell[i] - r;
        PRECISE float t = (lattice_plane(i, edge) - dda.o[i]) * dda.inv[i];
        if (t < best) {
            best = t;
            axis = i;
        }
    }
    return best;
}

// Jumps to the cell the ray enters at t (where it leaves the empty cube of
// half-width r across axis); on the other axes the cell comes from the
// point, kept inside the cube and never behind the current cell. False
// when the ray leaves the grid.
bool dda_jump(inout Dda dda, int r, float t, int axis) {
    bool inside = true;
    for (int i = 0; i < 3; i++) {
        if (dda.step[i] == 0) {
            continue;
        }
        int c;
        if (i == axis) {
            c = dda.cell[i] + dda.step[i] * (r + 1);
        } else {
            PRECISE float p = dda.o[i] + dda.d[i] * t;
            PRECISE float f = floor((p - g.grid_min[i]) / g.grid_cell[i]);
            int lo = dda.step[i] > 0 ? dda.cell[i] : dda.cell[i] - r;
            int hi = dda.step[i] > 0 ? dda.cell[i] + r : dda.cell[i];
            if (isnan(f) || f <= float(lo)) {
                c = lo;
            } else if (f >= float(hi)) {
                c = hi;
            } else {
                c = int(f);
            }
        }
        dda.cell[i] = c;
        inside = inside && c >= 0 && c < int(g.grid_dims[i]);
    }
    dda.prev_axis = 3;
    if (inside) {
        for (int i = 0; i < 3; i++) {
            if (dda.step[i] != 0) {
                dda.next[i] = dda_boundary(dda, i);
            }
        }
    }
    return inside;
}

// True when the primitive was already tested in the previous cell. It is
// listed in the current cell, so its cell range holds the current cell; the
// previous cell differs only on the last step's axis, so checking that one
// coordinate suffices.
bool seen_before(Prim prim, Dda dda) {
    return listed_at(prim, dda.prev_axis, dda.prev_coord);
}

uint cell_index(ivec3 c) {
    uvec4 d = g.grid_dims;
    return uint(c.x) + d.x * (uint(c.y) + d.y * uint(c.z));
}

// A ray visits at most dims.x + dims.y + dims.z − 2 cells (each step moves
// one axis one cell, monotonically); the loops stop there at the latest so
// that a NaN ray cannot hang the device. Never reached by a finite ray.
uint dda_max_cells() {
    return g.grid_dims.x + g.grid_dims.y + g.grid_dims.z;
}

// Walks the grid for query q (query.glsl): every primitive listed in the
// cells the ray crosses, each once, until the query is done, the ray
// leaves the grid, or q.t (the best hit so far, or the feeler's length)
// lies inside the current cell. The unbounded primitives are the
// caller's (accel.glsl). (Loops end with `break`, never `return`: returns
// from inside nested loops miscompiled on llvmpipe 22.3 when a SIMD
// group's lanes diverge.)
void grid_traverse(Ray ray, RayPre pre, inout Query q) {
    Dda dda;
    if (!dda_setup(ray, pre, q.t, dda)) {
        return;
    }
    uint max_cells = dda_max_cells();
    bool ended = false;
    for (uint visited = 0u; visited < max_cells; visited++) {
        work_cells += 1u;
        uint ci = cell_index(dda.cell);
        uint start;
        uint end;
        int skip;
        // The cell's one reference, inline (CELLS_PAIRS).
        bool one = false;
        uint single = 0u;
        if (CELLS_PAIRS) {
            uvec2 c = uvec2(cell_start_at(2u * ci), cell_start_at(2u * ci + 1u));
            skip = c.y == 0u ? int(c.x) : 0;
            start = c.y > 1u ? c.x : 0u;
            end = c.y > 1u ? c.x + c.y : c.y;
            one = c.y == 1u;
            single = c.x;
        } else {
            start = cell_start_at(ci);
            end = cell_start_at(ci + 1u);
            skip = start == end ? int(cell_skip(ci)) : 0;
        }
        if (!NO_JUMPS && skip >= 2) {
            int jaxis;
            float t_jump = dda_jump_exit(dda, skip - 1, jaxis);
            if (q.t <= t_jump || t_jump >= dda.t_end || !dda_jump(dda, skip - 1, t_jump, jaxis)) {
                ended = true;
                break;
            }
            continue;
        }
        int axis;
        float t_exit = dda_exit(dda, axis);
        uint k = start;
        for (; k < end; k++) {
            uint r = one ? single : ref_at(k);
            if (uses_accel(ACCEL_HYBRID) && (r & HYBRID_NODE) != 0u) {
                // A crowded cell's own BVH (src/pack/hybrid.rs), its
                // leaves' primitives skipped as the list's would be.
                bvh_walk(ray, pre, q, r & ~HYBRID_NODE, true, dda.prev_axis, dda.prev_coord);
                if (q.done) {
                    break;
                }
                continue;
            }
            Prim prim = load_prim(r);
            if (seen_before(prim, dda)) {
                continue;
            }
            if (query_prim_kinds(q, prim, r, ray, pre, BOUNDED_KINDS)) {
                break;
            }
        }
        if (!q.done && k != end) {
            loops_cut += 1u;
        }
        if (q.done || q.t <= t_exit || t_exit >= dda.t_end || !dda_advance(dda, axis)) {
            ended = true;
            break;
        }
    }
    if (!ended) {
        loops_cut += 1u;
    }
}

#endif
