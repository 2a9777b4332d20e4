// The 3-vector helpers of src/trace/math.rs (its twin), written out in the
// same order of arithmetic. GLSL's built-in dot/length/normalize/cross are
// never used: their order and rounding are the driver's.
#ifndef WHITTED_MATH_GLSL
#define WHITTED_MATH_GLSL

#define INF uintBitsToFloat(0x7F800000u)
#define NEG_INF uintBitsToFloat(0xFF800000u)

// A ray; d is unit length.
struct Ray {
    vec3 o;
    vec3 d;
};

float dot3(vec3 a, vec3 b) {
    precise float r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}

vec3 cross3(vec3 a, vec3 b) {
    precise float x = a.y * b.z - a.z * b.y;
    precise float y = a.z * b.x - a.x * b.z;
    precise float z = a.x * b.y - a.y * b.x;
    return vec3(x, y, z);
}

float length3(vec3 v) {
    precise float r = sqrt(dot3(v, v));
    return r;
}

vec3 normalize3(vec3 v) {
    precise float len = length3(v);
    precise vec3 r = v / len;
    return r;
}

// F::max of the three (Rust: x.max(y).max(z)).
float max_elem(vec3 v) { return max(max(v.x, v.y), v.z); }

#endif
