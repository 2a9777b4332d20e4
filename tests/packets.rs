//! Packets of rays (`trace::packet`, `--packet`): a packet's answers are
//! each ray's alone, bit for bit, and a render in packets of 4 or 8 is
//! the render one ray at a time, pixel for pixel and ray count for ray
//! count (docs/method.md, "Packets of rays").
//!
//! Tolerance: none. A packet hands each ray the same primitives'
//! intersection routines (or the same arithmetic lane by lane) with the
//! same bounds; ties go to the lower rank whatever the order; a feeler's
//! blockers multiply its light in the tree's depth-first order in both
//! walks. The glass here lets through 0.3 and 0.7 (in different colours),
//! whose products change in the last bit with their order, so a walk that
//! took a feeler's blockers in another order would fail.

mod common;

use glam::DVec3;
use proptest::prelude::*;
use whitted::constants::SAMPLING_CORNERS;
use whitted::cpu::render_packets;
use whitted::pack::{self, Accel, Packed, Sampling, Settings};
use whitted::scene::{Material, Object, Scene, Shape};
use whitted::trace::accel::{closest_hit, transmittance};
use whitted::trace::intersect::{Hit, RayPre};
use whitted::trace::math::{v3, Ray, V3};
use whitted::trace::packet::{closest_hit_packet, transmittance_packet};
use whitted::trace::query::Work;
use whitted::trace::sample::eye_dir;
use whitted::trace::SceneView;

use common::{v, Rng};

/// `count` primitives of every bounded kind in four clumps around the
/// origin, a floor polygon (in the BVH too) and an unbounded plane far
/// below, in matte, mirror and two coloured glasses.
fn scene(seed: u64, count: usize) -> Scene {
    let mut r = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let centres: Vec<DVec3> = (0..4)
        .map(|_| v(r.f() * 8.0 - 4.0, r.f() * 8.0 - 4.0, r.f() * 8.0 - 4.0))
        .collect();
    let mut objects = vec![
        Object {
            shape: Shape::Polygon {
                vertices: vec![
                    v(-30.0, -30.0, -6.0),
                    v(30.0, -30.0, -6.0),
                    v(30.0, 30.0, -6.0),
                    v(-30.0, 30.0, -6.0),
                ],
            },
            material: 1,
        },
        Object {
            shape: Shape::Plane {
                normal: v(0.0, 0.0, 1.0),
                point: v(0.0, 0.0, -40.0),
            },
            material: 0,
        },
    ];
    for i in 0..count {
        let c = centres[i % 4] + v(r.f() - 0.5, r.f() - 0.5, r.f() - 0.5) * 3.0;
        let s = 0.6;
        let shape = match i % 6 {
            0..=2 => Shape::Sphere {
                center: c,
                radius: (0.05 + r.f() * 0.8) * s,
            },
            // Smooth triangles: their hits' barycentric weights shade.
            3 => Shape::Triangle {
                vertices: [
                    c,
                    c + v(r.f(), r.f(), 0.0) * s,
                    c + v(0.0, r.f(), r.f() + 0.1) * s,
                ],
                normals: Some(Box::new([
                    v(0.0, -1.0, 0.2),
                    v(0.3, -1.0, 0.0),
                    v(-0.3, -1.0, 0.1),
                ])),
            },
            4 => Shape::Box {
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
    common::random_scene_frame(37, 23, [v(0.3, 0.7, 0.3), v(0.7, 0.3, 0.7)], objects)
}

fn pack_bvh(s: &Scene, settings: Settings) -> Packed {
    let p = pack::pack(
        s,
        &Settings {
            accel: Accel::Bvh,
            ..settings
        },
    )
    .unwrap();
    assert_eq!(p.structure(), Accel::Bvh);
    p
}

/// A packet: each lane's origin, direction (not yet unit) and feeler
/// length.
type Lane = ([f32; 3], [f32; 3], f32);

/// Packets of `P` rays: coherent ones (from one point or a small patch,
/// directions within a narrow cone, some lying in a plane of the axes)
/// and scattered ones (any origin, any direction: mixed signs, which walk
/// ray by ray).
fn packet_strategy<const P: usize>() -> impl Strategy<Value = Vec<Lane>> {
    let coord = || -12.0f32..12.0;
    let coherent = (
        [coord(), coord(), coord()],
        [-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0],
        0.0f32..0.5,
        0.0f32..0.2,
        any::<bool>(),
        prop::collection::vec(
            ([-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0], 0.5f32..30.0),
            P,
        ),
    )
        .prop_map(|(o, d, spread, patch, flat, jitter)| {
            jitter
                .into_iter()
                .map(|(j, len)| {
                    let oj = [0, 1, 2].map(|i| o[i] + j[i] * patch);
                    let mut dj = [0, 1, 2].map(|i| d[i] + j[(i + 1) % 3] * spread);
                    if flat {
                        // In the plane z = const: 1/d_z is infinite.
                        dj[2] = 0.0;
                    }
                    (oj, dj, len)
                })
                .collect::<Vec<_>>()
        });
    let scattered = prop::collection::vec(
        (
            [coord(), coord(), coord()],
            [-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0],
            0.5f32..30.0,
        ),
        P,
    );
    prop_oneof![3 => coherent, 1 => scattered]
}

/// A packet's rays, their precomputed values and feeler lengths.
type Packet<const P: usize> = ([Ray<f32>; P], [RayPre<f32>; P], [f32; P]);

fn lanes_of<const P: usize>(spec: &[Lane]) -> Option<Packet<P>> {
    let mut rays = [Ray {
        o: V3::zero(),
        d: v3(1.0, 0.0, 0.0),
    }; P];
    let mut dist = [0f32; P];
    for (j, (o, d, len)) in spec.iter().enumerate() {
        let d = v3(d[0], d[1], d[2]);
        if d.length() < 1e-3 {
            return None;
        }
        // World coordinates to packed ones, whose origin is the eye
        // (0, −20, 3).
        rays[j] = Ray {
            o: v3(o[0], o[1] + 20.0, o[2] - 3.0),
            d: d.normalize(),
        };
        dist[j] = *len;
    }
    Some((rays, rays.map(|r| RayPre::new(r.d, true)), dist))
}

/// Both packet queries against each ray's alone, every lane and a subset.
fn check_packet<const P: usize>(p: &Packed, spec: &[Lane], live: u32) -> Result<(), TestCaseError> {
    let s = SceneView::new(p);
    let Some((rays, pres, dist)) = lanes_of::<P>(spec) else {
        return Ok(());
    };
    let mut work = Work::default();
    let hits = closest_hit_packet(&s, &rays, &pres, f32::INFINITY, &mut work);
    for j in 0..P {
        let alone = closest_hit(&s, &rays[j], &pres[j], f32::INFINITY, &mut Work::default());
        // Up to the copy of a halved cone (`pack::bvh_pieces`).
        let same = |h: Option<(Hit<f32>, u32)>| h.map(|(h, i)| (h, p.prims[i as usize]));
        prop_assert_eq!(same(hits[j]), same(alone), "lane {} of {}", j, P);
    }
    for light in [0, 1, usize::MAX] {
        let mut work = Work::default();
        let through = transmittance_packet(&s, &rays, &pres, &dist, light, live, &mut work);
        let mut alone_work = Work::default();
        for j in 0..P {
            let alone = if (live >> j) & 1 == 1 {
                transmittance(&s, &rays[j], &pres[j], dist[j], light, &mut alone_work)
            } else {
                V3::zero()
            };
            prop_assert_eq!(through[j], alone, "feeler lane {} of {}", j, P);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn packets_of_four_answer_as_their_rays_alone(
        seed in 1u64..1000,
        count in 1usize..120,
        spec in packet_strategy::<4>(),
        live in 1u32..16,
    ) {
        let p = pack_bvh(&scene(seed, count), Settings::default());
        check_packet::<4>(&p, &spec, live)?;
    }

    #[test]
    fn packets_of_eight_answer_as_their_rays_alone(
        seed in 1u64..1000,
        count in 1usize..120,
        spec in packet_strategy::<8>(),
        live in 1u32..256,
    ) {
        let p = pack_bvh(&scene(seed, count), Settings::default());
        check_packet::<8>(&p, &spec, live)?;
    }
}

/// Packets meet the blockers of a feeler in the order one feeler does:
/// feelers along a row of glass spheres of different k_t, whose product
/// in f32 depends on the order (checked here), in packets of four.
#[test]
fn feelers_through_glass_keep_their_order() {
    let kts = [0.3, 0.71, 0.93, 0.45, 0.57, 0.83, 0.39, 0.61];
    let mut sc = scene(7, 0);
    sc.objects.truncate(1);
    for (i, kt) in kts.iter().enumerate() {
        sc.materials.push(Material {
            name: format!("glass {kt}"),
            kt: v(*kt, 1.0 - kt, *kt * 0.5),
            ior: 1.3,
            ..Material::default()
        });
        sc.objects.push(Object {
            shape: Shape::Sphere {
                center: v(i as f64 * 1.5, 0.0, 0.0),
                radius: 0.5,
            },
            material: (sc.materials.len() - 1) as u32,
        });
    }
    let p = pack_bvh(&sc, Settings::default());
    let s = SceneView::new(&p);
    // The order matters: the product left to right against right to left.
    let prod = |order: &mut dyn Iterator<Item = &f64>| {
        order.fold([1f32; 3], |t, kt| {
            let k = [*kt as f32, (1.0 - kt) as f32, (*kt * 0.5) as f32];
            [t[0] * k[0], t[1] * k[1], t[2] * k[2]]
        })
    };
    assert_ne!(prod(&mut kts.iter()), prod(&mut kts.iter().rev()));
    let mut crossed = 0;
    for k in 0..64 {
        let rays: [Ray<f32>; 4] = std::array::from_fn(|j| {
            let e = (k * 4 + j) as f32 * 1e-4;
            let d = if k % 2 == 0 {
                v3(1.0, e, -e)
            } else {
                v3(-1.0, -e, e)
            };
            let x = if k % 2 == 0 { -2.0 } else { 13.0 };
            // Packed coordinates have the eye at the origin.
            Ray {
                o: v3(x, 20.0 + 0.01 * j as f32, -3.0),
                d: d.normalize(),
            }
        });
        let pres = rays.map(|r| RayPre::new(r.d, true));
        let dist = [20.0f32; 4];
        let through = transmittance_packet(&s, &rays, &pres, &dist, 0, 15, &mut Work::default());
        for j in 0..4 {
            let alone = transmittance(&s, &rays[j], &pres[j], dist[j], 0, &mut Work::default());
            assert_eq!(through[j], alone, "feeler {k} lane {j}");
            if alone.x > 0.0 && alone.x < 0.02 {
                crossed += 1;
            }
        }
    }
    assert_eq!(crossed, 256, "every feeler crosses the row");
}

fn assert_same_render(p: &Packed, what: &str) {
    let one = render_packets::<f32>(p, 1, &|_, _| {});
    for width in [4, 8] {
        let f = render_packets::<f32>(p, width, &|_, _| {});
        assert_eq!(
            f.stats, one.stats,
            "{what}: ray counts in packets of {width}"
        );
        assert_eq!(f.pixels.len(), one.pixels.len());
        for (i, (a, b)) in f.pixels.iter().zip(&one.pixels).enumerate() {
            assert_eq!(
                a.map(f32::to_bits),
                b.map(f32::to_bits),
                "{what}: pixel {i} in packets of {width}"
            );
        }
    }
}

/// Whole renders: packets of 4 and 8 give the image of single rays on
/// an odd-sized image (tiles and blocks cut at its edges), with several
/// samples per pixel, with corner sampling, and in f64.
#[test]
fn renders_in_packets_are_the_renders_of_single_rays() {
    let sc = scene(11, 200);
    let base = Settings {
        max_depth: 4,
        ..Settings::default()
    };
    assert_same_render(&pack_bvh(&sc, base.clone()), "1 sample");
    assert_same_render(
        &pack_bvh(
            &sc,
            Settings {
                spp: 3,
                ..base.clone()
            },
        ),
        "3 samples",
    );
    let corners = pack_bvh(
        &sc,
        Settings {
            sampling: Sampling::Corners,
            ..base.clone()
        },
    );
    assert_eq!(corners.globals.image[3], SAMPLING_CORNERS);
    assert_same_render(&corners, "corners");
    let p = pack_bvh(&sc, base);
    let one = render_packets::<f64>(&p, 1, &|_, _| {});
    let eight = render_packets::<f64>(&p, 8, &|_, _| {});
    assert_eq!(one.pixels, eight.pixels, "f64");
}

/// An example scene with glass, boxes and two lights, under every
/// structure (packets walk only the BVH; the others trace ray by ray).
#[test]
fn example_scene_renders_the_same_in_packets_under_every_structure() {
    for accel in [Accel::Bvh, Accel::Grid, Accel::Octree, Accel::Hybrid] {
        let p = common::load(
            &common::repo().join("scenes/showcase.toml"),
            &Settings {
                accel,
                ..common::small(64, 48)
            },
        );
        assert_same_render(&p, &format!("showcase, {accel:?}"));
    }
}

/// Eye rays over a whole image, in packets of `P` (blocks of 2 × 2 or
/// 4 × 2 pixels), against each ray alone: the same hits (distance,
/// barycentric weights, primitive); the work of both.
fn eye_packets<const P: usize>(p: &Packed) -> (Work, Work) {
    let s = SceneView::new(p);
    let (w, h) = (p.globals.image[0], p.globals.image[1]);
    let bw = if P == 8 { 4 } else { 2 };
    let (mut alone, mut packed) = (Work::default(), Work::default());
    let mut triangles = 0;
    for by in (0..h).step_by(2) {
        for bx in (0..w).step_by(bw) {
            let rays: [Ray<f32>; P] = std::array::from_fn(|j| Ray {
                o: V3::zero(),
                d: eye_dir(
                    &p.globals,
                    (bx + j as u32 % bw as u32) as f32 + 0.5,
                    (by + j as u32 / bw as u32) as f32 + 0.5,
                ),
            });
            let pres = rays.map(|r| RayPre::new(r.d, true));
            let hits = closest_hit_packet(&s, &rays, &pres, f32::INFINITY, &mut packed);
            for j in 0..P {
                let one = closest_hit(&s, &rays[j], &pres[j], f32::INFINITY, &mut alone);
                // The same primitive up to the copy: a long opaque cone is
                // two identical ones in the BVH (`pack::bvh_pieces`).
                let same = |h: Option<(Hit<f32>, u32)>| h.map(|(h, i)| (h, p.prims[i as usize]));
                assert_eq!(
                    same(hits[j]),
                    same(one),
                    "pixel block ({bx}, {by}) lane {j}"
                );
                if let Some((_, i)) = one {
                    triangles +=
                        (p.prims[i as usize].kind() == whitted::constants::KIND_TRIANGLE) as u32;
                }
            }
        }
    }
    assert!(triangles > 40, "only {triangles} triangle hits");
    (alone, packed)
}

/// Packets walk fewer BVH nodes than their rays alone on coherent eye
/// rays (the point of them), and test about the same primitives.
#[test]
fn eye_packets_find_the_same_hits_visiting_fewer_nodes() {
    let p = pack_bvh(&scene(3, 400), common::small(128, 96));
    eye_packets::<8>(&p);
    let (alone, packed) = eye_packets::<4>(&p);
    assert!(
        packed.nodes * 2 < alone.nodes,
        "nodes: {} in packets against {} alone",
        packed.nodes,
        alone.nodes
    );
    // A packet's ray tests a leaf's primitives when its own box test at
    // the leaf passes, a single ray when its test at the parent did: the
    // bounds they see differ by the hits found in between.
    assert!(
        packed.tests * 100 <= alone.tests * 101,
        "tests: {} against {}",
        packed.tests,
        alone.tests
    );
}
