//! The packed scene: `#[repr(C)]` std430 structs, the only definition of the
//! data both tracers read. Twin of `shaders/layout.glsl`; every member is a
//! `vec4`/`uvec4` or a `uint` quadruple so std430 adds no padding, and the
//! layout test checks sizes and offsets against the shader's.
//!
//! Coordinates are f32 relative to the camera position (the camera sits at
//! the origin), so precision does not depend on where the scene is.

use bytemuck::{Pod, Zeroable};

/// Scene-wide values: camera, grid, counts, render settings.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Globals {
    /// xyz: right × half-width of the image plane at distance 1.
    pub cam_right: [f32; 4],
    /// xyz: up × half-height of the image plane at distance 1.
    pub cam_up: [f32; 4],
    /// xyz: unit viewing direction.
    pub cam_forward: [f32; 4],
    /// rgb background (rays that hit nothing).
    pub background: [f32; 4],
    /// rgb I_a.
    pub ambient: [f32; 4],
    /// xyz: grid's lower corner; w: 1 when the grid holds any primitive.
    pub grid_min: [f32; 4],
    /// xyz: grid's upper corner.
    pub grid_max: [f32; 4],
    /// xyz: cell size.
    pub grid_cell: [f32; 4],
    /// x, y, z: cells per axis; w: total cells.
    pub grid_dims: [u32; 4],
    /// x: primitives in the grid (they come first in `prims`), y: all
    /// primitives (the rest are unbounded: planes, unclipped quadrics),
    /// z: lights, w: materials.
    pub counts: [u32; 4],
    /// x: width, y: height, z: samples per pixel, w: sampling mode.
    pub image: [u32; 4],
    /// x: max depth, y: feature bits, z: strata in x, w: strata in y.
    pub trace: [u32; 4],
    /// x: min weight, y: surface offset (scene units), z, w: unused.
    pub params: [f32; 4],
    /// x: counting flags (`FLAG_*`), y: the acceleration structure the
    /// tracers walk (`ACCEL_GRID`, `ACCEL_BVH`, `ACCEL_OCTREE`), z: the
    /// BVH's nodes (0: none), or under the octree its walk
    /// (`OCTREE_WALK_*`), w: the light buffers' resolution (0: none).
    pub flags: [u32; 4],
}

/// One primitive, 64 bytes. `kind_mat` = kind (low 4 bits) | material << 4.
/// `cell_lo`/`cell_hi` are the grid cell range of its bounds, 10 bits per
/// axis (x | y << 10 | z << 20); a ray skips a primitive it already tested
/// in the previous cell by checking that cell against this range. Under
/// the BVH, which packs primitives in leaf order, `cell_lo` is instead the
/// primitive's rank, its index under the grid's order, which settles ties
/// (`trace::query::rank`).
///
/// | kind     | a                  | b                       | c                   | data            |
/// |----------|--------------------|-------------------------|---------------------|-----------------|
/// | sphere   | centre, r²         | radius, 0, 0, 0         |                     |                 |
/// | plane    | unit normal, d     |                         |                     |                 |
/// | triangle | v0                 | v1                      | v2                  | normals in extra or NO_NORMALS |
/// | polygon  | unit normal, d     | count, drop axis, convex, 0 |                 | vertices in extra |
/// | box      | min                | max                     |                     |                 |
/// | quadric  | clip min, clipped  | clip max                |                     | 3 vec4 coefficients in extra |
/// | cone     | base, base radius  | unit axis, apex radius  | length, side (±1), tolerance, long (0/1) |  |
///
/// Aligned to 64 bytes (its size, so the std430 layout is unchanged): a
/// large malloc'd array starts 16 bytes into a page, which made every
/// primitive straddle two cache lines.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Prim {
    pub kind_mat: u32,
    pub data: u32,
    pub cell_lo: u32,
    pub cell_hi: u32,
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

impl Prim {
    pub fn kind(&self) -> u32 {
        self.kind_mat & 15
    }
    pub fn material(&self) -> u32 {
        self.kind_mat >> 4
    }

    /// The kinds among `prims`, bit k for `KIND` k (the `FEAT_*` bit of
    /// each kind): what a structure holding them must be able to test.
    pub fn kind_bits<'a>(prims: impl IntoIterator<Item = &'a Prim>) -> u32 {
        prims.into_iter().fold(0, |k, p| k | 1 << p.kind())
    }
}

/// Material, all colours premultiplied: ka = k_a·colour, kd = k_d·colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Material {
    pub ka: [f32; 4],
    pub kd: [f32; 4],
    /// x: k_sr, y: n_r, z: k_st, w: n_t.
    pub ks: [f32; 4],
    /// rgb: k_r; w: index of refraction.
    pub kr: [f32; 4],
    /// rgb: k_t.
    pub kt: [f32; 4],
    /// rgb: absorption per unit length inside the medium.
    pub absorb: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Light {
    /// xyz: position (camera-relative).
    pub pos: [f32; 4],
    /// rgb: I_i.
    pub color: [f32; 4],
    /// c1, c2, c3 of f(d) = min(1, 1/(c1 + c2 d + c3 d²)).
    pub falloff: [f32; 4],
}

/// One node of the 4-wide BVH, 128 bytes: up to `BVH_WIDTH` children,
/// lane k of each field describing child k (nodes in depth-first order,
/// node 0 the root). `bounds[0][axis]`/`bounds[1][axis]` (`lo`, `hi`):
/// the children's boxes on that axis (f32, rounded outwards from the
/// primitives' padded bounds), low planes then high ones, so that a walk
/// picks a slab's near plane by indexing with the sign of the ray's
/// direction (`RayPre::near`) instead of a select per axis; laid
/// out lane by lane so that one node's four box tests are four-wide
/// arithmetic on both backends. `count[k]` > 0: a leaf of `count[k]`
/// primitives from `prims[link[k]]` on; `count[k]` = 0 and `link[k]` > 0:
/// the node `link[k]`; both 0: no child (an empty box, lo = +∞, hi = −∞;
/// the root is never a child).
///
/// In std430 a `vec4[3]` has a 16-byte stride: no padding; aligned to 64
/// bytes so that a node spans two whole cache lines.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub bounds: [[[f32; 4]; 3]; 2],
    pub link: [u32; 4],
    pub count: [u32; 4],
}

impl BvhNode {
    /// The children's low planes, `lo[axis][lane]`.
    #[inline(always)]
    pub fn lo(&self) -> &[[f32; 4]; 3] {
        &self.bounds[0]
    }

    /// The children's high planes, `hi[axis][lane]`.
    #[inline(always)]
    pub fn hi(&self) -> &[[f32; 4]; 3] {
        &self.bounds[1]
    }

    /// A node with no children.
    pub const EMPTY: BvhNode = BvhNode {
        bounds: [[[f32::INFINITY; 4]; 3], [[f32::NEG_INFINITY; 4]; 3]],
        link: [0; 4],
        count: [0; 4],
    };
}

impl Default for BvhNode {
    fn default() -> Self {
        BvhNode::EMPTY
    }
}

pub fn cell_pack(x: u32, y: u32, z: u32) -> u32 {
    x | (y << 10) | (z << 20)
}

pub fn cell_unpack(c: u32) -> [u32; 3] {
    [c & 1023, (c >> 10) & 1023, (c >> 20) & 1023]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    // The std430 layout of shaders/layout.glsl, written out: any padding slip
    // or reordering on either side fails here (and in the GPU layout probe).
    #[test]
    fn sizes_and_offsets_match_std430() {
        assert_eq!(size_of::<Globals>(), 14 * 16);
        assert_eq!(offset_of!(Globals, grid_dims), 8 * 16);
        assert_eq!(offset_of!(Globals, params), 12 * 16);
        assert_eq!(offset_of!(Globals, flags), 13 * 16);
        assert_eq!(size_of::<Prim>(), 64);
        // One cache line each (see Prim).
        assert_eq!(std::mem::align_of::<Prim>(), 64);
        assert_eq!(offset_of!(Prim, a), 16);
        assert_eq!(offset_of!(Prim, c), 48);
        assert_eq!(size_of::<Material>(), 96);
        assert_eq!(offset_of!(Material, absorb), 80);
        assert_eq!(size_of::<Light>(), 48);
        assert_eq!(size_of::<BvhNode>(), 128);
        assert_eq!(std::mem::align_of::<BvhNode>(), 64);
        // The shader's `hi` (bounds[1]) at byte 48.
        let mut n = BvhNode::EMPTY;
        n.bounds[1][0][0] = 7.0;
        assert_eq!(bytemuck::bytes_of(&n)[48..52], 7.0f32.to_ne_bytes());
        assert_eq!(offset_of!(BvhNode, link), 96);
        assert_eq!(offset_of!(BvhNode, count), 112);
    }

    #[test]
    fn cell_packing_round_trips() {
        for &(x, y, z) in &[(0, 0, 0), (1023, 0, 5), (17, 1023, 1023), (512, 3, 999)] {
            assert_eq!(cell_unpack(cell_pack(x, y, z)), [x, y, z]);
        }
    }
}
