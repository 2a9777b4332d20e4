// Test-only kernels that run one function on many inputs: twin of
// tests/probe.rs. One invocation per item; probe.x picks the function.
// Ray = (o.xyz, d.xyz), tmax = o.w; RayPre is ray_pre(d).
#version 460
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

// The probes check the twins bit for bit: only the exact arithmetic will do.
#ifdef WHITTED_FAST_MATH
#error probe.comp is compiled exact only, without WHITTED_FAST_MATH
#endif

#include "precise.glsl"
#include "layout.glsl"
#include "sample.glsl"
#include "trace.glsl"

struct ProbeItem {
    vec4 o;
    vec4 d;
    uvec4 u;
};

struct ProbeResult {
    vec4 a;
    vec4 b;
    uvec4 u;
};

layout(set = 0, binding = 9, std430) readonly buffer ProbeIn { ProbeItem items[]; };
layout(set = 0, binding = 10, std430) writeonly buffer ProbeOut { ProbeResult results[]; };

// probe.x: mode, probe.y: item count.
layout(push_constant) uniform Push { uvec4 probe; };

const uint PROBE_INTERSECT = 0u;
const uint PROBE_CLOSEST = 1u;
const uint PROBE_TRANSMITTANCE = 2u;
const uint PROBE_REFRACT = 3u;
const uint PROBE_TRACE = 4u;
const uint PROBE_SAMPLE = 5u;
const uint PROBE_SOLVE = 6u;

void main() {
    load_globals();
    uint idx = gl_GlobalInvocationID.x;
    shadow_cache_reset();
    if (idx >= probe.y) {
        return;
    }
    ProbeItem it = items[idx];
    Ray ray = Ray(it.o.xyz, it.d.xyz);
    float tmax = it.o.w;
    ProbeResult res;
    res.a = vec4(0.0);
    res.b = vec4(0.0);
    res.u = uvec4(0u);
    switch (probe.x) {
    case PROBE_INTERSECT: {
        // a = (hit, t, u, v); b.xyz = geometric normal and u.xyz = the bits
        // of the shading normal, both at p = o + d·t.
        RayPre pre = ray_pre(ray.d);
        Hit h;
        if (intersect(load_prim(it.u.x), ray, pre, tmax, h)) {
            res.a = vec4(1.0, h.t, h.u, h.v);
            PRECISE vec3 p = ray.o + ray.d * h.t;
            vec3 ng;
            vec3 ns;
            normals(load_prim(it.u.x), p, h, ng, ns);
            res.b = vec4(ng, 0.0);
            res.u = uvec4(floatBitsToUint(ns), 0u);
        }
        break;
    }
    case PROBE_CLOSEST: {
        // a = (hit, t, u, v); u.x = primitive index (0xFFFFFFFF: none).
        RayPre pre = ray_pre(ray.d);
        Hit h;
        uint pi;
        res.u.x = 0xFFFFFFFFu;
        if (closest_hit(ray, pre, tmax, h, pi)) {
            res.a = vec4(1.0, h.t, h.u, h.v);
            res.u.x = pi;
        }
        break;
    }
    case PROBE_TRANSMITTANCE: {
        RayPre pre = ray_pre(ray.d);
        res.a = vec4(transmittance(ray, pre, tmax, 0xFFFFFFFFu), 0.0);
        break;
    }
    case PROBE_REFRACT: {
        // i = d.xyz, n = o.xyz, eta = o.w.
        vec3 t;
        if (refract_dir(it.d.xyz, it.o.xyz, it.o.w, t)) {
            res.a = vec4(1.0, t);
        }
        res.b = vec4(reflect_dir(it.d.xyz, it.o.xyz), 0.0);
        break;
    }
    case PROBE_TRACE: {
        // a.xyz = colour; u = the ray tree's (eye_hit, reflect, refract, shadow).
        res.a = vec4(trace_ray(ray), 0.0);
        res.u = uvec4(stats.eye_hit, stats.reflect, stats.refract, stats.shadow);
        break;
    }
    case PROBE_SAMPLE: {
        res.a = vec4(eye_dir(g, it.o.x, it.o.y), rand01(it.u.x, it.u.y, it.u.z));
        vec2 sp = sample_pos(g, it.u.x, it.u.y, it.u.z);
        res.u = uvec4(hash(it.u.x), floatBitsToUint(sp.x), floatBitsToUint(sp.y), 0u);
        break;
    }
    case PROBE_SOLVE: {
        float t0;
        float t1;
        if (solve_quadratic(it.o.x, it.o.y, it.o.z, t0, t1)) {
            res.a = vec4(1.0, t0, t1, 0.0);
        }
        break;
    }
    default:
        break;
    }
    results[idx] = res;
}
