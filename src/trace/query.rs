//! The two questions a traversal answers, and what it does with each
//! primitive it reaches: twin of `shaders/query.glsl`.
//!
//! Every acceleration structure has one traversal (`grid::grid_traverse`,
//! `bvh::bvh_traverse`) that serves both queries: it hands each primitive
//! to `query_prim` and bounds its walk by `Query::t`. For the closest hit
//! `t` is the best hit so far and shrinks with every hit; for a shadow
//! feeler (any hit, with the transmittance of every transparent blocker)
//! it is the feeler's length and stays, and the walk stops once an opaque
//! blocker has made the light zero (`Query::done`).

use super::intersect::{intersect, sphere, Hit, RayPre};
use super::math::{Ray, Real, V3};
use super::SceneView;
use crate::constants::{ACCEL_BVH, SHADOW_CACHE_LEVELS, SHADOW_CACHE_LIGHTS};
use crate::pack::layout::Prim;

/// Per-thread scratch of the tracer: counters of intersection work (for
/// tests and profiling) and the shadow cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Primitive intersection tests.
    pub tests: u64,
    /// Grid cells visited.
    pub cells: u64,
    /// BVH nodes visited (each one tests its up to four children's boxes).
    pub nodes: u64,
    /// The eye rays' share of `tests`, `cells` and `nodes` (their closest
    /// hits, by a packet or alone): `Work::credit_eye`.
    pub eye: [u64; 3],
    /// The shadow feelers' share of `tests`, `cells` and `nodes` (the
    /// rest is the reflected and refracted rays' closest hits).
    pub shadow: [u64; 3],
    /// The deepest any structure walk's stack went: the most children a
    /// BVH walk (or octree stack walk) held pushed at once (the shader's
    /// `BVH_STACK_SIZE` bounds it).
    pub stack: u32,
    /// Shadow cache (Haines & Greenberg's "last blocker"): per level of the
    /// ray tree and per light, 1 + the index of the opaque primitive that
    /// last blocked a feeler to it from that level (0: none). Tested
    /// first, it answers most shadowed feelers without a traversal. It
    /// never changes a result: an opaque blocker makes the transmittance
    /// exactly zero whatever else the feeler crosses.
    pub shadow_cache: [[u32; SHADOW_CACHE_LIGHTS as usize]; SHADOW_CACHE_LEVELS as usize],
    /// Beside each cached blocker, the BVH leaf the walk met it in: 1 +
    /// node · `BVH_WIDTH` + lane (0: none, e.g. an unbounded primitive).
    /// Under the BVH the cache answers only where that leaf's box, tested
    /// as the walk tests it, admits the feeler (`accel::transmittance`).
    pub shadow_leaf: [[u32; SHADOW_CACHE_LIGHTS as usize]; SHADOW_CACHE_LEVELS as usize],
    /// The level of the ray tree whose cache feelers use now (the ray's
    /// depth, the deepest levels sharing the last: `Work::at_depth`).
    pub level: usize,
}

impl Work {
    /// Feelers from now on are cast from the hit of a ray of `depth`
    /// (0: an eye ray): they use that level's shadow cache.
    #[inline(always)]
    pub fn at_depth(&mut self, depth: u32) {
        self.level = (depth as usize).min(SHADOW_CACHE_LEVELS as usize - 1);
    }

    /// The shadow cache's entry for `light` (< `SHADOW_CACHE_LIGHTS`) at
    /// the current level.
    #[inline(always)]
    pub fn cached(&mut self, light: usize) -> &mut u32 {
        &mut self.shadow_cache[self.level % SHADOW_CACHE_LEVELS as usize][light]
    }

    /// The leaf of the shadow cache's entry for `light` (`shadow_leaf`).
    #[inline(always)]
    pub fn cached_leaf(&mut self, light: usize) -> &mut u32 {
        &mut self.shadow_leaf[self.level % SHADOW_CACHE_LEVELS as usize][light]
    }

    /// Adds `o`'s counters (not its cache); the deepest stack is the
    /// deeper of the two.
    pub fn add(&mut self, o: &Work) {
        self.tests += o.tests;
        self.cells += o.cells;
        self.nodes += o.nodes;
        for k in 0..3 {
            self.eye[k] += o.eye[k];
            self.shadow[k] += o.shadow[k];
        }
        self.stack = self.stack.max(o.stack);
    }

    /// The three counters (tests, cells, nodes) as they stand, to credit
    /// what a query adds to them to a kind of ray (`Work::credit_eye`,
    /// `Work::credit_shadow`).
    #[inline(always)]
    pub fn totals(&self) -> [u64; 3] {
        [self.tests, self.cells, self.nodes]
    }

    /// Credits what the counters grew by since `before` (`totals`) to the
    /// eye rays' share. The shaders do the same around the same queries
    /// (query.glsl's `work_eye` and `work_shadow`).
    #[inline(always)]
    pub fn credit_eye(&mut self, before: [u64; 3]) {
        let now = self.totals();
        for k in 0..3 {
            self.eye[k] += now[k] - before[k];
        }
    }

    /// Credits what the counters grew by since `before` to the feelers'
    /// share (`credit_eye`).
    #[inline(always)]
    pub fn credit_shadow(&mut self, before: [u64; 3]) {
        let now = self.totals();
        for k in 0..3 {
            self.shadow[k] += now[k] - before[k];
        }
    }

    /// The counters (tests, cells, nodes) of each kind of ray: eye,
    /// secondary (reflected and refracted: what the other two leave of
    /// the totals), shadow.
    pub fn by_kind(&self) -> [[u64; 3]; 3] {
        let total = self.totals();
        let secondary =
            std::array::from_fn(|k| total[k].saturating_sub(self.eye[k] + self.shadow[k]));
        [self.eye, secondary, self.shadow]
    }

    /// Notes a walk's stack holding `depth` pushed entries.
    #[inline(always)]
    pub fn stack_at(&mut self, depth: usize) {
        self.stack = self.stack.max(depth as u32);
    }
}

/// One query in progress.
#[derive(Clone, Copy, Debug)]
pub struct Query<F> {
    /// Hits count only below this distance: the best hit so far (closest
    /// hit), or the feeler's length (shadow).
    pub t: F,
    /// Any hit (a shadow feeler) rather than the closest.
    pub shadow: bool,
    /// Shadow: the light's slot in the shadow cache (≥
    /// `SHADOW_CACHE_LIGHTS`: none).
    pub light: usize,
    /// Closest hit: the best hit and its primitive.
    pub hit: Option<(Hit<F>, u32)>,
    /// Primitives are asked for hits below this: `t` until a hit is found
    /// (and always for a feeler), then the least value above the best
    /// hit's distance, so that a hit at the same distance (a tie) is seen.
    pub bound: F,
    /// Closest hit: the best hit's rank (`rank`); a tie goes to the lower.
    pub rank: u32,
    /// Shadow: the product of the k_t of the blockers found so far.
    pub trans: V3<F>,
    /// Shadow: an opaque blocker was found (the walk may stop).
    pub done: bool,
    /// Shadow: a blocker that lets light through counts only where its
    /// hit lies in `lo..hi` (everywhere but under the octree, whose walk
    /// sets its current leaf's stretch of the feeler: a primitive listed
    /// in several leaves multiplies the light once, in the leaf its hit
    /// lies in; `trace::octree`).
    pub lo: F,
    pub hi: F,
}

impl<F: Real> Query<F> {
    /// The nearest hit below `tmax`.
    pub fn closest(tmax: F) -> Self {
        Query {
            t: tmax,
            shadow: false,
            light: SHADOW_CACHE_LIGHTS as usize,
            hit: None,
            bound: tmax,
            rank: u32::MAX,
            trans: V3::splat(F::one()),
            done: false,
            lo: F::neg_infinity(),
            hi: F::infinity(),
        }
    }

    /// The light left at the end of a feeler of length `dist` towards
    /// light `light`.
    pub fn shadow(dist: F, light: usize) -> Self {
        Query {
            t: dist,
            shadow: true,
            light,
            hit: None,
            bound: dist,
            rank: u32::MAX,
            trans: V3::splat(F::one()),
            done: false,
            lo: F::neg_infinity(),
            hi: F::infinity(),
        }
    }
}

/// Where primitive `i` stands when two are hit at the same distance, the
/// same whatever order the structure packs them in: its index in the
/// grid's packing order (bounded primitives in the Morton order of their
/// boxes' centres, scene order among equal codes, then the unbounded
/// ones). Under the grid that is `i` itself; the BVH packs primitives in
/// leaf order and keeps the rank in `cell_lo`, which only the grid uses
/// otherwise (`pack::layout::Prim`; docs/method.md, "Ties").
#[inline(always)]
pub fn rank(s: &SceneView, prim: &Prim, i: u32) -> u32 {
    if s.globals.flags[1] == ACCEL_BVH {
        prim.cell_lo
    } else {
        i
    }
}

/// Tests `prim` (primitive `i`) for query `q`; true when the query is
/// done (an opaque blocker for a feeler: nothing further can change the
/// answer). Of two primitives hit at the same distance, the closest hit
/// is the one of lower `rank`, so that every structure, walked in any
/// order, and brute force find the same primitive (two surfaces meeting
/// where a ray crosses them: SPD rings' spheres and cylinders).
#[inline(always)]
pub fn query_prim<F: Real>(
    s: &SceneView,
    q: &mut Query<F>,
    prim: &Prim,
    i: u32,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    work: &mut Work,
) -> bool {
    work.tests += 1;
    match intersect(prim, s.extra, ray, pre, q.bound) {
        Some(h) => query_hit(s, q, prim, i, h, work),
        None => q.done,
    }
}

/// `query_prim` for primitive `i` of the structure (one of the first
/// `globals.counts.x`), a sphere tested from its 16-byte record when the
/// view has the sphere records (`SceneView::spheres`,
/// `pack::grid::Walk`): the 64-byte record is read only for a hit or for
/// another kind. The same test, answer and counters (docs/architecture.md,
/// "The CPU's own arrays").
#[inline(always)]
pub fn query_indexed<F: Real>(
    s: &SceneView,
    q: &mut Query<F>,
    i: u32,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    work: &mut Work,
) -> bool {
    if let Some(c) = s.spheres.get(i as usize) {
        if c[3] >= 0.0 {
            work.tests += 1;
            return match sphere(V3::of(c), F::of(c[3]), ray, q.bound) {
                Some(h) => query_hit(s, q, &s.prims[i as usize], i, h, work),
                None => q.done,
            };
        }
    }
    query_prim(s, q, &s.prims[i as usize], i, ray, pre, work)
}

/// What query `q` makes of hit `h` of `prim` (primitive `i`) below its
/// bound: `query_prim` once the intersection test has found it (a
/// packet's tests find it for several rays at once: `trace::packet`).
#[inline(always)]
pub fn query_hit<F: Real>(
    s: &SceneView,
    q: &mut Query<F>,
    prim: &Prim,
    i: u32,
    h: Hit<F>,
    work: &mut Work,
) -> bool {
    if q.shadow {
        let kt = V3::of(&s.materials[prim.material() as usize].kt);
        if kt.max_elem() > F::zero() && !(h.t >= q.lo && h.t < q.hi) {
            return false;
        }
        q.trans = q.trans.mul_elem(kt);
        if kt.max_elem() <= F::zero() && q.light < SHADOW_CACHE_LIGHTS as usize && s.shadow_cache()
        {
            *work.cached(q.light) = i + 1;
            // The BVH's walk names the leaf (`bvh::bvh_walk`).
            *work.cached_leaf(q.light) = 0;
        }
        if q.trans.max_elem() <= F::zero() {
            q.done = true;
        }
    } else {
        // h.t ≤ q.t: nearer, or a tie.
        let r = rank(s, prim, i);
        if h.t < q.t || r < q.rank {
            q.t = h.t;
            q.bound = h.t.next_up_t();
            q.rank = r;
            q.hit = Some((h, i));
        }
    }
    q.done
}

/// Runs query `q` over the unbounded primitives (planes, unclipped
/// quadrics, giants), which every ray and feeler tests before any walk;
/// true when the query is done.
#[inline(always)]
pub fn query_unbounded<F: Real>(
    s: &SceneView,
    q: &mut Query<F>,
    ray: &Ray<F>,
    pre: &RayPre<F>,
    work: &mut Work,
) -> bool {
    let g = s.globals;
    for i in g.counts[0]..g.counts[1] {
        if query_prim(s, q, &s.prims[i as usize], i, ray, pre, work) {
            return true;
        }
    }
    false
}
