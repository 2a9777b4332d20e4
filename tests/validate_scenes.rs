//! The SPD scenes (when `../shared/scenes/spd/` exists beside the repo):
//! each .nff rendered at 64×64 on the GPU and on the CPU mirror, compared
//! within `Tolerance::default()` (docs/gpu.md), ray counts included.

mod common;

use std::path::PathBuf;
use whitted::gpu::GpuOptions;
use whitted::metrics::{self, Tolerance};
use whitted::pack::{Sampling, Settings};

fn spd_dir() -> PathBuf {
    common::repo().join("../shared/scenes/spd")
}

#[test]
fn spd_scenes_match_the_cpu_mirror() {
    let dir = spd_dir();
    if !dir.is_dir() {
        println!(
            "note: {} is absent: no SPD scenes to validate",
            dir.display()
        );
        return;
    }
    let Some(g) = common::gpu() else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("nff")))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{} holds no .nff file", dir.display());
    let mut failures = Vec::new();
    for path in &files {
        // SPD's conventions: corner rays, depth 5, no adaptive cutoff.
        let settings = Settings {
            sampling: Sampling::Corners,
            min_weight: 0.0,
            ..common::small(64, 64)
        };
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let scene = whitted::scene::load(path).unwrap_or_else(|e| panic!("{e}"));
        let p = whitted::pack::pack(&scene, &settings).unwrap();
        let gf = g
            .render(&p, &GpuOptions::default(), &|_, _| {})
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        common::assert_no_validation_errors();
        let cf = whitted::cpu::render(&p, &|_, _| {});
        let c = metrics::compare(&cf, &gf, &Tolerance::default());
        println!(
            "{name}: {} prims; max abs {:.2e}, PSNR {:.1} dB, FLIP {:.5}, {} pixels over; rays cpu {:?} gpu {:?}; cpu {:.3} s, gpu {:.3} s",
            p.prims.len(), c.max_abs, c.psnr, c.mean_flip, c.pixels_over, cf.stats, gf.stats, cf.seconds, gf.seconds
        );
        if !c.passed() {
            let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-diff.png"));
            c.diff_image().save(&out).unwrap();
            failures.push(format!(
                "{name}: {} (difference image {})",
                c.failures.join("; "),
                out.display()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
