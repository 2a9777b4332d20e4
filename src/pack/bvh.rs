//! Building the bounding-volume hierarchy over the finite primitives
//! (docs/method.md, "Bounding-volume hierarchy").
//!
//! Binned surface-area heuristic (Wald 2007): at each node the centroids
//! are sorted into `BINS` equal bins on each axis, and the split between
//! two bins that minimises `TRAVERSAL_COST` + (A_L·N_L + A_R·N_R)/A is
//! taken, or a leaf is made when that is no cheaper than testing the
//! node's `N` primitives (at most `MAX_LEAF` of them); in a tree of at
//! least `LARGE_TREE` primitives a node of at most `LARGE_LEAF` is a
//! leaf without asking. Subtrees of at least `PARALLEL_MIN` primitives
//! are built in parallel (rayon).
//!
//! Every primitive is in exactly one leaf and a leaf is a contiguous run
//! of primitives: `Bvh::order` is the order the packed primitives take.
//! The binary tree is then collapsed into 4-wide nodes (`collapse`,
//! `pack::layout::BvhNode`), flattened depth-first: a node's children are
//! the binary tree's descendants two or three levels down, the one with
//! the largest surface area opened first, so that one node visit tests up
//! to four boxes with four-wide arithmetic and a walk visits about half
//! as many nodes.
//!
//! Boxes are f32, rounded outwards from the primitives' f64 bounds padded
//! by `PAD_REL` of their diagonal and `PAD_ULPS` f32 steps of the scene's
//! largest coordinate: a ray whose f32 intersection routine hits a
//! primitive enters every box around it, rounding and all.
//!
//! Depth: the traversal's stack has `BVH_STACK_SIZE` entries. A binary
//! walk would push at most one per interior node on its path, so the
//! binary tree keeps its interior nodes at depth < `BVH_STACK_SIZE`: a
//! node at depth d with N primitives is split by the heuristic only while
//! d + ⌈log₂ N⌉ < `BVH_STACK_SIZE` − 1, and at the median otherwise
//! (which halves N at each level). A 4-wide node pushes up to three; the
//! collapse opens a child only while every path keeps within the stack
//! (`collapse`), so a tree deep enough to need it keeps 2-wide nodes
//! where it must.

use super::grid::{Bounds, Progress, Stage};
use super::layout::BvhNode;
use crate::constants::{BVH_STACK_SIZE, BVH_WIDTH};
use std::sync::atomic::{AtomicU64, Ordering};

/// Bins per axis of the binned heuristic.
pub const BINS: usize = 16;
/// Most primitives in a leaf (more are split, at the median if need be).
pub const MAX_LEAF: usize = 8;
/// Cost of a binary node relative to one primitive intersection test.
/// Half a test: the collapse to 4-wide nodes tests the boxes of two
/// binary levels in one visit. Against 1, gears' tracing takes 16 % fewer
/// instructions (callgrind, 128², `--preset spd`), the other SPD scenes
/// within 1 % either way.
pub const TRAVERSAL_COST: f64 = 0.5;
/// A tree over at least this many primitives makes every node of at
/// most `LARGE_LEAF` primitives a leaf without asking the heuristic.
/// Such a tree's nodes and primitives (about 60 + 64 bytes each for
/// spheres) outgrow a large last-level cache (32 MB), and its walks
/// wait on memory more than they compute: SPD sphereflake level 6
/// (598 k spheres) takes 8 % more instructions per ray than level 3
/// (821) but 2.6 times the time per ray (callgrind and one-thread
/// renders, 2026-12-04). The heuristic, which counts a node visit as
/// half a primitive test, split that tree down to one sphere a leaf
/// (280 k nodes, 36 MB); leaves of up to four leave 96 k nodes (12 MB)
/// and take 10 % off its render, 15 % off its build; below the size
/// they cost time (gears +17 %, rings +10 % in cache), so smaller trees
/// keep the heuristic's leaves (BENCHMARKS.md, "Leaves of large trees").
pub const LARGE_TREE: usize = 1 << 18;
/// See `LARGE_TREE`.
pub const LARGE_LEAF: usize = 4;
/// Subtrees of at least this many primitives are built in parallel.
pub const PARALLEL_MIN: usize = 4096;
/// Padding of each primitive's bounds: this share of its diagonal ...
pub const PAD_REL: f64 = 1e-5;
/// ... plus this many f32 steps of the scene's largest coordinate.
pub const PAD_ULPS: f64 = 8.0;

/// Bytes per finite primitive while the BVH is built: the build items
/// (28), the leaf order (4), the binary tree's entries (a slot of two
/// 32-byte entries per primitive, allotted before the build: 64), its
/// heights (4), and the 4-wide nodes (`BYTES_PER_PRIM`).
pub const BUILD_BYTES_PER_PRIM: u64 = 28 + 4 + 64 + 4 + BYTES_PER_PRIM;
/// Bytes per finite primitive the BVH keeps for the render, at most: one
/// 128-byte node per binary interior node (where the stack forbids
/// opening any child), fewer than one per primitive. A heuristic tree
/// keeps about a fifth of that (the binary tree has about one interior
/// node per two primitives, and a 4-wide node replaces about three).
pub const BYTES_PER_PRIM: u64 = 128;

/// One child of a node of the binary tree the build makes before the
/// collapse: entries 2k and 2k + 1 are interior node k's children. A
/// positive `count`: a leaf of `count` primitives from `link` on; `count`
/// = 0: the interior node `link`; an empty box (`EMPTY`) for a root that
/// is one leaf.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhChild {
    pub lo: [f32; 3],
    pub link: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

impl BvhChild {
    /// The child that no ray enters.
    pub const EMPTY: BvhChild = BvhChild {
        lo: [f32::INFINITY; 3],
        link: 0,
        hi: [f32::NEG_INFINITY; 3],
        count: 0,
    };

    /// An interior node (not a leaf, not empty).
    fn interior(&self) -> bool {
        self.count == 0 && self.link > 0
    }

    fn half_area(&self) -> f64 {
        Aabb {
            lo: self.lo,
            hi: self.hi,
        }
        .half_area()
    }
}

/// The hierarchy: its 4-wide nodes, the primitives' leaf order, and its
/// shape.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The nodes, depth-first (node 0 the root).
    pub nodes: Vec<BvhNode>,
    /// Position i of the packed (finite) primitives holds primitive
    /// `order[i]` of the input.
    pub order: Vec<u32>,
    /// Depth of the deepest node (the root: 0).
    pub depth: u32,
    /// Interior nodes of the binary tree the nodes were collapsed from.
    pub binary_nodes: u32,
    pub leaves: u32,
    /// Most primitives in one leaf.
    pub max_leaf: u32,
}

impl Bvh {
    /// Nodes (4-wide).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
    }
}

/// A primitive's padded f32 box and its index in the input.
#[derive(Clone, Copy, Debug)]
struct Item {
    lo: [f32; 3],
    hi: [f32; 3],
    idx: u32,
}

impl Item {
    /// Twice the centroid on `axis` (the factor 2 changes no split).
    #[inline]
    fn c2(&self, axis: usize) -> f32 {
        self.lo[axis] + self.hi[axis]
    }
}

/// A box, `N` lanes a corner: 3, or 4 for a bin's box (`BinBox`).
#[derive(Clone, Copy, Debug)]
struct Aabb<const N: usize = 3> {
    lo: [f32; N],
    hi: [f32; N],
}

impl<const N: usize> Aabb<N> {
    const EMPTY: Self = Aabb {
        lo: [f32::INFINITY; N],
        hi: [f32::NEG_INFINITY; N],
    };
    /// The union with the box `lo..hi`. Selects rather than
    /// `f32::min`/`max` (which also handle a NaN in `self`, never the case
    /// here: boxes start `EMPTY` and a NaN bound is ignored either way):
    /// one `minss`/`maxss` each in the build's inner loops.
    #[inline]
    fn grow(&mut self, lo: &[f32; N], hi: &[f32; N]) {
        for i in 0..N {
            self.lo[i] = if lo[i] < self.lo[i] {
                lo[i]
            } else {
                self.lo[i]
            };
            self.hi[i] = if hi[i] > self.hi[i] {
                hi[i]
            } else {
                self.hi[i]
            };
        }
    }
}

impl Aabb {
    #[inline]
    fn grow_point(&mut self, p: [f32; 3]) {
        self.grow(&p, &p);
    }
    /// Half the surface area, in f64 (f32 overflows past 1.8e19).
    fn half_area(&self) -> f64 {
        if self.lo[0] > self.hi[0] {
            return 0.0;
        }
        let e = [0, 1, 2].map(|i| self.hi[i] as f64 - self.lo[i] as f64);
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
}

/// `x` as the largest f32 not above it.
fn round_down(x: f64) -> f32 {
    let y = x as f32;
    if y as f64 > x {
        y.next_down()
    } else {
        y
    }
}

/// `x` as the smallest f32 not below it.
fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if (y as f64) < x {
        y.next_up()
    } else {
        y
    }
}

/// Each primitive's box: its bounds padded (module docs), rounded out to f32.
fn items(bounds: &[Bounds]) -> Vec<Item> {
    let mag = bounds
        .iter()
        .flat_map(|b| b.lo.iter().chain(b.hi.iter()))
        .filter(|x| x.is_finite())
        .fold(0f64, |m, x| m.max(x.abs()));
    let abs_pad = PAD_ULPS * f32::EPSILON as f64 * mag;
    bounds
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let d = b.diagonal();
            let pad = abs_pad + if d.is_finite() { PAD_REL * d } else { 0.0 };
            Item {
                lo: b.lo.map(|x| round_down(x - pad)),
                hi: b.hi.map(|x| round_up(x + pad)),
                idx: i as u32,
            }
        })
        .collect()
}

/// Builds the hierarchy over `bounds` (camera-relative, f64), reporting
/// progress as primitives reach their leaves. Empty input: no nodes.
pub fn build(bounds: &[Bounds], progress: Progress) -> Bvh {
    let n = bounds.len();
    if n == 0 {
        return Bvh::default();
    }
    progress(Stage::Bvh, 0, n as u64);
    let mut items = items(bounds);
    let ctx = Ctx {
        done: AtomicU64::new(0),
        total: n as u64,
        min_leaf: if n >= LARGE_TREE { LARGE_LEAF } else { 1 },
        progress,
    };
    // Every interior node's slot, allotted before the build (see
    // `build_rec`): n − 1 slots of two children each.
    let mut nodes = vec![BvhChild::EMPTY; 2 * (n - 1)];
    let mut shape = Shape::default();
    let nb = node_bounds(&items);
    let root = build_rec(&ctx, &mut items, nb, 0, 0, 0, &mut nodes, &mut shape);
    if root.count > 0 {
        // The whole scene is one leaf: a root whose second child is empty.
        nodes = vec![root, BvhChild::EMPTY];
        shape.interior = 1;
    }
    let (wide, depth) = collapse(&nodes);
    progress(Stage::Bvh, n as u64, n as u64);
    Bvh {
        binary_nodes: shape.interior,
        nodes: wide,
        order: items.iter().map(|it| it.idx).collect(),
        depth,
        leaves: shape.leaves,
        max_leaf: shape.max_leaf,
    }
}

/// Collapses the binary tree `bin` (two entries per interior node) into
/// 4-wide nodes; returns them (depth-first, the root first) and the depth
/// of the deepest.
///
/// A node starts with its binary node's two children and opens the
/// interior child of largest surface area (replacing it by its two
/// children, in place, so that the left-to-right order stays) until it
/// has `BVH_WIDTH` children or none is left to open. The stack bounds the
/// opening: a walk reaching a node after p pushes pushes at most k − 1
/// there (k children), and below a child c at most h(c), the binary
/// height of c (interior nodes on its longest downward path, each a
/// 2-wide node in the worst case). A child is opened only if p + k − 1 +
/// max h(c) stays within `BVH_STACK_SIZE`; the binary tree's depth bound
/// makes that hold at the root with two children, so it holds on every
/// path. In a heuristic tree of ordinary depth every node is opened fully.
pub fn collapse(bin: &[BvhChild]) -> (Vec<BvhNode>, u32) {
    if bin.is_empty() {
        return (Vec::new(), 0);
    }
    // Binary heights, children after parents (depth-first order).
    let nodes = bin.len() / 2;
    let mut h = vec![0u32; nodes];
    for k in (0..nodes).rev() {
        let ch = |c: &BvhChild| if c.interior() { h[c.link as usize] } else { 0 };
        h[k] = 1 + ch(&bin[2 * k]).max(ch(&bin[2 * k + 1]));
    }
    let mut out = Vec::with_capacity(nodes / 2 + 1);
    let mut depth = 0;
    wide_node(bin, &h, 0, 0, 0, &mut out, &mut depth);
    (out, depth)
}

/// Appends the 4-wide node made from binary interior node `node`, reached
/// after `pushes` pushes at `depth`, and its subtree; returns its index.
fn wide_node(
    bin: &[BvhChild],
    h: &[u32],
    node: u32,
    pushes: u32,
    depth: u32,
    out: &mut Vec<BvhNode>,
    max_depth: &mut u32,
) -> u32 {
    const W: usize = BVH_WIDTH as usize;
    let height = |c: &BvhChild| if c.interior() { h[c.link as usize] } else { 0 };
    let k = 2 * node as usize;
    // The children so far, `kids[..len]` (on the stack: no allocation per
    // node).
    let mut kids = [BvhChild::EMPTY; W];
    kids[..2].copy_from_slice(&bin[k..k + 2]);
    let mut len = 2;
    while len < W {
        let Some((i, _)) = kids[..len]
            .iter()
            .enumerate()
            .filter(|(_, c)| c.interior())
            .max_by(|a, b| a.1.half_area().total_cmp(&b.1.half_area()))
        else {
            break;
        };
        let c = 2 * kids[i].link as usize;
        // Child i replaced by its two children, in place.
        let mut trial = kids;
        trial.copy_within(i + 1..len, i + 2);
        trial[i] = bin[c];
        trial[i + 1] = bin[c + 1];
        let below = trial[..len + 1].iter().map(height).max().unwrap_or(0);
        if pushes + len as u32 + below > BVH_STACK_SIZE {
            break;
        }
        kids = trial;
        len += 1;
    }
    let kids = &kids[..len];
    *max_depth = (*max_depth).max(depth);
    let at = out.len();
    out.push(BvhNode::EMPTY);
    let inner = pushes + kids.len() as u32 - 1;
    let mut n = BvhNode::EMPTY;
    for (lane, c) in kids.iter().enumerate() {
        for a in 0..3 {
            n.bounds[0][a][lane] = c.lo[a];
            n.bounds[1][a][lane] = c.hi[a];
        }
        if c.interior() {
            n.link[lane] = wide_node(bin, h, c.link, inner, depth + 1, out, max_depth);
        } else {
            n.link[lane] = c.link;
            n.count[lane] = c.count;
        }
    }
    out[at] = n;
    at as u32
}

struct Ctx<'a> {
    done: AtomicU64,
    total: u64,
    /// Nodes of at most this many primitives are leaves whatever the
    /// heuristic says (`LARGE_LEAF` in a large tree, else 1).
    min_leaf: usize,
    progress: Progress<'a>,
}

/// What a subtree looks like (for `Bvh`'s fields).
#[derive(Clone, Copy, Debug, Default)]
struct Shape {
    leaves: u32,
    max_leaf: u32,
    /// Interior nodes of the binary tree.
    interior: u32,
}

impl Shape {
    fn join(&mut self, o: &Shape) {
        self.leaves += o.leaves;
        self.max_leaf = self.max_leaf.max(o.max_leaf);
        self.interior += o.interior;
    }
}

/// ⌈log₂ n⌉ for n ≥ 1.
fn ceil_log2(n: usize) -> u32 {
    usize::BITS - (n.max(1) - 1).leading_zeros()
}

/// Builds the subtree of `items` (at positions `first..` of the final
/// order), an interior node of it at `depth`, and returns the child entry
/// that points at it (a leaf, or the interior node). Its interior nodes
/// go into `out`, the slots `slot..slot + n − 1` of the binary tree (two
/// entries each): a subtree of n primitives has at most n − 1 interior
/// nodes, so its root takes slot `slot`, the left subtree (m primitives)
/// the next m − 1 and the right one the rest. Both sides of a parallel
/// split write their own part of one array, with no copy and no growth
/// (a slot a leaf leaves unused stays `EMPTY`, which no node links to);
/// children always follow their parent, as `collapse` needs.
#[allow(clippy::too_many_arguments)]
fn build_rec(
    ctx: &Ctx,
    items: &mut [Item],
    NodeBounds { bb, cb }: NodeBounds,
    first: u32,
    slot: u32,
    depth: u32,
    out: &mut [BvhChild],
    shape: &mut Shape,
) -> BvhChild {
    let n = items.len();
    let leaf = |shape: &mut Shape| {
        shape.leaves += 1;
        shape.max_leaf = shape.max_leaf.max(n as u32);
        let done = ctx.done.fetch_add(n as u64, Ordering::Relaxed) + n as u64;
        if done >> 16 != (done - n as u64) >> 16 {
            (ctx.progress)(Stage::Bvh, done, ctx.total);
        }
        BvhChild {
            lo: bb.lo,
            hi: bb.hi,
            link: first,
            count: n as u32,
        }
    };
    if n <= ctx.min_leaf {
        return leaf(shape);
    }
    // The heuristic while the depth allows it (module docs), else the median.
    let free = depth + ceil_log2(n) < BVH_STACK_SIZE - 1;
    let split = match if free {
        sah_split(items, &bb, &cb)
    } else {
        None
    } {
        Some((cost, axis, bin)) => {
            let leaf_cost = n as f64;
            if n <= MAX_LEAF && leaf_cost <= cost {
                return leaf(shape);
            }
            let k = bin_scale(&cb, axis);
            let lo = cb.lo[axis];
            partition(items, |it| bin_of(it.c2(axis), lo, k) <= bin)
        }
        None => {
            if n <= MAX_LEAF {
                return leaf(shape);
            }
            median_split(items, &cb)
        }
    };
    // A split always leaves both sides non-empty (the heuristic only
    // weighs such splits); guard against a bin disagreeing anyway.
    let (mid, lb, rb) = if split.0 == 0 || split.0 == n {
        median_split(items, &cb)
    } else {
        split
    };
    let (left, right) = items.split_at_mut(mid);
    let (mine, rest) = out.split_at_mut(2);
    let (lout, rout) = rest.split_at_mut(2 * (mid - 1));
    let (lslot, rslot) = (slot + 1, slot + mid as u32);
    let rfirst = first + mid as u32;
    let (l, r) = if n >= PARALLEL_MIN {
        let ((l, ls), (r, rs)) = rayon::join(
            || {
                let mut s = Shape::default();
                let c = build_rec(ctx, left, lb, first, lslot, depth + 1, lout, &mut s);
                (c, s)
            },
            || {
                let mut s = Shape::default();
                let c = build_rec(ctx, right, rb, rfirst, rslot, depth + 1, rout, &mut s);
                (c, s)
            },
        );
        shape.join(&ls);
        shape.join(&rs);
        (l, r)
    } else {
        let l = build_rec(ctx, left, lb, first, lslot, depth + 1, lout, shape);
        let r = build_rec(ctx, right, rb, rfirst, rslot, depth + 1, rout, shape);
        (l, r)
    };
    mine[0] = l;
    mine[1] = r;
    shape.interior += 1;
    BvhChild {
        lo: bb.lo,
        hi: bb.hi,
        link: slot,
        count: 0,
    }
}

/// Bins per unit of (twice) the centroid on `axis`.
#[inline]
fn bin_scale(cb: &Aabb, axis: usize) -> f32 {
    BINS as f32 / (cb.hi[axis] - cb.lo[axis])
}

#[inline]
fn bin_of(c2: f32, lo: f32, k: f32) -> usize {
    // Non-negative, or NaN (0) for a centroid beyond f32: `as` saturates
    // (to i32: one conversion, where to usize takes two and a branch).
    (((c2 - lo) * k) as i32).clamp(0, BINS as i32 - 1) as usize
}

/// The best split by the binned heuristic: (cost relative to testing one
/// primitive, axis, last bin of the left side). `None` when every
/// centroid is at one point (nothing to split by).
fn sah_split(items: &[Item], bb: &Aabb, cb: &Aabb) -> Option<(f64, usize, usize)> {
    let ok = |a: usize| cb.hi[a] - cb.lo[a] > 0.0 && bin_scale(cb, a).is_finite();
    let axes = [ok(0), ok(1), ok(2)];
    if axes == [false; 3] {
        return None;
    }
    let scale = [0, 1, 2].map(|a| bin_scale(cb, a));
    let bin = |bins: &mut Bins, chunk: &[Item]| {
        for it in chunk {
            for a in 0..3 {
                if axes[a] {
                    let b = bin_of(it.c2(a), cb.lo[a], scale[a]);
                    bins.boxes[a][b].grow3(&it.lo, &it.hi);
                    bins.counts[a][b] += 1;
                }
            }
        }
    };
    // Filled in place: a `Bins` is 1.3 kB, and moving it out of a closure
    // cost the build three copies per node.
    let mut bins = Bins::default();
    if items.len() >= PARALLEL_MIN * 16 {
        use rayon::prelude::*;
        bins = items
            .par_chunks(PARALLEL_MIN * 4)
            .map(|chunk| {
                let mut b = Bins::default();
                bin(&mut b, chunk);
                b
            })
            .reduce(Bins::default, Bins::merge);
    } else {
        bin(&mut bins, items);
    }
    let Bins { boxes, counts } = &bins;
    let parent = bb.half_area();
    let mut best: Option<(f64, usize, usize)> = None;
    for a in (0..3).filter(|&a| axes[a]) {
        // Right-hand sweep: area × count of bins b+1.. for each b. An
        // empty bin adds nothing: the value of the bin after it, exactly.
        let mut right = [0f64; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0u64;
        for b in (1..BINS).rev() {
            if counts[a][b] == 0 {
                right[b - 1] = if n > 0 { right[b] } else { -1.0 };
                continue;
            }
            let bx = boxes[a][b].aabb();
            acc.grow(&bx.lo, &bx.hi);
            n += counts[a][b] as u64;
            right[b - 1] = acc.half_area() * n as f64;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0u64;
        for b in 0..BINS - 1 {
            // After an empty bin the split costs what the one before it
            // did (same left box and count, same right side), which a
            // strictly lower cost is needed to beat: skipping it changes
            // nothing, and small nodes' bins are mostly empty.
            if counts[a][b] == 0 {
                continue;
            }
            let bx = boxes[a][b].aabb();
            acc.grow(&bx.lo, &bx.hi);
            n += counts[a][b] as u64;
            if right[b] < 0.0 {
                continue;
            }
            let sah = acc.half_area() * n as f64 + right[b];
            let cost = if parent > 0.0 {
                TRAVERSAL_COST + sah / parent
            } else {
                // A box of no area (all primitives flat in one plane
                // and line): weigh by counts alone.
                TRAVERSAL_COST + items.len() as f64
            };
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, a, b));
            }
        }
    }
    best
}

/// The heuristic's bins on each axis: the union of their items' boxes and
/// their counts.
#[derive(Clone, Copy)]
struct Bins {
    boxes: [[BinBox; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Default for Bins {
    fn default() -> Self {
        Bins {
            boxes: [[BinBox::EMPTY; BINS]; 3],
            counts: [[0; BINS]; 3],
        }
    }
}

impl Bins {
    fn merge(mut self, o: Bins) -> Bins {
        for a in 0..3 {
            for b in 0..BINS {
                let ob = o.boxes[a][b].aabb();
                self.boxes[a][b].grow3(&ob.lo, &ob.hi);
                self.counts[a][b] += o.counts[a][b];
            }
        }
        self
    }
}

/// A bin's box, its corners padded to four lanes (the fourth stays
/// ±∞). With three lanes (`Aabb`) LLVM stored a grown corner with a
/// masked store (`vmaskmovps`), which the next item's load of the same
/// bin cannot take from the store buffer: the load waited for the store
/// to reach the cache, and those loads held over half of the binning's
/// samples (`perf annotate`, 598 k spheres). Four lanes give plain
/// stores. The same minima and maxima, so the same tree.
type BinBox = Aabb<4>;

impl BinBox {
    /// Grows by the three-lane box `lo..hi` (the fourth lanes stay ±∞).
    #[inline]
    fn grow3(&mut self, lo: &[f32; 3], hi: &[f32; 3]) {
        self.grow(
            &[lo[0], lo[1], lo[2], f32::INFINITY],
            &[hi[0], hi[1], hi[2], f32::NEG_INFINITY],
        );
    }
    fn aabb(&self) -> Aabb {
        Aabb {
            lo: [self.lo[0], self.lo[1], self.lo[2]],
            hi: [self.hi[0], self.hi[1], self.hi[2]],
        }
    }
}

/// A node's box and its items' centroid box (twice the centroids).
#[derive(Clone, Copy, Debug)]
struct NodeBounds {
    bb: Aabb,
    cb: Aabb,
}

impl NodeBounds {
    const EMPTY: NodeBounds = NodeBounds {
        bb: Aabb::EMPTY,
        cb: Aabb::EMPTY,
    };
    #[inline]
    fn grow(&mut self, it: &Item) {
        self.bb.grow(&it.lo, &it.hi);
        self.cb.grow_point([it.c2(0), it.c2(1), it.c2(2)]);
    }
    fn merge(mut self, o: NodeBounds) -> NodeBounds {
        self.bb.grow(&o.bb.lo, &o.bb.hi);
        self.cb.grow(&o.cb.lo, &o.cb.hi);
        self
    }
}

/// The bounds of `items` (in parallel when there are many).
fn node_bounds(items: &[Item]) -> NodeBounds {
    let fold = |chunk: &[Item]| {
        let mut nb = NodeBounds::EMPTY;
        for it in chunk {
            nb.grow(it);
        }
        nb
    };
    if items.len() >= PARALLEL_MIN * 16 {
        use rayon::prelude::*;
        items
            .par_chunks(PARALLEL_MIN * 4)
            .map(fold)
            .reduce(|| NodeBounds::EMPTY, NodeBounds::merge)
    } else {
        fold(items)
    }
}

/// Splits at the median centroid of the widest centroid axis (by index
/// when every centroid is at one point); returns the left side's length
/// and both sides' bounds.
fn median_split(items: &mut [Item], cb: &Aabb) -> (usize, NodeBounds, NodeBounds) {
    let mid = items.len() / 2;
    let axis = (0..3)
        .max_by(|&a, &b| (cb.hi[a] - cb.lo[a]).total_cmp(&(cb.hi[b] - cb.lo[b])))
        .unwrap_or(0);
    if cb.hi[axis] > cb.lo[axis] {
        items.select_nth_unstable_by(mid, |x, y| x.c2(axis).total_cmp(&y.c2(axis)));
    }
    (mid, node_bounds(&items[..mid]), node_bounds(&items[mid..]))
}

/// Moves the items for which `left` holds to the front, keeping nothing
/// else in order; returns how many there are and both sides' bounds
/// (gathered on the way: no further pass over the items).
fn partition(items: &mut [Item], left: impl Fn(&Item) -> bool) -> (usize, NodeBounds, NodeBounds) {
    let mut lb = NodeBounds::EMPTY;
    let mut rb = NodeBounds::EMPTY;
    let mut i = 0;
    let mut j = items.len();
    while i < j {
        if left(&items[i]) {
            lb.grow(&items[i]);
            i += 1;
        } else {
            // The item grows the right side from a copy: read back after
            // the swap's two overlapping stores, its bytes could not be
            // forwarded from them, and the load stalled (perf: half of
            // the partition's time sat after it).
            let it = items[i];
            rb.grow(&it);
            j -= 1;
            items[i] = items[j];
            items[j] = it;
        }
    }
    (i, lb, rb)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds_of(points: &[([f64; 3], f64)]) -> Vec<Bounds> {
        points
            .iter()
            .map(|&(c, r)| Bounds {
                lo: c.map(|x| x - r),
                hi: c.map(|x| x + r),
            })
            .collect()
    }

    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut h = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            (h >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Walks the flattened tree checking its invariants: every primitive
    /// in exactly one leaf, every child box inside its parent's and
    /// around its primitives' (padded) bounds, nodes depth-first, and the
    /// children a walk may push on any path within the stack.
    fn check(bvh: &Bvh, bounds: &[Bounds]) {
        let n = bounds.len();
        let mut seen = vec![false; n];
        assert_eq!(bvh.order.len(), n);
        for &o in &bvh.order {
            assert!(!seen[o as usize], "primitive {o} twice in the order");
            seen[o as usize] = true;
        }
        let mut covered = vec![0u32; n];
        let mut leaves = 0;
        let mut depth = 0;
        // (node, depth, pushes before it, parent box)
        let mut stack = vec![(0usize, 0u32, 0u32, None::<Aabb>)];
        let mut visited = 0;
        while let Some((k, d, pushes, parent)) = stack.pop() {
            visited += 1;
            assert_eq!(k, visited - 1, "nodes are numbered depth-first");
            depth = depth.max(d);
            let node = &bvh.nodes[k];
            let lanes: Vec<usize> = (0..BVH_WIDTH as usize)
                .filter(|&l| node.count[l] > 0 || node.link[l] > 0)
                .collect();
            assert!(!lanes.is_empty());
            let inner = pushes + lanes.len() as u32 - 1;
            assert!(inner <= BVH_STACK_SIZE, "{inner} pushes on a path");
            for l in 0..BVH_WIDTH as usize {
                let lo = [0, 1, 2].map(|a| node.lo()[a][l]);
                let hi = [0, 1, 2].map(|a| node.hi()[a][l]);
                if !lanes.contains(&l) {
                    assert_eq!((lo, hi), ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]));
                    continue;
                }
                if let Some(p) = parent {
                    for i in 0..3 {
                        assert!(lo[i] >= p.lo[i] && hi[i] <= p.hi[i]);
                    }
                }
                if node.count[l] > 0 {
                    leaves += 1;
                    assert!(node.count[l] as usize <= MAX_LEAF.max(1));
                    for p in node.link[l]..node.link[l] + node.count[l] {
                        covered[p as usize] += 1;
                        let b = &bounds[bvh.order[p as usize] as usize];
                        for i in 0..3 {
                            assert!((lo[i] as f64) < b.lo[i] && (hi[i] as f64) > b.hi[i]);
                        }
                    }
                }
            }
            for &l in lanes.iter().rev() {
                if node.count[l] == 0 {
                    let b = Aabb {
                        lo: [0, 1, 2].map(|a| node.lo()[a][l]),
                        hi: [0, 1, 2].map(|a| node.hi()[a][l]),
                    };
                    stack.push((node.link[l] as usize, d + 1, inner, Some(b)));
                }
            }
        }
        assert_eq!(visited, bvh.node_count(), "every node reached once");
        assert!(
            covered.iter().all(|&c| c == 1),
            "every primitive in one leaf"
        );
        assert_eq!(leaves, bvh.leaves);
        assert_eq!(depth, bvh.depth);
    }

    #[test]
    fn random_scenes_build_valid_trees() {
        for (seed, n) in [(1, 1), (2, 2), (3, 9), (4, 100), (5, 5000), (6, 20_000)] {
            let mut r = rng(seed);
            let pts: Vec<_> = (0..n)
                .map(|_| ([r() * 100.0, r() * 10.0, r()], r() * 0.5))
                .collect();
            let b = bounds_of(&pts);
            let bvh = build(&b, &|_, _, _| {});
            check(&bvh, &b);
            assert!(bvh.node_count() < n.max(2));
            assert!(bvh.node_count() as u32 <= bvh.binary_nodes);
            if n >= 100 {
                // Most nodes are opened to four children.
                assert!(bvh.node_count() * 2 < bvh.binary_nodes as usize, "{n}");
            }
        }
    }

    /// A pile of copies (every centroid at one point) and a line of
    /// spheres whose sizes grow geometrically (a deep tree under the
    /// heuristic) both stay within the traversal's stack.
    #[test]
    fn degenerate_scenes_stay_within_the_stack() {
        let pile = bounds_of(&vec![([1.0, 2.0, 3.0], 1.0); 10_000]);
        let bvh = build(&pile, &|_, _, _| {});
        check(&bvh, &pile);
        assert!(bvh.depth <= ceil_log2(10_000));
        assert!(bvh.binary_nodes > 0);
        let line: Vec<_> = (0..3000)
            .map(|i| {
                let x = 1.01f64.powi(i);
                ([x, 0.0, 0.0], x * 1e-3)
            })
            .collect();
        let b = bounds_of(&line);
        let bvh = build(&b, &|_, _, _| {});
        check(&bvh, &b);
        assert!(bvh.depth < BVH_STACK_SIZE);
    }

    /// Spheres far apart on a lattice: the heuristic gives each its own
    /// leaf, until the tree is large (`LARGE_TREE`), where nodes of up to
    /// `LARGE_LEAF` primitives stay leaves.
    #[test]
    fn large_trees_keep_small_nodes_as_leaves() {
        let lattice = |n: usize| {
            let pts: Vec<_> = (0..n)
                .map(|i| {
                    (
                        [(i % 64) as f64, (i / 64 % 64) as f64, (i / 4096) as f64],
                        0.01,
                    )
                })
                .collect();
            bounds_of(&pts)
        };
        let n = LARGE_TREE - 1;
        let small = build(&lattice(n), &|_, _, _| {});
        assert_eq!(small.leaves as usize, n, "one sphere a leaf");
        assert_eq!(small.max_leaf, 1);
        let b = lattice(LARGE_TREE);
        let large = build(&b, &|_, _, _| {});
        check(&large, &b);
        assert_eq!(large.max_leaf as usize, LARGE_LEAF);
        assert!(
            (large.leaves as usize) < LARGE_TREE / 2,
            "{} leaves",
            large.leaves
        );
        assert!(large.node_count() * 2 < small.node_count());
    }

    /// Two clusters far apart: the root separates them, whatever the
    /// primitives' order.
    #[test]
    fn the_heuristic_separates_clusters() {
        let mut r = rng(7);
        let mut pts = Vec::new();
        for k in 0..200 {
            let x = if k % 2 == 0 { 0.0 } else { 1000.0 };
            pts.push(([x + r(), r(), r()], 0.1));
        }
        let b = bounds_of(&pts);
        let bvh = build(&b, &|_, _, _| {});
        check(&bvh, &b);
        let root = &bvh.nodes[0];
        let (mut near, mut far) = (0, 0);
        for l in 0..BVH_WIDTH as usize {
            if root.hi()[0][l] < 10.0 {
                near += 1;
            } else if root.lo()[0][l] > 990.0 {
                far += 1;
            }
        }
        assert!(near > 0 && far > 0 && near + far == BVH_WIDTH as usize);
    }

    #[test]
    fn outward_rounding() {
        for x in [0.1f64, -0.1, 1e-30, 3.0, 1e20, -7.25] {
            assert!(round_down(x) as f64 <= x);
            assert!(round_up(x) as f64 >= x);
            assert!(round_up(x) as f64 - round_down(x) as f64 <= (x.abs() * 2.4e-7));
        }
        assert_eq!(ceil_log2(1), 0);
        assert_eq!(ceil_log2(2), 1);
        assert_eq!(ceil_log2(5), 3);
    }
}
