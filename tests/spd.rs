//! The SPD generators (src/gen/spd/): at their default sizes against the
//! SPD's own NFF files object by object when those are at hand
//! (`WHITTED_SPD_DIR`, else `../shared/scenes/spd` beside the repo), and
//! everywhere against facts recorded from those files (`RECORDED`: kinds
//! and counts, lights, bounds, mean point, radii, camera), the
//! SPD's formulas, determinism, NFF round trips, and that each scene packs
//! and renders.

mod common;

use glam::DVec3;
use std::path::{Path, PathBuf};
use whitted::gen::spd::{self, SpdScene};
use whitted::pack::{self, Settings};
use whitted::scene::{Material, Scene, Shape};

fn spd_dir() -> PathBuf {
    std::env::var_os("WHITTED_SPD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::repo().join("../shared/scenes/spd"))
}

/// NFF prints with `%g`: six significant digits.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 6e-6 * a.abs().max(b.abs()) + 1e-12
}

fn close3(a: DVec3, b: DVec3) -> bool {
    // A coordinate printed as 1e-17 may come out as 0 or -2.6e-17 on the
    // other side; compare against the vector's size too.
    let tol = 6e-6 * a.abs().max(b.abs()).max_element() + 1e-12;
    (a - b).abs().max_element() <= tol
}

fn kind(s: &Shape) -> &'static str {
    match s {
        Shape::Sphere { .. } => "sphere",
        Shape::Polygon { .. } => "polygon",
        Shape::Triangle {
            normals: Some(_), ..
        } => "smooth triangle",
        Shape::Triangle { .. } => "triangle",
        Shape::Cone { .. } => "cone",
        _ => "other",
    }
}

/// Where two shapes differ beyond NFF's precision, if they do.
fn shape_difference(a: &Shape, b: &Shape) -> Option<String> {
    let ok = match (a, b) {
        (
            Shape::Sphere {
                center: c0,
                radius: r0,
            },
            Shape::Sphere {
                center: c1,
                radius: r1,
            },
        ) => close3(*c0, *c1) && close(*r0, *r1),
        (Shape::Polygon { vertices: v0 }, Shape::Polygon { vertices: v1 }) => {
            v0.len() == v1.len() && v0.iter().zip(v1).all(|(p, q)| close3(*p, *q))
        }
        (
            Shape::Triangle {
                vertices: v0,
                normals: n0,
            },
            Shape::Triangle {
                vertices: v1,
                normals: n1,
            },
        ) => {
            v0.iter().zip(v1).all(|(p, q)| close3(*p, *q))
                && match (n0, n1) {
                    (Some(n0), Some(n1)) => n0.iter().zip(n1.iter()).all(|(p, q)| close3(*p, *q)),
                    (None, None) => true,
                    _ => false,
                }
        }
        (
            Shape::Cone {
                base: b0,
                base_radius: r0,
                apex: a0,
                apex_radius: s0,
            },
            Shape::Cone {
                base: b1,
                base_radius: r1,
                apex: a1,
                apex_radius: s1,
            },
        ) => close3(*b0, *b1) && close3(*a0, *a1) && close(*r0, *r1) && close(*s0, *s1),
        _ => false,
    };
    (!ok).then(|| format!("{a:?}\n  vs {b:?}"))
}

fn material_difference(a: &Material, b: &Material) -> Option<String> {
    let ok = close3(a.ka, b.ka)
        && close3(a.kd, b.kd)
        && close(a.ksr, b.ksr)
        && close(a.nr, b.nr)
        && a.kst == b.kst
        && close(a.nt, b.nt)
        && close3(a.kr, b.kr)
        && close3(a.kt, b.kt)
        && close(a.ior, b.ior)
        && a.absorption == b.absorption;
    (!ok).then(|| format!("{a:?}\n  vs {b:?}"))
}

fn bounds(s: &Scene) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = -lo;
    let mut add = |p: DVec3, r: f64| {
        lo = lo.min(p - r);
        hi = hi.max(p + r);
    };
    for o in &s.objects {
        match &o.shape {
            Shape::Sphere { center, radius } => add(*center, *radius),
            Shape::Polygon { vertices } => vertices.iter().for_each(|v| add(*v, 0.0)),
            Shape::Triangle { vertices, .. } => vertices.iter().for_each(|v| add(*v, 0.0)),
            // The end discs lie within their radius of the ends.
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => {
                add(*base, base_radius.abs());
                add(*apex, apex_radius.abs());
            }
            other => panic!("an SPD scene has no {other:?}"),
        }
    }
    (lo, hi)
}

/// Every way `a` (ours) and `b` (the original) differ, at most a few of
/// each kind.
fn differences(a: &Scene, b: &Scene) -> Vec<String> {
    let mut d = Vec::new();
    let (ca, cb) = (&a.camera, &b.camera);
    if !(close3(ca.from, cb.from)
        && close3(ca.at, cb.at)
        && close3(ca.up, cb.up)
        && ca.fov == cb.fov
        && (ca.width, ca.height) == (cb.width, cb.height))
    {
        d.push(format!("camera {ca:?}\n  vs {cb:?}"));
    }
    if !close3(a.background, b.background) || a.ambient != b.ambient {
        d.push("background or ambient light".into());
    }
    if a.lights.len() != b.lights.len() {
        d.push(format!("{} lights vs {}", a.lights.len(), b.lights.len()));
    }
    for (i, (la, lb)) in a.lights.iter().zip(&b.lights).enumerate() {
        if !close3(la.position, lb.position) || la.color != lb.color || la.falloff != lb.falloff {
            d.push(format!("light {i}: {la:?}\n  vs {lb:?}"));
        }
    }
    if a.objects.len() != b.objects.len() {
        d.push(format!(
            "{} objects vs {}",
            a.objects.len(),
            b.objects.len()
        ));
    }
    let mut shown = 0;
    for (i, (oa, ob)) in a.objects.iter().zip(&b.objects).enumerate() {
        let mut why = Vec::new();
        if kind(&oa.shape) != kind(&ob.shape) {
            why.push(format!("{} vs {}", kind(&oa.shape), kind(&ob.shape)));
        } else if let Some(s) = shape_difference(&oa.shape, &ob.shape) {
            why.push(s);
        }
        let (ma, mb) = (
            &a.materials[oa.material as usize],
            &b.materials[ob.material as usize],
        );
        if let Some(m) = material_difference(ma, mb) {
            why.push(m);
        }
        if !why.is_empty() {
            shown += 1;
            if shown <= 5 {
                d.push(format!("object {i}: {}", why.join("; ")));
            }
        }
    }
    if shown > 5 {
        d.push(format!("... {shown} objects differ in all"));
    }
    let ((la, ha), (lb, hb)) = (bounds(a), bounds(b));
    if !close3(la, lb) || !close3(ha, hb) {
        d.push(format!("bounds {la} {ha} vs {lb} {hb}"));
    }
    d
}

/// Needs the SPD's own files, outside the repo: not in the plain suite
/// (which checks the facts recorded from them everywhere:
/// default_sizes_match_the_recorded_originals), run by scripts/test.sh
/// with `--ignored` where the folder exists, and failing when a file is
/// absent rather than passing.
#[test]
#[ignore = "needs the SPD's NFF files (WHITTED_SPD_DIR or ../shared/scenes/spd); scripts/test.sh runs it where they are"]
fn default_sizes_match_the_spds_files() {
    let dir = spd_dir();
    assert!(
        dir.is_dir(),
        "{} is absent: set WHITTED_SPD_DIR to the SPD's NFF files",
        dir.display()
    );
    let mut failures = Vec::new();
    for s in SpdScene::ALL {
        let path = dir.join(format!("{s}.nff"));
        assert!(path.is_file(), "{} is absent", path.display());
        let original = whitted::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let ours = spd::generate(s, None).unwrap();
        let mut d = differences(&ours, &original);
        // The record the test above uses everywhere is the file's.
        if let Some(r) = facts_difference(&facts(&original), &recorded(s)) {
            d.push(format!("RECORDED is stale: {r}"));
        }
        println!(
            "{s}: {} objects, {} materials; {}",
            ours.objects.len(),
            ours.materials.len(),
            if d.is_empty() {
                "as the original"
            } else {
                "DIFFERENT"
            }
        );
        if !d.is_empty() {
            failures.push(format!("{s}:\n{}", d.join("\n")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

fn count_kinds(s: &Scene) -> std::collections::BTreeMap<&'static str, u64> {
    let mut m = std::collections::BTreeMap::new();
    for o in &s.objects {
        *m.entry(kind(&o.shape)).or_insert(0) += 1;
    }
    m
}

#[test]
fn counts_follow_the_spds_formulas() {
    for s in SpdScene::ALL {
        for size in [1, 2, 3, s.default_size()] {
            let scene = spd::generate(s, Some(size)).unwrap();
            let n = size as u64;
            let k = count_kinds(&scene);
            let get = |name| k.get(name).copied().unwrap_or(0);
            assert_eq!(
                Some(scene.objects.len() as u64),
                s.primitive_count(size),
                "{s} at size {size}: {k:?}"
            );
            let (spheres, polygons, smooth, cones) = match s {
                SpdScene::Balls => ((9u64.pow(size + 1) - 1) / 8, 1, 0, 0),
                SpdScene::Gears => (0, 146 * n * n * n + 1, 0, 0),
                SpdScene::Mount => (4, 2 * 4u64.pow(size), 0, 0),
                SpdScene::Rings => {
                    let c = 5 * n * (n + 1) * (2 * n + 1);
                    (c, 1, 0, c)
                }
                SpdScene::Teapot if size == 1 => (0, 1, 52, 0),
                SpdScene::Teapot => (0, n * n, 64 * n * n - 8 * n, 0),
                SpdScene::Tetra => (0, 4u64.pow(size), 0, 0),
                SpdScene::Tree => {
                    let c = 2u64.pow(size + 1) - 1;
                    (c, 1, 0, c)
                }
            };
            assert_eq!(
                (
                    get("sphere"),
                    get("polygon"),
                    get("smooth triangle"),
                    get("cone")
                ),
                (spheres, polygons, smooth, cones),
                "{s} at size {size}"
            );
            assert_eq!(scene.lights.len(), [3, 5, 1, 3, 2, 1, 7][s as usize], "{s}");
        }
    }
}

#[test]
fn generators_are_deterministic_and_size_changes_the_scene() {
    for s in SpdScene::ALL {
        let a = spd::generate(s, Some(2)).unwrap();
        assert_eq!(a, spd::generate(s, Some(2)).unwrap(), "{s}");
        assert_ne!(a.objects, spd::generate(s, Some(3)).unwrap().objects, "{s}");
    }
}

/// What each scene's description promises about where things are.
#[test]
fn bounds_are_where_the_spd_puts_them() {
    let within = |(lo, hi): (DVec3, DVec3), l: [f64; 3], h: [f64; 3]| {
        lo.cmpge(DVec3::from(l) - 1e-9).all() && hi.cmple(DVec3::from(h) + 1e-9).all()
    };
    for size in [1, 2, 3] {
        let b = |s| {
            let mut scene = spd::generate(s, Some(size)).unwrap();
            // Leave out the floor, wall or field: its own bounds are below.
            if !matches!(s, SpdScene::Mount | SpdScene::Tetra | SpdScene::Teapot) {
                scene.objects.remove(0);
            }
            bounds(&scene)
        };
        // The sphereflake grows out of a sphere of radius 1/2 but never
        // leaves the unit sphere (radius 1: the enclosing sphere).
        let balls = b(SpdScene::Balls);
        assert!(within(balls, [-1.0; 3], [1.0; 3]), "{balls:?}");
        assert!(close(balls.0.z, -0.5), "{balls:?}");
        // Gears: in the unit square, between heights 0 and 1.
        let gears = b(SpdScene::Gears);
        assert!(
            within(gears, [-1.0, -1.0, 0.0], [1.0, 1.0, 1.0]),
            "{gears:?}"
        );
        assert!(close(gears.1.z, 1.0), "{gears:?}");
        // Mountain: over [-1, 1]² exactly; the spheres' tops at
        // 1 + 0.17 + 0.17·√1.5.
        let mut mount = spd::generate(SpdScene::Mount, Some(size)).unwrap();
        let all = bounds(&mount);
        assert!(close(all.1.z, 1.17 + 0.17 * 1.5f64.sqrt()), "{all:?}");
        mount.objects.drain(..4);
        let m = bounds(&mount);
        assert_eq!((m.0.x, m.0.y, m.1.x, m.1.y), (-1.0, -1.0, 1.0, 1.0));
        // Tetra: the cube [-1, 1]³ exactly.
        assert_eq!(b(SpdScene::Tetra), (DVec3::splat(-1.0), DVec3::splat(1.0)));
        // Teapot: the board is [-4, 4]² at z = 0; the lid's knob at 3.15.
        let teapot = b(SpdScene::Teapot);
        assert_eq!((teapot.0.x, teapot.1.y, teapot.0.z), (-4.0, 4.0, 0.0));
        assert!(close(teapot.1.z, 3.15), "{teapot:?}");
        // Tree: its trunk of radius 0.15 stands on the origin.
        let tree = b(SpdScene::Tree);
        assert!(close(tree.0.z, -0.15) && tree.1.z > 1.0, "{tree:?}");
        // Rings: layer k is y_diff·k deep, y_diff = 1/sin(π/8).
        let rings = b(SpdScene::Rings);
        let y_diff = 1.0 / (std::f64::consts::PI / 8.0).sin();
        assert!(
            rings.1.y > y_diff * size as f64 && rings.1.y < y_diff * size as f64 + 1.0,
            "{rings:?}"
        );
    }
}

#[test]
fn nff_round_trip_keeps_every_primitive() {
    // Size 1 too: the teapot there had four zero-area triangles, which
    // the reader refused (found seeding the fuzz targets).
    for (s, size) in SpdScene::ALL.into_iter().flat_map(|s| [(s, 1), (s, 2)]) {
        let a = spd::generate(s, Some(size)).unwrap();
        let text = whitted::export::to_nff(&a).unwrap_or_else(|e| panic!("{s} {size}: {e}"));
        let b = whitted::scene::parse_str(&text, Path::new("spd.nff"))
            .unwrap_or_else(|e| panic!("{s} {size}: {e}"));
        // Shapes come back exactly (Rust prints the shortest exact form);
        // materials within a rounding (NFF splits k_d·colour in two).
        assert_eq!(a.objects.len(), b.objects.len(), "{s} {size}");
        for (oa, ob) in a.objects.iter().zip(&b.objects) {
            assert_eq!(oa.shape, ob.shape, "{s} {size}");
        }
        assert_eq!(differences(&a, &b), Vec::<String>::new(), "{s} {size}");
    }
}

#[test]
fn every_scene_packs_and_renders() {
    for s in SpdScene::ALL {
        let scene = spd::generate(s, Some(2)).unwrap();
        let p = pack::pack(&scene, &common::small(12, 12)).unwrap();
        // Every object one primitive, but under the BVH a long opaque
        // cone two (`pack::bvh_pieces`: rings' cylinders, tree's branches).
        let halved = scene
            .objects
            .iter()
            .filter(|o| match &o.shape {
                whitted::scene::Shape::Cone {
                    base,
                    base_radius,
                    apex,
                    apex_radius,
                } => {
                    p.structure() == pack::Accel::Bvh
                        && scene.materials[o.material as usize].kt.max_element() <= 0.0
                        && (*apex - *base).length()
                            >= pack::CONE_SPLIT_RATIO * base_radius.abs().max(apex_radius.abs())
                }
                _ => false,
            })
            .count();
        assert_eq!(p.prims.len(), scene.objects.len() + halved, "{s}");
        if matches!(s, SpdScene::Rings) {
            assert!(halved > 0, "rings: no cone halved");
        }
        let f = whitted::cpu::render(&p, &|_, _| {});
        assert_eq!(f.stats.eye, 144, "{s}");
        assert!(f.stats.eye_hit > 0, "{s}: {:?}", f.stats);
        assert!(
            f.pixels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0),
            "{s}"
        );
        // Something lit and something else: not a blank image.
        let first = f.pixels[0];
        assert!(f.pixels.iter().any(|p| *p != first), "{s}: a flat image");
    }
}

/// The preset's extra reflection rays are traced for the statistics only:
/// the image is the same bit for bit, and only the counts change (on
/// gears, whose transparent gears have k_s = 0).
#[test]
fn spd_counting_changes_counts_not_pixels() {
    let scene = spd::generate(SpdScene::Gears, Some(2)).unwrap();
    let settings = Settings {
        width: Some(40),
        height: Some(40),
        ..pack::Preset::Spd.settings()
    };
    let plain = pack::pack(&scene, &settings).unwrap();
    let mut spd = plain.clone();
    spd.set_counting(pack::Counting::Spd);
    let a = whitted::cpu::render(&plain, &|_, _| {});
    let b = whitted::cpu::render(&spd, &|_, _| {});
    let bits = |f: &whitted::cpu::Frame| -> Vec<u32> {
        f.pixels.iter().flatten().map(|v| v.to_bits()).collect()
    };
    assert!(bits(&a) == bits(&b), "the extra rays changed the image");
    assert_eq!(
        (a.stats.eye, a.stats.eye_hit),
        (b.stats.eye, b.stats.eye_hit)
    );
    assert!(
        b.stats.reflect > a.stats.reflect,
        "{:?} {:?}",
        a.stats,
        b.stats
    );
    assert!(
        b.stats.refract > a.stats.refract,
        "{:?} {:?}",
        a.stats,
        b.stats
    );
    assert!(
        b.stats.shadow > a.stats.shadow,
        "{:?} {:?}",
        a.stats,
        b.stats
    );
}

/// Our counts under the SPD's procedure against its published table, for
/// every scene at the table's size. The SPD expects a classical tracer
/// within about 10 %; ours are within 0.4 % but gears' refracted rays
/// (−3.2 %, docs/spd.md), so 4 % here: a change of what is counted or
/// traced (the transmitter rule, the feelers of weight-0 rays, which are
/// counted without being traced) shows.
#[test]
fn counts_match_the_spds_published_table() {
    for s in SpdScene::ALL {
        let (size, theirs) = s.published_stats();
        let scene = spd::generate(s, Some(size)).unwrap();
        let mut p = pack::pack(&scene, &pack::Preset::Spd.settings()).unwrap();
        p.set_counting(pack::Preset::Spd.counting());
        let f = whitted::cpu::render(&p, &|_, _| {});
        let st = f.stats;
        assert_eq!(st.eye, 513 * 513, "{s}");
        let ours = [st.eye_hit, st.reflect, st.refract, st.shadow];
        for (i, kind) in ["eye hit", "reflect", "refract", "shadow"]
            .iter()
            .enumerate()
        {
            let (o, t) = (ours[i] as f64, theirs[i] as f64);
            let ok = if t == 0.0 {
                o == 0.0
            } else {
                (o - t).abs() <= 0.04 * t
            };
            assert!(ok, "{s} ({size}): {kind} rays {o} against the SPD's {t}");
        }
    }
}

/// What the SPD's own files say of each scene at default size, recorded
/// from `../shared/scenes/spd/*.nff` (`default_sizes_match_the_spds_files`
/// checks the record against them where they are at hand), so that every
/// clone checks the generators against the originals, not only against
/// the SPD's formulas.
struct Facts {
    kinds: Vec<(&'static str, u64)>,
    lights: usize,
    /// Bounds lo, hi; the mean of the points (centres, vertices, cone
    /// ends); the sum of the sphere radii; camera from, at; fov.
    nums: Vec<f64>,
}

fn facts(s: &Scene) -> Facts {
    let (lo, hi) = bounds(s);
    let mut sum = DVec3::ZERO;
    let mut n = 0.0;
    let mut radii = 0.0;
    let mut add = |p: DVec3| {
        sum += p;
        n += 1.0;
    };
    for o in &s.objects {
        match &o.shape {
            Shape::Sphere { center, radius } => {
                add(*center);
                radii += radius;
            }
            Shape::Polygon { vertices } => vertices.iter().for_each(|v| add(*v)),
            Shape::Triangle { vertices, .. } => vertices.iter().for_each(|v| add(*v)),
            Shape::Cone { base, apex, .. } => {
                add(*base);
                add(*apex);
            }
            other => panic!("an SPD scene has no {other:?}"),
        }
    }
    let mean = sum / n;
    let c = &s.camera;
    let mut nums = Vec::new();
    for v in [lo, hi, mean] {
        nums.extend(v.to_array());
    }
    nums.push(radii);
    nums.extend(c.from.to_array());
    nums.extend(c.at.to_array());
    nums.push(c.fov);
    Facts {
        kinds: count_kinds(s).into_iter().collect(),
        lights: s.lights.len(),
        nums,
    }
}

/// Where `a` differs from the record `b` beyond NFF's six digits.
fn facts_difference(a: &Facts, b: &Facts) -> Option<String> {
    let scale = b.nums[..6].iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let near = |x: f64, y: f64| (x - y).abs() <= 1e-5 * x.abs().max(y.abs()) + 1e-6 * scale;
    let ok = a.kinds == b.kinds
        && a.lights == b.lights
        && a.nums.len() == b.nums.len()
        && a.nums.iter().zip(&b.nums).all(|(x, y)| near(*x, *y));
    (!ok).then(|| {
        format!(
            "{:?} {} lights {:?}\n  vs {:?} {} lights {:?}",
            a.kinds, a.lights, a.nums, b.kinds, b.lights, b.nums
        )
    })
}

type Record = (
    SpdScene,
    &'static [(&'static str, u64)],
    usize,
    &'static [f64],
);

/// `facts` of the SPD's files at default size (kinds, lights, then the
/// numbers of `Facts::nums`).
const RECORDED: [Record; 7] = [
    (
        SpdScene::Balls,
        &[("polygon", 1), ("sphere", 7381)],
        3,
        &[
            -12.0,
            -12.0,
            -0.5,
            12.0,
            12.0,
            0.8305668399999999,
            1.630602209076145e-9,
            4.067974709393187e-9,
            0.19907423881110373,
            60.49999633999474,
            2.1,
            1.3,
            1.7,
            0.0,
            0.0,
            0.0,
            45.0,
        ],
    ),
    (
        SpdScene::Gears,
        &[("polygon", 9345)],
        5,
        &[
            -2.0,
            -2.0,
            0.0,
            2.0,
            2.0,
            1.0,
            -1.6109275858213845e-17,
            -1.1302592376192958e-16,
            0.5749584086803707,
            0.0,
            -1.1,
            -2.1,
            2.6,
            0.0,
            0.0,
            0.0,
            45.0,
        ],
    ),
    (
        SpdScene::Mount,
        &[("polygon", 8192), ("sphere", 4)],
        1,
        &[
            -1.15961,
            -1.0,
            -0.702953,
            1.0,
            1.15961,
            1.37821,
            -0.00013018714401952068,
            0.00013018714401952068,
            0.19889075087357636,
            0.68,
            -1.6,
            1.6,
            1.7,
            0.0,
            0.0,
            0.0,
            45.0,
        ],
    ),
    (
        SpdScene::Rings,
        &[("cone", 4200), ("polygon", 1), ("sphere", 4200)],
        3,
        &[
            -10.8389,
            1.65358,
            -9.33895,
            8.83895,
            20.905,
            10.3389,
            -0.0003173516344010531,
            14.63550072437356,
            0.00015867185020621214,
            311.3039999999789,
            -1.0,
            -2.61313,
            0.5,
            -1.0,
            -1.61313,
            0.5,
            45.0,
        ],
    ),
    (
        SpdScene::Teapot,
        &[("polygon", 36), ("smooth triangle", 2256)],
        2,
        &[
            -4.0,
            -4.0,
            0.0,
            4.0,
            4.0,
            3.15,
            0.03719077256944434,
            -1.758816857587596e-17,
            1.692389192361124,
            0.0,
            4.86,
            7.2,
            5.4,
            0.0,
            0.0,
            0.0,
            45.0,
        ],
    ),
    (
        SpdScene::Tetra,
        &[("polygon", 4096)],
        1,
        &[
            -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.02285, -3.17715, -2.17451,
            -0.004103, -0.004103, 0.216539, 45.0,
        ],
    ),
    (
        SpdScene::Tree,
        &[("cone", 4095), ("polygon", 1), ("sphere", 4095)],
        7,
        &[
            -50.0,
            -50.0,
            -0.15,
            50.0,
            50.0,
            3.13748741,
            0.18969300637086248,
            0.2018556041410043,
            2.4525154300593845,
            9.611477120000234,
            4.5,
            0.4,
            2.0,
            0.0,
            0.0,
            1.5,
            45.0,
        ],
    ),
];

fn recorded(s: SpdScene) -> Facts {
    let r = RECORDED.iter().find(|r| r.0 == s).unwrap();
    Facts {
        kinds: r.1.to_vec(),
        lights: r.2,
        nums: r.3.to_vec(),
    }
}

/// Every clone: each generator at default size has the kinds and counts,
/// lights, bounds, mean point, sphere radii and camera of the
/// SPD's own file, as recorded in `RECORDED`.
#[test]
fn default_sizes_match_the_recorded_originals() {
    let mut failures = Vec::new();
    for s in SpdScene::ALL {
        let ours = facts(&spd::generate(s, None).unwrap());
        if let Some(d) = facts_difference(&ours, &recorded(s)) {
            failures.push(format!("{s}: {d}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
