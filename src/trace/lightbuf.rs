//! Shadow feelers through a light buffer: twin of `shaders/lightbuf.glsl`.
//! The cube of directions around each light (`pack::lightbuf`): a feeler
//! tests the unbounded primitives, then the primitives its direction's
//! cell lists.

use super::intersect::RayPre;
use super::math::{Ray, Real, V3};
use super::query::{query_prim, query_unbounded, Query, Work};
use super::SceneView;

/// The index along a face's side of coordinate `u` (in [−1, 1]) at `res`
/// cells: ⌊(u + 1)·0.5·res⌋, at most res − 1.
#[inline(always)]
pub fn lightbuf_index<F: Real>(u: F, res: u32) -> u32 {
    let x = (u + F::one()) * F::of(0.5) * F::of(res as f32);
    let i = x.trunc_i32().max(0) as u32;
    i.min(res - 1)
}

/// The cell of light `light`'s buffer (resolution `res`) that direction
/// `c` (from the light towards the feeler's origin) falls in; `None` when
/// `c` has no dominant component (zero, infinite or NaN). The dominant
/// axis is x on ties with y or z, then y on a tie with z.
#[inline(always)]
pub fn lightbuf_cell<F: Real>(res: u32, light: u32, c: V3<F>) -> Option<u32> {
    let ax = c.x.abs();
    let ay = c.y.abs();
    let az = c.z.abs();
    let axis: u32;
    let m: F;
    let u: F;
    let v: F;
    let neg: bool;
    if ax >= ay && ax >= az {
        axis = 0;
        m = ax;
        u = c.y;
        v = c.z;
        neg = c.x < F::zero();
    } else if ay >= az {
        axis = 1;
        m = ay;
        u = c.z;
        v = c.x;
        neg = c.y < F::zero();
    } else {
        axis = 2;
        m = az;
        u = c.x;
        v = c.y;
        neg = c.z < F::zero();
    }
    if !(m > F::zero() && m < F::infinity()) {
        return None;
    }
    let face = axis * 2 + neg as u32;
    let iu = lightbuf_index(u / m, res);
    let iv = lightbuf_index(v / m, res);
    Some(((light * 6 + face) * res + iv) * res + iu)
}

/// Runs shadow query `q` over the unbounded primitives, then the
/// primitives light buffer cell `cell` lists.
#[inline(always)]
pub fn lightbuf_traverse<F: Real>(
    s: &SceneView,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    q: &mut Query<F>,
    cell: u32,
    work: &mut Work,
) {
    if query_unbounded(s, q, ray, pre, work) {
        return;
    }
    work.cells += 1;
    let start = s.lb_start[cell as usize];
    let end = s.lb_start[cell as usize + 1];
    for k in start..end {
        let r = s.lb_refs[k as usize];
        if query_prim(s, q, &s.prims[r as usize], r, ray, pre, work) {
            return;
        }
    }
}
