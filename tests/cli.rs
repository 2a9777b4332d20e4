//! `whitted` end to end: renders, stats, and every kind of bad input
//! (exit code 2, a message naming file:line:column, no output written).

use assert_cmd::Command;
use common::render_stats;
use std::path::Path;

mod common;

fn whitted() -> Command {
    Command::cargo_bin("whitted").unwrap()
}

const SCENE: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\nwidth = 32\nheight = 24\n\n\
[[light]]\nposition = [5, -5, 10]\n\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 1]\nradius = 1\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn renders_png_with_stats() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let out = dir.path().join("out.png");
    let stats = dir.path().join("stats.json");
    whitted()
        .args([
            "render",
            "-q",
            "--backend",
            "cpu",
            "--width",
            "40",
            "--spp",
            "4",
        ])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .arg("--stats")
        .arg(&stats)
        .assert()
        .success();
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (40, 24));
    // the sphere is in the middle, the background (black) in the corner
    assert_ne!(img.get_pixel(20, 12).0, [0, 0, 0]);
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(j["backend"], "cpu");
    assert_eq!(j["width"], 40);
    assert_eq!(j["height"], 24);
    assert_eq!(j["rays"]["eye"], 40 * 24 * 4);
    let hit = j["rays"]["eye_hit"].as_u64().unwrap();
    assert!(hit > 0 && hit < 40 * 24 * 4);
    assert_eq!(j["rays"]["shadow"].as_u64().unwrap(), {
        // every hit faces the light or not; at most one feeler per hit
        let s = j["rays"]["shadow"].as_u64().unwrap();
        assert!(s <= hit && s > hit / 4);
        s
    });
    for k in ["load", "build", "render", "total"] {
        assert!(j["seconds"][k].as_f64().unwrap() >= 0.0);
    }
    assert_eq!(j["grid"]["cells"].as_array().unwrap().len(), 3);
    // The structure in use, and the work it did.
    let work = &j["work"];
    match j["accel"]["structure"].as_str().unwrap() {
        "grid" => {
            assert!(j["grid"]["refs"].as_u64().unwrap() >= 1);
            assert!(work["cells_visited"].as_u64().unwrap() >= 1);
        }
        "bvh" => {
            assert!(j["accel"]["nodes"].as_u64().unwrap() >= 1);
            assert!(work["nodes_visited"].as_u64().unwrap() >= 1);
        }
        s => panic!("structure {s}"),
    }
    assert!(j["accel"]["build_seconds"].as_f64().unwrap() >= 0.0);
    assert!(work["intersection_tests"].as_u64().unwrap() >= 1);
    // Per ray: the totals over every ray counted.
    let rays = ["eye", "reflect", "refract", "shadow"]
        .iter()
        .map(|k| j["rays"][k].as_u64().unwrap())
        .sum::<u64>() as f64;
    let per = j["work_per_ray"]["intersection_tests"].as_f64().unwrap();
    let total = work["intersection_tests"].as_u64().unwrap() as f64;
    assert!(
        (per * rays - total).abs() < 1e-6 * total,
        "{per} × {rays} vs {total}"
    );
}

/// `--accel octree` renders the grid's image, and `--stats` names the
/// octree, its shape and the leaves and descents of its walk.
#[test]
fn the_octree_renders_the_grids_image_and_reports_itself() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let mut images = Vec::new();
    for (accel, walk) in [
        ("grid", "neighbour"),
        ("octree", "neighbour"),
        ("octree", "stack"),
    ] {
        let out = dir.path().join(format!("{accel}-{walk}.png"));
        let stats = dir.path().join(format!("{accel}-{walk}.json"));
        Command::cargo_bin("whitted")
            .unwrap()
            .args([
                "render",
                "--backend",
                "cpu",
                "-q",
                "--accel",
                accel,
                "--octree-walk",
                walk,
            ])
            .arg(&scene)
            .arg("-o")
            .arg(&out)
            .arg("--stats")
            .arg(&stats)
            .assert()
            .success();
        images.push(std::fs::read(&out).unwrap());
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        assert_eq!(j["accel"]["structure"], accel);
        if accel == "octree" {
            assert!(j["accel"]["leaves"].as_u64().unwrap() >= 1);
            assert!(j["work"]["cells_visited"].as_u64().unwrap() >= 1);
        }
    }
    assert!(images[0] == images[1] && images[0] == images[2]);
}

#[test]
fn exr_and_linear_png_keep_linear_values() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "s.toml",
        &SCENE.replace("[camera]", "background = 0.5\n[camera]"),
    );
    let png = dir.path().join("lin.png");
    whitted()
        .args(["render", "-q", "--encoding", "linear"])
        .arg(&scene)
        .arg("-o")
        .arg(&png)
        .assert()
        .success();
    assert_eq!(
        image::open(&png).unwrap().to_rgb8().get_pixel(0, 0).0,
        [128, 128, 128]
    );
    let srgb = dir.path().join("srgb.png");
    whitted()
        .args(["render", "-q"])
        .arg(&scene)
        .arg("-o")
        .arg(&srgb)
        .assert()
        .success();
    assert_eq!(
        image::open(&srgb).unwrap().to_rgb8().get_pixel(0, 0).0,
        [188, 188, 188]
    );
    let exr = dir.path().join("out.exr");
    whitted()
        .args(["render", "-q"])
        .arg(&scene)
        .arg("-o")
        .arg(&exr)
        .assert()
        .success();
    let img = image::open(&exr).unwrap().to_rgb32f();
    assert_eq!(img.get_pixel(0, 0).0, [0.5, 0.5, 0.5]);
}

#[test]
fn corner_sampling_renders() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let j = render_stats(
        dir.path(),
        &scene,
        &["render", "-q", "--sampling", "corners"],
    );
    assert_eq!(j["rays"]["eye"], 33 * 25);
}

/// Renders `scene` with `flag bogus` to `dir/x.png`, expects exit code 2;
/// its stderr.
fn render_with_bogus(dir: &Path, scene: &Path, flag: &str) -> String {
    let a = whitted()
        .args(["render", flag, "bogus"])
        .arg(scene)
        .arg("-o")
        .arg(dir.join("x.png"))
        .assert()
        .code(2);
    String::from_utf8_lossy(&a.get_output().stderr).to_string()
}

/// `--shadows lightbuffer` renders the plain image byte for byte and says
/// so in `--stats`; anything else is a usage error (exit 2) naming the
/// values.
#[test]
fn shadows_option() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let mut images = Vec::new();
    for mode in ["plain", "lightbuffer"] {
        let out = dir.path().join(format!("{mode}.png"));
        let stats = dir.path().join(format!("{mode}.json"));
        whitted()
            .args(["render", "-q", "--backend", "cpu", "--shadows", mode])
            .arg(&scene)
            .arg("-o")
            .arg(&out)
            .arg("--stats")
            .arg(&stats)
            .assert()
            .success();
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        assert_eq!(j["shadows"], mode, "{j}");
        let cells = j["light_buffer"]["cells"].as_u64().unwrap();
        assert_eq!(cells > 0, mode == "lightbuffer", "{j}");
        images.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(images[0], images[1]);
    let err = render_with_bogus(dir.path(), &scene, "--shadows");
    assert!(
        err.contains("bogus") && err.contains("plain") && err.contains("lightbuffer"),
        "{err}"
    );
    assert!(!dir.path().join("x.png").exists());
}

/// `--counting` overrides the preset's: a glass sphere that does not
/// reflect (k_t > 0, k_r = 0) spawns, under SPD counting, reflection rays
/// of weight 0 for the counts alone. `--preset spd --counting traced`
/// writes the same image without them; a bad value is a usage error.
#[test]
fn counting_option_overrides_the_preset() {
    let dir = tempfile::tempdir().unwrap();
    let glass = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\nwidth = 24\nheight = 16\n\n\
        [[light]]\nposition = [5, -5, 10]\n\n\
        [material.glass]\nkd = 0.1\nkt = 0.9\nior = 1.5\n\n\
        [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 1]\nradius = 1\nmaterial = \"glass\"\n\n\
        [[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n";
    let scene = write(dir.path(), "g.toml", glass);
    let mut runs = Vec::new();
    for extra in [&[][..], &["--counting", "traced"], &["--counting", "spd"]] {
        let mut args = vec!["render", "-q", "--backend", "cpu", "--preset", "spd"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--width", "24", "--height", "16"]);
        let j = render_stats(dir.path(), &scene, &args);
        let image = std::fs::read(dir.path().join("o.png")).unwrap();
        runs.push((j, image));
    }
    let reflect = |j: &serde_json::Value| j["rays"]["reflect"].as_u64().unwrap();
    let (spd, traced, spd_again) = (&runs[0], &runs[1], &runs[2]);
    assert_eq!(spd.0["counting"], "Spd", "{}", spd.0);
    assert_eq!(traced.0["counting"], "Traced", "{}", traced.0);
    assert_eq!(spd_again.0["counting"], "Spd");
    assert!(
        reflect(&traced.0) < reflect(&spd.0),
        "traced {} against spd {}",
        reflect(&traced.0),
        reflect(&spd.0)
    );
    assert_eq!(reflect(&spd_again.0), reflect(&spd.0));
    assert_eq!(spd.1, traced.1, "the same image");
    let err = render_with_bogus(dir.path(), &scene, "--counting");
    assert!(err.contains("traced") && err.contains("spd"), "{err}");
    assert!(!dir.path().join("x.png").exists());
}

/// `--gpu-math`: `fast` is a value render takes (with the CPU backend it
/// changes nothing and says so); anything else is a usage error (exit 2)
/// naming the values.
#[test]
fn gpu_math_option() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    let out = dir.path().join("out.png");
    let a = whitted()
        .args(["render", "--backend", "cpu", "--gpu-math", "fast"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .success();
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(err.contains("--gpu-math fast has no effect"), "{err}");
    assert!(out.exists());
    let err = render_with_bogus(dir.path(), &scene, "--gpu-math");
    assert!(
        err.contains("bogus") && err.contains("exact") && err.contains("fast"),
        "{err}"
    );
    whitted()
        .args(["validate", "--gpu-math", "bogus"])
        .arg(&scene)
        .assert()
        .code(2);
}

/// Runs a render of `text` saved as `name` and expects exit code 2, stderr
/// containing `fragment`, and no output file.
fn bad_input(name: &str, text: &str, fragment: &str) {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), name, text);
    let out = dir.path().join("out.png");
    let a = whitted()
        .args(["render", "-q"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2);
    let err = String::from_utf8_lossy(&a.get_output().stderr).to_string();
    assert!(err.contains(fragment), "stderr {err:?} lacks {fragment:?}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "an output file was written");
    // nothing half-written left beside it either
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
}

#[test]
fn bad_scenes_exit_2_with_position_and_write_nothing() {
    bad_input(
        "a.toml",
        &SCENE.replace("radius = 1", "radus = 1"),
        "a.toml:13:1",
    );
    bad_input(
        "b.toml",
        &SCENE.replace("radius = 1", "radius = 0"),
        "b.toml:13:10",
    );
    bad_input(
        "c.toml",
        &SCENE.replace("radius = 1", "radius = nan"),
        "c.toml:13:10",
    );
    bad_input(
        "d.toml",
        &SCENE.replace("radius = 1", "radius = inf"),
        "d.toml:13:10",
    );
    bad_input(
        "e.toml",
        &SCENE.replace("at = [0, 0, 0]\n", ""),
        "e.toml:1:1",
    );
    bad_input(
        "f.toml",
        &format!("{SCENE}\n[[object]]\ntype = \"polygon\"\nvertices = [[0,0,0],[1,0,0],[2,0,0]]\n"),
        "f.toml:17:12",
    );
    bad_input(
        "g.toml",
        &format!("{SCENE}\n[material.x]\nior = -1\n"),
        "g.toml:16:7",
    );
    bad_input(
        "h.toml",
        &format!("{SCENE}\n[[object]]\ntype = \"mesh\"\nfile = \"missing.obj\"\n"),
        "h.toml:17:8",
    );
    bad_input(
        "t.nff",
        "v\nfrom 0 -5 0\nat 0 0 0\nup 0 0 1\nangle 40\nhither 1\nresolution 8 8\ns 0 0 0",
        "t.nff:8:",
    );
    bad_input(
        "u.nff",
        "v\nfrom 0 -5 0\nat 0 0 0\nup 0 0 1\nangle 40\nhither 1\nresolution 8 8\nq 1 2 3\n",
        "u.nff:8:1",
    );
}

#[test]
fn missing_scene_and_bad_options_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let a = whitted()
        .args(["render", "-q", "/nonexistent/scene.toml", "-o"])
        .arg(&out)
        .assert()
        .code(2);
    assert!(String::from_utf8_lossy(&a.get_output().stderr).contains("/nonexistent/scene.toml"));
    let scene = write(dir.path(), "s.toml", SCENE);
    for args in [
        vec!["--max-depth", "99"],
        vec!["--min-weight", "-1"],
        vec!["--grid", "4x4"],
        vec!["--spp", "0"],
        vec!["--sampling", "diagonal"],
    ] {
        whitted()
            .args(["render", "-q"])
            .arg(&scene)
            .args(&args)
            .arg("-o")
            .arg(&out)
            .assert()
            .code(2);
    }
    whitted()
        .args(["render", "-q"])
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("o.jpg"))
        .assert()
        .code(2);
    assert!(!out.exists());
}

#[test]
fn help_documents_every_option() {
    let a = whitted().args(["render", "--help"]).assert().success();
    let help = String::from_utf8_lossy(&a.get_output().stdout).to_string();
    for opt in [
        "--width",
        "--height",
        "--backend",
        "--max-depth",
        "--min-weight",
        "--spp",
        "--sampling",
        "--encoding",
        "--grid",
        "--threads",
        "--stats",
        "--quiet",
    ] {
        assert!(help.contains(opt), "render --help lacks {opt}");
    }
}

const NFF_VIEW: &str = "b 0.1 0.1 0.2\nv\nfrom 0 -6 2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\n\
resolution 32 24\nl 4 -3 5\nf 1 0.5 0.3 0.8 0.2 30 0 1\n";

/// Renders `scene` with `args` and returns (exit code, stderr, stats JSON
/// if the render succeeded); checks that a refusal leaves no file behind.
fn run_render(dir: &Path, scene: &Path, args: &[&str]) -> (i32, String, Option<serde_json::Value>) {
    let out = dir.join("out.png");
    let stats = dir.join("st.json");
    let _ = std::fs::remove_file(&out);
    let _ = std::fs::remove_file(&stats);
    let a = whitted()
        .args(["render", "-q", "--backend", "cpu"])
        .arg(scene)
        .args(args)
        .arg("-o")
        .arg(&out)
        .arg("--stats")
        .arg(&stats)
        .assert();
    let o = a.get_output();
    let code = o.status.code().unwrap_or(-1);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!err.contains("panicked"), "{err}");
    if code != 0 {
        assert!(!out.exists() && !stats.exists(), "a refusal wrote a file");
        let left: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().starts_with(".whitted-"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        return (code, err, None);
    }
    let j = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    (code, err, Some(j))
}

/// Issue 7's piles of identical spheres (which used to run out of memory,
/// panic or file for minutes) render, on one cell; small radii render on a
/// small grid. Radii f32 cannot hold (whose volume underflowed into a
/// 1023³ grid) are refused when the scene is read, at the value
/// (`docs/scene-format.md`, "f32 limits").
#[test]
fn degenerate_extents_render_on_a_small_grid() {
    let dir = tempfile::tempdir().unwrap();
    for (name, body, col) in [
        ("tiny-1e-120.nff", "s 0 0 0 1e-120\n", 9),
        ("tiny-5e-324.nff", "s 0 0 0 5e-324\n", 9),
        ("point-1e-300.nff", "s 0.5 0.5 0.5 1e-300\n", 15),
    ] {
        let scene = write(dir.path(), name, &format!("{NFF_VIEW}{body}"));
        let (code, err, _) = run_render(dir.path(), &scene, &[]);
        assert_eq!(code, 2, "{name}: {err}");
        let at = format!("{name}:11:{col}: radius must be at least 1e-18");
        assert!(err.contains(&at), "{name}: {err}");
    }
    for (name, body, cells_max) in [
        ("same-100k.nff", "s 0 0 0 1\n".repeat(100_000), 1),
        ("tiny-1e-5.nff", "s 0 0 0 1e-5\n".into(), 3000),
        ("point-10k.nff", "s 0.5 0.5 0.5 1e-5\n".repeat(10_000), 1),
    ] {
        let scene = write(dir.path(), name, &format!("{NFF_VIEW}{body}"));
        let (code, err, j) = run_render(dir.path(), &scene, &[]);
        assert_eq!(code, 0, "{name}: {err}");
        let j = j.unwrap();
        let cells: u64 = j["grid"]["cells"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_u64().unwrap())
            .product();
        assert!(cells <= cells_max, "{name}: {}", j["grid"]);
        assert!(
            j["grid"]["refs"].as_u64().unwrap() <= 8,
            "{name}: {}",
            j["grid"]
        );
        std::fs::remove_file(&scene).unwrap();
    }
}

/// `--width 65536 --height 65536` and `--grid 1023x1023x1023` are
/// refused by estimate (exit 2, naming the size, the limit and the flag)
/// before anything large is allocated; `--memory-limit` sets the limit so
/// the answer is the same on every machine.
#[test]
fn oversized_images_and_grids_are_refused_by_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "s.toml", SCENE);
    for (args, says) in [
        (
            &["--width", "65536", "--height", "65536"][..],
            "the image needs",
        ),
        (
            &[
                "--width",
                "65536",
                "--height",
                "65536",
                "--sampling",
                "corners",
                "--spp",
                "4096",
            ][..],
            "for 4.3 G samples",
        ),
        (&["--grid", "1023x1023x1023"][..], "coarser --grid"),
    ] {
        let mut a = args.to_vec();
        a.extend(["--memory-limit", "4GiB"]);
        let (code, err, _) = run_render(dir.path(), &scene, &a);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains(says)
                && err.contains("--memory-limit")
                && err.contains("limit 4.0 GiB, as asked"),
            "{args:?}: {err}"
        );
    }
    // a tiny limit refuses even a small render, naming the flag's value
    let (code, err, _) = run_render(
        dir.path(),
        &scene,
        &[
            "--width",
            "640",
            "--height",
            "480",
            "--memory-limit",
            "100K",
        ],
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--memory-limit"), "{err}");
    // and the same render fits a sensible one
    let (code, err, _) = run_render(dir.path(), &scene, &["--memory-limit", "1%"]);
    assert_eq!(code, 0, "{err}");
    for bad in ["0", "-1G", "12 parsecs", "101%", "99999999999999999999T"] {
        let out = whitted()
            .args(["render", "-q", "--backend", "cpu"])
            .arg(&scene)
            .args(["--memory-limit", bad, "-o"])
            .arg(dir.path().join("x.png"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "--memory-limit {bad}");
    }
}

/// The README's command list names every option each command's --help
/// lists (so neither drifts from the other).
#[test]
fn readme_lists_every_option_of_every_command() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let start = readme
        .find("## The command line")
        .expect("README has the command line section");
    let section = &readme[start..];
    let skip = ["--help", "--version", "--verbose", "--quiet"];
    for cmd in [
        "render",
        "validate",
        "devices",
        "generate",
        "export",
        "bench",
        "reference",
        "chart",
    ] {
        let a = whitted().args([cmd, "--help"]).assert().success();
        let help = String::from_utf8_lossy(&a.get_output().stdout).to_string();
        let mut seen = 0;
        for line in help.lines().map(str::trim_start) {
            // "-o, --output <OUTPUT>  ..." or "--width <WIDTH>  ..."
            let (short, rest) = match line.strip_prefix('-') {
                Some(r) if !r.starts_with('-') && r.len() > 3 && &r[1..3] == ", " => {
                    (Some(format!("-{}", &r[..1])), &r[3..])
                }
                _ => (None, line),
            };
            let Some(long) = rest.strip_prefix("--") else {
                continue;
            };
            let long = format!(
                "--{}",
                long.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                    .next()
                    .unwrap()
            );
            if skip.contains(&long.as_str()) {
                continue;
            }
            seen += 1;
            let listed = section.contains(&long)
                || short
                    .as_ref()
                    .is_some_and(|s| section.contains(&format!("{s} ")));
            assert!(listed, "README's command list lacks `{cmd} {long}`");
        }
        assert!(
            seen > 0 || cmd == "devices",
            "{cmd}: no option read from --help"
        );
    }
}

/// `--packet`: widths 1, 4 and 8 write the same image and count the same
/// rays under the BVH (where packets walk); any other width is refused
/// with exit 2 before anything is written.
#[test]
fn packet_widths_render_one_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/showcase.toml");
    let mut images = Vec::new();
    for width in ["1", "4", "8"] {
        let out = dir.path().join(format!("p{width}.png"));
        let stats = dir.path().join(format!("p{width}.json"));
        whitted()
            .args(["render", "-q", "--backend", "cpu", "--accel", "bvh"])
            .args([
                "--width", "61", "--height", "37", "--spp", "2", "--packet", width,
            ])
            .arg(&scene)
            .arg("-o")
            .arg(&out)
            .arg("--stats")
            .arg(&stats)
            .assert()
            .success();
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        images.push((image::open(&out).unwrap().to_rgb32f(), j["rays"].clone()));
    }
    assert!(images.iter().all(|i| *i == images[0]));
    let out = dir.path().join("bad.png");
    let a = whitted()
        .args(["render", "-q", "--backend", "cpu", "--packet", "3"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2);
    assert!(String::from_utf8_lossy(&a.get_output().stderr).contains("--packet"));
    assert!(!out.exists());
}

/// `--stats` says how much of the grid the hybrid nested: the cells that
/// hold a BVH (each listed more than --hybrid-cell primitives) and their
/// references; zero for the plain grid.
#[test]
fn stats_report_the_hybrids_nested_cells() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("balls.nff");
    Command::cargo_bin("whitted")
        .unwrap()
        .args(["-q", "generate", "balls", "--size", "2", "-o"])
        .arg(&scene)
        .assert()
        .success();
    let stats_of = |extra: &[&str]| {
        let mut args = vec![
            "-q",
            "render",
            "--backend",
            "cpu",
            "--width",
            "16",
            "--height",
            "16",
        ];
        args.extend_from_slice(extra);
        let j = render_stats(dir.path(), &scene, &args);
        let n = |k: &str| j["accel"][k].as_u64().unwrap();
        (n("hybrid_cells"), n("hybrid_refs"))
    };
    let (cells, refs) = stats_of(&["--accel", "hybrid", "--hybrid-cell", "2"]);
    assert!(cells >= 1, "{cells}");
    assert!(refs > 2 * cells, "{cells} cells, {refs} refs");
    assert_eq!(stats_of(&["--accel", "grid"]), (0, 0));
}

/// `--stats` counts the long opaque cones the BVH holds as two halves
/// (`pack::bvh_pieces`): every cylinder of a ring of them under the BVH,
/// none under the grid.
#[test]
fn stats_count_the_halved_cones() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("ring.nff");
    let mut nff = String::from(
        "v\nfrom 0 -10 2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 1\nresolution 16 16\n\
         l 5 -5 5\nf 1 0.2 0.2 0.8 0 30 0 0\n",
    );
    for k in 0..12 {
        let step = std::f64::consts::FRAC_PI_6;
        let (a, b) = (k as f64 * step, (k + 1) as f64 * step);
        nff += &format!(
            "c {} {} 0 0.05 {} {} 0 0.05\n",
            2.0 * a.cos(),
            2.0 * a.sin(),
            2.0 * b.cos(),
            2.0 * b.sin()
        );
    }
    std::fs::write(&scene, nff).unwrap();
    let halved = |accel: &str| {
        let j = render_stats(dir.path(), &scene, &["render", "-q", "--accel", accel]);
        j["accel"]["halved_cones"].as_u64().unwrap()
    };
    assert_eq!(halved("bvh"), 12);
    assert_eq!(halved("grid"), 0);
}
