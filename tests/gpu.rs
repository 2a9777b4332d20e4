//! The Vulkan backend against the CPU mirror: layout, every scene, the
//! sampling modes, tiling, limits, and the CLI end to end. Each GPU test
//! asserts the validation layer reported no error.
//!
//! Without a Vulkan device these tests print a note and pass, unless
//! WHITTED_REQUIRE_GPU=1 (then they fail). The layout test and the
//! no-driver CLI test need no device.

mod common;

use assert_cmd::Command;
use std::collections::HashMap;
use std::mem::{offset_of, size_of};
use std::path::PathBuf;
use whitted::cpu::{self, Frame};
use whitted::gpu::{GpuError, GpuOptions, ProbeItem, ProbeResult};
use whitted::metrics::{self, Tolerance};
use whitted::pack::layout::{Globals, Light, Material, Prim};
use whitted::pack::{Packed, Sampling, Settings};

// ------------------------------------------------------------ SPIR-V layout

/// What the layout test needs from a SPIR-V module's decorations.
#[derive(Default)]
struct Reflection {
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    offsets: HashMap<(u32, u32), u32>,
    strides: HashMap<u32, u32>,
    structs: HashMap<u32, Vec<u32>>,
    arrays: HashMap<u32, u32>,
    pointers: HashMap<u32, u32>,
    vars: HashMap<u32, u32>,
    bindings: HashMap<u32, u32>,
}

fn spirv_string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn reflect(spv: &[u8]) -> Reflection {
    assert!(!spv.is_empty(), "shader missing from the build");
    let w: Vec<u32> = spv
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(w[0], 0x0723_0203, "not SPIR-V");
    let mut r = Reflection::default();
    let mut i = 5;
    while i < w.len() {
        let (n, op) = ((w[i] >> 16) as usize, w[i] & 0xffff);
        let a = &w[i + 1..i + n];
        match op {
            5 => {
                r.names.insert(a[0], spirv_string(&a[1..]));
            }
            6 => {
                r.member_names.insert((a[0], a[1]), spirv_string(&a[2..]));
            }
            71 if a[1] == 6 => {
                r.strides.insert(a[0], a[2]);
            }
            71 if a[1] == 33 => {
                r.bindings.insert(a[0], a[2]);
            }
            72 if a[2] == 35 => {
                r.offsets.insert((a[0], a[1]), a[3]);
            }
            28 | 29 => {
                r.arrays.insert(a[0], a[1]);
            }
            30 => {
                r.structs.insert(a[0], a[1..].to_vec());
            }
            32 => {
                r.pointers.insert(a[0], a[2]);
            }
            59 => {
                r.vars.insert(a[1], a[0]);
            }
            _ => {}
        }
        i += n.max(1);
    }
    r
}

impl Reflection {
    /// Member (name, offset) of the laid-out struct type called `name`.
    fn layout(&self, name: &str) -> Vec<(String, u32)> {
        let id = self
            .structs
            .keys()
            .copied()
            .filter(|id| self.names.get(id).is_some_and(|n| n == name))
            .find(|id| self.offsets.contains_key(&(*id, 0)))
            .unwrap_or_else(|| panic!("no laid-out struct {name} in the module"));
        (0..self.structs[&id].len() as u32)
            .map(|m| (self.member_names[&(id, m)].clone(), self.offsets[&(id, m)]))
            .collect()
    }

    /// (element type name or "", array stride) of the array in the block
    /// at `binding`.
    fn binding_array(&self, binding: u32) -> (String, u32) {
        let var = *self
            .bindings
            .iter()
            .find(|(v, b)| **b == binding && self.vars.contains_key(v))
            .unwrap_or_else(|| panic!("no variable at binding {binding}"))
            .0;
        let block = self.pointers[&self.vars[&var]];
        let member = self.structs[&block][0];
        let elem = self.arrays.get(&member).copied().unwrap_or(member);
        let name = self.names.get(&elem).cloned().unwrap_or_default();
        (name, self.strides.get(&member).copied().unwrap_or(0))
    }
}

macro_rules! fields {
    ($t:ty: $($f:ident),*) => {
        vec![$((stringify!($f).to_string(), offset_of!($t, $f) as u32)),*]
    };
}

/// Every struct the shaders read or write, member by member and offset by
/// offset, against the Rust definitions; every array's stride against
/// size_of. A padding slip or reordering on either side fails here.
#[test]
fn shader_layout_matches_rust() {
    type Members = Vec<(String, u32)>;
    let expect: Vec<(&str, Members, usize)> = vec![
        (
            "Globals",
            fields!(Globals: cam_right, cam_up, cam_forward, background, ambient, grid_min,
                    grid_max, grid_cell, grid_dims, counts, image, trace, params, flags),
            size_of::<Globals>(),
        ),
        (
            "Prim",
            fields!(Prim: kind_mat, data, cell_lo, cell_hi, a, b, c),
            size_of::<Prim>(),
        ),
        (
            "Material",
            fields!(Material: ka, kd, ks, kr, kt, absorb),
            size_of::<Material>(),
        ),
        (
            "Light",
            fields!(Light: pos, color, falloff),
            size_of::<Light>(),
        ),
    ];
    for (kernel, spv) in [
        ("render", whitted::gpu::shaders::RENDER),
        ("probe", whitted::gpu::shaders::PROBE),
    ] {
        let r = reflect(spv);
        for (name, fields, size) in &expect {
            let got = r.layout(name);
            assert_eq!(&got, fields, "{kernel}.comp: struct {name}");
            // Every member is 16 bytes or a uint quadruple: the size is the
            // last offset plus 16.
            assert_eq!(
                got.last().unwrap().1 as usize + 16,
                *size,
                "{kernel}.comp: size of {name}"
            );
        }
        let arrays = [
            (1, "Prim", size_of::<Prim>()),
            (2, "", 16),
            (3, "Material", size_of::<Material>()),
            (4, "Light", size_of::<Light>()),
            (5, "", 4),
            (6, "", 4),
        ];
        for (b, elem, stride) in arrays {
            let (e, s) = r.binding_array(b);
            assert_eq!(
                (e.as_str(), s as usize),
                (elem, stride),
                "{kernel}.comp binding {b}"
            );
        }
        if kernel == "render" {
            assert_eq!(r.binding_array(7).1, 16, "render.comp samples");
            assert_eq!(r.binding_array(8).1, 4, "render.comp counts");
        } else {
            let pi = fields!(ProbeItem: o, d, u);
            let pr = fields!(ProbeResult: a, b, u);
            assert_eq!(r.layout("ProbeItem"), pi);
            assert_eq!(r.layout("ProbeResult"), pr);
            assert_eq!(
                r.binding_array(9),
                ("ProbeItem".into(), size_of::<ProbeItem>() as u32)
            );
            assert_eq!(
                r.binding_array(10),
                ("ProbeResult".into(), size_of::<ProbeResult>() as u32)
            );
        }
    }
}

// ------------------------------------------------------------ GPU vs CPU

fn render_both(p: &Packed, opts: &GpuOptions) -> Option<(Frame, Frame)> {
    let g = common::gpu()?;
    let gf = g
        .render(p, opts, &|_, _| {})
        .unwrap_or_else(|e| panic!("GPU render: {e}"));
    common::assert_no_validation_errors();
    let cf = cpu::render(p, &|_, _| {});
    Some((cf, gf))
}

/// Compares within `Tolerance::default()` (docs/gpu.md); on failure writes
/// the difference image and names it.
fn assert_close(name: &str, cpu: &Frame, gpu: &Frame) {
    let c = metrics::compare(cpu, gpu, &Tolerance::default());
    println!(
        "{name}: max abs {:.2e}, mean abs {:.2e}, PSNR {:.1} dB, FLIP {:.5}, {} pixels over; rays {:?}",
        c.max_abs, c.mean_abs, c.psnr, c.mean_flip, c.pixels_over, gpu.stats
    );
    if !c.passed() {
        let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("{}-diff.png", name.replace(['/', ' '], "_")));
        c.diff_image().save(&path).unwrap();
        panic!(
            "{name}: {}; difference image: {}",
            c.failures.join("; "),
            path.display()
        );
    }
}

fn scene_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(common::repo().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(!v.is_empty());
    v
}

#[test]
fn every_scene_matches_the_cpu_mirror() {
    for path in scene_files() {
        let p = common::load(&path, &common::small(96, 72));
        let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
            return;
        };
        assert_close(&path.file_name().unwrap().to_string_lossy(), &c, &g);
    }
}

#[test]
fn corner_and_jittered_sampling_match() {
    let path = common::repo().join("scenes/showcase.toml");
    let cases = [
        (
            "corners",
            Settings {
                sampling: Sampling::Corners,
                ..common::small(48, 36)
            },
        ),
        (
            "spp 4",
            Settings {
                spp: 4,
                ..common::small(40, 30)
            },
        ),
        (
            "spp 3",
            Settings {
                spp: 3,
                ..common::small(40, 30)
            },
        ),
        (
            "corners depth 1",
            Settings {
                sampling: Sampling::Corners,
                max_depth: 1,
                ..common::small(33, 17)
            },
        ),
    ];
    for (name, s) in cases {
        let p = common::load(&path, &s);
        let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
            return;
        };
        if s.sampling == Sampling::Corners {
            assert_eq!(
                g.stats.eye,
                (s.width.unwrap() as u64 + 1) * (s.height.unwrap() as u64 + 1)
            );
        } else {
            assert_eq!(
                g.stats.eye,
                (s.width.unwrap() * s.height.unwrap() * s.spp) as u64
            );
        }
        assert_close(name, &c, &g);
    }
}

/// Tiles, workgroup shapes (and lavapipe's scattered workgroup order
/// with them), staged uploads and the counters' per-tile readback are
/// plumbing: they must not change a single bit or ray.
#[test]
fn tiles_and_workgroups_do_not_change_the_image() {
    let p = common::load(
        &common::repo().join("scenes/showcase.toml"),
        &Settings {
            sampling: Sampling::Corners,
            ..common::small(50, 37)
        },
    );
    let Some(g) = common::gpu() else { return };
    let base = g.render(&p, &GpuOptions::default(), &|_, _| {}).unwrap();
    for (tile, wg, staging) in [
        (7, [3, 5], false),
        (16, [16, 4], false),
        (5, [1, 1], false),
        (1000, [32, 2], false),
        // The upload a discrete GPU makes: through staging buffers.
        (64, [8, 8], true),
    ] {
        let calls = std::sync::atomic::AtomicU64::new(0);
        let f = g
            .render(
                &p,
                &GpuOptions {
                    tile,
                    workgroup: wg,
                    staging,
                    ..Default::default()
                },
                &|_, _| {
                    calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                },
            )
            .unwrap();
        let bits = |f: &Frame| {
            f.pixels
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        };
        assert!(
            bits(&f) == bits(&base),
            "tile {tile}, workgroup {wg:?}, staging {staging} changed the image"
        );
        assert_eq!(
            f.stats, base.stats,
            "tile {tile}, workgroup {wg:?}, staging {staging}"
        );
        let tiles = 51u64.div_ceil(tile as u64) * 38u64.div_ceil(tile as u64);
        assert_eq!(calls.into_inner(), tiles, "one progress call per tile");
        assert!(f.device_seconds.is_none() || f.device_seconds.unwrap() > 0.0);
    }
    common::assert_no_validation_errors();
}

#[test]
fn over_the_device_limits_is_a_clear_error() {
    let Some(g) = common::gpu() else { return };
    let range = g.info().max_storage_buffer_range;
    let mut p = common::load(
        &common::repo().join("scenes/mesh.toml"),
        &common::small(8, 8),
    );
    // A refs array one element over maxStorageBufferRange (calloc'd: cheap).
    p.refs = vec![0u32; (range / 4 + 1) as usize].into();
    let e = g
        .render(&p, &GpuOptions::default(), &|_, _| {})
        .unwrap_err();
    assert!(
        matches!(e, GpuError::Limits(_)) && e.is_user_error(),
        "{e:?}"
    );
    let msg = e.to_string();
    assert!(
        msg.contains("refs") && msg.contains("maxStorageBufferRange") && msg.contains("--grid"),
        "{msg}"
    );
    drop(p);
    // An output lattice over the limit.
    let side = ((range / 16) as f64).sqrt() as u32 + 2;
    let p = common::load(
        &common::repo().join("scenes/mesh.toml"),
        &common::small(side, side),
    );
    let e = g
        .render(&p, &GpuOptions::default(), &|_, _| {})
        .unwrap_err();
    assert!(e.to_string().contains("output samples"), "{e}");
    // A workgroup over maxComputeWorkGroupInvocations.
    let big = g.info().max_compute_work_group_invocations;
    let e = g
        .render(
            &p,
            &GpuOptions {
                workgroup: [big, 2],
                ..Default::default()
            },
            &|_, _| {},
        )
        .unwrap_err();
    assert!(e.to_string().contains("--workgroup"), "{e}");
    common::assert_no_validation_errors();
}

// ------------------------------------------------------------ CLI

fn whitted() -> Command {
    let mut c = Command::cargo_bin("whitted").unwrap();
    c.current_dir(common::repo());
    c
}

fn stderr_of(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn cli_backend_gpu_end_to_end() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("s.png");
    let json = dir.path().join("s.json");
    let o = whitted()
        .env("WHITTED_VALIDATION", "1")
        .args([
            "render",
            "scenes/showcase.toml",
            "--width",
            "64",
            "--height",
            "48",
            "--backend",
            "gpu",
            "--tile",
            "32",
            "--workgroup",
            "8x4",
            "-q",
            "-o",
        ])
        .arg(&png)
        .arg("--stats")
        .arg(&json)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr_of(&o));
    assert!(!stderr_of(&o).contains("vulkan error"), "{}", stderr_of(&o));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (64, 48));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(s["backend"], "gpu");
    assert_eq!(
        s["device"].as_str().unwrap(),
        common::gpu().unwrap().info().name
    );
    assert!(s["seconds"]["gpu"].is_number() || s["seconds"]["gpu"].is_null());
    assert_eq!(s["rays"]["eye"], 64 * 48);

    // validate: agrees, exit 0, with a difference image.
    let diff = dir.path().join("d.png");
    let o = whitted()
        .env("WHITTED_VALIDATION", "1")
        .args([
            "validate",
            "scenes/quadric.toml",
            "--width",
            "40",
            "--height",
            "30",
            "--diff",
        ])
        .arg(&diff)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}{}", stderr_of(&o));
    for k in [
        "max abs error",
        "PSNR",
        "mean FLIP",
        "pixels over",
        "shadow",
        "PASS",
    ] {
        assert!(out.contains(k), "validate output lacks {k}: {out}");
    }
    assert!(diff.exists());
    assert!(!stderr_of(&o).contains("vulkan error"), "{}", stderr_of(&o));

    // devices names the device and what each backend picks.
    let o = whitted().arg("devices").output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    for k in [
        "maxStorageBufferRange",
        "subgroup size",
        "--backend gpu: device",
        "--backend auto",
    ] {
        assert!(out.contains(k), "devices output lacks {k}: {out}");
    }

    // Bad device index and workgroup: exit 2 with the reason.
    let o = whitted()
        .args([
            "render",
            "scenes/showcase.toml",
            "--backend",
            "gpu",
            "--device",
            "99",
            "-o",
        ])
        .arg(dir.path().join("x.png"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr_of(&o).contains("--device 99"), "{}", stderr_of(&o));
    let o = whitted()
        .args(["render", "scenes/showcase.toml", "--workgroup", "0x4"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}

/// With no Vulkan driver at all (the loader pointed at a missing ICD):
/// `gpu` fails with exit 2, `auto` renders on the CPU and says why once,
/// `devices` says there is none. Needs no device.
#[test]
fn cli_without_a_vulkan_driver() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-icd.json");
    let no_vk = |c: &mut Command| {
        c.env("VK_DRIVER_FILES", &missing)
            .env("VK_ICD_FILENAMES", &missing)
            .env_remove("WHITTED_VALIDATION");
    };
    let png = dir.path().join("a.png");
    let mut c = whitted();
    no_vk(&mut c);
    let o = c
        .args([
            "render",
            "scenes/mesh.toml",
            "--width",
            "16",
            "--height",
            "12",
            "--backend",
            "gpu",
            "-o",
        ])
        .arg(&png)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
    assert!(
        stderr_of(&o).contains("no Vulkan device"),
        "{}",
        stderr_of(&o)
    );
    assert!(!stderr_of(&o).contains("panicked"));

    let mut c = whitted();
    no_vk(&mut c);
    let o = c
        .args([
            "render",
            "scenes/mesh.toml",
            "--width",
            "16",
            "--height",
            "12",
            "-o",
        ])
        .arg(&png)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr_of(&o));
    let notes: Vec<_> = stderr_of(&o)
        .lines()
        .filter(|l| l.contains("CPU mirror:"))
        .map(String::from)
        .collect();
    assert_eq!(notes.len(), 1, "{}", stderr_of(&o));
    assert!(png.exists());

    let mut c = whitted();
    no_vk(&mut c);
    let o = c.arg("devices").output().unwrap();
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("no Vulkan device"));
}

/// llvmpipe stops every shader loop of a group of invocations after 65535
/// iterations in all. A scene that needs more (here 20 000 lights, one
/// feeler each) must be refused with a clear error on llvmpipe, never
/// rendered wrong; any other device must render it like the CPU.
#[test]
fn a_cut_loop_is_an_error_not_a_wrong_image() {
    let Some(g) = common::gpu() else { return };
    let mut text = String::from(
        "[camera]\nfrom = [0, -5, 0]\nat = [0, 0, 0]\n\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    for i in 0..20_000 {
        let a = i as f64 * 0.0003;
        text.push_str(&format!(
            "\n[[light]]\nposition = [{}, -6, {}]\ncolor = 0.00005\n",
            10.0 * a.cos(),
            10.0 * a.sin()
        ));
    }
    let p = common::parse(&text, &common::small(8, 8));
    let r = g.render(&p, &GpuOptions::default(), &|_, _| {});
    common::assert_no_validation_errors();
    if g.info().driver.to_lowercase().contains("llvmpipe") {
        let e = r.expect_err("llvmpipe cannot run 20 000 lights in one invocation");
        assert!(
            matches!(e, GpuError::LoopsCut { .. }) && e.is_user_error(),
            "{e:?}"
        );
        assert!(e.to_string().contains("--backend cpu"), "{e}");
    } else {
        let gf = r.unwrap_or_else(|e| panic!("{e}"));
        let cf = whitted::cpu::render(&p, &|_, _| {});
        assert_eq!(gf.stats, cf.stats);
    }
}
