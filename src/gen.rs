//! Procedural scenes for benchmarks and tests.
//!
//! `random_spheres(n, seed)`: n spheres scattered uniformly in the cube
//! [-1, 1]³ with radius 0.3 × their mean spacing (2/∛n), so a ray meets the
//! first sphere after about the same number of spacings whatever n is:
//! the grid's work per ray stays flat from 1 k to 1 M spheres, and render
//! time should too. Three lights, a floor (a large square), four materials (one of
//! them a mirror).

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
    let radius = 0.3 * spacing;
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

#[cfg(test)]
mod tests {
    use super::*;

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
            assert!((radius - 0.3 * 2.0 / 500f64.cbrt()).abs() < 1e-12);
        }
    }
}
