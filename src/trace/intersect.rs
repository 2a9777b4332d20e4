//! Ray-primitive intersection: twin of `shaders/intersect.glsl`.
//!
//! Each routine returns the nearest hit with 0 < t < tmax. Ray origins of
//! secondary rays are offset off the surface by the caller, so t > 0 is the
//! only lower bound (no per-routine epsilon to keep in step).

use super::math::{v3, Ray, Real, V3};
use crate::constants::*;
use crate::pack::layout::Prim;
use crate::pack::polygon::{axes, float_at, vertex};

/// A hit: distance `t` and two parameters whose meaning depends on the kind
/// (triangle: barycentric weights of v0 and v1; box: axis and side).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit<F> {
    pub t: F,
    pub u: F,
    pub v: F,
}

/// Per-ray values computed once: the watertight triangle test's shear and
/// axis permutation, 1/d for the slabs, and which of a BVH node's bounds
/// is each slab's near plane.
#[derive(Clone, Copy, Debug)]
pub struct RayPre<F> {
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    pub sx: F,
    pub sy: F,
    pub sz: F,
    pub inv_d: V3<F>,
    /// Per axis, the index into `BvhNode::bounds` of the near planes: 0
    /// (lo) where 1/d ≥ 0, else 1 (hi; a NaN too). `trace::bvh`.
    pub near: [usize; 3],
}

impl<F: Real> RayPre<F> {
    /// `shear`: compute the triangle test's shear (only a scene with
    /// triangles reads it; the shader's compiler drops it as dead code
    /// when the triangle path is specialized out).
    pub fn new(d: V3<F>, shear: bool) -> Self {
        let ad = d.map(|c| c.abs());
        let mut kz = 0;
        if ad.y > ad.x {
            kz = 1;
        }
        if ad.z > ad.get(kz) {
            kz = 2;
        }
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d.get(kz) < F::zero() {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = d.get(kz);
        let (sx, sy, sz) = if shear {
            (d.get(kx) / dz, d.get(ky) / dz, F::one() / dz)
        } else {
            (F::zero(), F::zero(), F::zero())
        };
        let inv_d = v3(F::one() / d.x, F::one() / d.y, F::one() / d.z);
        RayPre {
            kx,
            ky,
            kz,
            sx,
            sy,
            sz,
            inv_d,
            near: [0, 1, 2].map(|i| if inv_d.get(i) >= F::zero() { 0 } else { 1 }),
        }
    }
}

#[inline(always)]
fn hit<F: Real>(t: F) -> Option<Hit<F>> {
    Some(Hit {
        t,
        u: F::zero(),
        v: F::zero(),
    })
}

/// Geometric method (Haines et al., Ray Tracing Gems ch. 7): the
/// discriminant from the perpendicular distance, the near root without
/// cancellation. Handles origins inside the sphere.
#[inline(always)]
pub fn sphere<F: Real>(center: V3<F>, r2: F, ray: &Ray<F>, tmax: F) -> Option<Hit<F>> {
    let l = center - ray.o;
    let tca = l.dot(ray.d);
    let perp = l - ray.d * tca;
    let d2 = perp.dot(perp);
    if d2 > r2 {
        return None;
    }
    let thc = (r2 - d2).sqrt();
    let c = l.dot(l) - r2;
    let (t0, t1) = if tca > F::zero() {
        let q = tca + thc;
        (c / q, q)
    } else {
        let q = tca - thc;
        (q, c / q)
    };
    if t0 > F::zero() && t0 < tmax {
        return hit(t0);
    }
    if t1 > F::zero() && t1 < tmax {
        return hit(t1);
    }
    None
}

#[inline(always)]
pub fn plane<F: Real>(n: V3<F>, dist: F, ray: &Ray<F>, tmax: F) -> Option<Hit<F>> {
    let denom = n.dot(ray.d);
    if denom == F::zero() {
        return None;
    }
    let t = (dist - n.dot(ray.o)) / denom;
    if t > F::zero() && t < tmax {
        hit(t)
    } else {
        None
    }
}

/// Watertight ray/triangle (Woop, Benthin, Wald 2013). The edge functions
/// of a shared edge are exact negations of each other (never fused), so a
/// ray through an edge or vertex hits at least one of the triangles.
#[inline(always)]
pub fn triangle<F: Real>(
    v0: V3<F>,
    v1: V3<F>,
    v2: V3<F>,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<Hit<F>> {
    let a = v0 - ray.o;
    let b = v1 - ray.o;
    let c = v2 - ray.o;
    let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
    let ax = a.get(kx) - pre.sx * a.get(kz);
    let ay = a.get(ky) - pre.sy * a.get(kz);
    let bx = b.get(kx) - pre.sx * b.get(kz);
    let by = b.get(ky) - pre.sy * b.get(kz);
    let cx = c.get(kx) - pre.sx * c.get(kz);
    let cy = c.get(ky) - pre.sy * c.get(kz);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = F::zero();
    if (u < zero || v < zero || w < zero) && (u > zero || v > zero || w > zero) {
        return None;
    }
    let det = u + v + w;
    if det == zero {
        return None;
    }
    let az = pre.sz * a.get(kz);
    let bz = pre.sz * b.get(kz);
    let cz = pre.sz * c.get(kz);
    let tt = u * az + v * bz + w * cz;
    let t = tt / det;
    if t > zero && t < tmax {
        Some(Hit {
            t,
            u: u / det,
            v: v / det,
        })
    } else {
        None
    }
}

/// Planar polygon: the plane, then a 2D test in the plane of the two axes
/// other than the normal's largest (the vertices are packed projected,
/// `pack::polygon`): all edges on one side for convex polygons, the
/// crossings test (even-odd) for the rest, over the hit point's edge band
/// when the polygon has bands (the same parity as over every edge).
#[inline(always)]
pub fn polygon<F: Real>(prim: &Prim, extra: &[[f32; 4]], ray: &Ray<F>, tmax: F) -> Option<Hit<F>> {
    let n = V3::of(&prim.a);
    let h = plane(n, F::of(prim.a[3]), ray, tmax)?;
    let p = ray.o + ray.d * h.t;
    let count = prim.b[0] as usize;
    let (i0, i1) = axes(prim.b[1] as usize);
    let convex = prim.b[2] != 0.0;
    let px = p.get(i0);
    let py = p.get(i1);
    let base = prim.data as usize;
    let bands = prim.c[2] as usize;
    let lists = base + count.div_ceil(2);
    // A cell wholly inside or outside answers for the test (pack::polygon).
    match polygon_cell(prim, extra, px, py) {
        CELL_IN => return Some(h),
        CELL_OUT => return None,
        _ => {}
    }
    let zero = F::zero();
    if convex {
        // Every edge in order, each vertex read once, and out at the
        // first edge that disagrees in side. The same arithmetic and the
        // same answer as the general loop below, which the shader keeps
        // for both tests (intersect.glsl: llvmpipe's loop budget).
        let [lu, lv] = vertex(extra, base, count - 1);
        let (mut ax, mut ay) = (F::of(lu), F::of(lv));
        let mut pos = false;
        let mut neg = false;
        for j in 0..count {
            let [cu, cv] = vertex(extra, base, j);
            let (bx, by) = (F::of(cu), F::of(cv));
            let ex = bx - ax;
            let ey = by - ay;
            let e = ex * (py - ay) - ey * (px - ax);
            pos = pos || e > zero;
            neg = neg || e < zero;
            if pos && neg {
                return None;
            }
            (ax, ay) = (bx, by);
        }
        return Some(h);
    }
    let (lo, hi) = polygon_edges(prim, extra, py);
    let mut pos = false;
    let mut neg = false;
    let mut inside = false;
    for e in lo..hi {
        let j = if bands > 0 && !convex {
            float_at(extra, lists, bands + 1 + e) as usize
        } else {
            e
        };
        let [pu, pv] = vertex(extra, base, if j == 0 { count - 1 } else { j - 1 });
        let [cu, cv] = vertex(extra, base, j);
        let (ax, ay, bx, by) = (F::of(pu), F::of(pv), F::of(cu), F::of(cv));
        if convex {
            let ex = bx - ax;
            let ey = by - ay;
            let e = ex * (py - ay) - ey * (px - ax);
            pos = pos || e > zero;
            neg = neg || e < zero;
        } else if (ay > py) != (by > py) {
            let xc = ax + (py - ay) * (bx - ax) / (by - ay);
            if px < xc {
                inside = !inside;
            }
        }
    }
    let hit = if convex { !(pos && neg) } else { inside };
    if hit {
        Some(h)
    } else {
        None
    }
}

/// The code of the cell of a banded polygon that (`px`, `py`) falls in:
/// `CELL_IN`, `CELL_OUT`, or `CELL_EDGE` (take the crossings test), which
/// is also the answer for a polygon without cells and for a point outside
/// the cells' range (`pack::polygon::cells`).
#[inline(always)]
pub fn polygon_cell<F: Real>(prim: &Prim, extra: &[[f32; 4]], px: F, py: F) -> u32 {
    let at = prim.c[3] as usize;
    if at == 0 {
        return CELL_EDGE;
    }
    let lists = prim.data as usize + (prim.b[0] as usize).div_ceil(2);
    let k = prim.c[2];
    let u_min = F::of(float_at(extra, lists, at));
    let inv_w = F::of(float_at(extra, lists, at + 1));
    let m = float_at(extra, lists, at + 2);
    let fb = ((py - F::of(prim.c[0])) * F::of(prim.c[1])).floor();
    let fm = ((px - u_min) * inv_w).floor();
    let zero = F::zero();
    // Comparisons false for a NaN: such a point takes the test.
    let within = fb >= zero && fb < F::of(k) && fm >= zero && fm < F::of(m);
    if !within {
        return CELL_EDGE;
    }
    let (b, c) = (fb.to_usize().unwrap_or(0), fm.to_usize().unwrap_or(0));
    float_at(extra, lists, at + 3 + b * m as usize + c) as u32
}

/// The edges a polygon test walks at plane coordinate `py` (the second of
/// its two axes), as a range: every edge, or the list of `py`'s edge band
/// (`pack::polygon`).
#[inline(always)]
pub fn polygon_edges<F: Real>(prim: &Prim, extra: &[[f32; 4]], py: F) -> (usize, usize) {
    let count = prim.b[0] as usize;
    let convex = prim.b[2] != 0.0;
    let bands = prim.c[2] as usize;
    if convex || bands == 0 {
        return (0, count);
    }
    let lists = prim.data as usize + count.div_ceil(2);
    let fb = ((py - F::of(prim.c[0])) * F::of(prim.c[1])).floor();
    let b = fb
        .max(F::zero())
        .min(F::of((bands - 1) as f32))
        .to_usize()
        .unwrap_or(0);
    (
        float_at(extra, lists, b) as usize,
        float_at(extra, lists, b + 1) as usize,
    )
}

/// Slabs. A ray parallel to a slab pair misses unless its origin lies
/// between the two planes (no 0·∞). From inside, the exit is the hit.
/// `u` = axis of the face hit, `v` = its side (−1 min face, +1 max face).
#[inline(always)]
pub fn aabox<F: Real>(
    lo: V3<F>,
    hi: V3<F>,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<Hit<F>> {
    let mut tnear = F::neg_infinity();
    let mut tfar = F::infinity();
    let mut near_axis = 0usize;
    let mut near_side = -F::one();
    let mut far_axis = 0usize;
    let mut far_side = F::one();
    for i in 0..3 {
        let o = ray.o.get(i);
        let d = ray.d.get(i);
        if d == F::zero() {
            if o < lo.get(i) || o > hi.get(i) {
                return None;
            }
            continue;
        }
        let inv = pre.inv_d.get(i);
        let ta = (lo.get(i) - o) * inv;
        let tb = (hi.get(i) - o) * inv;
        let (tn, tf, sn) = if d > F::zero() {
            (ta, tb, -F::one())
        } else {
            (tb, ta, F::one())
        };
        if tn > tnear {
            tnear = tn;
            near_axis = i;
            near_side = sn;
        }
        if tf < tfar {
            tfar = tf;
            far_axis = i;
            far_side = -sn;
        }
    }
    if tnear > tfar {
        return None;
    }
    if tnear > F::zero() && tnear < tmax {
        return Some(Hit {
            t: tnear,
            u: F::of(near_axis as f32),
            v: near_side,
        });
    }
    if tnear <= F::zero() && tfar > F::zero() && tfar < tmax {
        return Some(Hit {
            t: tfar,
            u: F::of(far_axis as f32),
            v: far_side,
        });
    }
    None
}

/// Roots of a t² + b t + c = 0 in increasing order, without cancellation
/// (q = −(b + sign(b)·√disc)/2; roots q/a and c/q); the linear case when
/// |a| is negligible against |b|.
#[inline(always)]
pub fn solve_quadratic<F: Real>(a: F, b: F, c: F) -> Option<(F, F)> {
    let zero = F::zero();
    let half = F::of(0.5);
    if a.abs() <= F::of(1.0e-12) * b.abs() || a == zero {
        if b == zero {
            return None;
        }
        let t = -c / b;
        return Some((t, t));
    }
    let disc = b * b - F::of(4.0) * a * c;
    if disc < zero {
        return None;
    }
    let sq = disc.sqrt();
    let q = if b < zero {
        -half * (b - sq)
    } else {
        -half * (b + sq)
    };
    if q == zero {
        // b = 0 and c = 0: a double root at 0.
        return Some((zero, zero));
    }
    let t0 = q / a;
    let t1 = c / q;
    if t0 < t1 {
        Some((t0, t1))
    } else {
        Some((t1, t0))
    }
}

#[inline(always)]
fn inside_box<F: Real>(p: V3<F>, lo: V3<F>, hi: V3<F>) -> bool {
    p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z
}

/// General quadric A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J,
/// coefficients in `extra[data..data + 3]`, clipped to the box in a/b when a.w = 1.
#[inline(always)]
pub fn quadric<F: Real>(prim: &Prim, extra: &[[f32; 4]], ray: &Ray<F>, tmax: F) -> Option<Hit<F>> {
    let k0 = extra[prim.data as usize];
    let k1 = extra[prim.data as usize + 1];
    let k2 = extra[prim.data as usize + 2];
    let (ca, cb, cc, cd) = (F::of(k0[0]), F::of(k0[1]), F::of(k0[2]), F::of(k0[3]));
    let (ce, cf, cg, ch) = (F::of(k1[0]), F::of(k1[1]), F::of(k1[2]), F::of(k1[3]));
    let (ci, cj) = (F::of(k2[0]), F::of(k2[1]));
    let (o, d) = (ray.o, ray.d);
    let two = F::of(2.0);
    let a = ca * d.x * d.x
        + cb * d.y * d.y
        + cc * d.z * d.z
        + cd * d.x * d.y
        + ce * d.x * d.z
        + cf * d.y * d.z;
    let b = two * (ca * o.x * d.x + cb * o.y * d.y + cc * o.z * d.z)
        + cd * (o.x * d.y + o.y * d.x)
        + ce * (o.x * d.z + o.z * d.x)
        + cf * (o.y * d.z + o.z * d.y)
        + cg * d.x
        + ch * d.y
        + ci * d.z;
    let c = ca * o.x * o.x
        + cb * o.y * o.y
        + cc * o.z * o.z
        + cd * o.x * o.y
        + ce * o.x * o.z
        + cf * o.y * o.z
        + cg * o.x
        + ch * o.y
        + ci * o.z
        + cj;
    let (t0, t1) = solve_quadratic(a, b, c)?;
    let clipped = prim.a[3] != 0.0;
    let lo = V3::of(&prim.a);
    let hi = V3::of(&prim.b);
    for t in [t0, t1] {
        if t > F::zero() && t < tmax && (!clipped || inside_box(o + d * t, lo, hi)) {
            return hit(t);
        }
    }
    None
}

/// Open truncated cone (cylinder when the radii are equal) around a unit
/// axis from `base` (radius r0) to base + length·axis (radius r1).
///
/// The quadratic is solved from o' = o + t_c·d and t = t_c + s, with
/// t_c = (q − o)·d (any t_c is exact in theory): for a long cone (the
/// record's `c.w`, `pack::CONE_LONG_RATIO`) q is the axis's point of
/// closest approach to the ray, clamped to the segment; for a short one,
/// or a ray within `CONE_PARALLEL` of parallel, the cone's middle. From
/// the ray's own origin the constant term |w⊥|² − r_w² cancelled
/// catastrophically for a thin cone far away (a branch 0.002 wide seen
/// from 5 units had its radius wrong by a tenth, and hits fell outside its
/// bounds); from the cone's middle it still did near the ends of a long
/// one (the roots s of a cone of radius 0.007 hit 5 units from its middle
/// are 0.016 apart: their f32 error was 10⁻⁴, and for a needle 455 long
/// an f32 root came out where there is none). The
/// hit must also lie within the record's tolerance (`c.z`,
/// `pack::cone_tolerance`) of the side.
#[inline(always)]
pub fn cone<F: Real>(prim: &Prim, ray: &Ray<F>, tmax: F) -> Option<Hit<F>> {
    let base = V3::of(&prim.a);
    let axis = V3::of(&prim.b);
    let r0 = F::of(prim.a[3]);
    let r1 = F::of(prim.b[3]);
    let len = F::of(prim.c[0]);
    let k = (r1 - r0) / len;
    let dv = ray.d.dot(axis);
    let w0 = ray.o - base;
    let denom = F::one() - dv * dv;
    let mut hc = len * F::of(0.5);
    if prim.c[3] != 0.0 && denom > F::of(CONE_PARALLEL) {
        let hs = (w0.dot(axis) - dv * w0.dot(ray.d)) / denom;
        hc = if hs >= F::zero() {
            if hs > len {
                len
            } else {
                hs
            }
        } else {
            F::zero()
        };
    }
    let near = base + axis * hc;
    let tc = (near - ray.o).dot(ray.d);
    let w = (ray.o + ray.d * tc) - base;
    let wv = w.dot(axis);
    let pp = w - axis * wv;
    let dd = ray.d - axis * dv;
    let rw = r0 + k * wv;
    let a = dd.dot(dd) - k * k * dv * dv;
    let b = F::of(2.0) * (pp.dot(dd) - rw * k * dv);
    let c = pp.dot(pp) - rw * rw;
    let (s0, s1) = solve_quadratic(a, b, c)?;
    let tol = F::of(prim.c[2]);
    for s in [s0, s1] {
        let t = tc + s;
        let h = wv + s * dv;
        if t > F::zero() && t < tmax && h >= F::zero() && h <= len {
            // The point itself within `tol` of the side (`CONE_TOL_*`):
            // a root that cancellation made up (a needle seen across its
            // length) lies off the surface, outside the boxes that bound
            // the cone, and a walk's answer would depend on its order.
            let q = (ray.o + ray.d * t) - base;
            let hq = q.dot(axis);
            let perp = q - axis * hq;
            let lim = r0 + k * hq + tol;
            if perp.dot(perp) <= lim * lim {
                return hit(t);
            }
        }
    }
    None
}

/// Any primitive: the dispatch on kind (the shader's switch).
#[inline(always)]
pub fn intersect<F: Real>(
    prim: &Prim,
    extra: &[[f32; 4]],
    ray: &Ray<F>,
    pre: &RayPre<F>,
    tmax: F,
) -> Option<Hit<F>> {
    match prim.kind() {
        KIND_SPHERE => sphere(V3::of(&prim.a), F::of(prim.a[3]), ray, tmax),
        KIND_PLANE => plane(V3::of(&prim.a), F::of(prim.a[3]), ray, tmax),
        KIND_TRIANGLE => triangle(
            V3::of(&prim.a),
            V3::of(&prim.b),
            V3::of(&prim.c),
            ray,
            pre,
            tmax,
        ),
        KIND_POLYGON => polygon(prim, extra, ray, tmax),
        KIND_BOX => aabox(V3::of(&prim.a), V3::of(&prim.b), ray, pre, tmax),
        KIND_QUADRIC => quadric(prim, extra, ray, tmax),
        KIND_CONE => cone(prim, ray, tmax),
        _ => None,
    }
}

/// Outward geometric normal (unit) and shading normal (unit) at `p`.
pub fn normals<F: Real>(prim: &Prim, extra: &[[f32; 4]], p: V3<F>, h: &Hit<F>) -> (V3<F>, V3<F>) {
    match prim.kind() {
        KIND_SPHERE => {
            let n = ((p - V3::of(&prim.a)) / F::of(prim.b[0])).normalize();
            (n, n)
        }
        KIND_PLANE | KIND_POLYGON => {
            let n = V3::of(&prim.a);
            (n, n)
        }
        KIND_TRIANGLE => {
            let v0 = V3::<F>::of(&prim.a);
            let ng = (V3::of(&prim.b) - v0)
                .cross(V3::of(&prim.c) - v0)
                .normalize();
            if prim.data == NO_NORMALS {
                (ng, ng)
            } else {
                let i = prim.data as usize;
                let w = F::one() - h.u - h.v;
                let ns = (V3::of(&extra[i]) * h.u
                    + V3::of(&extra[i + 1]) * h.v
                    + V3::of(&extra[i + 2]) * w)
                    .normalize();
                (ng, ns)
            }
        }
        KIND_BOX => {
            let axis = h.u.to_f32() as usize;
            let mut n = V3::zero();
            match axis {
                0 => n.x = h.v,
                1 => n.y = h.v,
                _ => n.z = h.v,
            }
            (n, n)
        }
        KIND_QUADRIC => {
            let k0 = extra[prim.data as usize];
            let k1 = extra[prim.data as usize + 1];
            let k2 = extra[prim.data as usize + 2];
            let f = |x: f32| F::of(x);
            let two = F::of(2.0);
            let n = v3(
                two * f(k0[0]) * p.x + f(k0[3]) * p.y + f(k1[0]) * p.z + f(k1[2]),
                two * f(k0[1]) * p.y + f(k0[3]) * p.x + f(k1[1]) * p.z + f(k1[3]),
                two * f(k0[2]) * p.z + f(k1[0]) * p.x + f(k1[1]) * p.y + f(k2[0]),
            )
            .direction();
            (n, n)
        }
        KIND_CONE => {
            let base = V3::<F>::of(&prim.a);
            let axis = V3::<F>::of(&prim.b);
            let k = (F::of(prim.b[3]) - F::of(prim.a[3])) / F::of(prim.c[0]);
            let q = p - base;
            let radial = (q - axis * q.dot(axis)).normalize();
            let n = (radial - axis * k).normalize() * F::of(prim.c[1]);
            (n, n)
        }
        _ => (V3::zero(), V3::zero()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> (Ray<f64>, RayPre<f64>) {
        let d = v3(d[0], d[1], d[2]).normalize();
        (
            Ray {
                o: v3(o[0], o[1], o[2]),
                d,
            },
            RayPre::new(d, true),
        )
    }

    fn prim(kind: u32, a: [f32; 4], b: [f32; 4], c: [f32; 4]) -> Prim {
        Prim {
            kind_mat: kind,
            data: 0,
            cell_lo: 0,
            cell_hi: 0,
            a,
            b,
            c,
        }
    }

    const INF: f64 = f64::INFINITY;

    #[test]
    fn sphere_hits_near_root_far_root_from_inside_and_tangent() {
        let c = v3(0.0, 0.0, 5.0);
        let (r, _) = ray([0.0; 3], [0.0, 0.0, 1.0]);
        assert_eq!(sphere(c, 1.0, &r, INF).unwrap().t, 4.0);
        // tmax excludes it
        assert!(sphere(c, 1.0, &r, 3.9).is_none());
        // origin inside: the far root
        let (r, _) = ray([0.0, 0.0, 5.0], [0.0, 0.0, 1.0]);
        assert_eq!(sphere(c, 1.0, &r, INF).unwrap().t, 1.0);
        // behind the ray
        let (r, _) = ray([0.0, 0.0, 10.0], [0.0, 0.0, 1.0]);
        assert!(sphere(c, 1.0, &r, INF).is_none());
        // tangent: grazes at x = 1
        let (r, _) = ray([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let h = sphere(c, 1.0, &r, INF).unwrap();
        assert!((h.t - 5.0).abs() < 1e-9);
        let (r, _) = ray([1.0 + 1e-9, 0.0, 0.0], [0.0, 0.0, 1.0]);
        assert!(sphere(c, 1.0, &r, INF).is_none());
    }

    #[test]
    fn far_small_sphere_is_accurate_in_f32() {
        // The perpendicular-distance discriminant keeps a tiny sphere far away.
        let c = v3(0.0f32, 0.0, 10_000.0);
        let d = v3(0.0f32, 0.0, 1.0);
        let r = Ray { o: V3::zero(), d };
        let h = sphere(c, 0.01 * 0.01, &r, f32::INFINITY).unwrap();
        assert!((h.t - 9999.99).abs() < 2e-3, "{}", h.t);
        let r2 = Ray {
            o: v3(0.0099, 0.0, 0.0),
            d,
        };
        assert!(sphere(c, 0.01 * 0.01, &r2, f32::INFINITY).is_some());
    }

    #[test]
    fn plane_parallel_and_behind() {
        let n = v3(0.0, 0.0, 1.0);
        let (r, _) = ray([0.0, 0.0, 2.0], [0.0, 0.0, -1.0]);
        assert_eq!(plane(n, 0.0, &r, INF).unwrap().t, 2.0);
        let (r, _) = ray([0.0, 0.0, 2.0], [1.0, 0.0, 0.0]);
        assert!(plane(n, 0.0, &r, INF).is_none());
        let (r, _) = ray([0.0, 0.0, 2.0], [0.0, 0.0, 1.0]);
        assert!(plane(n, 0.0, &r, INF).is_none());
    }

    #[test]
    fn triangle_inside_outside_edge_and_both_facings() {
        let (a, b, c) = (v3(0.0, 0.0, 1.0), v3(1.0, 0.0, 1.0), v3(0.0, 1.0, 1.0));
        let (r, p) = ray([0.25, 0.25, 0.0], [0.0, 0.0, 1.0]);
        let h = triangle(a, b, c, &r, &p, INF).unwrap();
        assert_eq!(h.t, 1.0);
        assert!((h.u - 0.5).abs() < 1e-12 && (h.v - 0.25).abs() < 1e-12);
        // back side
        let (r, p) = ray([0.25, 0.25, 2.0], [0.0, 0.0, -1.0]);
        assert_eq!(triangle(a, b, c, &r, &p, INF).unwrap().t, 1.0);
        // outside
        let (r, p) = ray([0.75, 0.75, 0.0], [0.0, 0.0, 1.0]);
        assert!(triangle(a, b, c, &r, &p, INF).is_none());
        // exactly on the shared edge x + y = 1: at least one of the two
        let d = v3(1.0, 1.0, 1.0);
        let (r, p) = ray([0.5, 0.5, 0.0], [0.0, 0.0, 1.0]);
        let h1 = triangle(a, b, c, &r, &p, INF);
        let h2 = triangle(b, d, c, &r, &p, INF);
        assert!(h1.is_some() || h2.is_some());
        // parallel to the triangle's plane
        let (r, p) = ray([0.0, 0.0, 1.0], [1.0, 1.0, 0.0]);
        assert!(triangle(a, b, c, &r, &p, INF).is_none());
    }

    #[test]
    fn box_slabs_parallel_inside_and_faces() {
        let (lo, hi) = (v3(-1.0, -1.0, -1.0), v3(1.0, 1.0, 1.0));
        let (r, p) = ray([-5.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let h = aabox(lo, hi, &r, &p, INF).unwrap();
        assert_eq!((h.t, h.u, h.v), (4.0, 0.0, -1.0));
        // parallel to the y and z slabs, origin between them: hit
        let (r, p) = ray([-5.0, 1.0, -1.0], [1.0, 0.0, 0.0]);
        assert_eq!(aabox(lo, hi, &r, &p, INF).unwrap().t, 4.0);
        // parallel, outside a slab: miss (no 0·∞ = NaN surprise)
        let (r, p) = ray([-5.0, 1.0 + 1e-12, 0.0], [1.0, 0.0, 0.0]);
        assert!(aabox(lo, hi, &r, &p, INF).is_none());
        // from inside: the exit face, outward normal +z
        let (r, p) = ray([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let h = aabox(lo, hi, &r, &p, INF).unwrap();
        assert_eq!((h.t, h.u, h.v), (1.0, 2.0, 1.0));
        // entering through the max face when travelling −y
        let (r, p) = ray([0.0, 7.0, 0.0], [0.0, -1.0, 0.0]);
        let h = aabox(lo, hi, &r, &p, INF).unwrap();
        assert_eq!((h.t, h.u, h.v), (6.0, 1.0, 1.0));
    }

    #[test]
    fn quadratic_is_stable_and_handles_the_linear_case() {
        // roots 1e-8 and 1e8: the naive formula loses the small one entirely
        let (t0, t1) = solve_quadratic(1.0f32, -(1e8 + 1e-8), 1.0).unwrap();
        assert!((t0 - 1e-8).abs() / 1e-8 < 1e-5, "{t0}");
        assert!((t1 - 1e8).abs() / 1e8 < 1e-6);
        // a = 0: 2t − 4 = 0
        assert_eq!(solve_quadratic(0.0, 2.0, -4.0), Some((2.0, 2.0)));
        assert_eq!(solve_quadratic(0.0, 0.0, 1.0), None);
        assert_eq!(solve_quadratic(1.0, 0.0, 1.0), None);
    }

    #[test]
    fn quadric_sphere_paraboloid_and_clip() {
        // unit sphere x² + y² + z² − 1
        let extra = vec![
            [1.0, 1.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, -1.0, 0.0, 0.0],
        ];
        let mut q = prim(KIND_QUADRIC, [0.0; 4], [0.0; 4], [0.0; 4]);
        let (r, p) = ray([0.0, 0.0, -3.0], [0.0, 0.0, 1.0]);
        let h = intersect(&q, &extra, &r, &p, INF).unwrap();
        assert!((h.t - 2.0).abs() < 1e-12);
        let (_, n) = normals(&q, &extra, r.o + r.d * h.t, &h);
        assert!((n.z + 1.0).abs() < 1e-12);
        // clipped to z >= 0: the near root is cut off, the far one stays
        q.a = [-2.0, -2.0, 0.0, 1.0];
        q.b = [2.0, 2.0, 2.0, 0.0];
        assert!((intersect(&q, &extra, &r, &p, INF).unwrap().t - 4.0).abs() < 1e-12);
        // paraboloid z = x² + y² along its axis: a = 0, the linear case
        let extra = vec![
            [1.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0, 0.0],
        ];
        let q = prim(KIND_QUADRIC, [0.0; 4], [0.0; 4], [0.0; 4]);
        let (r, p) = ray([0.0, 0.0, -2.0], [0.0, 0.0, 1.0]);
        assert!((intersect(&q, &extra, &r, &p, INF).unwrap().t - 2.0).abs() < 1e-12);
    }

    #[test]
    fn cone_and_cylinder() {
        // cylinder radius 1 along z from 0 to 2
        let cyl = prim(
            KIND_CONE,
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [2.0, 1.0, 0.0, 0.0],
        );
        let (r, p) = ray([-5.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let h = intersect(&cyl, &[], &r, &p, INF).unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
        let (ng, _) = normals(&cyl, &[], r.o + r.d * h.t, &h);
        assert!((ng.x + 1.0).abs() < 1e-12);
        // above the cap: open, misses
        let (r, p) = ray([-5.0, 0.0, 2.5], [1.0, 0.0, 0.0]);
        assert!(intersect(&cyl, &[], &r, &p, INF).is_none());
        // looking down the open end sees the inside wall
        let (r, p) = ray([0.0, 0.0, 5.0], [0.3, 0.0, -1.0]);
        let h = intersect(&cyl, &[], &r, &p, INF).unwrap();
        let hp = r.o + r.d * h.t;
        assert!((hp.x - 1.0).abs() < 1e-9 && hp.z < 2.0 && hp.z > 0.0);
        // cone radius 1 at z=0 to 0 at z=1: at height 0.5 radius 0.5
        let cone_p = prim(
            KIND_CONE,
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0, 0.0],
        );
        let (r, p) = ray([-5.0, 0.0, 0.5], [1.0, 0.0, 0.0]);
        let h = intersect(&cone_p, &[], &r, &p, INF).unwrap();
        assert!((h.t - 4.5).abs() < 1e-12);
        let (ng, _) = normals(&cone_p, &[], r.o + r.d * h.t, &h);
        let s = 0.5f64.sqrt();
        assert!((ng.x + s).abs() < 1e-9 && (ng.z - s).abs() < 1e-9, "{ng:?}");
        // negative radii: the geometric normal points inwards
        let inside = prim(
            KIND_CONE,
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [2.0, -1.0, 0.0, 0.0],
        );
        let (r, p) = ray([-5.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let h = intersect(&inside, &[], &r, &p, INF).unwrap();
        assert!((normals(&inside, &[], r.o + r.d * h.t, &h).0.x - 1.0).abs() < 1e-12);
    }

    /// A cone's hit must lie within its tolerance of its side
    /// (`pack::cone_tolerance`); true hits pass it. Random cones, needles
    /// (length up to 10⁴ radii, zero radius at one end) among them, each
    /// hit from outside at a point of its side at up to 75° from the
    /// normal, in f32 as the tracer packs it: the hit is found, at the
    /// point aimed at.
    #[test]
    fn true_hits_on_cones_pass_the_tolerance() {
        use glam::DVec3;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tested = 0;
        for _ in 0..20_000 {
            let base = DVec3::new(next(), next(), next()) * 100.0 - 50.0;
            let axis = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
            if axis.length() < 0.1 {
                continue;
            }
            let axis = axis.normalize();
            let len = 10f64.powf(next() * 5.0 - 2.0);
            let needle = next() < 0.2;
            let (ra, rb) = (
                len * 10f64.powf(-4.0 * next()),
                len * 10f64.powf(-4.0 * next()),
            );
            let (r0, r1) = if needle { (0.0, rb) } else { (ra, rb) };
            let apex = base + axis * len;
            let (words, _) = crate::pack::cone_record(base, r0, apex, r1);
            let c = prim(KIND_CONE, words[0], words[1], words[2]);
            // A point of the side, the outward normal there.
            let h = len * (0.02 + 0.96 * next());
            let r = r0 + (r1 - r0) * h / len;
            let u = axis.any_orthonormal_vector();
            let w = axis.cross(u);
            let phi = next() * std::f64::consts::TAU;
            let radial = u * phi.cos() + w * phi.sin();
            let p = base + axis * h + radial * r;
            let n = (radial - axis * (r1 - r0) / len).normalize();
            // Towards it from outside, tilted up to 75° off the normal.
            let tangent = n.any_orthonormal_vector();
            let tangent =
                (tangent * (next() - 0.5) + n.cross(tangent) * (next() - 0.5)).normalize();
            let tilt = next() * 75f64.to_radians();
            let d = -(n * tilt.cos() + tangent * tilt.sin());
            let dist = 10f64.powf(next() * 3.0 - 1.0);
            let o = p - d * dist;
            // Thinner than f32 resolves where it lies, it may be missed.
            if r < 2e-4 * p.abs().max_element().max(o.abs().max_element()) {
                continue;
            }
            let d32 = V3::<f32>::of(&[d.x as f32, d.y as f32, d.z as f32, 0.0]).normalize();
            let ray = Ray {
                o: V3::of(&[o.x as f32, o.y as f32, o.z as f32, 0.0]),
                d: d32,
            };
            let Some(hit) = cone(&c, &ray, f32::INFINITY) else {
                panic!(
                    "no hit: base {base:?} axis {axis:?} len {len} radii {r0} {r1}, \
                     aiming at h {h} from {dist} away, tilt {tilt}"
                );
            };
            let err = (hit.t as f64 - dist).abs();
            assert!(
                err <= 1e-3 * (dist + len),
                "t {} against {dist}: len {len} radii {r0} {r1}",
                hit.t
            );
            tested += 1;
        }
        assert!(tested > 5_000, "{tested}");
    }

    #[test]
    fn polygons_convex_and_concave() {
        // L-shape in z = 1 (concave), and a square (convex); drop axis z,
        // so the projected coordinates are (x, y).
        let l = crate::pack::polygon::pack(
            &[
                [0.0, 0.0],
                [2.0, 0.0],
                [2.0, 1.0],
                [1.0, 1.0],
                [1.0, 2.0],
                [0.0, 2.0],
            ],
            false,
        )
        .extra;
        let poly = prim(
            KIND_POLYGON,
            [0.0, 0.0, 1.0, 1.0],
            [6.0, 2.0, 0.0, 0.0],
            [0.0; 4],
        );
        let at = |x: f64, y: f64| ray([x, y, 0.0], [0.0, 0.0, 1.0]);
        let hits = |poly: &Prim, x, y| {
            let (r, p) = at(x, y);
            intersect(poly, &l, &r, &p, INF).is_some()
        };
        assert!(hits(&poly, 0.5, 0.5));
        assert!(hits(&poly, 1.5, 0.5));
        assert!(hits(&poly, 0.5, 1.5));
        assert!(!hits(&poly, 1.5, 1.5), "the notch of the L");
        assert!(!hits(&poly, 2.5, 0.5));
        let sq =
            crate::pack::polygon::pack(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], true)
                .extra;
        let square = prim(
            KIND_POLYGON,
            [0.0, 0.0, 1.0, 1.0],
            [4.0, 2.0, 1.0, 0.0],
            [0.0; 4],
        );
        let (r, p) = at(0.5, 0.5);
        assert_eq!(intersect(&square, &sq, &r, &p, INF).unwrap().t, 1.0);
        let (r, p) = at(1.5, 0.5);
        assert!(intersect(&square, &sq, &r, &p, INF).is_none());
    }
}
