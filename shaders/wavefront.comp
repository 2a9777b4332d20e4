// The wavefront kernel: render.comp's ray tree (the megakernel) cut into
// stages, each its own dispatch over a queue of rays (docs/gpu.md,
// "Megakernel and wavefront"; host: src/gpu/wavefront.rs). Built once per
// stage (WF_STAGE, build.rs):
//
//   0 generate  one eye ray per sample of the tile (queue of depth 0)
//   1 extend    each queued ray's closest hit
//   2 shade     per hit: the local model's ambient term, its shadow
//               feelers and the spawned rays, appended (compacted) to the
//               feeler queue and the next depth's ray queue
//   3 shadow    each feeler's transmittance
//   4 combine   per hit: the lights' shares added in the light order, the
//               result weighted: the ray's contribution
//   5 resolve   per lattice point: every sample's ray tree summed in the
//               megakernel's order (reflection before refraction, depth
//               first), then the pixel's mean
//
// Each ray is a node of its eye ray's tree (nodes[], links to its
// children). Contributions are summed only at the end, in the order
// trace_ray sums them, and every stage calls the functions trace_ray and
// shade call: the image is the megakernel's bit for bit on lavapipe.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

// Workgroup size: specialization constants 0 and 1; the dispatch is a
// 1-D range of items (wf_index) whatever the shape.
layout(local_size_x = 8, local_size_y = 8, local_size_x_id = 0, local_size_y_id = 1) in;

#include "precise.glsl"
#include "layout.glsl"
#include "sample.glsl"
#include "trace.glsl"
#include "counts.glsl"

#ifndef WF_STAGE
#error "WF_STAGE: the stage to build (build.rs)"
#endif

// One vec4 per lattice point, as render.comp writes them.
layout(set = 0, binding = 7, std430) writeonly buffer Out { vec4 samples[]; };

// A queued ray: trace.glsl's Entry.
struct WfRay {
    vec3 o;
    uint depth;
    vec3 d;
    uint pad0;
    vec3 w;
    uint pad1;
    vec3 medium;
    uint pad2;
};

// One ray of a tree. c: after shade, the local model's ambient term
// (NODE_SHADE); after combine or for a miss, the ray's contribution
// (added when NODE_ADD). w: the weight at the hit. link: x, y the
// reflected and refracted children (NO_NODE: none); z, w the first
// feeler and the feeler count.
struct WfNode {
    vec3 c;
    uint flags;
    vec3 w;
    uint pad0;
    uvec4 link;
};

// A closest hit; prim NO_NODE: none.
struct WfHit {
    float t;
    float u;
    float v;
    uint prim;
};

// A shadow feeler of length dist to light `light`, the local model's
// bracket for it (term), and what it lets through (tr, the shadow stage).
struct WfFeeler {
    vec3 o;
    float dist;
    vec3 l;
    uint light;
    vec3 term;
    uint pad0;
    vec3 tr;
    uint pad1;
};

layout(set = 0, binding = 9, std430) buffer RaysBuf { WfRay rays[]; };
layout(set = 0, binding = 10, std430) buffer NodesBuf { WfNode nodes[]; };
layout(set = 0, binding = 14, std430) buffer HitsBuf { WfHit hits[]; };
layout(set = 0, binding = 15, std430) buffer FeelersBuf { WfFeeler feelers[]; };
// [0]: rays spawned, [1]: feelers queued by this shade dispatch (zeroed
// by the host before it). Either may exceed its capacity: then nothing
// past it was written, and the host grows the buffers and runs shade again.
layout(set = 0, binding = 16, std430) buffer QueueBuf { uint queue[4]; };

// tile: the lattice origin, width and height (generate, resolve).
// range.x: the items of this dispatch; range.y: where the queue's rays
// start in rays[]; range.z: the queue's first node; range.w: where
// spawned rays go in rays[]. cap.x: room for spawned rays; cap.y: room
// for feelers.
layout(push_constant) uniform Push {
    uvec4 tile;
    uvec4 range;
    uvec4 cap;
};

const uint NO_NODE = 0xFFFFFFFFu;
const uint NODE_ADD = 1u;
const uint NODE_SHADE = 2u;

// This invocation's item: the workgroups form a 2-D grid only because
// one axis may not hold them all.
uint wf_index() {
    uint lanes = gl_WorkGroupSize.x * gl_WorkGroupSize.y;
    uint grp = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    return grp * lanes + gl_LocalInvocationIndex;
}

// Room for `want` items at the end of queue `slot`: one atomic per
// subgroup, each invocation's items after its lower neighbours'
// (compaction). Every invocation must call it (subgroup operations).
uint wf_append(uint slot, uint want) {
    uint total = subgroupAdd(want);
    uint before = subgroupExclusiveAdd(want);
    uint first = 0u;
    if (subgroupElect() && total > 0u) {
        first = atomicAdd(queue[slot], total);
    }
    // Only the elected invocation holds a non-zero start: the maximum
    // hands it to all.
    return subgroupMax(first) + before;
}

Entry load_ray(uint at) {
    WfRay r = rays[at];
    return Entry(r.o, r.d, r.w, r.medium, r.depth);
}

void store_ray(uint at, Entry e) {
    rays[at] = WfRay(e.o, e.depth, e.d, 0u, e.w, 0u, e.medium, 0u);
}

#if WF_STAGE == 0
void main() {
    load_globals();
    uint i = wf_index();
    if (i < range.x) {
        bool corners = g.image.w == SAMPLING_CORNERS;
        uint spp = corners ? 1u : g.image.z;
        uint pt = i / spp;
        uint k = i % spp;
        uint x = tile.x + pt % tile.z;
        uint y = tile.y + pt / tile.z;
        vec2 xy = corners ? vec2(float(x), float(y)) : sample_pos(g, x, y, k);
        // render.comp's trace_sample
        stats.eye += 1u;
        vec3 d = eye_dir(g, xy.x, xy.y);
        store_ray(range.w + i, Entry(vec3(0.0), d, vec3(1.0), vec3(0.0), 0u));
    }
    flush_counts();
}
#endif

#if WF_STAGE == 1
void main() {
    load_globals();
    uint i = wf_index();
    if (i < range.x) {
        Entry e = load_ray(range.y + i);
        Ray r = Ray(e.o, e.d);
        RayPre pre = ray_pre(e.d);
        Hit h;
        uint pi;
        bool found = closest_hit(r, pre, INF, h, pi);
        if (e.depth == 0u) {
            // An eye ray's work is its own (work_eye).
            work_eye = work_totals();
        }
        hits[i] = WfHit(h.t, h.u, h.v, found ? pi : NO_NODE);
    }
    flush_counts();
}
#endif

#if WF_STAGE == 2
void main() {
    load_globals();
    uint i = wf_index();
    bool live = i < range.x;
    Entry e;
    WfHit wh;
    Surface s;
    bool hit = false;
    bool highlight_t = false;
    uint nf = 0u;
    uint kids = 0u;
    Entry tr;
    Entry rf;
    if (live) {
        e = load_ray(range.y + i);
        wh = hits[i];
        hit = wh.prim != NO_NODE;
    }
    if (hit) {
        if (e.depth == 0u) {
            stats.eye_hit += 1u;
        }
        s = surface_at(e, Hit(wh.t, wh.u, wh.v), wh.prim);
        highlight_t = transmit_highlight(s.mat);
        // First pass: count (as shade does) the feelers to queue.
        uint li_ = 0u;
        for (; li_ < g.counts.z; li_++) {
            vec3 o;
            vec3 l;
            float dist;
            float ndotl;
            if (light_feeler(s.p, s.n, s.ngf, s.weighted, highlight_t, li_, o, l, dist, ndotl)) {
                nf += 1u;
            }
        }
        if (li_ != g.counts.z) {
            loops_cut += 1u;
        }
        kids = spawn(e, s, tr, rf);
    }
    uint nk = bitCount(kids);
    uint fbase = wf_append(1u, nf);
    uint kbase = wf_append(0u, nk);
    bool room = fbase + nf <= cap.y && kbase + nk <= cap.x;
    if (live && !hit) {
        vec3 c;
        uint flags = miss_contribution(e, c) ? NODE_ADD : 0u;
        nodes[range.z + i] = WfNode(c, flags, vec3(0.0), 0u, uvec4(NO_NODE, NO_NODE, 0u, 0u));
    }
    if (hit && room) {
        // Second pass: the feelers themselves (counted already).
        uint counted = stats.shadow;
        uint m = 0u;
        for (uint li_ = 0u; li_ < g.counts.z && m < nf; li_++) {
            vec3 o;
            vec3 l;
            float dist;
            float ndotl;
            if (light_feeler(s.p, s.n, s.ngf, s.weighted, highlight_t, li_, o, l, dist, ndotl)) {
                vec3 term = light_term(s.mat, e.d, s.n, l, ndotl, s.front);
                feelers[fbase + m] = WfFeeler(o, dist, l, li_, term, 0u, vec3(0.0), 0u);
                m += 1u;
            }
        }
        stats.shadow = counted;
        // Children: the next depth's nodes follow this depth's.
        uint next = range.z + range.x;
        uvec2 child = uvec2(NO_NODE);
        uint k = kbase;
        if ((kids & 2u) != 0u) {
            store_ray(range.w + k, rf);
            child.x = next + k;
            k += 1u;
        }
        if ((kids & 1u) != 0u) {
            store_ray(range.w + k, tr);
            child.y = next + k;
        }
        PRECISE vec3 c0 = s.mat.ka.xyz * g.ambient.xyz;
        uint flags = NODE_SHADE | (s.weighted ? NODE_ADD : 0u);
        nodes[range.z + i] = WfNode(c0, flags, s.w, 0u, uvec4(child, fbase, nf));
    }
    flush_counts();
}
#endif

#if WF_STAGE == 3
void main() {
    load_globals();
    shadow_cache_reset();
    uint i = wf_index();
    if (i < range.x) {
        WfFeeler f = feelers[i];
        Ray r = Ray(f.o, f.l);
        RayPre pre = ray_pre(f.l);
        feelers[i].tr = transmittance(r, pre, f.dist, f.light);
        // Every query of this stage is a feeler's (work_shadow).
        work_shadow = work_totals();
    }
    flush_counts();
}
#endif

#if WF_STAGE == 4
void main() {
    load_globals();
    uint i = wf_index();
    if (i < range.x) {
        uint at = range.z + i;
        WfNode n = nodes[at];
        if ((n.flags & NODE_SHADE) != 0u) {
            // shade's sum, light by light in order
            vec3 c = n.c;
            uint end = n.link.z + n.link.w;
            uint m = n.link.z;
            for (; m < end; m++) {
                WfFeeler f = feelers[m];
                c = light_add(c, f.light, f.tr, f.dist, f.term);
            }
            if (m != end) {
                loops_cut += 1u;
            }
            // trace_ray: the local intensity, weighted
            nodes[at].c = mul_exact(n.w, c);
            nodes[at].flags = n.flags & NODE_ADD;
        }
    }
    flush_counts();
}
#endif

#if WF_STAGE == 5
// trace_ray's sum over the tree of the eye ray at node `root`: pop a
// node, add its contribution, push its refracted then its reflected
// child (so reflection is summed first).
vec3 tree_sum(uint root) {
    uint stack[STACK_SIZE];
    stack[0] = root;
    uint sp = 1u;
    vec3 color = vec3(0.0);
    while (sp > 0u) {
        sp -= 1u;
        WfNode n = nodes[stack[sp]];
        if ((n.flags & NODE_ADD) != 0u) {
            color = add_exact(color, n.c);
        }
        if (n.link.y != NO_NODE) {
            stack[sp] = n.link.y;
            sp += 1u;
        }
        if (n.link.x != NO_NODE) {
            stack[sp] = n.link.x;
            sp += 1u;
        }
    }
    if (sp > 0u) {
        loops_cut += 1u;
    }
    return color;
}

void main() {
    load_globals();
    uint i = wf_index();
    if (i < range.x) {
        bool corners = g.image.w == SAMPLING_CORNERS;
        uint lw = corners ? g.image.x + 1u : g.image.x;
        uint x = tile.x + i % tile.z;
        uint y = tile.y + i / tile.z;
        vec3 c;
        if (corners) {
            c = tree_sum(i);
        } else {
            // render.comp's render_pixel
            uint spp = g.image.z;
            PRECISE vec3 sum = vec3(0.0);
            for (uint k = 0u; k < spp; k++) {
                vec3 ck = tree_sum(i * spp + k);
                sum = sum + ck;
            }
            PRECISE float inv = 1.0 / float(spp);
            PRECISE vec3 mean = sum * inv;
            c = mean;
        }
        samples[y * lw + x] = vec4(c, 1.0);
    }
    flush_counts();
}
#endif
