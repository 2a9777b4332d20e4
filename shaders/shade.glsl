// The local model, twin of src/trace/shade.rs:
// I_L = k_a I_a + Σ_i I_i f(d) S_i [k_d (N·L) + k_sr (V·R_L)^n_r + k_st (V·T_L)^n_t]
// with one shadow feeler per light (S_i: product of the k_t of what it crosses).
#ifndef WHITTED_SHADE_GLSL
#define WHITTED_SHADE_GLSL

#include "precise.glsl"
#include "accel.glsl"

// Ray counts as the SPD defines them (Rust: trace::RayStats), per
// invocation, incremented at exactly the places the CPU increments them.
struct RayStats {
    uint eye;
    uint eye_hit;
    uint reflect;
    uint refract;
    uint shadow;
};
RayStats stats = RayStats(0u, 0u, 0u, 0u, 0u);

// Direction of light refracted through a surface with unit normal n (facing
// against i); false on total internal reflection. eta = n_incident / n_transmitted.
bool refract_dir(vec3 i, vec3 n, float eta, out vec3 t) {
    PRECISE float cosi = -dot3(n, i);
    PRECISE float k = 1.0 - eta * eta * (1.0 - cosi * cosi);
    if (k < 0.0) {
        return false;
    }
    PRECISE vec3 r = i * eta + n * (eta * cosi - sqrt(k));
    t = normalize3(r);
    return true;
}

// Mirror direction of i about unit normal n.
vec3 reflect_dir(vec3 i, vec3 n) {
    PRECISE vec3 r = i - n * (2.0 * dot3(i, n));
    return normalize3(r);
}

// Whether a surface with material mat makes a transmission highlight
// (k_st > 0 and the scene uses them).
bool transmit_highlight(Material mat) {
    return HAS_TRANSMIT_HIGHLIGHT && has(FEAT_TRANSMIT_HIGHLIGHT) && mat.ks.z > 0.0;
}

// The shadow feeler from p towards light li_ (first half of shade's loop
// body): false when none is traced (the surface faces away and makes no
// transmission highlight, or the ray carries no weight); counts it as the
// SPD does. o, l, dist: the feeler; ndotl: N·L.
bool light_feeler(vec3 p, vec3 n, vec3 ngf, bool weighted, bool highlight_t, uint li_,
                  out vec3 o, out vec3 l, out float dist, out float ndotl) {
    float eps = g.params.y;
    Light light = light_at(li_);
    PRECISE vec3 lv = light.pos.xyz - p;
    PRECISE float dist_ = length3(lv);
    PRECISE vec3 l_ = lv / dist_;
    PRECISE float ndotl_ = dot3(n, l_);
    dist = dist_;
    l = l_;
    ndotl = ndotl_;
    o = p;
    bool facing = ndotl_ > 0.0;
    if (!facing && !highlight_t) {
        return false;
    }
    // The SPD counts a feeler only towards a light the surface faces
    // (its rule 10): the transmission highlight's are not counted.
    if (facing || !spd_counting()) {
        stats.shadow += 1u;
    }
    if (!weighted) {
        return false;
    }
    PRECISE vec3 o_;
    if (dot3(l_, ngf) > 0.0) {
        o_ = p + ngf * eps;
    } else {
        o_ = p - ngf * eps;
    }
    o = o_;
    return true;
}

// The bracket of the local model for one light (light direction l,
// ndotl = N·L): k_d (N·L) + k_sr (V·R_L)^n_r where the surface faces the
// light, k_st (V·T_L)^n_t (the transmission highlight) where it does not.
vec3 light_term(Material mat, vec3 d, vec3 n, vec3 l, float ndotl, bool front) {
    vec3 v = -d;
    float ksr = mat.ks.x;
    float kst = mat.ks.z;
    PRECISE vec3 term = vec3(0.0);
    if (ndotl > 0.0) {
        term = mat.kd.xyz * ndotl;
        if (ksr > 0.0) {
            PRECISE vec3 r = n * (2.0 * ndotl) - l;
            PRECISE float vr = dot3(v, r);
            if (vr > 0.0) {
                PRECISE float spec = ksr * pow_twin(vr, mat.ks.y);
                term = term + vec3(spec);
            }
        }
    } else if (HAS_TRANSMIT_HIGHLIGHT) {
        // The light is on the far side: light refracted through the
        // surface towards the viewer makes the transmission highlight.
        // (Reached only when transmit_highlight(mat), as on the CPU.)
        float ior = mat.kr.w;
        PRECISE float eta = front ? ior : 1.0 / ior;
        vec3 t;
        if (refract_dir(-l, -n, eta, t)) {
            PRECISE float vt = dot3(v, t);
            if (vt > 0.0) {
                PRECISE float spec = kst * pow_twin(vt, mat.ks.w);
                term = term + vec3(spec);
            }
        }
    }
    return term;
}

// c plus light li_'s share, I_i f(d) S_i term, where its feeler of length
// dist let through tr (S_i); c itself where tr is zero.
vec3 light_add(vec3 c, uint li_, vec3 tr, float dist, vec3 term) {
    if (max_elem(tr) <= 0.0) {
        return c;
    }
    Light light = light_at(li_);
    PRECISE vec3 li = light.color.xyz * tr;
    if (HAS_FALLOFF && has(FEAT_FALLOFF)) {
        vec3 f = light.falloff.xyz;
        PRECISE float att = 1.0 / (f.x + f.y * dist + f.z * dist * dist);
        li = li * min(att, 1.0);
    }
    PRECISE vec3 sum = c + li * term;
    return sum;
}

// Local intensity at p seen along d. n: shading normal facing the viewer;
// ngf: geometric normal facing the viewer; front: the viewer is on the
// outside of the surface. weighted: the ray carries weight; a ray of
// weight 0 (SPD counting) only counts the feelers it would cast (Rust:
// trace::shade::shade). The loop body is split in light_feeler,
// light_term and light_add so that the wavefront kernel
// (shaders/wavefront.glsl) runs the same arithmetic stage by stage.
vec3 shade(Material mat, vec3 p, vec3 d, vec3 n, vec3 ngf, bool front, bool weighted) {
    PRECISE vec3 c = mat.ka.xyz * g.ambient.xyz;
    bool highlight_t = transmit_highlight(mat);
    // The feelers' work is theirs (work_shadow).
    uvec3 before = work_totals();
    uint li_ = 0u;
    for (; li_ < g.counts.z; li_++) {
        vec3 o;
        vec3 l;
        float dist;
        float ndotl;
        if (!light_feeler(p, n, ngf, weighted, highlight_t, li_, o, l, dist, ndotl)) {
            continue;
        }
        Ray sray = Ray(o, l);
        RayPre pre = ray_pre(l);
        vec3 tr = transmittance(sray, pre, dist, li_);
        if (max_elem(tr) <= 0.0) {
            continue;
        }
        vec3 term = light_term(mat, d, n, l, ndotl, front);
        c = light_add(c, li_, tr, dist, term);
    }
    if (li_ != g.counts.z) {
        loops_cut += 1u;
    }
    work_shadow += work_totals() - before;
    return c;
}

#endif
