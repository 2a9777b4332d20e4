//! The SPD's ray statistics for our renderer: each SPD scene generated at
//! its default size (the teapot at 12, the size of the SPD's published
//! table), rendered on the CPU under the SPD's procedure
//! (`Preset::Spd`: 512×512, corner rays, depth 5, no cut-off, the SPD's
//! counting), its counts printed beside the SPD's published ones as the
//! Markdown table of docs/spd.md.
//!
//! Run: `cargo run --release --example spd_stats [-- SCENE... [--size N]
//! [--traced]]` (`--size N`: every scene named at size N, beside the
//! table for another size; `--traced`: count the rays we trace instead of
//! the SPD's way).

use whitted::gen::spd::{self, SpdScene};
use whitted::pack::{self, Counting, Preset};
use whitted::trace::RayStats;

fn cell(ours: u64, theirs: u64) -> String {
    if theirs == 0 {
        if ours == 0 {
            "0 | 0 | —".into()
        } else {
            format!("{ours} | 0 | —")
        }
    } else {
        let pct = (ours as f64 - theirs as f64) / theirs as f64 * 100.0;
        format!("{ours} | {theirs} | {pct:+.1} %")
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let traced = args.iter().any(|a| a == "--traced");
    let size: Option<u32> = args
        .iter()
        .position(|a| a == "--size")
        .map(|i| args[i + 1].parse().expect("--size N"));
    let scenes: Vec<SpdScene> = {
        let named: Vec<SpdScene> = args
            .iter()
            .enumerate()
            .filter(|(i, a)| !a.starts_with("--") && (*i == 0 || args[i - 1] != "--size"))
            .map(|(_, a)| a)
            .map(|a| a.parse().unwrap_or_else(|e| panic!("{e}")))
            .collect();
        if named.is_empty() {
            SpdScene::ALL.to_vec()
        } else {
            named
        }
    };
    let counting = if traced {
        Counting::Traced
    } else {
        Preset::Spd.counting()
    };
    println!("| scene (size) | ray kind | ours | SPD | difference |");
    println!("|---|---|---:|---:|---:|");
    for s in scenes {
        let (published_size, theirs) = s.published_stats();
        let size = size.unwrap_or(published_size);
        let scene = spd::generate(s, Some(size)).unwrap();
        let mut p = pack::pack(&scene, &Preset::Spd.settings()).expect("fits");
        p.set_counting(counting);
        let f = whitted::cpu::render(&p, &|_, _| {});
        let RayStats {
            eye,
            eye_hit,
            reflect,
            refract,
            shadow,
        } = f.stats;
        assert_eq!(eye, 513 * 513);
        for (i, (kind, ours)) in [
            ("eye hit", eye_hit),
            ("reflect", reflect),
            ("refract", refract),
            ("shadow", shadow),
        ]
        .into_iter()
        .enumerate()
        {
            let name = if i == 0 {
                format!("{s} ({size})")
            } else {
                String::new()
            };
            println!("| {name} | {kind} | {} |", cell(ours, theirs[i]));
        }
        eprintln!("{s}: {:.1} s on the CPU", f.seconds);
    }
}
