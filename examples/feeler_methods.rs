//! Shadow feelers four ways on the CPU mirror, for issue 10's "measure the
//! light buffers and the last-blocker cache together and apart": plain
//! feelers (the structure's walk) and light buffers, each with the shadow
//! cache on and off (`Packed::set_shadow_cache`; the command line's
//! `--shadow-cache` is the GPU's alone). Each scene is packed once per
//! method under `--preset spd --counting traced` (as `whitted bench`
//! renders the SPD scenes), then the four are rendered in turn,
//! RUNS times, so that the machine's drift hits all alike. Prints each
//! one's median render time and its feelers' work per feeler, and checks
//! that the four images are the same; BENCHMARKS.md quotes it.
//!
//! cargo run --release --example feeler_methods -- RUNS SCENE.nff...

use std::path::Path;
use std::time::Instant;
use whitted::pack::{self, Counting, Packed, Preset, Settings, Shadows};
use whitted::{cpu, scene};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(7);
    for path in &args[2..] {
        let s = scene::load(Path::new(path)).unwrap_or_else(|e| panic!("{e}"));
        let packed = |shadows, cache| -> Packed {
            let mut p = pack::pack(
                &s,
                &Settings {
                    shadows,
                    ..Preset::Spd.settings()
                },
            )
            .unwrap_or_else(|e| panic!("{path}: {e}"));
            p.set_counting(Counting::Traced);
            p.set_shadow_cache(cache);
            p
        };
        let ways = [
            ("plain, cache", packed(Shadows::Plain, true)),
            ("plain, no cache", packed(Shadows::Plain, false)),
            ("lightbuffer, cache", packed(Shadows::LightBuffer, true)),
            ("lightbuffer, no cache", packed(Shadows::LightBuffer, false)),
        ];
        let frames: Vec<cpu::Frame> = ways
            .iter()
            .map(|(_, p)| cpu::render(p, &|_, _| {}))
            .collect();
        for (f, (name, _)) in frames.iter().zip(&ways) {
            assert_eq!(
                f.pixels, frames[0].pixels,
                "{path}: {name} gives another image"
            );
        }
        let mut times = vec![Vec::new(); ways.len()];
        for _ in 0..runs {
            for (i, (_, p)) in ways.iter().enumerate() {
                let t = Instant::now();
                std::hint::black_box(cpu::render(p, &|_, _| {}));
                times[i].push(t.elapsed().as_secs_f64());
            }
        }
        println!("{path} ({runs} runs, medians):");
        for (i, (name, p)) in ways.iter().enumerate() {
            let f = &frames[i];
            let feelers = f.stats.shadow.max(1) as f64;
            let [tests, cells, nodes] = f.work.shadow.map(|x| x as f64 / feelers);
            println!(
                "  {name:>22}: {:.1} ms; per feeler {tests:.2} tests, {cells:.2} cells, {nodes:.2} nodes; \
                 light buffer {} cells, {} references",
                median(&mut times[i]) * 1e3,
                p.lightbuf.cells,
                p.lightbuf.refs
            );
        }
    }
}
