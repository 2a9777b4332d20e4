// 3D-DDA (Amanatides & Woo) through the uniform voxel grid: twin of
// src/trace/grid.rs.
//
// Closest hit keeps the best hit found so far across cells (a primitive's
// hit may lie beyond the cell that referenced it) and stops once that hit
// lies inside the current cell. Each primitive is tested once per ray: a
// primitive whose cell range holds the previous cell was already tested
// there and is skipped. (The Rust `Work` counters are not kept here.)
#ifndef WHITTED_GRID_GLSL
#define WHITTED_GRID_GLSL

#include "intersect.glsl"

// Traversal state: the current cell and where the ray leaves it.
struct Dda {
    ivec3 cell;
    ivec3 step;
    float t_end; // where the ray segment inside the grid ends
    ivec3 prev;  // cell being left last (−1: none yet)
};

// Clips the ray to the grid; false when it misses the grid or the grid is empty.
bool dda_setup(Ray ray, RayPre pre, float tmax, out Dda dda) {
    if (g.grid_min.w == 0.0) {
        return false;
    }
    vec3 lo = g.grid_min.xyz;
    vec3 hi = g.grid_max.xyz;
    float t0 = 0.0;
    float t1 = tmax;
    for (int i = 0; i < 3; i++) {
        float o = ray.o[i];
        if (ray.d[i] == 0.0) {
            if (o < lo[i] || o > hi[i]) {
                return false;
            }
            continue;
        }
        float inv = pre.inv_d[i];
        precise float ta = (lo[i] - o) * inv;
        precise float tb = (hi[i] - o) * inv;
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    if (t0 > t1) {
        return false;
    }
    vec3 cs = g.grid_cell.xyz;
    precise vec3 p = ray.o + ray.d * t0;
    for (int i = 0; i < 3; i++) {
        int n = int(g.grid_dims[i]);
        precise float c = floor((p[i] - lo[i]) / cs[i]);
        // Rust: NaN → 0, else a saturating `as i32`, then clamp(0, n − 1);
        // the same without ever converting an out-of-range float.
        int ci;
        if (isnan(c) || c <= 0.0) {
            ci = 0;
        } else if (c >= float(n - 1)) {
            ci = n - 1;
        } else {
            ci = int(c);
        }
        dda.cell[i] = ci;
        float d = ray.d[i];
        dda.step[i] = d > 0.0 ? 1 : (d < 0.0 ? -1 : 0);
    }
    dda.t_end = t1;
    dda.prev = ivec3(-1);
    return true;
}

// Distance along the ray to the far boundary of the current cell on each
// axis, computed afresh from the cell index (no accumulated error); the
// axis of the nearest one in `axis`.
float dda_exit(Ray ray, RayPre pre, Dda dda, out int axis) {
    float best = INF;
    axis = 0;
    for (int i = 0; i < 3; i++) {
        if (dda.step[i] == 0) {
            continue;
        }
        int edge = dda.cell[i] + (dda.step[i] > 0 ? 1 : 0);
        precise float bound = g.grid_min[i] + float(edge) * g.grid_cell[i];
        precise float t = (bound - ray.o[i]) * pre.inv_d[i];
        if (t < best) {
            best = t;
            axis = i;
        }
    }
    return best;
}

// Moves to the next cell along axis; false when the ray leaves the grid.
bool dda_advance(inout Dda dda, int axis) {
    dda.prev = dda.cell;
    dda.cell[axis] += dda.step[axis];
    return dda.cell[axis] >= 0 && dda.cell[axis] < int(g.grid_dims[axis]);
}

// True when the primitive was already tested in the previous cell.
bool seen_before(Prim prim, ivec3 prev) {
    if (prev.x < 0) {
        return false;
    }
    ivec3 lo = ivec3(cell_unpack(prim.cell_lo));
    ivec3 hi = ivec3(cell_unpack(prim.cell_hi));
    return all(greaterThanEqual(prev, lo)) && all(lessThanEqual(prev, hi));
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

// The nearest hit along the ray with t < tmax: the hit and the primitive index.
bool closest_hit(Ray ray, RayPre pre, float tmax, out Hit best, out uint best_prim) {
    float best_t = tmax;
    bool found = false;
    best_prim = 0xFFFFFFFFu;
    for (uint i = g.counts.x; i < g.counts.y; i++) {
        Hit h;
        if (intersect(prims[i], ray, pre, best_t, h)) {
            best_t = h.t;
            best = h;
            best_prim = i;
            found = true;
        }
    }
    Dda dda;
    if (!dda_setup(ray, pre, best_t, dda)) {
        return found;
    }
    uint max_cells = dda_max_cells();
    for (uint visited = 0u; visited < max_cells; visited++) {
        int axis;
        float t_exit = dda_exit(ray, pre, dda, axis);
        uint ci = cell_index(dda.cell);
        uint start = cell_start[ci];
        uint end = cell_start[ci + 1u];
        for (uint k = start; k < end; k++) {
            uint r = refs[k];
            Prim prim = prims[r];
            if (seen_before(prim, dda.prev)) {
                continue;
            }
            Hit h;
            if (intersect(prim, ray, pre, best_t, h)) {
                best_t = h.t;
                best = h;
                best_prim = r;
                found = true;
            }
        }
        if (best_t <= t_exit || t_exit >= dda.t_end) {
            return found;
        }
        if (!dda_advance(dda, axis)) {
            return found;
        }
    }
    return found;
}

// Light reaching the end of a shadow feeler of length dist: every primitive
// crossing it multiplies by its k_t (opaque ones give zero). Shadow feelers
// are not refracted.
vec3 transmittance(Ray ray, RayPre pre, float dist) {
    precise vec3 trans = vec3(1.0);
    for (uint i = g.counts.x; i < g.counts.y; i++) {
        Prim prim = prims[i];
        Hit h;
        if (intersect(prim, ray, pre, dist, h)) {
            trans = trans * materials[prim_material(prim)].kt.xyz;
            if (max_elem(trans) <= 0.0) {
                return vec3(0.0);
            }
        }
    }
    Dda dda;
    if (!dda_setup(ray, pre, dist, dda)) {
        return trans;
    }
    uint max_cells = dda_max_cells();
    for (uint visited = 0u; visited < max_cells; visited++) {
        int axis;
        float t_exit = dda_exit(ray, pre, dda, axis);
        uint ci = cell_index(dda.cell);
        uint start = cell_start[ci];
        uint end = cell_start[ci + 1u];
        for (uint k = start; k < end; k++) {
            Prim prim = prims[refs[k]];
            if (seen_before(prim, dda.prev)) {
                continue;
            }
            Hit h;
            if (intersect(prim, ray, pre, dist, h)) {
                trans = trans * materials[prim_material(prim)].kt.xyz;
                if (max_elem(trans) <= 0.0) {
                    return vec3(0.0);
                }
            }
        }
        if (t_exit >= dda.t_end || !dda_advance(dda, axis)) {
            return trans;
        }
    }
    return trans;
}

#endif
