//! `whitted bench` end to end on a tiny suite: every case and engine gets a
//! row with the counts `whitted render --stats` reports, the CSV and the
//! plots are written, and --vs povray times POV-Ray beside us when it is
//! installed (required when WHITTED_REQUIRE_POVRAY=1).

use assert_cmd::Command;

mod common;

fn whitted() -> Command {
    Command::cargo_bin("whitted").unwrap()
}

fn require_povray() -> bool {
    std::env::var("WHITTED_REQUIRE_POVRAY").is_ok_and(|v| v == "1")
}

fn have_povray() -> bool {
    std::process::Command::new("povray")
        .arg("--version")
        .output()
        .is_ok()
}

/// Runs `whitted bench ARGS --csv FILE` in the repository; returns the
/// CSV's text, header and rows.
fn bench_csv(
    args: &[&str],
    csv: &std::path::Path,
) -> (String, csv::StringRecord, Vec<csv::StringRecord>) {
    let out = whitted()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .arg("--csv")
        .arg(csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(csv).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let header = r.headers().unwrap().clone();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    (text, header, rows)
}

/// `bench_csv` on the SPD scenes at size 1, 32×32, CPU only, one run and
/// no warm-up, with `extra` arguments.
fn small_spd_bench(
    extra: &[&str],
    csv: &std::path::Path,
) -> (String, csv::StringRecord, Vec<csv::StringRecord>) {
    let mut args = vec![
        "-q",
        "bench",
        "--suite",
        "spd",
        "--size",
        "1",
        "--runs",
        "1",
        "--warmup",
        "0",
        "--resolution",
        "32x32",
        "--backends",
        "cpu",
    ];
    args.extend_from_slice(extra);
    bench_csv(&args, csv)
}

#[test]
fn bench_writes_a_row_per_case_and_engine() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("b.csv");
    let plot = d.path().join("b.svg");
    let mut args = vec![
        "-q",
        "bench",
        "--suite",
        "examples,spheres",
        "--runs",
        "2",
        "--warmup",
        "0",
        "--resolution",
        "24x16",
        "--backends",
        "cpu",
    ];
    let vs = have_povray();
    assert!(vs || !require_povray(), "povray is not installed");
    if vs {
        args.extend(["--vs", "povray"]);
    } else {
        eprintln!("note: povray is not installed: --vs povray is not tested");
    }
    let root = env!("CARGO_MANIFEST_DIR");
    let plot_arg = plot.to_str().unwrap().to_string();
    args.extend(["--plot", plot_arg.as_str()]);
    let (_, header, rows) = bench_csv(&args, &csv);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let examples = std::fs::read_dir(format!("{root}/scenes"))
        .unwrap()
        .filter(|e| {
            let p = e.as_ref().unwrap().path();
            matches!(p.extension().and_then(|x| x.to_str()), Some("toml" | "nff"))
        })
        .count();
    let engines = if vs { 2 } else { 1 };
    assert_eq!(rows.len(), (examples + 1) * engines);
    for row in rows.iter().filter(|x| &x[col("engine")] == "cpu") {
        assert_eq!(&row[col("runs")], "2");
        assert_eq!(&row[col("width")], "24");
        // 24x16 eye rays at least; every ray counted
        let rays: u64 = row[col("rays")].parse().unwrap();
        assert!(rays >= 24 * 16, "{row:?}");
        let render: f64 = row[col("render_median_s")].parse().unwrap();
        let mrays: f64 = row[col("mrays_per_s")].parse().unwrap();
        assert!((mrays - rays as f64 / render / 1e6).abs() <= 1e-6 * mrays.max(1.0));
        let peak: u64 = row[col("peak_bytes")].parse().unwrap();
        assert!(peak > 1 << 20);
        let (lo, med, hi): (f64, f64, f64) = (
            row[col("wall_min_s")].parse().unwrap(),
            row[col("wall_median_s")].parse().unwrap(),
            row[col("wall_max_s")].parse().unwrap(),
        );
        assert!(lo <= med && med <= hi && lo > 0.0);
        // The work per kind of ray, filled in: every case's eye rays and
        // feelers test primitives (the spheres and the example scenes
        // are lit), and the deepest stack is a count.
        let per = |name: &str| -> f64 { row[col(name)].parse().unwrap() };
        assert!(per("eye_tests_per_ray") > 0.0, "{row:?}");
        assert!(per("shadow_tests_per_ray") > 0.0, "{row:?}");
        assert!(per("eye_steps_per_ray") >= 0.0 && per("secondary_steps_per_ray") >= 0.0);
        let _: u64 = row[col("deepest_stack")].parse().unwrap();
        if vs {
            let ratio: f64 = row[col("povray_over_this")].parse().unwrap();
            assert!(ratio > 0.0);
            let psnr: f64 = row[col("psnr_vs_povray_db")].parse().unwrap();
            assert!(psnr > 10.0, "{row:?}");
        }
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("spheres-20k") && svg.contains("median wall time"));
}

#[test]
fn bench_refuses_bad_requests_before_work() {
    let d = tempfile::tempdir().unwrap();
    for (args, fragment) in [
        (vec!["bench", "--csv", "x.txt"], "writes .csv"),
        (vec!["bench", "--plot", "x.pdf"], "writes .svg or .png"),
        (vec!["bench", "--only", "nothing-matches"], "no case to run"),
        (vec!["bench", "--runs", "0"], "0"),
        (vec!["bench", "--gpu-math", "fast"], "--gpu-math"),
        (vec!["bench", "--kernels", "wavefront"], "--kernels"),
    ] {
        let out = whitted()
            .current_dir(d.path())
            .args(&args)
            .args([
                "--suite",
                "spheres",
                "--backends",
                "cpu",
                "--resolution",
                "8x8",
            ])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(fragment), "{args:?}: {err}");
    }
}

/// A chart without a font is refused before the work (exit 2, the flag,
/// the file and the font named, nothing written): `WHITTED_FONT` names a
/// missing file, then one that is not a font.
#[test]
fn a_plot_without_a_font_is_refused_before_work() {
    let d = tempfile::tempdir().unwrap();
    let not_a_font = d.path().join("font.ttf");
    std::fs::write(&not_a_font, b"not a font").unwrap();
    for (font, fragment) in [
        (d.path().join("missing.ttf"), "cannot read"),
        (not_a_font, "not a usable TrueType font"),
    ] {
        let out = whitted()
            .current_dir(d.path())
            .env("WHITTED_FONT", &font)
            .args(["bench", "--suite", "spheres", "--backends", "cpu"])
            .args(["--resolution", "8x8", "--csv", "b.csv", "--plot", "b.svg"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains("--plot b.svg") && err.contains("WHITTED_FONT") && err.contains(fragment),
            "{err}"
        );
        assert!(!d.path().join("b.csv").exists() && !d.path().join("b.svg").exists());
    }
}

/// `--accel grid,bvh`: each backend once per structure, labelled by it,
/// with that structure's counters (cells for the grid, nodes for the BVH)
/// and the same rays.
#[test]
fn bench_times_each_structure() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("a.csv");
    let (text, header, rows) =
        small_spd_bench(&["--only", "teapot,balls", "--accel", "grid,bvh"], &csv);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    assert_eq!(rows.len(), 4, "{text}");
    for case in ["teapot-1", "balls-1"] {
        let of = |engine: &str| {
            rows.iter()
                .find(|x| &x[col("scene")] == case && &x[col("engine")] == engine)
                .unwrap_or_else(|| panic!("{case} {engine}: {text}"))
        };
        let (g, b) = (of("cpu/grid"), of("cpu/bvh"));
        // The same rays but for ties: a ray through an edge that two
        // primitives share meets both at one distance, and which of them
        // is the hit (so which normal spawns the children) follows the
        // order each structure tests them in.
        let rays = |r: &csv::StringRecord| r[col("rays")].parse::<f64>().unwrap();
        assert!(
            (rays(g) - rays(b)).abs() <= 0.005 * rays(g),
            "{case}: {} against {}",
            rays(g),
            rays(b)
        );
        let num = |r: &csv::StringRecord, c: &str| r[col(c)].parse::<f64>().unwrap_or(0.0);
        assert!(num(g, "cells_per_ray") > 0.0 && num(g, "nodes_per_ray") == 0.0);
        assert!(num(b, "nodes_per_ray") > 0.0 && num(b, "cells_per_ray") == 0.0);
    }
}

/// `--shadows plain,lightbuffer`: each backend once per shadow method,
/// labelled by it; the light buffers are exact, so the rays are the same
/// to the last one.
#[test]
fn bench_times_each_shadow_method() {
    let (p, l, text) = two_engines_rays(
        &[
            "--only",
            "balls",
            "--accel",
            "bvh",
            "--shadows",
            "plain,lightbuffer",
        ],
        "cpu/bvh/plain",
        "cpu/bvh/lightbuffer",
    );
    assert_eq!(p, l, "{text}");
}

/// `--backends auto` times `render`'s default backend beside the CPU
/// mirror: a row of its own, tracing the same rays (the CPU mirror's
/// where there is no GPU; a real GPU's may count a few differently).
#[test]
fn bench_times_the_default_backend() {
    let (c, a, text) = two_engines_rays(&["--only", "tetra", "--backends", "auto"], "cpu", "auto");
    assert!(c.abs_diff(a) * 100 <= c, "{text}");
}

/// `small_spd_bench` with `extra` on one scene: two rows, engines `a` and
/// `b`, and the rays each traced (more than none); and the CSV.
fn two_engines_rays(extra: &[&str], a: &str, b: &str) -> (u64, u64, String) {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("two.csv");
    let (text, header, rows) = small_spd_bench(extra, &csv);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    assert_eq!(rows.len(), 2, "{text}");
    let of = |engine: &str| {
        rows.iter()
            .find(|x| &x[col("engine")] == engine)
            .unwrap_or_else(|| panic!("{engine}: {text}"))
    };
    let rays = |engine: &str| of(engine)[col("rays")].parse::<u64>().unwrap();
    let (x, y) = (rays(a), rays(b));
    assert!(x > 0 && y > 0, "{text}");
    (x, y, text)
}

/// The SPD cases time the image: the rays `render --preset spd
/// --counting traced` traces, not the zero-weight rays the SPD's own
/// counting adds on gears (whose glass does not reflect), which change
/// no pixel and which POV-Ray does not trace.
#[test]
fn bench_times_the_spd_image_without_the_spd_counting() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("g.csv");
    let (text, header, rows) = small_spd_bench(&["--only", "gears"], &csv);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    assert_eq!(rows.len(), 1, "{text}");
    let benched: u64 = rows[0][col("rays")].parse().unwrap();
    let scene = d.path().join("gears.nff");
    whitted()
        .args(["-q", "generate", "gears", "--size", "1", "-o"])
        .arg(&scene)
        .assert()
        .success();
    let rays = |counting: &str| {
        let j = common::render_stats(
            d.path(),
            &scene,
            &[
                "-q",
                "render",
                "--backend",
                "cpu",
                "--preset",
                "spd",
                "--counting",
                counting,
                "--width",
                "32",
                "--height",
                "32",
            ],
        );
        ["eye", "reflect", "refract", "shadow"]
            .iter()
            .map(|k| j["rays"][k].as_u64().unwrap())
            .sum::<u64>()
    };
    let (traced, spd) = (rays("traced"), rays("spd"));
    assert!(spd > traced, "SPD counting {spd}, traced {traced}");
    assert_eq!(benched, traced, "{text}");
}
