// The counters every render kernel adds to (render.comp and the wavefront
// stages): ray counts (shade.glsl: stats), loops the device cut short
// (query.glsl: loops_cut) and the work counters, summed per subgroup
// before one atomic each. The host zeroes and reads them per submission.
#ifndef WHITTED_COUNTS_GLSL
#define WHITTED_COUNTS_GLSL

#include "shade.glsl"

// [0] eye, [1] eye_hit, [2] reflect, [3] refract, [4] shadow, [5] loops
// cut; [6..12) tests, cells, nodes as 64-bit (low, high) pairs.
layout(set = 0, binding = 8, std430) buffer Counters { uint counts[12]; };

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
    if (subgroupElect()) {
        atomicAdd(counts[0], eye);
        atomicAdd(counts[1], eye_hit);
        atomicAdd(counts[2], reflect_);
        atomicAdd(counts[3], refract_);
        atomicAdd(counts[4], shadow);
        atomicAdd(counts[5], cut);
        // The work counters are 64-bit: low word, and a carry into the
        // high one when the low one wraps.
        if (atomicAdd(counts[6], tests) > 0xFFFFFFFFu - tests) {
            atomicAdd(counts[7], 1u);
        }
        if (atomicAdd(counts[8], cells) > 0xFFFFFFFFu - cells) {
            atomicAdd(counts[9], 1u);
        }
        if (atomicAdd(counts[10], nodes) > 0xFFFFFFFFu - nodes) {
            atomicAdd(counts[11], 1u);
        }
    }
}

#endif
