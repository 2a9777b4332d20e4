//! Criterion benchmarks of the CPU renderer (the figures in BENCHMARKS.md).
//!
//! - `rays/*`: rays per second (eye + reflected + refracted + shadow, as
//!   the SPD counts them) on three scenes.
//! - `spheres/*`: render time of the random-spheres scene (src/gen/mod.rs) from
//!   1 k to 1 M spheres at the same resolution: a uniform grid sized to
//!   the scene should keep it nearly flat. (Denser fields also reflect
//!   more: the ray count grows too.)
//! - `sphereflake/*`: a sphereflake from 821 to 597 872 primitives; the
//!   picture and the ray count hardly change, so this is the grid alone.
//!
//! Run: `cargo bench --bench render` (add `-- spheres` for one group).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::path::Path;
use std::time::Duration;
use whitted::pack::{self, Packed, Settings};
use whitted::{cpu, gen, scene};

fn packed(s: &scene::Scene, w: u32, h: u32) -> Packed {
    let settings = Settings {
        width: Some(w),
        height: Some(h),
        ..Settings::default()
    };
    pack::pack(s, &settings).expect("the bench scenes fit")
}

fn rays(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = [
        (
            "showcase",
            scene::load(&root.join("scenes/showcase.toml")).unwrap(),
        ),
        ("mesh", scene::load(&root.join("scenes/mesh.toml")).unwrap()),
        ("spheres-20k", gen::random_spheres(20_000, 1)),
    ];
    let mut g = c.benchmark_group("rays");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for (name, s) in &scenes {
        let p = packed(s, 512, 384);
        let n = cpu::render(&p, &|_, _| {}).stats.total();
        g.throughput(Throughput::Elements(n));
        g.bench_function(*name, |b| b.iter(|| cpu::render(&p, &|_, _| {})));
    }
    g.finish();
}

fn spheres(c: &mut Criterion) {
    let mut g = c.benchmark_group("spheres");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for n in [1_000usize, 10_000, 100_000, 1_000_000] {
        let p = packed(&gen::random_spheres(n, 1), 512, 384);
        g.bench_with_input(BenchmarkId::from_parameter(n), &p, |b, p| {
            b.iter(|| cpu::render(p, &|_, _| {}))
        });
    }
    g.finish();
    // The same picture with more and more spheres: the grid alone.
    let mut g = c.benchmark_group("sphereflake");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for level in [3u32, 4, 5, 6] {
        let p = packed(&gen::sphereflake(level), 512, 384);
        g.bench_with_input(BenchmarkId::from_parameter(p.prims.len()), &p, |b, p| {
            b.iter(|| cpu::render(p, &|_, _| {}))
        });
    }
    g.finish();
}

criterion_group!(benches, rays, spheres);
criterion_main!(benches);
