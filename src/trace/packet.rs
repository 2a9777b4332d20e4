//! Packets of coherent rays on the CPU (docs/method.md, "Packets of
//! rays"): `P` rays walk the BVH together. CPU only: the shader walks one
//! ray per invocation, and the GPU's lanes are its packets. The renderer
//! traces eye rays in packets (`cpu::render_packets`, `--packet`); feelers
//! in packets are measured (`examples/rays_per_core.rs --packet`) and no
//! faster than alone, so the renderer casts them one by one.
//!
//! The walk is the single ray's (`bvh::bvh_walk`: nearer children first
//! for the closest hit, lane order for feelers), with the packet's lanes
//! instead of one ray. At a node, interval arithmetic over the packet's
//! origins and inverse directions bounds from below where any of its
//! rays enters each child and from above where any leaves it (a rounded
//! product is monotone in each factor, so the bounds hold for each ray's
//! rounded values): one box test for the whole packet. Feelers, whose
//! intervals are wide, then test each lane's ray against the children
//! the bound let through, and carry the lanes entering each child down
//! the walk (`EXACT_FEELERS`). At a leaf each lane's own box test
//! (`bvh::bvh_entries`' arithmetic, one vector operation per axis)
//! decides which rays test its primitives, spheres and triangles all
//! lanes at once.
//! So each ray tests the primitives of the leaves it enters, as alone,
//! and more only where its own walk would have dropped a leaf for a hit
//! found meanwhile, which cannot change a closest hit (ties go to the
//! lower rank) or a feeler's light (what multiplies it is every blocker
//! the feeler meets, in the tree's depth-first lane order, which the
//! packet keeps). Answers are bit for bit each ray's alone
//! (tests/packets.rs; of a long opaque cone's two copies in the BVH,
//! `pack::bvh_pieces`, either may be the one named).
//!
//! A packet whose rays do not share each axis's direction sign, or with a
//! non-finite origin or inverse direction, walks ray by ray instead, as do
//! packets under the other structures and feelers under light buffers.

// Lanes and axes are indexed side by side in several arrays at once, the
// form the compiler turns into vector instructions.
#![allow(clippy::needless_range_loop)]

use super::accel::{accel_traverse, cache_admits, transmittance};
use super::bvh::bvh_walk;
use super::intersect::{intersect, Hit, RayPre};
use super::math::{Ray, Real, V3};
use super::query::{query_hit, query_prim, query_unbounded, Query, Work};
use super::SceneView;
use crate::constants::{
    ACCEL_BVH, BVH_EXIT_WIDEN, BVH_STACK_SIZE, BVH_WIDTH, KIND_SPHERE, KIND_TRIANGLE,
    SHADOW_CACHE_LIGHTS,
};
use crate::pack::layout::BvhNode;

const W: usize = BVH_WIDTH as usize;

/// Eye rays share their origin and their walk keeps close together: the
/// whole packet's bound decides at a node, each ray's own test at a
/// leaf. Feelers spread (their inverse directions' intervals grow wide
/// where a direction nearly lies in a plane of the axes): each ray's
/// test decides at every node too (BENCHMARKS.md, "Packets of rays").
const EXACT_EYE: bool = false;
const EXACT_FEELERS: bool = true;

/// The set of lanes of a packet, as bits (lane j: bit j).
pub type Lanes = u32;

/// Every lane of a packet of `p`.
#[inline(always)]
pub fn all_lanes(p: usize) -> Lanes {
    if p >= 32 {
        u32::MAX
    } else {
        (1 << p) - 1
    }
}

/// The lanes in `m`, lowest first.
#[inline(always)]
fn lanes(mut m: Lanes) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        if m == 0 {
            None
        } else {
            let j = m.trailing_zeros() as usize;
            m &= m - 1;
            Some(j)
        }
    })
}

/// Per axis, the least and greatest origin coordinate and inverse
/// direction of a packet's live rays, and whether the inverse directions
/// are negative (all of them, or none).
struct Interval<F> {
    olo: [F; 3],
    ohi: [F; 3],
    ilo: [F; 3],
    ihi: [F; 3],
    neg: [bool; 3],
}

/// The packet's interval, or `None` when it cannot serve: an axis on
/// which the rays' directions differ in sign (the near and far planes
/// would differ), or a non-finite origin or inverse direction.
#[inline(always)]
fn interval<F: Real, const P: usize>(
    rays: &[Ray<F>; P],
    pres: &[RayPre<F>; P],
    live: Lanes,
) -> Option<Interval<F>> {
    let mut iv = Interval {
        olo: [F::infinity(); 3],
        ohi: [F::neg_infinity(); 3],
        ilo: [F::infinity(); 3],
        ihi: [F::neg_infinity(); 3],
        neg: [false; 3],
    };
    let first = live.trailing_zeros() as usize;
    for i in 0..3 {
        iv.neg[i] = pres[first].inv_d.get(i) < F::zero();
        for j in lanes(live) {
            let o = rays[j].o.get(i);
            let inv = pres[j].inv_d.get(i);
            if !o.is_finite() || !inv.is_finite() || (inv < F::zero()) != iv.neg[i] {
                return None;
            }
            iv.olo[i] = iv.olo[i].min(o);
            iv.ohi[i] = iv.ohi[i].max(o);
            iv.ilo[i] = iv.ilo[i].min(inv);
            iv.ihi[i] = iv.ihi[i].max(inv);
        }
    }
    Some(iv)
}

/// For each child of `n`: a lower bound of where any ray of the packet
/// enters its box within 0..`tmax` and whether any may (a mask). Per
/// ray, t = (plane − o)·(1/d); with 1/d of one sign, the least entry
/// comes from the extreme origin on the near side and the greater or
/// lesser 1/d, the greatest exit likewise: the two candidate products
/// cover both signs of (plane − o). A ray that enters the box (as
/// `bvh_entries` computes it) enters this interval box.
#[inline(always)]
fn packet_entries<F: Real>(n: &BvhNode, iv: &Interval<F>, tmax: F) -> ([F; W], u32) {
    let mut t0 = [F::zero(); W];
    let mut t1 = [tmax; W];
    for i in 0..3 {
        let (a, b) = (iv.ilo[i], iv.ihi[i]);
        // 1/d ≥ 0: near = lo, t grows with (plane − o): the least entry at
        // the greatest origin, the greatest exit at the least. 1/d < 0:
        // near = hi, t falls as (plane − o) grows: the reverse.
        let (near, far, on, of) = if iv.neg[i] {
            (&n.hi()[i], &n.lo()[i], iv.olo[i], iv.ohi[i])
        } else {
            (&n.lo()[i], &n.hi()[i], iv.ohi[i], iv.olo[i])
        };
        for k in 0..W {
            let xn = F::of(near[k]) - on;
            let xf = F::of(far[k]) - of;
            let tn = (xn * a).min(xn * b);
            let tf = (xf * a).max(xf * b) * F::of(BVH_EXIT_WIDEN);
            if tn > t0[k] {
                t0[k] = tn;
            }
            if tf < t1[k] {
                t1[k] = tf;
            }
        }
    }
    let mut mask = 0;
    for k in 0..W {
        mask |= ((t0[k] <= t1[k]) as u32) << k;
    }
    (t0, mask)
}

/// A packet's rays side by side, axis by axis: origins and inverse
/// directions, each axis's array a vector register's worth.
struct Lanewise<F, const P: usize> {
    o: [[F; P]; 3],
    d: [[F; P]; 3],
    inv: [[F; P]; 3],
    /// The triangle test's shear per lane, and its axis permutation when
    /// every lane has the same one.
    shear: [[F; P]; 3],
    k: Option<[usize; 3]>,
}

/// Triangle `prim` against every lane's ray below its `bound` when the
/// lanes share the watertight test's axis permutation: each lane's hit
/// (t = +∞: none), `intersect::triangle`'s arithmetic lane by lane.
#[inline(always)]
fn triangle_lanes<F: Real, const P: usize>(
    prim: &crate::pack::layout::Prim,
    lw: &Lanewise<F, P>,
    [kx, ky, kz]: [usize; 3],
    bound: &[F; P],
) -> ([F; P], [F; P], [F; P]) {
    let v = [&prim.a, &prim.b, &prim.c].map(|p| [F::of(p[kx]), F::of(p[ky]), F::of(p[kz])]);
    let (mut ot, mut ou, mut ov) = ([F::infinity(); P], [F::zero(); P], [F::zero(); P]);
    let zero = F::zero();
    for j in 0..P {
        let (ox, oy, oz) = (lw.o[kx][j], lw.o[ky][j], lw.o[kz][j]);
        let (sx, sy, sz) = (lw.shear[0][j], lw.shear[1][j], lw.shear[2][j]);
        let (a, b, c) = (
            [v[0][0] - ox, v[0][1] - oy, v[0][2] - oz],
            [v[1][0] - ox, v[1][1] - oy, v[1][2] - oz],
            [v[2][0] - ox, v[2][1] - oy, v[2][2] - oz],
        );
        let ax = a[0] - sx * a[2];
        let ay = a[1] - sy * a[2];
        let bx = b[0] - sx * b[2];
        let by = b[1] - sy * b[2];
        let cx = c[0] - sx * c[2];
        let cy = c[1] - sy * c[2];
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let outside = (u < zero || v < zero || w < zero) && (u > zero || v > zero || w > zero);
        let det = u + v + w;
        let az = sz * a[2];
        let bz = sz * b[2];
        let cz = sz * c[2];
        let tt = u * az + v * bz + w * cz;
        let t = tt / det;
        let hit = !outside && det != zero && t > zero && t < bound[j];
        ot[j] = if hit { t } else { F::infinity() };
        ou[j] = u / det;
        ov[j] = v / det;
    }
    (ot, ou, ov)
}

/// Sphere `prim` against every lane's ray below its `bound`: each lane's
/// hit distance (+∞: none), `intersect::sphere`'s arithmetic lane by lane
/// (the same operations in the same order, so the same values).
#[inline(always)]
fn sphere_lanes<F: Real, const P: usize>(
    prim: &crate::pack::layout::Prim,
    lw: &Lanewise<F, P>,
    bound: &[F; P],
) -> [F; P] {
    let c = [F::of(prim.a[0]), F::of(prim.a[1]), F::of(prim.a[2])];
    let r2 = F::of(prim.a[3]);
    let mut out = [F::infinity(); P];
    for j in 0..P {
        let (lx, ly, lz) = (c[0] - lw.o[0][j], c[1] - lw.o[1][j], c[2] - lw.o[2][j]);
        let (dx, dy, dz) = (lw.d[0][j], lw.d[1][j], lw.d[2][j]);
        let tca = lx * dx + ly * dy + lz * dz;
        let (px, py, pz) = (lx - dx * tca, ly - dy * tca, lz - dz * tca);
        let d2 = px * px + py * py + pz * pz;
        let thc = (r2 - d2).sqrt();
        let cc = (lx * lx + ly * ly + lz * lz) - r2;
        let q = if tca > F::zero() {
            tca + thc
        } else {
            tca - thc
        };
        let (t0, t1) = if tca > F::zero() {
            (cc / q, q)
        } else {
            (q, cc / q)
        };
        let t = if t0 > F::zero() && t0 < bound[j] {
            t0
        } else if t1 > F::zero() && t1 < bound[j] {
            t1
        } else {
            F::infinity()
        };
        out[j] = if d2 > r2 { F::infinity() } else { t };
    }
    out
}

/// Where each lane's ray enters and leaves child `k`'s box of `n` within
/// 0..its `tmax` (entered when the first is at most the second):
/// `bvh_entries`' arithmetic, ray by ray (the rays share each axis's
/// sign, so its near plane is the same for all: one vector operation per
/// axis).
#[inline(always)]
fn slab_lanes<F: Real, const P: usize>(
    n: &BvhNode,
    k: usize,
    lw: &Lanewise<F, P>,
    neg: &[bool; 3],
    tmax: &[F; P],
) -> ([F; P], [F; P]) {
    let mut t0 = [F::zero(); P];
    let mut t1 = *tmax;
    for i in 0..3 {
        let (near, far) = if neg[i] {
            (F::of(n.hi()[i][k]), F::of(n.lo()[i][k]))
        } else {
            (F::of(n.lo()[i][k]), F::of(n.hi()[i][k]))
        };
        for j in 0..P {
            let tn = (near - lw.o[i][j]) * lw.inv[i][j];
            let tf = (far - lw.o[i][j]) * lw.inv[i][j] * F::of(BVH_EXIT_WIDEN);
            t0[j] = if tn > t0[j] { tn } else { t0[j] };
            t1[j] = if tf < t1[j] { tf } else { t1[j] };
        }
    }
    (t0, t1)
}

/// For each child of `n` the interval test lets through (`cand`), the
/// lanes of `m` whose own ray enters its box, and the least of their
/// entry distances.
#[inline(always)]
fn lanes_entering<F: Real, const P: usize>(
    n: &BvhNode,
    mut cand: u32,
    lw: &Lanewise<F, P>,
    neg: &[bool; 3],
    tmax: &[F; P],
    m: Lanes,
) -> ([Lanes; W], [F; W]) {
    let mut tl = [0 as Lanes; W];
    let mut te = [F::infinity(); W];
    while cand != 0 {
        let k = cand.trailing_zeros() as usize;
        cand &= cand - 1;
        let (t0, t1) = slab_lanes(n, k, lw, neg, tmax);
        for j in 0..P {
            if t0[j] <= t1[j] && (m >> j) & 1 == 1 {
                tl[k] |= 1 << j;
                te[k] = te[k].min(t0[j]);
            }
        }
    }
    (tl, te)
}

/// The lanes of `m` whose own ray enters child `k` of `n` (a leaf's
/// lanes, asked again when the walk reaches it with bounds that shrank).
#[inline(always)]
fn child_lanes<F: Real, const P: usize>(
    n: &BvhNode,
    k: usize,
    lw: &Lanewise<F, P>,
    neg: &[bool; 3],
    tmax: &[F; P],
    m: Lanes,
) -> Lanes {
    let (t0, t1) = slab_lanes(n, k, lw, neg, tmax);
    let mut enter = 0;
    for j in 0..P {
        enter |= ((t0[j] <= t1[j]) as u32) << j;
    }
    enter & m
}

/// Walks the BVH for the queries `qs` of the packet's `live` lanes
/// together (the unbounded primitives are the caller's). Each child
/// entered carries the lanes whose rays enter it; a lane leaves when its
/// query is done (a feeler fully blocked).
pub fn bvh_walk_packet<F: Real, const P: usize>(
    s: &SceneView,
    rays: &[Ray<F>; P],
    pres: &[RayPre<F>; P],
    qs: &mut [Query<F>; P],
    mut live: Lanes,
    exact: bool,
    work: &mut Work,
) {
    let nodes = s.globals.flags[2];
    if nodes == 0 || live == 0 {
        return;
    }
    let Some(iv) = interval(rays, pres, live) else {
        for j in lanes(live) {
            bvh_walk(s, &rays[j], &pres[j], &mut qs[j], work, 0, Some);
        }
        return;
    };
    let shadow = qs[live.trailing_zeros() as usize].shadow;
    let mut lw = Lanewise {
        o: [[F::zero(); P]; 3],
        d: [[F::zero(); P]; 3],
        inv: [[F::zero(); P]; 3],
        shear: [[F::zero(); P]; 3],
        k: None,
    };
    let k0 = [pres[0].kx, pres[0].ky, pres[0].kz];
    if pres.iter().all(|p| [p.kx, p.ky, p.kz] == k0) {
        lw.k = Some(k0);
    }
    for j in 0..P {
        lw.shear[0][j] = pres[j].sx;
        lw.shear[1][j] = pres[j].sy;
        lw.shear[2][j] = pres[j].sz;
    }
    for i in 0..3 {
        for j in 0..P {
            lw.o[i][j] = rays[j].o.get(i);
            lw.d[i][j] = rays[j].d.get(i);
            lw.inv[i][j] = pres[j].inv_d.get(i);
        }
    }
    // Each lane's query's bound, kept beside the queries.
    let mut tq = qs.map(|q| q.t);
    let reach = |tq: &[F; P], m: Lanes| {
        let mut r = F::neg_infinity();
        for j in 0..P {
            let v = if (m >> j) & 1 == 1 {
                tq[j]
            } else {
                F::neg_infinity()
            };
            r = if v > r { v } else { r };
        }
        r
    };
    // The pushed children (node · BVH_WIDTH + lane), the lanes entering
    // each and the least of their entry distances; the packet's stack is
    // the single ray's.
    let mut stack_slot = [0u32; BVH_STACK_SIZE as usize];
    let mut stack_lanes = [0 as Lanes; BVH_STACK_SIZE as usize];
    let mut stack_t = [F::zero(); BVH_STACK_SIZE as usize];
    let mut sp = 0usize;
    // The current child: its lanes, link and count; the root first (a
    // node: count 0).
    let mut m = live;
    let mut slot = u32::MAX;
    let mut link = 0u32;
    let mut count = 0u32;
    let mut t = F::zero();
    for _ in 0..W as u64 * nodes as u64 + 1 {
        m &= live;
        if m != 0 && t <= reach(&tq, m) {
            if count > 0 {
                let parent = &s.bvh[slot as usize / W];
                m = child_lanes(parent, slot as usize % W, &lw, &iv.neg, &tq, m);
                let mut bound = qs.map(|q| q.bound);
                for i in link..link + count {
                    let prim = &s.prims[i as usize];
                    let lanewise = match prim.kind() {
                        KIND_SPHERE => {
                            let t = sphere_lanes(prim, &lw, &bound);
                            Some((t, [F::zero(); P], [F::zero(); P]))
                        }
                        KIND_TRIANGLE => lw.k.map(|k| triangle_lanes(prim, &lw, k, &bound)),
                        _ => None,
                    };
                    if let Some((th, tu, tv)) = lanewise {
                        // All lanes at once; then each lane's query.
                        work.tests += m.count_ones() as u64;
                        for j in lanes(m) {
                            if th[j] == F::infinity() {
                                continue;
                            }
                            let h = Hit {
                                t: th[j],
                                u: tu[j],
                                v: tv[j],
                            };
                            if query_hit(s, &mut qs[j], prim, i, h, work) {
                                m &= !(1 << j);
                                live &= !(1 << j);
                            }
                            (tq[j], bound[j]) = (qs[j].t, qs[j].bound);
                        }
                    } else {
                        for j in lanes(m) {
                            if query_prim(s, &mut qs[j], prim, i, &rays[j], &pres[j], work) {
                                m &= !(1 << j);
                                live &= !(1 << j);
                            }
                            (tq[j], bound[j]) = (qs[j].t, qs[j].bound);
                        }
                    }
                    if m == 0 {
                        break;
                    }
                }
                if live == 0 {
                    return;
                }
            } else {
                work.nodes += 1;
                let Some(node) = s.bvh.get(link as usize) else {
                    return;
                };
                // The whole packet's bound first; then, for each child it
                // may enter, which of the lanes' rays do.
                let (tb, cand) = packet_entries(node, &iv, reach(&tq, m));
                let (tl, te) = if exact {
                    lanes_entering(node, cand, &lw, &iv.neg, &tq, m)
                } else {
                    (
                        [0, 1, 2, 3].map(|k| if (cand >> k) & 1 == 1 { m } else { 0 }),
                        tb,
                    )
                };
                let mut entered = 0;
                for k in 0..W {
                    entered |= ((tl[k] != 0) as u32) << k;
                }
                if entered != 0 {
                    // Nearest first for the closest hit, lane order for
                    // feelers, as the single ray's walk.
                    let mut order = [0usize; W];
                    let mut n = 0;
                    while entered != 0 {
                        let k = entered.trailing_zeros() as usize;
                        entered &= entered - 1;
                        let mut j = n;
                        while !shadow && j > 0 && te[k] < te[order[j - 1]] {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = k;
                        n += 1;
                    }
                    for j in (1..n).rev() {
                        stack_slot[sp] = link * BVH_WIDTH + order[j] as u32;
                        stack_lanes[sp] = tl[order[j]];
                        stack_t[sp] = te[order[j]];
                        sp += 1;
                    }
                    work.stack_at(sp);
                    let k = order[0];
                    slot = link * BVH_WIDTH + k as u32;
                    m = tl[k];
                    count = node.count[k];
                    link = node.link[k];
                    t = te[k];
                    continue;
                }
            }
        }
        if sp == 0 {
            return;
        }
        sp -= 1;
        slot = stack_slot[sp];
        let n = &s.bvh[slot as usize / W];
        link = n.link[slot as usize % W];
        count = n.count[slot as usize % W];
        m = stack_lanes[sp];
        t = stack_t[sp];
    }
}

/// The nearest hit below `tmax` of each ray of a packet: what
/// `accel::closest_hit` gives each alone.
pub fn closest_hit_packet<F: Real, const P: usize>(
    s: &SceneView,
    rays: &[Ray<F>; P],
    pres: &[RayPre<F>; P],
    tmax: F,
    work: &mut Work,
) -> [Option<(Hit<F>, u32)>; P] {
    let mut qs = [Query::closest(tmax); P];
    if s.globals.flags[1] == ACCEL_BVH {
        for j in 0..P {
            query_unbounded(s, &mut qs[j], &rays[j], &pres[j], work);
        }
        bvh_walk_packet(s, rays, pres, &mut qs, all_lanes(P), EXACT_EYE, work);
    } else {
        for j in 0..P {
            accel_traverse(s, &rays[j], &pres[j], &mut qs[j], work);
        }
    }
    qs.map(|q| q.hit)
}

/// The light reaching the far ends of the feelers of lanes `live`
/// (lengths `dist`) towards light `light`: what `accel::transmittance`
/// gives each alone (zero in the other lanes).
pub fn transmittance_packet<F: Real, const P: usize>(
    s: &SceneView,
    rays: &[Ray<F>; P],
    pres: &[RayPre<F>; P],
    dist: &[F; P],
    light: usize,
    mut live: Lanes,
    work: &mut Work,
) -> [V3<F>; P] {
    let g = s.globals;
    let mut out = [V3::zero(); P];
    let light_buffers = g.flags[3] > 0 && light < g.counts[2] as usize;
    if g.flags[1] != ACCEL_BVH || light_buffers {
        for j in lanes(live) {
            out[j] = transmittance(s, &rays[j], &pres[j], dist[j], light, work);
        }
        return out;
    }
    let lanes_in = live;
    // The shadow cache's primitive first, as for one feeler.
    let cached = if light < SHADOW_CACHE_LIGHTS as usize && s.shadow_cache() {
        *work.cached(light)
    } else {
        0
    };
    if cached != 0 {
        let prim = &s.prims[cached as usize - 1];
        let leaf = *work.cached_leaf(light);
        for j in lanes(live) {
            if !cache_admits(s, cached - 1, leaf, &rays[j], &pres[j], dist[j]) {
                continue;
            }
            work.tests += 1;
            if intersect(prim, s.extra, &rays[j], &pres[j], dist[j]).is_some() {
                live &= !(1 << j);
            }
        }
    }
    let mut qs = [Query::shadow(F::zero(), light); P];
    for j in lanes(live) {
        qs[j] = Query::shadow(dist[j], light);
        if query_unbounded(s, &mut qs[j], &rays[j], &pres[j], work) {
            live &= !(1 << j);
        }
    }
    bvh_walk_packet(s, rays, pres, &mut qs, live, EXACT_FEELERS, work);
    for j in lanes(lanes_in) {
        // A lane the cache blocked kept its query's zero length: done or
        // not, its light is zero.
        if !qs[j].done && (live >> j) & 1 == 1 {
            out[j] = qs[j].trans;
        }
    }
    out
}
