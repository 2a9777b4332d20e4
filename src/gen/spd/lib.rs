//! The SPD's library, the part its seven generators call: 4×4 matrices,
//! vector helpers, its Gaussian random numbers, and `Out`, which takes the
//! `lib_output_*` calls and builds a [`Scene`] (what `scene::load` makes of
//! the NFF text the original writes).
//!
//! Ported from Eric Haines' Standard Procedural Databases (libvec.c,
//! libpr1.c, libpr2.c; public domain, CC0). The arithmetic keeps the C's
//! order operation for operation (no fused multiply-adds, no reciprocals
//! where the C divides) so that the scenes match the originals to the last
//! printed digit. Matrices are row-major and multiply row vectors, as in
//! the C: `p' = p · M`.

use crate::scene::{Camera, Light, Material, Object, Scene, Shape};
use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::PathBuf;

pub(super) type V3 = [f64; 3];
pub(super) type V4 = [f64; 4];
pub(super) type Matrix = [[f64; 4]; 4];

pub(super) const X_AXIS: usize = 0;
pub(super) const Y_AXIS: usize = 1;
pub(super) const Z_AXIS: usize = 2;

/// The SPD's background colour, "UNC sky blue", the same in every scene.
pub(super) const SKY_BLUE: V3 = [0.078, 0.361, 0.753];

pub(super) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(super) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(super) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn xyz(v: V4) -> V3 {
    [v[0], v[1], v[2]]
}

/// `lib_normalize_vector`: divides by the length unless it is 0; returns
/// the length.
pub(super) fn normalize(v: &mut V3) -> f64 {
    let d = dot(*v, *v).sqrt();
    if d > 0.0 {
        v[0] /= d;
        v[1] /= d;
        v[2] /= d;
    }
    d
}

pub(super) fn zero_matrix() -> Matrix {
    [[0.0; 4]; 4]
}

pub(super) fn identity() -> Matrix {
    let mut m = zero_matrix();
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    m
}

/// `lib_create_rotate_matrix`: rotation by `angle` radians about one axis.
pub(super) fn rotate(axis: usize, angle: f64) -> Matrix {
    let mut m = zero_matrix();
    let (c, s) = (angle.cos(), angle.sin());
    match axis {
        X_AXIS => {
            m[0][0] = 1.0;
            m[1][1] = c;
            m[2][2] = c;
            m[1][2] = s;
            m[2][1] = -s;
        }
        Y_AXIS => {
            m[1][1] = 1.0;
            m[0][0] = c;
            m[2][2] = c;
            m[2][0] = s;
            m[0][2] = -s;
        }
        _ => {
            m[2][2] = 1.0;
            m[0][0] = c;
            m[1][1] = c;
            m[0][1] = s;
            m[1][0] = -s;
        }
    }
    m[3][3] = 1.0;
    m
}

/// `lib_create_axis_rotate_matrix`: rotation by `angle` about the unit
/// vector `a`.
pub(super) fn axis_rotate(a: V3, angle: f64) -> Matrix {
    let c = angle.cos();
    let s = angle.sin();
    let omc = 1.0 - c;
    let sq = |x: f64| x * x;
    [
        [
            sq(a[0]) + (1.0 - sq(a[0])) * c,
            a[0] * a[1] * omc + a[2] * s,
            a[0] * a[2] * omc - a[1] * s,
            0.0,
        ],
        [
            a[0] * a[1] * omc - a[2] * s,
            sq(a[1]) + (1.0 - sq(a[1])) * c,
            a[1] * a[2] * omc + a[0] * s,
            0.0,
        ],
        [
            a[0] * a[2] * omc + a[1] * s,
            a[1] * a[2] * omc - a[0] * s,
            sq(a[2]) + (1.0 - sq(a[2])) * c,
            0.0,
        ],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `lib_matrix_multiply`: a · b.
pub(super) fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    let mut r = zero_matrix();
    for i in 0..4 {
        for j in 0..4 {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] + a[i][3] * b[3][j];
        }
    }
    r
}

pub(super) fn transpose(m: &Matrix) -> Matrix {
    let mut r = zero_matrix();
    for i in 0..4 {
        for j in 0..4 {
            r[j][i] = m[i][j];
        }
    }
    r
}

/// `lib_transform_vector`: v · M, no translation.
pub(super) fn transform_vector(v: V3, m: &Matrix) -> V3 {
    [
        v[0] * m[0][0] + v[1] * m[1][0] + v[2] * m[2][0],
        v[0] * m[0][1] + v[1] * m[1][1] + v[2] * m[2][1],
        v[0] * m[0][2] + v[1] * m[1][2] + v[2] * m[2][2],
    ]
}

/// `lib_transform_point`: v · M with M's translation row.
pub(super) fn transform_point(v: V3, m: &Matrix) -> V3 {
    [
        v[0] * m[0][0] + v[1] * m[1][0] + v[2] * m[2][0] + m[3][0],
        v[0] * m[0][1] + v[1] * m[1][1] + v[2] * m[2][1] + m[3][1],
        v[0] * m[0][2] + v[1] * m[1][2] + v[2] * m[2][2] + m[3][2],
    ]
}

/// `lib_transform_coord`: the homogeneous v · M.
pub(super) fn transform_coord(v: V4, m: &Matrix) -> V4 {
    let mut r = [0.0; 4];
    for (j, out) in r.iter_mut().enumerate() {
        *out = v[0] * m[0][j] + v[1] * m[1][j] + v[2] * m[2][j] + v[3] * m[3][j];
    }
    r
}

/// `lib_gauss_rand`: a Gaussian deviate (the polar Box–Muller method of
/// Numerical Recipes' GASDEV) from a linear congruential generator seeded
/// with `seed`; the same seed always gives the same number.
pub(super) fn gauss_rand(seed: i64) -> f64 {
    const M1: i64 = 134_456;
    const IA1: i64 = 8121;
    const IC1: i64 = 28_411;
    let mut ix2 = seed;
    loop {
        let ix1 = (IC1 + ix2 * IA1) % M1;
        ix2 = (IC1 + ix1 * IA1) % M1;
        // The C's `ix * 2.0 * RM1` with `#define RM1 1.0/M1`.
        let v1 = ix1 as f64 * 2.0 * 1.0 / M1 as f64 - 1.0;
        let v2 = ix2 as f64 * 2.0 * 1.0 / M1 as f64 - 1.0;
        let r = v1 * v1 + v2 * v2;
        if r < 1.0 {
            let fac = (-2.0 * r.ln() / r).sqrt();
            return v1 * fac;
        }
    }
}

/// `lib_output_color`'s Phong exponent: the highlight falls to half at
/// `ang` degrees from the mirror direction.
pub(super) fn phong_pow(ang: f64) -> f64 {
    let rad = PI * ang / 180.0;
    if rad <= 0.0 {
        100_000.0
    } else if rad >= PI / 2.0 {
        1.0
    } else {
        0.5f64.ln() / rad.cos().ln()
    }
}

/// The material `scene::load` makes of an NFF `f` line (see
/// src/scene/nff.rs; `tests/spd.rs` checks that the two agree).
fn nff_material(
    name: String,
    color: V3,
    kd: f64,
    ks: f64,
    shine: f64,
    t: f64,
    ior: f64,
) -> Material {
    let c = DVec3::from_array(color);
    Material {
        name,
        ka: kd * c,
        kd: kd * c,
        ksr: ks,
        nr: shine,
        kst: 0.0,
        nt: shine,
        kr: DVec3::splat(ks),
        kt: DVec3::splat(t),
        // The SPD writes ior 0 for opaque surfaces; the reader takes it as 1.
        ior: if t == 0.0 && ior == 0.0 { 1.0 } else { ior },
        absorption: DVec3::ZERO,
    }
}

fn dv(v: V3) -> DVec3 {
    DVec3::from_array(v)
}

/// The scene as the SPD's `lib_output_*` calls describe it, in the order
/// they come. Materials are shared between identical `f` lines, as the
/// NFF reader shares them.
pub(super) struct Out {
    scene: Scene,
    current: u32,
    index: HashMap<[u64; 8], u32>,
}

impl Out {
    /// `lib_output_background_color` and `lib_output_viewpoint` (the SPD's
    /// views are all square, aspect 1; hither is not kept).
    pub(super) fn new(name: &str, size: u32, from: V3, at: V3, up: V3, angle: f64) -> Out {
        Out {
            scene: Scene {
                camera: Camera {
                    from: dv(from),
                    at: dv(at),
                    up: dv(up),
                    fov: angle,
                    width: 512,
                    height: 512,
                },
                background: dv(SKY_BLUE),
                ambient: DVec3::ZERO,
                lights: Vec::new(),
                // Index 0 is the reader's default, for objects before any `f`.
                materials: vec![Material::default()],
                objects: Vec::new(),
                source: PathBuf::from(format!("spd-{name}-{size}")),
            },
            current: 0,
            index: HashMap::new(),
        }
    }

    /// `lib_output_light`. NFF lights carry no intensity: `finish` gives
    /// each the reader's sqrt(n)/(2n).
    pub(super) fn light(&mut self, p: V3) {
        self.scene.lights.push(Light {
            position: dv(p),
            color: DVec3::ZERO,
            falloff: [1.0, 0.0, 0.0],
        });
    }

    /// `lib_output_color`. NFF keeps the colour, kd, ks, the Phong
    /// exponent of `ang`, kt and the index of refraction; `ka` and
    /// `ks_spec` go nowhere.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn color(
        &mut self,
        color: V3,
        _ka: f64,
        kd: f64,
        ks: f64,
        _ks_spec: f64,
        ang: f64,
        kt: f64,
        ior: f64,
    ) {
        let shine = phong_pow(ang);
        let key = [color[0], color[1], color[2], kd, ks, shine, kt, ior].map(f64::to_bits);
        let materials = &mut self.scene.materials;
        self.current = *self.index.entry(key).or_insert_with(|| {
            let name = format!("nff{}", materials.len());
            materials.push(nff_material(name, color, kd, ks, shine, kt, ior));
            materials.len() as u32 - 1
        });
    }

    fn push(&mut self, shape: Shape) {
        self.scene.objects.push(Object {
            shape,
            material: self.current,
        });
    }

    /// `lib_output_sphere`: centre xyz, radius w.
    pub(super) fn sphere(&mut self, c: V4) {
        self.push(Shape::Sphere {
            center: dv(xyz(c)),
            radius: c[3],
        });
    }

    /// `lib_output_polygon`.
    pub(super) fn polygon(&mut self, vs: &[V3]) {
        self.push(Shape::Polygon {
            vertices: vs.iter().map(|&v| dv(v)).collect(),
        });
    }

    /// `lib_output_polypatch` of a triangle: vertices with normals. A
    /// triangle of zero area (by the readers' test) is left out: the NFF
    /// reader would refuse the file (four of the teapot's at size 1).
    pub(super) fn polypatch(&mut self, vs: &[V3; 3], ns: &[V3; 3]) {
        if crate::scene::triangle_is_degenerate(&vs.map(dv)) {
            return;
        }
        self.push(Shape::Triangle {
            vertices: vs.map(dv),
            normals: Some(Box::new(ns.map(dv))),
        });
    }

    /// `lib_output_cylcone`: an open cone from `base` to `apex`, radii in w.
    pub(super) fn cylcone(&mut self, base: V4, apex: V4) {
        self.push(Shape::Cone {
            base: dv(xyz(base)),
            base_radius: base[3],
            apex: dv(xyz(apex)),
            apex_radius: apex[3],
        });
    }

    /// The scene, with every light and the ambient term at the NFF
    /// reader's sqrt(n)/(2n).
    pub(super) fn finish(mut self) -> Scene {
        let n = self.scene.lights.len();
        // As src/scene/nff.rs reads lights without a colour.
        let grey = DVec3::splat(if n == 0 {
            0.0
        } else {
            (n as f64).sqrt() / (2.0 * n as f64)
        });
        for l in &mut self.scene.lights {
            l.color = grey;
        }
        self.scene.ambient = grey;
        self.scene
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn rotations_turn_the_right_way() {
        // A row vector times the SPD's Z rotation by +90° goes x → y.
        let v = transform_vector([1.0, 0.0, 0.0], &rotate(Z_AXIS, PI / 2.0));
        assert!((v[0]).abs() < 1e-15 && (v[1] - 1.0).abs() < 1e-15);
        // The axis form about +Z agrees with it.
        let a = axis_rotate([0.0, 0.0, 1.0], 0.7);
        let b = rotate(Z_AXIS, 0.7);
        for i in 0..4 {
            for j in 0..4 {
                assert!((a[i][j] - b[i][j]).abs() < 1e-15, "{i} {j}");
            }
        }
        let m = multiply(&rotate(X_AXIS, 0.3), &transpose(&rotate(X_AXIS, 0.3)));
        for i in 0..4 {
            for j in 0..4 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((m[i][j] - e).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn gauss_rand_is_a_fixed_sequence_of_plausible_deviates() {
        assert_eq!(gauss_rand(21).to_bits(), gauss_rand(21).to_bits());
        let xs: Vec<f64> = (0..20_000).map(|s| gauss_rand(s * 3 + 1)).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.05, "mean {mean}");
        assert!((var - 1.0).abs() < 0.1, "variance {var}");
    }

    #[test]
    fn phong_exponents_as_the_spd_prints_them() {
        // The NFF files carry these for 37°, 6.7°, 30° and 0°.
        assert_eq!(format!("{:.4}", phong_pow(37.0)), "3.0827");
        assert_eq!(format!("{:.3}", phong_pow(6.7)), "101.148");
        assert_eq!(format!("{:.5}", phong_pow(30.0)), "4.81884");
        assert_eq!(phong_pow(0.0), 100_000.0);
        assert_eq!(phong_pow(95.0), 1.0);
    }
}
