//! Scene → Packed: camera-relative f32 std430 arrays and the voxel grid.
//! Both tracers read only what this produces.

pub mod grid;
pub mod layout;
pub mod pages;

use crate::constants::*;
use crate::scene::{Scene, Shape};
use glam::DVec3;
use grid::Bounds;
use layout::{Globals, Light, Material, Prim};
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

/// The render settings that shape the packed data.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub max_depth: u32,
    pub min_weight: f32,
    pub spp: u32,
    pub sampling: Sampling,
    pub grid: Option<[u32; 3]>,
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
        }
    }
}

/// How rays are counted (`RayStats`), set on the packed scene with
/// `Packed::set_counting`. Both ways give the same image, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
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

/// What the grid build cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GridInfo {
    pub cells: [u32; 3],
    pub refs: usize,
    pub bytes: usize,
    pub seconds: f64,
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
    pub grid: GridInfo,
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
                    [v4(c, r), [(r * r) as f32, 0.0, 0.0, 0.0], [0.0; 4]],
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
                let data = self.extra.len() as u32;
                for p in &vs {
                    self.extra.push(v4(*p, 0.0));
                }
                let b = [
                    vs.len() as f32,
                    drop_axis(n) as f32,
                    is_convex(&vs, n) as u32 as f32,
                    0.0,
                ];
                let bb = Self::points_bounds(&vs);
                self.push_bounded(KIND_POLYGON, mat, data, [v4(n, d), b, [0.0; 4]], bb);
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
                let b = self.rel(*base);
                let a = self.rel(*apex);
                let len = (a - b).length();
                let axis = (a - b) / len;
                let side = if *base_radius < 0.0 && *apex_radius < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                let (r0, r1) = (base_radius.abs(), apex_radius.abs());
                // Bounds of the two end discs.
                let ext = |r: f64| {
                    DVec3::new(
                        r * (1.0 - axis.x * axis.x).max(0.0).sqrt(),
                        r * (1.0 - axis.y * axis.y).max(0.0).sqrt(),
                        r * (1.0 - axis.z * axis.z).max(0.0).sqrt(),
                    )
                };
                let bb = Self::points_bounds(&[b - ext(r0), b + ext(r0), a - ext(r1), a + ext(r1)]);
                self.push_bounded(
                    KIND_CONE,
                    mat,
                    0,
                    [v4(b, r0), v4(axis, r1), [len as f32, side as f32, 0.0, 0.0]],
                    bb,
                );
            }
        }
    }
}

/// Most primitives kept out of the grid for being as large as the scene.
pub const GIANTS_MAX: usize = 8;

/// A few primitives as large as the whole scene (a floor polygon under a
/// small object, a box round the room) would stretch the grid over empty
/// space and sit in most of its cells: the SPD's balls put 7 381 spheres
/// in a 74×74×4 grid because of a 24×24 floor. Up to `GIANTS_MAX` finite
/// primitives that span at least half the scene's extent on some axis are
/// instead tested against every ray, like planes; the grid then fits the
/// rest. Which list a primitive is in never changes a hit.
fn take_out_giants(all: &Bounds, bounded: &mut Vec<(Prim, Bounds)>, unbounded: &mut Vec<Prim>) {
    let e = all.extent();
    let giant = |b: &Bounds| (0..3).any(|i| e[i] > 0.0 && b.hi[i] - b.lo[i] >= 0.5 * e[i]);
    let count = bounded.iter().filter(|(_, b)| giant(b)).count();
    if count == 0 || count > GIANTS_MAX || count == bounded.len() {
        return;
    }
    let (giants, rest): (Vec<_>, Vec<_>) = bounded.drain(..).partition(|(_, b)| giant(b));
    *bounded = rest;
    unbounded.extend(giants.into_iter().map(|(p, _)| p));
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

/// Puts primitives that are near in space near in memory (Morton order of
/// their bounds' centres): a ray's tests then touch few cache lines, which
/// is what keeps a million primitives from being memory-bound.
fn morton_order(prims: &mut [(Prim, Bounds)]) {
    let all = prims.iter().fold(Bounds::EMPTY, |a, (_, b)| a.union(b));
    let e = all.extent().map(|x| x.max(f64::MIN_POSITIVE));
    prims.sort_by_cached_key(|(_, b)| {
        let q = [0, 1, 2].map(|i| {
            let c = (b.lo[i] + b.hi[i]) * 0.5;
            (((c - all.lo[i]) / e[i]) * 1023.0).clamp(0.0, 1023.0) as u32
        });
        spread3(q[0]) | spread3(q[1]) << 1 | spread3(q[2]) << 2
    });
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

/// Packs a scene for rendering with `settings`.
pub fn pack(scene: &Scene, settings: &Settings) -> Packed {
    let cam = &scene.camera;
    let origin = cam.from;
    let width = settings.width.unwrap_or(cam.width).max(1);
    let height = settings.height.unwrap_or(cam.height).max(1);

    let mut b = Builder {
        origin,
        bounded: Vec::new(),
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
    take_out_giants(&finite, &mut b.bounded, &mut b.unbounded);
    morton_order(&mut b.bounded);
    let bounds: Vec<Bounds> = b.bounded.iter().map(|(_, bb)| *bb).collect();
    let g = grid::build(&bounds, settings.grid);
    let grid_seconds = t0.elapsed().as_secs_f64();
    let n_bounded = b.bounded.len() as u32;
    let mut prims: Vec<Prim> = Vec::with_capacity(b.bounded.len() + b.unbounded.len());
    for (i, (mut p, _)) in b.bounded.into_iter().enumerate() {
        (p.cell_lo, p.cell_hi) = g.ranges[i];
        prims.push(p);
    }
    prims.extend(b.unbounded);

    let forward = (cam.at - cam.from).normalize();
    let right = forward.cross(cam.up).normalize();
    let up = right.cross(forward);
    let half_h = (cam.fov.to_radians() * 0.5).tan();
    let half_w = half_h * width as f64 / height as f64;
    let scale = if finite.lo[0] > finite.hi[0] {
        (cam.at - cam.from).length()
    } else {
        finite.diagonal().max((cam.at - cam.from).length())
    };
    let (nx, ny) = crate::trace::sample::strata(settings.spp);
    let sampling = match settings.sampling {
        Sampling::Corners => SAMPLING_CORNERS,
        Sampling::Centers if settings.spp > 1 => SAMPLING_JITTER,
        Sampling::Centers => SAMPLING_CENTERS,
    };
    let ncells = g.dims[0] * g.dims[1] * g.dims[2];
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
            if n_bounded > 0 { 1.0 } else { 0.0 },
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
        params: [
            settings.min_weight,
            (scale * EPS_OFFSET_REL as f64) as f32,
            0.0,
            0.0,
        ],
        flags: [0; 4],
    };
    let grid_info = GridInfo {
        cells: g.dims,
        refs: g.refs.len(),
        bytes: (g.cell_start.len() + g.refs.len()) * 4,
        seconds: grid_seconds,
    };
    Packed {
        globals,
        prims: prims.into(),
        extra: b.extra.into(),
        materials,
        lights,
        cell_start: g.cell_start.into(),
        refs: g.refs.into(),
        grid: grid_info,
    }
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
        let p = pack(&s, &Settings::default());
        assert_eq!(p.globals.counts[0], 100, "the spheres are in the grid");
        assert_eq!(
            p.globals.counts[1], 101,
            "the floor is tested against every ray"
        );
        assert_eq!(p.prims[100].kind(), KIND_POLYGON);
        // the grid fits the spheres, not the floor
        assert!(p.globals.grid_max[0] - p.globals.grid_min[0] < 1.2);
    }

    #[test]
    fn the_spd_preset_and_its_counting() {
        let s = Preset::Spd.settings();
        assert_eq!((s.width, s.height), (Some(512), Some(512)));
        assert_eq!((s.max_depth, s.min_weight), (4, 0.0));
        assert_eq!(s.sampling, Sampling::Corners);
        let scene = crate::gen::random_spheres(10, 1);
        let mut p = pack(&scene, &s);
        assert_eq!(p.counting(), Counting::Traced);
        assert_eq!(p.globals.image, [512, 512, 1, SAMPLING_CORNERS]);
        p.set_counting(Preset::Spd.counting());
        assert_eq!(p.counting(), Counting::Spd);
        assert_eq!(p.globals.flags[0], FLAG_SPD_COUNTING);
        p.set_counting(Counting::Traced);
        assert_eq!(p.globals.flags, [0; 4]);
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
