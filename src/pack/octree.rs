//! Building the octree over the finite primitives (docs/method.md,
//! "Octree").
//!
//! The octree subdivides the grid's box (`grid::grid_box`, not a cube:
//! each axis is halved at every level) adaptively: a node is split into
//! eight children while it lists more than `max_leaf` primitives, above
//! the deepest level (`max_levels`), and while the surface-area heuristic
//! expects the split to save tests: a ray crossing the node crosses each
//! child with probability a quarter (its share of the surface), so the
//! split costs `NODE_COST` + Σ n_child / 4 tests against n. Primitives
//! that overlap one another stop it where splitting only copies them
//! into every child (a pile, or the faces of overlapping boxes, which a
//! count rule alone would refine down to the deepest level). A primitive
//! is listed in every leaf its bounds overlap, like a grid cell's list.
//!
//! Every node lies on the lattice of the deepest level: 2^L cells on each
//! axis, L = `Octree::levels`, a node at level l spans 2^(L−l) of them. A
//! primitive's bounds become a range of lattice cells once (grown by a
//! thousandth of a lattice cell, like the grid's ranges, so that a hit
//! the traversal's rounding puts one cell over is still listed there),
//! and the build is integer arithmetic from there: no primitive is lost
//! at a boundary. The traversal (`trace::octree`) finds the next leaf
//! from a lattice point too.
//!
//! Layout (`Packed::cell_start`, which the grid's offsets use otherwise):
//! two words per node, node 0 the root. An interior node: the index of
//! its first child (the eight are consecutive; child k holds the half
//! with bit 0 of k set on x, bit 1 on y, bit 2 on z) and
//! `OCTREE_INTERIOR`; a leaf: the offset of its list in `refs` and its
//! length.

use super::grid::{grid_box, Bounds};
use crate::constants::{OCTREE_INTERIOR, OCTREE_MAX_LEVELS};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Cost of visiting a node (finding the leaf, leaving it) against one
/// intersection test, for the split rule.
pub const NODE_COST: f64 = 1.0;
/// Default most primitives in a leaf (`--octree-leaf`). Measured on the
/// SPD scenes and the scaling families (docs/method.md, "Octree").
pub const DEFAULT_LEAF: u32 = 8;
/// Default deepest level (`--octree-levels`).
pub const DEFAULT_LEVELS: u32 = 12;

/// How the tracers walk the octree (`--octree-walk`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Walk {
    /// Leaf to leaf: from where the ray leaves a leaf, the leaf across
    /// that face (the lecture's method; `trace::octree::octree_traverse`).
    #[default]
    Neighbour,
    /// Top down with a stack, the children a ray passes through in order
    /// (`trace::octree::octree_traverse_stack`).
    Stack,
}

/// How far the build subdivides, and how the tracers walk it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Params {
    /// A node listing at most this many primitives is a leaf.
    pub max_leaf: u32,
    /// The deepest level (the root at 0), at most `OCTREE_MAX_LEVELS`.
    pub max_levels: u32,
    pub walk: Walk,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            max_leaf: DEFAULT_LEAF,
            max_levels: DEFAULT_LEVELS,
            walk: Walk::Neighbour,
        }
    }
}

/// The octree: its box, the lattice, the nodes and the leaves' lists.
#[derive(Clone, Debug, Default)]
pub struct Octree {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    /// The lattice cell's size on each axis: (hi − lo) / 2^levels.
    pub cell: [f32; 3],
    /// The lattice's levels: 2^levels cells per axis.
    pub levels: u32,
    /// Two words per node (module docs).
    pub nodes: Vec<u32>,
    pub refs: Vec<u32>,
    pub leaves: u32,
    /// The deepest leaf's level.
    pub depth: u32,
    /// Most primitives in one leaf.
    pub max_leaf: u32,
}

impl Octree {
    pub fn node_count(&self) -> usize {
        self.nodes.len() / 2
    }

    /// Bytes kept for the render.
    pub fn bytes(&self) -> usize {
        (self.nodes.len() + self.refs.len()) * 4
    }
}

/// Why no octree was built: its nodes' words and references when it
/// passed the budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refusal {
    pub words: u64,
    pub refs: u64,
}

/// The most levels an axis of the box `lo..hi` allows: each lattice cell
/// at least 8 f32 steps of the coordinates wide, so that the lattice's
/// planes stay distinct numbers.
fn f32_levels(lo: f32, hi: f32) -> u32 {
    let ulp = lo.abs().max(hi.abs()) as f64 * f32::EPSILON as f64;
    let cells = (hi as f64 - lo as f64) / (8.0 * ulp);
    if cells.is_nan() || cells < 2.0 {
        return 0;
    }
    (cells.log2().floor() as u32).min(OCTREE_MAX_LEVELS)
}

/// One primitive's lattice cells: lowest and highest on each axis.
#[derive(Clone, Copy, Debug)]
struct Range {
    lo: [u32; 3],
    hi: [u32; 3],
}

/// A node still to build: its lattice origin and side, its level, the
/// primitives overlapping it.
struct Task {
    node: usize,
    org: [u32; 3],
    size: u32,
    level: u32,
    items: Vec<u32>,
}

/// Builds the octree over `bounds` (the packed finite primitives, in
/// order: a leaf lists indices into it, ascending). `max_words(words)`:
/// the most references the build may make with that many node words
/// within the memory budget; refused once it passes that.
pub fn build(
    bounds: &[Bounds],
    params: Params,
    max_refs: &(dyn Fn(u64) -> u64 + Sync),
) -> Result<Octree, Refusal> {
    if bounds.is_empty() {
        return Ok(Octree {
            nodes: vec![0, 0],
            leaves: 1,
            ..Octree::default()
        });
    }
    let all = bounds.iter().fold(Bounds::EMPTY, |a, b| a.union(b));
    let (lo, hi) = grid_box(&all);
    let levels = (0..3)
        .map(|i| f32_levels(lo[i], hi[i]))
        .min()
        .unwrap_or(0)
        .min(params.max_levels.min(OCTREE_MAX_LEVELS));
    let side = 1u32 << levels;
    let cell = [0, 1, 2].map(|i| (hi[i] - lo[i]) / side as f32);
    let cell_of = |x: f64, i: usize| -> u32 {
        let c = ((x - lo[i] as f64) / cell[i] as f64).floor();
        (c.max(0.0) as u32).min(side - 1)
    };
    let ranges: Vec<Range> = bounds
        .iter()
        .map(|b| {
            let margin = |i: usize| cell[i] as f64 * 1e-3;
            Range {
                lo: [0, 1, 2].map(|i| cell_of(b.lo[i] - margin(i), i)),
                hi: [0, 1, 2].map(|i| cell_of(b.hi[i] + margin(i), i)),
            }
        })
        .collect();
    let used = Used {
        words: AtomicU64::new(2),
        refs: AtomicU64::new(0),
        max_refs,
    };
    let root = Task {
        node: 0,
        org: [0; 3],
        size: side,
        level: 0,
        items: (0..bounds.len() as u32).collect(),
    };
    // The top levels, serially, down to nodes of fewer than
    // `PARALLEL_MIN` primitives; then those subtrees in parallel.
    let mut t = Octree {
        lo,
        hi,
        cell,
        levels,
        nodes: vec![0, 0],
        ..Octree::default()
    };
    let mut pending = vec![root];
    let mut frontier = Vec::new();
    while let Some(task) = pending.pop() {
        let kids = if task.items.len() >= PARALLEL_MIN {
            split(&ranges, params, &task)
        } else {
            None
        };
        let Some(k) = kids else {
            frontier.push(task);
            continue;
        };
        let base = interior(&mut t.nodes, task.node);
        used.add(16, 0)?;
        pending.extend(children(&task, base, k));
    }
    let subs: Vec<Result<Sub, Refusal>> = frontier
        .par_iter_mut()
        .map(|task| {
            subtree(
                &ranges,
                params,
                std::mem::take(&mut task.items),
                task,
                &used,
            )
        })
        .collect();
    for (task, sub) in frontier.iter().zip(subs) {
        let sub = sub?;
        // Local node i ≥ 1 becomes node `offset + i`; the root takes the
        // frontier node's place.
        let offset = (t.nodes.len() / 2 - 1) as u32;
        let refs_at = t.refs.len() as u32;
        let fix = |w: &[u32]| {
            if w[1] == OCTREE_INTERIOR {
                [w[0] + offset, OCTREE_INTERIOR]
            } else {
                [w[0] + refs_at, w[1]]
            }
        };
        let root = fix(&sub.nodes[0..2]);
        t.nodes[2 * task.node..2 * task.node + 2].copy_from_slice(&root);
        for w in sub.nodes[2..].chunks_exact(2) {
            t.nodes.extend_from_slice(&fix(w));
        }
        t.refs.extend_from_slice(&sub.refs);
        t.leaves += sub.leaves;
        t.depth = t.depth.max(sub.depth);
        t.max_leaf = t.max_leaf.max(sub.max_leaf);
    }
    Ok(t)
}

/// Subtrees of at least this many primitives are split before the rest
/// is built in parallel (rayon).
pub const PARALLEL_MIN: usize = 4096;

/// The words and references made so far, by every thread, against the
/// budget.
struct Used<'a> {
    words: AtomicU64,
    refs: AtomicU64,
    max_refs: &'a (dyn Fn(u64) -> u64 + Sync),
}

impl Used<'_> {
    /// Counts `words` more node words and `refs` more references; refused
    /// once they pass the budget or 32-bit offsets.
    fn add(&self, words: u64, refs: u64) -> Result<(), Refusal> {
        let w = self.words.fetch_add(words, Ordering::Relaxed) + words;
        let r = self.refs.fetch_add(refs, Ordering::Relaxed) + refs;
        if r > (self.max_refs)(w) || r > u32::MAX as u64 || w > u32::MAX as u64 {
            return Err(Refusal { words: w, refs: r });
        }
        Ok(())
    }
}

/// The primitives of each child of `task`'s node, when the split rule
/// (module docs) splits it.
fn split(ranges: &[Range], params: Params, task: &Task) -> Option<[Vec<u32>; 8]> {
    let n = task.items.len();
    if n <= params.max_leaf as usize || task.size <= 1 {
        return None;
    }
    let h = task.size / 2;
    let mut k: [Vec<u32>; 8] = Default::default();
    for &i in &task.items {
        let r = &ranges[i as usize];
        // The halves the range overlaps on each axis: from the lower (0)
        // or the upper (1), to the lower or the upper.
        let from = [0, 1, 2].map(|a| (r.lo[a] >= task.org[a] + h) as usize);
        let to = [0, 1, 2].map(|a| (r.hi[a] >= task.org[a] + h) as usize);
        for z in from[2]..=to[2] {
            for y in from[1]..=to[1] {
                for x in from[0]..=to[0] {
                    k[x | y << 1 | z << 2].push(i);
                }
            }
        }
    }
    // The surface-area heuristic: a ray crossing the node crosses a child
    // with the child's share of its surface, a quarter, so it tests
    // Σ n_c / 4 primitives after a node visit instead of n.
    let cost = NODE_COST + k.iter().map(|l| l.len()).sum::<usize>() as f64 / 4.0;
    (cost < n as f64).then_some(k)
}

/// Makes `node` interior: its eight children (left to fill) appended to
/// `nodes`; the first child's index.
fn interior(nodes: &mut Vec<u32>, node: usize) -> usize {
    let base = nodes.len() / 2;
    nodes[2 * node] = base as u32;
    nodes[2 * node + 1] = OCTREE_INTERIOR;
    nodes.extend_from_slice(&[0; 16]);
    base
}

/// The tasks of the eight children of `task`'s node, whose first is node
/// `base`, last to first (popped child 0 first).
fn children(task: &Task, base: usize, k: [Vec<u32>; 8]) -> impl Iterator<Item = Task> + '_ {
    let h = task.size / 2;
    k.into_iter().enumerate().rev().map(move |(c, items)| Task {
        node: base + c,
        org: [0, 1, 2].map(|a| task.org[a] + h * ((c as u32 >> a) & 1)),
        size: h,
        level: task.level + 1,
        items,
    })
}

/// A subtree built on its own: its nodes (root first) with local indices
/// and offsets into its own `refs`.
struct Sub {
    nodes: Vec<u32>,
    refs: Vec<u32>,
    leaves: u32,
    depth: u32,
    max_leaf: u32,
}

/// Builds the subtree of `root` (whose primitives are `items`)
/// depth-first.
fn subtree(
    ranges: &[Range],
    params: Params,
    items: Vec<u32>,
    root: &Task,
    used: &Used,
) -> Result<Sub, Refusal> {
    let mut t = Sub {
        nodes: vec![0, 0],
        refs: Vec::new(),
        leaves: 0,
        depth: 0,
        max_leaf: 0,
    };
    let mut stack = vec![Task {
        node: 0,
        org: root.org,
        size: root.size,
        level: root.level,
        items,
    }];
    while let Some(task) = stack.pop() {
        match split(ranges, params, &task) {
            Some(k) => {
                let base = interior(&mut t.nodes, task.node);
                used.add(16, 0)?;
                stack.extend(children(&task, base, k));
            }
            None => {
                let n = task.items.len();
                used.add(0, n as u64)?;
                t.nodes[2 * task.node] = t.refs.len() as u32;
                t.nodes[2 * task.node + 1] = n as u32;
                t.refs.extend_from_slice(&task.items);
                t.leaves += 1;
                t.depth = t.depth.max(task.level);
                t.max_leaf = t.max_leaf.max(n as u32);
            }
        }
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(c: [f64; 3], r: f64) -> Bounds {
        Bounds {
            lo: c.map(|x| x - r),
            hi: c.map(|x| x + r),
        }
    }

    fn free(_: u64) -> u64 {
        u64::MAX
    }

    /// The leaf holding lattice cell `p`: (node, origin, size).
    fn leaf_of(t: &Octree, p: [u32; 3]) -> (usize, [u32; 3], u32) {
        let mut node = 0usize;
        let mut size = 1u32 << t.levels;
        let mut org = [0u32; 3];
        while t.nodes[2 * node + 1] == OCTREE_INTERIOR {
            size /= 2;
            let c = (0..3).fold(0, |c, a| c | (((p[a] & size) != 0) as usize) << a);
            for (a, o) in org.iter_mut().enumerate() {
                *o += size * ((c as u32 >> a) & 1);
            }
            node = t.nodes[2 * node] as usize + c;
        }
        (node, org, size)
    }

    /// Checks, for a sample of primitives, that the leaf holding its
    /// centre lists it, that its list ascends, and that every primitive
    /// it lists is near it; the number checked.
    fn check_lists(t: &Octree, b: &[Bounds]) -> usize {
        let side = 1u32 << t.levels;
        // Walk a sample of lattice cells: each leaf lists exactly the
        // primitives whose cells meet it, ascending.
        let cell_of = |x: f64, i: usize| {
            (((x - t.lo[i] as f64) / t.cell[i] as f64).floor().max(0.0) as u32).min(side - 1)
        };
        let mut checked = 0;
        for i in (0..b.len()).step_by(7) {
            let c = [0, 1, 2].map(|a| cell_of((b[i].lo[a] + b[i].hi[a]) / 2.0, a));
            let (node, org, size) = leaf_of(t, c);
            let (start, n) = (t.nodes[2 * node] as usize, t.nodes[2 * node + 1] as usize);
            let list = &t.refs[start..start + n];
            assert!(list.contains(&(i as u32)), "{i} not in its leaf");
            assert!(list.windows(2).all(|w| w[0] < w[1]));
            for &j in list {
                let bj = &b[j as usize];
                for (a, &o) in org.iter().enumerate() {
                    let (l, h) = (cell_of(bj.lo[a] - 1.0, a), cell_of(bj.hi[a] + 1.0, a));
                    assert!(l < o + size && h >= o, "{j} listed far from its leaf");
                }
            }
            checked += 1;
        }
        checked
    }

    #[test]
    fn a_large_build_made_in_parallel_lists_what_a_leaf_overlaps() {
        // Above PARALLEL_MIN: the top levels split serially, the rest in
        // parallel and spliced together.
        let mut s = 99u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let b: Vec<Bounds> = (0..40_000)
            .map(|_| cube([rnd() * 100.0, rnd() * 100.0, rnd() * 100.0], rnd() * 0.8))
            .collect();
        let t = build(&b, Params::default(), &free).unwrap();
        assert!(t.leaves > 4000, "{}", t.leaves);
        assert!(check_lists(&t, &b) > 5000);
        // Every node is reached once from the root, every reference
        // from one leaf.
        let mut seen = vec![false; t.node_count()];
        let mut refs = 0usize;
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            assert!(!seen[n], "node {n} reached twice");
            seen[n] = true;
            if t.nodes[2 * n + 1] == OCTREE_INTERIOR {
                stack.extend((0..8).map(|c| t.nodes[2 * n] as usize + c));
            } else {
                refs += t.nodes[2 * n + 1] as usize;
            }
        }
        assert!(seen.iter().all(|&x| x), "unreachable nodes");
        assert_eq!(refs, t.refs.len());
    }

    #[test]
    fn every_leaf_a_primitive_overlaps_lists_it() {
        // Random small cubes, a few large ones, a pile of equal ones.
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut b: Vec<Bounds> = (0..3000)
            .map(|_| cube([rnd() * 100.0, rnd() * 100.0, rnd() * 10.0], rnd() * 0.5))
            .collect();
        b.extend((0..5).map(|_| cube([rnd() * 100.0, rnd() * 100.0, 5.0], 20.0)));
        b.extend((0..40).map(|_| cube([50.0, 50.0, 5.0], 0.1)));
        let t = build(&b, Params::default(), &free).unwrap();
        assert!(t.leaves > 100, "{}", t.leaves);
        let checked = check_lists(&t, &b);
        assert!(checked > 400);
        // The pile of 40 equal cubes cannot be split: one leaf holds them
        // all, at a level above the deepest.
        assert!(t.max_leaf >= 40 && t.max_leaf < 60, "{}", t.max_leaf);
    }

    #[test]
    fn leaves_hold_at_most_max_leaf_where_they_can_be_split() {
        let b: Vec<Bounds> = (0..512)
            .map(|i| {
                let c = [(i % 8) as f64, ((i / 8) % 8) as f64, (i / 64) as f64];
                cube(c.map(|x| x * 10.0), 1.0)
            })
            .collect();
        for max_leaf in [1, 4, 8] {
            let t = build(
                &b,
                Params {
                    max_leaf,
                    max_levels: DEFAULT_LEVELS,
                    ..Params::default()
                },
                &free,
            )
            .unwrap();
            assert!(t.max_leaf <= max_leaf, "{max_leaf}: {}", t.max_leaf);
            // Separated cubes are each in one leaf.
            assert_eq!(t.refs.len(), 512, "{max_leaf}");
        }
        let t = build(
            &b,
            Params {
                max_leaf: 1,
                max_levels: 2,
                ..Params::default()
            },
            &free,
        )
        .unwrap();
        assert_eq!(t.levels, 2);
        assert_eq!(t.depth, 2);
        assert_eq!(t.leaves, 64);
        assert_eq!(t.max_leaf, 8);
    }

    #[test]
    fn overlapping_primitives_stop_the_subdivision() {
        // Nine large cubes overlapping one another, and a few small ones:
        // a count rule would refine the faces of the overlaps down to the
        // deepest level (billions of leaves at 16 levels).
        let mut b: Vec<Bounds> = (0..9)
            .map(|i| cube([i as f64 * 0.3, (i % 3) as f64 * 0.2, 0.0], 10.0))
            .collect();
        b.extend((0..60).map(|i| {
            cube(
                [(i % 20) as f64 * 2.0 - 20.0, 15.0 - (i / 20) as f64, 7.3],
                0.1,
            )
        }));
        let t = build(
            &b,
            Params {
                max_leaf: 1,
                max_levels: 16,
                ..Params::default()
            },
            &free,
        )
        .unwrap();
        assert!(t.node_count() < 2000, "{} nodes", t.node_count());
        assert!(t.refs.len() < 2000, "{} refs", t.refs.len());
        // The small cubes are still separated.
        assert!(t.depth >= 5, "depth {}", t.depth);
    }

    #[test]
    fn the_budget_refuses_before_the_lists_grow_past_it() {
        let b: Vec<Bounds> = (0..1000)
            .map(|i| cube([i as f64, (i * 7 % 13) as f64, 0.0], 3.0))
            .collect();
        let whole = build(&b, Params::default(), &free).unwrap();
        let cap = whole.refs.len() as u64 / 2;
        let r = build(&b, Params::default(), &|_| cap).unwrap_err();
        assert!(r.refs > cap && r.refs <= cap + 1000, "{r:?}");
    }

    #[test]
    fn one_primitive_or_none_is_one_leaf() {
        let t = build(&[], Params::default(), &free).unwrap();
        assert_eq!((t.nodes.clone(), t.leaves), (vec![0, 0], 1));
        let t = build(&[cube([1.0, 2.0, 3.0], 1.0)], Params::default(), &free).unwrap();
        assert_eq!((t.nodes.clone(), t.refs.clone()), (vec![0, 1], vec![0]));
    }

    #[test]
    fn levels_stop_where_f32_planes_would_merge() {
        assert_eq!(f32_levels(0.0, 1.0), OCTREE_MAX_LEVELS);
        // 1e6 .. 1e6 + 1: an f32 step there is 1/16; 2 cells of 8 steps.
        assert_eq!(f32_levels(1.0e6, 1.0e6 + 1.0), 0);
        assert_eq!(f32_levels(1.0e6, 1.0e6 + 16.0), 4);
    }
}
