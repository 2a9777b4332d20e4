//! Rays per second per core without shading, for the comparison with
//! Intel Embree's single-ray kernel (issue 10; `scripts/embree-rays.py`
//! times Embree on the very rays this writes).
//!
//! The scene under the SPD's procedure (512², the 513 × 513 corner eye
//! rays): every eye ray's closest hit, then from each eye hit one shadow
//! feeler per light (from the hit point backed off along the ray by 10⁻⁴
//! of its distance, to the light), on one thread, through the structure
//! `auto` picks. The feelers keep the tracer's last-blocker cache (it is
//! part of the method); the eye rays have no seed. Best of `--repeat`
//! (default 5) passes each. With `--rays FILE` it writes the rays in world
//! coordinates for the script: a little-endian header of two u64 counts
//! (eye, shadow), then per ray seven f32 (origin, direction, far end: +∞
//! for eye rays, the light's distance for feelers).
//!
//! Run: `cargo run --release --example rays_per_core -- tetra.nff [--rays rays.bin]`

use std::io::Write;
use std::time::Instant;
use whitted::pack::{self, Preset};
use whitted::trace::accel::{closest_hit, transmittance};
use whitted::trace::intersect::RayPre;
use whitted::trace::math::{Ray, V3};
use whitted::trace::query::Work;
use whitted::trace::sample::eye_dir;
use whitted::trace::SceneView;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .expect("usage: rays_per_core SCENE [--rays FILE] [--repeat N]");
    let after = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    let repeat: usize = after("--repeat").map_or(5, |n| n.parse().expect("--repeat N"));
    let scene = whitted::scene::load(std::path::Path::new(path)).unwrap_or_else(|e| panic!("{e}"));
    let p = pack::pack(&scene, &Preset::Spd.settings()).expect("the scene packs");
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

    let best = |f: &mut dyn FnMut() -> u64| {
        let mut t = f64::INFINITY;
        let mut n = 0;
        for _ in 0..repeat {
            let t0 = Instant::now();
            n = f();
            t = t.min(t0.elapsed().as_secs_f64());
        }
        (t, n)
    };
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
