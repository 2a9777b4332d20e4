//! Scene → Packed: camera-relative f32 std430 arrays and the voxel grid.
//! Both tracers read only what this produces.

pub mod bvh;
pub mod grid;
pub mod hybrid;
pub mod layout;
pub mod lightbuf;
pub mod octree;
pub mod pages;
pub mod polygon;

use crate::budget::{Budget, BudgetError, Need};
use crate::constants::*;
use crate::scene::{Scene, Shape};
use glam::DVec3;
use grid::Bounds;
pub use grid::{Progress, Stage};
use layout::{BvhNode, Globals, Light, Material, Prim};
pub use pages::Pages;
use std::time::Instant;

/// How eye rays sample a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
pub enum Sampling {
    /// One ray through each pixel centre, or `spp` stratified jittered rays.
    #[default]
    Centers,
    /// SPD's convention: (W+1)×(H+1) rays through the pixel corners, each
    /// pixel the mean of its four.
    Corners,
}

/// The acceleration structure the tracers walk (`--accel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Accel {
    /// The uniform voxel grid, walked by 3D-DDA.
    Grid,
    /// A bounding-volume hierarchy built with the surface-area heuristic.
    Bvh,
    /// An octree, subdivided where the primitives crowd (`--octree-leaf`,
    /// `--octree-levels`), walked leaf to leaf from exit points.
    Octree,
    /// The grid, whose cells listing more than `--hybrid-cell` primitives
    /// hold a small BVH each (`pack::hybrid`).
    Hybrid,
    /// Chosen per scene by the rule in docs/method.md ("Choosing the
    /// structure").
    #[default]
    Auto,
}

/// How shadow feelers find their blockers (`--shadows`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Shadows {
    /// Through the acceleration structure, like every other ray.
    #[default]
    Plain,
    /// Through a light buffer per light: a direction cube whose cells list
    /// the primitives a feeler in that direction can meet (docs/method.md,
    /// "Light buffers"). Same images, bit for bit.
    #[value(name = "lightbuffer")]
    #[serde(rename = "lightbuffer")]
    LightBuffer,
}

/// The render settings that shape the packed data.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub max_depth: u32,
    pub min_weight: f32,
    pub spp: u32,
    pub sampling: Sampling,
    /// `--grid`: this resolution or a refusal; `None`: the heuristic.
    pub grid: Option<[u32; 3]>,
    /// `--accel`: the acceleration structure. An explicit `--grid`
    /// with `Auto` means the grid.
    pub accel: Accel,
    /// The memory the run may use (`--memory-limit`); packing refuses,
    /// before allocating, a run whose estimate is over it.
    pub budget: Budget,
    /// The surface offset ε of secondary rays relative to the scene's
    /// size; None: `EPS_OFFSET_REL` (`whitted stability` sweeps it).
    pub offset: Option<f32>,
    /// `--shadows`: how shadow feelers find their blockers.
    pub shadows: Shadows,
    /// `--octree-leaf`, `--octree-levels`: how far the octree subdivides.
    pub octree: octree::Params,
    /// `--hybrid-cell`: under the hybrid, a cell listing more primitives
    /// than this holds a BVH.
    pub hybrid_cell: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            width: None,
            height: None,
            max_depth: 5,
            min_weight: 1.0 / 256.0,
            spp: 1,
            sampling: Sampling::Centers,
            grid: None,
            accel: Accel::Auto,
            budget: Budget::system(),
            offset: None,
            shadows: Shadows::Plain,
            octree: octree::Params::default(),
            hybrid_cell: hybrid::DEFAULT_CELL,
        }
    }
}

/// Largest image width or height (the shader's lattice indices and the
/// image formats stay in 32 bits with room to spare).
pub const MAX_IMAGE_SIZE: u32 = 65536;

/// Why a scene cannot be packed: it or its image is too large.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PackError {
    /// The estimate is over the memory budget.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// More references than the 32-bit offsets address.
    #[error(
        "the grid {} needs {refs} references, more than the {} its 32-bit offsets can address; {}",
        dims_text(dims),
        grid::MAX_REFS,
        if *explicit { "choose a coarser --grid" } else { "the scene's primitives overlap too much" }
    )]
    GridRefs {
        dims: [u32; 3],
        refs: u64,
        explicit: bool,
    },
    /// More primitives (or extra data) than 32-bit indices address.
    #[error("the scene has {count} {what}, more than the {max} the packed format's 32-bit indices can address")]
    TooMany {
        what: &'static str,
        count: u64,
        max: u64,
    },
    /// `--grid` with `--accel bvh` or `octree` (the structure named).
    #[error("--grid sets the voxel grid's resolution; it does not go with --accel {0}")]
    GridWith(&'static str),
    /// An image side over `MAX_IMAGE_SIZE`.
    #[error("image {what} {value} is over the limit of {MAX_IMAGE_SIZE}")]
    ImageSize { what: &'static str, value: u32 },
}

impl PackError {
    /// Every refusal is the user's to fix (a smaller image, scene or grid,
    /// or a larger `--memory-limit`): the CLI exits with 2.
    pub fn is_user_error(&self) -> bool {
        true
    }
}

fn dims_text(d: &[u32; 3]) -> String {
    format!("{}x{}x{}", d[0], d[1], d[2])
}

/// How rays are counted (`RayStats`), set on the packed scene with
/// `Packed::set_counting`. Both ways give the same image, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, clap::ValueEnum)]
pub enum Counting {
    /// The rays whitted traces: a reflection ray where k_r > 0 (or on total
    /// internal reflection), one shadow feeler counted per feeler cast.
    #[default]
    Traced,
    /// As the SPD counts them (docs/spd.md): a surface with k_t > 0 also
    /// spawns a reflection ray where k_r = 0 (weight 0: traced, with its
    /// subtree, for the counts only; with `min_weight` > 0 such rays are
    /// cut at once), and only feelers towards lights the surface faces
    /// count as shadow rays.
    Spd,
}

/// A named set of render settings (`--preset`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Preset {
    /// The SPD's testing procedure: 512 × 512 pixels, rays through the
    /// pixel corners (513 × 513 eye rays), a tree depth of 5 counting the
    /// eye ray (`max_depth` 4), no adaptive cut-off (`min_weight` 0), rays
    /// counted as the SPD counts them.
    Spd,
}

impl Preset {
    /// The preset's settings (any of them may still be overridden).
    pub fn settings(self) -> Settings {
        match self {
            Preset::Spd => Settings {
                width: Some(512),
                height: Some(512),
                max_depth: 4,
                min_weight: 0.0,
                spp: 1,
                sampling: Sampling::Corners,
                grid: None,
                accel: Accel::Auto,
                budget: Budget::system(),
                offset: None,
                shadows: Shadows::Plain,
                octree: octree::Params::default(),
                hybrid_cell: hybrid::DEFAULT_CELL,
            },
        }
    }

    /// How the preset counts rays.
    pub fn counting(self) -> Counting {
        match self {
            Preset::Spd => Counting::Spd,
        }
    }
}

/// The acceleration structure in use and what it cost (`--stats`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AccelInfo {
    /// `Grid`, `Bvh` or `Octree` (never `Auto`).
    pub structure: Accel,
    /// Chosen by `Accel::Auto`'s rule.
    pub auto: bool,
    /// Build time: ordering, copies, and the structure itself.
    pub build_seconds: f64,
    /// Bytes the structure keeps for the render.
    pub bytes: usize,
    /// BVH and octree (0 for the grid): nodes (the BVH's 4-wide), leaves,
    /// the deepest node's depth, the most primitives in a leaf.
    pub nodes: usize,
    pub leaves: usize,
    pub depth: u32,
    pub max_leaf: u32,
    /// The hybrid (0 otherwise): the grid cells that hold a BVH of their
    /// own, and the references they list, now in those BVHs' leaves.
    pub hybrid_cells: u64,
    pub hybrid_refs: u64,
    /// The BVH (0 otherwise): the long opaque cones built in as two
    /// halves, each one primitive more (`bvh_pieces`).
    pub halved_cones: u64,
}

/// What the grid build cost (all zero but `duplicates` when the BVH is
/// in use).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GridInfo {
    pub cells: [u32; 3],
    /// Opaque primitives left out as exact copies of another.
    pub duplicates: usize,
    pub refs: usize,
    pub bytes: usize,
    pub seconds: f64,
}

/// What the light buffers cost (`--stats`); all zero without them.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LightBufInfo {
    /// Cells along a face's side (0: no light buffer).
    pub res: u32,
    pub cells: usize,
    pub refs: usize,
    pub bytes: usize,
    pub build_seconds: f64,
}

/// The packed scene: exactly the buffers the shader binds.
#[derive(Clone, Debug, Default)]
pub struct Packed {
    pub globals: Globals,
    /// Grid primitives first (`globals.counts.x` of them), then unbounded ones.
    pub prims: Pages<Prim>,
    pub extra: Pages<[f32; 4]>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    pub cell_start: Pages<u32>,
    pub refs: Pages<u32>,
    /// The BVH's 4-wide nodes (`BvhNode`); empty with the grid.
    pub bvh: Pages<BvhNode>,
    /// Light buffers (`lightbuf`): `cells + 1` offsets into `lb_refs` and
    /// each face's window, and the references as (primitive, depth) pairs;
    /// empty without them (`globals.flags.w` = 0).
    pub lb_start: Pages<u32>,
    pub lb_refs: Pages<u32>,
    /// The CPU grid walk's own arrays, derived from the above (not
    /// uploaded; empty but under the plain grid): `grid::Walk`.
    pub walk: grid::Walk,
    pub lightbuf: LightBufInfo,
    pub grid: GridInfo,
    pub accel: AccelInfo,
}

impl Packed {
    pub fn width(&self) -> u32 {
        self.globals.image[0]
    }
    pub fn height(&self) -> u32 {
        self.globals.image[1]
    }

    /// Counts rays `c`'s way from now on (both backends).
    pub fn set_counting(&mut self, c: Counting) {
        let f = &mut self.globals.flags[0];
        match c {
            Counting::Traced => *f &= !FLAG_SPD_COUNTING,
            Counting::Spd => *f |= FLAG_SPD_COUNTING,
        }
    }

    /// Whether feelers keep the shadow cache (both backends; on by
    /// default: `FLAG_NO_SHADOW_CACHE`). Off, every feeler walks the
    /// structure: the same image, more work.
    pub fn set_shadow_cache(&mut self, on: bool) {
        let f = &mut self.globals.flags[0];
        if on {
            *f &= !FLAG_NO_SHADOW_CACHE;
        } else {
            *f |= FLAG_NO_SHADOW_CACHE;
        }
    }

    /// The structure the tracers walk (`Grid` or `Bvh`).
    pub fn structure(&self) -> Accel {
        match self.globals.flags[1] {
            ACCEL_BVH => Accel::Bvh,
            ACCEL_OCTREE => Accel::Octree,
            ACCEL_HYBRID => Accel::Hybrid,
            _ => Accel::Grid,
        }
    }

    pub fn counting(&self) -> Counting {
        if self.globals.flags[0] & FLAG_SPD_COUNTING != 0 {
            Counting::Spd
        } else {
            Counting::Traced
        }
    }
}

fn v4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

/// Newell's normal of a polygon (unnormalized; robust for non-convex ones).
pub fn newell_normal(vs: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for i in 0..vs.len() {
        let a = vs[i];
        let b = vs[(i + 1) % vs.len()];
        n += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    n
}

fn drop_axis(n: DVec3) -> usize {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// True when every turn of the (planar) polygon goes the same way.
fn is_convex(vs: &[DVec3], n: DVec3) -> bool {
    let k = vs.len();
    let mut pos = false;
    let mut neg = false;
    for i in 0..k {
        let e0 = vs[(i + 1) % k] - vs[i];
        let e1 = vs[(i + 2) % k] - vs[(i + 1) % k];
        let s = e0.cross(e1).dot(n);
        pos |= s > 0.0;
        neg |= s < 0.0;
    }
    !(pos && neg)
}

struct Builder {
    origin: DVec3,
    bounded: Vec<(Prim, Bounds)>,
    unbounded: Vec<Prim>,
    extra: Vec<[f32; 4]>,
    features: u32,
}

impl Builder {
    fn rel(&self, p: DVec3) -> DVec3 {
        p - self.origin
    }

    fn push_bounded(
        &mut self,
        kind: u32,
        mat: u32,
        data: u32,
        [a, b, c]: [[f32; 4]; 3],
        bb: Bounds,
    ) {
        self.bounded.push((
            Prim {
                kind_mat: kind | (mat << 4),
                data,
                cell_lo: 0,
                cell_hi: 0,
                a,
                b,
                c,
            },
            bb,
        ));
    }

    fn push_unbounded(&mut self, kind: u32, mat: u32, data: u32, a: [f32; 4], b: [f32; 4]) {
        self.unbounded.push(Prim {
            kind_mat: kind | (mat << 4),
            data,
            cell_lo: 0,
            cell_hi: 0,
            a,
            b,
            c: [0.0; 4],
        });
    }

    fn points_bounds(pts: &[DVec3]) -> Bounds {
        let mut b = Bounds::EMPTY;
        for p in pts {
            b = b.union(&Bounds {
                lo: p.to_array(),
                hi: p.to_array(),
            });
        }
        b
    }

    fn triangle(&mut self, mat: u32, v: [DVec3; 3], n: Option<[DVec3; 3]>) {
        let v = v.map(|p| self.rel(p));
        if (v[1] - v[0]).cross(v[2] - v[0]).length_squared() == 0.0 {
            return; // cannot be hit; a mesh may carry such slivers
        }
        self.features |= FEAT_TRIANGLE;
        let data = match n {
            Some(n) => {
                self.features |= FEAT_SMOOTH;
                let i = self.extra.len() as u32;
                for k in n {
                    self.extra.push(v4(k.normalize_or_zero(), 0.0));
                }
                i
            }
            None => NO_NORMALS,
        };
        let bb = Self::points_bounds(&v);
        self.push_bounded(
            KIND_TRIANGLE,
            mat,
            data,
            [v4(v[0], 0.0), v4(v[1], 0.0), v4(v[2], 0.0)],
            bb,
        );
    }

    fn shape(&mut self, shape: &Shape, mat: u32) {
        match shape {
            Shape::Sphere { center, radius } => {
                self.features |= FEAT_SPHERE;
                let c = self.rel(*center);
                let r = *radius;
                let bb = Bounds {
                    lo: (c - r).to_array(),
                    hi: (c + r).to_array(),
                };
                self.push_bounded(
                    KIND_SPHERE,
                    mat,
                    0,
                    [v4(c, r * r), [r as f32, 0.0, 0.0, 0.0], [0.0; 4]],
                    bb,
                );
            }
            Shape::Plane { point, normal } => {
                self.features |= FEAT_PLANE;
                let n = normal.normalize();
                let d = n.dot(self.rel(*point));
                self.push_unbounded(KIND_PLANE, mat, 0, v4(n, d), [0.0; 4]);
            }
            Shape::Polygon { vertices } => {
                if vertices.len() == 3 {
                    self.triangle(mat, [vertices[0], vertices[1], vertices[2]], None);
                    return;
                }
                self.features |= FEAT_POLYGON;
                let vs: Vec<DVec3> = vertices.iter().map(|&p| self.rel(p)).collect();
                let n = newell_normal(&vs).normalize();
                let d = vs.iter().map(|p| n.dot(*p)).sum::<f64>() / vs.len() as f64;
                let drop = drop_axis(n);
                let convex = is_convex(&vs, n);
                let (i0, i1) = polygon::axes(drop);
                // The f32 the tracers read (docs/method.md, "Polygon").
                let q: Vec<[f32; 2]> = vs.iter().map(|p| [p[i0] as f32, p[i1] as f32]).collect();
                let packed = polygon::pack(&q, convex);
                let data = self.extra.len() as u32;
                self.extra.extend(packed.extra);
                let b = [
                    vs.len() as f32,
                    drop as f32,
                    convex as u32 as f32,
                    packed.longest as f32,
                ];
                let bb = Self::points_bounds(&vs);
                self.push_bounded(KIND_POLYGON, mat, data, [v4(n, d), b, packed.c], bb);
            }
            Shape::Triangle { vertices, normals } => {
                self.triangle(mat, *vertices, normals.as_deref().copied());
            }
            Shape::Mesh(m) => {
                for t in &m.triangles {
                    let v = t.map(|i| m.positions[i as usize]);
                    let n = m.normals.as_ref().map(|ns| t.map(|i| ns[i as usize]));
                    self.triangle(mat, v, n);
                }
            }
            Shape::Box { min, max } => {
                self.features |= FEAT_BOX;
                let (lo, hi) = (self.rel(*min), self.rel(*max));
                let bb = Bounds {
                    lo: lo.to_array(),
                    hi: hi.to_array(),
                };
                self.push_bounded(KIND_BOX, mat, 0, [v4(lo, 0.0), v4(hi, 0.0), [0.0; 4]], bb);
            }
            Shape::Quadric { coefficients, clip } => {
                self.features |= FEAT_QUADRIC;
                let k = relative_quadric(coefficients, self.origin);
                let data = self.extra.len() as u32;
                self.extra.push([k[0], k[1], k[2], k[3]].map(|x| x as f32));
                self.extra.push([k[4], k[5], k[6], k[7]].map(|x| x as f32));
                self.extra.push([k[8] as f32, k[9] as f32, 0.0, 0.0]);
                match clip {
                    Some((lo, hi)) => {
                        let (lo, hi) = (self.rel(*lo), self.rel(*hi));
                        let bb = Bounds {
                            lo: lo.to_array(),
                            hi: hi.to_array(),
                        };
                        self.push_bounded(
                            KIND_QUADRIC,
                            mat,
                            data,
                            [v4(lo, 1.0), v4(hi, 0.0), [0.0; 4]],
                            bb,
                        );
                    }
                    None => self.push_unbounded(KIND_QUADRIC, mat, data, [0.0; 4], [0.0; 4]),
                }
            }
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => {
                self.features |= FEAT_CONE;
                let (words, bb) =
                    cone_record(self.rel(*base), *base_radius, self.rel(*apex), *apex_radius);
                self.push_bounded(KIND_CONE, mat, 0, words, bb);
            }
        }
    }
}

/// A cone's record words (`layout::Prim`: base and r0, unit axis and r1,
/// length, side, tolerance, long) and bounds, from its end points (relative to
/// the camera) and radii (both negative: the normals point inwards).
pub(crate) fn cone_record(
    b: DVec3,
    base_radius: f64,
    a: DVec3,
    apex_radius: f64,
) -> ([[f32; 4]; 3], Bounds) {
    let len = (a - b).length();
    let axis = (a - b) / len;
    let side = if base_radius < 0.0 && apex_radius < 0.0 {
        -1.0
    } else {
        1.0
    };
    let (r0, r1) = (base_radius.abs(), apex_radius.abs());
    let bb = discs_bounds(axis, b, r0, a, r1);
    let tol = cone_tolerance(&bb);
    let long = (len >= CONE_LONG_RATIO * r0.min(r1)) as u32 as f32;
    (
        [
            v4(b, r0),
            v4(axis, r1),
            [len as f32, side as f32, tol, long],
        ],
        bb,
    )
}

/// How far off its side a cone's hit point may lie (`trace::intersect::
/// cone`, the record's `c.z`): `CONE_TOL_REL` of its box's diagonal plus
/// `CONE_TOL_ULPS` f32 steps of its largest coordinate. Half the padding
/// of the boxes the BVH builds around it and around each of its halves
/// (`bvh::PAD_REL`, `bvh::PAD_ULPS`) or less, so an accepted hit lies in
/// every box and cell that bounds the cone, whatever walk finds it; and
/// far above a true hit's f32 error off the side (a few steps of its
/// coordinates: a hit on a grazing ray errs along the side, not off it).
/// The `nff` fuzz target found a root made up by cancellation: a needle
/// 455 long with radii 0 and 0.056, whose test reported a hit 0.017 off
/// its axis (900 times its radius there), outside its boxes, found by
/// eye rays in packets and culled by the single ray's walk
/// (docs/reliability.md).
fn cone_tolerance(bb: &Bounds) -> f32 {
    let mag = bb.lo.iter().chain(&bb.hi).fold(0f64, |m, x| m.max(x.abs()));
    let d = bb.diagonal();
    let tol = CONE_TOL_REL * if d.is_finite() { d } else { 0.0 }
        + CONE_TOL_ULPS * f32::EPSILON as f64 * if mag.is_finite() { mag } else { 0.0 };
    tol as f32
}

/// A cone at least this many times as long as its smaller radius is
/// solved from the ray's point nearest its axis segment, a shorter one
/// from the ray's point nearest its middle (`trace::intersect::cone`;
/// the record's `c.w` says which): the nearest point costs a division
/// and a dozen operations more a test (SPD rings, 4 200 cylinders 15
/// radii long, rendered 15 % slower), and from the middle of a short
/// cone the roots keep their precision.
pub const CONE_LONG_RATIO: f64 = 32.0;

/// See `cone_tolerance`: a quarter of `bvh::PAD_REL`.
pub const CONE_TOL_REL: f64 = 0.25 * bvh::PAD_REL;
/// See `cone_tolerance`: half of `bvh::PAD_ULPS`.
pub const CONE_TOL_ULPS: f64 = 0.5 * bvh::PAD_ULPS;

/// An opaque cone at least this many times as long as its larger radius
/// goes into the BVH as two halves (`bvh_pieces`).
pub const CONE_SPLIT_RATIO: f64 = 4.0;

/// The cones `bvh_pieces` halves: opaque, and long for their radius.
/// (A length that rounded to 0 or overflowed in f32 stays whole.)
fn splits(p: &Prim, opaque: &[bool]) -> bool {
    let len = p.c[0];
    p.kind() == KIND_CONE
        && opaque.get(p.material() as usize) == Some(&true)
        && len > 0.0
        && len.is_finite()
        && len as f64 >= CONE_SPLIT_RATIO * p.a[3].max(p.b[3]) as f64
}

/// The BVH's build items where they are not the primitives one for one
/// (Ernst and Greiner's early split clipping, for cones alone). A long
/// thin cylinder lying across the axes (SPD rings' 4 200) has a box
/// mostly of empty space, which every ray passing near it enters and
/// which overlaps its neighbours': each opaque one of `CONE_SPLIT_RATIO`
/// or more goes into the build as its two halves, each bounded by the
/// box of its end discs (stretched by 10⁻³ of the length past the middle,
/// so that the halves overlap), and comes out as two copies of the same
/// primitive, one in each half's leaf. A ray crossing both halves' boxes
/// may test it twice; a copy's hit is the primitive's whole hit, found
/// wherever it lies, and ties go to the same rank (the copies share it),
/// so no answer changes. Only opaque ones: a transparent blocker met twice
/// would dim a feeler twice, an opaque one makes it zero either way.
/// More pieces than two lost on rings (three: +6 % render time, four: +4 %
/// against two, medians of 7; the copies' repeated tests). Replaces the
/// halved cones' entries in `bounds` by their first halves and appends
/// the second halves; returns, per entry, the index it stands for.
fn bvh_pieces(bounded: &[(Prim, Bounds)], opaque: &[bool], bounds: &mut Vec<Bounds>) -> Vec<u32> {
    let mut piece_of: Vec<u32> = (0..bounds.len() as u32).collect();
    for (i, (p, _)) in bounded.iter().enumerate() {
        if !splits(p, opaque) {
            continue;
        }
        let base = DVec3::new(p.a[0] as f64, p.a[1] as f64, p.a[2] as f64);
        let axis = DVec3::new(p.b[0] as f64, p.b[1] as f64, p.b[2] as f64);
        let (r0, r1, len) = (p.a[3] as f64, p.b[3] as f64, p.c[0] as f64);
        let half = |s0: f64, s1: f64| {
            let r = |s: f64| r0 + (r1 - r0) * s / len;
            discs_bounds(axis, base + axis * s0, r(s0), base + axis * s1, r(s1))
        };
        let overlap = 1e-3 * len;
        bounds[i] = half(0.0, 0.5 * len + overlap);
        bounds.push(half(0.5 * len - overlap, len));
        piece_of.push(i as u32);
    }
    piece_of
}

/// The box of a cone's stretch between its discs centred at `p` (radius
/// `rp`) and `q` (radius `rq`), whose normal is the unit vector `axis`:
/// the box of the two discs (each reaching r·√(1 − axis_i²) along axis i).
fn discs_bounds(axis: DVec3, p: DVec3, rp: f64, q: DVec3, rq: f64) -> Bounds {
    let reach = (DVec3::ONE - axis * axis).max(DVec3::ZERO);
    let ext = |r: f64| DVec3::new(r * reach.x.sqrt(), r * reach.y.sqrt(), r * reach.z.sqrt());
    let (ep, eq) = (ext(rp), ext(rq));
    Builder::points_bounds(&[p - ep, p + ep, q - eq, q + eq])
}

/// Most primitives kept out of the grid for being as large as the scene.
pub const GIANTS_MAX: usize = 8;

/// Giants are taken out only while they are at most one in this many of
/// the finite primitives (`take_out_giants`).
pub const GIANTS_SHARE_MAX: usize = 4;

/// A few primitives as large as the whole scene (a floor polygon under a
/// small object, a box round the room) would stretch the grid over empty
/// space and sit in most of its cells: the SPD's balls put 7 381 spheres
/// in a 74×74×4 grid because of a 24×24 floor. Up to `GIANTS_MAX` finite
/// primitives that span at least half the scene's extent on some axis are
/// instead tested against every ray, like planes; the grid then fits the
/// rest. Only while they are a few among many: where they would be more
/// than a quarter of the finite primitives (a handful of objects standing
/// on a floor plane, each as tall as the scene: scenes/quadric.toml had 4
/// of its 5 taken out) there is no crowd for the grid to fit, and every
/// ray would test most of the scene. Which list a primitive is in never
/// changes a hit. The giants
/// go to the end of `unbounded`; their bounds are returned, in that
/// order: a BVH takes them back into its tree (`pack`) when they are of
/// kinds the tree holds already, where a box test at a node turns most
/// rays away from them (the floor polygon under the SPD's gears:
/// feelers cast upwards never reach its leaf). A giant of another kind
/// stays out: the GPU's walks compile only the kinds their structure
/// holds, and a floor polygon among spheres would put the polygon's
/// test into every sphere test (docs/profiling.md, "Giants of the
/// tree's own kinds").
fn take_out_giants(
    all: &Bounds,
    bounded: &mut Vec<(Prim, Bounds)>,
    unbounded: &mut Vec<Prim>,
) -> Vec<Bounds> {
    let e = all.extent();
    let giant = |b: &Bounds| (0..3).any(|i| e[i] > 0.0 && b.hi[i] - b.lo[i] >= 0.5 * e[i]);
    let count = bounded.iter().filter(|(_, b)| giant(b)).count();
    if count == 0 || count > GIANTS_MAX || count * GIANTS_SHARE_MAX > bounded.len() {
        return Vec::new();
    }
    // In place, both sides in their order: a partition into two new
    // vectors copied every primitive (598 k spheres and one floor: 0.13 s).
    unbounded.reserve(count);
    let mut giants = Vec::with_capacity(count);
    bounded.retain(|(p, b)| {
        let g = giant(b);
        if g {
            unbounded.push(*p);
            giants.push(*b);
        }
        !g
    });
    giants
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread3(v: u32) -> u64 {
    let mut x = (v & 1023) as u64;
    x = (x | x << 16) & 0x0300_00FF;
    x = (x | x << 8) & 0x0300_F00F;
    x = (x | x << 4) & 0x030C_30C3;
    x = (x | x << 2) & 0x0924_9249;
    x
}

/// The Morton code of `b`'s centre in the box `all` (10 bits per axis).
fn morton_key(all: &Bounds, e: &[f64; 3], b: &Bounds) -> u64 {
    let q = [0, 1, 2].map(|i| {
        let c = (b.lo[i] + b.hi[i]) * 0.5;
        (((c - all.lo[i]) / e[i]) * 1023.0).clamp(0.0, 1023.0) as u32
    });
    spread3(q[0]) | spread3(q[1]) << 1 | spread3(q[2]) << 2
}

/// Puts primitives that are near in space near in memory (Morton order of
/// their bounds' centres): a ray's tests then touch few cache lines, which
/// is what keeps a million primitives from being memory-bound. Stable:
/// primitives with one code keep the scene's order. Returns each
/// primitive's code, in the new order.
///
/// The codes are sorted with the indices in their low 32 bits (a code has
/// 30), so every key is distinct and an unstable sort gives the stable
/// order; the primitives (112 bytes each) are then gathered once into a
/// new array, where sorting them in place by a cached key moved each one
/// by swaps along the permutation's cycles (BENCHMARKS.md, "Packing large
/// scenes").
fn morton_order(prims: &mut Vec<(Prim, Bounds)>) -> Vec<u64> {
    let all = prims.iter().fold(Bounds::EMPTY, |a, (_, b)| a.union(b));
    let e = all.extent().map(|x| x.max(f64::MIN_POSITIVE));
    // `census` keeps the count within u32.
    let key = |(i, (_, b)): (usize, &(Prim, Bounds))| morton_key(&all, &e, b) << 32 | i as u64;
    let index = |k: &u64| (k & 0xFFFF_FFFF) as usize;
    let mut keys: Vec<u64>;
    if prims.len() >= 1 << 16 {
        use rayon::prelude::*;
        keys = prims.par_iter().enumerate().map(key).collect();
        keys.par_sort_unstable();
        *prims = keys.par_iter().map(|k| prims[index(k)]).collect();
        keys.par_iter_mut().for_each(|k| *k >>= 32);
    } else {
        keys = prims.iter().enumerate().map(key).collect();
        keys.sort_unstable();
        *prims = keys.iter().map(|k| prims[index(k)]).collect();
        keys.iter_mut().for_each(|k| *k >>= 32);
    }
    keys
}

/// Drops every opaque primitive that is an exact copy of an earlier one
/// (the same packed bytes: kind, material and f32 geometry), after
/// `morton_order`, whose codes `keys` are; returns how many. The tracer
/// reads only those bytes, so a copy gives the same hit at the same
/// distance with the same shading, and a shadow feeler through an opaque
/// primitive is blocked whether it crosses one copy or many: the image and
/// the ray counts are unchanged.
/// Transparent copies stay (each multiplies a feeler's transmittance).
/// A pile of N identical spheres otherwise costs every ray N tests.
/// Copies have one Morton code, so only runs of equal codes are searched:
/// in ordinary scenes those are short and rare, and this costs one pass.
fn drop_opaque_copies(prims: &mut Vec<(Prim, Bounds)>, keys: &[u64], opaque: &[bool]) -> usize {
    let mut keep = vec![true; prims.len()];
    let mut dropped = 0;
    let mut i = 0;
    while i < prims.len() {
        let mut j = i + 1;
        while j < prims.len() && keys[j] == keys[i] {
            j += 1;
        }
        if j - i > 1 {
            // Copies of the run's first primitive need no hashing (a pile
            // of one sphere is one long run of them).
            let first = bytemuck::bytes_of(&prims[i].0);
            let mut seen = std::collections::HashSet::new();
            for k in i..j {
                let p = &prims[k].0;
                if !opaque.get(p.material() as usize).copied().unwrap_or(false) {
                    continue;
                }
                let bytes = bytemuck::bytes_of(p);
                let copy = if k > i && bytes == first {
                    true
                } else {
                    !seen.insert(bytes)
                };
                if copy {
                    keep[k] = false;
                    dropped += 1;
                }
            }
        }
        i = j;
    }
    if dropped > 0 {
        let mut k = 0;
        prims.retain(|_| {
            k += 1;
            keep[k - 1]
        });
    }
    dropped
}

/// Coefficients of the same quadric in coordinates relative to `o`
/// (x = x' + o), scaled so the largest is 1 (the surface is unchanged).
pub fn relative_quadric(k: &[f64; 10], o: DVec3) -> [f64; 10] {
    let [a, b, c, d, e, f, g, h, i, j] = *k;
    // Q(x) = xᵀMx + (G,H,I)·x + J, M symmetric with off-diagonals D/2, E/2, F/2.
    let g2 = 2.0 * a * o.x + d * o.y + e * o.z + g;
    let h2 = 2.0 * b * o.y + d * o.x + f * o.z + h;
    let i2 = 2.0 * c * o.z + e * o.x + f * o.y + i;
    let j2 = a * o.x * o.x
        + b * o.y * o.y
        + c * o.z * o.z
        + d * o.x * o.y
        + e * o.x * o.z
        + f * o.y * o.z
        + g * o.x
        + h * o.y
        + i * o.z
        + j;
    let r = [a, b, c, d, e, f, g2, h2, i2, j2];
    let m = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m > 0.0 {
        r.map(|x| x / m)
    } else {
        r
    }
}

/// What a scene will pack into, counted before anything is built:
/// primitives (an upper bound: degenerate triangles are dropped later),
/// `extra` entries, and the bytes the loaded scene holds.
pub fn census(scene: &Scene) -> (u64, u64, u64) {
    use std::mem::size_of;
    let mut prims = 0u64;
    let mut extra = 0u64;
    let mut bytes = (size_of::<Scene>()
        + scene.objects.capacity() * size_of::<crate::scene::Object>()
        + scene.lights.capacity() * size_of::<crate::scene::Light>()
        + scene.materials.capacity() * size_of::<crate::scene::Material>())
        as u64;
    for m in &scene.materials {
        bytes += m.name.capacity() as u64;
    }
    for o in &scene.objects {
        match &o.shape {
            Shape::Mesh(m) => {
                let t = m.triangles.len() as u64;
                prims += t;
                if m.normals.is_some() {
                    extra += 3 * t;
                }
                bytes += (size_of::<crate::scene::Mesh>()
                    + m.positions.capacity() * size_of::<DVec3>()
                    + m.normals.as_ref().map_or(0, |n| n.capacity()) * size_of::<DVec3>()
                    + m.triangles.capacity() * size_of::<[u32; 3]>())
                    as u64;
            }
            Shape::Polygon { vertices } => {
                prims += 1;
                if vertices.len() > 3 {
                    // Vertex pairs, edge bands and cells (pack::polygon):
                    // at most n/2 + 1 + (BANDS_MAX + 1 + 8n + 3 + 32n)/4
                    // vec4s (K ≤ n/2 bands of M ≤ 64 cells).
                    let n = vertices.len() as u64;
                    extra += n / 2 + 1 + (polygon::BANDS_MAX as u64 + 1) / 4 + 2 + 10 * n;
                }
                bytes += (vertices.capacity() * size_of::<DVec3>()) as u64;
            }
            Shape::Triangle { normals, .. } => {
                prims += 1;
                if normals.is_some() {
                    extra += 3;
                    bytes += size_of::<[DVec3; 3]>() as u64;
                }
            }
            Shape::Quadric { .. } => {
                prims += 1;
                extra += 3;
            }
            _ => prims += 1,
        }
    }
    (prims, extra, bytes)
}

/// The structure to build for `settings` over the finite primitives'
/// `bounds`, and whether `Accel::Auto` chose it. An explicit `--grid`
/// under `Auto` means the grid.
/// `samples`: the eye rays the render traces (lattice points × samples
/// per point), which the BVH's longer build is spread over.
pub fn choose_structure(settings: &Settings, bounds: &[Bounds], samples: u64) -> (Accel, bool) {
    match settings.accel {
        Accel::Auto if settings.grid.is_some() => (Accel::Grid, false),
        Accel::Auto => (auto_structure(bounds, samples), true),
        a => (a, false),
    }
}

/// `Accel::Auto` may take the BVH up to this many finite primitives
/// whatever the image; beyond it only while the render it speeds up is
/// long enough to pay for its build (`AUTO_BVH_PRIMS_PER_RAY`).
pub const AUTO_BVH_MAX_PRIMS: usize = 1 << 16;

/// Beyond `AUTO_BVH_MAX_PRIMS`, `Accel::Auto` takes the BVH while its N
/// finite primitives are at most this many per eye ray: its build costs
/// about 0.2 µs (spheres) to 0.5 µs (triangles) a primitive more than the
/// grid's, and on a clustered scene its render saves about 0.75 µs
/// (sphereflake) to 1.3 µs (teapot) an eye ray, so the two meet at 3-8
/// primitives an eye ray. Measured on sphereflakes of 66 k and 598 k
/// spheres and teapots of 104 k and 233 k triangles from 128×96 to
/// 1024×768 (docs/method.md, "Choosing the structure"). An evenly filled
/// scene takes the grid whatever its size (`AUTO_GRID_FILL`).
pub const AUTO_BVH_PRIMS_PER_RAY: f64 = 5.0;

/// `Accel::Auto` takes the grid when the primitives' boxes fill at least
/// this share of their union's box (`fill_ratio`): an evenly filled scene,
/// which the grid's uniform cells suit (docs/method.md).
pub const AUTO_GRID_FILL: f64 = 0.5;

/// The sum of the primitives' box volumes over their union's box volume
/// (overlaps counted each time). Each extent, of the union and of every
/// box, is taken as at least 1/1000 of the union's largest, as the grid's
/// heuristic does, so flat scenes and flat primitives still compare.
pub fn fill_ratio(bounds: &[Bounds]) -> f64 {
    let all = bounds.iter().fold(Bounds::EMPTY, |a, b| a.union(b));
    let ext = |b: &Bounds| [0, 1, 2].map(|i| (b.hi[i] - b.lo[i]).max(0.0));
    let e = ext(&all);
    let floor = e.iter().cloned().fold(0.0, f64::max) / 1000.0;
    if !floor.is_finite() || floor <= 0.0 {
        return 1.0; // every primitive at one point: nothing to separate
    }
    let vol = |e: [f64; 3]| e.iter().map(|x| x.max(floor) / floor).product::<f64>();
    let whole = vol(e);
    bounds.iter().map(|b| vol(ext(b))).sum::<f64>() / whole
}

/// `Accel::Auto`'s rule (docs/method.md, "Choosing the structure"): the
/// BVH, except for large scenes and evenly filled ones, where the grid
/// was measured faster.
pub fn auto_structure(bounds: &[Bounds], samples: u64) -> Accel {
    let fill = fill_ratio(bounds);
    log::debug!(
        "auto structure: {} finite primitives, fill ratio {fill:.3}, {samples} eye rays",
        bounds.len()
    );
    if bounds.len() > AUTO_BVH_MAX_PRIMS
        && bounds.len() as f64 > AUTO_BVH_PRIMS_PER_RAY * samples as f64
    {
        return Accel::Grid;
    }
    if fill >= AUTO_GRID_FILL {
        Accel::Grid
    } else {
        Accel::Bvh
    }
}

/// Packs a scene for rendering with `settings`, or refuses it by estimate
/// (before allocating) when it does not fit `settings.budget`.
pub fn pack(scene: &Scene, settings: &Settings) -> Result<Packed, PackError> {
    pack_with_progress(scene, settings, &|_, _, _| {})
}

/// `pack`, reporting the grid build's passes: `progress(stage, done,
/// total)` (`Stage`). The CLI shows a bar when they take long.
pub fn pack_with_progress(
    scene: &Scene,
    settings: &Settings,
    progress: Progress,
) -> Result<Packed, PackError> {
    let cam = &scene.camera;
    let origin = cam.from;
    let width = settings.width.unwrap_or(cam.width).max(1);
    let height = settings.height.unwrap_or(cam.height).max(1);
    for (what, value) in [("width", width), ("height", height)] {
        if value > MAX_IMAGE_SIZE {
            return Err(PackError::ImageSize { what, value });
        }
    }
    let (n_prims, n_extra, scene_bytes) = census(scene);
    for (what, count) in [("primitives", n_prims), ("extra data entries", n_extra)] {
        if count > u32::MAX as u64 {
            return Err(PackError::TooMany {
                what,
                count,
                max: u32::MAX as u64,
            });
        }
    }
    let mut need = Need {
        width,
        height,
        corners: settings.sampling == Sampling::Corners,
        scene_objects: scene.objects.len() as u64,
        scene_bytes,
        prims: n_prims,
        bounded: n_prims,
        extra: n_extra,
        cells: 1,
        refs: 0,
        explicit_grid: settings.grid.is_some(),
        bvh: false,
        octree: false,
    };
    if settings.grid.is_some() {
        match settings.accel {
            Accel::Bvh => return Err(PackError::GridWith("bvh")),
            Accel::Octree => return Err(PackError::GridWith("octree")),
            _ => {}
        }
    }
    // The image and the primitives, before any of them is allocated.
    settings.budget.check(&need)?;

    let mut b = Builder {
        origin,
        // The census counts them (at most), so the array never regrows.
        bounded: Vec::with_capacity(n_prims as usize),
        unbounded: Vec::new(),
        extra: Vec::new(),
        features: 0,
    };
    for o in &scene.objects {
        b.shape(&o.shape, o.material);
    }

    let materials: Vec<Material> = scene
        .materials
        .iter()
        .map(|m| Material {
            ka: v4(m.ka, 0.0),
            kd: v4(m.kd, 0.0),
            ks: [m.ksr as f32, m.nr as f32, m.kst as f32, m.nt as f32],
            kr: v4(m.kr, m.ior),
            kt: v4(m.kt, 0.0),
            absorb: v4(m.absorption, 0.0),
        })
        .collect();
    let used = |f: &dyn Fn(&crate::scene::Material) -> bool| scene.materials.iter().any(f);
    if used(&|m| m.kr.max_element() > 0.0) {
        b.features |= FEAT_REFLECT;
    }
    if used(&|m| m.kt.max_element() > 0.0) {
        b.features |= FEAT_REFRACT | FEAT_REFLECT;
    }
    if used(&|m| m.kt.max_element() > 0.0 && m.absorption.max_element() > 0.0) {
        b.features |= FEAT_ABSORB;
    }
    if used(&|m| m.kst > 0.0) {
        b.features |= FEAT_TRANSMIT_HIGHLIGHT;
    }
    let lights: Vec<Light> = scene
        .lights
        .iter()
        .map(|l| {
            let f = l.falloff;
            if f != [1.0, 0.0, 0.0] {
                b.features |= FEAT_FALLOFF;
            }
            Light {
                pos: v4(l.position - origin, 0.0),
                color: v4(l.color, 0.0),
                falloff: [f[0] as f32, f[1] as f32, f[2] as f32, 0.0],
            }
        })
        .collect();

    // The scene's size (for the surface offset) counts every finite
    // primitive, the ones kept out of the grid too.
    let finite = b
        .bounded
        .iter()
        .fold(Bounds::EMPTY, |a, (_, bb)| a.union(bb));
    let t0 = Instant::now();
    let giants = take_out_giants(&finite, &mut b.bounded, &mut b.unbounded);
    // Where the giants start in `unbounded` (after the planes and
    // unclipped quadrics).
    let giants_at = b.unbounded.len() - giants.len();
    let n = b.bounded.len() as u64;
    progress(Stage::Sort, 0, n);
    let keys = morton_order(&mut b.bounded);
    let opaque: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| m.kt.max_element() <= 0.0)
        .collect();
    let duplicates = drop_opaque_copies(&mut b.bounded, &keys, &opaque);
    drop(keys);
    let n = b.bounded.len() as u64;
    progress(Stage::Sort, n, n);
    let bounds: Vec<Bounds> = b.bounded.iter().map(|(_, bb)| *bb).collect();
    need.prims = (b.bounded.len() + b.unbounded.len()) as u64;
    need.bounded = n;
    need.extra = b.extra.len() as u64;
    let budget = &settings.budget;
    let eye_rays = need.lattice()
        * if need.corners {
            1
        } else {
            settings.spp.max(1) as u64
        };
    let (mut structure, auto) = choose_structure(settings, &bounds, eye_rays);
    // `auto` does not choose a BVH the memory budget refuses (its build
    // needs more per primitive than the grid's): the grid, checked as
    // it is built, may fit.
    if auto && structure == Accel::Bvh && budget.check(&Need { bvh: true, ..need }).is_err() {
        log::debug!("auto structure: the BVH's build would exceed the memory budget; the grid");
        structure = Accel::Grid;
    }
    need.bvh = structure == Accel::Bvh;
    need.octree = structure == Accel::Octree;
    // Under the BVH each long opaque cone is two primitives (`bvh_pieces`).
    let halves = if need.bvh {
        b.bounded.iter().filter(|(p, _)| splits(p, &opaque)).count()
    } else {
        0
    };
    need.prims += halves as u64;
    need.bounded += halves as u64;
    let mut n_bounded = b.bounded.len() as u32;
    // The unbounded primitives' ranks start here (`rank`).
    let n_ranked = b.bounded.len();
    let mut prims: Vec<Prim> = Vec::with_capacity(b.bounded.len() + halves + b.unbounded.len());
    // The octree's shape (leaves, depth, most in a leaf), when built.
    let mut octree_shape = None;
    // The hybrid's nested cells and their references, when built.
    let mut nested_counts = (0, 0);
    let mut walk = grid::Walk::default();
    let max_refs = |cells: u64| need.max_refs(budget, cells);
    // The primitives the structure holds, by their index in the tree's
    // order: the bounded ones, then (under the BVH) the giants.
    let mut bounds = bounds;
    // Under the BVH the giants go back into the tree when it holds their
    // kinds already (`take_out_giants`), keeping their rank among the
    // unbounded primitives.
    let take_back = need.bvh
        && !giants.is_empty()
        && Prim::kind_bits(&b.unbounded[giants_at..])
            & !Prim::kind_bits(b.bounded.iter().map(|(p, _)| p))
            == 0;
    let taken = if take_back { giants.len() } else { 0 };
    let (g, tree) = if need.bvh {
        budget.check(&need)?;
        bounds.extend_from_slice(&giants[..taken]);
        let piece_of = bvh_pieces(&b.bounded, &opaque, &mut bounds);
        debug_assert_eq!(piece_of.len(), b.bounded.len() + taken + halves);
        if halves > 0 {
            log::debug!("BVH: {halves} long opaque cones built in as two halves each");
        }
        n_bounded = bounds.len() as u32;
        let tree = bvh::build(&bounds, progress);
        // Leaf order: each leaf a contiguous run of primitives, each
        // keeping its rank (its index in the grid's order: the bounded
        // primitives, then the unbounded ones, giants last) in `cell_lo`
        // for ties (`trace::query::rank`); a halved cone's two copies
        // share theirs.
        let n = n_ranked;
        for &e in &tree.order {
            let i = piece_of[e as usize] as usize;
            let (mut p, rank) = if i < n {
                (b.bounded[i].0, i)
            } else {
                (b.unbounded[giants_at + i - n], n + giants_at + i - n)
            };
            p.cell_lo = rank as u32;
            prims.push(p);
        }
        b.unbounded.truncate(b.unbounded.len() - taken);
        let empty = grid::Grid {
            dims: [1, 1, 1],
            cell_start: vec![0, 0],
            ..grid::Grid::default()
        };
        (empty, tree)
    } else if structure == Accel::Octree {
        // The grid's order (the rank is the index); the nodes and lists
        // take the grid's buffers (`pack::octree`).
        let oct = match octree::build(&bounds, settings.octree, &max_refs) {
            Ok(o) => o,
            Err(r) => {
                let over = Need {
                    cells: r.words,
                    refs: r.refs,
                    ..need
                };
                budget.check(&over)?;
                return Err(PackError::TooMany {
                    what: "octree references",
                    count: r.refs,
                    max: u32::MAX as u64,
                });
            }
        };
        prims.extend(b.bounded.iter().map(|(p, _)| *p));
        octree_shape = Some((oct.leaves, oct.depth, oct.max_leaf));
        let side = 1u32 << oct.levels;
        let g = grid::Grid {
            lo: oct.lo,
            hi: oct.hi,
            dims: [side; 3],
            cell: oct.cell,
            ranges: Vec::new(),
            cell_start: oct.nodes,
            refs: oct.refs,
            bits: Vec::new(),
        };
        (g, bvh::Bvh::default())
    } else {
        // The hybrid's top grid is coarser than the plain grid's: its
        // cells are meant to crowd (about hybrid::PRIMS_PER_CELL
        // primitives each, where the grid aims at GRID_DENSITY), their
        // BVHs sorting them out.
        let dims = match (structure, settings.grid) {
            (Accel::Hybrid, None) => {
                let all = bounds.iter().fold(Bounds::EMPTY, |a, b| a.union(b));
                Some(grid::resolution(
                    &all,
                    bounds.len() / hybrid::PRIMS_PER_CELL,
                ))
            }
            (_, dims) => dims,
        };
        let mut g = match grid::build(&bounds, dims, &max_refs, progress) {
            Ok(g) => g,
            Err(r) => {
                let over = Need {
                    cells: r.cells,
                    refs: r.refs,
                    ..need
                };
                return Err(match budget.check(&over) {
                    Err(e) => e.into(),
                    Ok(()) => PackError::GridRefs {
                        dims: r.dims,
                        refs: r.refs,
                        explicit: settings.grid.is_some(),
                    },
                });
            }
        };
        for (i, (mut p, _)) in b.bounded.iter().copied().enumerate() {
            (p.cell_lo, p.cell_hi) = g.ranges[i];
            prims.push(p);
        }
        let bits = std::mem::take(&mut g.bits);
        if structure == Accel::Grid {
            walk = grid::Walk {
                bits: bits.into(),
                spheres: grid::sphere_records(&prims).into(),
            };
        }
        let mut tree = bvh::Bvh::default();
        if structure == Accel::Hybrid {
            // The crowded cells' BVHs, refused by their largest size
            // before they are built (counted as references: 4 bytes each).
            let (cells, refs) = hybrid::crowded(&g, settings.hybrid_cell);
            let with = Need {
                cells: grid::cells_of(g.dims),
                refs: g.refs.len() as u64 + hybrid::bytes_at_most(cells, refs).div_ceil(4),
                ..need
            };
            budget.check(&with)?;
            tree = match hybrid::nest(&mut g, &bounds, settings.hybrid_cell) {
                Ok(nested) => {
                    nested_counts = (nested.cells, nested.refs);
                    nested.tree
                }
                Err(nodes) => {
                    return Err(PackError::TooMany {
                        what: "hybrid BVH nodes",
                        count: nodes,
                        max: HYBRID_NODE as u64,
                    })
                }
            };
        }
        (g, tree)
    };
    drop(b.bounded);
    let build_seconds = t0.elapsed().as_secs_f64();
    prims.extend(b.unbounded);
    if need.bvh {
        // The planes and unbounded quadrics: their rank is their index
        // after the bounded primitives (giants, ranked after them, are
        // in the tree).
        let n = n_ranked;
        for (j, p) in prims.iter_mut().skip(n_bounded as usize).enumerate() {
            p.cell_lo = (n + j) as u32;
        }
    }

    let forward = (cam.at - cam.from).normalize();
    let right = forward.cross(cam.up).normalize();
    let up = right.cross(forward);
    let half_h = (cam.fov.to_radians() * 0.5).tan();
    let half_w = half_h * width as f64 / height as f64;
    // The surface offset's scale: the scene's size, or how far from the
    // camera (the origin of the packed coordinates) its farthest point
    // lies, whichever is larger, since f32 hit points are as precise as
    // their distance from the origin allows. Not where the camera looks:
    // a far `at` behind a small scene would push every secondary ray off
    // its surface.
    let scale = if finite.lo[0] > finite.hi[0] {
        (cam.at - cam.from).length()
    } else {
        let far = (0..8)
            .map(|c| {
                let pick = |i: usize| {
                    if c >> i & 1 == 0 {
                        finite.lo[i]
                    } else {
                        finite.hi[i]
                    }
                };
                DVec3::new(pick(0), pick(1), pick(2)).length()
            })
            .fold(0.0f64, f64::max);
        finite.diagonal().max(far)
    };
    let eps = (scale * settings.offset.unwrap_or(EPS_OFFSET_REL) as f64) as f32;
    // The grid's cells, or the octree's node words (two per node).
    let cells_kept = if structure == Accel::Octree {
        g.cell_start.len() as u64
    } else {
        grid::cells_of(g.dims)
    };
    // Light buffers over the finite primitives in `prims` order.
    let mut lb = lightbuf::LightBuf::default();
    let mut lb_seconds = 0.0;
    if settings.shadows == Shadows::LightBuffer && n_bounded > 0 && !lights.is_empty() {
        let t = Instant::now();
        let ordered: Vec<Bounds> = if need.bvh {
            tree.order.iter().map(|&i| bounds[i as usize]).collect()
        } else {
            bounds.clone()
        };
        let now = Need {
            cells: cells_kept,
            refs: g.refs.len() as u64,
            ..need
        };
        let free = budget.limit().saturating_sub(now.peak());
        // Words: the offsets, each light's six windows of four, and two a
        // reference.
        let room = free / 4;
        let res = lightbuf::resolution(ordered.len());
        let cells = lightbuf::cells(lights.len(), res);
        let max_refs = room.saturating_sub(cells + 1 + 24 * lights.len() as u64) / 2;
        let at: Vec<[f64; 3]> = scene
            .lights
            .iter()
            .map(|l| (l.position - origin).to_array())
            .collect();
        match lightbuf::build(&at, &ordered, eps as f64, scale, max_refs, free) {
            Some(built) => lb = built,
            None => log::info!(
                "the light buffers do not fit the memory budget (or 32-bit offsets); \
                 shadow feelers use the acceleration structure"
            ),
        }
        lb_seconds = t.elapsed().as_secs_f64();
    }
    drop(bounds);
    let (nx, ny) = crate::trace::sample::strata(settings.spp);
    let sampling = match settings.sampling {
        Sampling::Corners => SAMPLING_CORNERS,
        Sampling::Centers if settings.spp > 1 => SAMPLING_JITTER,
        Sampling::Centers => SAMPLING_CENTERS,
    };
    // The grid's cells, at most 1023³ < 2³² (GRID_MAX_DIM), or the
    // octree's nodes (its build keeps their words within 32 bits).
    let ncells = if structure == Accel::Octree {
        cells_kept / 2
    } else {
        cells_kept
    } as u32;
    let globals = Globals {
        cam_right: v4(right * half_w, 0.0),
        cam_up: v4(up * half_h, 0.0),
        cam_forward: v4(forward, 0.0),
        background: v4(scene.background, 0.0),
        ambient: v4(scene.ambient, 0.0),
        grid_min: [
            g.lo[0],
            g.lo[1],
            g.lo[2],
            if n_bounded > 0 && matches!(structure, Accel::Grid | Accel::Octree | Accel::Hybrid) {
                1.0
            } else {
                0.0
            },
        ],
        grid_max: [g.hi[0], g.hi[1], g.hi[2], 0.0],
        grid_cell: [g.cell[0], g.cell[1], g.cell[2], 0.0],
        grid_dims: [g.dims[0], g.dims[1], g.dims[2], ncells],
        counts: [
            n_bounded,
            prims.len() as u32,
            lights.len() as u32,
            materials.len() as u32,
        ],
        image: [width, height, settings.spp.max(1), sampling],
        trace: [settings.max_depth.min(MAX_DEPTH_LIMIT), b.features, nx, ny],
        params: [settings.min_weight, eps, 0.0, 0.0],
        flags: [
            0,
            match structure {
                Accel::Bvh => ACCEL_BVH,
                Accel::Octree => ACCEL_OCTREE,
                Accel::Hybrid => ACCEL_HYBRID,
                _ => ACCEL_GRID,
            },
            match (structure, settings.octree.walk) {
                (Accel::Octree, octree::Walk::Stack) => OCTREE_WALK_STACK,
                (Accel::Octree, octree::Walk::Neighbour) => OCTREE_WALK_NEIGHBOUR,
                _ => tree.node_count() as u32,
            },
            lb.res,
        ],
    };
    // With the CPU walk's own arrays (`grid::Walk`).
    let grid_bytes = (g.cell_start.len() + g.refs.len()) * 4
        + std::mem::size_of_val(&walk.bits[..])
        + std::mem::size_of_val(&walk.spheres[..]);
    let grid_info = if !matches!(structure, Accel::Grid | Accel::Hybrid) {
        GridInfo {
            duplicates,
            ..GridInfo::default()
        }
    } else {
        GridInfo {
            cells: g.dims,
            duplicates,
            refs: g.refs.len(),
            bytes: grid_bytes,
            seconds: build_seconds,
        }
    };
    let (leaves, depth, max_leaf) =
        octree_shape.unwrap_or((tree.leaves, tree.depth, tree.max_leaf));
    let accel = AccelInfo {
        structure,
        auto,
        build_seconds,
        bytes: if need.bvh {
            tree.bytes()
        } else {
            grid_bytes + tree.bytes()
        },
        nodes: if octree_shape.is_some() {
            ncells as usize
        } else {
            tree.node_count()
        },
        leaves: leaves as usize,
        depth,
        max_leaf,
        hybrid_cells: nested_counts.0,
        hybrid_refs: nested_counts.1,
        halved_cones: halves as u64,
    };
    let lightbuf = LightBufInfo {
        res: lb.res,
        cells: lightbuf::cells(lights.len(), lb.res) as usize,
        refs: lb.refs.len() / 2,
        bytes: (lb.start.len() + lb.refs.len()) * 4,
        build_seconds: lb_seconds,
    };
    Ok(Packed {
        globals,
        prims: prims.into(),
        extra: b.extra.into(),
        materials,
        lights,
        cell_start: g.cell_start.into(),
        refs: g.refs.into(),
        bvh: tree.nodes.into(),
        lb_start: lb.start.into(),
        lb_refs: lb.refs.into(),
        walk,
        lightbuf,
        grid: grid_info,
        accel,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_quadric_is_the_same_surface() {
        // Sphere of radius 2 around (1, 2, 3): x² + y² + z² − 2x − 4y − 6z + 10 = 0.
        let k = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, -2.0, -4.0, -6.0, 10.0];
        let o = DVec3::new(5.0, -1.0, 0.5);
        let r = relative_quadric(&k, o);
        let q = |k: &[f64; 10], p: DVec3| {
            k[0] * p.x * p.x
                + k[1] * p.y * p.y
                + k[2] * p.z * p.z
                + k[3] * p.x * p.y
                + k[4] * p.x * p.z
                + k[5] * p.y * p.z
                + k[6] * p.x
                + k[7] * p.y
                + k[8] * p.z
                + k[9]
        };
        for p in [
            DVec3::new(3.0, 2.0, 3.0),
            DVec3::new(1.0, 2.0, 1.0),
            DVec3::new(1.0, 4.0, 3.0),
        ] {
            assert!(q(&k, p).abs() < 1e-12);
            assert!(q(&r, p - o).abs() < 1e-12, "{}", q(&r, p - o));
        }
        assert!(q(&r, DVec3::new(1.0, 2.0, 3.0) - o) < 0.0);
    }

    #[test]
    fn morton_codes_interleave() {
        assert_eq!(spread3(0b11), 0b1001);
        assert_eq!(spread3(1023).count_ones(), 10);
        let code = |x: u32, y: u32, z: u32| spread3(x) | spread3(y) << 1 | spread3(z) << 2;
        assert_eq!(code(1, 1, 1), 7);
        assert!(code(1, 0, 0) < code(0, 1, 0) && code(0, 1, 0) < code(0, 0, 1));
    }

    #[test]
    fn a_floor_under_a_small_object_stays_out_of_the_grid() {
        use crate::scene::{Camera, Light, Object, Scene};
        let mut objects = vec![Object {
            shape: Shape::Polygon {
                vertices: vec![
                    DVec3::new(-12.0, -12.0, 0.0),
                    DVec3::new(12.0, -12.0, 0.0),
                    DVec3::new(12.0, 12.0, 0.0),
                    DVec3::new(-12.0, 12.0, 0.0),
                ],
            },
            material: 0,
        }];
        for i in 0..100 {
            objects.push(Object {
                shape: Shape::Sphere {
                    center: DVec3::new((i % 10) as f64 * 0.1, (i / 10) as f64 * 0.1, 0.5),
                    radius: 0.04,
                },
                material: 0,
            });
        }
        let s = Scene {
            camera: Camera {
                from: DVec3::new(0.0, -5.0, 1.0),
                at: DVec3::ZERO,
                up: DVec3::Z,
                fov: 40.0,
                width: 8,
                height: 8,
            },
            background: DVec3::ZERO,
            ambient: DVec3::ZERO,
            lights: vec![Light {
                position: DVec3::new(0.0, 0.0, 9.0),
                color: DVec3::ONE,
                falloff: [1.0, 0.0, 0.0],
            }],
            materials: vec![crate::scene::Material::default()],
            objects,
            source: "t".into(),
        };
        let p = pack(&s, &Settings::default()).unwrap();
        assert_eq!(p.globals.counts[0], 100, "the spheres are in the grid");
        assert_eq!(
            p.globals.counts[1], 101,
            "the floor is tested against every ray"
        );
        assert_eq!(p.prims[100].kind(), KIND_POLYGON);
        // the grid fits the spheres, not the floor
        assert!(p.globals.grid_max[0] - p.globals.grid_min[0] < 1.2);
    }

    /// A handful of objects as tall as the scene (scenes/quadric.toml's
    /// shape): each spans the whole height, so each is a giant by extent,
    /// but four of five are no crowd to fit a grid to. They stay in the
    /// structure, where a ray tests only those whose cells (or boxes) it
    /// meets; one such among four small ones still goes out.
    #[test]
    fn giants_go_out_only_as_a_few_among_many() {
        use crate::scene::Object;
        let sphere = |x: f64, radius: f64| Object {
            shape: Shape::Sphere {
                center: DVec3::new(x, 0.0, 0.0),
                radius,
            },
            material: 0,
        };
        let tall = (0..4).map(|i| sphere(3.0 * i as f64, 1.0));
        let handful = scene_of(tall.chain([sphere(1.5, 0.2)]).collect(), false);
        let p = pack(&handful, &small()).unwrap();
        assert_eq!(p.globals.counts[0], 5, "every object is in the grid");
        assert_eq!(p.globals.counts[1], 5);
        let small_ones = (0..4).map(|i| sphere(0.5 * i as f64, 0.1));
        let few = scene_of(
            [sphere(0.0, 1.0)].into_iter().chain(small_ones).collect(),
            false,
        );
        let p = pack(&few, &small()).unwrap();
        assert_eq!(
            (p.globals.counts[0], p.globals.counts[1]),
            (4, 5),
            "one giant among five is tested against every ray"
        );
    }

    fn scene_of(objects: Vec<crate::scene::Object>, glass: bool) -> Scene {
        use crate::scene::{Camera, Light, Material};
        let m = if glass {
            Material {
                kt: DVec3::splat(0.8),
                ior: 1.5,
                ..Material::default()
            }
        } else {
            Material::default()
        };
        Scene {
            camera: Camera {
                from: DVec3::new(0.0, -6.0, 2.0),
                at: DVec3::ZERO,
                up: DVec3::Z,
                fov: 40.0,
                width: 24,
                height: 16,
            },
            background: DVec3::new(0.1, 0.1, 0.2),
            ambient: DVec3::splat(0.1),
            lights: vec![Light {
                position: DVec3::new(4.0, -3.0, 5.0),
                color: DVec3::ONE,
                falloff: [1.0, 0.0, 0.0],
            }],
            materials: vec![m],
            objects,
            source: "t".into(),
        }
    }

    fn spheres(n: usize, center: DVec3, radius: f64) -> Vec<crate::scene::Object> {
        vec![
            crate::scene::Object {
                shape: Shape::Sphere { center, radius },
                material: 0,
            };
            n
        ]
    }

    /// The grid (these tests are about it) under a 1 GiB budget.
    fn small() -> Settings {
        Settings {
            budget: Budget::bytes(1 << 30),
            accel: Accel::Grid,
            ..Settings::default()
        }
    }

    /// The 100 k copies of one sphere: one primitive, one cell,
    /// and the image and ray counts of the single sphere.
    #[test]
    fn opaque_copies_pack_and_render_as_one() {
        let one = pack(&scene_of(spheres(1, DVec3::ZERO, 1.0), false), &small()).unwrap();
        let many = pack(
            &scene_of(spheres(100_000, DVec3::ZERO, 1.0), false),
            &small(),
        )
        .unwrap();
        assert_eq!(many.globals.counts[0], 1);
        assert_eq!(many.grid.duplicates, 99_999);
        assert_eq!(many.grid.refs, 1);
        let (a, b) = (
            crate::cpu::render(&one, &|_, _| {}),
            crate::cpu::render(&many, &|_, _| {}),
        );
        assert!(a.stats.eye_hit > 0);
        assert_eq!(a.pixels, b.pixels);
        assert_eq!(a.stats, b.stats);
    }

    /// Transparent copies stay (each dims a shadow), yet the grid is one
    /// cell with one reference each, not N × 3N.
    #[test]
    fn transparent_copies_stay_in_one_cell() {
        let p = pack(
            &scene_of(spheres(100_000, DVec3::ZERO, 1.0), true),
            &small(),
        )
        .unwrap();
        assert_eq!(p.globals.counts[0], 100_000);
        assert_eq!(p.grid.duplicates, 0);
        assert_eq!(p.grid.cells, [1, 1, 1]);
        assert_eq!(p.grid.refs, 100_000);
    }

    /// Copies only of the same primitive: spheres one f32 step apart, or
    /// in another material, all stay.
    #[test]
    fn near_copies_stay() {
        let mut objects = spheres(3, DVec3::ZERO, 1.0);
        objects[1].shape = Shape::Sphere {
            center: DVec3::ZERO,
            radius: 1.0 + f32::EPSILON as f64,
        };
        objects[2].material = 1;
        let mut s = scene_of(objects, false);
        s.materials.push(crate::scene::Material::default());
        let p = pack(&s, &small()).unwrap();
        assert_eq!((p.globals.counts[0], p.grid.duplicates), (3, 0));
    }

    /// Radii of 1e-120 and 5e-324 (scene volume underflows), and 1000
    /// tiny spheres at one point: a small grid, and a render.
    #[test]
    fn tiny_radii_get_a_small_grid() {
        for (n, r) in [(1, 1e-120), (1, 5e-324), (1000, 1e-120)] {
            let mut objects = spheres(n, DVec3::ZERO, r);
            for (i, o) in objects.iter_mut().enumerate() {
                o.shape = Shape::Sphere {
                    center: DVec3::new(i as f64 * 1e-300, 0.0, 0.0),
                    radius: r,
                };
            }
            let p = pack(&scene_of(objects, false), &small()).unwrap();
            let cells: u64 = p.grid.cells.iter().map(|&c| c as u64).product();
            assert!(cells <= 3000 * n as u64, "{n} × {r}: {:?}", p.grid.cells);
            assert!(p.grid.refs <= 8 * n, "{n} × {r}: {}", p.grid.refs);
            let f = crate::cpu::render(&p, &|_, _| {});
            assert_eq!(f.pixels.len(), 24 * 16);
        }
    }

    /// The image at every option's limit: refused by estimate (never
    /// allocated, never wrapped), the count exact in 64 bits.
    #[test]
    fn the_largest_images_are_refused_by_estimate() {
        let s = scene_of(spheres(1, DVec3::ZERO, 1.0), false);
        for sampling in [Sampling::Centers, Sampling::Corners] {
            let settings = Settings {
                width: Some(MAX_IMAGE_SIZE),
                height: Some(MAX_IMAGE_SIZE),
                spp: 4096,
                max_depth: MAX_DEPTH_LIMIT,
                sampling,
                ..small()
            };
            let Err(PackError::Budget(e)) = pack(&s, &settings) else {
                panic!("65536² was not refused");
            };
            let side = MAX_IMAGE_SIZE as u64 + (sampling == Sampling::Corners) as u64;
            assert_eq!(e.item.what, crate::budget::What::Image);
            assert_eq!(e.item.count, side * side);
            assert!(e.item.bytes >= side * side * crate::budget::SAMPLE_BYTES);
            assert_eq!(e.limit, 1 << 30);
            let msg = e.to_string();
            assert!(msg.contains("render a smaller image"), "{msg}");
        }
        for (w, h) in [(MAX_IMAGE_SIZE + 1, 1), (1, u32::MAX)] {
            let settings = Settings {
                width: Some(w),
                height: Some(h),
                ..small()
            };
            assert!(matches!(
                pack(&s, &settings),
                Err(PackError::ImageSize { .. })
            ));
        }
        // a 65536 × 1 strip fits and packs
        let strip = Settings {
            width: Some(MAX_IMAGE_SIZE),
            height: Some(1),
            spp: 4096,
            ..small()
        };
        assert_eq!(pack(&s, &strip).unwrap().width(), MAX_IMAGE_SIZE);
    }

    /// `--grid 1023x1023x1023`: refused by estimate, naming the cells,
    /// the limit and both ways out.
    #[test]
    fn an_explicit_grid_over_budget_is_refused() {
        let s = scene_of(spheres(1, DVec3::ZERO, 1.0), false);
        let settings = Settings {
            grid: Some([GRID_MAX_DIM; 3]),
            ..small()
        };
        let Err(PackError::Budget(e)) = pack(&s, &settings) else {
            panic!("not refused");
        };
        assert_eq!(e.item.what, crate::budget::What::Grid);
        assert_eq!(e.need.cells, 1023 * 1023 * 1023);
        let msg = e.to_string();
        assert!(
            msg.starts_with("the grid needs 25 GiB for 1.1 G cells and 1.1 G references"),
            "{msg}"
        );
        assert!(
            msg.contains("--memory-limit") && msg.contains("coarser --grid"),
            "{msg}"
        );
        // within the offsets and the budget, an explicit grid is built as asked
        let settings = Settings {
            grid: Some([64, 1, 1]),
            ..small()
        };
        assert_eq!(pack(&s, &settings).unwrap().grid.cells, [64, 1, 1]);
    }

    /// Under a small budget the heuristic picks a coarser grid, and the
    /// image is the same as with the full one.
    #[test]
    fn a_small_budget_coarsens_the_grid_not_the_image() {
        let s = crate::gen::random_spheres(20_000, 1);
        let settings = |budget| Settings {
            width: Some(48),
            height: Some(32),
            budget,
            accel: Accel::Grid,
            ..Settings::default()
        };
        let full = pack(&s, &settings(Budget::unlimited())).unwrap();
        let need = |p: &Packed| {
            let (prims, extra, scene_bytes) = census(&s);
            Need {
                width: 48,
                height: 32,
                scene_objects: s.objects.len() as u64,
                scene_bytes,
                prims,
                bounded: prims,
                extra,
                cells: p.grid.cells.iter().map(|&c| c as u64).product(),
                refs: p.grid.refs as u64,
                ..Need::default()
            }
        };
        let limit = need(&full).peak() - full.grid.refs as u64 * 4;
        let tight = pack(&s, &settings(Budget::bytes(limit))).unwrap();
        assert!(tight.grid.refs < full.grid.refs);
        assert!(Budget::bytes(limit).fits(&need(&tight)));
        let (a, b) = (
            crate::cpu::render(&full, &|_, _| {}),
            crate::cpu::render(&tight, &|_, _| {}),
        );
        assert_eq!(a.pixels, b.pixels);
        assert_eq!(a.stats, b.stats);
        // a budget below the primitives themselves: refused, naming them
        let Err(PackError::Budget(e)) = pack(&s, &settings(Budget::bytes(1 << 20))) else {
            panic!("not refused");
        };
        assert_eq!(e.item.what, crate::budget::What::Primitives);
    }

    #[test]
    fn the_spd_preset_and_its_counting() {
        let s = Preset::Spd.settings();
        assert_eq!((s.width, s.height), (Some(512), Some(512)));
        assert_eq!((s.max_depth, s.min_weight), (4, 0.0));
        assert_eq!(s.sampling, Sampling::Corners);
        let scene = crate::gen::random_spheres(10, 1);
        let mut p = pack(&scene, &s).unwrap();
        assert_eq!(p.counting(), Counting::Traced);
        assert_eq!(p.globals.image, [512, 512, 1, SAMPLING_CORNERS]);
        p.set_counting(Preset::Spd.counting());
        assert_eq!(p.counting(), Counting::Spd);
        assert_eq!(p.globals.flags[0], FLAG_SPD_COUNTING);
        p.set_counting(Counting::Traced);
        assert_eq!(p.globals.flags[0], 0);
    }

    /// `auto` takes the BVH for clustered scenes (the SPD's, a
    /// sphereflake), the grid for an evenly filled field of spheres and
    /// above `AUTO_BVH_MAX_PRIMS` primitives, unless there are eye rays
    /// enough for the BVH's build to pay (`AUTO_BVH_PRIMS_PER_RAY`).
    #[test]
    fn auto_picks_by_fill_and_size() {
        let auto = |s: &Scene| pack(s, &Settings::default()).unwrap().structure();
        assert_eq!(auto(&crate::gen::random_spheres(2000, 3)), Accel::Grid);
        assert_eq!(auto(&crate::gen::sphereflake(2)), Accel::Bvh);
        for spd in [
            crate::gen::spd::SpdScene::Teapot,
            crate::gen::spd::SpdScene::Tree,
        ] {
            let s = crate::gen::spd::generate(spd, None).unwrap();
            assert_eq!(auto(&s), Accel::Bvh, "{spd:?}");
        }
        // Sparse (fill far below AUTO_GRID_FILL) but too many.
        // Tiny boxes on a lattice of spacing 10.
        let tiny = |i: usize| {
            let p = [i % 64, (i / 64) % 64, i / 4096].map(|k| 10.0 * k as f64);
            Bounds {
                lo: p,
                hi: p.map(|x| x + 1e-3),
            }
        };
        let few: Vec<Bounds> = (0..1000).map(tiny).collect();
        assert!(fill_ratio(&few) < AUTO_GRID_FILL);
        assert_eq!(auto_structure(&few, 1), Accel::Bvh);
        let many: Vec<Bounds> = (0..AUTO_BVH_MAX_PRIMS + 1).map(tiny).collect();
        assert!(fill_ratio(&many) < AUTO_GRID_FILL);
        let rays = (many.len() as f64 / AUTO_BVH_PRIMS_PER_RAY) as u64;
        assert_eq!(auto_structure(&many, rays / 2), Accel::Grid);
        // ... unless the render has enough eye rays to pay for the build.
        assert_eq!(auto_structure(&many, rays * 2), Accel::Bvh);
        // Every primitive at one point: nothing for either to separate.
        let pile = vec![
            Bounds {
                lo: [1.0; 3],
                hi: [1.0; 3]
            };
            10
        ];
        assert_eq!(fill_ratio(&pile), 1.0);
    }

    /// Under a memory limit that the BVH's build exceeds and the grid's
    /// does not, `auto` takes the grid (and says it is its choice) where
    /// `--accel bvh` is refused.
    #[test]
    fn auto_takes_the_grid_where_the_bvh_would_exceed_the_budget() {
        let scene = crate::gen::sphereflake(3);
        let with = |accel, limit| {
            pack(
                &scene,
                &Settings {
                    accel,
                    budget: Budget::bytes(limit),
                    ..Settings::default()
                },
            )
        };
        assert_eq!(with(Accel::Auto, u64::MAX).unwrap().structure(), Accel::Bvh);
        // The least limit each structure packs under (monotone in it).
        let least = |accel| {
            let (mut lo, mut hi) = (0u64, 1u64 << 40);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if with(accel, mid).is_ok() {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            lo
        };
        let (grid, bvh) = (least(Accel::Grid), least(Accel::Bvh));
        assert!(grid < bvh, "grid {grid} bytes, BVH {bvh}");
        assert!(with(Accel::Bvh, bvh - 1).is_err());
        let p = with(Accel::Auto, bvh - 1).expect("auto falls back to the grid");
        assert_eq!(p.structure(), Accel::Grid);
        assert!(p.accel.auto);
    }

    /// `--accel` picks the structure the tracers walk; `--grid` under
    /// `auto` means the grid, beside `--accel bvh` it is refused.
    #[test]
    fn the_structure_is_the_one_asked_for() {
        let s = crate::gen::random_spheres(500, 2);
        for (accel, grid, want) in [
            (Accel::Grid, None, Accel::Grid),
            (Accel::Bvh, None, Accel::Bvh),
            (Accel::Auto, Some([4, 4, 4]), Accel::Grid),
            (Accel::Grid, Some([4, 4, 4]), Accel::Grid),
        ] {
            let p = pack(
                &s,
                &Settings {
                    accel,
                    grid,
                    ..Settings::default()
                },
            )
            .unwrap();
            assert_eq!((p.structure(), p.accel.structure), (want, want));
            assert!(!p.accel.auto);
            let bvh = want == Accel::Bvh;
            assert_eq!(p.bvh.is_empty(), !bvh);
            assert_eq!(p.globals.flags[2] as usize, p.bvh.len());
            assert_eq!(
                p.globals.grid_min[3] == 1.0,
                !bvh,
                "the DDA runs only on the grid"
            );
            assert_eq!(p.grid.refs > 0, !bvh);
            assert!(p.accel.bytes > 0 && p.accel.build_seconds >= 0.0);
            if bvh {
                assert!(p.accel.nodes > 0 && p.accel.leaves > p.accel.nodes);
                assert_eq!(p.accel.bytes, p.bvh.len() * 128);
            }
        }
        let p = pack(&s, &Settings::default()).unwrap();
        assert!(p.accel.auto);
        let e = pack(
            &s,
            &Settings {
                accel: Accel::Bvh,
                grid: Some([4, 4, 4]),
                ..Settings::default()
            },
        )
        .unwrap_err();
        assert_eq!(e, PackError::GridWith("bvh"));
        assert!(e.to_string().contains("--accel bvh"), "{e}");
    }

    /// A budget the grid fits but the BVH's build does not: refused by
    /// estimate, the BVH counted.
    #[test]
    fn the_bvh_is_budgeted() {
        let s = crate::gen::random_spheres(20_000, 1);
        let settings = |accel, budget| Settings {
            width: Some(16),
            height: Some(16),
            accel,
            budget,
            ..Settings::default()
        };
        let (prims, extra, scene_bytes) = census(&s);
        let base = Need {
            width: 16,
            height: 16,
            scene_objects: s.objects.len() as u64,
            scene_bytes,
            prims,
            bounded: prims,
            extra,
            cells: 1,
            ..Need::default()
        };
        let with_bvh = Need { bvh: true, ..base };
        // Between what the packing needs without the BVH and with it.
        let limit = (base.peak() + with_bvh.peak()) / 2;
        let Err(PackError::Budget(e)) = pack(&s, &settings(Accel::Bvh, Budget::bytes(limit)))
        else {
            panic!("not refused");
        };
        assert!(e.need.bvh);
        assert!(e.total > limit && e.total <= with_bvh.peak());
        assert!(pack(&s, &settings(Accel::Grid, Budget::bytes(limit))).is_ok());
        assert!(pack(&s, &settings(Accel::Bvh, Budget::bytes(with_bvh.peak()))).is_ok());
    }

    #[test]
    fn convexity() {
        let sq = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert!(is_convex(&sq, DVec3::Z));
        let l = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        assert!(!is_convex(&l, DVec3::Z));
    }
}
