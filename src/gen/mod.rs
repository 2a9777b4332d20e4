//! Procedural scenes for benchmarks and tests: random spheres and a
//! sphereflake here, and the SPD's seven scenes in `spd`.
//!
//! `random_spheres(n, seed)`: n spheres scattered uniformly in the cube
//! [-1, 1]³ with radius 0.45 × their mean spacing (2/∛n), so a ray meets
//! the first sphere after about the same number of spacings whatever n is
//! (the grid's work per ray stays flat from 1 k to 1 M spheres), and the
//! cube is optically thick even at 1 k (the mean free path, 1/(n/8 · πr²),
//! is about a sixth of its side), so the picture and the ray count change
//! little with n: render time measures the acceleration structure. Three lights, a floor (a large square), four materials (one of
//! them a mirror).

pub mod spd;

use crate::scene::{Camera, Light, Material, Object, Scene, Shape};
use glam::DVec3;
use std::path::PathBuf;

/// xorshift64*: small, deterministic, good enough for placing spheres.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}

pub fn random_spheres(n: usize, seed: u64) -> Scene {
    let mut rng = Rng::new(seed);
    let spacing = 2.0 / (n.max(1) as f64).cbrt();
    let radius = 0.45 * spacing;
    let materials = vec![
        Material::default(),
        Material {
            name: "red".into(),
            ka: DVec3::new(0.08, 0.02, 0.02),
            kd: DVec3::new(0.7, 0.15, 0.1),
            ksr: 0.4,
            nr: 30.0,
            ..Material::default()
        },
        Material {
            name: "mirror".into(),
            ka: DVec3::splat(0.02),
            kd: DVec3::splat(0.1),
            ksr: 0.6,
            nr: 80.0,
            kr: DVec3::splat(0.7),
            ..Material::default()
        },
        Material {
            name: "blue".into(),
            ka: DVec3::new(0.02, 0.03, 0.08),
            kd: DVec3::new(0.1, 0.25, 0.7),
            ksr: 0.3,
            nr: 20.0,
            kr: DVec3::splat(0.2),
            ..Material::default()
        },
    ];
    let mut objects = Vec::with_capacity(n + 1);
    objects.push(Object {
        shape: Shape::Polygon {
            vertices: [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)]
                .iter()
                .map(|&(x, y)| DVec3::new(x, y, -1.05))
                .collect(),
        },
        material: 0,
    });
    for i in 0..n {
        let c = DVec3::new(
            rng.next_f64() * 2.0 - 1.0,
            rng.next_f64() * 2.0 - 1.0,
            rng.next_f64() * 2.0 - 1.0,
        );
        objects.push(Object {
            shape: Shape::Sphere { center: c, radius },
            material: 1 + (i % 3) as u32,
        });
    }
    let white = |s: f64| DVec3::splat(s);
    Scene {
        camera: Camera {
            from: DVec3::new(2.6, -3.4, 1.9),
            at: DVec3::ZERO,
            up: DVec3::Z,
            fov: 40.0,
            width: 1024,
            height: 768,
        },
        background: DVec3::new(0.05, 0.08, 0.15),
        ambient: white(0.3),
        lights: vec![
            Light {
                position: DVec3::new(4.0, -3.0, 6.0),
                color: white(0.6),
                falloff: [1.0, 0.0, 0.0],
            },
            Light {
                position: DVec3::new(-5.0, -4.0, 3.0),
                color: white(0.35),
                falloff: [1.0, 0.0, 0.0],
            },
            Light {
                position: DVec3::new(0.5, 5.0, 4.0),
                color: white(0.25),
                falloff: [1.0, 0.0, 0.0],
            },
        ],
        materials,
        objects,
        source: PathBuf::from(format!("random-spheres-{n}")),
    }
}

/// A sphereflake after Haines' SPD `balls`: a sphere with nine children a
/// third its radius on its surface (six round its equator, three above),
/// each with nine of its own, `level` times: (9^(level+1) − 1)/8 spheres
/// (level 3: 820, 4: 7 381, 5: 66 430, 6: 597 871). The picture hardly
/// changes with the level, so render time against level shows how the
/// grid scales with the primitive count alone.
pub fn sphereflake(level: u32) -> Scene {
    let mut scene = random_spheres(0, 1);
    scene.objects.truncate(1); // keep the floor
    scene.camera.from = DVec3::new(2.1, 1.3, 1.7);
    scene.camera.at = DVec3::new(0.0, 0.0, -0.1);
    fn grow(objects: &mut Vec<Object>, c: DVec3, r: f64, axis: DVec3, level: u32, mat: u32) {
        objects.push(Object {
            shape: Shape::Sphere {
                center: c,
                radius: r,
            },
            material: mat,
        });
        if level == 0 {
            return;
        }
        let t = if axis.x.abs() < 0.9 {
            DVec3::X
        } else {
            DVec3::Y
        };
        let u = axis.cross(t).normalize();
        let v = axis.cross(u);
        let child = r / 3.0;
        for k in 0..9 {
            let (elev, az) = if k < 6 {
                (0.0f64, k as f64 * std::f64::consts::FRAC_PI_3)
            } else {
                (
                    std::f64::consts::FRAC_PI_3,
                    (k - 6) as f64 * 2.0 * std::f64::consts::FRAC_PI_3 + 0.5,
                )
            };
            let dir = (u * az.cos() + v * az.sin()) * elev.cos() + axis * elev.sin();
            grow(
                objects,
                c + dir * (r + child),
                child,
                dir,
                level - 1,
                1 + (mat % 3),
            );
        }
    }
    grow(
        &mut scene.objects,
        DVec3::new(0.0, 0.0, -0.55),
        0.5,
        DVec3::Z,
        level,
        2,
    );
    scene.source = PathBuf::from(format!("sphereflake-{level}"));
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphereflake_counts() {
        for (level, n) in [(0, 1), (1, 10), (3, 820), (4, 7381)] {
            assert_eq!(sphereflake(level).objects.len(), n + 1, "level {level}");
        }
    }

    #[test]
    fn deterministic_and_inside_the_cube() {
        let a = random_spheres(500, 7);
        assert_eq!(a, random_spheres(500, 7));
        assert_ne!(a.objects[5], random_spheres(500, 8).objects[5]);
        assert_eq!(a.objects.len(), 501);
        for o in &a.objects[1..] {
            let Shape::Sphere { center, radius } = o.shape else {
                panic!("not a sphere")
            };
            assert!(center.abs().max_element() <= 1.0);
            assert!((radius - 0.45 * 2.0 / 500f64.cbrt()).abs() < 1e-12);
        }
    }
}
