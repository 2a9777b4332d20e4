//! Work per ray of the grid and the BVH on one scene, 128 × 128 corner
//! rays under the SPD's settings: eye rays (intersection tests, cells or
//! nodes visited) and one feeler per light from each eye ray's hit, split
//! into blocked feelers (and those the last-blocker cache answers alone)
//! and unblocked ones. A diagnostic for docs/spd.md's causes.
//!
//! Run: `cargo run --release --example work_per_ray -- SCENE.nff`
use whitted::pack::{self, Accel, Preset, Settings};
use whitted::trace::accel::{closest_hit, transmittance};
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{Ray, V3};
use whitted::trace::query::Work;
use whitted::trace::sample::eye_dir;
use whitted::trace::SceneView;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let n: u32 = 128;
    let scene = whitted::scene::load(std::path::Path::new(&path)).unwrap();
    for accel in [Accel::Grid, Accel::Bvh] {
        let settings = Settings {
            width: Some(n),
            height: Some(n),
            accel,
            ..Preset::Spd.settings()
        };
        let p = pack::pack(&scene, &settings).unwrap();
        let s = SceneView::new(&p);
        let (mut wc, mut ws) = (Work::default(), Work::default());
        let (mut nc, mut ns) = (0u64, 0u64);
        let (mut blocked, mut cache_hits) = (0u64, 0u64);
        let (mut nodes_b, mut tests_b, mut nodes_u, mut tests_u) = (0u64, 0u64, 0u64, 0u64);
        for y in 0..=n {
            for x in 0..=n {
                let d = eye_dir::<f32>(&p.globals, x as f32, y as f32);
                let ray = Ray { o: V3::zero(), d };
                let pre = RayPre::new(d, true);
                nc += 1;
                let Some((h, _)) = closest_hit(&s, &ray, &pre, f32::INFINITY, &mut wc) else {
                    continue;
                };
                let pt = d * h.t * 0.9999;
                for (li, l) in p.lights.iter().enumerate() {
                    let lv = V3::of(&l.pos) - pt;
                    let dist = lv.length();
                    let ld = lv / dist;
                    let sray = Ray { o: pt, d: ld };
                    let spre = RayPre::new(ld, true);
                    ns += 1;
                    let mut w = Work {
                        shadow_cache: ws.shadow_cache,
                        ..Work::default()
                    };
                    let tr = transmittance(&s, &sray, &spre, dist, li, &mut w);
                    if tr.max_elem() <= 0.0 {
                        blocked += 1;
                        cache_hits += (w.nodes == 0 && w.cells == 0) as u64;
                        nodes_b += w.nodes + w.cells;
                        tests_b += w.tests;
                    } else {
                        nodes_u += w.nodes + w.cells;
                        tests_u += w.tests;
                    }
                    ws.add(&w);
                    ws.shadow_cache = w.shadow_cache;
                }
            }
        }
        println!("{accel:?}: eye {nc}: tests {:.2} cells {:.2} nodes {:.2} | feelers {ns}: tests {:.2} cells {:.2} nodes {:.2}",
            wc.tests as f64 / nc as f64, wc.cells as f64 / nc as f64, wc.nodes as f64 / nc as f64,
            ws.tests as f64 / ns as f64, ws.cells as f64 / ns as f64, ws.nodes as f64 / ns as f64);
        let per = |x: u64, n: u64| x as f64 / n.max(1) as f64;
        println!(
            "  blocked {blocked} ({cache_hits} by the shadow cache alone): cells or nodes {:.2}, tests {:.2}; \
             unblocked {}: cells or nodes {:.2}, tests {:.2}",
            per(nodes_b, blocked),
            per(tests_b, blocked),
            ns - blocked,
            per(nodes_u, ns - blocked),
            per(tests_u, ns - blocked)
        );
    }
}
