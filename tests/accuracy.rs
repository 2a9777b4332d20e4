//! Speed against accuracy end to end: `--precision`, `whitted reference`
//! and its cache, `whitted chart` (docs/accuracy.md).

use assert_cmd::Command;
use std::path::Path;

fn whitted() -> Command {
    let mut c = Command::cargo_bin("whitted").unwrap();
    // No test reads or writes the user's cache.
    c.env(
        "XDG_CACHE_HOME",
        std::env::temp_dir().join("whitted-test-no-cache"),
    );
    c
}

/// A mirror sphere over a diffuse floor: depth matters, edges alias.
const SCENE: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0.8]\nup = [0, 0, 1]\nfov = 40\n\
width = 48\nheight = 36\n\n[[light]]\nposition = [5, -5, 10]\n\n\
[material.mirror]\ncolor = [0.9, 0.9, 0.9]\nkd = 0.2\nks = 0.5\nshine = 50\nkr = 0.7\n\n\
[material.floor]\ncolor = [0.8, 0.6, 0.3]\nkd = 0.8\nkr = 0.3\n\n\
[[object]]\ntype = \"sphere\"\ncenter = [-0.6, 0, 1]\nradius = 1\nmaterial = \"mirror\"\n\n\
[[object]]\ntype = \"sphere\"\ncenter = [1.2, 0.8, 0.6]\nradius = 0.6\nmaterial = \"mirror\"\n\n\
[[object]]\ntype = \"polygon\"\nvertices = [[-6, -6, 0], [6, -6, 0], [6, 6, 0], [-6, 6, 0]]\n\
material = \"floor\"\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn exr(path: &Path) -> Vec<f32> {
    image::open(path).unwrap().into_rgb32f().into_raw()
}

#[test]
fn precision_f64_renders_on_the_cpu_and_differs_from_f32_only_in_the_last_bits() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let mut img = Vec::new();
    for p in ["f32", "f64"] {
        let out = dir.path().join(format!("{p}.exr"));
        whitted()
            .args(["render", "-q", "--precision", p])
            .arg(&scene)
            .arg("-o")
            .arg(&out)
            .assert()
            .success();
        img.push(exr(&out));
    }
    let max = img[0]
        .iter()
        .zip(&img[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(img[0] != img[1], "f64 should not be f32 bit for bit");
    assert!(max < 1e-3, "f32 and f64 differ by {max}");
    // The shader has no f64: asking the GPU for it is a usage error.
    let o = whitted()
        .args(["render", "-q", "--precision", "f64", "--backend", "gpu"])
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("never.png"))
        .assert()
        .code(2);
    let err = String::from_utf8_lossy(&o.get_output().stderr).into_owned();
    assert!(err.contains("CPU only"), "{err}");
    assert!(!dir.path().join("never.png").exists());
}

#[test]
fn the_reference_is_cached_and_the_cache_survives_a_corrupt_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let cache = dir.path().join("cache");
    let run = |out: &str| {
        let o = whitted()
            .args(["reference", "--spp", "4", "--max-depth", "6", "--cache"])
            .arg(&cache)
            .arg(&scene)
            .arg("-o")
            .arg(dir.path().join(out))
            .assert()
            .success();
        String::from_utf8(o.get_output().stderr.clone()).unwrap()
    };
    let first = run("a.exr");
    assert!(first.contains("rendered in"), "{first}");
    let second = run("b.exr");
    assert!(second.contains("from the cache"), "{second}");
    assert_eq!(
        exr(&dir.path().join("a.exr")),
        exr(&dir.path().join("b.exr"))
    );
    let entries: Vec<_> = std::fs::read_dir(&cache).unwrap().collect();
    assert_eq!(entries.len(), 1);
    std::fs::write(entries[0].as_ref().unwrap().path(), b"garbage").unwrap();
    let third = run("c.exr");
    assert!(third.contains("rendered in"), "{third}");
    assert_eq!(
        exr(&dir.path().join("a.exr")),
        exr(&dir.path().join("c.exr"))
    );
    // An edit to the scene is a new entry, never the stale one.
    write(dir.path(), "s.toml", &SCENE.replace("kr = 0.7", "kr = 0.6"));
    assert!(run("d.exr").contains("rendered in"));
    assert_ne!(
        exr(&dir.path().join("a.exr")),
        exr(&dir.path().join("d.exr"))
    );
}

#[test]
fn the_chart_measures_each_knob_against_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let csv_path = dir.path().join("c.csv");
    let svg = dir.path().join("c.svg");
    whitted()
        .args([
            "chart",
            "-q",
            "--knobs",
            "max-depth,spp,precision",
            "--runs",
            "1",
            "--reference-spp",
            "16",
            "--cache",
        ])
        .arg(dir.path().join("cache"))
        .arg(&scene)
        .arg("-o")
        .arg(&svg)
        .arg("--csv")
        .arg(&csv_path)
        .assert()
        .success();
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    let mut r = csv::Reader::from_path(&csv_path).unwrap();
    let h = r.headers().unwrap().clone();
    let col = |name: &str| h.iter().position(|x| x == name).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    let get = |knob: &str, value: &str, c: &str| -> f64 {
        let row = rows
            .iter()
            .find(|r| &r[0] == knob && &r[1] == value)
            .unwrap_or_else(|| panic!("no row {knob}={value}"));
        row[col(c)].parse().unwrap()
    };
    assert_eq!(rows.len(), 10 + 7 + 2);
    // Depth 0 misses every reflection; depth 16 leaves only sampling error.
    assert!(get("max-depth", "0", "rmse") > 2.0 * get("max-depth", "16", "rmse"));
    // Against the reference through the same samples the deep tree is
    // nearly exact, and more samples bring the total error down.
    assert!(get("max-depth", "16", "own_rmse") < 1e-3);
    assert!(get("spp", "16", "rmse") < get("spp", "1", "rmse"));
    // f64 and f32 differ by far less than a display step.
    assert!((get("precision", "f64", "rmse") - get("precision", "f32", "rmse")).abs() < 1e-4);
    // Some point is on the front, and the cheapest point always is.
    let pareto: Vec<bool> = rows.iter().map(|r| &r[col("pareto")] == "true").collect();
    let t: Vec<f64> = rows
        .iter()
        .map(|r| r[col("seconds_median")].parse().unwrap())
        .collect();
    let fastest = (0..t.len()).min_by(|&a, &b| t[a].total_cmp(&t[b])).unwrap();
    // Of points tied at the least time, the most accurate is on the front
    // (the others are dominated by it).
    assert!((0..t.len()).any(|i| t[i] == t[fastest] && pareto[i]));
}
