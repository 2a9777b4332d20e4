// Per-lattice-point entry: twin of src/cpu.rs (trace_sample, render_pixel).
//
// One invocation per point of the sample lattice of one tile: for centre
// and jitter sampling the lattice is the W×H pixels and the value is the
// pixel's mean over g.image.z samples (render_pixel); for corner sampling
// it is the (W+1)×(H+1) corners and the value is one eye ray through the
// corner (trace_sample), which the host resolves into pixels.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

// Workgroup size: specialization constants 0 and 1 (default 8 × 8).
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

#include "precise.glsl"
#include "layout.glsl"
#include "sample.glsl"
#include "trace.glsl"
#include "counts.glsl"

// One vec4 per lattice point (rgb, w = 1), index y * lattice_width + x.
layout(set = 0, binding = 7, std430) writeonly buffer Out { vec4 samples[]; };
// tile.xy: lattice origin of this tile; tile.zw: its width and height.
// order.x: the workgroup order's stride (src/gpu/dispatch.rs,
// scatter_stride; 1: plain order).
layout(push_constant) uniform Push {
    uvec4 tile;
    uvec4 order;
};

// One eye ray through image position (x, y); counts it.
vec3 trace_sample(float x, float y) {
    stats.eye += 1u;
    vec3 d = eye_dir(g, x, y);
    return trace_ray(Ray(vec3(0.0), d));
}

// The mean of a pixel's samples.
vec3 render_pixel(uint px, uint py) {
    uint spp = g.image.z;
    PRECISE vec3 sum = vec3(0.0);
    for (uint k = 0u; k < spp; k++) {
        vec2 xy = sample_pos(g, px, py, k);
        vec3 c = trace_sample(xy.x, xy.y);
        sum = sum + c;
    }
    PRECISE float inv = 1.0 / float(spp);
    PRECISE vec3 mean = sum * inv;
    return mean;
}

void main() {
    // Workgroup k of the dispatch renders group (k · stride) mod n of the
    // tile: a permutation, since the stride is coprime to n.
    uvec2 ng = gl_NumWorkGroups.xy;
    uint n = ng.x * ng.y;
    uint k = gl_WorkGroupID.y * ng.x + gl_WorkGroupID.x;
    uint p = (k * order.x) % n;
    uvec2 gid = uvec2(p % ng.x, p / ng.x) * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy;
    shadow_cache_reset();
    bool corners = g.image.w == SAMPLING_CORNERS;
    uint lw = corners ? g.image.x + 1u : g.image.x;
    uint lh = corners ? g.image.y + 1u : g.image.y;
    uint x = tile.x + gid.x;
    uint y = tile.y + gid.y;
    if (gid.x < tile.z && gid.y < tile.w && x < lw && y < lh) {
        vec3 c;
        if (corners) {
            c = trace_sample(float(x), float(y));
        } else {
            c = render_pixel(x, y);
        }
        samples[y * lw + x] = vec4(c, 1.0);
    }
    // Every invocation (in range or not) reaches the reductions.
    flush_counts();
}
