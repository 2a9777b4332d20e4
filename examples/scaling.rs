//! Render-time growth from 1 k to 1 M primitives, measured as a ratio in
//! one run: the scenes are packed first, then rendered in alternating
//! order (small, large, small, large, ...), so that a change in the
//! machine's load during the run hits both sides alike. Prints the
//! median render time of each and the ratio of the medians; BENCHMARKS.md
//! quotes it. (Criterion runs one size after the other, so on a shared
//! machine its ratio drifts with the load.)
//!
//! cargo run --release --example scaling -- [RUNS] [spheres|sphereflake]

use std::time::Instant;
use whitted::pack::{self, Packed, Settings};
use whitted::{cpu, gen};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(11);
    let kind = args.get(2).map(String::as_str).unwrap_or("spheres");
    let settings = Settings {
        width: Some(512),
        height: Some(384),
        ..Settings::default()
    };
    let scenes: Vec<(String, Packed)> = match kind {
        "sphereflake" => [3u32, 6]
            .iter()
            .map(|&l| {
                let p = pack::pack(&gen::sphereflake(l), &settings).expect("fits");
                (format!("sphereflake {} prims", p.prims.len()), p)
            })
            .collect(),
        _ => [1_000usize, 1_000_000]
            .iter()
            .map(|&n| {
                let p = pack::pack(&gen::random_spheres(n, 1), &settings).expect("fits");
                (format!("{n} spheres"), p)
            })
            .collect(),
    };
    // Warm-up: page in the data and the thread pool.
    let rays: Vec<u64> = scenes
        .iter()
        .map(|(_, p)| cpu::render(p, &|_, _| {}).stats.total())
        .collect();
    let mut times = vec![Vec::new(); scenes.len()];
    for _ in 0..runs {
        for (i, (_, p)) in scenes.iter().enumerate() {
            let t = Instant::now();
            std::hint::black_box(cpu::render(p, &|_, _| {}));
            times[i].push(t.elapsed().as_secs_f64());
        }
    }
    let mut medians = Vec::new();
    for (i, (name, _)) in scenes.iter().enumerate() {
        let mut t = times[i].clone();
        let m = median(&mut t);
        medians.push(m);
        let all: Vec<String> = times[i].iter().map(|x| format!("{:.1}", x * 1e3)).collect();
        println!(
            "{name:>28}: median {:.1} ms over {runs} runs ({} rays) [{}]",
            m * 1e3,
            rays[i],
            all.join(" ")
        );
    }
    println!(
        "growth (median large / median small): {:.2}x in time, {:.2}x in rays",
        medians[1] / medians[0],
        rays[1] as f64 / rays[0] as f64
    );
}
