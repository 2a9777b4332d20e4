//! What the render shader's loops iterate, seen from the host, for
//! llvmpipe's loop budget (docs/gpu.md, "lavapipe's loop budget"): which
//! property of the scene drives them (named when the device reports a cut
//! loop) and a certain lower bound from eye rays the CPU twin traces (to
//! refuse a render before dispatching it).
//!
//! The shader's loops, innermost first: a polygon's vertices (per
//! intersection test), a grid cell's primitives, the cells a ray steps
//! through (or a BVH leaf's primitives and the nodes), the unbounded primitives (per ray and per feeler), the lights
//! (per shaded point, each with a feeler), the rays of a sample's ray tree,
//! a pixel's samples.

use crate::constants::{FEAT_REFLECT, FEAT_REFRACT, FEAT_TRIANGLE, KIND_POLYGON, SAMPLING_CORNERS};
use crate::pack::Packed;
use crate::trace::accel::closest_hit;
use crate::trace::intersect::RayPre;
use crate::trace::math::{Ray, V3};
use crate::trace::query::Work;
use crate::trace::sample::{eye_dir, sample_pos};
use crate::trace::SceneView;

/// llvmpipe's budget: loop iterations a group of invocations (one SIMD
/// vector) may make in the whole shader, all loops together, before every
/// loop is stopped after one iteration (`LP_MAX_TGSI_LOOP_ITERATIONS`).
pub const LLVMPIPE_LOOP_BUDGET: u64 = 65_535;
/// `LLVMPIPE_LOOP_BUDGET` as messages print it.
pub const BUDGET_TEXT: &str = "65 535";

/// Most eye rays `certain_cut` traces along each axis of the lattice.
const PROBE_EDGE: u32 = 32;

/// `n` with a space between groups of three digits from 10 000 up.
pub fn thousands(n: u64) -> String {
    let s = n.to_string();
    if n < 10_000 {
        return s;
    }
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(c);
    }
    out
}

/// A property of the scene or the settings that multiplies the shader's
/// loop iterations.
#[derive(Clone, Debug, PartialEq)]
pub enum Driver {
    /// Samples per pixel (each traces a ray tree).
    Samples(u32),
    /// Rays in one sample's ray tree at most, and the depth that allows it.
    Depth { max_depth: u32, rays: u64 },
    /// Lights: every shaded point loops over them, a feeler each.
    Lights(u32),
    /// The polygon with the most vertices: every test of it walks them.
    Polygon {
        prim: u32,
        vertices: u32,
        /// Centre of its bounds, relative to the camera.
        centre: [f32; 3],
    },
    /// Unbounded primitives (planes, unclipped quadrics): every ray and
    /// feeler tests each.
    Unbounded(u32),
    /// The most primitives one grid cell lists.
    CellRefs(u32),
    /// The most primitives one light-buffer cell lists: every shadow
    /// feeler in that direction walks them all.
    LightBufferCell(u32),
    /// The most cells a ray steps through (the grid's x + y + z).
    GridCells { dims: [u32; 3] },
}

impl Driver {
    /// What it is, for a message: "20 000 lights".
    pub fn describe(&self) -> String {
        match self {
            Driver::Samples(n) => format!(
                "{} per pixel",
                super::plural(*n as u64, "sample", "samples")
            ),
            Driver::Depth { max_depth, rays } => format!(
                "ray trees of up to {} rays per sample (--max-depth {max_depth} with reflective or \
                 transparent materials)",
                thousands(*rays)
            ),
            Driver::Lights(n) => format!(
                "{} (every shaded point loops over all of them, with a shadow feeler each)",
                super::plural(*n as u64, "light", "lights")
            ),
            Driver::Polygon {
                prim,
                vertices,
                centre,
            } => format!(
                "a polygon with {} vertices (primitive {prim}, centred at ({:.3}, {:.3}, {:.3}) \
                 relative to the camera), all walked by every ray that tests it",
                thousands(*vertices as u64),
                centre[0],
                centre[1],
                centre[2]
            ),
            Driver::Unbounded(n) => format!(
                "{} (planes or unclipped quadrics), which every ray and shadow feeler tests",
                super::plural(*n as u64, "unbounded primitive", "unbounded primitives")
            ),
            Driver::CellRefs(n) => format!(
                "a grid cell listing {}",
                super::plural(*n as u64, "primitive", "primitives")
            ),
            Driver::LightBufferCell(n) => format!(
                "a light-buffer cell listing {}, all tested by every shadow feeler in its direction",
                super::plural(*n as u64, "primitive", "primitives")
            ),
            Driver::GridCells { dims } => format!(
                "a {}x{}x{} grid, through up to {} cells of which a ray steps",
                dims[0],
                dims[1],
                dims[2],
                thousands(dims.iter().map(|&d| d as u64).sum())
            ),
        }
    }

    /// What the user can change.
    pub fn remedy(&self) -> &'static str {
        match self {
            Driver::Samples(_) => "use a smaller --spp",
            Driver::Depth { .. } => "use a smaller --max-depth",
            Driver::Lights(_) => "use fewer lights",
            Driver::Polygon { .. } => "split the polygon into smaller ones or triangles",
            Driver::Unbounded(_) => "use fewer unbounded primitives",
            Driver::CellRefs(_) => "use a finer --grid",
            Driver::LightBufferCell(_) => "use --shadows plain",
            Driver::GridCells { .. } => "use a coarser --grid",
        }
    }
}

/// The loop lengths of a packed scene, each the largest one ray or sample
/// can meet.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopLoad {
    /// Samples per lattice point (1 for corner sampling).
    pub samples: u32,
    pub max_depth: u32,
    /// Rays in one sample's tree at most: 2^(depth+1) − 1 when a material
    /// reflects or refracts, else 1.
    pub rays: u64,
    pub lights: u32,
    /// The polygon with the most vertices: (primitive, vertices, centre).
    pub polygon: Option<(u32, u32, [f32; 3])>,
    pub unbounded: u32,
    pub cell_refs: u32,
    /// The most primitives one light-buffer cell lists (0: no light
    /// buffers).
    pub lb_refs: u32,
    pub dims: [u32; 3],
    /// With the BVH: a typical walk's steps, `BVH_WIDTH` per level of the
    /// deepest path (a node, and its other children pushed and popped)
    /// plus one leaf. With the octree: its leaves along a ray, each with
    /// its descent.
    pub bvh_steps: u32,
}

impl LoopLoad {
    /// Reads the loop lengths off `p` (one pass over the primitives and the
    /// grid's cell table).
    pub fn of(p: &Packed) -> LoopLoad {
        let g = &p.globals;
        let corners = g.image[3] == SAMPLING_CORNERS;
        let max_depth = g.trace[0];
        let rays = if g.trace[1] & (FEAT_REFLECT | FEAT_REFRACT) != 0 {
            (1u64 << (max_depth.min(62) + 1)) - 1
        } else {
            1
        };
        let mut polygon: Option<(u32, u32, [f32; 3])> = None;
        for (i, prim) in p.prims.iter().enumerate() {
            if prim.kind() != KIND_POLYGON {
                continue;
            }
            // The loop a test makes: every edge, or the longest edge band
            // (pack::polygon).
            let n = prim.b[3] as u32;
            if polygon.is_none_or(|(_, m, _)| n > m) {
                polygon = Some((i as u32, n, polygon_centre(p, prim)));
            }
        }
        // The longest list of an offsets array (a cell's first entry,
        // then the next cell's).
        let longest = |start: &[u32]| {
            start
                .windows(2)
                .map(|w| w[1].saturating_sub(w[0]))
                .max()
                .unwrap_or(0)
        };
        let octree = p.structure() == crate::pack::Accel::Octree;
        // The octree keeps its nodes where the grid keeps its offsets. The
        // grid's ncells + 1 offsets only: the skip bytes after them are no
        // offsets (read as such, they named a cell of 16 843 009
        // primitives, four skips of 1 in one word).
        let cell_refs = if octree {
            p.accel.max_leaf
        } else {
            let n = (g.grid_dims[3] as usize + 1).min(p.cell_start.len());
            longest(&p.cell_start[..n])
        };
        let lb_refs = if g.flags[3] > 0 {
            // The offsets, not the windows after them (pack::lightbuf).
            let cells = crate::pack::lightbuf::cells(g.counts[2] as usize, g.flags[3]) as usize;
            longest(&p.lb_start[..(cells + 1).min(p.lb_start.len())])
        } else {
            0
        };
        let has_grid = g.grid_min[3] != 0.0;
        LoopLoad {
            samples: if corners { 1 } else { g.image[2].max(1) },
            max_depth,
            rays,
            lights: p.lights.len() as u32,
            polygon,
            unbounded: g.counts[1].saturating_sub(g.counts[0]),
            cell_refs,
            lb_refs,
            dims: if has_grid && !octree {
                [g.grid_dims[0], g.grid_dims[1], g.grid_dims[2]]
            } else {
                [0; 3]
            },
            // The BVH's walk, or under the hybrid one crowded cell's BVH.
            bvh_steps: if matches!(
                p.structure(),
                crate::pack::Accel::Bvh | crate::pack::Accel::Hybrid
            ) && g.flags[2] > 0
            {
                crate::constants::BVH_WIDTH * (p.accel.depth + 1) + p.accel.max_leaf
            } else if octree && has_grid {
                // The leaves a ray crosses (at most one per lattice step,
                // and no more than there are), each found from the root.
                let steps = (3 * g.grid_dims[0]).min(p.accel.leaves as u32);
                steps.saturating_mul(p.accel.depth + 1)
            } else {
                0
            },
        }
    }

    /// Iterations one traversal (a ray or a feeler) makes at most: the
    /// unbounded primitives, the cells, one cell's list (or a BVH walk),
    /// the largest polygon once.
    fn traversal(&self) -> f64 {
        let cells: u32 = self.dims.iter().sum();
        let v = self.polygon.map_or(0, |(_, n, _)| n);
        (self.unbounded as f64
            + cells as f64
            + self.cell_refs as f64
            + self.bvh_steps as f64
            + v as f64)
            .max(1.0)
    }

    /// Iterations one shadow feeler makes at most: a traversal, or with
    /// light buffers the unbounded primitives, the longest cell list and
    /// the largest polygon once.
    fn feeler(&self) -> f64 {
        if self.lb_refs == 0 {
            return self.traversal();
        }
        let v = self.polygon.map_or(0, |(_, n, _)| n);
        (self.unbounded as f64 + self.lb_refs as f64 + v as f64).max(1.0)
    }

    /// A (loose) upper bound of the loop iterations of one invocation: per
    /// sample, per ray of its tree, a traversal plus, at the hit, the light
    /// loop with one feeler per light.
    pub fn worst(&self) -> f64 {
        let c = self.traversal();
        let l = self.lights as f64;
        self.samples as f64 * self.rays as f64 * (c + l * self.feeler() + l)
    }

    /// Each driver with the factor by which it multiplies `worst` (its
    /// value against the smallest it can take; light buffers against
    /// plain feelers), largest first, but light buffers that lengthen the
    /// loops first of all.
    pub fn drivers(&self) -> Vec<(Driver, f64)> {
        let c = self.traversal();
        let l = self.lights as f64;
        let cells: u32 = self.dims.iter().sum();
        // `worst` with the traversal cost cut by `less`, over `worst`.
        let without = |less: f64| c / (c - less).max(1.0);
        let mut v = vec![
            (Driver::Samples(self.samples), self.samples as f64),
            (
                Driver::Depth {
                    max_depth: self.max_depth,
                    rays: self.rays,
                },
                self.rays as f64,
            ),
        ];
        let f = self.feeler();
        if self.lights > 0 {
            // With plain feelers (the light buffers' share is their own).
            v.push((Driver::Lights(self.lights), (c + l * c + l) / c));
        }
        if self.lb_refs > 0 && self.lights > 0 {
            // Against plain feelers (each one a traversal).
            v.push((
                Driver::LightBufferCell(self.lb_refs),
                (c + l * f + l) / (c + l * c + l),
            ));
        }
        if let Some((prim, vertices, centre)) = self.polygon {
            v.push((
                Driver::Polygon {
                    prim,
                    vertices,
                    centre,
                },
                without(vertices as f64),
            ));
        }
        if self.unbounded > 0 {
            v.push((
                Driver::Unbounded(self.unbounded),
                without(self.unbounded as f64),
            ));
        }
        if self.cell_refs > 1 {
            v.push((
                Driver::CellRefs(self.cell_refs),
                without(self.cell_refs as f64 - 1.0),
            ));
        }
        if cells > 3 {
            v.push((
                Driver::GridCells { dims: self.dims },
                without(cells as f64 - 3.0),
            ));
        }
        // Stable: on a tie the order above (the user's simplest lever) wins.
        v.sort_by(|a, b| b.1.total_cmp(&a.1));
        // Light buffers that lengthen the loops come first whatever their
        // factor: the one remedy that leaves the image as it is
        // (`--shadows plain` gives the same pixels, bit for bit).
        if let Some(i) = v
            .iter()
            .position(|(d, k)| matches!(d, Driver::LightBufferCell(_)) && *k > 1.0)
        {
            let lb = v.remove(i);
            v.insert(0, lb);
        }
        v
    }

    /// The driver that multiplies the loops most.
    pub fn largest(&self) -> Driver {
        self.drivers().swap_remove(0).0
    }
}

fn polygon_centre(p: &Packed, prim: &crate::pack::layout::Prim) -> [f32; 3] {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in crate::pack::polygon::vertices_3d(prim, &p.extra) {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    [0, 1, 2].map(|k| 0.5 * lo[k] + 0.5 * hi[k])
}

/// A cut the host can predict: one eye ray whose own loops exceed the
/// budget, whatever its neighbours in the SIMD group do.
#[derive(Clone, Debug, PartialEq)]
pub struct CertainCut {
    /// The lattice point (a pixel, or a pixel corner with corner sampling).
    pub point: (u32, u32),
    pub corners: bool,
    /// Loop iterations that invocation makes at least.
    pub iterations: u64,
    /// The largest part of them.
    pub driver: Driver,
}

impl CertainCut {
    /// "pixel (4, 4)" or "pixel corner (4, 4)".
    pub fn at(&self) -> String {
        let (x, y) = self.point;
        if self.corners {
            format!("pixel corner ({x}, {y})")
        } else {
            format!("pixel ({x}, {y})")
        }
    }
}

/// Traces the first eye ray of up to 32 × 32 lattice points, spread over
/// the image, with the CPU twin (bit for bit what llvmpipe computes) and
/// counts the loop iterations its invocation must make whatever else
/// happens: the pixel's samples, the ray tree's first pass, every
/// unbounded primitive, and at the first hit every light and, for a
/// polygon, every vertex. The first point over `LLVMPIPE_LOOP_BUDGET`, if
/// any.
pub fn certain_cut(p: &Packed) -> Option<CertainCut> {
    let g = &p.globals;
    let s = SceneView::new(p);
    let corners = g.image[3] == SAMPLING_CORNERS;
    let (lw, lh) = if corners {
        (g.image[0] + 1, g.image[1] + 1)
    } else {
        (g.image[0], g.image[1])
    };
    if lw == 0 || lh == 0 {
        return None;
    }
    let samples = if corners { 0 } else { g.image[2].max(1) as u64 };
    let unbounded = g.counts[1].saturating_sub(g.counts[0]) as u64;
    let lights = p.lights.len() as u64;
    // Without a hit: the samples, one pass of the tree loop, the unbounded
    // primitives. A cheap early out before any ray is traced.
    let floor = samples + 1 + unbounded;
    let ceiling = floor + lights + LoopLoad::max_polygon(p) as u64;
    if ceiling <= LLVMPIPE_LOOP_BUDGET {
        return None;
    }
    let pick = |n: u32| -> Vec<u32> {
        let k = n.min(PROBE_EDGE);
        (0..k)
            .map(|i| (i as u64 * (n - 1) as u64 / (k - 1).max(1) as u64) as u32)
            .collect()
    };
    let mut work = Work::default();
    for y in pick(lh) {
        for x in pick(lw) {
            let (fx, fy) = if corners {
                (x as f32, y as f32)
            } else {
                sample_pos(g, x, y, 0)
            };
            let d = eye_dir::<f32>(g, fx, fy);
            let ray = Ray { o: V3::zero(), d };
            let pre = RayPre::new(d, s.has(FEAT_TRIANGLE));
            let hit = closest_hit::<f32>(&s, &ray, &pre, f32::INFINITY, &mut work);
            let mut parts = vec![
                (Driver::Samples(samples as u32), samples),
                (Driver::Unbounded(unbounded as u32), unbounded),
            ];
            if let Some((h, prim)) = hit {
                parts.push((Driver::Lights(lights as u32), lights));
                let pr = &p.prims[prim as usize];
                if pr.kind() == KIND_POLYGON {
                    // The edges this hit's test walks (all, or its band's).
                    let at = ray.o + ray.d * h.t;
                    let (_, i1) = crate::pack::polygon::axes(pr.b[1] as usize);
                    let (lo, hi) = crate::trace::intersect::polygon_edges(pr, &p.extra, at.get(i1));
                    let n = pr.b[0] as u32;
                    parts.push((
                        Driver::Polygon {
                            prim,
                            vertices: n,
                            centre: polygon_centre(p, pr),
                        },
                        (hi - lo) as u64,
                    ));
                }
            }
            let iterations = 1 + parts.iter().map(|p| p.1).sum::<u64>();
            if iterations > LLVMPIPE_LOOP_BUDGET {
                let driver = parts
                    .into_iter()
                    .max_by_key(|p| p.1)
                    .map(|p| p.0)
                    .expect("parts is not empty");
                return Some(CertainCut {
                    point: (x, y),
                    corners,
                    iterations,
                    driver,
                });
            }
        }
    }
    None
}

impl LoopLoad {
    /// The most vertices of any polygon in `p`.
    fn max_polygon(p: &Packed) -> u32 {
        p.prims
            .iter()
            .filter(|pr| pr.kind() == KIND_POLYGON)
            .map(|pr| pr.b[3] as u32)
            .max()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thousands_groups_from_ten_thousand() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(9999), "9999");
        assert_eq!(thousands(65_535), "65 535");
        assert_eq!(thousands(100_000), "100 000");
        assert_eq!(thousands(1_234_567), "1 234 567");
    }
}
