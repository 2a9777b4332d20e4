//! Shared by the test files: one device per test binary, the skip/fail
//! policy, the validation-error check, and random scenes' helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use whitted::gpu::{Gpu, GpuError, GpuOptions};
use whitted::pack::{self, Packed, Settings};

/// The logger of a test binary: env_logger (RUST_LOG, default `warn`)
/// prints; every record of level warn or above is also kept for `logged`.
struct TestLog {
    print: env_logger::Logger,
    kept: Mutex<Vec<(log::Level, String)>>,
}

impl log::Log for TestLog {
    fn enabled(&self, m: &log::Metadata) -> bool {
        m.level() <= log::Level::Warn || self.print.enabled(m)
    }
    fn log(&self, r: &log::Record) {
        if r.level() <= log::Level::Warn {
            self.kept
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push((r.level(), r.args().to_string()));
        }
        self.print.log(r);
    }
    fn flush(&self) {}
}

fn test_log() -> &'static TestLog {
    static LOG: OnceLock<&'static TestLog> = OnceLock::new();
    LOG.get_or_init(|| {
        let print =
            env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn"))
                .is_test(true)
                .build();
        let max = print.filter().max(log::LevelFilter::Warn);
        let me: &'static TestLog = Box::leak(Box::new(TestLog {
            print,
            kept: Mutex::new(Vec::new()),
        }));
        log::set_logger(me).expect("one logger per test binary");
        log::set_max_level(max);
        me
    })
}

/// Installs the test logger (once per binary).
pub fn init_log() {
    test_log();
}

/// Every warning and error logged so far in this binary whose text
/// contains `needle`.
pub fn logged(needle: &str) -> Vec<(log::Level, String)> {
    test_log()
        .kept
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .iter()
        .filter(|(_, m)| m.contains(needle))
        .cloned()
        .collect()
}

/// `WHITTED_REQUIRE_GPU=1`: a missing Vulkan device fails the test.
pub fn require_gpu() -> bool {
    std::env::var("WHITTED_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// The device every GPU test of this binary shares (with the validation
/// layer on), or None (after a printed note) when there is no Vulkan
/// device and WHITTED_REQUIRE_GPU is not 1. Any other error fails.
pub fn gpu() -> Option<&'static Gpu> {
    static GPU: OnceLock<Option<Gpu>> = OnceLock::new();
    GPU.get_or_init(|| {
        init_log();
        // Before the instance exists: the layer is chosen at creation.
        std::env::set_var("WHITTED_VALIDATION", "1");
        match Gpu::new(&GpuOptions::default()) {
            Ok(g) => {
                eprintln!(
                    "GPU tests on {} ({}), validation layer {}",
                    g.info().name,
                    g.info().kind.name(),
                    if g.validation() {
                        "on"
                    } else {
                        "not installed"
                    }
                );
                Some(g)
            }
            Err(e @ GpuError::NoDevice(_)) if !require_gpu() => {
                eprintln!(
                    "note: skipping GPU tests: {e} (set WHITTED_REQUIRE_GPU=1 to fail instead)"
                );
                None
            }
            Err(e) => panic!("cannot open a Vulkan device: {e}"),
        }
    })
    .as_ref()
}

/// Fails when the validation layer (or driver) has reported an error.
pub fn assert_no_validation_errors() {
    assert_eq!(
        whitted::gpu::validation_errors(),
        0,
        "the Vulkan debug messenger reported errors (see stderr)"
    );
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn load(path: &Path, settings: &Settings) -> Packed {
    let s = whitted::scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    pack::pack(&s, settings).unwrap()
}

pub fn parse(text: &str, settings: &Settings) -> Packed {
    let s =
        whitted::scene::parse_str(text, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"));
    pack::pack(&s, settings).unwrap()
}

pub fn small(w: u32, h: u32) -> Settings {
    Settings {
        width: Some(w),
        height: Some(h),
        ..Default::default()
    }
}

/// A point or vector, shorter.
pub fn v(x: f64, y: f64, z: f64) -> glam::DVec3 {
    glam::DVec3::new(x, y, z)
}

/// xorshift64: deterministic scenes from a seed.
pub struct Rng(pub u64);

impl Rng {
    /// The next value in [0, 1).
    pub fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The random test scenes' frame (tests/accel.rs, tests/packets.rs): a
/// camera at (0, −20, 3) looking at the origin, `width` × `height`, two
/// lights, and four materials: matte, mirror, and glass letting through
/// `kt[0]` and `kt[1]` (per channel, index 1.3).
pub fn random_scene_frame(
    width: u32,
    height: u32,
    kt: [glam::DVec3; 2],
    objects: Vec<whitted::scene::Object>,
) -> whitted::scene::Scene {
    use glam::DVec3;
    use whitted::scene::{Camera, Light, Material, Scene};
    let glass = |kt: DVec3| Material {
        name: format!("glass {kt}"),
        kt,
        ior: 1.3,
        ..Material::default()
    };
    Scene {
        camera: Camera {
            from: v(0.0, -20.0, 3.0),
            at: DVec3::ZERO,
            up: v(0.0, 0.0, 1.0),
            fov: 45.0,
            width,
            height,
        },
        background: v(0.2, 0.3, 0.5),
        ambient: DVec3::splat(0.1),
        lights: vec![
            Light {
                position: v(8.0, -10.0, 12.0),
                color: DVec3::ONE,
                falloff: [1.0, 0.0, 0.0],
            },
            Light {
                position: v(-9.0, 4.0, 6.0),
                color: DVec3::splat(0.5),
                falloff: [1.0, 0.0, 0.0],
            },
        ],
        materials: vec![
            Material::default(),
            Material {
                name: "mirror".into(),
                kr: DVec3::splat(0.5),
                ..Material::default()
            },
            glass(kt[0]),
            glass(kt[1]),
        ],
        objects,
        source: std::path::PathBuf::from("random"),
    }
}

/// Runs `whitted ARGS SCENE -o DIR/o.png --stats DIR/s.json`, expects
/// success; the statistics.
pub fn render_stats(dir: &Path, scene: &Path, args: &[&str]) -> serde_json::Value {
    let stats = dir.join("s.json");
    assert_cmd::Command::cargo_bin("whitted")
        .unwrap()
        .args(args)
        .arg(scene)
        .arg("-o")
        .arg(dir.join("o.png"))
        .arg("--stats")
        .arg(&stats)
        .assert()
        .success();
    serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap()
}
