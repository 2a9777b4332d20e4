// The ray tree, walked iteratively: twin of src/trace/tree.rs.
//
// An explicit stack in a fixed order (no recursion): pop a ray, find its
// closest hit, add its weighted local intensity, then push the refracted
// ray and after it the reflected one (so reflection is walked first). A
// ray's weight is the product of the k_r/k_t along its path times its
// medium's Beer–Lambert attenuation, so I = I_L + k_r I_R + k_t I_T is
// summed in place. A branch ends at the depth limit or when its weight
// (largest channel) falls under min weight.
//
// Under SPD counting (spd_counting(), docs/spd.md) a surface with k_t > 0
// also spawns a reflection ray where k_r = 0, as the SPD's reference
// tracer did; its weight is 0, so it and its subtree are traced for the
// ray counts only and add nothing to the image: their closest hits are
// found, their shadow feelers only counted.
#ifndef WHITTED_TRACE_GLSL
#define WHITTED_TRACE_GLSL

#include "precise.glsl"
#include "shade.glsl"

struct Entry {
    vec3 o;
    vec3 d;
    vec3 w;      // accumulated weight of this ray's contribution
    vec3 medium; // absorption coefficient of the medium the ray travels in
    uint depth;
};

// exp(−σ·ε/|cos|): the absorption over the stretch a ray spawned into a
// medium skips (twin of offset_absorption in src/trace/tree.rs).
vec3 offset_absorption(vec3 sigma, float eps, float cosn) {
    PRECISE float c = max(abs(cosn), 1e-3);
    PRECISE float delta = eps / c;
    PRECISE vec3 x = -sigma * delta;
    return vec3(exp_twin(x.x), exp_twin(x.y), exp_twin(x.z));
}

// The contribution of a ray that hits nothing: the background, weighted,
// unless it escapes inside an absorbing medium (exp(-sigma * inf) = 0):
// false then.
bool miss_contribution(Entry e, out vec3 c) {
    PRECISE vec3 c_ = e.w * g.background.xyz;
    c = c_;
    return max_elem(e.medium) <= 0.0;
}

// What a ray's closest hit shows: the surface, its material, and the
// weight the ray arrives with (after the medium's absorption).
struct Surface {
    Material mat;
    vec3 p;
    vec3 n;        // shading normal facing the viewer
    vec3 ngf;      // geometric normal facing the viewer
    bool front;    // the viewer is outside the surface
    vec3 w;        // the ray's weight at the hit
    bool weighted; // w > 0: a ray of weight 0 (SPD counting) adds nothing
};

Surface surface_at(Entry e, Hit h, uint pi) {
    PRECISE vec3 w = e.w;
    if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(e.medium) > 0.0) {
        PRECISE vec3 x = -e.medium * h.t;
        w = w * vec3(exp_twin(x.x), exp_twin(x.y), exp_twin(x.z));
    }
    Prim prim = load_prim(pi);
    Material mat = material_at(prim_material(prim));
    PRECISE vec3 p = e.o + e.d * h.t;
    vec3 ng;
    vec3 ns;
    normals(prim, p, h, ng, ns);
    bool front = dot3(e.d, ng) < 0.0;
    vec3 n = front ? ns : -ns;
    vec3 ngf = front ? ng : -ng;
    vec3 wv = w;
    vec3 pv = p;
    return Surface(mat, pv, n, ngf, front, wv, max_elem(wv) > 0.0);
}

// The rays a hit spawns (none at the depth limit): bit 0 of the result,
// the refracted ray tr; bit 1, the reflected ray rf. Counts them.
uint spawn(Entry e, Surface s, out Entry tr, out Entry rf) {
    uint kids = 0u;
    if (e.depth >= g.trace.x) {
        return kids;
    }
    float min_weight = g.params.x;
    float eps = g.params.y;
    PRECISE vec3 refl = s.mat.kr.xyz;
    vec3 kt = s.mat.kt.xyz;
    if (HAS_REFRACT && has(FEAT_REFRACT) && max_elem(kt) > 0.0) {
        float ior = s.mat.kr.w;
        PRECISE float eta = s.front ? 1.0 / ior : ior;
        vec3 t;
        if (!refract_dir(e.d, s.n, eta, t)) {
            // Total internal reflection: the transmitted share reflects.
            refl = refl + kt;
        } else {
            PRECISE vec3 wt = s.w * kt;
            vec3 medium = s.front ? s.mat.absorb.xyz : vec3(0.0);
            if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(medium) > 0.0) {
                wt = wt * offset_absorption(medium, eps, dot3(s.ngf, t));
            }
            if (max_elem(wt) >= min_weight) {
                stats.refract += 1u;
                PRECISE vec3 o = s.p - s.ngf * eps;
                tr = Entry(o, t, wt, medium, e.depth + 1u);
                kids |= 1u;
            }
        }
    }
    // FEAT_REFLECT is set whenever a material has k_r or k_t > 0, the
    // only ways refl can be positive (or SPD counting spawn a ray):
    // the guard changes nothing.
    if (HAS_REFLECT && (max_elem(refl) > 0.0 || (spd_counting() && max_elem(kt) > 0.0))) {
        PRECISE vec3 wr = s.w * refl;
        vec3 dr = reflect_dir(e.d, s.n);
        if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(e.medium) > 0.0) {
            wr = wr * offset_absorption(e.medium, eps, dot3(s.ngf, dr));
        }
        if (max_elem(wr) >= min_weight) {
            stats.reflect += 1u;
            PRECISE vec3 o = s.p + s.ngf * eps;
            rf = Entry(o, dr, wr, e.medium, e.depth + 1u);
            kids |= 2u;
        }
    }
    return kids;
}

// a + b, w·b, and a + w·b, exact. (Functions, so that glslang's `precise`
// propagation stops at the call: following a precise sum back into a
// Surface that surface_at returned crashes glslang 11-14.)
vec3 add_exact(vec3 a, vec3 b) {
    PRECISE vec3 r = a + b;
    return r;
}

vec3 mul_exact(vec3 w, vec3 b) {
    PRECISE vec3 r = w * b;
    return r;
}

vec3 add_weighted(vec3 a, vec3 w, vec3 b) {
    return add_exact(a, mul_exact(w, b));
}

// Intensity arriving along an eye ray. (The wavefront kernel,
// shaders/wavefront.comp, runs the same steps as separate dispatches;
// render.comp's render_lane repeats this loop's body, between samples of
// several points: a change here changes it there.)
//
// The ray walked now, `e`, is a plain variable: a hit's reflected ray
// becomes the next `e` at once, and only refracted rays wait in the
// stack, to be popped when a branch ends (the order of pushing the
// refracted ray and then the reflected one and popping the reflected
// first, as the CPU twin walks it). llvmpipe reads and writes a private
// array at a varying index lane by lane, 13 words an entry, and runs
// each access, masked, on every pass of the loop: before, every ray went
// through the stack (a pop and two pushes a pass); now a pass has one pop
// and one push, and a scene without refraction (no FEAT_REFRACT: nothing
// is ever pushed) has no stack at all (docs/profiling.md, "The reflected
// ray out of the stack").
vec3 trace_ray(Ray ray) {
    Entry stack[STACK_SIZE];
    uint sp = 0u;
    Entry e = Entry(ray.o, ray.d, vec3(1.0), vec3(0.0), 0u);
    // Whether `e` holds the next ray (else the stack's top, if any).
    bool have = true;
    vec3 color = vec3(0.0);
    while (have || (HAS_REFRACT && sp > 0u)) {
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
        Surface s = surface_at(e, h, pi);
        shadow_cache_at_depth(e.depth);
        vec3 local_ = shade(s.mat, s.p, e.d, s.n, s.ngf, s.front, s.weighted);
        if (s.weighted) {
            color = add_weighted(color, s.w, local_);
        }
        Entry tr;
        Entry rf;
        uint kids = spawn(e, s, tr, rf);
        // The refracted ray waits below what the reflected one spawns:
        // reflection is walked first.
        if (HAS_REFRACT && (kids & 1u) != 0u) {
            stack[sp] = tr;
            sp += 1u;
        }
        if ((kids & 2u) != 0u) {
            e = rf;
            have = true;
        }
    }
    if (have || sp > 0u) {
        loops_cut += 1u;
    }
    return color;
}

#endif
