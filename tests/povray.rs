//! Export fidelity: each example scene, and small scenes that isolate one
//! primitive or one material term, rendered by our CPU mirror and by
//! POV-Ray 3.7 from `export::to_pov`; the two images must agree to a PSNR
//! (linear RGB clamped to [0, 1], peak 1, metrics::psnr) measured for each
//! scene. The measured values and the reason for every difference are in
//! docs/povray.md; keep the two in step.
//!
//! Thresholds: where the export is exact, 90 dB. POV-Ray's 16-bit output
//! caps agreement near 107 dB, our f32 tracer against POV-Ray's f64 costs a
//! few dB at a handful of edge pixels (94.5 to 105.6 dB measured), and one
//! missing term costs far more (dropping phong: 38 dB on `sphere`, 55 dB
//! on `quadric`). Where a term differs for a
//! reason docs/povray.md states, the measured value less 2 dB: both
//! renderers are deterministic, and the margin covers another build's libm
//! (pow, exp) or POV-Ray patch release moving a few pixels.
//!
//! POV-Ray missing: the tests print a note and pass, unless
//! WHITTED_REQUIRE_POVRAY=1 (scripts/test.sh, CI), which makes them fail.
//! WHITTED_POVRAY_OUT=DIR keeps each case's images there (whitted, POV-Ray,
//! difference ×4, side by side in NAME-all.png) with its .pov file; a
//! failing case keeps them in target/povray-diff/.

use std::path::{Path, PathBuf};
use whitted::cpu::{self, Frame};
use whitted::metrics;
use whitted::output::{self, Encoding};
use whitted::pack::{self, Sampling, Settings};
use whitted::scene::{self, Scene};

/// Image size of every comparison: big enough for the features, small
/// enough that the whole file runs in seconds.
const W: u32 = 160;
const H: u32 = 120;
const DEPTH: u32 = 5;
const MIN_WEIGHT: f32 = 1.0 / 256.0;

/// Threshold where `to_pov` reproduces every term (see the top).
const EXACT: f64 = 90.0;

fn require_povray() -> bool {
    std::env::var("WHITTED_REQUIRE_POVRAY").is_ok_and(|v| v == "1")
}

/// False (after a note) when POV-Ray is not installed and not required.
fn have_povray() -> bool {
    match whitted::povray::version() {
        Ok(v) => {
            eprintln!("comparing against {v}");
            true
        }
        Err(e) if !require_povray() => {
            eprintln!(
                "note: skipping the POV-Ray comparisons: {e:#} \
                 (set WHITTED_REQUIRE_POVRAY=1 to fail instead)"
            );
            false
        }
        Err(e) => panic!("WHITTED_REQUIRE_POVRAY=1 but POV-Ray cannot run: {e:#}"),
    }
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One comparison: a scene, how to sample it, and the least PSNR allowed.
struct Case {
    name: String,
    scene: Scene,
    sampling: Sampling,
    min_psnr: f64,
}

struct Measured {
    psnr: f64,
    flip: f64,
    /// Fraction of pixels with a channel off by more than one 8-bit step.
    over: f64,
    ours: Frame,
    theirs: Frame,
    pov: String,
}

/// Renders a case both ways and compares.
fn measure(c: &Case) -> Measured {
    let dir = tempfile::tempdir().unwrap();
    let pov_path = dir.path().join("scene.pov");
    let pov = whitted::export::to_pov(&c.scene, W, H, DEPTH, MIN_WEIGHT).unwrap();
    std::fs::write(&pov_path, &pov).unwrap();
    let opts = whitted::povray::Options {
        threads: 2,
        sampling: c.sampling,
        ..whitted::povray::Options::new(W, H)
    };
    let theirs = whitted::povray::render(&pov_path, &opts)
        .unwrap_or_else(|e| panic!("{}: {e:#}", c.name))
        .frame;
    let settings = Settings {
        width: Some(W),
        height: Some(H),
        max_depth: DEPTH,
        min_weight: MIN_WEIGHT,
        sampling: c.sampling,
        ..Default::default()
    };
    let mut ours = cpu::render(&pack::pack(&c.scene, &settings).unwrap(), &|_, _| {});
    // POV-Ray clips to [0, 1], as any 8- or 16-bit file does.
    for p in &mut ours.pixels {
        *p = p.map(|v| v.clamp(0.0, 1.0));
    }
    let psnr = metrics::psnr(&ours.pixels, &theirs.pixels);
    let a = output::to_rgb8(&ours, Encoding::Srgb);
    let b = output::to_rgb8(&theirs, Encoding::Srgb);
    let (_, flip) = metrics::flip(a.as_raw(), b.as_raw(), W, H);
    let over = ours
        .pixels
        .iter()
        .zip(&theirs.pixels)
        .filter(|(p, q)| (0..3).any(|i| (p[i] - q[i]).abs() > 1.0 / 255.0))
        .count() as f64
        / ours.pixels.len() as f64;
    Measured {
        psnr,
        flip,
        over,
        ours,
        theirs,
        pov,
    }
}

/// Measures every case at once (POV-Ray spends most of its 0.6 s start-up
/// idle), prints the table, and fails listing every case under its bound.
fn check(cases: Vec<Case>) {
    let measured: Vec<Measured> = std::thread::scope(|sc| {
        let runs: Vec<_> = cases.iter().map(|c| sc.spawn(|| measure(c))).collect();
        runs.into_iter().map(|r| r.join().unwrap()).collect()
    });
    let keep_in = std::env::var("WHITTED_POVRAY_OUT").ok().map(PathBuf::from);
    let mut failures = Vec::new();
    for (c, m) in cases.iter().zip(&measured) {
        eprintln!(
            "{:<24} PSNR {:6.2} dB (min {:5.1})   mean FLIP {:.4}   pixels off by > 1/255: {:5.2}%",
            c.name,
            m.psnr,
            c.min_psnr,
            m.flip,
            m.over * 100.0
        );
        let failed = m.psnr.is_nan() || m.psnr < c.min_psnr;
        if let Some(dir) = &keep_in {
            keep(dir, &c.name, m);
        }
        if failed {
            keep(&repo().join("target/povray-diff"), &c.name, m);
            failures.push(format!(
                "{}: PSNR {:.2} dB, below {} dB (images in target/povray-diff/)",
                c.name, m.psnr, c.min_psnr
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "against POV-Ray (docs/povray.md):\n{}",
        failures.join("\n")
    );
}

/// Writes a case's .pov, both images, their difference (|a − b| × 4,
/// linear) and the three side by side, doubled (NAME-all.png).
fn keep(dir: &Path, name: &str, m: &Measured) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join(format!("{name}.pov")), &m.pov).unwrap();
    let diff = Frame {
        width: m.ours.width,
        height: m.ours.height,
        pixels: m
            .ours
            .pixels
            .iter()
            .zip(&m.theirs.pixels)
            .map(|(p, q)| [0, 1, 2].map(|i| (p[i] - q[i]).abs() * 4.0))
            .collect(),
        ..Default::default()
    };
    let images = [
        ("whitted", output::to_rgb8(&m.ours, Encoding::Srgb)),
        ("povray", output::to_rgb8(&m.theirs, Encoding::Srgb)),
        ("diff", output::to_rgb8(&diff, Encoding::Linear)),
    ];
    let (w, h) = (m.ours.width, m.ours.height);
    let mut all = image::RgbImage::new(3 * w, h);
    for (k, (what, img)) in images.iter().enumerate() {
        img.save(dir.join(format!("{name}-{what}.png"))).unwrap();
        image::imageops::replace(&mut all, img, (k as u32 * w) as i64, 0);
    }
    image::imageops::resize(&all, 6 * w, 2 * h, image::imageops::FilterType::Nearest)
        .save(dir.join(format!("{name}-all.png")))
        .unwrap();
}

fn load(file: &str) -> Scene {
    scene::load(&repo().join("scenes").join(file)).unwrap_or_else(|e| panic!("{e}"))
}

fn toml(text: &str) -> Scene {
    scene::parse_str(text, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"))
}

/// Camera, one white light and a floor, shared by the isolated cases.
const STAGE: &str = r#"
background = [0.1, 0.15, 0.3]
ambient = 0.2

[camera]
from = [0, -6, 2.5]
at = [0, 0, 0.6]
fov = 40

[[light]]
position = [-4, -5, 8]
color = 0.9

[material.floor]
color = [0.75, 0.7, 0.6]
ka = 0.2
kd = 0.8

[[object]]
type = "polygon"
vertices = [[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]]
material = "floor"
"#;

fn staged(extra: &str) -> Scene {
    toml(&format!("{STAGE}\n{extra}"))
}

#[test]
fn isolated_terms() {
    if !have_povray() {
        return;
    }
    // (name, what the stage gets, least PSNR): docs/povray.md says why
    // each bound below EXACT is where it is.
    let cases: &[(&str, &str, f64)] = &[
        (
            "sphere",
            r#"
[material.red]
color = [0.9, 0.2, 0.1]
ks = 0.5
shine = 40
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "red"
"#,
            EXACT,
        ),
        (
            "box",
            r#"
[material.green]
color = [0.2, 0.8, 0.3]
ks = 0.3
shine = 20
[[object]]
type = "box"
min = [-1, -0.7, 0]
max = [0.8, 0.9, 1.3]
material = "green"
"#,
            EXACT,
        ),
        (
            "quadric",
            r#"
[material.blue]
color = [0.2, 0.4, 0.9]
ks = 0.5
shine = 60
[[object]]
type = "quadric"
coefficients = [1, 1, -1, 0, 0, 0, 0, 0, 2, -0.75]
clip = { min = [-2, -2, 0], max = [2, 2, 2] }
material = "blue"
"#,
            EXACT,
        ),
        (
            "cone",
            r#"
[material.gold]
color = [0.9, 0.7, 0.2]
ks = 0.4
shine = 30
[[object]]
type = "cone"
base = [-0.8, 0, 0]
base_radius = 0.9
apex = [-0.8, 0, 2]
apex_radius = 0.2
material = "gold"
[[object]]
type = "cylinder"
base = [1.2, 0.5, 0]
apex = [1.2, 0.5, 1.2]
radius = 0.5
material = "gold"
"#,
            EXACT,
        ),
        (
            "smooth_mesh",
            r#"
[material.porcelain]
color = [0.9, 0.85, 0.8]
ks = 0.5
shine = 80
[[object]]
type = "mesh"
file = "SCENES/icosphere.obj"
smooth = true
material = "porcelain"
"#,
            39.0,
        ),
        (
            "mirror",
            r#"
[material.mirror]
color = 0.9
ka = 0.02
kd = 0.1
ks = 0.8
shine = 200
kr = 0.8
[material.red]
color = [0.9, 0.2, 0.1]
[[object]]
type = "sphere"
center = [-0.6, 0, 1]
radius = 1
material = "mirror"
[[object]]
type = "sphere"
center = [1.4, -1, 0.5]
radius = 0.5
material = "red"
"#,
            EXACT,
        ),
        (
            // Two facing mirrors: the depth limit ends every path, so
            // max_trace_level must be the depth + 1 exactly.
            "facing_mirrors",
            r#"
[material.mirror]
color = [0.9, 0.95, 1]
ka = 0.05
kd = 0.1
kr = 0.85
[material.red]
color = [0.9, 0.2, 0.1]
[[object]]
type = "box"
min = [-3, 1, 0.1]
max = [3, 1.2, 3]
material = "mirror"
[[object]]
type = "box"
min = [-3, -8, 0.1]
max = [3, -7.8, 3]
material = "mirror"
[[object]]
type = "sphere"
center = [0.6, -2, 0.8]
radius = 0.7
material = "red"
"#,
            49.0,
        ),
        (
            "glass",
            r#"
[material.glass]
ka = 0
kd = 0.05
ks = 0.6
shine = 150
kr = 0.1
kt = 0.9
ior = 1.5
[material.red]
color = [0.9, 0.2, 0.1]
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "glass"
[[object]]
type = "sphere"
center = [0.8, 2.5, 0.5]
radius = 0.5
material = "red"
"#,
            42.0,
        ),
        (
            "absorbing_glass",
            r#"
[material.glass]
ka = 0
kd = 0
kt = 1
ior = 1.3
absorption = [0.1, 0.6, 1.2]
[[object]]
type = "box"
min = [-1, -1, 0.01]
max = [1, 1, 1.6]
material = "glass"
"#,
            EXACT,
        ),
        (
            "coloured_glass",
            r#"
[material.glass]
color = [1, 1, 1]
ka = 0.05
kd = 0.2
ks = 0.5
shine = 50
kt = [0.2, 0.5, 0.8]
ior = 1.2
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "glass"
"#,
            36.0,
        ),
        (
            // k_st (V·T_L)^n_t, lit from behind: POV-Ray has no such term.
            "transmission_highlight",
            r#"
[[light]]
position = [1, 6, 2.5]
color = 0.8
[material.glass]
ka = 0
kd = 0
kst = 0.8
shine_t = 30
kt = 0.9
ior = 1.1
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "glass"
"#,
            33.0,
        ),
        (
            // Fall-offs POV-Ray's fade expresses exactly: quadratic, linear,
            // and a pure inverse square (c1 = 0) never clamped here.
            "falloff_exact",
            r#"
[[light]]
position = [3, -2, 2]
color = [1.5, 0.3, 0.2]
falloff = [1, 0, 0.08]
[[light]]
position = [-2, -1, 1.5]
color = [0.2, 0.6, 2]
falloff = [1, 0.5, 0]
[[light]]
position = [2, -12, 8]
color = [0.4, 1.2, 0.3]
falloff = [0, 0, 0.012]
[material.white]
color = 0.9
ks = 0.4
shine = 30
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "white"
"#,
            EXACT,
        ),
        (
            // c1 < 1 and both terms: fitted (docs/povray.md).
            "falloff_fitted",
            r#"
[[light]]
position = [0, -2, 3]
color = [0.4, 1.2, 0.3]
falloff = [0.5, 0.2, 0.05]
[material.white]
color = 0.9
ks = 0.4
shine = 30
[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "white"
"#,
            43.0,
        ),
        (
            "polygons",
            r#"
[material.violet]
color = [0.6, 0.3, 0.9]
ks = 0.3
shine = 25
kr = 0.2
[[object]]
type = "polygon"
vertices = [[-2, 0, 0.1], [-0.5, 0, 0.1], [-0.5, 0, 1.8], [-1.2, 0, 0.9], [-2, 0, 1.8]]
material = "violet"
[[object]]
type = "mesh"
positions = [[0.2, -0.6, 0], [1.4, -0.6, 0], [1.4, 0.6, 0], [0.2, 0.6, 0], [0.8, 0, 1.4]]
triangles = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
material = "violet"
"#,
            EXACT,
        ),
        (
            "ambient",
            r#"
[material.lit]
color = [0.3, 0.9, 0.5]
ka = [0.6, 0.1, 0.9]
kd = 0
[[object]]
type = "sphere"
center = [-0.8, 0, 1]
radius = 0.8
material = "lit"
[[object]]
type = "triangle"
vertices = [[0.5, 0, 0.2], [2, 0, 0.2], [1.2, 0.5, 1.8]]
material = "lit"
"#,
            EXACT,
        ),
    ];
    let scenes = repo().join("scenes");
    check(
        cases
            .iter()
            .map(|(name, extra, min)| Case {
                name: name.to_string(),
                scene: staged(&extra.replace("SCENES/", &format!("{}/", scenes.display()))),
                sampling: Sampling::Centers,
                min_psnr: *min,
            })
            .collect(),
    );
}

#[test]
fn example_scenes() {
    if !have_povray() {
        return;
    }
    check(
        [
            // Glass: shadows through it, absorption (docs/povray.md).
            ("showcase.toml", 40.0),
            ("quadric.toml", EXACT),
            // Smooth-triangle silhouettes.
            ("mesh.toml", 38.0),
            // Reflections among small spheres: the surface offset.
            ("many.nff", 42.0),
        ]
        .into_iter()
        .map(|(file, min)| Case {
            name: file.to_string(),
            scene: load(file),
            sampling: Sampling::Centers,
            min_psnr: min,
        })
        .collect(),
    );
}

/// `--sampling corners` (the SPD's convention) against POV-Ray's adaptive
/// anti-aliasing at threshold 0, one level, no jitter.
#[test]
fn corner_sampling() {
    if !have_povray() {
        return;
    }
    // One corner ray meets the cone's apex exactly (docs/povray.md).
    check(vec![Case {
        name: "quadric.toml-corners".into(),
        scene: load("quadric.toml"),
        sampling: Sampling::Corners,
        min_psnr: 58.0,
    }]);
}
