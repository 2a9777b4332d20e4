//! Box against sphere bounds for the BVH (issue 10): the same hierarchy
//! (the SAH build's, `--accel bvh`) with each child bounded by its box,
//! or by the sphere circumscribing that box, walked by the same rays.
//!
//! Per SPD scene and sphereflake 4 under `--preset spd`: the corner eye
//! rays (every `--step`-th of the 513 × 513 on each axis, default 4) and
//! from each eye hit one feeler per light. Each walk enters every child
//! whose bound the ray's segment meets (eye rays to infinity, feelers to
//! the light), with no pruning by a hit found: what a shadow feeler with
//! no opaque blocker does, and an upper bound for an eye ray. Counted per
//! ray: children entered (interior and leaf) and the primitives the
//! entered leaves list (the tests the bounds let through). f64 arithmetic;
//! the boxes are the packed f32 ones.
//!
//! Run: `cargo run --release --example bounds [-- --step N]`

use whitted::gen::spd::{generate, SpdScene};
use whitted::pack::{self, Accel, Preset};
use whitted::trace::accel::closest_hit;
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{Ray, V3};
use whitted::trace::query::Work;
use whitted::trace::sample::eye_dir;
use whitted::trace::SceneView;

type P = [f64; 3];

/// The segment o + t·d, 0 ≤ t ≤ tmax, meets the box lo..hi.
fn meets_box(o: P, d: P, tmax: f64, lo: P, hi: P) -> bool {
    let (mut t0, mut t1) = (0.0f64, tmax);
    for i in 0..3 {
        if d[i] == 0.0 {
            if o[i] < lo[i] || o[i] > hi[i] {
                return false;
            }
            continue;
        }
        let (a, b) = ((lo[i] - o[i]) / d[i], (hi[i] - o[i]) / d[i]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    t0 <= t1
}

/// The segment meets the sphere around c of radius r (d of unit length).
fn meets_sphere(o: P, d: P, tmax: f64, c: P, r: f64) -> bool {
    let oc = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
    let t = (oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2]).clamp(0.0, tmax);
    let q = [
        o[0] + d[0] * t - c[0],
        o[1] + d[1] * t - c[1],
        o[2] + d[2] * t - c[2],
    ];
    q[0] * q[0] + q[1] * q[1] + q[2] * q[2] <= r * r
}

/// (children entered, primitives listed by entered leaves) for one ray.
fn walk(p: &pack::Packed, o: P, d: P, tmax: f64, sphere: bool) -> (u64, u64) {
    let (mut entered, mut tests) = (0u64, 0u64);
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        let node = &p.bvh[n as usize];
        for k in 0..4 {
            let (link, count) = (node.link[k], node.count[k]);
            if link == 0 && count == 0 {
                continue;
            }
            let lo = [0, 1, 2].map(|i| node.lo()[i][k] as f64);
            let hi = [0, 1, 2].map(|i| node.hi()[i][k] as f64);
            let hit = if sphere {
                let c = [0, 1, 2].map(|i| 0.5 * (lo[i] + hi[i]));
                let r = 0.5 * (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f64>().sqrt();
                meets_sphere(o, d, tmax, c, r)
            } else {
                meets_box(o, d, tmax, lo, hi)
            };
            if !hit {
                continue;
            }
            entered += 1;
            if count > 0 {
                tests += count as u64;
            } else {
                stack.push(link);
            }
        }
    }
    (entered, tests)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let step: u32 = args
        .iter()
        .position(|a| a == "--step")
        .and_then(|i| args.get(i + 1))
        .map_or(4, |s| s.parse().expect("--step N"));
    let mut scenes: Vec<(String, whitted::scene::Scene)> = SpdScene::ALL
        .into_iter()
        .map(|k| (k.name().to_string(), generate(k, None).unwrap()))
        .collect();
    scenes.push(("sphereflake 4".into(), whitted::gen::sphereflake(4)));
    println!("| scene | rays | box: children entered / ray | sphere | box: primitive tests / ray | sphere |");
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, scene) in &scenes {
        let settings = pack::Settings {
            accel: Accel::Bvh,
            ..Preset::Spd.settings()
        };
        let p = pack::pack(scene, &settings).expect("the scene packs");
        let s = SceneView::new(&p);
        let g = &p.globals;
        let (w, h) = (g.image[0], g.image[1]);
        let mut rays: Vec<(P, P, f64)> = Vec::new();
        let mut work = Work::default();
        for y in (0..=h).step_by(step as usize) {
            for x in (0..=w).step_by(step as usize) {
                let d = eye_dir::<f32>(g, x as f32, y as f32);
                let df = [d.x as f64, d.y as f64, d.z as f64];
                rays.push(([0.0; 3], df, f64::INFINITY));
                let pre = RayPre::new(d, true);
                let ray = Ray { o: V3::zero(), d };
                if let Some((hit, _)) = closest_hit(&s, &ray, &pre, f32::INFINITY, &mut work) {
                    let pt = [0, 1, 2].map(|i| df[i] * hit.t as f64 * 0.9999);
                    for l in p.lights.iter() {
                        let lv = [0, 1, 2].map(|i| l.pos[i] as f64 - pt[i]);
                        let dist = (lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]).sqrt();
                        rays.push((pt, lv.map(|v| v / dist), dist));
                    }
                }
            }
        }
        let sum = |sphere: bool| {
            rays.iter().fold((0u64, 0u64), |acc, &(o, d, t)| {
                let (e, k) = walk(&p, o, d, t, sphere);
                (acc.0 + e, acc.1 + k)
            })
        };
        let (be, bt) = sum(false);
        let (se, st) = sum(true);
        let n = rays.len() as f64;
        println!(
            "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} |",
            rays.len(),
            be as f64 / n,
            se as f64 / n,
            bt as f64 / n,
            st as f64 / n
        );
    }
}
