// The 3-vector helpers of src/trace/math.rs (its twin), written out in the
// same order of arithmetic. GLSL's built-in dot/length/normalize/cross are
// never used: their order and rounding are the driver's.
#ifndef WHITTED_MATH_GLSL
#define WHITTED_MATH_GLSL

#include "precise.glsl"

#define INF uintBitsToFloat(0x7F800000u)
#define NEG_INF uintBitsToFloat(0xFF800000u)

// A ray; d is unit length.
struct Ray {
    vec3 o;
    vec3 d;
};

float dot3(vec3 a, vec3 b) {
    PRECISE float r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}

vec3 cross3(vec3 a, vec3 b) {
    PRECISE float x = a.y * b.z - a.z * b.y;
    PRECISE float y = a.z * b.x - a.x * b.z;
    PRECISE float z = a.x * b.y - a.y * b.x;
    return vec3(x, y, z);
}

float length3(vec3 v) {
    PRECISE float r = sqrt(dot3(v, v));
    return r;
}

vec3 normalize3(vec3 v) {
    PRECISE float len = length3(v);
    PRECISE vec3 r = v / len;
    return r;
}

// Whether x is infinite or a NaN, by its bits (a GPU compiler may assume
// neither and drop isinf/isnan).
bool not_finite(float x) {
    return (floatBitsToUint(x) & 0x7f800000u) == 0x7f800000u;
}

// The unit vector along v where normalize3 fails (a squared length that
// underflows or overflows): v scaled by its largest component first; an
// infinite component gives its axis; zero (or a subnormal) or a NaN gives
// +z. Twin of V3::direction (src/trace/math.rs).
vec3 direction3(vec3 v) {
    bvec3 bad = bvec3(not_finite(v.x), not_finite(v.y), not_finite(v.z));
    if (any(bad)) {
        bool nan = (bad.x && (floatBitsToUint(v.x) & 0x007fffffu) != 0u) ||
                   (bad.y && (floatBitsToUint(v.y) & 0x007fffffu) != 0u) ||
                   (bad.z && (floatBitsToUint(v.z) & 0x007fffffu) != 0u);
        if (nan) {
            return vec3(0.0, 0.0, 1.0);
        }
        vec3 s = vec3(bad.x ? sign(v.x) : 0.0, bad.y ? sign(v.y) : 0.0, bad.z ? sign(v.z) : 0.0);
        return normalize3(s);
    }
    vec3 a = abs(v);
    float m = max(max(a.x, a.y), a.z);
    // Below the least normal float, as zero (a device may flush
    // subnormals).
    if (m < uintBitsToFloat(0x00800000u)) {
        return vec3(0.0, 0.0, 1.0);
    }
    PRECISE vec3 u = v / m;
    return normalize3(u);
}

// exp, log and pow from +, −, ×, ÷, floor and bit moves alone: twins of
// exp_f32, log_f32 and pow_f32 in src/trace/math.rs (Cephes' expf and
// logf), bit for bit where the device rounds IEEE and does not fuse
// (lavapipe). The built-in exp and pow are the driver's, a few ULP from
// any libm.
const float LOG2E = 1.442695;
const float LN2_HI = 0.693359375;
const float LN2_LO = -2.1219444e-4;

float exp_twin(float z) {
    if (isnan(z)) {
        return z;
    }
    if (z <= -87.0) {
        return 0.0;
    }
    if (z >= 88.0) {
        return INF;
    }
    PRECISE float k = floor(z * LOG2E + 0.5);
    PRECISE float x = z - k * LN2_HI - k * LN2_LO;
    PRECISE float z2 = x * x;
    PRECISE float p = ((((0.00019875691 * x + 0.0013981999) * x + 0.008333452) * x
        + 0.041665796) * x + 0.16666666) * x + 0.5;
    PRECISE float y = p * z2 + x + 1.0;
    PRECISE float r = y * uintBitsToFloat(uint(int(k) + 127) << 23);
    return r;
}

float log_twin(float x) {
    if (isnan(x) || x < 0.0) {
        return uintBitsToFloat(0x7FC00000u);
    }
    if (x == 0.0) {
        return NEG_INF;
    }
    if (isinf(x)) {
        return x;
    }
    x = max(x, uintBitsToFloat(0x00800000u));
    uint bits = floatBitsToUint(x);
    int e = int((bits >> 23) & 0xFFu) - 126;
    PRECISE float m = uintBitsToFloat((bits & 0x007FFFFFu) | 0x3F000000u);
    if (m < 0.70710677) {
        e -= 1;
        m = m + m - 1.0;
    } else {
        m = m - 1.0;
    }
    PRECISE float z = m * m;
    PRECISE float p = (((((((0.070376836 * m - 0.1151461) * m + 0.116769984) * m
        - 0.12420141) * m + 0.14249323) * m - 0.16668057) * m
        + 0.20000714) * m - 0.24999994) * m + 0.3333333;
    PRECISE float fe = float(e);
    PRECISE float y = p * m * z;
    y = y + LN2_LO * fe;
    y = y + -0.5 * z;
    PRECISE float r = m + y;
    r = r + LN2_HI * fe;
    return r;
}

// x^y for x > 0 (a cosine and a shininess).
float pow_twin(float x, float y) {
    PRECISE float a = y * log_twin(x);
    return exp_twin(a);
}

// F::max of the three (Rust: x.max(y).max(z)).
float max_elem(vec3 v) { return max(max(v.x, v.y), v.z); }

#endif
