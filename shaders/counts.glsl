// The counters every render kernel adds to (render.comp and the wavefront
// stages): ray counts (shade.glsl: stats), loops the device cut short
// (query.glsl: loops_cut) and the work counters, summed per subgroup
// before one atomic each. The host zeroes and reads them per submission.
#ifndef WHITTED_COUNTS_GLSL
#define WHITTED_COUNTS_GLSL

#include "shade.glsl"

// [0] eye, [1] eye_hit, [2] reflect, [3] refract, [4] shadow, [5] loops
// cut; [6..12) tests, cells, nodes as 64-bit (low, high) pairs; [12..18)
// the eye rays' share of them and [18..24) the feelers' (work_eye,
// work_shadow), alike; [24] the deepest walk stack (work_stack). Host:
// gpu::read_counts (COUNTERS_BYTES).
layout(set = 0, binding = 8, std430) buffer Counters { uint counts[25]; };

// Adds v to the 64-bit counter at counts[at] (low word) and counts[at + 1]
// (high word): a carry into the high word when the low one wraps.
void add_wide(uint at, uint v) {
    if (atomicAdd(counts[at], v) > 0xFFFFFFFFu - v) {
        atomicAdd(counts[at + 1u], 1u);
    }
}

// Adds this invocation's counters to the buffer. Every invocation of the
// dispatch (in range or not) must reach it: subgroup operations.
void flush_counts() {
    uint eye = subgroupAdd(stats.eye);
    uint eye_hit = subgroupAdd(stats.eye_hit);
    uint reflect_ = subgroupAdd(stats.reflect);
    uint refract_ = subgroupAdd(stats.refract);
    uint shadow = subgroupAdd(stats.shadow);
    uint cut = subgroupAdd(loops_cut);
    uint tests = subgroupAdd(work_tests);
    uint cells = subgroupAdd(work_cells);
    uint nodes = subgroupAdd(work_nodes);
    uvec3 eye_ = subgroupAdd(work_eye);
    uvec3 shadow_ = subgroupAdd(work_shadow);
    uint stack_ = subgroupMax(work_stack);
    if (subgroupElect()) {
        atomicAdd(counts[0], eye);
        atomicAdd(counts[1], eye_hit);
        atomicAdd(counts[2], reflect_);
        atomicAdd(counts[3], refract_);
        atomicAdd(counts[4], shadow);
        atomicAdd(counts[5], cut);
        // The work counters are 64-bit.
        add_wide(6u, tests);
        add_wide(8u, cells);
        add_wide(10u, nodes);
        for (uint k = 0u; k < 3u; k++) {
            add_wide(12u + 2u * k, eye_[k]);
            add_wide(18u + 2u * k, shadow_[k]);
        }
        atomicMax(counts[24], stack_);
    }
}

#endif
