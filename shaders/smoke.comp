#version 450
// Plumbing test kernel (owned by the Vulkan layer, not a twin of anything):
// the render kernel's interface (bindings, push constant, specialization
// constants) with a trivial body. Each lattice point writes
// (x, y, image width + feature bits, 1) and counts one eye ray.
#extension GL_GOOGLE_include_directive : require
#include "constants.glsl"

layout(local_size_x_id = 0, local_size_y_id = 1) in;
layout(constant_id = 2) const uint FEATURES = 0u;

layout(std430, set = 0, binding = 0) readonly buffer GlobalsBuf { uvec4 g[13]; };
layout(std430, set = 0, binding = 7) writeonly buffer Samples { vec4 samples[]; };
layout(std430, set = 0, binding = 8) buffer Counts { uint counts[8]; };
layout(push_constant) uniform Push { uvec4 tile; } pc;

void main() {
    uvec2 local = gl_GlobalInvocationID.xy;
    if (local.x >= pc.tile.z || local.y >= pc.tile.w) return;
    uint x = pc.tile.x + local.x;
    uint y = pc.tile.y + local.y;
    uint lw = g[10].x + (g[10].w == SAMPLING_CORNERS ? 1u : 0u);
    samples[y * lw + x] = vec4(float(x), float(y), float(g[10].x + FEATURES), 1.0);
    atomicAdd(counts[0], 1u);
    atomicAdd(counts[4], 2u);
}
