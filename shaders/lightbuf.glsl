// Shadow feelers through a light buffer: twin of src/trace/lightbuf.rs.
// The cube of directions around each light (src/pack/lightbuf.rs): a
// feeler tests the unbounded primitives, then the primitives its
// direction's cell lists.
#ifndef WHITTED_LIGHTBUF_GLSL
#define WHITTED_LIGHTBUF_GLSL

#include "precise.glsl"
#include "query.glsl"

// The index along a face's side of coordinate u (in [-1, 1]) at res
// cells: floor((u + 1)·0.5·res), at most res - 1.
uint lightbuf_index(float u, uint res) {
    PRECISE float x = (u + 1.0) * 0.5 * float(res);
    uint i = uint(max(int(x), 0));
    return min(i, res - 1u);
}

// The cell of light `light`'s buffer (resolution res) that direction c
// (from the light towards the feeler's origin) falls in; false when c has
// no dominant component (zero, infinite or NaN). The dominant axis is x on
// ties with y or z, then y on a tie with z.
bool lightbuf_cell(uint res, uint light, vec3 c, out uint cell) {
    float ax = abs(c.x);
    float ay = abs(c.y);
    float az = abs(c.z);
    uint axis;
    float m;
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
    uint iu = lightbuf_index(un, res);
    uint iv = lightbuf_index(vn, res);
    cell = ((light * 6u + face) * res + iv) * res + iu;
    return true;
}

// Runs shadow query q over the unbounded primitives, then the primitives
// light buffer cell `cell` lists.
void lightbuf_traverse(Ray ray, RayPre pre, inout Query q, uint cell) {
    query_unbounded(q, ray, pre);
    if (q.done) {
        return;
    }
    work_cells += 1u;
    uint start = lb_start_at(cell);
    uint end = lb_start_at(cell + 1u);
    uint k = start;
    for (; k < end; k++) {
        uint r = lb_ref_at(k);
        if (query_prim(q, load_prim(r), r, ray, pre)) {
            break;
        }
    }
    if (!q.done && k != end) {
        loops_cut += 1u;
    }
}

#endif
