// The calibration kernel: a plain grid tracer, the yardstick of issue
// 11's lavapipe target (docs/profiling.md, "A plain grid tracer as the
// yardstick"). Not a twin of anything, and never the scene's image:
// `--kernel calibration` (render, bench, profile) runs it to show how
// fast the simplest kernel for a scene runs on a device, against the
// exact kernel (render.comp) and the CPU mirror.
//
// It traces what render.comp traces on a field of opaque spheres under
// the grid (eye rays, one feeler per light facing the surface,
// reflections to the depth limit and above min weight; the same ray
// counts within about 2 %), with the textbook method and
// nothing else: the DDA without the empty-cell jumps or the test-once
// rule, the sphere test reading one word of four per test, opaque
// feelers that stop at the first blocker, Phong shading, no `precise`,
// no shadow cache, no ray-tree stack. Its pixels are close to the exact
// kernel's (tests/gpu.rs, `the_calibration_kernel_traces_the_same_rays`),
// not equal. Any other scene (another structure, primitives other than
// spheres, unbounded ones, refraction, SPD counting) comes out magenta:
// this kernel does not model it (`--kernel calibration` refuses such a
// scene before it runs: gpu::calibration_refusal, the twin of
// `supported` below).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

#include "precise.glsl"
#include "layout.glsl"
#include "sample.glsl"
#include "counts.glsl"

// render.comp's interface (bindings, push constants).
layout(set = 0, binding = 7, std430) writeonly buffer Out { vec4 samples[]; };
layout(push_constant) uniform Push {
    uvec4 tile;
    uvec4 order;
};

// What this kernel models: the grid, bounded spheres only, reflection
// and light falloff at most.
bool supported() {
    uint allowed = FEAT_SPHERE | FEAT_REFLECT | FEAT_FALLOFF;
    return g.flags.y == ACCEL_GRID && g.counts.x == g.counts.y && (g.trace.y & ~allowed) == 0u &&
           !spd_counting();
}

// The nearest sphere hit on o + t·d, 0 < t < tmax (any hit when
// `shadow`): the primitive in `hit`, its distance in `t`.
bool cal_walk(vec3 o, vec3 d, float tmax, bool shadow, out float t, out uint hit) {
    t = tmax;
    hit = 0u;
    if (g.grid_min.w == 0.0) {
        return false;
    }
    vec3 inv = 1.0 / d;
    vec3 lo = g.grid_min.xyz;
    vec3 ta = (lo - o) * inv;
    vec3 tb = (g.grid_max.xyz - o) * inv;
    vec3 tn = min(ta, tb);
    vec3 tf = max(ta, tb);
    float t0 = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float t1 = min(min(tf.x, tf.y), min(tf.z, tmax));
    if (!(t0 <= t1)) {
        return false;
    }
    ivec3 dims = ivec3(g.grid_dims.xyz);
    vec3 cs = g.grid_cell.xyz;
    ivec3 c = clamp(ivec3(floor((o + d * t0 - lo) / cs)), ivec3(0), dims - 1);
    ivec3 st = ivec3(sign(d));
    vec3 tnext = (lo + (vec3(c) + vec3(greaterThan(d, vec3(0.0)))) * cs - o) * inv;
    vec3 dt = abs(cs * inv);
    bool found = false;
    bool done = false;
    for (int it = 0; it < dims.x + dims.y + dims.z && !done; it++) {
        work_cells += 1u;
        uint ci = uint(c.x + dims.x * (c.y + dims.y * c.z));
        uint s;
        uint e;
        bool one = false;
        uint single = 0u;
        if (CELLS_PAIRS) {
            uvec2 cp = uvec2(cell_start_at(2u * ci), cell_start_at(2u * ci + 1u));
            s = cp.y > 1u ? cp.x : 0u;
            e = cp.y > 1u ? cp.x + cp.y : cp.y;
            one = cp.y == 1u;
            single = cp.x;
        } else {
            s = cell_start_at(ci);
            e = cell_start_at(ci + 1u);
        }
        for (uint k = s; k < e; k++) {
            uint i = one ? single : ref_at(k);
            work_tests += 1u;
            vec4 sp = uintBitsToFloat(prim_word(4u * i + 1u));
            vec3 oc = o - sp.xyz;
            float b = dot(oc, d);
            float disc = b * b - (dot(oc, oc) - sp.w);
            if (disc < 0.0) {
                continue;
            }
            float q = sqrt(disc);
            float th = -b - q > 0.0 ? -b - q : -b + q;
            if (th > 0.0 && th < t) {
                t = th;
                hit = i;
                found = true;
                if (shadow) {
                    done = true;
                    break;
                }
            }
        }
        float tx = min(tnext.x, min(tnext.y, tnext.z));
        if (t <= tx || tx >= t1) {
            break;
        }
        if (tnext.x == tx) {
            c.x += st.x;
            tnext.x += dt.x;
        } else if (tnext.y == tx) {
            c.y += st.y;
            tnext.y += dt.y;
        } else {
            c.z += st.z;
            tnext.z += dt.z;
        }
        if (any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, dims))) {
            break;
        }
    }
    return found;
}

// An eye ray's intensity: the ray tree as a loop (one reflected ray a
// hit, no refraction), counted as render.comp counts it.
vec3 cal_trace(vec3 o, vec3 d) {
    stats.eye += 1u;
    vec3 color = vec3(0.0);
    vec3 w = vec3(1.0);
    for (uint depth = 0u; depth <= g.trace.x; depth++) {
        float t;
        uint pi;
        uvec3 before = work_totals();
        bool found = cal_walk(o, d, INF, false, t, pi);
        if (depth == 0u) {
            work_eye += work_totals() - before;
        }
        if (!found) {
            color += w * g.background.rgb;
            break;
        }
        if (depth == 0u) {
            stats.eye_hit += 1u;
        }
        Prim pr = load_prim(pi);
        Material m = materials[prim_material(pr)];
        vec3 p = o + d * t;
        vec3 n = normalize(p - pr.a.xyz);
        if (dot(n, d) > 0.0) {
            n = -n;
        }
        vec3 r = reflect(d, n);
        vec3 po = p + n * g.params.y;
        vec3 local_ = m.ka.rgb * g.ambient.rgb;
        for (uint l = 0u; l < g.counts.z; l++) {
            vec3 to = lights[l].pos.xyz - p;
            float dist = length(to);
            vec3 L = to / dist;
            float nl = dot(n, L);
            if (nl <= 0.0) {
                continue;
            }
            stats.shadow += 1u;
            float tb;
            uint bi;
            uvec3 before_ = work_totals();
            bool blocked = cal_walk(po, L, dist, true, tb, bi);
            work_shadow += work_totals() - before_;
            if (blocked) {
                continue;
            }
            vec3 f = lights[l].falloff.xyz;
            float att = (g.trace.y & FEAT_FALLOFF) != 0u ? min(1.0 / (f.x + f.y * dist + f.z * dist * dist), 1.0) : 1.0;
            float spec = m.ks.x * pow(max(dot(r, L), 0.0), m.ks.y);
            local_ += lights[l].color.rgb * att * (m.kd.rgb * nl + vec3(spec));
        }
        color += w * local_;
        w *= m.kr.rgb;
        if (depth >= g.trace.x || max(m.kr.r, max(m.kr.g, m.kr.b)) <= 0.0 ||
            max(w.r, max(w.g, w.b)) < g.params.x) {
            break;
        }
        stats.reflect += 1u;
        o = po;
        d = r;
    }
    return color;
}

void main() {
    load_globals();
    uvec2 ng = gl_NumWorkGroups.xy;
    uint n = ng.x * ng.y;
    uint k = gl_WorkGroupID.y * ng.x + gl_WorkGroupID.x;
    uint p = (k * order.x) % n;
    uvec2 base = uvec2(p % ng.x, p / ng.x) * gl_WorkGroupSize.xy;
    bool corners = g.image.w == SAMPLING_CORNERS;
    uint lw = corners ? g.image.x + 1u : g.image.x;
    uint lh = corners ? g.image.y + 1u : g.image.y;
    uvec2 gid = base + gl_LocalInvocationID.xy;
    uint x = tile.x + gid.x;
    uint y = tile.y + gid.y;
    if (gid.x < tile.z && gid.y < tile.w && x < lw && y < lh) {
        vec3 c = vec3(1.0, 0.0, 1.0);
        if (supported()) {
            if (corners) {
                c = cal_trace(vec3(0.0), eye_dir(g, float(x), float(y)));
            } else {
                c = vec3(0.0);
                for (uint s = 0u; s < g.image.z; s++) {
                    vec2 xy = sample_pos(g, x, y, s);
                    c += cal_trace(vec3(0.0), eye_dir(g, xy.x, xy.y));
                }
                c /= float(g.image.z);
            }
        }
        samples[y * lw + x] = vec4(c, 1.0);
    }
    flush_counts();
}
