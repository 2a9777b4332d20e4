//! The tracer, generic over its float type. Each file is the twin of a
//! shader file (see ARCHITECTURE.md): same names, same order of arithmetic.

pub mod accel;
pub mod bvh;
pub mod grid;
pub mod intersect;
pub mod lightbuf;
pub mod math;
pub mod octree;
pub mod packet;
pub mod query;
pub mod sample;
pub mod shade;
pub mod tree;

use crate::pack::layout::{BvhNode, Globals, Light, Material, Prim};
use crate::pack::Packed;

/// Borrowed view of the packed arrays: what the shader's buffers hold.
#[derive(Clone, Copy)]
pub struct SceneView<'a> {
    pub globals: &'a Globals,
    pub prims: &'a [Prim],
    pub extra: &'a [[f32; 4]],
    pub materials: &'a [Material],
    pub lights: &'a [Light],
    pub cell_start: &'a [u32],
    pub refs: &'a [u32],
    pub bvh: &'a [BvhNode],
    pub lb_start: &'a [u32],
    pub lb_refs: &'a [u32],
    /// The CPU grid walk's test-once bits and sphere records
    /// (`pack::grid::Walk`): empty unless the structure is the plain grid
    /// and they match the arrays above, when the walk reads the
    /// primitives' records instead.
    pub walk_bits: &'a [u8],
    pub spheres: &'a [[f32; 4]],
}

impl<'a> SceneView<'a> {
    pub fn new(p: &'a Packed) -> Self {
        let g = &p.globals;
        let walk = g.flags[1] == crate::constants::ACCEL_GRID
            && !p.walk.bits.is_empty()
            && p.walk.bits.len() == p.refs.len()
            && (p.walk.spheres.is_empty() || p.walk.spheres.len() == g.counts[0] as usize)
            && g.counts[0] as usize <= p.prims.len();
        SceneView {
            globals: &p.globals,
            prims: &p.prims,
            extra: &p.extra,
            materials: &p.materials,
            lights: &p.lights,
            cell_start: &p.cell_start,
            refs: &p.refs,
            bvh: &p.bvh,
            lb_start: &p.lb_start,
            lb_refs: &p.lb_refs,
            walk_bits: if walk { &p.walk.bits } else { &[] },
            spheres: if walk { &p.walk.spheres } else { &[] },
        }
    }

    /// The same view without the grid walk's own arrays: the walk reads
    /// the primitives' records (tests compare the two).
    pub fn without_walk_arrays(self) -> Self {
        SceneView {
            walk_bits: &[],
            spheres: &[],
            ..self
        }
    }

    #[inline(always)]
    pub fn has(&self, feature: u32) -> bool {
        self.globals.trace[1] & feature != 0
    }

    /// Rays are counted as the SPD counts them (`FLAG_SPD_COUNTING`).
    #[inline(always)]
    pub fn spd_counting(&self) -> bool {
        self.globals.flags[0] & crate::constants::FLAG_SPD_COUNTING != 0
    }

    /// Feelers use the shadow cache (not `FLAG_NO_SHADOW_CACHE`).
    #[inline(always)]
    pub fn shadow_cache(&self) -> bool {
        self.globals.flags[0] & crate::constants::FLAG_NO_SHADOW_CACHE == 0
    }
}

/// Ray counts as the SPD defines them (to the letter under
/// `pack::Counting::Spd`: docs/spd.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayStats {
    pub eye: u64,
    pub eye_hit: u64,
    pub reflect: u64,
    pub refract: u64,
    pub shadow: u64,
}

impl RayStats {
    pub fn add(&mut self, o: &RayStats) {
        self.eye += o.eye;
        self.eye_hit += o.eye_hit;
        self.reflect += o.reflect;
        self.refract += o.refract;
        self.shadow += o.shadow;
    }
    pub fn total(&self) -> u64 {
        self.eye + self.reflect + self.refract + self.shadow
    }
    /// The rays of each kind `Work::by_kind` splits the work by: eye,
    /// secondary (reflected and refracted), shadow.
    pub fn by_kind(&self) -> [u64; 3] {
        [self.eye, self.reflect + self.refract, self.shadow]
    }
}
