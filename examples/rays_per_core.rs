//! Rays per second per core without shading, for the comparison with
//! Intel Embree's single-ray kernel (issue 10; `scripts/embree-rays.py`
//! times Embree on the very rays this writes).
//!
//! The scene under the SPD's procedure (512², the 513 × 513 corner eye
//! rays): every eye ray's closest hit, then from each eye hit one shadow
//! feeler per light (from the hit point backed off along the ray by 10⁻⁴
//! of its distance, to the light), on one thread, through the structure
//! `auto` picks (or `--accel NAME`). The feelers keep the tracer's last-blocker cache (it is
//! part of the method); the eye rays have no seed. Best of `--repeat`
//! (default 5) passes each. With `--rays FILE` it writes the rays in world
//! coordinates for the script: a little-endian header of two u64 counts
//! (eye, shadow), then per ray seven f32 (origin, direction, far end: +∞
//! for eye rays, the light's distance for feelers).
//!
//! With `--packet 4` or `--packet 8` it also traces the same rays in
//! packets (`trace::packet`): the eye rays in blocks of 2 × 2 or 4 × 2
//! lattice points, the feelers of a block's hits to each light together.
//!
//! Run: `cargo run --release --example rays_per_core -- tetra.nff [--rays rays.bin] [--packet 4]`

use std::io::Write;
use std::time::Instant;
use whitted::pack::{self, Preset};
use whitted::trace::accel::{closest_hit, transmittance};
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{Ray, V3};
use whitted::trace::packet::{closest_hit_packet, transmittance_packet};
use whitted::trace::query::Work;
use whitted::trace::sample::eye_dir;
use whitted::trace::SceneView;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().expect(
        "usage: rays_per_core SCENE [--rays FILE] [--repeat N] [--packet 4|8] [--accel NAME]",
    );
    let after = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    let repeat: usize = after("--repeat").map_or(5, |n| n.parse().expect("--repeat N"));
    let scene = whitted::scene::load(std::path::Path::new(path)).unwrap_or_else(|e| panic!("{e}"));
    let mut settings = Preset::Spd.settings();
    if let Some(a) = after("--accel") {
        settings.accel =
            clap::ValueEnum::from_str(a, true).expect("--accel grid|bvh|octree|hybrid|auto");
    }
    let p = pack::pack(&scene, &settings).expect("the scene packs");
    let s = SceneView::new(&p);
    let g = &p.globals;
    let (w, h) = (g.image[0], g.image[1]);

    let mut eye = Vec::new();
    for y in 0..=h {
        for x in 0..=w {
            let d = eye_dir::<f32>(g, x as f32, y as f32);
            eye.push((Ray { o: V3::zero(), d }, RayPre::new(d, true)));
        }
    }
    // The eye hits (once, untimed) give the feelers.
    let mut work = Work::default();
    let mut feelers = Vec::new();
    for (ray, pre) in &eye {
        if let Some((hit, _)) = closest_hit(&s, ray, pre, f32::INFINITY, &mut work) {
            let pt = ray.d * (hit.t * 0.9999);
            for (li, l) in p.lights.iter().enumerate() {
                let lv = V3::of(&l.pos) - pt;
                let dist = lv.length();
                let d = lv / dist;
                feelers.push((Ray { o: pt, d }, RayPre::new(d, true), dist, li));
            }
        }
    }

    let best = |f: &mut dyn FnMut() -> u64| best_of(repeat, f);
    let (te, hits) = best(&mut || {
        let mut work = Work::default();
        eye.iter()
            .filter(|(ray, pre)| closest_hit(&s, ray, pre, f32::INFINITY, &mut work).is_some())
            .count() as u64
    });
    let (ts, blocked) = best(&mut || {
        let mut work = Work::default();
        feelers
            .iter()
            .filter(|(ray, pre, dist, li)| {
                transmittance(&s, ray, pre, *dist, *li, &mut work).max_elem() <= 0.0
            })
            .count() as u64
    });
    let m = |n: usize, t: f64| n as f64 / t / 1e6;
    println!(
        "{path}: {} primitives, {:?}; eye rays {} ({hits} hit) in {te:.4} s: {:.2} Mrays/s; \
         feelers {} ({blocked} blocked) in {ts:.4} s: {:.2} Mrays/s; together {:.2} Mrays/s \
         (one thread, no shading, best of {repeat})",
        p.prims.len(),
        p.structure(),
        eye.len(),
        m(eye.len(), te),
        feelers.len(),
        m(feelers.len(), ts),
        m(eye.len() + feelers.len(), te + ts),
    );

    // The work behind those times: one more pass of each, counted.
    let (mut ew, mut fw) = (Work::default(), Work::default());
    for (ray, pre) in &eye {
        closest_hit(&s, ray, pre, f32::INFINITY, &mut ew);
    }
    for (ray, pre, dist, li) in &feelers {
        transmittance(&s, ray, pre, *dist, *li, &mut fw);
    }
    let per = |w: &Work, n: usize| {
        let n = n.max(1) as f64;
        format!(
            "{:.2} nodes, {:.2} cells, {:.2} tests",
            w.nodes as f64 / n,
            w.cells as f64 / n,
            w.tests as f64 / n
        )
    };
    println!(
        "per eye ray: {}; per feeler: {}",
        per(&ew, eye.len()),
        per(&fw, feelers.len())
    );

    match after("--packet").map(String::as_str) {
        Some("4") => packets::<4>(&s, &p, repeat, (te, ts)),
        Some("8") => packets::<8>(&s, &p, repeat, (te, ts)),
        Some(other) => panic!("--packet takes 4 or 8, not {other}"),
        None => {}
    }

    if let Some(out) = after("--rays") {
        let c = scene.camera.from;
        let world = |v: V3<f32>| [v.x + c.x as f32, v.y + c.y as f32, v.z + c.z as f32];
        let mut bytes = Vec::new();
        bytes.extend((eye.len() as u64).to_le_bytes());
        bytes.extend((feelers.len() as u64).to_le_bytes());
        let mut put = |o: [f32; 3], d: V3<f32>, far: f32| {
            for x in o.into_iter().chain([d.x, d.y, d.z, far]) {
                bytes.extend(x.to_le_bytes());
            }
        };
        for (ray, _) in &eye {
            put(world(ray.o), ray.d, f32::INFINITY);
        }
        for (ray, _, dist, _) in &feelers {
            put(world(ray.o), ray.d, *dist);
        }
        std::fs::File::create(out)
            .and_then(|mut f| f.write_all(&bytes))
            .unwrap_or_else(|e| panic!("{out}: {e}"));
        println!("wrote {out}");
    }
}

/// The least time of `repeat` runs of `f`, and what it returned.
fn best_of(repeat: usize, f: &mut dyn FnMut() -> u64) -> (f64, u64) {
    let mut t = f64::INFINITY;
    let mut n = 0;
    for _ in 0..repeat {
        let t0 = Instant::now();
        n = f();
        t = t.min(t0.elapsed().as_secs_f64());
    }
    (t, n)
}

/// A packet's rays and their precomputed values.
type Lanes<const P: usize> = ([Ray<f32>; P], [RayPre<f32>; P]);

/// The corner eye rays in packets of `P` (blocks of 2 × 2 or 4 × 2, the
/// renderer's) and, per light, the feelers from each packet's hits, as
/// the single rays above; `single`: their times one by one.
fn packets<const P: usize>(s: &SceneView, p: &pack::Packed, repeat: usize, single: (f64, f64)) {
    let g = &p.globals;
    let (w, h) = (g.image[0] + 1, g.image[1] + 1);
    let (bw, bh) = if P == 8 { (4, 2) } else { (2, 2) };
    // Each packet and how many of its lanes are real (a block cut at the
    // lattice's edge repeats its last point).
    let mut eye: Vec<(Lanes<P>, usize)> = Vec::new();
    for by in (0..h).step_by(bh) {
        for bx in (0..w).step_by(bw) {
            let mut pts = Vec::new();
            for y in by..(by + bh as u32).min(h) {
                for x in bx..(bx + bw as u32).min(w) {
                    pts.push((x, y));
                }
            }
            let rays: [Ray<f32>; P] = std::array::from_fn(|j| {
                let (x, y) = pts[j.min(pts.len() - 1)];
                Ray {
                    o: V3::zero(),
                    d: eye_dir::<f32>(g, x as f32, y as f32),
                }
            });
            eye.push(((rays, rays.map(|r| RayPre::new(r.d, true))), pts.len()));
        }
    }
    let n_eye = (w * h) as usize;
    // The feelers of each packet's hits, light by light: (rays, lengths,
    // light, lanes).
    let mut feelers: Vec<(Lanes<P>, [f32; P], usize, u32)> = Vec::new();
    for ((rays, pres), real) in &eye {
        let hits = closest_hit_packet(s, rays, pres, f32::INFINITY, &mut Work::default());
        for (li, l) in p.lights.iter().enumerate() {
            let mut fr = *rays;
            let mut dist = [0f32; P];
            let mut live = 0u32;
            for j in 0..*real {
                if let Some((hit, _)) = hits[j] {
                    let pt = rays[j].d * (hit.t * 0.9999);
                    let lv = V3::of(&l.pos) - pt;
                    dist[j] = lv.length();
                    fr[j] = Ray {
                        o: pt,
                        d: lv / dist[j],
                    };
                    live |= 1 << j;
                }
            }
            if live == 0 {
                continue;
            }
            let k = live.trailing_zeros() as usize;
            for j in 0..P {
                if (live >> j) & 1 == 0 {
                    (fr[j], dist[j]) = (fr[k], dist[k]);
                }
            }
            feelers.push(((fr, fr.map(|r| RayPre::new(r.d, true))), dist, li, live));
        }
    }
    let n_feelers: usize = feelers.iter().map(|f| f.3.count_ones() as usize).sum();
    let best = |f: &mut dyn FnMut() -> u64| best_of(repeat, f);
    let (te, hits) = best(&mut || {
        let mut work = Work::default();
        eye.iter()
            .map(|((rays, pres), real)| {
                let h = closest_hit_packet(s, rays, pres, f32::INFINITY, &mut work);
                h[..*real].iter().filter(|h| h.is_some()).count() as u64
            })
            .sum::<u64>()
    });
    let (ts, blocked) = best(&mut || {
        let mut work = Work::default();
        feelers
            .iter()
            .map(|((rays, pres), dist, li, live)| {
                let t = transmittance_packet(s, rays, pres, dist, *li, *live, &mut work);
                (0..P)
                    .filter(|&j| (live >> j) & 1 == 1 && t[j].max_elem() <= 0.0)
                    .count() as u64
            })
            .sum::<u64>()
    });
    let m = |n: usize, t: f64| n as f64 / t / 1e6;
    println!(
        "packets of {P}: eye rays {n_eye} ({hits} hit) \
         in {te:.4} s: {:.2} Mrays/s ({:.2}x single); feelers {n_feelers} ({blocked} blocked) \
         in {ts:.4} s: {:.2} Mrays/s ({:.2}x single)",
        m(n_eye, te),
        single.0 / te,
        m(n_feelers, ts),
        single.1 / ts,
    );
}
