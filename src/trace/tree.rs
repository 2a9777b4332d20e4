//! The ray tree, walked iteratively: twin of `shaders/trace.glsl`.
//!
//! An explicit stack in a fixed order (the GPU has no recursion and must
//! reproduce it): pop a ray, find its closest hit, add its weighted local
//! intensity, then push the refracted ray and after it the reflected one
//! (so reflection is walked first). The reflected ray is not pushed but
//! walked next straight away, the same order, here and in the shader:
//! here it saves a store and a stalled reload per ray, there llvmpipe's
//! lane-by-lane copies of a 13-word entry (docs/profiling.md, "The
//! reflected ray out of the stack"). A ray's weight is the product of the
//! k_r/k_t along its path times its medium's Beer–Lambert attenuation, so
//! I = I_L + k_r I_R + k_t I_T is summed in place. A branch ends at the
//! depth limit or when its weight (largest channel) falls under min weight.
//!
//! Under SPD counting (`SceneView::spd_counting`, docs/spd.md) a surface
//! with k_t > 0 also spawns a reflection ray where k_r = 0, as the SPD's
//! reference tracer did; its weight is 0, so it and its subtree are traced
//! for the ray counts only and add nothing to the image: their closest
//! hits are found (what they spawn depends on them), their shadow feelers
//! only counted (whether a feeler is cast depends on the light's side, not
//! on what it would meet).

use super::accel::closest_hit;
use super::intersect::{normals, Hit, RayPre};
use super::math::{Ray, Real, V3};
use super::query::Work;
use super::shade::{reflect_dir, refract_dir, shade};
use super::{RayStats, SceneView};
use crate::constants::*;
use arrayvec::ArrayVec;

#[derive(Clone, Copy, Debug)]
struct Entry<F> {
    o: V3<F>,
    d: V3<F>,
    /// Accumulated weight of this ray's contribution.
    w: V3<F>,
    /// Absorption coefficient of the medium the ray travels in.
    medium: V3<F>,
    depth: u32,
}

/// exp(−σ·ε/|cos|), cos = N·d: the absorption over the stretch a ray
/// spawned into a medium skips, its origin sitting ε off the surface along
/// the normal (exact for a flat surface; |cos| is taken as at least 1e-3,
/// so a grazing ray skips at most 1000 ε). Without it a slab's
/// transmission erred by σ·ε/cos relative (docs/accuracy.md).
#[inline(always)]
fn offset_absorption<F: Real>(sigma: V3<F>, eps: F, cosn: F) -> V3<F> {
    let c = cosn.abs().max(F::of(1e-3));
    let delta = eps / c;
    (-sigma * delta).map(|x| x.exp_t())
}

/// Intensity arriving along an eye ray.
pub fn trace_ray<F: Real>(
    s: &SceneView,
    ray: Ray<F>,
    stats: &mut RayStats,
    work: &mut Work,
) -> V3<F> {
    trace_ray_from(s, ray, None, stats, work)
}

/// Intensity arriving along an eye ray whose closest hit is `first` when
/// given (found beforehand by a packet: `trace::packet`), found here
/// otherwise.
pub fn trace_ray_from<F: Real>(
    s: &SceneView,
    ray: Ray<F>,
    mut first: Option<Option<(Hit<F>, u32)>>,
    stats: &mut RayStats,
    work: &mut Work,
) -> V3<F> {
    let g = s.globals;
    let max_depth = g.trace[0];
    let min_weight = F::of(g.params[0]);
    let eps = F::of(g.params[1]);
    let background = V3::<F>::of(&g.background);
    let spd = s.spd_counting();
    // The ray walked now (`e`): the eye ray, then the reflected one when
    // there is one, kept out of the stack (pushed last, it would be popped
    // first), so that a tree without refraction never touches the stack.
    // The stack is not zeroed (`ArrayVec`): that cost every eye ray a
    // memset of 884 bytes and a stalled load after it (BENCHMARKS.md, "The
    // ray tree's stack"). `e` is a plain variable, overwritten in place:
    // held as an `Option<Entry>` for the next ray, it went through memory
    // in pieces and came back as one 32-byte load, which the store buffer
    // cannot forward (the stall held 15 % of this function's samples on
    // SPD tetra; BENCHMARKS.md, "The SPD suite times the image").
    let mut e = Entry {
        o: ray.o,
        d: ray.d,
        w: V3::splat(F::one()),
        medium: V3::zero(),
        depth: 0,
    };
    let mut stack = ArrayVec::<Entry<F>, { STACK_SIZE as usize }>::new();
    let mut color = V3::zero();
    'tree: loop {
        // This ray's part of the tree; it ends by walking its reflection
        // next (`continue 'tree`) or by leaving the block, after which the
        // stack's top is next and an empty stack ends the tree.
        'ray: {
            let r = Ray { o: e.o, d: e.d };
            let found = first.take().unwrap_or_else(|| {
                let pre = RayPre::new(e.d, s.has(FEAT_TRIANGLE));
                let before = work.totals();
                let found = closest_hit(s, &r, &pre, F::infinity(), work);
                if e.depth == 0 {
                    // An eye ray's work is its own (`Work::eye`).
                    work.credit_eye(before);
                }
                found
            });
            let Some((h, pi)) = found else {
                // Escaping inside an absorbing medium: exp(−σ·∞) = 0.
                if e.medium.max_elem() <= F::zero() {
                    color += e.w.mul_elem(background);
                }
                break 'ray;
            };
            if e.depth == 0 {
                stats.eye_hit += 1;
            }
            let mut w = e.w;
            if s.has(FEAT_ABSORB) && e.medium.max_elem() > F::zero() {
                w = w.mul_elem((-e.medium * h.t).map(|x| x.exp_t()));
            }
            let prim = &s.prims[pi as usize];
            let mat = &s.materials[prim.material() as usize];
            let p = e.o + e.d * h.t;
            let (ng, ns) = normals(prim, s.extra, p, &h);
            let front = e.d.dot(ng) < F::zero();
            let n = if front { ns } else { -ns };
            let ngf = if front { ng } else { -ng };
            // A ray of weight 0 (SPD counting) adds nothing: its feelers are
            // counted, not traced, and its local intensity is not added.
            let weighted = w.max_elem() > F::zero();
            work.at_depth(e.depth);
            let local = shade(s, mat, p, e.d, n, ngf, front, weighted, stats, work);
            if weighted {
                color += w.mul_elem(local);
            }
            if e.depth >= max_depth {
                break 'ray;
            }
            let mut refl = V3::<F>::of(&mat.kr);
            let kt = V3::<F>::of(&mat.kt);
            if s.has(FEAT_REFRACT) && kt.max_elem() > F::zero() {
                let ior = F::of(mat.kr[3]);
                let eta = if front { F::one() / ior } else { ior };
                match refract_dir(e.d, n, eta) {
                    // Total internal reflection: the transmitted share reflects.
                    None => refl += kt,
                    Some(t) => {
                        let mut wt = w.mul_elem(kt);
                        let medium = if front {
                            V3::of(&mat.absorb)
                        } else {
                            V3::zero()
                        };
                        if s.has(FEAT_ABSORB) && medium.max_elem() > F::zero() {
                            wt = wt.mul_elem(offset_absorption(medium, eps, ngf.dot(t)));
                        }
                        if wt.max_elem() >= min_weight {
                            stats.refract += 1;
                            // At most one refracted ray per depth waits.
                            stack.push(Entry {
                                o: p - ngf * eps,
                                d: t,
                                w: wt,
                                medium,
                                depth: e.depth + 1,
                            });
                        }
                    }
                }
            }
            if refl.max_elem() > F::zero() || (spd && kt.max_elem() > F::zero()) {
                let mut wr = w.mul_elem(refl);
                let d = reflect_dir(e.d, n);
                if s.has(FEAT_ABSORB) && e.medium.max_elem() > F::zero() {
                    wr = wr.mul_elem(offset_absorption(e.medium, eps, ngf.dot(d)));
                }
                if wr.max_elem() >= min_weight {
                    stats.reflect += 1;
                    e = Entry {
                        o: p + ngf * eps,
                        d,
                        w: wr,
                        medium: e.medium,
                        depth: e.depth + 1,
                    };
                    continue 'tree;
                }
            }
        }
        match stack.pop() {
            Some(x) => e = x,
            None => break,
        }
    }
    color
}
