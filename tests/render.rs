//! The tracer end to end on scenes built in code: closed forms, the crack
//! test, grid traversal against brute force, and sanity over every example.

use glam::DVec3;
use proptest::prelude::*;
use std::path::PathBuf;
use whitted::cpu::{self, Frame};
use whitted::pack::{self, Packed, Settings};
use whitted::scene::{self, Camera, Light, Material, Mesh, Object, Scene, Shape};
use whitted::trace::accel::{closest_hit, closest_hit_brute};
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{v3, Ray};
use whitted::trace::query::Work;
use whitted::trace::SceneView;

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn scene(
    camera: Camera,
    objects: Vec<Object>,
    materials: Vec<Material>,
    lights: Vec<Light>,
) -> Scene {
    Scene {
        camera,
        background: v(1.0, 0.0, 0.0),
        ambient: DVec3::ZERO,
        lights,
        materials,
        objects,
        source: PathBuf::from("test"),
    }
}

fn render(p: &Packed) -> Frame {
    cpu::render(p, &|_, _| {})
}

fn px(f: &Frame, x: u32, y: u32) -> [f32; 3] {
    f.pixels[(y * f.width + x) as usize]
}

/// One sphere lit by one light: every pixel against the closed form
/// I = k_a I_a + I_L [k_d (N·L) + k_s (V·R)^n], with the hit point solved
/// independently in f64.
#[test]
fn single_lit_sphere_matches_closed_form() {
    let cam = Camera {
        from: v(0.0, -5.0, 0.0),
        at: DVec3::ZERO,
        up: v(0.0, 0.0, 1.0),
        fov: 30.0,
        width: 64,
        height: 48,
    };
    let light_pos = v(3.0, -4.0, 5.0);
    let mat = Material {
        name: "m".into(),
        ka: v(0.1, 0.2, 0.3),
        kd: v(0.6, 0.5, 0.4),
        ksr: 0.5,
        nr: 10.0,
        ..Material::default()
    };
    let mut s = scene(
        cam.clone(),
        vec![Object {
            shape: Shape::Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
            material: 0,
        }],
        vec![mat.clone()],
        vec![Light {
            position: light_pos,
            color: v(0.9, 0.8, 0.7),
            falloff: [1.0, 0.0, 0.0],
        }],
    );
    s.ambient = v(0.5, 0.5, 0.5);
    s.background = v(0.25, 0.5, 0.75);
    let p = pack::pack(&s, &Settings::default()).unwrap();
    let f = render(&p);
    // The camera model, in f64: vertical fov edge to edge.
    let fwd = (cam.at - cam.from).normalize();
    let right = fwd.cross(cam.up).normalize();
    let up = right.cross(fwd);
    let hh = (cam.fov.to_radians() / 2.0).tan();
    let hw = hh * 64.0 / 48.0;
    let mut hits = 0;
    for y in 0..48 {
        for x in 0..64 {
            let sx = (x as f64 + 0.5) / 64.0 * 2.0 - 1.0;
            let sy = 1.0 - (y as f64 + 0.5) / 48.0 * 2.0;
            let d = (fwd + right * (sx * hw) + up * (sy * hh)).normalize();
            let o = cam.from;
            // |o + t d|² = 1
            let b = o.dot(d);
            let disc = b * b - (o.dot(o) - 1.0);
            let got = px(&f, x, y);
            let want = if disc < 0.0 {
                s.background
            } else {
                hits += 1;
                let t = -b - disc.sqrt();
                let p = o + d * t;
                let n = p.normalize();
                let l = (light_pos - p).normalize();
                let ndotl = n.dot(l).max(0.0);
                let r = n * (2.0 * n.dot(l)) - l;
                let vr = (-d).dot(r);
                let spec = if ndotl > 0.0 && vr > 0.0 {
                    mat.ksr * vr.powf(mat.nr)
                } else {
                    0.0
                };
                mat.ka * s.ambient + v(0.9, 0.8, 0.7) * (mat.kd * ndotl + DVec3::splat(spec))
            };
            for c in 0..3 {
                assert!(
                    (got[c] as f64 - want[c]).abs() < 2e-4,
                    "pixel ({x},{y}) channel {c}: {} vs {}",
                    got[c],
                    want[c]
                );
            }
        }
    }
    assert!(hits > 500 && hits < 64 * 48, "{hits}");
    assert_eq!(f.stats.eye, 64 * 48);
    assert_eq!(f.stats.eye_hit, hits);
}

/// A plane tiled with jittered triangles, viewed at a grazing angle and
/// straight down through a shared vertex: no background pixel gets
/// through (watertight triangles), none is NaN.
#[test]
fn tiled_plane_has_no_cracks() {
    let n = 48usize;
    let mut positions = Vec::new();
    let mut h: u32 = 12345;
    let mut rnd = || {
        h ^= h << 13;
        h ^= h >> 17;
        h ^= h << 5;
        (h as f64 / u32::MAX as f64) - 0.5
    };
    for j in 0..=n {
        for i in 0..=n {
            let interior = i > 0 && j > 0 && i < n && j < n && (i, j) != (n / 2, n / 2);
            let (jx, jy) = if interior {
                (rnd() * 0.6, rnd() * 0.6)
            } else {
                (0.0, 0.0)
            };
            positions.push(v(
                i as f64 - n as f64 / 2.0 + jx,
                j as f64 - n as f64 / 2.0 + jy,
                0.0,
            ));
        }
    }
    let mut triangles = Vec::new();
    let idx = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    for j in 0..n {
        for i in 0..n {
            triangles.push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    let mesh = Shape::Mesh(Box::new(Mesh {
        positions,
        normals: None,
        triangles,
    }));
    let white = Material {
        name: "w".into(),
        ka: DVec3::ONE,
        kd: DVec3::ZERO,
        ..Material::default()
    };
    for cam in [
        Camera {
            from: v(0.3, -20.0, 2.5),
            at: v(0.0, 0.0, 0.0),
            up: v(0.0, 0.0, 1.0),
            fov: 20.0,
            width: 201,
            height: 101,
        },
        // straight down onto the central vertex: the centre ray hits it exactly
        Camera {
            from: v(0.0, 0.0, 7.0),
            at: v(0.0, 0.0, 0.0),
            up: v(0.0, 1.0, 0.0),
            fov: 60.0,
            width: 101,
            height: 101,
        },
    ] {
        let mut s = scene(
            cam,
            vec![Object {
                shape: mesh.clone(),
                material: 0,
            }],
            vec![white.clone()],
            vec![],
        );
        s.ambient = DVec3::ONE;
        let p = pack::pack(&s, &Settings::default()).unwrap();
        let f = render(&p);
        let mut leaks = Vec::new();
        for y in 0..f.height {
            for x in 0..f.width {
                let c = px(&f, x, y);
                assert!(c.iter().all(|v| v.is_finite()));
                // the plane fills the lower part of the grazing view and all of the top view
                let on_plane = if f.height == 101 && f.width == 201 {
                    y > 60
                } else {
                    true
                };
                if on_plane && c != [1.0, 1.0, 1.0] {
                    leaks.push((x, y, c));
                }
            }
        }
        assert!(
            leaks.is_empty(),
            "{} leaks, first {:?}",
            leaks.len(),
            &leaks[..leaks.len().min(5)]
        );
    }
}

fn random_spheres(seed: u64, count: usize) -> Scene {
    let mut h = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut rnd = move || {
        h ^= h << 13;
        h ^= h >> 7;
        h ^= h << 17;
        (h >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut objects = Vec::new();
    for i in 0..count {
        let c = v(rnd() * 10.0 - 5.0, rnd() * 10.0 - 5.0, rnd() * 10.0 - 5.0);
        let shape = match i % 4 {
            0 | 1 => Shape::Sphere {
                center: c,
                radius: 0.05 + rnd() * 0.8,
            },
            2 => Shape::Triangle {
                vertices: [c, c + v(rnd(), rnd(), 0.0), c + v(0.0, rnd(), rnd() + 0.1)],
                normals: None,
            },
            _ => Shape::Box {
                min: c,
                max: c + v(rnd() + 0.01, rnd() + 0.01, rnd() + 0.01),
            },
        };
        objects.push(Object { shape, material: 0 });
    }
    scene(
        Camera {
            from: v(0.0, -20.0, 0.0),
            at: DVec3::ZERO,
            up: v(0.0, 0.0, 1.0),
            fov: 45.0,
            width: 8,
            height: 8,
        },
        objects,
        vec![Material::default()],
        vec![],
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The grid's closest hit equals brute force over every primitive,
    /// for random scenes, grid resolutions and rays (from outside and
    /// inside the grid), and tests each primitive at most once.
    #[test]
    fn grid_traversal_equals_brute_force(
        seed in 0u64..1000,
        count in 1usize..120,
        dims in prop::array::uniform3(1u32..24),
        rays in prop::collection::vec((prop::array::uniform3(-12.0f32..12.0), prop::array::uniform3(-1.0f32..1.0)), 64),
    ) {
        let s = random_spheres(seed, count);
        let settings = Settings { grid: Some(dims), ..Settings::default() };
        let p = pack::pack(&s, &settings).unwrap();
        let view = SceneView::new(&p);
        for (o, d) in rays {
            let d = v3(d[0], d[1], d[2]);
            prop_assume!(d.length() > 1e-3);
            let d = d.normalize();
            let ray = Ray { o: v3(o[0], o[1], o[2]), d };
            let pre = RayPre::new(d, true);
            let mut work = Work::default();
            let g = closest_hit(&view, &ray, &pre, f32::INFINITY, &mut work);
            let b = closest_hit_brute(&view, &ray, &pre, f32::INFINITY);
            prop_assert!(work.tests <= p.prims.len() as u64, "{} tests for {} prims", work.tests, p.prims.len());
            match (g, b) {
                (None, None) => {}
                (Some((hg, pg)), Some((hb, pb))) => {
                    prop_assert_eq!(hg.t, hb.t, "prims {} vs {}", pg, pb);
                }
                (g, b) => prop_assert!(false, "grid {:?} vs brute {:?}", g, b),
            }
        }
    }
}

/// Every example scene renders without NaN or infinite pixels, and its ray
/// counts obey the SPD's relations.
#[test]
fn example_scenes_render_clean() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        if !matches!(
            path.extension().and_then(|x| x.to_str()),
            Some("toml" | "nff")
        ) {
            continue;
        }
        let s = scene::load(&path).unwrap();
        let settings = Settings {
            width: Some(64),
            height: Some(48),
            ..Settings::default()
        };
        let f = render(&pack::pack(&s, &settings).unwrap());
        assert!(
            f.pixels
                .iter()
                .flatten()
                .all(|c| c.is_finite() && *c >= 0.0),
            "{}",
            path.display()
        );
        assert_eq!(f.stats.eye, 64 * 48);
        assert!(f.stats.eye_hit <= f.stats.eye);
        assert!(
            f.stats.shadow
                <= (f.stats.eye_hit + f.stats.reflect + f.stats.refract) * s.lights.len() as u64
        );
        n += 1;
    }
    assert!(n >= 3, "found only {n} example scenes in {}", dir.display());
}

/// The classic figure's premise: with max depth 0 the glass sphere shows no
/// refraction; deeper renders add reflected and refracted rays, and depth
/// 1 differs from depth 2 (the inside of the glass appears).
#[test]
fn depth_limit_controls_the_ray_tree() {
    let s = scene::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/showcase.toml"))
        .unwrap();
    let mut frames = Vec::new();
    for depth in 0..4 {
        let settings = Settings {
            width: Some(80),
            height: Some(60),
            max_depth: depth,
            ..Settings::default()
        };
        frames.push(render(&pack::pack(&s, &settings).unwrap()));
    }
    assert_eq!(frames[0].stats.reflect + frames[0].stats.refract, 0);
    assert!(frames[1].stats.refract > 0 && frames[1].stats.reflect > 0);
    assert!(frames[2].stats.refract > frames[1].stats.refract);
    for d in 0..3 {
        assert_ne!(
            frames[d].pixels,
            frames[d + 1].pixels,
            "depth {d} vs {}",
            d + 1
        );
    }
}

/// Adaptive depth control: a higher min weight prunes rays, 0 prunes none.
#[test]
fn min_weight_prunes_branches() {
    let s = scene::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/showcase.toml"))
        .unwrap();
    let count = |w: f32| {
        let settings = Settings {
            width: Some(60),
            height: Some(45),
            max_depth: 8,
            min_weight: w,
            ..Settings::default()
        };
        let st = render(&pack::pack(&s, &settings).unwrap()).stats;
        st.reflect + st.refract
    };
    let (off, low, high) = (count(0.0), count(1.0 / 256.0), count(0.2));
    assert!(off > low && low > high, "{off} {low} {high}");
}

/// Beer–Lambert: light through an absorbing slab falls as exp(−σ d).
#[test]
fn absorption_follows_beer_lambert() {
    let cam = Camera {
        from: v(0.0, 0.0, 10.0),
        at: DVec3::ZERO,
        up: v(0.0, 1.0, 0.0),
        fov: 1.0,
        width: 3,
        height: 3,
    };
    let glass = |sigma: f64| Material {
        name: "g".into(),
        ka: DVec3::ZERO,
        kd: DVec3::ZERO,
        kt: DVec3::ONE,
        ior: 1.0,
        absorption: DVec3::splat(sigma),
        ..Material::default()
    };
    let mut out = Vec::new();
    for sigma in [0.0, 0.5] {
        let mut s = scene(
            cam.clone(),
            vec![Object {
                shape: Shape::Box {
                    min: v(-1.0, -1.0, -1.0),
                    max: v(1.0, 1.0, 1.0),
                },
                material: 0,
            }],
            vec![glass(sigma)],
            vec![],
        );
        s.background = DVec3::ONE;
        let f = render(&pack::pack(&s, &Settings::default()).unwrap());
        out.push(px(&f, 1, 1)[0]);
    }
    assert!((out[0] - 1.0).abs() < 1e-5, "{}", out[0]);
    let want = (-0.5f32 * 2.0).exp();
    assert!((out[1] - want).abs() < 1e-3, "{} vs {want}", out[1]);
}

/// Shadow feelers: a transparent blocker dims the light by its k_t, an
/// opaque one blocks it.
#[test]
fn shadows_dim_through_glass_and_stop_at_stone() {
    let cam = Camera {
        from: v(0.0, 0.0, 10.0),
        at: DVec3::ZERO,
        up: v(0.0, 1.0, 0.0),
        fov: 1.0,
        width: 1,
        height: 1,
    };
    let floor = Material {
        name: "f".into(),
        ka: DVec3::ZERO,
        kd: DVec3::ONE,
        ..Material::default()
    };
    let blocker = |kt: f64| Material {
        name: "b".into(),
        kt: DVec3::splat(kt),
        ..Material::default()
    };
    let mut got = Vec::new();
    for kt in [0.0, 0.25, 1.0] {
        let s = scene(
            cam.clone(),
            vec![
                Object {
                    shape: Shape::Plane {
                        point: DVec3::ZERO,
                        normal: v(0.0, 0.0, 1.0),
                    },
                    material: 0,
                },
                // a small blocker between the floor point and the light, off the eye ray
                Object {
                    shape: Shape::Sphere {
                        center: v(2.0, 0.0, 2.0),
                        radius: 0.5,
                    },
                    material: 1,
                },
            ],
            vec![floor.clone(), blocker(kt)],
            vec![Light {
                position: v(4.0, 0.0, 4.0),
                color: DVec3::ONE,
                falloff: [1.0, 0.0, 0.0],
            }],
        );
        let f = render(
            &pack::pack(
                &s,
                &Settings {
                    max_depth: 0,
                    ..Settings::default()
                },
            )
            .unwrap(),
        );
        got.push(px(&f, 0, 0)[0]);
    }
    let lit = (0.5f32).sqrt(); // N·L for the light at 45°
    assert!(got[0].abs() < 1e-6, "{got:?}");
    assert!((got[1] - 0.25 * lit).abs() < 1e-4, "{got:?}");
    assert!((got[2] - lit).abs() < 1e-4, "{got:?}");
}

/// Where the camera looks does not move secondary rays: the surface offset
/// follows the scene's extent and distance, not |at - from| (a far `at`
/// once pushed every shadow and reflection ray 20 units off a 2-unit scene).
#[test]
fn a_far_look_at_point_changes_nothing() {
    let objects = vec![
        Object {
            shape: Shape::Sphere {
                center: v(0.0, 0.0, 1.0),
                radius: 1.0,
            },
            material: 1,
        },
        Object {
            shape: Shape::Polygon {
                vertices: vec![
                    v(-3.0, -3.0, 0.0),
                    v(3.0, -3.0, 0.0),
                    v(3.0, 3.0, 0.0),
                    v(-3.0, 3.0, 0.0),
                ],
            },
            material: 0,
        },
    ];
    let mirror = Material {
        kr: DVec3::splat(0.5),
        ..Material::default()
    };
    let light = Light {
        position: v(4.0, -4.0, 8.0),
        color: DVec3::ONE,
        falloff: [1.0, 0.0, 0.0],
    };
    let frame_for = |at_distance: f64| {
        let from = v(0.0, -8.0, 3.0);
        let dir = (v(0.0, 0.0, 0.5) - from).normalize();
        let cam = Camera {
            from,
            at: from + dir * at_distance,
            up: DVec3::Z,
            fov: 40.0,
            width: 48,
            height: 36,
        };
        let s = scene(
            cam,
            objects.clone(),
            vec![Material::default(), mirror.clone()],
            vec![light.clone()],
        );
        render(&pack::pack(&s, &Settings::default()).unwrap())
    };
    let near = frame_for(8.0);
    let far = frame_for(1.0e6);
    let worst = near
        .pixels
        .iter()
        .zip(&far.pixels)
        .flat_map(|(a, b)| (0..3).map(move |i| (a[i] - b[i]).abs()))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "largest difference {worst}");
    assert_eq!(near.stats.shadow, far.stats.shadow);
}

/// `--shadows lightbuffer` renders every bundled scene and the SPD's gears
/// (transparent gears: products of several k_t) and rings bit for bit as
/// plain shadow feelers do, with the same ray counts, under both
/// structures.
#[test]
fn light_buffers_render_every_scene_bit_for_bit() {
    use whitted::pack::{Accel, Shadows};
    let mut scenes: Vec<(String, Scene)> =
        std::fs::read_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .map(|p| (p.display().to_string(), scene::load(&p).unwrap()))
            .collect();
    assert!(scenes.len() >= 3);
    for s in [
        whitted::gen::spd::SpdScene::Gears,
        whitted::gen::spd::SpdScene::Rings,
    ] {
        scenes.push((
            format!("{s}"),
            whitted::gen::spd::generate(s, Some(2)).unwrap(),
        ));
    }
    for (name, sc) in &scenes {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            let settings = |shadows| Settings {
                width: Some(64),
                height: Some(48),
                accel,
                shadows,
                ..Settings::default()
            };
            let plain = pack::pack(sc, &settings(Shadows::Plain)).unwrap();
            let lb = pack::pack(sc, &settings(Shadows::LightBuffer)).unwrap();
            assert_eq!(plain.globals.flags[3], 0);
            assert!(lb.globals.flags[3] > 0, "{name}: no light buffer");
            let a = cpu::render(&plain, &|_, _| {});
            let b = cpu::render(&lb, &|_, _| {});
            assert_eq!(a.stats, b.stats, "{name} {accel:?}");
            let differ = a
                .pixels
                .iter()
                .zip(&b.pixels)
                .filter(|(x, y)| x != y)
                .count();
            assert_eq!(differ, 0, "{name} {accel:?}: {differ} pixels differ");
        }
    }
}

/// The work counters split by the kind of ray that asked (`Work::eye`,
/// `Work::shadow`, what is left being the reflected and refracted rays'),
/// and the deepest walk stack (`Work::stack`), on SPD balls (reflective
/// spheres over a plane, three lights) under the BVH and the grid:
/// - the eye share is the work of the eye rays' closest hits, counted
///   here ray by ray through `closest_hit` (corner sampling: the
///   (W+1)×(H+1) lattice's rays from the camera);
/// - without secondary rays (max depth 0) the eye and feeler shares make
///   the totals; with them the eye share is unchanged and the rest grows;
/// - the BVH's walks push (a stack of at least one entry, within the
///   stack's size); the grid keeps no stack.
#[test]
fn work_counters_split_by_kind_of_ray() {
    use whitted::constants::BVH_STACK_SIZE;
    use whitted::pack::Accel;
    use whitted::trace::sample::eye_dir;
    let balls = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Balls, Some(2)).unwrap();
    for accel in [Accel::Bvh, Accel::Grid] {
        let settings = |max_depth: u32| Settings {
            accel,
            width: Some(48),
            height: Some(40),
            max_depth,
            ..pack::Preset::Spd.settings()
        };
        let p0 = pack::pack(&balls, &settings(0)).unwrap();
        let p5 = pack::pack(&balls, &settings(5)).unwrap();
        let (f0, f5) = (cpu::render(&p0, &|_, _| {}), cpu::render(&p5, &|_, _| {}));
        let (w0, w5) = (f0.work, f5.work);

        let s = SceneView::new(&p5);
        let g = &p5.globals;
        let mut direct = Work::default();
        for y in 0..=g.image[1] {
            for x in 0..=g.image[0] {
                let d = eye_dir::<f32>(g, x as f32, y as f32);
                let ray = Ray {
                    o: v3(0.0, 0.0, 0.0),
                    d,
                };
                closest_hit(&s, &ray, &RayPre::new(d, true), f32::INFINITY, &mut direct);
            }
        }
        assert_eq!(f5.stats.eye, u64::from((g.image[0] + 1) * (g.image[1] + 1)));
        assert_eq!(w5.eye, direct.totals(), "{accel:?}: eye share");
        assert_eq!(w0.eye, w5.eye, "{accel:?}: eye share at depth 0 and 5");

        let sum = |a: [u64; 3], b: [u64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
        assert_eq!(sum(w0.eye, w0.shadow), w0.totals(), "{accel:?}: depth 0");
        assert!(w0.shadow[0] > 0, "{accel:?}: no feeler tests");
        assert!(f5.stats.reflect > 0);
        let secondary = w5.tests - w5.eye[0] - w5.shadow[0];
        assert!(secondary > 0, "{accel:?}: no secondary tests: {w5:?}");
        assert!(w5.shadow[0] > w0.shadow[0], "{accel:?}: {w0:?} {w5:?}");
        match accel {
            Accel::Bvh => assert!(
                (1..=BVH_STACK_SIZE).contains(&w5.stack),
                "{accel:?}: stack {}",
                w5.stack
            ),
            _ => assert_eq!(w5.stack, 0, "{accel:?}: stack"),
        }
    }
}
