//! The local model, twin of `shaders/shade.glsl`:
//! I_L = k_a I_a + Σ_i I_i f(d) S_i [k_d (N·L) + k_sr (V·R_L)^n_r + k_st (V·T_L)^n_t]
//! with one shadow feeler per light (S_i: product of the k_t of what it crosses).

use super::accel::transmittance;
use super::intersect::RayPre;
use super::math::{Ray, Real, V3};
use super::query::Work;
use super::{RayStats, SceneView};
use crate::constants::*;
use crate::pack::layout::Material;

/// Direction of light refracted through a surface with unit normal `n`
/// (facing against `i`), or `None` on total internal reflection.
/// `eta` = n_incident / n_transmitted.
#[inline(always)]
pub fn refract_dir<F: Real>(i: V3<F>, n: V3<F>, eta: F) -> Option<V3<F>> {
    let cosi = -n.dot(i);
    let k = F::one() - eta * eta * (F::one() - cosi * cosi);
    if k < F::zero() {
        return None;
    }
    Some((i * eta + n * (eta * cosi - k.sqrt())).normalize())
}

/// Mirror direction of `i` about unit normal `n`.
#[inline(always)]
pub fn reflect_dir<F: Real>(i: V3<F>, n: V3<F>) -> V3<F> {
    (i - n * (F::of(2.0) * i.dot(n))).normalize()
}

/// Local intensity at `p` seen along `d`. `n`: shading normal facing the
/// viewer; `ngf`: geometric normal facing the viewer; `front`: the viewer is
/// on the outside of the surface. `weighted`: the ray carries weight, so
/// its local intensity is wanted; for a ray of weight 0 (SPD counting)
/// the feelers it would cast are counted, not traced (the count depends
/// on the light's side alone), and what is returned is not to be used.
#[allow(clippy::too_many_arguments)]
pub fn shade<F: Real>(
    s: &SceneView,
    mat: &Material,
    p: V3<F>,
    d: V3<F>,
    n: V3<F>,
    ngf: V3<F>,
    front: bool,
    weighted: bool,
    stats: &mut RayStats,
    work: &mut Work,
) -> V3<F> {
    let g = s.globals;
    let eps = F::of(g.params[1]);
    let mut c = V3::<F>::of(&mat.ka).mul_elem(V3::of(&g.ambient));
    let v = -d;
    let kd = V3::<F>::of(&mat.kd);
    let ksr = F::of(mat.ks[0]);
    let kst = F::of(mat.ks[2]);
    let highlight_t = s.has(FEAT_TRANSMIT_HIGHLIGHT) && kst > F::zero();
    // The feelers' work is theirs (`Work::shadow`).
    let before = work.totals();
    for (li_index, light) in s.lights.iter().enumerate() {
        let lv = V3::<F>::of(&light.pos) - p;
        let dist = lv.length();
        let l = lv / dist;
        let ndotl = n.dot(l);
        let facing = ndotl > F::zero();
        if !facing && !highlight_t {
            continue;
        }
        // The SPD counts a feeler only towards a light the surface faces
        // (its rule 10): the transmission highlight's are not counted.
        if facing || !s.spd_counting() {
            stats.shadow += 1;
        }
        if !weighted {
            continue;
        }
        let o = if l.dot(ngf) > F::zero() {
            p + ngf * eps
        } else {
            p - ngf * eps
        };
        let sray = Ray { o, d: l };
        let pre = RayPre::new(l, s.has(FEAT_TRIANGLE));
        let tr = transmittance(s, &sray, &pre, dist, li_index, work);
        if tr.max_elem() <= F::zero() {
            continue;
        }
        let mut li = V3::<F>::of(&light.color).mul_elem(tr);
        if s.has(FEAT_FALLOFF) {
            let f = V3::<F>::of(&light.falloff);
            let att = F::one() / (f.x + f.y * dist + f.z * dist * dist);
            li *= att.min(F::one());
        }
        let mut term = V3::zero();
        if facing {
            term = kd * ndotl;
            if ksr > F::zero() {
                let r = n * (F::of(2.0) * ndotl) - l;
                let vr = v.dot(r);
                if vr > F::zero() {
                    term += V3::splat(ksr * vr.pow_t(F::of(mat.ks[1])));
                }
            }
        } else {
            // The light is on the far side: light refracted through the
            // surface towards the viewer makes the transmission highlight.
            let ior = F::of(mat.kr[3]);
            let eta = if front { ior } else { F::one() / ior };
            if let Some(t) = refract_dir(-l, -n, eta) {
                let vt = v.dot(t);
                if vt > F::zero() {
                    term += V3::splat(kst * vt.pow_t(F::of(mat.ks[3])));
                }
            }
        }
        c += li.mul_elem(term);
    }
    work.credit_shadow(before);
    c
}
