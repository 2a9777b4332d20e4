//! The acceleration structures against brute force and against each
//! other (docs/method.md, "Bounding-volume hierarchy"): on random scenes
//! of spheres, triangles, boxes and cones in opaque and transparent
//! materials, both queries of both structures equal the test of every
//! primitive, the two structures render the same image, and the shadow
//! cache changes no answer.
//!
//! Tolerance: none. Every comparison is exact, because both structures
//! hand the same primitives to the same intersection routine with the same
//! `tmax` semantics, so the nearest hit is the same f32 distance; the
//! transmittance is a product whose order is the structure's, so the
//! transparent materials' k_t here are powers of two (products exact in
//! any order). Two primitives hit at exactly the same f32 distance
//! (coincident surfaces, or two surfaces meeting where the ray crosses
//! them) resolve to the one of lower rank (`trace::query::rank`) on every
//! structure, so the tests compare the primitive found, not only its
//! distance, and images bit for bit; scenes of coincident copies check
//! the ties themselves.

mod common;

use glam::DVec3;
use proptest::prelude::*;
use whitted::constants::SHADOW_CACHE_LEVELS;
use whitted::pack::octree::Walk;
use whitted::pack::{self, Accel, Packed, Settings, Shadows};
use whitted::scene::{Light, Object, Scene, Shape};
use whitted::trace::accel::{closest_hit, closest_hit_brute, transmittance, transmittance_brute};
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{v3, Ray, V3};
use whitted::trace::query::Work;
use whitted::trace::SceneView;

use common::{v, Rng};

/// `count` random primitives in [−5, 5]³ (clustered when `clustered`: a
/// few dense clumps, the case the BVH is for), a floor polygon, and four
/// materials: matte, mirror, and glass of k_t 0.5 and 0.25.
fn random_scene(seed: u64, count: usize, clustered: bool) -> Scene {
    let mut r = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let centres: Vec<DVec3> = (0..4)
        .map(|_| v(r.f() * 8.0 - 4.0, r.f() * 8.0 - 4.0, r.f() * 8.0 - 4.0))
        .collect();
    let mut objects = vec![Object {
        shape: Shape::Polygon {
            vertices: vec![
                v(-30.0, -30.0, -6.0),
                v(30.0, -30.0, -6.0),
                v(30.0, 30.0, -6.0),
                v(-30.0, 30.0, -6.0),
            ],
        },
        material: 1,
    }];
    for i in 0..count {
        let c = if clustered {
            centres[i % 4] + v(r.f() - 0.5, r.f() - 0.5, r.f() - 0.5) * 1.5
        } else {
            v(r.f() * 10.0 - 5.0, r.f() * 10.0 - 5.0, r.f() * 10.0 - 5.0)
        };
        let s = if clustered { 0.3 } else { 1.0 };
        let shape = match i % 5 {
            0 | 1 => Shape::Sphere {
                center: c,
                radius: (0.05 + r.f() * 0.8) * s,
            },
            2 => Shape::Triangle {
                vertices: [
                    c,
                    c + v(r.f(), r.f(), 0.0) * s,
                    c + v(0.0, r.f(), r.f() + 0.1) * s,
                ],
                normals: None,
            },
            3 => Shape::Box {
                min: c,
                max: c + v(r.f() + 0.01, r.f() + 0.01, r.f() + 0.01) * s,
            },
            _ => Shape::Cone {
                base: c,
                base_radius: 0.2 * s,
                apex: c + v(r.f() - 0.5, r.f() - 0.5, r.f() + 0.2) * s,
                apex_radius: 0.05 * s,
            },
        };
        objects.push(Object {
            shape,
            material: (i % 4) as u32,
        });
    }
    common::random_scene_frame(24, 18, [DVec3::splat(0.5), DVec3::splat(0.25)], objects)
}

fn pack_with(s: &Scene, accel: Accel) -> Packed {
    let p = pack::pack(
        s,
        &Settings {
            accel,
            ..Settings::default()
        },
    )
    .unwrap();
    assert_eq!(p.structure(), accel);
    p
}

type RaySpec = ([f32; 3], [f32; 3], f32);

fn ray_of((o, d, _): &RaySpec) -> Option<(Ray<f32>, RayPre<f32>)> {
    let d = v3(d[0], d[1], d[2]);
    if d.length() < 1e-3 {
        return None;
    }
    let d = d.normalize();
    Some((
        Ray {
            o: v3(o[0], o[1], o[2]),
            d,
        },
        RayPre::new(d, true),
    ))
}

/// Both queries of the packed scene's structure against brute force.
fn check_against_brute(p: &Packed, rays: &[RaySpec]) -> Result<(), TestCaseError> {
    let s = SceneView::new(p);
    for spec in rays {
        let Some((ray, pre)) = ray_of(spec) else {
            continue;
        };
        let mut work = Work::default();
        let a = closest_hit(&s, &ray, &pre, f32::INFINITY, &mut work);
        let b = closest_hit_brute(&s, &ray, &pre, f32::INFINITY);
        // Each primitive is tested at most once per ray (the octree's
        // walk may test one once per leaf listing it).
        let most = if p.structure() == Accel::Octree {
            p.prims.len() + p.refs.len()
        } else {
            p.prims.len()
        };
        prop_assert!(work.tests <= most as u64);
        // The same distance and the same primitive: under the BVH a
        // halved cone is two identical copies (`pack::bvh_pieces`), either
        // of which may be the one found.
        prop_assert_eq!(
            a.map(|h| (h.0.t, p.prims[h.1 as usize])),
            b.map(|h| (h.0.t, p.prims[h.1 as usize])),
            "{:?}",
            p.structure()
        );
        let dist = spec.2;
        let mut work = Work::default();
        let ta = transmittance(&s, &ray, &pre, dist, usize::MAX, &mut work);
        let tb = transmittance_brute(&s, &ray, &pre, dist);
        prop_assert_eq!(ta, tb, "{:?}: feeler of length {}", p.structure(), dist);
    }
    Ok(())
}

fn ray_strategy() -> impl Strategy<Value = Vec<RaySpec>> {
    prop::collection::vec(
        (
            prop::array::uniform3(-12.0f32..12.0),
            prop::array::uniform3(-1.0f32..1.0),
            0.1f32..30.0,
        ),
        48,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The BVH's closest hit and transmittance equal brute force over
    /// every primitive, for random scenes (uniform and clustered) and
    /// random rays from outside and inside, and test each primitive at
    /// most once.
    #[test]
    fn bvh_queries_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        rays in ray_strategy(),
    ) {
        let s = random_scene(seed, count, clustered);
        check_against_brute(&pack_with(&s, Accel::Bvh), &rays)?;
    }

    /// The same for the grid (its closest hit has its own proptest in
    /// tests/render.rs; this adds the shadow query and the cones).
    #[test]
    fn grid_queries_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        rays in ray_strategy(),
    ) {
        let s = random_scene(seed, count, clustered);
        check_against_brute(&pack_with(&s, Accel::Grid), &rays)?;
    }

    /// The same for the octree, shallow and deep (a leaf of one primitive
    /// lists many that cross it, and transparent blockers are listed in
    /// many leaves: each must multiply a feeler's light once).
    #[test]
    fn octree_queries_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        max_leaf in 1u32..12,
        max_levels in 0u32..14,
        stack: bool,
        rays in ray_strategy(),
    ) {
        let s = random_scene(seed, count, clustered);
        let p = pack_octree(&s, max_leaf, max_levels, walk(stack));
        check_against_brute(&p, &rays)?;
    }

    /// The same for the hybrid, every crowded cell's BVH walked with the
    /// grid's skip of what the previous cell listed (a cell of more than
    /// `cell` primitives holds a BVH; 1: nearly every cell).
    #[test]
    fn hybrid_queries_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        cell in 1u32..12,
        fine: bool,
        rays in ray_strategy(),
    ) {
        let s = random_scene(seed, count, clustered);
        // Its own coarse top grid, or the plain grid's resolution (cells
        // crossed by many rays, primitives in several cells).
        let grid = fine.then(|| {
            let g = pack_with(&s, Accel::Grid).globals.grid_dims;
            [g[0], g[1], g[2]]
        });
        let p = pack::pack(&s, &Settings { accel: Accel::Hybrid, hybrid_cell: cell, grid, ..Settings::default() }).unwrap();
        prop_assert_eq!(p.structure(), Accel::Hybrid);
        check_against_brute(&p, &rays)?;
    }
}

fn pack_hybrid(s: &Scene, cell: u32) -> Packed {
    let p = pack::pack(
        s,
        &Settings {
            accel: Accel::Hybrid,
            hybrid_cell: cell,
            ..Settings::default()
        },
    )
    .unwrap();
    assert_eq!(p.structure(), Accel::Hybrid);
    p
}

fn walk(stack: bool) -> Walk {
    if stack {
        Walk::Stack
    } else {
        Walk::Neighbour
    }
}

fn pack_octree(s: &Scene, max_leaf: u32, max_levels: u32, walk: Walk) -> Packed {
    let p = pack::pack(
        s,
        &Settings {
            accel: Accel::Octree,
            octree: whitted::pack::octree::Params {
                max_leaf,
                max_levels,
                walk,
            },
            ..Settings::default()
        },
    )
    .unwrap();
    assert_eq!(p.structure(), Accel::Octree);
    p
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Grid, BVH, octree and hybrid render the same image, bit for bit,
    /// with the same ray counts: the same closest hits, the same
    /// transmittances.
    #[test]
    fn every_structure_renders_the_same_image(
        seed in 0u64..1000,
        count in 1usize..400,
        clustered: bool,
    ) {
        let s = random_scene(seed, count, clustered);
        let g = whitted::cpu::render(&pack_with(&s, Accel::Grid), &|_, _| {});
        prop_assert!(g.stats.eye_hit > 0);
        let others = [
            pack_with(&s, Accel::Bvh),
            pack_with(&s, Accel::Octree),
            pack_octree(&s, 4, 10, Walk::Stack),
            pack_with(&s, Accel::Hybrid),
            pack_hybrid(&s, 1),
        ];
        for p in &others {
            let b = whitted::cpu::render(p, &|_, _| {});
            prop_assert_eq!(g.stats, b.stats);
            let differ = g.pixels.iter().zip(&b.pixels).filter(|(x, y)| x != y).count();
            prop_assert_eq!(differ, 0, "{:?} {:?}: {} of {} pixels differ", p.structure(), p.globals.flags[2], differ, g.pixels.len());
        }
    }
}

/// Long opaque cones (SPD rings' cylinders) go into the BVH as two
/// halves, each a copy of the primitive in its own leaf; glass ones and
/// short ones whole (`pack::bvh_pieces`). Both queries still equal brute
/// force, the copies are identical, and whole-image renders on the grid
/// and the BVH agree bit for bit.
#[test]
fn long_opaque_cones_enter_the_bvh_halved() {
    let mut r = Rng(77);
    let mut objects = Vec::new();
    let mut long_opaque = 0;
    for i in 0..240 {
        let base = v(r.f() * 10.0 - 5.0, r.f() * 10.0 - 5.0, r.f() * 10.0 - 5.0);
        let dir = v(r.f() - 0.5, r.f() - 0.5, r.f() - 0.5).normalize_or(v(0.0, 0.0, 1.0));
        // Lengths 0.3 (short: under 4 radii) and 2.0; materials matte,
        // mirror, glass, glass.
        let len = if i % 3 == 0 { 0.3 } else { 2.0 };
        let material = (i % 4) as u32;
        if len > 1.0 && material < 2 {
            long_opaque += 1;
        }
        objects.push(Object {
            shape: Shape::Cone {
                base,
                base_radius: 0.1,
                apex: base + dir * len,
                apex_radius: if i % 2 == 0 { 0.1 } else { 0.05 },
            },
            material,
        });
    }
    let s = common::random_scene_frame(48, 36, [DVec3::splat(0.5), DVec3::splat(0.25)], objects);
    let pb = pack_with(&s, Accel::Bvh);
    let pg = pack_with(&s, Accel::Grid);
    assert!(long_opaque > 50);
    assert_eq!(pg.globals.counts[0], 240);
    assert_eq!(pb.globals.counts[0] as usize, 240 + long_opaque);
    // Every primitive of the grid's packing is in the BVH's, a long
    // opaque cone twice, with its rank.
    for (i, g) in pg.prims[..240].iter().enumerate() {
        let copies = pb
            .prims
            .iter()
            .filter(|b| b.cell_lo == i as u32)
            .collect::<Vec<_>>();
        let halved = g.kind_mat >> 4 < 2 && g.c[0] > 1.0;
        assert_eq!(copies.len(), if halved { 2 } else { 1 }, "primitive {i}");
        for c in copies {
            assert_eq!((c.kind_mat, c.a, c.b, c.c), (g.kind_mat, g.a, g.b, g.c));
        }
    }
    let mut r = Rng(78);
    let rays: Vec<RaySpec> = (0..3000)
        .map(|_| {
            let f = |r: &mut Rng, k: f64| (r.f() * 2.0 - 1.0) as f32 * k as f32;
            (
                [f(&mut r, 8.0), f(&mut r, 8.0), f(&mut r, 8.0)],
                [f(&mut r, 1.0), f(&mut r, 1.0), f(&mut r, 1.0)],
                (r.f() * 20.0) as f32 + 0.1,
            )
        })
        .collect();
    check_against_brute(&pb, &rays).unwrap();
    let gi = whitted::cpu::render(&pg, &|_, _| {});
    let bi = whitted::cpu::render(&pb, &|_, _| {});
    assert!(
        gi.pixels == bi.pixels,
        "the grid and the BVH render differently"
    );
}

/// `random_scene` with every other primitive listed again in the next
/// material: coincident surfaces, every hit on them a tie.
fn scene_with_copies(seed: u64, count: usize, clustered: bool) -> Scene {
    let mut s = random_scene(seed, count, clustered);
    let copies: Vec<Object> = s
        .objects
        .iter()
        .skip(1)
        .step_by(2)
        .map(|o| Object {
            material: (o.material + 1) % 4,
            ..o.clone()
        })
        .collect();
    s.objects.extend(copies);
    s
}

/// Ties (coincident copies in different materials) go to the same
/// primitive on both structures and under brute force: the same hit, the
/// same material, the same image bit for bit. Before ranks settled ties
/// the BVH took whichever copy its leaf listed first, and SPD rings
/// (spheres meeting cylinders) rendered differently on the grid and the
/// BVH at 10 of its 263 169 eye rays.
#[test]
fn ties_go_to_the_same_primitive_on_every_structure() {
    for (seed, clustered) in [(3, false), (4, true), (5, true)] {
        let s = scene_with_copies(seed, 300, clustered);
        let (pg, pb) = (pack_with(&s, Accel::Grid), pack_with(&s, Accel::Bvh));
        let po = pack_with(&s, Accel::Octree);
        let ph = pack_hybrid(&s, 1);
        let (sg, sb, so, sh) = (
            SceneView::new(&pg),
            SceneView::new(&pb),
            SceneView::new(&po),
            SceneView::new(&ph),
        );
        let mut r = Rng(seed * 7919 + 1);
        let (mut hits, mut ties) = (0, 0);
        for _ in 0..4000 {
            let o = v3(r.f() as f32 * 24.0 - 12.0, -20.0, r.f() as f32 * 10.0 - 3.0);
            let at = v3(
                r.f() as f32 * 10.0 - 5.0,
                r.f() as f32 * 10.0 - 5.0,
                r.f() as f32 * 10.0 - 5.0,
            );
            let d = (at - o).normalize();
            let ray = Ray { o, d };
            let pre = RayPre::new(d, true);
            let mut w = Work::default();
            let g = closest_hit(&sg, &ray, &pre, f32::INFINITY, &mut w);
            let b = closest_hit(&sb, &ray, &pre, f32::INFINITY, &mut w);
            // The octree and the hybrid keep the grid's order: the very
            // same answer.
            let key0 =
                |h: Option<(whitted::trace::intersect::Hit<f32>, u32)>| h.map(|h| (h.0.t, h.1));
            assert_eq!(
                key0(closest_hit(&so, &ray, &pre, f32::INFINITY, &mut w)),
                key0(g)
            );
            assert_eq!(
                key0(closest_hit(&sh, &ray, &pre, f32::INFINITY, &mut w)),
                key0(g)
            );
            // Within one packing, the very primitive brute force finds.
            let key =
                |h: Option<(whitted::trace::intersect::Hit<f32>, u32)>| h.map(|h| (h.0.t, h.1));
            assert_eq!(
                key(g),
                key(closest_hit_brute(&sg, &ray, &pre, f32::INFINITY))
            );
            // (Under the BVH, the same primitive up to the copy: a halved
            // cone is two, `pack::bvh_pieces`.)
            let prim_b = |h: Option<(whitted::trace::intersect::Hit<f32>, u32)>| {
                h.map(|h| (h.0.t, pb.prims[h.1 as usize]))
            };
            assert_eq!(
                prim_b(b),
                prim_b(closest_hit_brute(&sb, &ray, &pre, f32::INFINITY))
            );
            // Across packings (the BVH reorders), the same distance and
            // the same primitive: its rank and its material.
            let what = |p: &Packed, h: Option<(whitted::trace::intersect::Hit<f32>, u32)>| {
                h.map(|h| {
                    let prim = &p.prims[h.1 as usize];
                    let rank = if p.structure() == Accel::Bvh {
                        prim.cell_lo
                    } else {
                        h.1
                    };
                    (h.0.t, rank, prim.material())
                })
            };
            assert_eq!(what(&pg, g), what(&pb, b), "seed {seed}");
            if let Some((h, i)) = g {
                hits += 1;
                // A copy of this primitive in another material here too?
                let prim = &pg.prims[i as usize];
                ties += pg
                    .prims
                    .iter()
                    .filter(|q| {
                        q.kind() == prim.kind()
                            && q.a == prim.a
                            && q.b == prim.b
                            && q.c == prim.c
                            && q.material() != prim.material()
                    })
                    .count()
                    .min(1);
                let _ = h;
            }
        }
        assert!(
            hits > 1000 && ties >= 30,
            "seed {seed}: {hits} hits, {ties} on copies"
        );
        let gi = whitted::cpu::render(&pg, &|_, _| {});
        let bi = whitted::cpu::render(&pb, &|_, _| {});
        let differ = gi
            .pixels
            .iter()
            .zip(&bi.pixels)
            .filter(|(x, y)| x != y)
            .count();
        assert_eq!(differ, 0, "seed {seed}: {differ} pixels differ");
    }
}

/// The last-blocker cache changes no transmittance: feelers from a
/// raster of points on the floor to the lights, each answered with the cache its predecessors
/// left (as the tracer does) and with an empty one, on both structures;
/// and it saves work (intersection tests, cells and nodes visited: about
/// a quarter here).
#[test]
fn the_shadow_cache_changes_no_answer() {
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        for seed in 0..6 {
            let s = random_scene(seed, 400, false);
            let p = pack_with(&s, accel);
            let view = SceneView::new(&p);
            let mut cached = Work::default();
            let mut fresh_work = 0;
            let mut blocked = 0;
            // Packed coordinates are relative to the camera.
            let eye = s.camera.from.as_vec3();
            // Points on the floor under the primitives, in raster order
            // (neighbours' feelers meet the same blockers, as a tile's do).
            for k in 0..2 * 40 * 40 {
                let (light, i, j) = (k / 1600, k % 40, k / 40 % 40);
                let o = v3(
                    i as f32 * 0.25 - 5.0 - eye.x,
                    j as f32 * 0.25 - 5.0 - eye.y,
                    -5.9 - eye.z,
                );
                let lv = V3::of(&p.lights[light].pos) - o;
                let dist = lv.length();
                let d = lv / dist;
                let ray = Ray { o, d };
                let pre = RayPre::new(d, true);
                let with = transmittance(&view, &ray, &pre, dist, light, &mut cached);
                let mut fresh = Work::default();
                let without = transmittance(&view, &ray, &pre, dist, light, &mut fresh);
                assert_eq!(with, without, "{accel:?} seed {seed} feeler {k}");
                fresh_work += fresh.tests + fresh.cells + fresh.nodes;
                blocked += (without.max_elem() == 0.0) as u32;
            }
            assert!(blocked > 200, "{accel:?} seed {seed}: {blocked} blocked");
            let with_cache = cached.tests + cached.cells + cached.nodes;
            assert!(
                with_cache < fresh_work,
                "{accel:?} seed {seed}: the cache saved nothing ({with_cache} vs {fresh_work})",
            );
        }
    }
}

/// Each level of the ray tree keeps its own last blocker: a feeler cast
/// from a reflection's hit (level 1) leaves level 0's entry alone, so the
/// next eye hit's feeler still finds its blocker there with one test;
/// depths past the last level share it.
#[test]
fn each_ray_tree_level_keeps_its_own_blocker() {
    let s = random_scene(0, 400, false);
    let p = pack_with(&s, Accel::Bvh);
    let view = SceneView::new(&p);
    let eye = s.camera.from.as_vec3();
    let feeler = |i: usize, j: usize| {
        let o = v3(
            i as f32 * 0.25 - 5.0 - eye.x,
            j as f32 * 0.25 - 5.0 - eye.y,
            -5.9 - eye.z,
        );
        let lv = V3::of(&p.lights[0].pos) - o;
        let d = lv / lv.length();
        (Ray { o, d }, RayPre::new(d, true), lv.length())
    };
    // Two feelers to light 0 blocked by different primitives.
    type Feeler = (Ray<f32>, RayPre<f32>, f32);
    let mut blocked: Vec<(Feeler, u32)> = Vec::new();
    for k in 0..40 * 40 {
        let f = feeler(k % 40, k / 40);
        let mut w = Work::default();
        if transmittance(&view, &f.0, &f.1, f.2, 0, &mut w).max_elem() == 0.0 {
            let blocker = *w.cached(0);
            if blocked.iter().all(|(_, b)| *b != blocker) {
                blocked.push((f, blocker));
            }
        }
    }
    assert!(blocked.len() >= 2, "{} distinct blockers", blocked.len());
    let ((a, a_blocker), (b, b_blocker)) = (&blocked[0], &blocked[1]);
    let mut w = Work::default();
    w.at_depth(0);
    transmittance(&view, &a.0, &a.1, a.2, 0, &mut w);
    w.at_depth(1);
    transmittance(&view, &b.0, &b.1, b.2, 0, &mut w);
    assert_eq!(*w.cached(0), *b_blocker);
    w.at_depth(0);
    assert_eq!(
        *w.cached(0),
        *a_blocker,
        "level 1's feeler evicted level 0's blocker"
    );
    let before = w;
    assert_eq!(transmittance(&view, &a.0, &a.1, a.2, 0, &mut w), V3::zero());
    assert_eq!(
        (w.tests, w.nodes),
        (before.tests + 1, before.nodes),
        "not answered by the cache"
    );
    // The deepest levels share the last cache.
    w.at_depth(SHADOW_CACHE_LEVELS - 1);
    transmittance(&view, &b.0, &b.1, b.2, 0, &mut w);
    w.at_depth(40);
    assert_eq!(*w.cached(0), *b_blocker);
}

/// The BVH does what it is for: on a clustered scene it tests fewer
/// primitives than the grid (a third fewer at least; measured: half).
#[test]
fn the_bvh_tests_fewer_primitives_on_clustered_scenes() {
    let s = random_scene(3, 2000, true);
    let g = whitted::cpu::render(&pack_with(&s, Accel::Grid), &|_, _| {});
    let b = whitted::cpu::render(&pack_with(&s, Accel::Bvh), &|_, _| {});
    assert_eq!(g.pixels, b.pixels);
    assert!(b.work.nodes > 0 && b.work.cells == 0);
    assert!(g.work.cells > 0 && g.work.nodes == 0);
    assert!(
        3 * b.work.tests < 2 * g.work.tests,
        "BVH {} tests, grid {}",
        b.work.tests,
        g.work.tests
    );
}

/// Giants (primitives as large as the scene, kept out of the grid) join
/// the BVH's tree where it holds their kind already (SPD gears: the
/// floor polygon among the gears' polygons) and stay out where they would
/// add one (random spheres on a floor polygon): the GPU's walks compile
/// only the tree's kinds. Every primitive keeps its rank, the index the
/// grid's packing gives it, so ties go alike; the images are the grid's.
#[test]
fn giants_join_the_bvh_only_among_their_own_kinds() {
    use std::collections::HashMap;
    let gears = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Gears, Some(1)).unwrap();
    let spheres = whitted::gen::random_spheres(400, 5);
    for (name, s, joins) in [("gears", &gears, true), ("spheres", &spheres, false)] {
        let settings = |accel| Settings {
            accel,
            width: Some(48),
            height: Some(36),
            ..Settings::default()
        };
        let g = pack::pack(s, &settings(Accel::Grid)).unwrap();
        let b = pack::pack(s, &settings(Accel::Bvh)).unwrap();
        assert_eq!((g.structure(), b.structure()), (Accel::Grid, Accel::Bvh));
        let [gc, bc] = [g.globals.counts, b.globals.counts];
        assert!(gc[0] < gc[1], "{name}: the grid keeps a giant out");
        assert_eq!(bc[0] == bc[1], joins, "{name}: {bc:?}");
        // The BVH keeps each primitive's grid index in cell_lo.
        let key = |p: &whitted::pack::layout::Prim| {
            (
                p.kind_mat,
                p.data,
                p.a.map(f32::to_bits),
                p.b.map(f32::to_bits),
                p.c.map(f32::to_bits),
            )
        };
        let at: HashMap<_, u32> = g
            .prims
            .iter()
            .enumerate()
            .map(|(i, p)| (key(p), i as u32))
            .collect();
        assert_eq!(at.len(), g.prims.len(), "{name}: primitives told apart");
        for p in b.prims.iter() {
            assert_eq!(Some(&p.cell_lo), at.get(&key(p)), "{name}: a rank moved");
        }
        let [gi, bi] = [&g, &b].map(|p| whitted::cpu::render(p, &|_, _| {}));
        assert!(
            gi.pixels == bi.pixels,
            "{name}: the BVH's image is not the grid's"
        );
    }
}

/// Rays parallel to the axes and to the axis planes (components exactly
/// 0, 1/d = ±∞), from lattice points on the primitives' own planes, on a
/// lattice of boxes and spheres: both structures equal brute force.
#[test]
fn axis_parallel_rays_equal_brute_force() {
    let mut objects = Vec::new();
    for i in 0..64 {
        let c = v((i % 4) as f64, (i / 4 % 4) as f64, (i / 16) as f64) * 2.0;
        let shape = if i % 3 == 0 {
            Shape::Sphere {
                center: c,
                radius: 0.5,
            }
        } else {
            Shape::Box {
                min: c,
                max: c + DVec3::ONE,
            }
        };
        objects.push(Object { shape, material: 0 });
    }
    let mut s = random_scene(1, 0, false);
    s.objects = objects;
    s.camera.from = DVec3::ZERO;
    s.camera.at = v(1.0, 1.0, 1.0);
    let mut dirs = Vec::new();
    for d in [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, -1.0],
        [-1.0, 0.0, 1.0],
    ] {
        dirs.push(d);
        dirs.push(d.map(|x: f32| -x));
    }
    let mut rays = Vec::new();
    for k in 0..8 * 8 * 8 {
        let o = [k % 8, k / 8 % 8, k / 64].map(|x| x as f32);
        for d in &dirs {
            rays.push((o, *d, 20.0));
        }
    }
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        check_against_brute(&pack_with(&s, accel), &rays).unwrap();
    }
    // A deep octree too, both walks: its lattice planes through the
    // primitives' own.
    for stack in [false, true] {
        check_against_brute(&pack_octree(&s, 1, 8, walk(stack)), &rays).unwrap();
    }
}

/// Rays from non-finite origins (an infinite or NaN component, as a
/// reflection off a plane hit beyond f32 would start) end, and both
/// structures give the same answer: none. From an infinite origin that is
/// brute force's answer too; from a NaN one brute force may find a box
/// (its slabs take a NaN as inside), which neither walk reaches: such a
/// ray has no meaningful answer. The 4-wide BVH's walk never mistakes an
/// empty lane for a child (∞ − ∞ in the slabs) nor runs off its stack.
#[test]
fn rays_from_non_finite_origins_end_and_meet_nothing() {
    let s = random_scene(3, 300, true);
    let packs = [
        pack_with(&s, Accel::Grid),
        pack_with(&s, Accel::Bvh),
        pack_with(&s, Accel::Octree),
        pack_with(&s, Accel::Hybrid),
    ];
    for o in [
        v3(f32::INFINITY, 0.0, 0.0),
        v3(0.0, f32::NEG_INFINITY, 1.0),
        v3(f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY),
        v3(f32::NAN, 0.0, 0.0),
    ] {
        for d in [v3(-1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(0.6, -0.8, 0.0)] {
            let ray = Ray { o, d };
            let pre = RayPre::new(d, true);
            let mut answers = Vec::new();
            for p in &packs {
                let view = SceneView::new(p);
                let mut work = Work::default();
                let hit = closest_hit(&view, &ray, &pre, f32::INFINITY, &mut work);
                let t = transmittance(&view, &ray, &pre, 10.0, usize::MAX, &mut work);
                assert!(hit.is_none(), "{:?} {o:?} {d:?}", p.structure());
                answers.push(t);
                if !o.x.is_nan() {
                    let b = closest_hit_brute(&view, &ray, &pre, f32::INFINITY);
                    assert!(b.is_none(), "{o:?} {d:?}");
                    assert_eq!(t, transmittance_brute(&view, &ray, &pre, 10.0));
                }
            }
            assert_eq!(answers[0], answers[1], "{o:?} {d:?}");
            assert_eq!(answers[0], answers[2], "{o:?} {d:?}");
        }
    }
}

/// `random_scene` with five more lights: one at a primitive's centre
/// (inside its bounds), one inside a glass sphere added around it, one
/// at the corner of a primitive's bounds, one among the primitives and
/// one far off. Light positions are integers and the camera sits at an
/// integer point, so the packed (camera-relative) positions are exact
/// and feelers can be aimed along exact cube diagonals and cell
/// boundaries.
fn scene_with_lights(seed: u64, count: usize, clustered: bool) -> Scene {
    let mut s = random_scene(seed, count, clustered);
    let light = |p: DVec3| Light {
        position: p,
        color: DVec3::splat(0.3),
        falloff: [1.0, 0.0, 0.0],
    };
    let inside = match s.objects.get(1).map(|o| &o.shape) {
        Some(Shape::Sphere { center, .. }) => center.round(),
        Some(Shape::Box { min, .. }) => min.ceil(),
        _ => v(1.0, 1.0, 1.0),
    };
    s.objects.push(Object {
        shape: Shape::Sphere {
            center: v(-2.0, 3.0, 1.0),
            radius: 1.5,
        },
        material: 2,
    });
    s.lights.extend([
        light(inside),
        light(v(-2.0, 3.0, 1.0)),
        light(v(-1.0, 1.0, 4.0)),
        light(v(0.0, 0.0, 0.0)),
        light(v(40.0, -30.0, 25.0)),
    ]);
    s
}

fn pack_lb(s: &Scene, accel: Accel) -> Packed {
    let p = pack::pack(
        s,
        &Settings {
            accel,
            shadows: Shadows::LightBuffer,
            ..Settings::default()
        },
    )
    .unwrap();
    assert_eq!(p.structure(), accel);
    assert!(p.globals.flags[3] > 0, "no light buffer was built");
    // The offsets, then four window words per light and face.
    assert_eq!(
        p.lb_start.len() as u32,
        p.globals.flags[3].pow(2) * 6 * p.globals.counts[2] + 1 + 24 * p.globals.counts[2]
    );
    p
}

/// Feelers towards each light of a light-buffered scene against brute
/// force: from random points, and from points placed so that the
/// direction from the light lies exactly on a cube diagonal (|x| = |y|,
/// |x| = |y| = |z|) or on a cell boundary of the light buffer.
fn check_feelers(p: &Packed, points: &[[f32; 3]]) -> Result<(), TestCaseError> {
    let s = SceneView::new(p);
    let res = p.globals.flags[3] as i32;
    for (li, l) in p.lights.iter().enumerate() {
        let lp = V3::of(&l.pos);
        let mut origins: Vec<V3<f32>> = points.iter().map(|o| v3(o[0], o[1], o[2])).collect();
        // Diagonals and cell boundaries: c = (a, b, e) with |a| dominant
        // and b = a·(2j/res − 1) exactly (a = res/2·k).
        for k in [1i32, 3] {
            let a = (res / 2 * k) as f32;
            for j in [0, 1, res / 2, res - 1, res] {
                let b = (2 * j - res) as f32 * k as f32 / 2.0;
                for (x, y, z) in [
                    (a, b, b),
                    (a, a, b),
                    (b, a, a),
                    (a, b, -a),
                    (-a, -a, -a),
                    (a, a, a),
                ] {
                    for perm in 0..3 {
                        let c = match perm {
                            0 => v3(x, y, z),
                            1 => v3(z, x, y),
                            _ => v3(y, z, x),
                        };
                        origins.push(lp + c * 0.125);
                        origins.push(lp + c);
                    }
                }
            }
        }
        for o in origins {
            let lv = lp - o;
            let dist = lv.length();
            if dist.is_nan() || dist <= 0.0 {
                continue;
            }
            let d = lv / dist;
            let ray = Ray { o, d };
            let pre = RayPre::new(d, true);
            let mut work = Work::default();
            let ta = transmittance(&s, &ray, &pre, dist, li, &mut work);
            let tb = transmittance_brute(&s, &ray, &pre, dist);
            prop_assert_eq!(ta, tb, "light {} at {:?}, feeler from {:?}", li, lp, o);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Shadow feelers through the light buffers equal brute force, with
    /// either structure (their unbounded primitives and order differ), on
    /// random scenes with lights inside and at the corner of primitives'
    /// bounds.
    #[test]
    fn light_buffer_feelers_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        which in 0usize..4,
        points in prop::collection::vec(prop::array::uniform3(-12.0f32..12.0), 24),
    ) {
        let s = scene_with_lights(seed, count, clustered);
        let accel = [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid][which];
        check_feelers(&pack_lb(&s, accel), &points)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Feelers from just in front of and just behind the spheres'
    /// surfaces (where a cell's depth cut decides between testing a
    /// sphere and stopping before it) equal brute force, towards every
    /// light, the far one included (whose faces' windows are small).
    #[test]
    fn light_buffer_feelers_from_surfaces_equal_brute_force(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        which in 0usize..4,
    ) {
        let s = scene_with_lights(seed, count, clustered);
        let mut points = Vec::new();
        for o in &s.objects {
            if let Shape::Sphere { center, radius } = o.shape {
                for axis in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::NEG_X, DVec3::NEG_Y, DVec3::NEG_Z] {
                    for f in [1.0 - 1e-3, 1.0 - 1e-6, 1.0 + 1e-6, 1.0 + 1e-3] {
                        let p = center + axis * radius * f;
                        points.push([p.x as f32, p.y as f32, p.z as f32]);
                    }
                }
            }
        }
        let accel = [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid][which];
        check_feelers(&pack_lb(&s, accel), &points)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// `--shadows lightbuffer` renders the plain image bit for bit, with
    /// the same ray counts, and tests fewer primitives for its feelers.
    #[test]
    fn light_buffers_render_the_same_image(
        seed in 0u64..1000,
        count in 1usize..400,
        clustered: bool,
        which in 0usize..4,
    ) {
        let s = scene_with_lights(seed, count, clustered);
        let accel = [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid][which];
        let plain = whitted::cpu::render(&pack_with(&s, accel), &|_, _| {});
        let lb = whitted::cpu::render(&pack_lb(&s, accel), &|_, _| {});
        prop_assert!(plain.stats.shadow > 0);
        prop_assert_eq!(plain.stats, lb.stats);
        let differ = plain.pixels.iter().zip(&lb.pixels).filter(|(x, y)| x != y).count();
        prop_assert_eq!(differ, 0, "{} of {} pixels differ", differ, plain.pixels.len());
    }
}

/// The light buffer lists far fewer primitives per feeler than there are
/// (it prunes), and the light inside a primitive's bounds lists that
/// primitive in every cell. Its offsets are followed by four window words
/// per light and face, its references are (primitive, depth) pairs.
#[test]
fn light_buffer_cells_prune() {
    let s = scene_with_lights(7, 600, false);
    let p = pack_lb(&s, Accel::Grid);
    let lights = p.lights.len();
    let cells = p.lb_start.len() - 1 - 24 * lights;
    let res = p.globals.flags[3] as usize;
    assert_eq!(cells, lights * 6 * res * res);
    let refs = p.lb_refs.len() / 2;
    assert_eq!(p.lb_start[cells] as usize, refs);
    let mean = refs as f64 / cells as f64;
    let n = p.globals.counts[0] as f64;
    assert!(mean < n / 4.0, "{mean} refs per cell of {n} primitives");
    assert_eq!(p.lightbuf.cells, cells);
    assert_eq!(p.lightbuf.refs, refs);
}

/// A feeler through glass that the octree lists in many leaves multiplies
/// its light by the glass's k_t once, as brute force does: large glass
/// spheres among a crowd of small opaque ones (which make the leaves
/// small), feelers crossing the glass between them. Without the walk's
/// leaf stretches (`Query::lo`, `hi`) a sphere listed in k leaves the
/// feeler crosses would count k times.
#[test]
fn glass_in_many_leaves_counts_once_per_feeler() {
    let mut s = random_scene(11, 0, false);
    let mut r = Rng(77);
    let mut objects = Vec::new();
    for _ in 0..3000 {
        objects.push(Object {
            shape: Shape::Sphere {
                center: v(r.f() * 20.0 - 10.0, r.f() * 20.0 - 10.0, r.f() * 2.0 + 6.0),
                radius: 0.02,
            },
            material: 0,
        });
    }
    for (k, c) in [v(-4.0, 0.0, 0.0), v(3.0, 2.0, 1.0), v(0.0, -5.0, -2.0)]
        .into_iter()
        .enumerate()
    {
        objects.push(Object {
            shape: Shape::Sphere {
                center: c,
                radius: 2.5,
            },
            material: 2 + (k % 2) as u32,
        });
    }
    s.objects = objects;
    for stack in [false, true] {
        glass_feelers(&s, &pack_octree(&s, 2, 12, walk(stack)));
    }
}

fn glass_feelers(s: &Scene, p: &Packed) {
    assert!(p.accel.leaves > 1000, "{} leaves", p.accel.leaves);
    let view = SceneView::new(p);
    let e = s.camera.from.as_vec3();
    let eye = v3(e.x, e.y, e.z);
    let mut through_glass = 0;
    let mut r = Rng(5);
    for _ in 0..2000 {
        let a = v3(r.f() as f32 * 16.0 - 8.0, r.f() as f32 * 16.0 - 8.0, -5.0) - eye;
        let b = v3(r.f() as f32 * 16.0 - 8.0, r.f() as f32 * 16.0 - 8.0, 5.0) - eye;
        let dist = (b - a).length();
        let d = (b - a) / dist;
        let ray = Ray { o: a, d };
        let pre = RayPre::new(d, true);
        let mut work = Work::default();
        let t = transmittance(&view, &ray, &pre, dist, usize::MAX, &mut work);
        assert_eq!(
            t,
            transmittance_brute(&view, &ray, &pre, dist),
            "{a:?} -> {b:?}"
        );
        if t.x > 0.0 && t.x < 1.0 {
            through_glass += 1;
            // Each glass sphere the feeler crosses was listed in more
            // than one leaf it visited.
            assert!(work.cells > 2, "{work:?}");
        }
    }
    assert!(through_glass > 300, "{through_glass} feelers through glass");
}

/// `random_scene` with only its spheres (`Some(true)`), with none of them
/// (`Some(false)`), or whole (`None`); the floor polygon stays.
fn scene_of_kinds(seed: u64, count: usize, clustered: bool, spheres: Option<bool>) -> Scene {
    let mut s = random_scene(seed, count, clustered);
    if let Some(keep) = spheres {
        s.objects.retain(|o| {
            matches!(o.shape, Shape::Polygon { .. })
                || matches!(o.shape, Shape::Sphere { .. }) == keep
        });
    }
    s
}

/// The plain grid's walk arrays (`pack::grid::Walk`, docs/architecture.md,
/// "The CPU's own arrays") hold what the walk would otherwise read from
/// the primitives' records: per reference the test-once rule for each way
/// into its cell, recomputed here from the primitive's cell range and the
/// cell, and per grid primitive a sphere's first word. Only the plain grid
/// has them.
#[test]
fn the_walk_arrays_hold_the_test_once_rule_and_the_spheres() {
    for (seed, kinds) in [(1, None), (2, Some(true)), (3, Some(false)), (4, None)] {
        let s = scene_of_kinds(seed, 250, seed == 4, kinds);
        let p = pack_with(&s, Accel::Grid);
        assert_eq!(p.walk.bits.len(), p.refs.len());
        assert!(!SceneView::new(&p).walk_bits.is_empty());
        let d = p.globals.grid_dims;
        let cells = (d[0] * d[1] * d[2]) as usize;
        let (mut below, mut above) = (0, 0);
        for c in 0..cells {
            let at = [
                c as u32 % d[0],
                c as u32 / d[0] % d[1],
                c as u32 / (d[0] * d[1]),
            ];
            for k in p.cell_start[c] as usize..p.cell_start[c + 1] as usize {
                let prim = &p.prims[p.refs[k] as usize];
                let lo = whitted::pack::layout::cell_unpack(prim.cell_lo);
                let hi = whitted::pack::layout::cell_unpack(prim.cell_hi);
                let mut want = 0u8;
                for a in 0..3 {
                    assert!(
                        lo[a] <= at[a] && at[a] <= hi[a],
                        "cell {c} lists {k} out of range"
                    );
                    want |= ((at[a] > lo[a]) as u8) << (2 * a);
                    want |= ((at[a] < hi[a]) as u8) << (2 * a + 1);
                }
                assert_eq!(
                    p.walk.bits[k], want,
                    "seed {seed}: reference {k} in cell {at:?}"
                );
                below += (want & 0b01_0101 != 0) as u32;
                above += (want & 0b10_1010 != 0) as u32;
            }
        }
        // Primitives span cells: the rule is not all zeros.
        assert!(below > 0 && above > 0, "seed {seed}: {below} {above}");
        let grid_prims = p.globals.counts[0] as usize;
        if kinds == Some(false) {
            assert!(p.walk.spheres.is_empty());
        } else {
            assert_eq!(p.walk.spheres.len(), grid_prims);
            for (i, (w, prim)) in p.walk.spheres.iter().zip(&p.prims[..]).enumerate() {
                if prim.kind() == whitted::constants::KIND_SPHERE {
                    assert_eq!(*w, prim.a, "sphere {i}");
                } else {
                    assert_eq!(*w, [0.0, 0.0, 0.0, -1.0], "{i} is no sphere");
                }
            }
        }
    }
    let s = random_scene(5, 200, true);
    for accel in [Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        let p = pack_with(&s, accel);
        assert!(
            p.walk.bits.is_empty() && p.walk.spheres.is_empty(),
            "{accel:?}"
        );
        assert!(SceneView::new(&p).walk_bits.is_empty(), "{accel:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The grid's walk with its own arrays and without them (reading the
    /// primitives' records) finds the same hit of the same primitive and
    /// the same transmittance, with the same work counters and the same
    /// shadow cache: the same tests in the same order. Scenes of every
    /// kind, of spheres only and of no spheres.
    #[test]
    fn the_grid_walks_the_same_with_and_without_its_arrays(
        seed in 0u64..1000,
        count in 1usize..300,
        clustered: bool,
        kinds in prop::option::of(any::<bool>()),
        rays in ray_strategy(),
    ) {
        let s = scene_of_kinds(seed, count, clustered, kinds);
        let p = pack_with(&s, Accel::Grid);
        let with = SceneView::new(&p);
        prop_assert!(!with.walk_bits.is_empty());
        let without = SceneView::new(&p).without_walk_arrays();
        let (mut wa, mut wb) = (Work::default(), Work::default());
        for spec in &rays {
            let Some((ray, pre)) = ray_of(spec) else {
                continue;
            };
            let a = closest_hit(&with, &ray, &pre, f32::INFINITY, &mut wa);
            let b = closest_hit(&without, &ray, &pre, f32::INFINITY, &mut wb);
            prop_assert_eq!(a.map(|h| (h.0.t, h.1)), b.map(|h| (h.0.t, h.1)));
            prop_assert_eq!(wa, wb);
            for light in [0, usize::MAX] {
                let ta = transmittance(&with, &ray, &pre, spec.2, light, &mut wa);
                let tb = transmittance(&without, &ray, &pre, spec.2, light, &mut wb);
                prop_assert_eq!(ta, tb);
                prop_assert_eq!(wa, wb);
            }
        }
    }

    /// A whole render with the walk arrays and without them (the packed
    /// scene's cleared): the same image bit for bit and the same counts.
    #[test]
    fn the_grid_renders_the_same_with_and_without_its_arrays(
        seed in 0u64..1000,
        count in 1usize..400,
        clustered: bool,
        kinds in prop::option::of(any::<bool>()),
    ) {
        let s = scene_of_kinds(seed, count, clustered, kinds);
        let p = pack_with(&s, Accel::Grid);
        let mut bare = p.clone();
        bare.walk = Default::default();
        prop_assert!(SceneView::new(&bare).walk_bits.is_empty());
        let a = whitted::cpu::render(&p, &|_, _| {});
        let b = whitted::cpu::render(&bare, &|_, _| {});
        prop_assert_eq!(a.stats, b.stats);
        prop_assert_eq!((a.work.tests, a.work.cells), (b.work.tests, b.work.cells));
        prop_assert!(a.pixels == b.pixels, "the images differ");
    }
}
