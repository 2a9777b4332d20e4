//! Scenes with a closed-form image, checked on every backend against the
//! formula, not against the other backend: a lit sphere (the local model,
//! docs/method.md) and Beer–Lambert absorption through a slab. The
//! expected values are computed in f64 from the scene's parameters and the
//! camera model of docs/scene-format.md; the only things taken from the
//! renderer are the f32 camera basis it packed and the f32 image-plane
//! position of each pixel centre (so that the check measures the tracer,
//! not the rounding of the camera into f32).
//!
//! Tolerances, each from measured errors with room (printed by the tests):
//! f32 on any backend 1e-5 absolute per channel (measured ≤ 2.2e-6); f64
//! on the CPU 4e-7 relative (measured ≤ 6e-8 absolute: the packed coefficients
//! and the pixel are f32, each within 6e-8). A wrong term of the model is off by 1e-2 or more; the slab's
//! transmission erred by σ·ε/cos (1e-3 relative here) before the offset
//! of a ray spawned into a medium was accounted for.

mod common;

use std::path::Path;
use whitted::cpu::Frame;
use whitted::gpu::GpuOptions;
use whitted::pack::{self, Packed, Settings};

const W: u32 = 64;
const H: u32 = 48;

fn settings() -> Settings {
    Settings {
        width: Some(W),
        height: Some(H),
        min_weight: 0.0,
        ..Default::default()
    }
}

fn packed(text: &str) -> Packed {
    let s = whitted::scene::parse_str(text, Path::new("analytic.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    pack::pack(&s, &settings()).unwrap()
}

type V = [f64; 3];
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn norm(a: V) -> V {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// The eye ray through pixel (x, y)'s centre, from the packed camera basis
/// (forward, right·tan(fov/2)·W/H, up·tan(fov/2)) in f64.
fn eye_ray(p: &Packed, x: u32, y: u32) -> V {
    let g = &p.globals;
    let v = |a: &[f32; 4]| [a[0] as f64, a[1] as f64, a[2] as f64];
    // The image-plane position is f32 on every backend (and in f64
    // renders): the formula is evaluated where the sample really is.
    let sx = ((x as f32 + 0.5) / W as f32 * 2.0 - 1.0) as f64;
    let sy = (1.0 - (y as f32 + 0.5) / H as f32 * 2.0) as f64;
    let (f, r, u) = (v(&g.cam_forward), v(&g.cam_right), v(&g.cam_up));
    norm([
        f[0] + r[0] * sx + u[0] * sy,
        f[1] + r[1] * sx + u[1] * sy,
        f[2] + r[2] * sx + u[2] * sy,
    ])
}

/// Every backend's frame: CPU f32, CPU f64, and the GPU when there is one.
fn frames(p: &Packed) -> Vec<(&'static str, Frame)> {
    let mut v = vec![
        ("cpu f32", whitted::cpu::render(p, &|_, _| {})),
        ("cpu f64", whitted::cpu::render_as::<f64>(p, &|_, _| {})),
    ];
    if let Some(g) = common::gpu() {
        let f = g
            .render(p, &GpuOptions::default(), &|_, _| {})
            .unwrap_or_else(|e| panic!("GPU render: {e}"));
        common::assert_no_validation_errors();
        v.push(("gpu", f));
    }
    v
}

/// Checks every pixel the formula gives (None: too close to an edge to
/// say) and returns the largest error per backend.
fn check(p: &Packed, expected: impl Fn(u32, u32) -> Option<V>) -> usize {
    let mut checked = 0;
    for (name, f) in frames(p) {
        // f64 arithmetic on coefficients stored in f32 (each within 6e-8
        // relative), into an f32 pixel: 4e-7 relative.
        let tol = |e: f64| {
            if name == "cpu f64" {
                1e-10 + e.abs() * 4e-7
            } else {
                1e-5
            }
        };
        let mut worst = 0.0f64;
        checked = 0;
        for y in 0..H {
            for x in 0..W {
                let Some(e) = expected(x, y) else { continue };
                checked += 1;
                let got = f.pixels[(y * W + x) as usize];
                for c in 0..3 {
                    let d = (got[c] as f64 - e[c]).abs();
                    worst = worst.max(d);
                    let tol = tol(e[c]);
                    assert!(
                        d <= tol,
                        "{name}: pixel ({x}, {y}) channel {c}: {} against the formula's {} \
                         (error {d:e}, tolerance {tol:e})",
                        got[c],
                        e[c]
                    );
                }
            }
        }
        println!("{name}: {checked} pixels, worst error {worst:e}");
    }
    checked
}

#[test]
fn a_lit_sphere_is_the_local_model_in_closed_form() {
    // Camera on −y looking at the origin, z up; one white light; the
    // sphere alone, so nothing shadows a lit point.
    let text = "ambient = [0.3, 0.3, 0.3]\nbackground = [0.05, 0.1, 0.2]\n\
        [camera]\nfrom = [0, -5, 0]\nat = [0, 0, 0]\nup = [0, 0, 1]\nfov = 30\nwidth = 64\nheight = 48\n\
        [[light]]\nposition = [4, -6, 5]\ncolor = [1, 0.9, 0.8]\n\
        [material.m]\ncolor = [0.8, 0.5, 0.3]\nka = 0.2\nkd = 0.7\nks = 0.4\nshine = 20\n\
        [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n";
    let p = packed(text);
    let (eye, light, li) = ([0.0, -5.0, 0.0], [4.0, -6.0, 5.0], [1.0, 0.9, 0.8]);
    let (color, ka, kd, ks, shine) = ([0.8, 0.5, 0.3], 0.2, 0.7, 0.4, 20.0);
    let n = check(&p, |x, y| {
        let d = eye_ray(&p, x, y);
        // |eye + t d|² = 1: t² + 2 b t + c = 0.
        let b = dot(eye, d);
        let c = dot(eye, eye) - 1.0;
        let disc = b * b - c;
        if disc.abs() < 1e-2 {
            return None; // the silhouette: a pixel's ray grazes the sphere
        }
        if disc < 0.0 {
            return Some([0.05, 0.1, 0.2]);
        }
        let t = -b - disc.sqrt();
        let hit = [eye[0] + t * d[0], eye[1] + t * d[1], eye[2] + t * d[2]];
        let nrm = hit; // unit sphere at the origin
        let l = norm(sub(light, hit));
        let ndotl = dot(nrm, l);
        let v = scale(d, -1.0);
        let mut out = [0.0; 3];
        for k in 0..3 {
            out[k] = ka * color[k] * 0.3;
            if ndotl > 0.0 {
                let r = sub(scale(nrm, 2.0 * ndotl), l);
                let vr = dot(v, r).max(0.0);
                out[k] += li[k] * (kd * color[k] * ndotl + ks * vr.powf(shine));
            }
        }
        Some(out)
    });
    assert!(n > (W * H / 2) as usize, "only {n} pixels checked");
}

#[test]
fn light_through_an_absorbing_slab_falls_off_as_beer_lambert() {
    // A slab 1 thick across the whole view, k_t = 1, ior 1 (no bending),
    // no other term: each pixel is the background times exp(−σ·1/|d_y|).
    let text = "ambient = [0, 0, 0]\nbackground = [0.9, 0.8, 0.7]\n\
        [camera]\nfrom = [0, -5, 0]\nat = [0, 0, 0]\nup = [0, 0, 1]\nfov = 60\nwidth = 64\nheight = 48\n\
        [[light]]\nposition = [0, -5, 0]\n\
        [material.glass]\nka = 0\nkd = 0\nkt = 1\nior = 1\nabsorption = [0.3, 0.7, 1.5]\n\
        [[object]]\ntype = \"box\"\nmin = [-50, -0.5, -50]\nmax = [50, 0.5, 50]\nmaterial = \"glass\"\n";
    let p = packed(text);
    let (bg, sigma) = ([0.9, 0.8, 0.7], [0.3, 0.7, 1.5]);
    let n = check(&p, |x, y| {
        let d = eye_ray(&p, x, y);
        let path = 1.0 / d[1].abs();
        Some([
            bg[0] * (-sigma[0] * path).exp(),
            bg[1] * (-sigma[1] * path).exp(),
            bg[2] * (-sigma[2] * path).exp(),
        ])
    });
    assert_eq!(n, (W * H) as usize);
}
