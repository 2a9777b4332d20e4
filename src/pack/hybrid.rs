//! The hybrid structure (`--accel hybrid`): the uniform grid, whose
//! crowded cells hold a small BVH each instead of a flat list
//! (docs/method.md, "Hybrid"). A cell listing more than `--hybrid-cell`
//! primitives lists one entry instead, `HYBRID_NODE | root`: the root of
//! a BVH (`pack::bvh`, the same build and node layout) over the cell's
//! primitives, whose leaves list them (by index, after every cell's list
//! in `refs`). The nodes live in the BVH's buffer. The walks:
//! `trace::grid` (twin: `shaders/grid.glsl`) steps through the cells and
//! walks a nested BVH where a cell has one (`trace::bvh`, `bvh.glsl`).
//!
//! The nested BVHs bound each primitive by its whole box, not the box
//! clipped to the cell: the grid skips a primitive the previous cell
//! listed (its cell range), which is right only if that cell tested it
//! whenever the ray meets it, and a box clipped to the previous cell
//! would not be entered by a ray that meets the primitive further on.

use super::bvh;
use super::grid::{cells_of, Bounds, Grid};
use crate::constants::{BVH_WIDTH, HYBRID_NODE};
use crate::pack::layout::BvhNode;
use rayon::prelude::*;

/// `--hybrid-cell` by default: a cell listing more primitives than this
/// holds a BVH: `bvh::MAX_LEAF`, the most a BVH leaf lists.
pub const DEFAULT_CELL: u32 = super::bvh::MAX_LEAF as u32;

/// The hybrid's top grid: about this many primitives per cell, where the
/// plain grid aims at `GRID_DENSITY` (about 2): its cells are meant to
/// crowd, their BVHs sorting them out. Measured on SPD rings, gears,
/// teapot, balls, sphereflake 4 and 20 000 random spheres at 8 to 512
/// (BENCHMARKS.md, "The hybrid"): the coarser, the nearer the BVH on the
/// clustered scenes and the farther from the grid on the even one.
pub const PRIMS_PER_CELL: usize = 128;

/// What nesting adds.
#[derive(Clone, Debug, Default)]
pub struct Nested {
    /// Every crowded cell's BVH, depth-first each, one after another
    /// (`nodes`), and their shape together: the deepest node of any
    /// (`depth`, a root: 0), their leaves, the most primitives in one.
    /// No `order`: the leaves list their primitives through `refs`.
    pub tree: bvh::Bvh,
    /// Cells that hold a BVH.
    pub cells: u64,
    /// Their primitives (references), now in the BVHs' leaves.
    pub refs: u64,
}

/// The cells of `g` listing more than `threshold` primitives, and how
/// many references they list together.
pub fn crowded(g: &Grid, threshold: u32) -> (u64, u64) {
    let n = cells_of(g.dims) as usize;
    let mut cells = 0u64;
    let mut refs = 0u64;
    for c in 0..n {
        let k = (g.cell_start[c + 1] - g.cell_start[c]) as u64;
        if k > threshold as u64 {
            cells += 1;
            refs += k;
        }
    }
    (cells, refs)
}

/// The most bytes nesting may add to the grid for `crowded` cells
/// listing `refs` references: a 4-wide node per reference at most (a
/// binary tree over n primitives has n − 1 interior nodes), each cell's
/// one entry, and the leaves' lists.
pub fn bytes_at_most(cells: u64, refs: u64) -> u64 {
    refs * std::mem::size_of::<BvhNode>() as u64 + 4 * (cells + refs)
}

/// Replaces every cell of `g` listing more than `threshold` primitives
/// (`bounds`: all of them, in the grid's order) by one entry naming its
/// BVH's root; the BVHs are built in parallel. `Err(nodes)` when their
/// nodes would not fit below `HYBRID_NODE` (then the grid stays as it
/// was).
pub fn nest(g: &mut Grid, bounds: &[Bounds], threshold: u32) -> Result<Nested, u64> {
    let ncells = cells_of(g.dims) as usize;
    let crowded: Vec<usize> = (0..ncells)
        .filter(|&c| g.cell_start[c + 1] - g.cell_start[c] > threshold)
        .collect();
    let none = |_: super::grid::Stage, _: u64, _: u64| {};
    // Per crowded cell: its BVH (links local to it) and its leaves' list.
    let built: Vec<(bvh::Bvh, Vec<u32>)> = crowded
        .par_iter()
        .map(|&c| {
            let list = &g.refs[g.cell_start[c] as usize..g.cell_start[c + 1] as usize];
            let cb: Vec<Bounds> = list.iter().map(|&p| bounds[p as usize]).collect();
            let tree = bvh::build(&cb, &none);
            let leaves = tree.order.iter().map(|&o| list[o as usize]).collect();
            (tree, leaves)
        })
        .collect();
    let total_nodes: u64 = built.iter().map(|(t, _)| t.nodes.len() as u64).sum();
    if total_nodes >= HYBRID_NODE as u64 {
        return Err(total_nodes);
    }
    // The new lists: each crowded cell one entry, the others as they were.
    let mut offsets = Vec::with_capacity(g.cell_start.len());
    let mut refs = Vec::with_capacity(g.refs.len());
    let mut out = Nested {
        cells: crowded.len() as u64,
        ..Nested::default()
    };
    let mut next = 0usize;
    let mut node_base = 0u32;
    for c in 0..ncells {
        offsets.push(refs.len() as u32);
        let (a, b) = (g.cell_start[c] as usize, g.cell_start[c + 1] as usize);
        if next < crowded.len() && crowded[next] == c {
            refs.push(HYBRID_NODE | node_base);
            node_base += built[next].0.nodes.len() as u32;
            next += 1;
        } else {
            refs.extend_from_slice(&g.refs[a..b]);
        }
    }
    offsets.push(refs.len() as u32);
    // The BVHs' nodes with their links made global, and their leaves'
    // lists after the cells'.
    for (tree, leaves) in &built {
        let node_base = out.tree.nodes.len() as u32;
        let leaf_base = refs.len() as u32;
        for n in &tree.nodes {
            let mut n = *n;
            for k in 0..BVH_WIDTH as usize {
                if n.count[k] > 0 {
                    n.link[k] += leaf_base;
                } else if n.link[k] > 0 {
                    n.link[k] += node_base;
                }
            }
            out.tree.nodes.push(n);
        }
        refs.extend_from_slice(leaves);
        out.refs += leaves.len() as u64;
        out.tree.depth = out.tree.depth.max(tree.depth);
        out.tree.leaves += tree.leaves;
        out.tree.max_leaf = out.tree.max_leaf.max(tree.max_leaf);
    }
    // The empty-space distances after the offsets are unchanged: no cell
    // became empty or listed.
    offsets.extend_from_slice(&g.cell_start[ncells + 1..]);
    g.cell_start = offsets;
    g.refs = refs;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pack::grid::{self, Bounds};

    fn ball(x: f64, y: f64, z: f64, r: f64) -> Bounds {
        Bounds {
            lo: [x - r, y - r, z - r],
            hi: [x + r, y + r, z + r],
        }
    }

    #[test]
    fn crowded_cells_list_one_root_and_the_leaves_list_their_primitives() {
        // 200 small balls in one corner, 20 spread out: the corner's cells crowd.
        let mut b: Vec<Bounds> = (0..200)
            .map(|i| {
                ball(
                    (i % 10) as f64 * 0.01,
                    (i / 10 % 10) as f64 * 0.01,
                    (i / 100) as f64 * 0.01,
                    0.004,
                )
            })
            .collect();
        b.extend((0..20).map(|i| ball(i as f64, (i * 7 % 20) as f64, (i * 3 % 20) as f64, 0.3)));
        let none = |_: grid::Stage, _: u64, _: u64| {};
        let mut g = grid::build(&b, None, &|_| u64::MAX, &none).unwrap();
        let before = g.clone();
        let (cells, refs) = crowded(&g, 16);
        assert!(cells >= 1 && refs >= 200, "{cells} {refs}");
        let nested = nest(&mut g, &b, 16).unwrap();
        assert_eq!((nested.cells, nested.refs), (cells, refs));
        assert!(!nested.tree.nodes.is_empty());
        assert!(
            (nested.tree.nodes.len() as u64) * 128 + 4 * (cells + refs)
                <= bytes_at_most(cells, refs)
        );
        let n = cells_of(g.dims) as usize;
        for c in 0..n {
            let old =
                &before.refs[before.cell_start[c] as usize..before.cell_start[c + 1] as usize];
            let new = &g.refs[g.cell_start[c] as usize..g.cell_start[c + 1] as usize];
            if old.len() > 16 {
                // One entry naming the root; its leaves list the same primitives.
                assert_eq!(new.len(), 1);
                assert!(new[0] & HYBRID_NODE != 0);
                let mut found = Vec::new();
                let mut stack = vec![new[0] & !HYBRID_NODE];
                while let Some(k) = stack.pop() {
                    let node = &nested.tree.nodes[k as usize];
                    for l in 0..4 {
                        if node.count[l] > 0 {
                            let a = node.link[l] as usize;
                            found.extend_from_slice(&g.refs[a..a + node.count[l] as usize]);
                        } else if node.link[l] > 0 {
                            stack.push(node.link[l]);
                        }
                    }
                }
                found.sort_unstable();
                let mut want = old.to_vec();
                want.sort_unstable();
                assert_eq!(found, want, "cell {c}");
            } else {
                assert_eq!(new, old, "cell {c}");
            }
        }
        // The empty-space distances are kept.
        assert_eq!(g.cell_start[n + 1..], before.cell_start[n + 1..]);
    }
}
