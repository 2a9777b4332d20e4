// Ray-primitive intersection: twin of src/trace/intersect.rs.
//
// Each routine returns true for the nearest hit with 0 < t < tmax and
// writes it to `h` (left unwritten on a miss). Secondary-ray origins are
// offset off the surface by the caller, so t > 0 is the only lower bound.
// Every primitive kind is guarded by its HAS_* constant.
#ifndef WHITTED_INTERSECT_GLSL
#define WHITTED_INTERSECT_GLSL

#include "precise.glsl"
#include "layout.glsl"
#include "math.glsl"

// Distance t and two parameters whose meaning depends on the kind
// (triangle: barycentric weights of v0 and v1; box: axis and side).
struct Hit {
    float t;
    float u;
    float v;
};

// Per-ray values computed once: the watertight triangle test's shear and
// axis permutation, and 1/d for the slabs.
struct RayPre {
    int kx;
    int ky;
    int kz;
    float sx;
    float sy;
    float sz;
    vec3 inv_d;
};

RayPre ray_pre(vec3 d) {
    vec3 ad = abs(d);
    int kz = 0;
    if (ad.y > ad.x) {
        kz = 1;
    }
    if (ad.z > ad[kz]) {
        kz = 2;
    }
    int kx = (kz + 1) % 3;
    int ky = (kx + 1) % 3;
    if (d[kz] < 0.0) {
        int tmp = kx;
        kx = ky;
        ky = tmp;
    }
    PRECISE float dz = d[kz];
    RayPre pre;
    pre.kx = kx;
    pre.ky = ky;
    pre.kz = kz;
    PRECISE float sx = d[kx] / dz;
    PRECISE float sy = d[ky] / dz;
    PRECISE float sz = 1.0 / dz;
    PRECISE vec3 inv_d = vec3(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
    pre.sx = sx;
    pre.sy = sy;
    pre.sz = sz;
    pre.inv_d = inv_d;
    return pre;
}

Hit hit_at(float t) { return Hit(t, 0.0, 0.0); }

// Geometric method (Haines et al., Ray Tracing Gems ch. 7): the
// discriminant from the perpendicular distance, the near root without
// cancellation. Handles origins inside the sphere.
bool sphere(vec3 center, float r2, Ray ray, float tmax, out Hit h) {
    PRECISE vec3 l = center - ray.o;
    PRECISE float tca = dot3(l, ray.d);
    PRECISE vec3 perp = l - ray.d * tca;
    PRECISE float d2 = dot3(perp, perp);
    if (d2 > r2) {
        return false;
    }
    PRECISE float thc = sqrt(r2 - d2);
    PRECISE float c = dot3(l, l) - r2;
    PRECISE float t0;
    PRECISE float t1;
    if (tca > 0.0) {
        PRECISE float q = tca + thc;
        t0 = c / q;
        t1 = q;
    } else {
        PRECISE float q = tca - thc;
        t0 = q;
        t1 = c / q;
    }
    if (t0 > 0.0 && t0 < tmax) {
        h = hit_at(t0);
        return true;
    }
    if (t1 > 0.0 && t1 < tmax) {
        h = hit_at(t1);
        return true;
    }
    return false;
}

bool plane(vec3 n, float dist, Ray ray, float tmax, out Hit h) {
    PRECISE float denom = dot3(n, ray.d);
    if (denom == 0.0) {
        return false;
    }
    PRECISE float t = (dist - dot3(n, ray.o)) / denom;
    if (t > 0.0 && t < tmax) {
        h = hit_at(t);
        return true;
    }
    return false;
}

// Watertight ray/triangle (Woop, Benthin, Wald 2013). The edge functions
// of a shared edge are exact negations of each other (never fused), so a
// ray through an edge or vertex hits at least one of the triangles.
bool triangle(vec3 v0, vec3 v1, vec3 v2, Ray ray, RayPre pre, float tmax, out Hit h) {
    PRECISE vec3 a = v0 - ray.o;
    PRECISE vec3 b = v1 - ray.o;
    PRECISE vec3 c = v2 - ray.o;
    int kx = pre.kx;
    int ky = pre.ky;
    int kz = pre.kz;
    PRECISE float ax = a[kx] - pre.sx * a[kz];
    PRECISE float ay = a[ky] - pre.sy * a[kz];
    PRECISE float bx = b[kx] - pre.sx * b[kz];
    PRECISE float by = b[ky] - pre.sy * b[kz];
    PRECISE float cx = c[kx] - pre.sx * c[kz];
    PRECISE float cy = c[ky] - pre.sy * c[kz];
    PRECISE float u = cx * by - cy * bx;
    PRECISE float v = ax * cy - ay * cx;
    PRECISE float w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return false;
    }
    PRECISE float det = u + v + w;
    if (det == 0.0) {
        return false;
    }
    PRECISE float az = pre.sz * a[kz];
    PRECISE float bz = pre.sz * b[kz];
    PRECISE float cz = pre.sz * c[kz];
    PRECISE float tt = u * az + v * bz + w * cz;
    PRECISE float t = tt / det;
    if (t > 0.0 && t < tmax) {
        PRECISE float hu = u / det;
        PRECISE float hv = v / det;
        h = Hit(t, hu, hv);
        return true;
    }
    return false;
}

// Vertex j of a polygon, projected (pack::polygon): two to a vec4.
vec2 polyVertex(uint base, uint j) {
    vec4 e = extra_at(base + j / 2u);
    return (j % 2u) == 0u ? e.xy : e.zw;
}

// Float i of the stream that starts at extra[base].
float floatAt(uint base, uint i) {
    return extra_at(base + i / 4u)[i % 4u];
}

// The code of the cell of a banded polygon that (px, py) falls in:
// CELL_IN, CELL_OUT, or CELL_EDGE (take the crossings test), which is also
// the answer for a polygon without cells and for a point outside the
// cells' range (src/pack/polygon.rs, cells).
uint polygonCell(Prim prim, uint lists, float px, float py) {
    uint at = uint(prim.c.w);
    if (at == 0u) {
        return CELL_EDGE;
    }
    float k = prim.c.z;
    float uMin = floatAt(lists, at);
    float invW = floatAt(lists, at + 1u);
    float m = floatAt(lists, at + 2u);
    PRECISE float fb = floor((py - prim.c.x) * prim.c.y);
    PRECISE float fm = floor((px - uMin) * invW);
    // Comparisons false for a NaN: such a point takes the test.
    bool within = fb >= 0.0 && fb < k && fm >= 0.0 && fm < m;
    if (!within) {
        return CELL_EDGE;
    }
    return uint(floatAt(lists, at + 3u + uint(fb) * uint(m) + uint(fm)));
}

// Planar polygon: the plane, then a 2D test in the plane of the two axes
// other than the normal's largest (the vertices are packed projected,
// pack::polygon): all edges on one side for convex polygons, the
// crossings test (even-odd) for the rest, over the hit point's edge band
// when the polygon has bands (the same parity as over every edge).
bool polygon(Prim prim, Ray ray, float tmax, out Hit h) {
    vec3 n = prim.a.xyz;
    Hit ph;
    if (!plane(n, prim.a.w, ray, tmax, ph)) {
        return false;
    }
    PRECISE vec3 p = ray.o + ray.d * ph.t;
    uint count = uint(prim.b.x);
    uint drop = uint(prim.b.y);
    bool convex = prim.b.z != 0.0;
    int i0;
    int i1;
    if (drop == 0u) {
        i0 = 1;
        i1 = 2;
    } else if (drop == 1u) {
        i0 = 2;
        i1 = 0;
    } else {
        i0 = 0;
        i1 = 1;
    }
    float px = p[i0];
    float py = p[i1];
    uint base = prim.data;
    if (CONVEX_POLYGONS) {
        // Every edge in order, each vertex read once, two to a read (the
        // vertices lie two to a vec4): the arithmetic of the loop below
        // for a convex polygon (and of the CPU mirror's convex branch),
        // without its cells, bands and crossings.
        vec2 a = polyVertex(base, count - 1u);
        bool pos = false;
        bool neg = false;
        for (uint j = 0u; j < count; j += 2u) {
            vec4 pair = extra_at(base + j / 2u);
            for (uint k = 0u; k < 2u; k++) {
                vec2 c = k == 0u ? pair.xy : pair.zw;
                if (j + k < count) {
                    PRECISE float ex = c.x - a.x;
                    PRECISE float ey = c.y - a.y;
                    PRECISE float ee = ex * (py - a.y) - ey * (px - a.x);
                    pos = pos || ee > 0.0;
                    neg = neg || ee < 0.0;
                    a = c;
                }
            }
        }
        if (!(pos && neg)) {
            h = ph;
            return true;
        }
        return false;
    }
    uint bands = uint(prim.c.z);
    bool banded = !convex && bands > 0u;
    uint lists = base + (count + 1u) / 2u;
    // A cell wholly inside or outside answers for the test.
    uint cell = polygonCell(prim, lists, px, py);
    if (cell != CELL_EDGE) {
        h = ph;
        return cell == CELL_IN;
    }
    // Edges [lo, hi): every edge, or the hit point's band's list.
    uint lo = 0u;
    uint hi = count;
    if (banded) {
        PRECISE float fb = floor((py - prim.c.x) * prim.c.y);
        uint b = uint(min(max(fb, 0.0), float(bands - 1u)));
        lo = uint(floatAt(lists, b));
        hi = uint(floatAt(lists, b + 1u));
    }
    // One loop for both tests (Rust has one too): llvmpipe 22.3 bug: all
    // loops share a 65535-iteration budget per SIMD group
    // (LP_MAX_TGSI_LOOP_ITERATIONS), and a loop no lane enters still costs
    // one, so each extra loop here costs one per intersect() call.
    bool pos = false;
    bool neg = false;
    bool inside = false;
    for (uint e = lo; e < hi; e++) {
        uint j = banded ? uint(floatAt(lists, bands + 1u + e)) : e;
        vec2 a = polyVertex(base, j == 0u ? count - 1u : j - 1u);
        vec2 c = polyVertex(base, j);
        float ax = a.x;
        float ay = a.y;
        float bx = c.x;
        float by = c.y;
        if (convex) {
            PRECISE float ex = bx - ax;
            PRECISE float ey = by - ay;
            PRECISE float ee = ex * (py - ay) - ey * (px - ax);
            pos = pos || ee > 0.0;
            neg = neg || ee < 0.0;
        } else if ((ay > py) != (by > py)) {
            PRECISE float xc = ax + (py - ay) * (bx - ax) / (by - ay);
            if (px < xc) {
                inside = !inside;
            }
        }
    }
    if (convex ? !(pos && neg) : inside) {
        h = ph;
        return true;
    }
    return false;
}

// Slabs. A ray parallel to a slab pair misses unless its origin lies
// between the two planes (no 0·∞). From inside, the exit is the hit.
// u = axis of the face hit, v = its side (−1 min face, +1 max face).
bool aabox(vec3 lo, vec3 hi, Ray ray, RayPre pre, float tmax, out Hit h) {
    float tnear = NEG_INF;
    float tfar = INF;
    int near_axis = 0;
    float near_side = -1.0;
    int far_axis = 0;
    float far_side = 1.0;
    for (int i = 0; i < 3; i++) {
        float o = ray.o[i];
        float d = ray.d[i];
        if (d == 0.0) {
            if (o < lo[i] || o > hi[i]) {
                return false;
            }
            continue;
        }
        float inv = pre.inv_d[i];
        PRECISE float ta = (lo[i] - o) * inv;
        PRECISE float tb = (hi[i] - o) * inv;
        float tn;
        float tf;
        float sn;
        if (d > 0.0) {
            tn = ta;
            tf = tb;
            sn = -1.0;
        } else {
            tn = tb;
            tf = ta;
            sn = 1.0;
        }
        if (tn > tnear) {
            tnear = tn;
            near_axis = i;
            near_side = sn;
        }
        if (tf < tfar) {
            tfar = tf;
            far_axis = i;
            far_side = -sn;
        }
    }
    if (tnear > tfar) {
        return false;
    }
    if (tnear > 0.0 && tnear < tmax) {
        h = Hit(tnear, float(near_axis), near_side);
        return true;
    }
    if (tnear <= 0.0 && tfar > 0.0 && tfar < tmax) {
        h = Hit(tfar, float(far_axis), far_side);
        return true;
    }
    return false;
}

// Roots of a t² + b t + c = 0 in increasing order, without cancellation
// (q = −(b + sign(b)·√disc)/2; roots q/a and c/q); the linear case when
// |a| is negligible against |b|.
bool solve_quadratic(float a, float b, float c, out float t0, out float t1) {
    PRECISE float negligible = 1.0e-12 * abs(b);
    if (abs(a) <= negligible || a == 0.0) {
        if (b == 0.0) {
            return false;
        }
        PRECISE float t = -c / b;
        t0 = t;
        t1 = t;
        return true;
    }
    PRECISE float disc = b * b - 4.0 * a * c;
    if (disc < 0.0) {
        return false;
    }
    PRECISE float sq = sqrt(disc);
    PRECISE float q;
    if (b < 0.0) {
        q = -0.5 * (b - sq);
    } else {
        q = -0.5 * (b + sq);
    }
    if (q == 0.0) {
        // b = 0 and c = 0: a double root at 0.
        t0 = 0.0;
        t1 = 0.0;
        return true;
    }
    PRECISE float r0 = q / a;
    PRECISE float r1 = c / q;
    if (r0 < r1) {
        t0 = r0;
        t1 = r1;
    } else {
        t0 = r1;
        t1 = r0;
    }
    return true;
}

bool inside_box(vec3 p, vec3 lo, vec3 hi) {
    return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
}

// General quadric A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J,
// coefficients in extra[data .. data + 3], clipped to the box in a/b when a.w = 1.
bool quadric(Prim prim, Ray ray, float tmax, out Hit h) {
    vec4 k0 = extra_at(prim.data);
    vec4 k1 = extra_at(prim.data + 1u);
    vec4 k2 = extra_at(prim.data + 2u);
    float ca = k0.x, cb = k0.y, cc = k0.z, cd = k0.w;
    float ce = k1.x, cf = k1.y, cg = k1.z, ch = k1.w;
    float ci = k2.x, cj = k2.y;
    vec3 o = ray.o;
    vec3 d = ray.d;
    PRECISE float a = ca * d.x * d.x
        + cb * d.y * d.y
        + cc * d.z * d.z
        + cd * d.x * d.y
        + ce * d.x * d.z
        + cf * d.y * d.z;
    PRECISE float b = 2.0 * (ca * o.x * d.x + cb * o.y * d.y + cc * o.z * d.z)
        + cd * (o.x * d.y + o.y * d.x)
        + ce * (o.x * d.z + o.z * d.x)
        + cf * (o.y * d.z + o.z * d.y)
        + cg * d.x
        + ch * d.y
        + ci * d.z;
    PRECISE float c = ca * o.x * o.x
        + cb * o.y * o.y
        + cc * o.z * o.z
        + cd * o.x * o.y
        + ce * o.x * o.z
        + cf * o.y * o.z
        + cg * o.x
        + ch * o.y
        + ci * o.z
        + cj;
    float r0;
    float r1;
    if (!solve_quadratic(a, b, c, r0, r1)) {
        return false;
    }
    bool clipped = prim.a.w != 0.0;
    vec3 lo = prim.a.xyz;
    vec3 hi = prim.b.xyz;
    for (int k = 0; k < 2; k++) {
        float t = k == 0 ? r0 : r1;
        if (t > 0.0 && t < tmax) {
            PRECISE vec3 p = o + d * t;
            if (!clipped || inside_box(p, lo, hi)) {
                h = hit_at(t);
                return true;
            }
        }
    }
    return false;
}

// Open truncated cone (cylinder when the radii are equal) around a unit
// axis from base (radius r0) to base + length·axis (radius r1). Solved from
// o' = o + t_c·d, for a long cone (c.w) the ray's point nearest the axis
// segment's point nearest the ray, for a short one (or a ray nearly
// parallel to the axis) its point nearest the middle, and t = t_c + s; the hit within the record's tolerance (c.z) of the side
// (src/trace/intersect.rs).
bool cone(Prim prim, Ray ray, float tmax, out Hit h) {
    vec3 base = prim.a.xyz;
    vec3 axis = prim.b.xyz;
    float r0 = prim.a.w;
    float r1 = prim.b.w;
    float len = prim.c.x;
    PRECISE float k = (r1 - r0) / len;
    PRECISE float dv = dot3(ray.d, axis);
    PRECISE vec3 w0 = ray.o - base;
    PRECISE float denom = 1.0 - dv * dv;
    PRECISE float hc = len * 0.5;
    if (prim.c.w != 0.0 && denom > CONE_PARALLEL) {
        PRECISE float hs = (dot3(w0, axis) - dv * dot3(w0, ray.d)) / denom;
        hc = hs >= 0.0 ? (hs > len ? len : hs) : 0.0;
    }
    PRECISE vec3 near = base + axis * hc;
    PRECISE float tc = dot3(near - ray.o, ray.d);
    PRECISE vec3 w = (ray.o + ray.d * tc) - base;
    PRECISE float wv = dot3(w, axis);
    PRECISE vec3 pp = w - axis * wv;
    PRECISE vec3 dd = ray.d - axis * dv;
    PRECISE float rw = r0 + k * wv;
    PRECISE float a = dot3(dd, dd) - k * k * dv * dv;
    PRECISE float b = 2.0 * (dot3(pp, dd) - rw * k * dv);
    PRECISE float c = dot3(pp, pp) - rw * rw;
    float s0;
    float s1;
    if (!solve_quadratic(a, b, c, s0, s1)) {
        return false;
    }
    float tol = prim.c.z;
    for (int j = 0; j < 2; j++) {
        float s = j == 0 ? s0 : s1;
        PRECISE float t = tc + s;
        PRECISE float hgt = wv + s * dv;
        if (t > 0.0 && t < tmax && hgt >= 0.0 && hgt <= len) {
            // The point itself within tol of the side (intersect.rs).
            PRECISE vec3 q = (ray.o + ray.d * t) - base;
            PRECISE float hq = dot3(q, axis);
            PRECISE vec3 perp = q - axis * hq;
            PRECISE float lim = r0 + k * hq + tol;
            PRECISE float lim2 = lim * lim;
            if (dot3(perp, perp) <= lim2) {
                h = hit_at(t);
                return true;
            }
        }
    }
    return false;
}

// Any primitive: the dispatch on kind.
// intersect, compiled for the kinds in `kinds` only (a constant where
// the walks call it: BOUNDED_KINDS); false for a primitive of another kind.
bool intersect_kinds(Prim prim, Ray ray, RayPre pre, float tmax, out Hit h, uint kinds) {
    switch (prim_kind(prim)) {
    case KIND_SPHERE:
        if (HAS_SPHERE && (kinds & FEAT_SPHERE) != 0u) {
            return sphere(prim.a.xyz, prim.a.w, ray, tmax, h);
        }
        break;
    case KIND_PLANE:
        if (HAS_PLANE && (kinds & FEAT_PLANE) != 0u) {
            return plane(prim.a.xyz, prim.a.w, ray, tmax, h);
        }
        break;
    case KIND_TRIANGLE:
        if (HAS_TRIANGLE && (kinds & FEAT_TRIANGLE) != 0u) {
            return triangle(prim.a.xyz, prim.b.xyz, prim.c.xyz, ray, pre, tmax, h);
        }
        break;
    case KIND_POLYGON:
        if (HAS_POLYGON && (kinds & FEAT_POLYGON) != 0u) {
            return polygon(prim, ray, tmax, h);
        }
        break;
    case KIND_BOX:
        if (HAS_BOX && (kinds & FEAT_BOX) != 0u) {
            return aabox(prim.a.xyz, prim.b.xyz, ray, pre, tmax, h);
        }
        break;
    case KIND_QUADRIC:
        if (HAS_QUADRIC && (kinds & FEAT_QUADRIC) != 0u) {
            return quadric(prim, ray, tmax, h);
        }
        break;
    case KIND_CONE:
        if (HAS_CONE && (kinds & FEAT_CONE) != 0u) {
            return cone(prim, ray, tmax, h);
        }
        break;
    default:
        break;
    }
    return false;
}

bool intersect(Prim prim, Ray ray, RayPre pre, float tmax, out Hit h) {
    return intersect_kinds(prim, ray, pre, tmax, h, 0xFFFFFFFFu);
}

// Outward geometric normal ng (unit) and shading normal ns (unit) at p.
void normals(Prim prim, vec3 p, Hit h, out vec3 ng, out vec3 ns) {
    ng = vec3(0.0);
    ns = vec3(0.0);
    switch (prim_kind(prim)) {
    case KIND_SPHERE:
        if (HAS_SPHERE) {
            PRECISE vec3 q = (p - prim.a.xyz) / prim.b.x;
            vec3 n = normalize3(q);
            ng = n;
            ns = n;
        }
        break;
    case KIND_PLANE:
    case KIND_POLYGON:
        if (HAS_PLANE || HAS_POLYGON) {
            ng = prim.a.xyz;
            ns = prim.a.xyz;
        }
        break;
    case KIND_TRIANGLE:
        if (HAS_TRIANGLE) {
            vec3 v0 = prim.a.xyz;
            PRECISE vec3 e1 = prim.b.xyz - v0;
            PRECISE vec3 e2 = prim.c.xyz - v0;
            vec3 n = normalize3(cross3(e1, e2));
            ng = n;
            ns = n;
            // FEAT_SMOOTH is set whenever a triangle carries normals, so the
            // extra guard changes nothing the CPU computes.
            if (HAS_SMOOTH && prim.data != NO_NORMALS) {
                uint i = prim.data;
                PRECISE float w = 1.0 - h.u - h.v;
                PRECISE vec3 s = extra_at(i).xyz * h.u
                    + extra_at(i + 1u).xyz * h.v
                    + extra_at(i + 2u).xyz * w;
                ns = normalize3(s);
            }
        }
        break;
    case KIND_BOX:
        if (HAS_BOX) {
            uint axis = uint(h.u);
            vec3 n = vec3(0.0);
            if (axis == 0u) {
                n.x = h.v;
            } else if (axis == 1u) {
                n.y = h.v;
            } else {
                n.z = h.v;
            }
            ng = n;
            ns = n;
        }
        break;
    case KIND_QUADRIC:
        if (HAS_QUADRIC) {
            vec4 k0 = extra_at(prim.data);
            vec4 k1 = extra_at(prim.data + 1u);
            vec4 k2 = extra_at(prim.data + 2u);
            PRECISE float nx = 2.0 * k0.x * p.x + k0.w * p.y + k1.x * p.z + k1.z;
            PRECISE float ny = 2.0 * k0.y * p.y + k0.w * p.x + k1.y * p.z + k1.w;
            PRECISE float nz = 2.0 * k0.z * p.z + k1.x * p.x + k1.y * p.y + k2.x;
            vec3 n = direction3(vec3(nx, ny, nz));
            ng = n;
            ns = n;
        }
        break;
    case KIND_CONE:
        if (HAS_CONE) {
            vec3 base = prim.a.xyz;
            vec3 axis = prim.b.xyz;
            PRECISE float k = (prim.b.w - prim.a.w) / prim.c.x;
            PRECISE vec3 q = p - base;
            PRECISE vec3 rq = q - axis * dot3(q, axis);
            vec3 radial = normalize3(rq);
            PRECISE vec3 m = radial - axis * k;
            PRECISE vec3 n = normalize3(m) * prim.c.y;
            ng = n;
            ns = n;
        }
        break;
    default:
        break;
    }
}

#endif
