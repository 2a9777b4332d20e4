// The packed scene: std430 structs and the buffers that hold them.
// Twin of src/pack/layout.rs (the only other layout definition): every
// member is a vec4/uvec4 or a uint quadruple, so std430 adds no padding.
#ifndef WHITTED_LAYOUT_GLSL
#define WHITTED_LAYOUT_GLSL

#include "constants.glsl"

// Scene-wide values: camera, grid, counts, render settings.
struct Globals {
    vec4 cam_right;   // xyz: right × half-width of the image plane at distance 1
    vec4 cam_up;      // xyz: up × half-height
    vec4 cam_forward; // xyz: unit viewing direction
    vec4 background;  // rgb
    vec4 ambient;     // rgb I_a
    vec4 grid_min;    // xyz: lower corner; w: 1 when the grid holds any primitive
    vec4 grid_max;    // xyz: upper corner
    vec4 grid_cell;   // xyz: cell size
    uvec4 grid_dims;  // cells per axis; w: total cells
    uvec4 counts;     // x: grid prims, y: all prims, z: lights, w: materials
    uvec4 image;      // x: width, y: height, z: samples per pixel, w: sampling mode
    uvec4 trace;      // x: max depth, y: feature bits, z, w: strata in x, y
    vec4 params;      // x: min weight, y: surface offset
    uvec4 flags;      // x: counting flags (FLAG_*), y: ACCEL_*, z: BVH nodes (under the
                      // octree: OCTREE_WALK_*),
                      // w: light buffer resolution (0: none)
};

// One primitive, 64 bytes; kind_mat = kind (low 4 bits) | material << 4.
// See src/pack/layout.rs for what a, b, c and data hold per kind.
struct Prim {
    uint kind_mat;
    uint data;
    uint cell_lo;  // under the BVH: the rank that settles ties (query.glsl)
    uint cell_hi;
    vec4 a;
    vec4 b;
    vec4 c;
};

uint prim_kind(Prim p) { return p.kind_mat & 15u; }
uint prim_material(Prim p) { return p.kind_mat >> 4; }

// Colours premultiplied: ka = k_a·colour, kd = k_d·colour.
struct Material {
    vec4 ka;
    vec4 kd;
    vec4 ks;     // x: k_sr, y: n_r, z: k_st, w: n_t
    vec4 kr;     // rgb: k_r; w: index of refraction
    vec4 kt;     // rgb: k_t
    vec4 absorb; // rgb: absorption per unit length
};

struct Light {
    vec4 pos;     // xyz: camera-relative position
    vec4 color;   // rgb: I_i
    vec4 falloff; // c1, c2, c3 of f(d) = min(1, 1/(c1 + c2 d + c3 d²))
};

// One node of the 4-wide BVH (src/pack/layout.rs, BvhNode): lane k of
// each field describes child k. lo[axis], hi[axis]: the children's boxes
// on that axis. In the buffer (src/gpu/mod.rs, bvh_for_gpu) link[k] holds
// child k's link in its low BVH_COUNT_SHIFT bits and its count above, and
// count is zero: one texel for both (a node visit reads 7 texels, a pop
// 1). bvh_node returns them apart: count[k] > 0: a leaf of count[k]
// primitives from primitive link[k]; count[k] = 0 and link[k] > 0: the
// node link[k]; both 0: no child (an empty box).
struct BvhNode {
    vec4 lo[3];
    vec4 hi[3];
    uvec4 link;
    uvec4 count;
};

const uint BVH_LINK_MASK = (1u << BVH_COUNT_SHIFT) - 1u;

layout(set = 0, binding = 0, std430) readonly buffer GlobalsBuf { Globals g_buf; };
// A private copy of the globals, read from the buffer once per invocation
// (`load_globals`, first in every entry point) and then used everywhere as
// `g`. llvmpipe loads a storage-buffer word in a loop over the lanes even
// when every lane reads the same word, and the walks read the grid's box,
// cell size and dimensions at every step: the copy took 24 % off the
// device time of 20 000 random spheres on lavapipe (docs/profiling.md,
// "Texel reads"). A uniform buffer instead was 1.5-3x slower there.
Globals g;
void load_globals() { g = g_buf; }
// The primitives, 16-byte words: an array of structures (primitive i's
// four words at 4i) or, under PRIMS_SOA, a structure of arrays (word k of
// primitive i at k·n + i, n the primitive count); read through load_prim.
layout(set = 0, binding = 1, std430) readonly buffer PrimsBuf { uvec4 prim_words[]; };
layout(set = 0, binding = 2, std430) readonly buffer ExtraBuf { vec4 extra[]; };
layout(set = 0, binding = 3, std430) readonly buffer MaterialsBuf { Material materials[]; };
layout(set = 0, binding = 4, std430) readonly buffer LightsBuf { Light lights[]; };
layout(set = 0, binding = 5, std430) readonly buffer CellStartBuf { uint cell_start[]; };
layout(set = 0, binding = 6, std430) readonly buffer RefsBuf { uint refs[]; };
// Binding 11 (7 to 10 are the kernels' own): the BVH, when it is in use.
layout(set = 0, binding = 11, std430) readonly buffer BvhBuf { BvhNode bvh[]; };
// Bindings 12 and 13: the light buffers' cell offsets and primitive lists
// (src/pack/lightbuf.rs), when g.flags.w > 0.
layout(set = 0, binding = 12, std430) readonly buffer LbStartBuf { uint lb_start[]; };
layout(set = 0, binding = 13, std430) readonly buffer LbRefsBuf { uint lb_refs[]; };

uvec3 cell_unpack(uint c) { return uvec3(c & 1023u, (c >> 10) & 1023u, (c >> 20) & 1023u); }

// What the scene uses (Globals::trace.y), as a specialization constant so
// that unused paths compile out. The default (all bits) runs any scene.
layout(constant_id = 2) const uint FEATURES = 0xFFFFFFFFu;
const bool HAS_SPHERE = (FEATURES & FEAT_SPHERE) != 0u;
const bool HAS_PLANE = (FEATURES & FEAT_PLANE) != 0u;
const bool HAS_TRIANGLE = (FEATURES & FEAT_TRIANGLE) != 0u;
const bool HAS_POLYGON = (FEATURES & FEAT_POLYGON) != 0u;
const bool HAS_BOX = (FEATURES & FEAT_BOX) != 0u;
const bool HAS_QUADRIC = (FEATURES & FEAT_QUADRIC) != 0u;
const bool HAS_CONE = (FEATURES & FEAT_CONE) != 0u;
const bool HAS_REFLECT = (FEATURES & FEAT_REFLECT) != 0u;
const bool HAS_REFRACT = (FEATURES & FEAT_REFRACT) != 0u;
const bool HAS_ABSORB = (FEATURES & FEAT_ABSORB) != 0u;
const bool HAS_TRANSMIT_HIGHLIGHT = (FEATURES & FEAT_TRANSMIT_HIGHLIGHT) != 0u;
const bool HAS_FALLOFF = (FEATURES & FEAT_FALLOFF) != 0u;
const bool HAS_SMOOTH = (FEATURES & FEAT_SMOOTH) != 0u;

// The structure the scene walks, as specialization constant 3, so that
// the walks not in use compile out: llvmpipe runs both sides of every
// branch with lanes masked off, so a walk chosen at run time costs every
// other walk's code on each query (docs/profiling.md). Bits 0-3: ACCEL_*;
// bits 4-7: OCTREE_WALK_* under the octree; bit 8: light buffers. The
// default (all bits) decides at run time from g.flags, for any scene; the
// host passes structure_key(g.flags) (src/gpu/mod.rs), never a value that
// differs from the scene's.
layout(constant_id = 3) const uint STRUCTURE = 0xFFFFFFFFu;
const bool STRUCTURE_ANY = STRUCTURE == 0xFFFFFFFFu;

// Bit 9: the primitives lie as a structure of arrays (src/gpu/mod.rs,
// PrimLayout; the default: as structures).
// Never under STRUCTURE_ANY, whose bit 31 no key sets. (One comparison,
// not `&&`: glslang evaluates a short-circuit global initializer with
// run-time code, which it put after main's return in wavefront.comp.)
const bool PRIMS_SOA = (STRUCTURE & 0x80000200u) == 512u;

// Bit 10: the grid's cells as pairs (src/gpu/mod.rs, CellLayout::Pairs;
// the default: offsets and skip bytes, as packed). Pairs: two words per
// cell in cell_start, (start, count) for a cell with two references or
// more, (the reference itself, 1) for one, (skip distance, 0) for an
// empty cell: one load per cell visit instead of two or three, and none
// from refs for a single reference. Grid and hybrid only.
const bool CELLS_PAIRS = (STRUCTURE & 0x80000400u) == 1024u;

// Bits 12-18: the kinds (FEAT_SPHERE … FEAT_CONE, bit k for KIND k) of
// the primitives the structure holds (the first g.counts.x; the others
// are tested against every ray by query_unbounded). The walks test
// their primitives with only these kinds' code: llvmpipe runs every
// kind's test, masked, on each test whatever the kind, so a floor
// polygon among spheres made every sphere test run the polygon's too
// (docs/profiling.md). All kinds under STRUCTURE_ANY.
const uint BOUNDED_KINDS = (STRUCTURE >> 12) & 127u;

// Bit 19: no shadow cache (src/gpu/mod.rs, GpuShadowCache: the default
// on a CPU device). Feelers then walk the structure without testing the
// last blocker first: the same light, other work counters. On llvmpipe
// the cached primitive's test runs, masked, for all 8 lanes before every
// feeler, and the walk runs unless all 8 were answered: 2-7 % more device
// time with the cache (docs/profiling.md). Kept under STRUCTURE_ANY.
const bool SHADOW_CACHE = (STRUCTURE & 0x80080000u) != 0x00080000u;

// Bit 20: the scene has no unbounded primitives (g.counts.x ==
// g.counts.y: no plane, unclipped quadric or giant), so query_unbounded
// compiles out. llvmpipe runs a loop's body once, masked, even when no
// lane enters it: an intersection test of every kind the scene has, on
// every ray and feeler (SPD mount, teapot and tetra have none;
// docs/profiling.md). Never under STRUCTURE_ANY.
const bool NO_UNBOUNDED = (STRUCTURE & 0x80100000u) == 0x00100000u;

// Bits 22-28: the kinds of the unbounded primitives (g.counts.x to
// g.counts.y), which query_unbounded tests with only these kinds' code,
// as the walks test theirs with BOUNDED_KINDS': the floor polygon of the
// random spheres, tested by every ray and feeler, no longer runs a sphere
// test beside its own. All kinds under STRUCTURE_ANY.
const uint UNBOUNDED_KINDS = (STRUCTURE >> 22) & 127u;

// Bit 21: every polygon of the scene is convex (src/gpu/mod.rs,
// layout_key), and convex polygons have neither edge bands nor cells
// (src/pack/polygon.rs), so `polygon` compiles to the all-edges-on-one-side
// loop alone, each vertex read once, as the CPU mirror's convex branch
// does. llvmpipe runs the cells' lookup, the band lists and the crossings
// test, masked, on every polygon test otherwise, each read of `extra` a
// loop over the lanes: the floor polygon of the random spheres is tested
// by every ray and feeler (docs/profiling.md). Never under STRUCTURE_ANY.
const bool CONVEX_POLYGONS = (STRUCTURE & 0x80200000u) == 0x00200000u;

// Bit 29: no cell of the grid has a skip distance of 2 or more
// (src/gpu/mod.rs, grid_jumps; src/pack/grid.rs, jumps_pay caps a dense
// grid's at 1; set too where there is no grid), so grid_traverse's
// empty-space jump compiles out. llvmpipe ran the
// jump's code, masked, at every cell visit of a dense field, where rays
// almost never jump (docs/profiling.md). Never under STRUCTURE_ANY.
const bool NO_JUMPS = (STRUCTURE & 0xA0000000u) == 0x20000000u;

// Bit 11: every array of the scene but the globals is read through a
// uniform texel buffer view of its buffer (bindings 20 to 28): the
// primitives, `extra`, the materials, the lights and the BVH as 16-byte
// texels (R32G32B32A32_UINT), the grid's (or octree's) cell and reference
// lists and the light buffers' as 4-byte ones (R32_UINT), instead of as
// storage buffers. The same values, bit for bit. llvmpipe loads a
// storage-buffer word whose index differs between lanes in a loop over
// the 8 lanes, word by word, each with its bounds check (even where all
// lanes read the same word, as a light's); a texel fetch gathers a texel
// per lane without the loop. Measured on lavapipe: 15-30 % less device
// time for the first four arrays, then 6-25 % more off for the materials
// and lights, `extra`, and the light buffers' lists (docs/profiling.md,
// "Texel reads" and "Every array as texels"). The host sets the bit
// unless `--reads storage` is given or one of the arrays has more texels
// than the device's maxTexelBufferElements (src/gpu/mod.rs, GpuReads).
const bool TEXELS = (STRUCTURE & 0x80000800u) == 2048u;

layout(set = 0, binding = 20) uniform usamplerBuffer prim_texels;
layout(set = 0, binding = 21) uniform usamplerBuffer cell_start_texels;
layout(set = 0, binding = 22) uniform usamplerBuffer refs_texels;
layout(set = 0, binding = 23) uniform usamplerBuffer bvh_texels;
layout(set = 0, binding = 24) uniform usamplerBuffer material_texels;
layout(set = 0, binding = 25) uniform usamplerBuffer light_texels;
layout(set = 0, binding = 26) uniform usamplerBuffer extra_texels;
layout(set = 0, binding = 27) uniform usamplerBuffer lb_start_texels;
layout(set = 0, binding = 28) uniform usamplerBuffer lb_refs_texels;

// Word i of each array, through the texel view or the storage buffer.
uvec4 prim_word(uint i) {
    if (TEXELS) {
        return texelFetch(prim_texels, int(i));
    }
    return prim_words[i];
}

uint cell_start_at(uint i) {
    if (TEXELS) {
        return texelFetch(cell_start_texels, int(i)).x;
    }
    return cell_start[i];
}

uint ref_at(uint i) {
    if (TEXELS) {
        return texelFetch(refs_texels, int(i)).x;
    }
    return refs[i];
}

vec4 extra_at(uint i) {
    if (TEXELS) {
        return uintBitsToFloat(texelFetch(extra_texels, int(i)));
    }
    return extra[i];
}

uint lb_start_at(uint i) {
    if (TEXELS) {
        return texelFetch(lb_start_texels, int(i)).x;
    }
    return lb_start[i];
}

uint lb_ref_at(uint i) {
    if (TEXELS) {
        return texelFetch(lb_refs_texels, int(i)).x;
    }
    return lb_refs[i];
}

// Material i and light i, through the texel view (6 and 3 texels each)
// or the storage buffer: a light's words, the same for all 8 lanes, cost
// llvmpipe the same per-lane loop as any other storage read.
vec4 material_word(uint i, uint k) { return uintBitsToFloat(texelFetch(material_texels, int(6u * i + k))); }

Material material_at(uint i) {
    if (TEXELS) {
        return Material(material_word(i, 0u), material_word(i, 1u), material_word(i, 2u),
                        material_word(i, 3u), material_word(i, 4u), material_word(i, 5u));
    }
    return materials[i];
}

vec4 light_word(uint i, uint k) { return uintBitsToFloat(texelFetch(light_texels, int(3u * i + k))); }

Light light_at(uint i) {
    if (TEXELS) {
        return Light(light_word(i, 0u), light_word(i, 1u), light_word(i, 2u));
    }
    return lights[i];
}

vec4 bvh_word(int k) { return uintBitsToFloat(texelFetch(bvh_texels, k)); }

BvhNode bvh_node(uint i) {
    if (TEXELS) {
        int k = int(8u * i);
        BvhNode n;
        n.lo[0] = bvh_word(k);
        n.lo[1] = bvh_word(k + 1);
        n.lo[2] = bvh_word(k + 2);
        n.hi[0] = bvh_word(k + 3);
        n.hi[1] = bvh_word(k + 4);
        n.hi[2] = bvh_word(k + 5);
        uvec4 child = texelFetch(bvh_texels, k + 6);
        n.link = child & BVH_LINK_MASK;
        n.count = child >> BVH_COUNT_SHIFT;
        return n;
    }
    BvhNode n = bvh[i];
    n.count = n.link >> BVH_COUNT_SHIFT;
    n.link = n.link & BVH_LINK_MASK;
    return n;
}

// Node i's children's links and counts, one word each (bvh_for_gpu):
// the link in the low BVH_COUNT_SHIFT bits, the count above.
uvec4 bvh_children(uint i) {
    if (TEXELS) {
        return texelFetch(bvh_texels, int(8u * i) + 6);
    }
    return bvh[i].link;
}

// Primitive i, from either layout (bit moves only: the same values).
Prim load_prim(uint i) {
    uvec4 h, a, b, c;
    if (PRIMS_SOA) {
        uint n = g.counts.y;
        h = prim_word(i);
        a = prim_word(n + i);
        b = prim_word(2u * n + i);
        c = prim_word(3u * n + i);
    } else {
        h = prim_word(4u * i);
        a = prim_word(4u * i + 1u);
        b = prim_word(4u * i + 2u);
        c = prim_word(4u * i + 3u);
    }
    return Prim(h.x, h.y, h.z, h.w, uintBitsToFloat(a), uintBitsToFloat(b), uintBitsToFloat(c));
}

// The scene's acceleration structure is ACCEL_* accel.
bool uses_accel(uint accel) {
    return STRUCTURE_ANY ? g.flags.y == accel : (STRUCTURE & 15u) == accel;
}

// Under the octree: the walk is OCTREE_WALK_* walk.
bool uses_octree_walk(uint walk) {
    return STRUCTURE_ANY ? g.flags.z == walk : ((STRUCTURE >> 4) & 15u) == walk;
}

// The scene carries light buffers (g.flags.w > 0: their resolution).
bool uses_light_buffers() {
    return STRUCTURE_ANY ? g.flags.w > 0u : (STRUCTURE & 256u) != 0u;
}

// SceneView::has: the scene's own feature bits (read at run time, as the
// CPU does). Where the Rust calls s.has(F), the shader writes
// `HAS_F && has(F)`: identical results whatever FEATURES holds (as long as
// it is a superset of g.trace.y), and the path compiles out when it is not.
bool has(uint feature) { return (g.trace.y & feature) != 0u; }

// SceneView::spd_counting: rays are counted as the SPD counts them.
bool spd_counting() { return (g.flags.x & FLAG_SPD_COUNTING) != 0u; }

// SceneView::shadow_cache: feelers use the shadow cache (compiled in, and
// not turned off by the packed scene's FLAG_NO_SHADOW_CACHE).
bool shadow_cache_on() { return SHADOW_CACHE && (g.flags.x & FLAG_NO_SHADOW_CACHE) == 0u; }

#endif
