// The constants shared by the CPU tracer and the shader. This file is the
// only place they are written: build.rs `include!`s it and emits them as
// `#define`s into the generated `constants.glsl`. Keep it free of `use` and
// of anything but plain `pub const` items of type u32 or f32.

/// Most generations of reflection/refraction `--max-depth` may ask for.
pub const MAX_DEPTH_LIMIT: u32 = 16;
/// Entries of the explicit ray-tree stack: a depth-first walk of a binary
/// tree of depth D never holds more than D + 2 pending rays.
pub const STACK_SIZE: u32 = MAX_DEPTH_LIMIT + 2;
/// Secondary-ray origins are moved off the surface along the geometric
/// normal by this fraction of the scene's size (never by a multiple of |p|).
pub const EPS_OFFSET_REL: f32 = 2.0e-5;
/// Lights whose last opaque shadow blocker is remembered (the shadow
/// cache); lights past this many are traced without it.
pub const SHADOW_CACHE_LIGHTS: u32 = 8;
/// Levels of the ray tree with a shadow cache of their own (eye hits,
/// first bounce, second, the rest together): a feeler from a reflection's
/// hit no longer evicts the blocker the next eye hit's feeler would have
/// met. SPD gears: 8 % fewer intersection tests and 6 % fewer node visits
/// per ray than one cache for every level, 4 % less render time.
pub const SHADOW_CACHE_LEVELS: u32 = 4;
/// Most cells on one grid axis (cell ranges pack 10 bits per axis).
pub const GRID_MAX_DIM: u32 = 1023;
/// Cap of the per-cell empty-space distance (cells); an empty cell whose
/// nearest listed cell is k cells away (chessboard metric) lets a ray jump
/// over the k − 1 cells around it.
pub const SKIP_MAX: u32 = 15;
/// A cone's test takes the ray as parallel to its axis when 1 − (d·a)²
/// is at most this (`trace::intersect::cone`): it then solves from the
/// ray's point nearest the cone's middle.
pub const CONE_PARALLEL: f32 = 1e-6;
/// Target cells per finite primitive for the grid heuristic.
pub const GRID_DENSITY: f32 = 3.0;
/// Entries of the BVH traversal stack. The binary build keeps every
/// interior node at depth < BVH_STACK_SIZE (the root at depth 0), and the
/// collapse to 4-wide nodes keeps, on every path, the children a traversal
/// may push within it (`pack::bvh::collapse`).
pub const BVH_STACK_SIZE: u32 = 64;
/// Children per BVH node (`pack::layout::BvhNode`).
pub const BVH_WIDTH: u32 = 4;
/// On the GPU a BVH child's link and count share one word: the link in
/// the low `BVH_COUNT_SHIFT` bits, the count (at most `pack::bvh::MAX_LEAF`)
/// above (`gpu::bvh_for_gpu`; docs/profiling.md, "One word per child").
pub const BVH_COUNT_SHIFT: u32 = 28;
/// A BVH box's exit distance is widened by this factor (≥ 1 + 2γ₃, γ₃ =
/// 3u/(1 − 3u), u = 2⁻²⁴: Ize, "Robust BVH Ray Traversal", 2013), so that
/// the rounding of (plane − origin)·(1/d) never makes a ray that crosses a
/// box miss it, even from an origin so far away that the subtraction
/// rounds the box's size off (a feeler from a giant sphere 7·10¹⁰ away
/// crossing a 10-unit polygon missed it before; docs/method.md).
pub const BVH_EXIT_WIDEN: f32 = 1.000_000_5;
/// The shadow cache answers for a grid's or a hybrid's blocker only when
/// the cached test's hit lies inside the cells that list it by this
/// share of a cell on every axis (`trace::accel::cache_hit_listed`), so
/// that the walk, whose f32 steps err by far less, would have tested it
/// there too.
pub const CACHE_HIT_MARGIN: f32 = 0.015_625;
/// Acceleration structures (`Globals::flags.y`): which one the tracers walk.
pub const ACCEL_GRID: u32 = 0;
pub const ACCEL_BVH: u32 = 1;
pub const ACCEL_OCTREE: u32 = 2;
/// The grid whose crowded cells hold a small BVH each (`pack::hybrid`).
pub const ACCEL_HYBRID: u32 = 3;
/// Under the hybrid, a grid cell's list entry with this bit set is the
/// root node (the low bits) of the cell's own BVH, not a primitive.
pub const HYBRID_NODE: u32 = 0x8000_0000;
/// Second word of an interior octree node (`pack::octree`); a leaf's
/// second word is its primitive count, always less.
pub const OCTREE_INTERIOR: u32 = 0xFFFF_FFFF;
/// Deepest level an octree may reach (the root at 0): its lattice has
/// 2^OCTREE_MAX_LEVELS cells on each axis.
pub const OCTREE_MAX_LEVELS: u32 = 16;
/// Entries of the octree's stack walk (`--octree-walk stack`): an
/// interior node pushes at most three children, one node per level.
pub const OCTREE_STACK_SIZE: u32 = 3 * OCTREE_MAX_LEVELS + 1;
/// `Globals::flags.z` under the octree: which walk (`--octree-walk`).
pub const OCTREE_WALK_NEIGHBOUR: u32 = 0;
pub const OCTREE_WALK_STACK: u32 = 1;
/// Codes of a banded polygon's cells (`pack::polygon::cells`): every
/// point outside, every point inside, or near an edge (test the edges).
pub const CELL_OUT: u32 = 0;
pub const CELL_IN: u32 = 1;
pub const CELL_EDGE: u32 = 2;
/// Primitive kinds (low 4 bits of `Prim::kind_mat`).
pub const KIND_SPHERE: u32 = 0;
pub const KIND_PLANE: u32 = 1;
pub const KIND_TRIANGLE: u32 = 2;
pub const KIND_POLYGON: u32 = 3;
pub const KIND_BOX: u32 = 4;
pub const KIND_QUADRIC: u32 = 5;
pub const KIND_CONE: u32 = 6;
/// `Prim::data` of a triangle without vertex normals.
pub const NO_NORMALS: u32 = 0xFFFF_FFFF;
/// Feature bits (`Globals::trace.y`): what the scene uses. The shader is
/// specialized on them so unused paths compile out.
pub const FEAT_SPHERE: u32 = 1;
pub const FEAT_PLANE: u32 = 2;
pub const FEAT_TRIANGLE: u32 = 4;
pub const FEAT_POLYGON: u32 = 8;
pub const FEAT_BOX: u32 = 16;
pub const FEAT_QUADRIC: u32 = 32;
pub const FEAT_CONE: u32 = 64;
pub const FEAT_REFLECT: u32 = 128;
pub const FEAT_REFRACT: u32 = 256;
pub const FEAT_ABSORB: u32 = 512;
pub const FEAT_TRANSMIT_HIGHLIGHT: u32 = 1024;
pub const FEAT_FALLOFF: u32 = 2048;
pub const FEAT_SMOOTH: u32 = 4096;
/// Counting flags (`Globals::flags.x`). SPD_COUNTING: count rays as the
/// SPD does (docs/spd.md): a surface with k_t > 0 also spawns a
/// reflection ray where k_r = 0 (of weight 0, traced for the counts
/// only), and a shadow feeler counts only towards a light the surface
/// faces.
pub const FLAG_SPD_COUNTING: u32 = 1;
/// NO_SHADOW_CACHE: neither backend keeps the shadow cache (every feeler
/// walks the structure); for checking that the cache changes no pixel,
/// and for comparing the two backends' work counters exactly.
pub const FLAG_NO_SHADOW_CACHE: u32 = 2;
/// Sampling modes (`Globals::image.w`).
pub const SAMPLING_CENTERS: u32 = 0;
pub const SAMPLING_JITTER: u32 = 1;
pub const SAMPLING_CORNERS: u32 = 2;
