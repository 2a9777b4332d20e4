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

// Intensity arriving along an eye ray.
vec3 trace_ray(Ray ray) {
    uint max_depth = g.trace.x;
    float min_weight = g.params.x;
    float eps = g.params.y;
    vec3 background = g.background.xyz;
    bool spd = spd_counting();
    Entry stack[STACK_SIZE];
    stack[0] = Entry(ray.o, ray.d, vec3(1.0), vec3(0.0), 0u);
    uint sp = 1u;
    PRECISE vec3 color = vec3(0.0);
    while (sp > 0u) {
        sp -= 1u;
        Entry e = stack[sp];
        Ray r = Ray(e.o, e.d);
        RayPre pre = ray_pre(e.d);
        Hit h;
        uint pi;
        if (!closest_hit(r, pre, INF, h, pi)) {
            // Escaping inside an absorbing medium: exp(−σ·∞) = 0.
            if (max_elem(e.medium) <= 0.0) {
                color = color + e.w * background;
            }
            continue;
        }
        if (e.depth == 0u) {
            stats.eye_hit += 1u;
        }
        PRECISE vec3 w = e.w;
        if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(e.medium) > 0.0) {
            PRECISE vec3 x = -e.medium * h.t;
            w = w * vec3(exp_twin(x.x), exp_twin(x.y), exp_twin(x.z));
        }
        Prim prim = load_prim(pi);
        Material mat = materials[prim_material(prim)];
        PRECISE vec3 p = e.o + e.d * h.t;
        vec3 ng;
        vec3 ns;
        normals(prim, p, h, ng, ns);
        bool front = dot3(e.d, ng) < 0.0;
        vec3 n = front ? ns : -ns;
        vec3 ngf = front ? ng : -ng;
        // A ray of weight 0 (SPD counting) adds nothing: its feelers are
        // counted, not traced, and its local intensity is not added.
        bool weighted = max_elem(w) > 0.0;
        vec3 local_ = shade(mat, p, e.d, n, ngf, front, weighted);
        if (weighted) {
            color = color + w * local_;
        }
        if (e.depth >= max_depth) {
            continue;
        }
        PRECISE vec3 refl = mat.kr.xyz;
        vec3 kt = mat.kt.xyz;
        if (HAS_REFRACT && has(FEAT_REFRACT) && max_elem(kt) > 0.0) {
            float ior = mat.kr.w;
            PRECISE float eta = front ? 1.0 / ior : ior;
            vec3 t;
            if (!refract_dir(e.d, n, eta, t)) {
                // Total internal reflection: the transmitted share reflects.
                refl = refl + kt;
            } else {
                PRECISE vec3 wt = w * kt;
                vec3 medium = front ? mat.absorb.xyz : vec3(0.0);
                if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(medium) > 0.0) {
                    wt = wt * offset_absorption(medium, eps, dot3(ngf, t));
                }
                if (max_elem(wt) >= min_weight) {
                    stats.refract += 1u;
                    PRECISE vec3 o = p - ngf * eps;
                    stack[sp] = Entry(o, t, wt, medium, e.depth + 1u);
                    sp += 1u;
                }
            }
        }
        // FEAT_REFLECT is set whenever a material has k_r or k_t > 0, the
        // only ways refl can be positive (or SPD counting spawn a ray):
        // the guard changes nothing.
        if (HAS_REFLECT && (max_elem(refl) > 0.0 || (spd && max_elem(kt) > 0.0))) {
            PRECISE vec3 wr = w * refl;
            vec3 dr = reflect_dir(e.d, n);
            if (HAS_ABSORB && has(FEAT_ABSORB) && max_elem(e.medium) > 0.0) {
                wr = wr * offset_absorption(e.medium, eps, dot3(ngf, dr));
            }
            if (max_elem(wr) >= min_weight) {
                stats.reflect += 1u;
                PRECISE vec3 o = p + ngf * eps;
                stack[sp] = Entry(o, dr, wr, e.medium, e.depth + 1u);
                sp += 1u;
            }
        }
    }
    if (sp > 0u) {
        loops_cut += 1u;
    }
    return color;
}

#endif
