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

#ifdef WHITTED_LANES
// Built as render_lanes.spv (WHITTED_LANES, build.rs): the lattice points
// one invocation renders are specialization constant 4 (`--lane-pixels`
// above 1; docs/profiling.md, "Persistent lanes"); render.spv renders one
// each, as above. K > 1: the first ceil(lanes / K) invocations of a workgroup take
// K of its points each (the rest return at once), and an invocation whose
// sample's ray tree ends starts its next sample inside the same ray loop,
// so its lanes stop waiting for their neighbours' deeper trees. Each
// point's sums keep render_pixel's and trace_ray's order: the same image.
layout(constant_id = 4) const uint LANE_PIXELS = 1u;

// The mean of `spp` samples summed in `sum` (render_pixel's last steps).
vec3 mean_of(vec3 sum, uint spp) {
    PRECISE float inv = 1.0 / float(spp);
    PRECISE vec3 mean = sum * inv;
    return mean;
}

// Lattice point j of this invocation's LANE_PIXELS: its coordinates, and
// whether it lies in the tile and the lattice.
bool lane_point(uvec2 base, uint workers, uint j, uint lw, uint lh, out uint x, out uint y) {
    uint lanes = gl_WorkGroupSize.x * gl_WorkGroupSize.y;
    uint idx = gl_LocalInvocationIndex + j * workers;
    uvec2 gid = base + uvec2(idx % gl_WorkGroupSize.x, idx / gl_WorkGroupSize.x);
    x = tile.x + gid.x;
    y = tile.y + gid.y;
    return idx < lanes && gid.x < tile.z && gid.y < tile.w && x < lw && y < lh;
}

// The next of this invocation's points from j on that lies in the image
// (LANE_PIXELS when none is left).
uint lane_next(uvec2 base, uint workers, uint j, uint lw, uint lh, out uint x, out uint y) {
    while (j < LANE_PIXELS && !lane_point(base, workers, j, lw, lh, x, y)) {
        j++;
    }
    return j;
}

// LANE_PIXELS > 1: this invocation's points, one ray loop for all their
// samples' trees (trace_ray's body, the sample and pixel sums between).
void render_lane(uvec2 base, bool corners, uint lw, uint lh) {
    uint lanes = gl_WorkGroupSize.x * gl_WorkGroupSize.y;
    uint workers = (lanes + LANE_PIXELS - 1u) / LANE_PIXELS;
    if (gl_LocalInvocationIndex >= workers) {
        return;
    }
    uint spp = corners ? 1u : g.image.z;
    uint px = 0u;
    uint py = 0u;
    uint j = lane_next(base, workers, 0u, lw, lh, px, py);
    bool more = j < LANE_PIXELS;
    Entry stack[STACK_SIZE];
    uint sp = 0u;
    vec3 color = vec3(0.0);
    vec3 sum = vec3(0.0);
    uint s = 0u;
    bool started = false;
    // The ray walked next, when `have`; else the stack's top (trace.glsl,
    // trace_ray: only refracted rays wait in the stack).
    Entry e;
    bool have = false;
    while (more) {
        if (!have && (!HAS_REFRACT || sp == 0u)) {
            if (started) {
                // A sample's tree is done: render_pixel's sum, and the
                // point's mean once all its samples are.
                if (corners) {
                    samples[py * lw + px] = vec4(color, 1.0);
                    s = spp;
                } else {
                    sum = add_exact(sum, color);
                    s += 1u;
                    if (s == spp) {
                        samples[py * lw + px] = vec4(mean_of(sum, spp), 1.0);
                    }
                }
                if (s == spp) {
                    sum = vec3(0.0);
                    s = 0u;
                    j = lane_next(base, workers, j + 1u, lw, lh, px, py);
                    if (j == LANE_PIXELS) {
                        more = false;
                        break;
                    }
                }
            }
            started = true;
            color = vec3(0.0);
            // trace_sample
            stats.eye += 1u;
            vec3 d;
            if (corners) {
                d = eye_dir(g, float(px), float(py));
            } else {
                vec2 xy = sample_pos(g, px, py, s);
                d = eye_dir(g, xy.x, xy.y);
            }
            e = Entry(vec3(0.0), d, vec3(1.0), vec3(0.0), 0u);
            have = true;
        }
        // trace_ray's loop body (trace.glsl), unchanged: keep the two alike.
        if (HAS_REFRACT && !have) {
            sp -= 1u;
            e = stack[sp];
        }
        have = false;
        Ray r = Ray(e.o, e.d);
        RayPre pre = ray_pre(e.d);
        Hit h;
        uint pi;
        uvec3 before = work_totals();
        bool found = closest_hit(r, pre, INF, h, pi);
        if (e.depth == 0u) {
            // An eye ray's work is its own (work_eye).
            work_eye += work_totals() - before;
        }
        if (!found) {
            vec3 c;
            if (miss_contribution(e, c)) {
                color = add_exact(color, c);
            }
            continue;
        }
        if (e.depth == 0u) {
            stats.eye_hit += 1u;
        }
        Surface sf = surface_at(e, h, pi);
        shadow_cache_at_depth(e.depth);
        vec3 local_ = shade(sf.mat, sf.p, e.d, sf.n, sf.ngf, sf.front, sf.weighted);
        if (sf.weighted) {
            color = add_weighted(color, sf.w, local_);
        }
        Entry tr;
        Entry rf;
        uint kids = spawn(e, sf, tr, rf);
        if (HAS_REFRACT && (kids & 1u) != 0u) {
            stack[sp] = tr;
            sp += 1u;
        }
        if ((kids & 2u) != 0u) {
            e = rf;
            have = true;
        }
    }
    if (more) {
        // The loop was cut short (lavapipe's loop budget).
        loops_cut += 1u;
    }
}
#endif

void main() {
    load_globals();
    // Workgroup k of the dispatch renders group (k · stride) mod n of the
    // tile: a permutation, since the stride is coprime to n.
    uvec2 ng = gl_NumWorkGroups.xy;
    uint n = ng.x * ng.y;
    uint k = gl_WorkGroupID.y * ng.x + gl_WorkGroupID.x;
    uint p = (k * order.x) % n;
    uvec2 base = uvec2(p % ng.x, p / ng.x) * gl_WorkGroupSize.xy;
    shadow_cache_reset();
    bool corners = g.image.w == SAMPLING_CORNERS;
    uint lw = corners ? g.image.x + 1u : g.image.x;
    uint lh = corners ? g.image.y + 1u : g.image.y;
#ifdef WHITTED_LANES
    render_lane(base, corners, lw, lh);
#else
    uvec2 gid = base + gl_LocalInvocationID.xy;
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
#endif
    // Every invocation (in range or not) reaches the reductions.
    flush_counts();
}
