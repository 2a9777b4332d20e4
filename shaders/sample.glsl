// Sampling: the counter-based hash and eye-ray directions. Twin of
// src/trace/sample.rs; integer arithmetic, so both sides agree exactly.
#ifndef WHITTED_SAMPLE_GLSL
#define WHITTED_SAMPLE_GLSL

#include "precise.glsl"
#include "layout.glsl"
#include "math.glsl"

// lowbias32 (Chris Wellons): a 32-bit integer hash with good avalanche.
uint hash(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// A reproducible number in [0, 1) for (pixel, sample, dimension).
// (`sample` is a GLSL keyword: the sample index is `s`.)
float rand01(uint pixel, uint s, uint dim) {
    uint h = hash(pixel ^ hash((s * 2u + dim) ^ 0x9e3779b9u));
    PRECISE float r = float(h >> 8) * (1.0 / 16777216.0);
    return r;
}

// Position of sample s inside pixel (px, py), in pixel units from the
// image's top-left corner: the centre, or a jittered stratum of nx × ny.
vec2 sample_pos(Globals g, uint px, uint py, uint s) {
    if (g.image.w == SAMPLING_JITTER) {
        uint nx = g.trace.z;
        uint ny = g.trace.w;
        uint pixel = py * g.image.x + px;
        PRECISE float sx = float(s % nx) + rand01(pixel, s, 0u);
        PRECISE float sy = float(s / nx) + rand01(pixel, s, 1u);
        PRECISE float x = float(px) + sx / float(nx);
        PRECISE float y = float(py) + sy / float(ny);
        return vec2(x, y);
    } else {
        PRECISE float x = float(px) + 0.5;
        PRECISE float y = float(py) + 0.5;
        return vec2(x, y);
    }
}

// Unit direction of the eye ray through image position (x, y) (pixel units;
// (0, 0) is the top-left corner, (width, height) the bottom-right).
vec3 eye_dir(Globals g, float x, float y) {
    PRECISE float sx = x / float(g.image.x) * 2.0 - 1.0;
    PRECISE float sy = 1.0 - y / float(g.image.y) * 2.0;
    vec3 f = g.cam_forward.xyz;
    vec3 r = g.cam_right.xyz;
    vec3 u = g.cam_up.xyz;
    PRECISE vec3 d = f + r * sx + u * sy;
    return normalize3(d);
}

#endif
