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
use std::path::{Path, PathBuf};
use std::time::Duration;
use whitted::cpu::{self, Frame};
use whitted::gpu::loops::{self, Driver, LoopLoad};
use whitted::gpu::{
    DeviceKind, Fault, Gpu, GpuError, GpuMath, GpuOptions, GpuShadowCache, PipelineCache,
    ProbeItem, ProbeResult,
};
use whitted::metrics::{self, Tolerance};
use whitted::pack::layout::{BvhNode, Globals, Light, Material, Prim};
use whitted::pack::{Accel, Packed, Sampling, Settings, Shadows};

// ------------------------------------------------------------ SPIR-V layout

/// What the layout test needs from a SPIR-V module's names, decorations
/// and types, read with rspirv.
#[derive(Default)]
struct Reflection {
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    offsets: HashMap<(u32, u32), u32>,
    strides: HashMap<u32, u32>,
    structs: HashMap<u32, Vec<u32>>,
    /// Array type → element type.
    arrays: HashMap<u32, u32>,
    /// Pointer type → pointee type.
    pointers: HashMap<u32, u32>,
    /// Variable → its (pointer) type.
    vars: HashMap<u32, u32>,
    bindings: HashMap<u32, u32>,
}

fn reflect(spv: &[u8]) -> Reflection {
    use rspirv::dr::Operand::{Decoration, IdRef, LiteralBit32, LiteralString};
    use rspirv::spirv::{Decoration as D, Op};
    assert!(!spv.is_empty(), "shader missing from the build");
    let m = rspirv::dr::load_bytes(spv).unwrap_or_else(|e| panic!("not SPIR-V: {e}"));
    let mut r = Reflection::default();
    for i in &m.debug_names {
        match (i.class.opcode, i.operands.as_slice()) {
            (Op::Name, [IdRef(id), LiteralString(n)]) => {
                r.names.insert(*id, n.clone());
            }
            (Op::MemberName, [IdRef(id), LiteralBit32(k), LiteralString(n)]) => {
                r.member_names.insert((*id, *k), n.clone());
            }
            _ => {}
        }
    }
    for i in &m.annotations {
        match (i.class.opcode, i.operands.as_slice()) {
            (Op::Decorate, [IdRef(id), Decoration(D::ArrayStride), LiteralBit32(s)]) => {
                r.strides.insert(*id, *s);
            }
            (Op::Decorate, [IdRef(id), Decoration(D::Binding), LiteralBit32(b)]) => {
                r.bindings.insert(*id, *b);
            }
            (
                Op::MemberDecorate,
                [IdRef(id), LiteralBit32(k), Decoration(D::Offset), LiteralBit32(o)],
            ) => {
                r.offsets.insert((*id, *k), *o);
            }
            _ => {}
        }
    }
    let ids = |ops: &[rspirv::dr::Operand]| -> Vec<u32> {
        ops.iter()
            .filter_map(|o| match o {
                IdRef(id) => Some(*id),
                _ => None,
            })
            .collect()
    };
    for i in &m.types_global_values {
        let Some(id) = i.result_id else { continue };
        match i.class.opcode {
            Op::TypeArray | Op::TypeRuntimeArray => {
                r.arrays.insert(id, ids(&i.operands)[0]);
            }
            Op::TypeStruct => {
                r.structs.insert(id, ids(&i.operands));
            }
            Op::TypePointer => {
                r.pointers.insert(id, ids(&i.operands)[0]);
            }
            Op::Variable => {
                r.vars
                    .insert(id, i.result_type.expect("a variable has a type"));
            }
            _ => {}
        }
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
    // The shader reads a primitive as four 16-byte words (load_prim,
    // shaders/layout.glsl): the header's four words, then a, b and c.
    assert_eq!(
        fields!(Prim: kind_mat, data, cell_lo, cell_hi, a, b, c),
        [
            ("kind_mat", 0),
            ("data", 4),
            ("cell_lo", 8),
            ("cell_hi", 12),
            ("a", 16),
            ("b", 32),
            ("c", 48)
        ]
        .map(|(n, o)| (n.to_string(), o))
        .to_vec()
    );
    assert_eq!(size_of::<Prim>(), 64);
    type Members = Vec<(String, u32)>;
    let expect: Vec<(&str, Members, usize)> = vec![
        (
            "Globals",
            fields!(Globals: cam_right, cam_up, cam_forward, background, ambient, grid_min,
                    grid_max, grid_cell, grid_dims, counts, image, trace, params, flags),
            size_of::<Globals>(),
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
        ("render_fast", whitted::gpu::shaders::RENDER_FAST),
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
            // The primitives as 16-byte words (load_prim, layout.glsl).
            (1, "", 16),
            (2, "", 16),
            (3, "Material", size_of::<Material>()),
            (4, "Light", size_of::<Light>()),
            (5, "", 4),
            (6, "", 4),
            (12, "", 4),
            (13, "", 4),
        ];
        for (b, elem, stride) in arrays {
            let (e, s) = r.binding_array(b);
            assert_eq!(
                (e.as_str(), s as usize),
                (elem, stride),
                "{kernel}.comp binding {b}"
            );
        }
        // BvhNode: three vec4s per box corner, lane by lane; the shader's
        // `lo` and `hi` are the Rust node's `bounds[0]` and `bounds[1]`.
        let hi = std::mem::size_of::<[[f32; 4]; 3]>() as u32;
        let mut node = fields!(BvhNode: bounds, link, count);
        node[0].0 = "lo".into();
        node.insert(1, ("hi".into(), offset_of!(BvhNode, bounds) as u32 + hi));
        assert_eq!(r.layout("BvhNode"), node, "{kernel}.comp: struct BvhNode");
        assert_eq!(
            r.binding_array(11),
            ("BvhNode".into(), size_of::<BvhNode>() as u32),
            "{kernel}.comp binding 11"
        );
        if kernel.starts_with("render") {
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

/// How many NoContraction decorations (GLSL `precise`) a module carries.
fn no_contraction(spv: &[u8]) -> usize {
    use rspirv::dr::Operand::Decoration;
    use rspirv::spirv::{Decoration as D, Op};
    let m = rspirv::dr::load_bytes(spv).unwrap_or_else(|e| panic!("not SPIR-V: {e}"));
    m.annotations
        .iter()
        .filter(|i| {
            matches!(i.class.opcode, Op::Decorate | Op::MemberDecorate)
                && i.operands.contains(&Decoration(D::NoContraction))
        })
        .count()
}

/// `--gpu-math`: the fast render kernel is the exact one without
/// `precise` (no NoContraction left), and the probe kernel, which checks
/// the twins bit for bit, stays exact. Needs no device.
#[test]
fn the_fast_kernel_is_the_exact_one_without_precise() {
    use whitted::gpu::shaders::{PROBE, RENDER, RENDER_FAST};
    let (exact, fast, probe) = (
        no_contraction(RENDER),
        no_contraction(RENDER_FAST),
        no_contraction(PROBE),
    );
    println!("NoContraction: render {exact}, render_fast {fast}, probe {probe}");
    assert!(exact > 100, "render.spv has only {exact} NoContraction");
    assert_eq!(fast, 0, "render_fast.spv still has NoContraction");
    assert!(probe > 100, "probe.spv has only {probe} NoContraction");
    assert_ne!(RENDER, RENDER_FAST);
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

/// Compares within the device's tolerance (`Tolerance::for_device`:
/// bit for bit on lavapipe, docs/gpu.md); on failure writes the difference
/// image and names it.
fn assert_close(name: &str, cpu: &Frame, gpu: &Frame) {
    let kind = common::gpu().expect("a GPU frame has a device").info().kind;
    assert_within(name, cpu, gpu, &Tolerance::for_device(kind));
}

/// Compares within `tol`; on failure writes the difference image and
/// names it.
fn assert_within(name: &str, cpu: &Frame, gpu: &Frame, tol: &Tolerance) {
    let c = metrics::compare(cpu, gpu, tol);
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

/// A frame's pixels as bit patterns, to compare bit for bit.
fn bits(f: &Frame) -> Vec<u32> {
    f.pixels.iter().flatten().map(|v| v.to_bits()).collect()
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

/// Every bundled scene, with each structure: the GPU's image is the
/// mirror's within the device's tolerance (bit for bit on lavapipe:
/// docs/gpu.md), and on a CPU device the ray counts are equal.
#[test]
fn every_scene_matches_the_cpu_mirror() {
    for path in scene_files() {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            let p = common::load(
                &path,
                &Settings {
                    accel,
                    ..common::small(96, 72)
                },
            );
            assert_eq!(p.structure(), accel);
            let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
                return;
            };
            let name = format!("{} {accel:?}", path.file_name().unwrap().to_string_lossy());
            assert_close(&name, &c, &g);
            if common::gpu().is_some_and(|d| d.info().kind == DeviceKind::Cpu) {
                assert_eq!(c.stats, g.stats, "{name}: ray counts");
            }
        }
    }
}

/// With light buffers (bindings 12 and 13), every bundled scene and the
/// SPD's gears render on the GPU as on the CPU mirror (bit for bit on
/// lavapipe), with the shadow cache off and on, and as plain shadow
/// feelers do.
#[test]
fn light_buffers_match_the_cpu_mirror() {
    let mut packs: Vec<(String, Settings, whitted::scene::Scene)> = Vec::new();
    for path in scene_files() {
        let s = whitted::scene::load(&path).unwrap();
        packs.push((path.display().to_string(), common::small(64, 48), s));
    }
    let gears = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Gears, Some(2)).unwrap();
    packs.push(("gears".into(), common::small(64, 64), gears));
    for (name, base, scene) in packs {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            let settings = |shadows| Settings {
                accel,
                shadows,
                ..base.clone()
            };
            let p = whitted::pack::pack(&scene, &settings(Shadows::LightBuffer)).unwrap();
            assert!(p.globals.flags[3] > 0, "{name}: no light buffer");
            let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
                return;
            };
            let name = format!("{name} {accel:?} lightbuffer");
            assert_close(&name, &c, &g);
            // With the shadow cache on (off by default on lavapipe), which
            // answers through the light buffer's cells.
            let cached = GpuOptions {
                shadow_cache: GpuShadowCache::On,
                ..GpuOptions::default()
            };
            let (_, gc) = render_both(&p, &cached).expect("a device");
            assert_close(&format!("{name}, cache on"), &c, &gc);
            let plain = whitted::pack::pack(&scene, &settings(Shadows::Plain)).unwrap();
            let pc = cpu::render(&plain, &|_, _| {});
            assert_eq!(pc.pixels, c.pixels, "{name}: plain and light buffer");
            if common::gpu().is_some_and(|d| d.info().kind == DeviceKind::Cpu) {
                assert_eq!(c.stats, g.stats, "{name}: ray counts");
            }
        }
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

/// `--gpu-math fast`: the kernel without `precise` renders the showcase
/// within its validate tolerance of the CPU mirror (`Tolerance::
/// for_kernel`: the hardware one, on lavapipe too), grid and BVH; and
/// switching kernels on one device changes nothing of the exact one's
/// image (each kernel is its own pipeline).
#[test]
fn the_fast_kernel_renders_close_to_the_mirror() {
    let Some(g) = common::gpu() else {
        return;
    };
    let path = common::repo().join("scenes/showcase.toml");
    let fast = GpuOptions {
        math: GpuMath::Fast,
        ..Default::default()
    };
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        let p = common::load(
            &path,
            &Settings {
                accel,
                ..common::small(96, 72)
            },
        );
        let exact = g.render(&p, &GpuOptions::default(), &|_, _| {}).unwrap();
        let Some((c, f)) = render_both(&p, &fast) else {
            return;
        };
        let name = format!("showcase {accel:?} fast");
        assert_close(&format!("showcase {accel:?} exact"), &c, &exact);
        let kind = g.info().kind;
        assert_within(&name, &c, &f, &Tolerance::for_kernel(kind, GpuMath::Fast));
        let vs_exact = metrics::compare(&exact, &f, &Tolerance::default());
        println!(
            "{name} against exact: max abs {:.2e}, PSNR {:.1} dB",
            vs_exact.max_abs, vs_exact.psnr
        );
        let again = g.render(&p, &GpuOptions::default(), &|_, _| {}).unwrap();
        assert_eq!(again.pixels, exact.pixels, "{name}: exact after fast");
        assert_eq!(again.stats, exact.stats, "{name}: exact after fast");
        common::assert_no_validation_errors();
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

/// The primitives' layout in the device's buffer (`--prim-layout`) is
/// plumbing too: both layouts give the same image and rays, every
/// structure and primitive kind, and the CPU mirror's bit for bit on
/// lavapipe; the SoA bytes are the AoS bytes transposed.
#[test]
fn prim_layouts_do_not_change_the_image() {
    use whitted::gpu::PrimLayout;
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    // Every scene under the grid and the BVH, the showcase under every
    // structure (each walk loads its primitives at its own place).
    let mut cases: Vec<(PathBuf, Accel)> = scene_files()
        .into_iter()
        .flat_map(|f| [(f.clone(), Accel::Grid), (f, Accel::Bvh)])
        .collect();
    let showcase = common::repo().join("scenes/showcase.toml");
    cases.push((showcase.clone(), Accel::Octree));
    cases.push((showcase, Accel::Hybrid));
    for (path, accel) in cases {
        let p = common::load(
            &path,
            &Settings {
                accel,
                ..common::small(40, 30)
            },
        );
        let name = format!("{} {accel:?}", path.display());
        let aos = g.render(&p, &GpuOptions::default(), &|_, _| {}).unwrap();
        let soa = g
            .render(
                &p,
                &GpuOptions {
                    prim_layout: PrimLayout::Soa,
                    ..Default::default()
                },
                &|_, _| {},
            )
            .unwrap();
        assert!(bits(&aos) == bits(&soa), "{name}: the layouts differ");
        assert_eq!(aos.stats, soa.stats, "{name}");
        if exact {
            let cpu = cpu::render(&p, &|_, _| {});
            assert!(
                bits(&soa) == bits(&cpu),
                "{name}: SoA against the CPU mirror"
            );
        }
    }
    let p = common::load(
        &common::repo().join("scenes/mesh.toml"),
        &common::small(8, 8),
    );
    let (aos, soa) = (
        PrimLayout::Aos.bytes(&p.prims),
        PrimLayout::Soa.bytes(&p.prims),
    );
    let n = p.prims.len();
    assert_eq!(aos.len(), soa.len());
    for i in [0, n / 2, n - 1] {
        for k in 0..4 {
            assert_eq!(
                aos[i * 64 + k * 16..i * 64 + k * 16 + 16],
                soa[(k * n + i) * 16..(k * n + i) * 16 + 16],
                "primitive {i}, word {k}"
            );
        }
    }
    common::assert_no_validation_errors();
}

/// `--reads texel` (the primitives, the BVH and the cell and reference
/// lists read through texel buffer views) and `--reads storage` give the
/// same image, rays and work on every scene file under every structure
/// and walk, with either primitive layout and either kernel, and the CPU
/// mirror's bit for bit on lavapipe; where an array has more texels than
/// the device's views hold, the reads fall back to storage buffers.
#[test]
fn texel_and_storage_reads_give_one_image() {
    use whitted::gpu::{CellLayout, GpuKernel, GpuReads, PrimLayout};
    use whitted::pack::octree::{Params, Walk};
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    assert!(
        g.info().max_texel_buffer_elements >= 65536,
        "the Vulkan minimum"
    );
    let structures = [
        (Accel::Grid, Walk::Neighbour),
        (Accel::Bvh, Walk::Neighbour),
        (Accel::Octree, Walk::Neighbour),
        (Accel::Octree, Walk::Stack),
        (Accel::Hybrid, Walk::Neighbour),
    ];
    for path in scene_files() {
        for (accel, walk) in structures {
            let settings = Settings {
                accel,
                octree: Params {
                    walk,
                    ..Default::default()
                },
                hybrid_cell: 2,
                ..common::small(32, 24)
            };
            let p = common::load(&path, &settings);
            let name = format!("{} {accel:?} {walk:?}", path.display());
            let with = |reads, prim_layout, kernel| GpuOptions {
                reads,
                prim_layout,
                kernel,
                ..Default::default()
            };
            // The texel reads are specialization bit 11 (`TEXELS`).
            let key = |reads| {
                whitted::gpu::layout_key(&with(reads, PrimLayout::Aos, GpuKernel::Mega), &p)
            };
            assert_eq!(
                (
                    key(GpuReads::Texel) >> 11 & 1,
                    key(GpuReads::Storage) >> 11 & 1
                ),
                (1, 0)
            );
            // load_prim serves every walk: the SoA layout under one.
            let mut variants = vec![(PrimLayout::Aos, GpuKernel::Mega)];
            match accel {
                Accel::Grid => variants.push((PrimLayout::Soa, GpuKernel::Mega)),
                Accel::Bvh => variants.push((PrimLayout::Aos, GpuKernel::Wavefront)),
                _ => {}
            }
            let mut first = None;
            for (layout, kernel) in variants {
                let [storage, texel] = [GpuReads::Storage, GpuReads::Texel].map(|reads| {
                    g.render(&p, &with(reads, layout, kernel), &|_, _| {})
                        .unwrap()
                });
                let what = format!("{name} {layout:?} {kernel:?}");
                assert!(
                    bits(&texel) == bits(&storage),
                    "{what}: texel and storage reads differ"
                );
                assert_eq!(texel.stats, storage.stats, "{what}");
                // The work too (the wavefront's shadow cache lives
                // differently, so only against the same kernel).
                assert_eq!(texel.work, storage.work, "{what}");
                first.get_or_insert(storage);
            }
            let storage = first.unwrap();
            if exact {
                let cpu = cpu::render(&p, &|_, _| {});
                assert!(
                    bits(&storage) == bits(&cpu),
                    "{name}: against the CPU mirror"
                );
            }
        }
    }
    // The fallback: one texel short of the longest array read as texels.
    let p = common::load(
        &common::repo().join("scenes/showcase.toml"),
        &Settings {
            accel: Accel::Bvh,
            ..common::small(8, 8)
        },
    );
    let longest = [
        p.prims.len() as u64 * 4,
        CellLayout::Pairs.bytes(&p) / 4,
        p.refs.len() as u64,
        p.bvh.len() as u64 * 8,
    ]
    .into_iter()
    .max()
    .unwrap();
    let fit = |m| GpuReads::Texel.fitting(&p, CellLayout::Pairs, m);
    assert_eq!(fit(longest), GpuReads::Texel);
    assert_eq!(fit(longest - 1), GpuReads::Storage);
    assert_eq!(
        GpuReads::Storage.fitting(&p, CellLayout::Pairs, u64::MAX),
        GpuReads::Storage
    );
    common::assert_no_validation_errors();
}

/// The walks compile only the intersection tests of the kinds the
/// structure holds (`BOUNDED_KINDS`, bits 12-18 of specialization constant
/// 3): for random spheres on a floor polygon the spheres alone, the floor
/// being a giant tested by `query_unbounded` with every kind's code; and
/// `query_unbounded` compiles out where there is nothing unbounded (bit
/// 20). (The images with them are the CPU mirror's: every other test
/// here, SPD tetra, mount and teapot in tests/validate_scenes.rs.)
#[test]
fn walks_compile_the_kinds_their_structure_holds() {
    use whitted::constants::{KIND_POLYGON, KIND_SPHERE};
    use whitted::gpu::{bounded_kinds, layout_key};
    for accel in [Accel::Grid, Accel::Bvh] {
        let p = whitted::pack::pack(
            &whitted::gen::random_spheres(500, 3),
            &Settings {
                accel,
                ..common::small(8, 8)
            },
        )
        .unwrap();
        let n = p.globals.counts[0] as usize;
        let kind = |prim: &Prim| prim.kind_mat & 15;
        assert!(
            p.prims[n..].iter().any(|q| kind(q) == KIND_POLYGON),
            "{accel:?}: a giant floor"
        );
        assert_eq!(bounded_kinds(&p), 1 << KIND_SPHERE, "{accel:?}");
        let key = layout_key(&GpuOptions::default(), &p);
        assert_eq!(key >> 12 & 127, 1 << KIND_SPHERE, "{accel:?}");
    }
    // Every scene file and SPD rings (cylinders and spheres): the kinds of
    // their first counts[0] primitives; some structure holds two kinds.
    let rings = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Rings, Some(1)).unwrap();
    let mut cases: Vec<(String, Packed)> = scene_files()
        .into_iter()
        .map(|f| {
            (
                f.display().to_string(),
                common::load(&f, &common::small(8, 8)),
            )
        })
        .collect();
    cases.push((
        "rings".into(),
        whitted::pack::pack(&rings, &common::small(8, 8)).unwrap(),
    ));
    let tetra = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Tetra, Some(2)).unwrap();
    cases.push((
        "tetra".into(),
        whitted::pack::pack(&tetra, &common::small(8, 8)).unwrap(),
    ));
    let mut mixed = 0;
    // Bit 20 (`NO_UNBOUNDED`): set exactly where nothing follows the
    // structure's primitives, so `query_unbounded` compiles out.
    let mut unbounded = [0, 0];
    for (name, p) in &cases {
        let n = p.globals.counts[0] as usize;
        let want: u32 = p.prims[..n]
            .iter()
            .fold(0, |k, q| k | 1 << (q.kind_mat & 15));
        assert_eq!(bounded_kinds(p), want, "{name}");
        mixed += usize::from(want.count_ones() > 1);
        let none = p.globals.counts[0] == p.globals.counts[1];
        assert_eq!(n == p.prims.len(), none, "{name}");
        let key = layout_key(&GpuOptions::default(), p);
        assert_eq!(key >> 20 & 1, u32::from(none), "{name}: NO_UNBOUNDED");
        unbounded[usize::from(none)] += 1;
    }
    assert!(mixed > 0, "no scene file mixes kinds in its structure");
    assert!(
        unbounded[0] > 0 && unbounded[1] > 0,
        "scenes with and without unbounded primitives: {unbounded:?}"
    );
}

/// Bits 21 (`CONVEX_POLYGONS`) and 22-28 (`UNBOUNDED_KINDS`) of
/// specialization constant 3: set from the packed scene (every polygon
/// convex; the kinds of the unbounded primitives), and the kernel they
/// compile renders the mirror's image (bit for bit on lavapipe): a convex
/// pentagon floor (a giant, an odd vertex count for the two-at-a-time
/// vertex reads) under spheres, with and without a glass sphere (whose
/// feelers read k_t) and with a concave polygon beside it (bit 21 clear:
/// the general test).
#[test]
fn convex_polygons_and_unbounded_kinds_compile_only_what_the_scene_needs() {
    use whitted::constants::{KIND_POLYGON, KIND_SPHERE};
    use whitted::gpu::{convex_polygons, layout_key, unbounded_kinds};
    let scene = |glass: bool, concave: bool| {
        let mut t = String::from(
            "b 0.1 0.1 0.2\nv\nfrom 1 -7 4\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.001\n\
             resolution 64 48\nl 3 -4 6\nl -4 -2 5\n\
             f 0.8 0.8 0.7 0.6 0.3 10 0 1\n\
             p 5\n-30 -20 -1\n20 -30 -1\n30 10 -1\n0 30 -1\n-30 10 -1\n\
             f 0.9 0.3 0.2 0.7 0.4 20 0 1\n",
        );
        for i in 0..12 {
            let a = f64::from(i) * 0.52;
            t += &format!(
                "s {:.3} {:.3} {:.3} 0.45\n",
                2.0 * a.cos(),
                2.0 * a.sin(),
                0.3 * a
            );
        }
        if glass {
            t += "f 0.9 0.9 1 0.1 0.5 60 0.8 1.5\ns 0.2 -1.5 0.4 0.7\n";
        }
        if concave {
            // An arrow head, upright behind the spheres.
            t += "f 0.2 0.7 0.3 0.8 0.2 5 0 1\np 4\n-1.5 3 -1\n0 3 0.2\n1.5 3 -1\n0 3 2.5\n";
        }
        t
    };
    for (glass, concave) in [(false, false), (true, false), (false, true)] {
        for accel in [Accel::Grid, Accel::Bvh] {
            let name = format!("glass {glass}, concave {concave}, {accel:?}");
            let s = whitted::scene::parse_str(&scene(glass, concave), Path::new("test.nff"))
                .unwrap_or_else(|e| panic!("{e}"));
            let p = whitted::pack::pack(
                &s,
                &Settings {
                    accel,
                    ..common::small(64, 48)
                },
            )
            .unwrap();
            let (lo, hi) = (p.globals.counts[0] as usize, p.globals.counts[1] as usize);
            let kind = |q: &Prim| q.kind_mat & 15;
            let want = p.prims[lo..hi].iter().fold(0, |k, q| k | 1 << kind(q));
            assert_eq!(
                want,
                1 << KIND_POLYGON,
                "{name}: the floor alone is unbounded"
            );
            assert!(
                p.prims[..lo].iter().any(|q| kind(q) == KIND_SPHERE),
                "{name}: spheres in the structure"
            );
            assert_eq!(unbounded_kinds(&p), want, "{name}");
            assert_eq!(convex_polygons(&p), !concave, "{name}");
            let key = layout_key(&GpuOptions::default(), &p);
            assert_eq!(
                key >> 21 & 1,
                u32::from(!concave),
                "{name}: CONVEX_POLYGONS"
            );
            assert_eq!(key >> 22 & 127, want, "{name}: UNBOUNDED_KINDS");
            assert_eq!(key >> 31, 0, "{name}: never the run-time default");
            let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
                return;
            };
            assert!(
                c.stats.shadow > 0 && c.stats.reflect > 0,
                "{name}: {:?}",
                c.stats
            );
            assert_eq!(glass, c.stats.refract > 0, "{name}: refraction");
            assert_close(&name, &c, &g);
            if common::gpu().is_some_and(|d| d.info().kind == DeviceKind::Cpu) {
                assert_eq!(c.stats, g.stats, "{name}: ray counts");
            }
        }
    }
}

/// Bit 29 of specialization constant 3 (`NO_JUMPS`): a dense field's grid
/// keeps no skip distance over 1 (`pack::grid::jumps_pay`), so the kernel
/// compiles the jump out; a sparse one (SPD balls under the grid) keeps
/// its jumps and the bit clear. Both render the mirror's image and ray
/// counts (bit for bit on lavapipe).
#[test]
fn dense_grids_walk_without_jumps() {
    use whitted::gpu::{grid_jumps, layout_key};
    let field = whitted::gen::random_spheres(3000, 5);
    let balls = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Balls, Some(3)).unwrap();
    let cases = [
        ("3000 spheres grid", &field, Accel::Grid, false),
        ("3000 spheres hybrid", &field, Accel::Hybrid, false),
        ("balls grid", &balls, Accel::Grid, true),
    ];
    for (name, scene, accel, jumps) in cases {
        let p = whitted::pack::pack(
            scene,
            &Settings {
                accel,
                ..common::small(64, 48)
            },
        )
        .unwrap();
        let n = p.globals.grid_dims[3] as usize;
        let skip = |ci: usize| (p.cell_start[n + 1 + ci / 4] >> (8 * (ci % 4))) & 255;
        let empty = (0..n).filter(|&ci| skip(ci) > 0).count();
        // (The hybrid's coarser grid may have none.)
        assert!(empty > 0 || accel == Accel::Hybrid, "{name}: no empty cell");
        assert_eq!(grid_jumps(&p), jumps, "{name}");
        assert_eq!((0..n).any(|ci| skip(ci) >= 2), jumps, "{name}");
        let key = layout_key(&GpuOptions::default(), &p);
        assert_eq!(key >> 29 & 1, u32::from(!jumps), "{name}: NO_JUMPS");
        let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
            return;
        };
        assert_close(name, &c, &g);
        if common::gpu().is_some_and(|d| d.info().kind == DeviceKind::Cpu) {
            assert_eq!(c.stats, g.stats, "{name}: ray counts");
        }
    }
}

/// The BVH the kernels read (`gpu::bvh_for_gpu`): each child's link and
/// count in one word (the link below `BVH_COUNT_SHIFT` bits, the count
/// above, the count field zero), the boxes as packed, for a BVH with
/// leaves of several primitives and a hybrid's nested nodes; a link
/// that does not fit is refused with a limits error. (Every GPU test with
/// the BVH renders through it: the images are the mirror's.)
#[test]
fn bvh_children_share_one_word_on_the_gpu() {
    use whitted::constants::BVH_COUNT_SHIFT;
    use whitted::gpu::bvh_for_gpu;
    let mask = (1u32 << BVH_COUNT_SHIFT) - 1;
    let mut leaves_over_one = 0;
    for accel in [Accel::Bvh, Accel::Hybrid] {
        let p = whitted::pack::pack(
            &whitted::gen::random_spheres(3000, 7),
            &Settings {
                accel,
                ..common::small(8, 8)
            },
        )
        .unwrap();
        assert!(!p.bvh.is_empty(), "{accel:?}: no BVH nodes");
        let g = bvh_for_gpu(&p.bvh).unwrap();
        assert_eq!(g.len(), p.bvh.len());
        for (a, b) in p.bvh.iter().zip(&g) {
            assert_eq!(a.bounds, b.bounds);
            for k in 0..4 {
                assert_eq!(b.link[k] & mask, a.link[k], "{accel:?}");
                assert_eq!(b.link[k] >> BVH_COUNT_SHIFT, a.count[k], "{accel:?}");
                assert_eq!(b.count[k], 0);
                leaves_over_one += usize::from(a.count[k] > 1);
            }
        }
    }
    assert!(leaves_over_one > 0, "no leaf of several primitives");
    let mut n = BvhNode::EMPTY;
    n.link[2] = 1 << BVH_COUNT_SHIFT;
    n.count[2] = 1;
    match bvh_for_gpu(&[n]) {
        Err(GpuError::Limits(m)) => assert!(m.contains("links to"), "{m}"),
        other => panic!("a link over 2^28 gave {:?}", other.map(|v| v.len())),
    }
}

/// `--shadow-cache`: `auto` is off on a CPU device and on elsewhere,
/// off sets bit 19 of specialization constant 3 (`SHADOW_CACHE` in
/// layout.glsl), and the cache changes no pixel and no ray count, on
/// either kernel, against the CPU mirror bit for bit on lavapipe; it
/// changes the work counters (proof that the bit reaches the shader)
/// where opaque blockers shadow feelers.
#[test]
fn the_shadow_cache_changes_no_pixel_on_the_gpu() {
    use whitted::gpu::{layout_key, GpuKernel};
    assert_eq!(
        GpuShadowCache::Auto.for_device(DeviceKind::Cpu),
        GpuShadowCache::Off
    );
    for kind in [
        DeviceKind::Discrete,
        DeviceKind::Integrated,
        DeviceKind::Virtual,
        DeviceKind::Other,
    ] {
        assert_eq!(GpuShadowCache::Auto.for_device(kind), GpuShadowCache::On);
        assert_eq!(GpuShadowCache::Off.for_device(kind), GpuShadowCache::Off);
    }
    assert_eq!(
        GpuShadowCache::On.for_device(DeviceKind::Cpu),
        GpuShadowCache::On
    );
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    let with = |shadow_cache, kernel| GpuOptions {
        shadow_cache,
        kernel,
        ..Default::default()
    };
    let mut changed = 0;
    for f in scene_files() {
        for accel in [Accel::Grid, Accel::Bvh] {
            let p = common::load(
                &f,
                &Settings {
                    accel,
                    ..common::small(48, 36)
                },
            );
            let key = |c| layout_key(&with(c, GpuKernel::Mega), &p) >> 19 & 1;
            assert_eq!((key(GpuShadowCache::On), key(GpuShadowCache::Off)), (0, 1));
            let name = format!("{} {accel:?}", f.display());
            let cpu = cpu::render(&p, &|_, _| {});
            for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
                let [on, off] = [GpuShadowCache::On, GpuShadowCache::Off].map(|c| {
                    g.render(&p, &with(c, kernel), &|_, _| {})
                        .unwrap_or_else(|e| panic!("{name} {kernel:?}: {e}"))
                });
                assert!(bits(&on) == bits(&off), "{name} {kernel:?}: the image");
                assert_eq!(on.stats, off.stats, "{name} {kernel:?}");
                if exact {
                    assert!(bits(&off) == bits(&cpu), "{name} {kernel:?}: the mirror");
                }
                changed += usize::from(on.work != off.work);
            }
        }
    }
    assert!(changed > 0, "the cache changed no work counter anywhere");
    common::assert_no_validation_errors();
}

/// The scene and settings of the pack fuzz target's finding `name`
/// (tests/fuzz_regressions/pack/), as the target renders it.
fn pack_finding(name: &str) -> (whitted::scene::Scene, Settings) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions/pack")
        .join(name);
    let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    whitted::fuzzing::pack_case(&data).expect("the finding is a scene")
}

/// The pack fuzz target's finding `shadow-cache-far-feeler.bin`
/// (tests/fuzz_corpus.rs): a feeler from a hit on a plane 10^12 away for
/// which the f32 test of a cached sphere reports a hit the BVH's boxes
/// rule out. With the shadow cache on, both kernels answer only where the
/// walk would reach the cached blocker's leaf (bvh.glsl,
/// bvh_leaf_admits): the image and the ray counts of the cache off, and
/// the CPU mirror's bit for bit on lavapipe. (At 32×32, 3 samples a
/// pixel, lavapipe's megakernel changed pixels with the cache on before
/// the check; the fuzz target's own 7×7 did not show it there.)
#[test]
fn a_cached_blocker_far_from_the_feeler_on_the_gpu() {
    use whitted::gpu::GpuKernel;
    let (scene, settings) = pack_finding("shadow-cache-far-feeler.bin");
    let settings = Settings {
        width: Some(32),
        height: Some(32),
        spp: 3,
        ..settings
    };
    let p = whitted::pack::pack(&scene, &settings).expect("the finding packs");
    assert_eq!(p.structure(), Accel::Bvh);
    if common::gpu().is_none() {
        return;
    }
    for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
        the_cache_changes_nothing(&p, kernel, &format!("{kernel:?}"));
    }
}

/// The pack fuzz finding `quadric-normal-underflow.bin`
/// (tests/fuzz_corpus.rs): a quadric whose gradient's squared length
/// underflows where the eye rays hit it. The shader's normal
/// (`direction3`) is the CPU's on both kernels: every pixel finite, and
/// the mirror's image bit for bit on lavapipe.
#[test]
fn a_quadric_gradient_whose_square_underflows_on_the_gpu() {
    use whitted::gpu::GpuKernel;
    let (scene, settings) = pack_finding("quadric-normal-underflow.bin");
    let p = whitted::pack::pack(&scene, &settings).expect("the finding packs");
    let Some(g) = common::gpu() else { return };
    let cpu = cpu::render(&p, &|_, _| {});
    for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
        let opts = GpuOptions {
            kernel,
            ..Default::default()
        };
        let f = g
            .render(&p, &opts, &|_, _| {})
            .unwrap_or_else(|e| panic!("{kernel:?}: {e}"));
        assert!(
            f.pixels.iter().flatten().all(|c| c.is_finite()),
            "{kernel:?}: a pixel is not finite"
        );
        if g.info().kind == DeviceKind::Cpu {
            assert!(bits(&f) == bits(&cpu), "{kernel:?}: not the mirror's image");
        }
    }
    common::assert_no_validation_errors();
}

/// Renders `p` on the GPU with the shadow cache on and off (`kernel`):
/// the same image and ray counts, and the CPU mirror's image bit for bit
/// on lavapipe.
fn the_cache_changes_nothing(p: &Packed, kernel: whitted::gpu::GpuKernel, name: &str) {
    let g = common::gpu().expect("a GPU");
    let [on, off] = [GpuShadowCache::On, GpuShadowCache::Off].map(|shadow_cache| {
        let opts = GpuOptions {
            shadow_cache,
            kernel,
            ..Default::default()
        };
        g.render(p, &opts, &|_, _| {})
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    });
    assert!(
        bits(&on) == bits(&off),
        "{name}: the cache changed the image"
    );
    assert_eq!(on.stats, off.stats, "{name}");
    if g.info().kind == DeviceKind::Cpu {
        let cpu = cpu::render(p, &|_, _| {});
        assert!(bits(&on) == bits(&cpu), "{name}: not the mirror's image");
    }
    common::assert_no_validation_errors();
}

/// The nff fuzz findings `shadow-cache-giant-feeler.nff` and
/// `shadow-cache-long-cylinder.nff` (tests/fuzz_corpus.rs): feelers from a
/// giant sphere's surface, 5·10^16 away, and feelers passing beside the
/// grid's box, for which the f32 test of a cached primitive reports a hit
/// the grid's walk never reaches. With the shadow cache on, the grid, the
/// octree and the hybrid answer only for feelers that start near their
/// box and enter it (accel.glsl, cache_admits): on both kernels the image
/// and ray counts of the cache off, and the CPU mirror's bit for bit on
/// lavapipe.
#[test]
fn a_cached_blocker_for_a_feeler_from_a_giant_on_the_gpu() {
    use whitted::gpu::GpuKernel;
    if common::gpu().is_none() {
        return;
    }
    for name in [
        "shadow-cache-giant-feeler.nff",
        "shadow-cache-long-cylinder.nff",
    ] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fuzz_regressions/nff")
            .join(name);
        for accel in [Accel::Grid, Accel::Octree, Accel::Hybrid] {
            let p = common::load(
                &path,
                &Settings {
                    accel,
                    ..common::small(48, 48)
                },
            );
            for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
                the_cache_changes_nothing(&p, kernel, &format!("{name} {accel:?} {kernel:?}"));
            }
        }
    }
}

/// The nff fuzz finding `packets-needle-cone.nff` (tests/fuzz_corpus.rs):
/// a needle cone 455 long with radii 0 and 0.056, for which the f32 test
/// solved from the cone's middle made up a root outside the cone's boxes.
/// Long cones are now solved from the ray's point nearest the axis and a
/// hit must lie within the record's tolerance of the side, in both twins:
/// every structure gives the CPU mirror the same image, and lavapipe's
/// kernels the mirror's, bit for bit.
#[test]
fn a_needle_cone_on_the_gpu() {
    use whitted::gpu::GpuKernel;
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions/nff/packets-needle-cone.nff");
    let mut images = Vec::new();
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        let p = common::load(
            &path,
            &Settings {
                accel,
                ..common::small(48, 48)
            },
        );
        let cpu = cpu::render(&p, &|_, _| {});
        if let Some(g) = common::gpu() {
            for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
                let opts = GpuOptions {
                    kernel,
                    ..Default::default()
                };
                let gpu = g
                    .render(&p, &opts, &|_, _| {})
                    .unwrap_or_else(|e| panic!("{accel:?} {kernel:?}: {e}"));
                if g.info().kind == DeviceKind::Cpu {
                    assert!(
                        bits(&gpu) == bits(&cpu),
                        "{accel:?} {kernel:?}: not the mirror's image"
                    );
                }
            }
        }
        images.push((accel, bits(&cpu)));
    }
    for (accel, img) in &images[1..] {
        assert!(*img == images[0].1, "{accel:?}: not the grid's image");
    }
    common::assert_no_validation_errors();
}

/// The `pack` target's long cone (2026-12-07): a cylinder 10^6 times as
/// long as wide under a 6³ grid, and a feeler some 70 units from its axis
/// for which the f32 cone test reports a hit in cells that do not list
/// it. With the shadow cache on, the grid and the hybrid answer only for
/// a cached hit inside the blocker's cells (accel.glsl, cache_hit_listed):
/// on both kernels the image and ray counts of the cache off, and the CPU
/// mirror's bit for bit on lavapipe.
#[test]
fn a_cached_long_cone_hit_outside_its_cells_on_the_gpu() {
    use whitted::gpu::GpuKernel;
    if common::gpu().is_none() {
        return;
    }
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions/pack/shadow-cache-long-cone-grid.bin");
    let data = std::fs::read(&path).expect("the finding is committed");
    let (scene, settings) = whitted::fuzzing::pack_case(&data).expect("a scene");
    for accel in [Accel::Grid, Accel::Hybrid] {
        for (w, h) in [(7, 7), (32, 32)] {
            let p = whitted::pack::pack(
                &scene,
                &Settings {
                    accel,
                    width: Some(w),
                    height: Some(h),
                    ..settings.clone()
                },
            )
            .expect("packs");
            for kernel in [GpuKernel::Mega, GpuKernel::Wavefront] {
                the_cache_changes_nothing(&p, kernel, &format!("{accel:?} {w}x{h} {kernel:?}"));
            }
        }
    }
}

/// With the shadow cache off in the packed scene (`Packed::set_shadow_cache`,
/// `FLAG_NO_SHADOW_CACHE`), which turns it off on both backends whatever
/// `--shadow-cache` says, the twins count the same work: on lavapipe the
/// GPU's tests, cells and nodes equal the CPU mirror's exactly on every
/// bundled scene and structure (with the cache on they differ by its
/// lifetime: `gpu_work_counters_match_the_cpu`), and the image is the one
/// rendered with the cache. (The cache can cost tests as well as save
/// them: a cached primitive that does not block is one test more.)
#[test]
fn without_the_shadow_cache_the_work_counters_are_equal() {
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    let on = GpuOptions {
        shadow_cache: GpuShadowCache::On,
        ..Default::default()
    };
    let mut changed = 0;
    for path in scene_files() {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            let mut p = common::load(
                &path,
                &Settings {
                    accel,
                    ..common::small(40, 30)
                },
            );
            let name = format!("{} {accel:?}", path.display());
            let cached = cpu::render(&p, &|_, _| {});
            p.set_shadow_cache(false);
            let Some((c, gf)) = render_both(&p, &on) else {
                return;
            };
            assert!(
                bits(&c) == bits(&cached),
                "{name}: the cache changed the image"
            );
            changed += usize::from(c.work != cached.work);
            if exact {
                assert_eq!(c.work, gf.work, "{name}: work counters");
                assert!(bits(&c) == bits(&gf), "{name}: not the mirror's image");
            }
        }
    }
    assert!(changed > 0, "the flag changed no CPU work counter anywhere");
}

/// `--cell-layout pairs` (the grid's cells as (start, count) pairs, one
/// reference inline, the skip in the pair): the same image, counts and
/// work as the packed offsets on every scene file under the grid, on
/// random spheres and on gears under the grid and the hybrid (which has empty, single and
/// crowded cells, and hybrid cells whose one reference is a node), and
/// the CPU mirror's bit for bit on lavapipe.
#[test]
fn cell_layouts_do_not_change_the_image() {
    use whitted::gpu::CellLayout;
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    let gears = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Gears, Some(1)).unwrap();
    let mut cases: Vec<(String, whitted::pack::Packed)> = Vec::new();
    for accel in [Accel::Grid, Accel::Hybrid] {
        let settings = Settings {
            accel,
            ..common::small(48, 36)
        };
        // The scene files under the grid (the hybrid's cells are the
        // generated scenes' below).
        for f in scene_files().into_iter().filter(|_| accel == Accel::Grid) {
            cases.push((
                format!("{} {accel:?}", f.display()),
                common::load(&f, &settings),
            ));
        }
        for (name, scene) in [
            ("random 2000", whitted::gen::random_spheres(2000, 8)),
            ("gears 1", gears.clone()),
        ] {
            let hybrid_one = Settings {
                hybrid_cell: 1,
                ..settings.clone()
            };
            for s in [&settings, &hybrid_one] {
                let p = whitted::pack::pack(&scene, s).unwrap();
                cases.push((format!("{name} {accel:?} cell {}", s.hybrid_cell), p));
            }
        }
    }
    let mut inline_nodes = 0;
    for (name, p) in &cases {
        assert!(CellLayout::Pairs.applies(p), "{name}");
        // The pairs say what the offsets say.
        let words = CellLayout::Pairs.words(p);
        let n = p.globals.grid_dims[3] as usize;
        assert_eq!(words.len(), 2 * n, "{name}");
        for ci in 0..n {
            let (start, end) = (p.cell_start[ci], p.cell_start[ci + 1]);
            let pair = [words[2 * ci], words[2 * ci + 1]];
            let skip = (p.cell_start[n + 1 + ci / 4] >> (8 * (ci % 4))) & 255;
            let want = match end - start {
                0 => [skip, 0],
                1 => [p.refs[start as usize], 1],
                c => [start, c],
            };
            assert_eq!(pair, want, "{name}: cell {ci}");
            if pair[1] == 1 && pair[0] & whitted::constants::HYBRID_NODE != 0 {
                inline_nodes += 1;
            }
        }
        let with = |cell_layout| GpuOptions {
            cell_layout,
            ..Default::default()
        };
        let offsets = g.render(p, &with(CellLayout::Offsets), &|_, _| {}).unwrap();
        let pairs = g.render(p, &with(CellLayout::Pairs), &|_, _| {}).unwrap();
        assert!(bits(&offsets) == bits(&pairs), "{name}: the layouts differ");
        assert_eq!(offsets.stats, pairs.stats, "{name}");
        assert_eq!(offsets.work, pairs.work, "{name}");
        if exact {
            let cpu = cpu::render(p, &|_, _| {});
            assert!(
                bits(&pairs) == bits(&cpu),
                "{name}: pairs against the CPU mirror"
            );
        }
    }
    // Some hybrid cell's one reference is its own BVH: the inline path
    // meets a node, not only primitives.
    assert!(inline_nodes > 0);
    // Where the pairs would not fit the device's buffer range, the offsets.
    let p = &cases[0].1;
    let pairs = CellLayout::Pairs.bytes(p);
    assert_eq!(pairs, 8 * p.globals.grid_dims[3] as u64);
    assert_eq!(CellLayout::Pairs.fitting(p, pairs), CellLayout::Pairs);
    assert_eq!(CellLayout::Pairs.fitting(p, pairs - 1), CellLayout::Offsets);
    assert_eq!(CellLayout::Offsets.fitting(p, 0), CellLayout::Offsets);
    common::assert_no_validation_errors();
}

/// Only refracted rays wait in the kernels' ray-tree stack (a hit's
/// reflected ray is walked next from registers, trace.glsl): overlapping
/// glass spheres with both k_r and k_t, ten levels deep, keep several
/// refracted rays waiting at once, popped in the CPU mirror's order. Both
/// kernels (`--lane-pixels` 1 and 2, lavapipe's default) and both
/// structures give the mirror's ray counts, and its image within the
/// device's tolerance (`assert_close`: bit for bit on lavapipe).
#[test]
fn deep_refraction_trees_pop_in_the_mirrors_order() {
    let Some(g) = common::gpu() else { return };
    let scene = r#"
background = [0.2, 0.3, 0.5]
ambient = 0.2
[camera]
from = [0, -6, 1]
at = [0, 0, 0]
fov = 40
[[light]]
position = [-4, -5, 6]
color = 0.8
[material.glass]
color = [1, 1, 1]
kd = 0.1
ks = 0.5
shine = 50
kr = 0.4
kt = 0.6
ior = 1.5
absorption = [0.1, 0.05, 0.02]
[material.floor]
color = [0.8, 0.7, 0.6]
kr = 0.3
[[object]]
type = "plane"
point = [0, 0, -1]
normal = [0, 0, 1]
material = "floor"
[[object]]
type = "sphere"
center = [0, 0, 0]
radius = 1
material = "glass"
[[object]]
type = "sphere"
center = [0.6, -0.5, 0.3]
radius = 0.6
material = "glass"
[[object]]
type = "sphere"
center = [-0.7, 0.4, -0.2]
radius = 0.7
material = "glass"
"#;
    for accel in [Accel::Bvh, Accel::Grid] {
        let p = common::parse(
            scene,
            &Settings {
                accel,
                max_depth: 10,
                min_weight: 0.002,
                spp: 2,
                ..common::small(40, 30)
            },
        );
        let cpu = cpu::render(&p, &|_, _| {});
        // Enough refracted rays that stacks of several entries occur.
        assert!(cpu.stats.refract > 4 * 40 * 30, "{:?}", cpu.stats);
        // 2, not 0 (the device's default): a default that cuts loops
        // falls back to 1 and would hide the lanes kernel's answer.
        for lane_pixels in [1, 2] {
            let f = g
                .render(
                    &p,
                    &GpuOptions {
                        lane_pixels,
                        ..Default::default()
                    },
                    &|_, _| {},
                )
                .unwrap();
            let name = format!("deep refraction, {accel:?}, lane pixels {lane_pixels}");
            assert_eq!(f.stats, cpu.stats, "{name}");
            assert_close(&name, &cpu, &f);
        }
    }
    common::assert_no_validation_errors();
}

/// `--lane-pixels K` (render_lanes.spv: K lattice points an invocation,
/// each sample started inside one ray loop) gives the one-point kernel's
/// image and ray counts on every scene file, with odd workgroup shapes and
/// tiles, several samples and corner sampling; and the CPU mirror's bit
/// for bit on lavapipe.
#[test]
fn lane_pixels_do_not_change_the_image() {
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    for path in scene_files() {
        for (spp, sampling, accel) in [
            (3, Sampling::Centers, Accel::Bvh),
            (1, Sampling::Corners, Accel::Grid),
        ] {
            let p = common::load(
                &path,
                &Settings {
                    accel,
                    spp,
                    sampling,
                    ..common::small(37, 23)
                },
            );
            let with = |lane_pixels| GpuOptions {
                lane_pixels,
                ..Default::default()
            };
            let one = g.render(&p, &with(1), &|_, _| {}).unwrap();
            // 0: the device's default (2 on lavapipe).
            let default = g.render(&p, &with(0), &|_, _| {}).unwrap();
            assert!(bits(&one) == bits(&default), "{}", path.display());
            for (k, workgroup, tile) in [(2, [8, 8], 256), (3, [3, 5], 16), (8, [1, 1], 8)] {
                let name = format!("{} spp {spp} K {k} {workgroup:?}", path.display());
                let f = g
                    .render(
                        &p,
                        &GpuOptions {
                            lane_pixels: k,
                            workgroup,
                            tile,
                            ..Default::default()
                        },
                        &|_, _| {},
                    )
                    .unwrap();
                assert!(bits(&one) == bits(&f), "{name}: not the one-point image");
                assert_eq!(one.stats, f.stats, "{name}");
                if exact {
                    let cpu = cpu::render(&p, &|_, _| {});
                    assert!(bits(&f) == bits(&cpu), "{name}: against the CPU mirror");
                }
            }
        }
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
    // The debug messenger's errors and warnings print as "error: vulkan: ...".
    assert!(!stderr_of(&o).contains("vulkan:"), "{}", stderr_of(&o));
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
    assert_eq!(s["gpu_math"], "exact");

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
        "work/ray",
        "secondary",
        "PASS",
    ] {
        assert!(out.contains(k), "validate output lacks {k}: {out}");
    }
    assert!(diff.exists());
    // The debug messenger's errors and warnings print as "error: vulkan: ...".
    assert!(!stderr_of(&o).contains("vulkan:"), "{}", stderr_of(&o));

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

/// `--gpu-math fast` end to end: `render` uses the fast kernel (and says
/// so in --stats), `validate` checks it against the mirror with the usual
/// tolerance, and `bench` times both kernels as separate engines.
#[test]
fn cli_gpu_math_fast() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("f.png");
    let json = dir.path().join("f.json");
    let o = whitted()
        .env("WHITTED_VALIDATION", "1")
        .args([
            "render",
            "scenes/showcase.toml",
            "--width",
            "48",
            "--height",
            "36",
            "--backend",
            "gpu",
            "--gpu-math",
            "fast",
            "-q",
            "-o",
        ])
        .arg(&png)
        .arg("--stats")
        .arg(&json)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr_of(&o));
    assert!(!stderr_of(&o).contains("vulkan:"), "{}", stderr_of(&o));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(s["backend"], "gpu");
    assert_eq!(s["gpu_math"], "fast");
    assert_eq!(s["rays"]["eye"], 48 * 36);

    let o = whitted()
        .env("WHITTED_VALIDATION", "1")
        .args([
            "validate",
            "scenes/showcase.toml",
            "--width",
            "48",
            "--height",
            "36",
            "--gpu-math",
            "fast",
            "--json",
            "-",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr_of(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["gpu_math"], "fast");
    assert_eq!(v["passed"], true);
    // Each side's work per kind of ray, beside the verdict.
    for side in ["cpu", "gpu"] {
        let w = &v["work_by_ray"][side];
        assert_eq!(w["eye"]["rays"], 48 * 36, "{side}: {w}");
        assert!(
            w["eye"]["intersection_tests"].as_u64().unwrap() > 0,
            "{side}: {w}"
        );
        assert!(
            w["shadow"]["per_ray"]["intersection_tests"]
                .as_f64()
                .unwrap()
                > 0.0
        );
    }

    let csv = dir.path().join("b.csv");
    let o = whitted()
        .args([
            "-q",
            "bench",
            "--suite",
            "examples",
            "--only",
            "showcase",
            "--resolution",
            "16x12",
            "--runs",
            "1",
            "--warmup",
            "0",
            "--backends",
            "gpu",
            "--gpu-math",
            "exact,fast",
            "--csv",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr_of(&o));
    let text = std::fs::read_to_string(&csv).unwrap();
    let engines: Vec<&str> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').find(|f| f.starts_with("gpu:")))
        .collect();
    assert_eq!(engines.len(), 2, "{text}");
    assert!(!engines[0].ends_with("/fast"), "{text}");
    assert!(engines[1].ends_with("/fast"), "{text}");
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

/// A unit sphere seen from 5 away, lit by `n` lights of colour `color`
/// along an arc: one feeler each per shaded point.
fn many_lights(n: usize, color: f64) -> String {
    let mut text = String::from(
        "[camera]\nfrom = [0, -5, 0]\nat = [0, 0, 0]\n\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    for i in 0..n {
        let a = i as f64 * 0.0003;
        text.push_str(&format!(
            "\n[[light]]\nposition = [{}, -6, {}]\ncolor = {color}\n",
            10.0 * a.cos(),
            10.0 * a.sin()
        ));
    }
    text
}

/// llvmpipe stops every shader loop of a group of invocations after 65535
/// iterations in all. A scene that needs more (here 20 000 lights, one
/// feeler each) must be refused with a clear error on llvmpipe, never
/// rendered wrong; any other device must render it like the CPU.
#[test]
fn a_cut_loop_is_an_error_not_a_wrong_image() {
    let Some(g) = common::gpu() else { return };
    let p = common::parse(&many_lights(20_000, 0.00005), &common::small(8, 8));
    let r = g.render(&p, &GpuOptions::default(), &|_, _| {});
    common::assert_no_validation_errors();
    // One eye ray's own loops need only about 20 000 iterations: the host
    // cannot be sure of a cut, so it dispatches and the device reports it.
    assert_eq!(loops::certain_cut(&p), None);
    if g.info().has_loop_budget() {
        let e = r.expect_err("llvmpipe cannot run 20 000 lights in one invocation");
        assert!(
            matches!(e, GpuError::LoopsCut { .. }) && e.is_user_error(),
            "{e:?}"
        );
        let msg = e.to_string();
        for k in [
            "the likely cause is 20 000 lights",
            "use fewer lights",
            "--backend cpu",
        ] {
            assert!(msg.contains(k), "{k}: {msg}");
        }
    } else {
        let gf = r.unwrap_or_else(|e| panic!("{e}"));
        let cf = whitted::cpu::render(&p, &|_, _| {});
        assert_eq!(gf.stats, cf.stats);
    }
}

/// An invocation that renders two lattice points (`--lane-pixels 2`, the
/// default on CPU devices) makes about twice the loop iterations of one
/// against the same budget. A scene within the budget at one point per
/// invocation (here 10 000 lights) must still render by default, as the
/// CPU does: the render falls back to one point. Asked for explicitly,
/// two points is refused with `--lane-pixels 1` as the first remedy.
#[test]
fn the_default_lane_pixels_fall_back_to_one_when_loops_are_cut() {
    let Some(g) = common::gpu() else { return };
    let p = common::parse(&many_lights(10_000, 0.0001), &common::small(32, 32));
    let gf = g
        .render(&p, &GpuOptions::default(), &|_, _| {})
        .unwrap_or_else(|e| panic!("the default must render: {e}"));
    common::assert_no_validation_errors();
    let cf = whitted::cpu::render(&p, &|_, _| {});
    assert_eq!(gf.stats, cf.stats);
    let c = metrics::compare(&cf, &gf, &Tolerance::for_device(g.info().kind));
    assert!(c.passed(), "{:?}", c.failures);
    let two = GpuOptions {
        lane_pixels: 2,
        ..GpuOptions::default()
    };
    let r = g.render(&p, &two, &|_, _| {});
    if g.info().has_loop_budget() {
        let e = r.expect_err("llvmpipe cuts 10 000 lights at two points per invocation");
        assert!(matches!(e, GpuError::LoopsCut { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.contains("use --lane-pixels 1"), "{msg}");
        assert!(msg.contains("use fewer lights"), "{msg}");
    } else {
        assert_eq!(r.unwrap_or_else(|e| panic!("{e}")).stats, cf.stats);
    }
}

// ------------------------------------------------------------ loop budget

/// A scene of one regular polygon of `n` vertices facing the camera, lit by
/// `lights` lights.
fn polygon_scene(n: usize, lights: usize) -> String {
    let mut t = String::from(
        "[camera]\nfrom = [0, -5, 0]\nat = [0, 0, 0]\n\n[[object]]\ntype = \"polygon\"\nvertices = [",
    );
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        t.push_str(&format!("[{:.9}, 0, {:.9}],", a.cos(), a.sin()));
    }
    t.push_str("]\n");
    for i in 0..lights {
        t.push_str(&format!(
            "\n[[light]]\nposition = [{}, -6, 2]\ncolor = 0.5\n",
            i as f64 * 0.01
        ));
    }
    t
}

/// The host names what drives the shader's loops, and predicts a cut only
/// where one eye ray's own loops exceed the budget. Needs no device.
#[test]
fn the_host_names_what_drives_the_loops() {
    // A 100 000-vertex polygon: the eye ray through the middle hits it and
    // walks every vertex, more than the budget, before any dispatch.
    let p = common::parse(&polygon_scene(100_000, 1), &common::small(8, 8));
    let load = LoopLoad::of(&p);
    assert!(
        matches!(
            load.largest(),
            Driver::Polygon {
                vertices: 100_000,
                prim: 0,
                ..
            }
        ),
        "{:?}",
        load.drivers()
    );
    assert!(load.worst() > loops::LLVMPIPE_LOOP_BUDGET as f64);
    let cut = loops::certain_cut(&p).expect("the middle ray meets 100 000 vertices");
    assert!(
        matches!(
            cut.driver,
            Driver::Polygon {
                vertices: 100_000,
                ..
            }
        ),
        "{cut:?}"
    );
    assert!(cut.iterations > loops::LLVMPIPE_LOOP_BUDGET && cut.iterations < 100_010);
    assert!(cut
        .driver
        .describe()
        .contains("a polygon with 100 000 vertices"));
    // The same polygon with 1000 vertices is under the budget.
    let p = common::parse(&polygon_scene(1000, 1), &common::small(8, 8));
    assert_eq!(loops::certain_cut(&p), None);

    // 70 000 lights: every shaded point loops over them all.
    let mut p = common::parse(&polygon_scene(4, 1), &common::small(8, 8));
    p.lights = vec![p.lights[0]; 70_000];
    p.globals.counts[2] = 70_000;
    assert_eq!(LoopLoad::of(&p).largest(), Driver::Lights(70_000));
    let cut = loops::certain_cut(&p).expect("a shaded point loops over 70 000 lights");
    assert_eq!(cut.driver, Driver::Lights(70_000));
    // A mirror box at depth 16: the ray tree dominates.
    let p = common::load(
        &common::repo().join("scenes/showcase.toml"),
        &Settings {
            max_depth: 16,
            ..common::small(8, 8)
        },
    );
    let load = LoopLoad::of(&p);
    assert!(
        matches!(load.largest(), Driver::Depth { max_depth: 16, .. }),
        "{:?}",
        load.drivers()
    );
    assert_eq!(loops::certain_cut(&p), None);
}

/// The longest cell list the host names after a cut is the grid's own:
/// read from the ncells + 1 offsets only, not from the skip bytes packed
/// after them (which it once read as offsets). Needs no device.
#[test]
fn the_host_reads_the_longest_cell_list_from_the_offsets() {
    for (name, scene) in [
        ("3000 spheres", whitted::gen::random_spheres(3000, 5)),
        (
            "balls",
            whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Balls, Some(3)).unwrap(),
        ),
    ] {
        let p = whitted::pack::pack(
            &scene,
            &Settings {
                accel: Accel::Grid,
                ..common::small(8, 8)
            },
        )
        .unwrap();
        let n = p.globals.grid_dims[3] as usize;
        assert!(
            p.cell_start.len() > n + 1,
            "{name}: skip bytes after the offsets"
        );
        let longest = (0..n)
            .map(|c| p.cell_start[c + 1] - p.cell_start[c])
            .max()
            .unwrap();
        assert!(longest > 1, "{name}");
        assert_eq!(LoopLoad::of(&p).cell_refs, longest, "{name}");
    }
}

/// With light buffers on a column of 800 spheres seen end-on from the
/// light (every sphere's directions cover the window's centre, so its
/// cells list all of them, nearest first), the longest cell list is what
/// the host names, with `--shadows plain` as the remedy; plain feelers on
/// the same scene name something else. Needs no device.
#[test]
fn the_host_names_a_crowded_light_buffer_cell() {
    let mut t = String::from(
        "[camera]\nfrom = [4, 0, 40]\nat = [0, 0, 40]\n\n[[light]]\nposition = [0, 0, -10]\ncolor = 0.5\n",
    );
    for k in 0..800 {
        t.push_str(&format!(
            "\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, {}]\nradius = 0.04\n",
            k as f64 * 0.1
        ));
    }
    let settings = |shadows| Settings {
        shadows,
        accel: Accel::Bvh,
        ..common::small(16, 16)
    };
    let p = common::parse(&t, &settings(Shadows::LightBuffer));
    let load = LoopLoad::of(&p);
    let Driver::LightBufferCell(n) = load.largest() else {
        panic!("{:?}", load.drivers());
    };
    assert!(n > 500 && n <= p.prims.len() as u32, "{n}");
    assert_eq!(load.largest().remedy(), "use --shadows plain");
    assert!(load
        .largest()
        .describe()
        .contains("a light-buffer cell listing"));
    let plain = common::parse(&t, &settings(Shadows::Plain));
    let lp = LoopLoad::of(&plain);
    assert_eq!(lp.lb_refs, 0);
    assert!(lp.worst() < load.worst());
    assert!(!matches!(lp.largest(), Driver::LightBufferCell(_)));
}

/// On llvmpipe the 100 000-vertex polygon is refused before dispatching,
/// naming it and where; any other device renders it like the CPU.
#[test]
fn a_huge_polygon_is_refused_before_dispatch_on_llvmpipe() {
    let Some(g) = common::gpu() else { return };
    let p = common::parse(&polygon_scene(100_000, 1), &common::small(8, 8));
    let r = g.render(&p, &GpuOptions::default(), &|_, _| {});
    common::assert_no_validation_errors();
    if g.info().has_loop_budget() {
        let e = r.expect_err("llvmpipe cannot walk 100 000 vertices");
        assert!(
            matches!(e, GpuError::LoopsWouldBeCut { .. }) && e.is_user_error(),
            "{e:?}"
        );
        let msg = e.to_string();
        for k in [
            "a polygon with 100 000 vertices",
            "the eye ray of pixel (",
            "split the polygon",
            "--backend cpu",
        ] {
            assert!(msg.contains(k), "{k}: {msg}");
        }
    } else {
        let gf = r.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(gf.stats, cpu::render(&p, &|_, _| {}).stats);
    }
}

// ------------------------------------------------------------ device faults

fn fault_options(fault: Fault) -> GpuOptions {
    GpuOptions {
        fault: Some(fault),
        // The never-signalling fence ends the test in about a second.
        fence_timeout: Some(Duration::from_secs(1)),
        // Several tiles, so that a fault meets work in flight and made.
        tile: 8,
        ..Default::default()
    }
}

fn small_showcase() -> Packed {
    common::load(
        &common::repo().join("scenes/showcase.toml"),
        &common::small(24, 18),
    )
}

/// Every injected fault: one clear line naming the device and what
/// failed, a device fault (exit 4, CPU fallback), never a user error; a
/// loss or a timeout ends the device; and everything made before the fault
/// is released without a word from the validation layer.
#[test]
fn every_injected_fault_is_one_clear_error() {
    let Some(shared) = common::gpu() else { return };
    let p = small_showcase();
    for fault in Fault::ALL {
        let opts = fault_options(fault);
        let g = Gpu::new(&opts).unwrap_or_else(|e| panic!("{fault:?}: {e}"));
        let e = g.render(&p, &opts, &|_, _| {}).unwrap_err();
        let msg = e.to_string();
        assert!(
            e.is_device_fault() && !e.is_user_error(),
            "{fault:?}: {e:?}"
        );
        assert!(
            !msg.contains('\n') && msg.contains(&shared.info().name),
            "{msg}"
        );
        let (ok, words) = match fault {
            Fault::DeviceLost => (
                matches!(e, GpuError::DeviceLost { .. }),
                "was lost during vkWaitForFences (VK_ERROR_DEVICE_LOST",
            ),
            Fault::OutOfDeviceMemory => (
                matches!(e, GpuError::OutOfDeviceMemory { .. }),
                "ran out of device memory allocating samples",
            ),
            Fault::OutOfHostMemory => (
                matches!(e, GpuError::OutOfHostMemory { .. }),
                "ran out of host memory in vkCreateBuffer",
            ),
            Fault::FenceNeverSignals => (
                matches!(e, GpuError::Timeout { timeout, .. } if timeout == Duration::from_secs(1)),
                "did not finish tile 1 of 9 within the fence timeout of 1 second",
            ),
            Fault::PipelineRefused => (
                matches!(e, GpuError::PipelineRefused { .. }),
                // render, or render_lanes (--lane-pixels above 1, the
                // default on a CPU device).
                "kernel (vkCreateComputePipelines: ERROR_UNKNOWN)",
            ),
        };
        assert!(ok, "{fault:?}: {e:?}");
        assert!(msg.contains(words), "{fault:?}: {msg}");
        let ends = matches!(fault, Fault::DeviceLost | Fault::FenceNeverSignals);
        assert_eq!(g.failed().is_some(), ends, "{fault:?}");
        if ends {
            // Not used again: the same error, at once, from a render or a probe.
            let again = g.render(&p, &opts, &|_, _| {}).unwrap_err();
            assert_eq!(again.to_string(), msg);
            let probe = g.probe(&p, whitted::gpu::ProbeMode::Solve, &[ProbeItem::default()]);
            assert_eq!(probe.unwrap_err().to_string(), msg);
        }
        drop(g);
        common::assert_no_validation_errors();
    }
}

/// `--backend auto`'s fallback: after a device fault the CPU mirror
/// renders the image (bit for bit the mirror's), and the fault comes back
/// to be reported; other errors are not swallowed, and a healthy device
/// renders itself.
#[test]
fn a_device_fault_finishes_on_the_cpu_mirror() {
    let Some(shared) = common::gpu() else { return };
    let p = small_showcase();
    let cpu_frame = cpu::render(&p, &|_, _| {});
    for fault in [Fault::DeviceLost, Fault::OutOfDeviceMemory] {
        let opts = fault_options(fault);
        let g = Gpu::new(&opts).unwrap();
        let fell_back = std::cell::Cell::new(false);
        let (f, why) = g
            .render_or(&p, &opts, &|_, _| {}, || {
                fell_back.set(true);
                cpu::render(&p, &|_, _| {})
            })
            .unwrap_or_else(|e| panic!("{fault:?}: {e}"));
        assert!(fell_back.get());
        assert!(why.is_some_and(|e| e.is_device_fault()), "{fault:?}");
        assert!(
            bits(&f) == bits(&cpu_frame),
            "{fault:?}: not the mirror's image"
        );
        assert_eq!(f.stats, cpu_frame.stats);
    }
    let (f, why) = shared
        .render_or(&p, &GpuOptions::default(), &|_, _| {}, || {
            panic!("a healthy device needs no fallback")
        })
        .unwrap();
    assert!(why.is_none() && f.width == 24);
    // A user error is the user's, not a reason to fall back.
    let e = shared
        .render_or(
            &p,
            &GpuOptions {
                workgroup: [0, 1],
                ..Default::default()
            },
            &|_, _| {},
            || panic!("no fallback for a bad --workgroup"),
        )
        .unwrap_err();
    assert!(e.is_user_error(), "{e:?}");
    common::assert_no_validation_errors();
}

/// Synchronization validation on (VK_EXT_validation_features), a scene in
/// several tiles through the staging path, twice on one device (the
/// second render reuses the kernel and its descriptor set): silent.
#[test]
fn synchronization_validation_is_silent() {
    if common::gpu().is_none() {
        return;
    }
    let opts = GpuOptions {
        sync_validation: true,
        staging: true,
        tile: 16,
        ..Default::default()
    };
    let g = Gpu::new(&opts).unwrap();
    if g.validation() {
        assert!(
            g.sync_validation(),
            "the layer should offer VK_EXT_validation_features"
        );
    }
    let p = common::load(
        &common::repo().join("scenes/showcase.toml"),
        &common::small(40, 30),
    );
    let cpu_frame = cpu::render(&p, &|_, _| {});
    for _ in 0..2 {
        let f = g.render(&p, &opts, &|_, _| {}).unwrap();
        assert_close("sync validation", &cpu_frame, &f);
    }
    drop(g);
    common::assert_no_validation_errors();
}

/// A corrupt cache file, a cache folder that cannot be made, and no cache
/// at all: the render goes on; the corrupt file is named in a warning.
#[test]
fn a_bad_pipeline_cache_never_fails_a_render() {
    let Some(shared) = common::gpu() else { return };
    let p = common::load(
        &common::repo().join("scenes/mesh.toml"),
        &common::small(16, 12),
    );
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("corrupt");
    std::fs::create_dir(&corrupt).unwrap();
    let file = whitted::gpu::pipeline::cache_file(&corrupt, shared.info());
    std::fs::write(&file, b"this is not a Vulkan pipeline cache at all").unwrap();
    let blocked = dir.path().join("a file");
    std::fs::write(&blocked, b"x").unwrap();
    for (cache, warned) in [
        (
            PipelineCache::Dir(corrupt.clone()),
            Some(file.display().to_string()),
        ),
        (PipelineCache::Dir(blocked.join("sub")), None),
        (PipelineCache::Off, None),
    ] {
        let opts = GpuOptions {
            pipeline_cache: cache.clone(),
            ..Default::default()
        };
        let g = Gpu::new(&opts).unwrap();
        match &cache {
            PipelineCache::Off => assert!(g.pipeline_cache_dir().is_none()),
            PipelineCache::Dir(d) => assert_eq!(g.pipeline_cache_dir(), Some(d.as_path())),
            PipelineCache::Default => unreachable!(),
        }
        g.render(&p, &opts, &|_, _| {})
            .unwrap_or_else(|e| panic!("{cache:?}: {e}"));
        if let Some(w) = warned {
            let logs = common::logged(&w);
            assert!(
                logs.iter()
                    .any(|(l, m)| *l == log::Level::Warn && m.contains("bad header")),
                "{logs:?}"
            );
        }
    }
    common::assert_no_validation_errors();
}

/// The CLI with each fault injected through WHITTED_GPU_FAULT: `--backend
/// gpu` exits with 4 and one `error:` line saying what failed, writes no
/// image, never panics; an unknown fault name is the user's error (2).
#[test]
fn cli_device_faults_exit_4_with_one_line() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("f.png");
    let run = |fault: &str| {
        whitted()
            .env("WHITTED_GPU_FAULT", fault)
            .env("WHITTED_FENCE_TIMEOUT", "1")
            .args([
                "render",
                "scenes/showcase.toml",
                "--width",
                "24",
                "--height",
                "18",
                "--backend",
                "gpu",
                "--tile",
                "8",
                "-q",
                "-o",
            ])
            .arg(&png)
            .output()
            .unwrap()
    };
    for (fault, words) in [
        (Fault::DeviceLost, "VK_ERROR_DEVICE_LOST"),
        (Fault::OutOfDeviceMemory, "ran out of device memory"),
        (Fault::OutOfHostMemory, "ran out of host memory"),
        (
            Fault::FenceNeverSignals,
            "within the fence timeout of 1 second",
        ),
        (Fault::PipelineRefused, "refused to build the render"),
    ] {
        let o = run(fault.name());
        let err = stderr_of(&o);
        assert_eq!(o.status.code(), Some(4), "{fault:?}: {err}");
        let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(lines.len(), 1, "{fault:?}: {err}");
        assert!(lines[0].contains(words), "{fault:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!png.exists(), "{fault:?} wrote an image");
    }
    let o = run("no-such-fault");
    assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
    assert!(stderr_of(&o).contains("WHITTED_GPU_FAULT=no-such-fault"));
}

/// `--backend auto --device 0` with a device fault injected: the CPU
/// mirror finishes the render (exit 0, the image, `"backend": "cpu"` in
/// the stats) and one warning says so and why.
#[test]
fn cli_auto_finishes_on_the_cpu_mirror_after_a_fault() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for fault in [Fault::DeviceLost, Fault::FenceNeverSignals] {
        let png = dir.path().join(format!("{}.png", fault.name()));
        let json = dir.path().join(format!("{}.json", fault.name()));
        let o = whitted()
            .env("WHITTED_GPU_FAULT", fault.name())
            .env("WHITTED_FENCE_TIMEOUT", "1")
            .args([
                "render",
                "scenes/showcase.toml",
                "--width",
                "24",
                "--height",
                "18",
                "--backend",
                "auto",
                "--device",
                "0",
                "--tile",
                "8",
                "-o",
            ])
            .arg(&png)
            .arg("--stats")
            .arg(&json)
            .output()
            .unwrap();
        let err = stderr_of(&o);
        assert!(o.status.success(), "{fault:?}: {err}");
        assert!(png.exists(), "{fault:?}");
        let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(s["backend"], "cpu", "{fault:?}");
        let notes: Vec<&str> = err
            .lines()
            .filter(|l| l.starts_with("warning:") && l.contains("CPU mirror"))
            .collect();
        assert_eq!(notes.len(), 1, "{fault:?}: {err}");
        let why = match fault {
            Fault::DeviceLost => "VK_ERROR_DEVICE_LOST",
            _ => "fence timeout",
        };
        assert!(notes[0].contains(why), "{err}");
        assert!(!err.lines().any(|l| l.starts_with("error:")), "{err}");
    }
}

/// WHITTED_PIPELINE_CACHE: a folder holding a corrupt cache file, or
/// `off`: the render succeeds.
#[test]
fn cli_pipeline_cache_env() {
    let Some(g) = common::gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = whitted::gpu::pipeline::cache_file(dir.path(), g.info());
    std::fs::write(&file, vec![0xffu8; 100]).unwrap();
    for value in [dir.path().to_str().unwrap(), "off"] {
        let png = dir.path().join("c.png");
        let o = whitted()
            .env("WHITTED_PIPELINE_CACHE", value)
            .args([
                "render",
                "scenes/mesh.toml",
                "--width",
                "16",
                "--height",
                "12",
                "--backend",
                "gpu",
                "-q",
                "-o",
            ])
            .arg(&png)
            .output()
            .unwrap();
        assert!(o.status.success(), "{value}: {}", stderr_of(&o));
        assert!(png.exists());
    }
}

/// `WHITTED_RENDER_SPV`: a kernel from a file renders (here the built-in
/// kernel's own bytes: the same image), and a file that is not SPIR-V is
/// a setting error naming the variable and the file, exit 2, no image.
#[test]
fn cli_render_spv_variant() {
    let Some(_g) = common::gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let spv = dir.path().join("variant.spv");
    std::fs::write(&spv, whitted::gpu::shaders::RENDER).unwrap();
    let not_spv = dir.path().join("not.spv");
    std::fs::write(&not_spv, b"#version 460\nvoid main() {}\n").unwrap();
    let render = |env: Option<&std::path::Path>, png: &std::path::Path| {
        let mut c = whitted();
        if let Some(e) = env {
            c.env("WHITTED_RENDER_SPV", e);
        }
        c.args([
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
        .arg(png)
        .output()
        .unwrap()
    };
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    let o = render(None, &a);
    assert!(o.status.success(), "{}", stderr_of(&o));
    let o = render(Some(&spv), &b);
    assert!(o.status.success(), "{}", stderr_of(&o));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    // The note names the built-in module the variant stands in for, and
    // where that is the several-points module, how to compile a variant
    // like it (a one-point module there is no measure of a variant).
    let err = stderr_of(&o);
    assert!(err.contains("where the built-in kernel is render"), "{err}");
    assert_eq!(
        err.contains("render_lanes.spv"),
        err.contains("-DWHITTED_LANES=1"),
        "{err}"
    );
    let c = dir.path().join("c.png");
    let o = render(Some(&not_spv), &c);
    assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
    let err = stderr_of(&o);
    assert!(
        err.contains("WHITTED_RENDER_SPV") && err.contains("not a SPIR-V module"),
        "{err}"
    );
    assert!(!c.exists());
}

/// `whitted profile`: every combination measured (the refused one with its
/// reason), the best marked once, the phases printed, and `--save` makes
/// `render` use the best shape unless a shape is given.
#[test]
fn cli_profile_sweeps_saves_and_render_uses_the_saved_shape_and_kernel() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let csv_path = dir.path().join("p.csv");
    let svg = dir.path().join("p.svg");
    let cache = dir.path().join("cache");
    let o = whitted()
        .env("XDG_CACHE_HOME", &cache)
        .args([
            "profile",
            "scenes/showcase.toml",
            "--width",
            "48",
            "--height",
            "36",
            "--workgroups",
            "8x8,16x2,64x32",
            "--tiles",
            "16,full",
            "--kernels",
            "mega,wavefront",
            "--repeat",
            "1",
            "--save",
            "--csv",
        ])
        .arg(&csv_path)
        .arg("--plot")
        .arg(&svg)
        .assert()
        .success();
    let out = String::from_utf8_lossy(&o.get_output().stdout).into_owned();
    for phase in [
        "load", "pack", "pipeline", "upload", "dispatch", "readback", "output",
    ] {
        assert!(out.contains(phase), "no phase {phase} in:\n{out}");
    }
    let mut r = csv::Reader::from_path(&csv_path).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    // Columns: kernel, workgroup, tile, device median, min, max, wall
    // median, rays, Mrays/s, best, refused.
    assert_eq!(rows.len(), 12);
    for k in ["mega", "wavefront"] {
        assert_eq!(rows.iter().filter(|r| &r[0] == k).count(), 6, "{k}");
    }
    assert_eq!(rows.iter().filter(|r| &r[9] == "true").count(), 1);
    // 64×32 = 2048 invocations, over lavapipe's limit of 1024 (some GPUs
    // allow it): where a device refuses a shape, the reason names its limit.
    for row in &rows {
        if !row[10].is_empty() {
            assert!(row[10].contains("invocations"), "{:?}", row);
        } else {
            assert!(row[3].parse::<f64>().unwrap() > 0.0);
        }
    }
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    let best = rows.iter().find(|r| &r[9] == "true").unwrap();
    let (kernel, wg, tile) = (
        best[0].to_string(),
        best[1].to_string(),
        best[2].to_string(),
    );
    let saved: Vec<_> = std::fs::read_dir(cache.join("whitted/profiles"))
        .unwrap()
        .collect();
    assert_eq!(saved.len(), 1);
    let render = |extra: &[&str]| {
        let o = whitted()
            .env("XDG_CACHE_HOME", &cache)
            .args([
                "render",
                "scenes/showcase.toml",
                "--width",
                "48",
                "--height",
                "36",
                "--backend",
                "gpu",
                "-v",
                "-o",
            ])
            .arg(dir.path().join("r.png"))
            .args(extra)
            .assert()
            .success();
        String::from_utf8_lossy(&o.get_output().stderr).into_owned()
    };
    let stats = dir.path().join("r.json");
    let stats_arg = stats.to_str().unwrap();
    let used = render(&["--stats", stats_arg]);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["gpu_kernel"], kernel.as_str(), "{used}");
    assert!(
        used.contains(&format!("the {kernel} kernel from")),
        "{used}"
    );
    let tile_shown = if tile == "full" {
        "16384".to_string()
    } else {
        tile
    };
    assert!(
        used.contains(&format!("dispatch shape {wg}, tile {tile_shown} from")),
        "{used}"
    );
    let given = render(&["--workgroup", "8x4"]);
    assert!(!given.contains("dispatch shape"), "{given}");
    assert!(given.contains("kernel from"), "{given}");
    // A kernel given on the command line wins over the saved one.
    let other = if kernel == "mega" {
        "wavefront"
    } else {
        "mega"
    };
    let given = render(&["--kernel", other, "--stats", stats_arg]);
    assert!(!given.contains("kernel from"), "{given}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["gpu_kernel"], other);
}

/// The GPU's work counters (`Frame::work`, 64-bit through a carry word)
/// mean what the CPU's mean: counted at the same places of the twins.
/// With the shadow cache on (`--shadow-cache on`; the CPU mirror always
/// keeps it) they differ only through its lifetime (one invocation
/// on the GPU, a 16×16 tile on the CPU; docs/gpu.md), so: within 5 % on
/// every bundled scene with each structure on a CPU device (lavapipe, two
/// lattice points per invocation; the cells and nodes within three times
/// that, below), 10 % on a GPU (one point per
/// invocation: a shorter life; an NVIDIA H200 counted 5.2 % fewer tests
/// on mesh.toml with the BVH), or 16 where there are only a handful; and
/// equal on a CPU device where no opaque blocker is ever cached (glass
/// only).
#[test]
fn gpu_work_counters_match_the_cpu() {
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    let cached = GpuOptions {
        shadow_cache: GpuShadowCache::On,
        ..Default::default()
    };
    // 5 % (10 % on a GPU), or 16 where a scene walks only a handful of
    // cells.
    let share = if exact { 0.05 } else { 0.10 };
    let close_within = |a: u64, b: u64, share: f64| {
        (a as f64 - b as f64).abs() <= (share * a.max(b) as f64).max(16.0)
    };
    let close = |a: u64, b: u64| close_within(a, b, share);
    for path in scene_files() {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            let p = common::load(
                &path,
                &Settings {
                    accel,
                    ..common::small(64, 48)
                },
            );
            let Some((c, gf)) = render_both(&p, &cached) else {
                return;
            };
            let name = format!("{} {accel:?}", path.display());
            let (cw, gw) = (c.work, gf.work);
            assert!(gw.tests > 0, "{name}: no tests counted on the GPU");
            // The octree counts its leaves as cells, its descents as nodes
            // (a small scene's octree may be its root alone).
            let walked = match accel {
                Accel::Grid => (cw.cells, gw.cells),
                Accel::Bvh => (cw.nodes, gw.nodes),
                _ => (cw.cells + cw.nodes, gw.cells + gw.nodes),
            };
            assert!(walked.1 > 0, "{name}: no cells or nodes counted on the GPU");
            assert!(
                close(cw.tests, gw.tests),
                "{name}: tests cpu {} gpu {}",
                cw.tests,
                gw.tests
            );
            // Three times the share for the cells and nodes: a feeler
            // whose cached blocker stops it skips its whole walk, where its
            // tests would have been one or two. scenes/quadric.toml, five
            // objects in a 4×3×1 grid or a small octree, its floor's
            // feelers often stopped by the cache: 3 800 cells on the CPU
            // against 4 095 on lavapipe under the grid (7.8 %), 2 197
            // against 2 445 under the octree (10.1 %), the tests 2 % and
            // 0.5 % apart; equal without the cache
            // (`without_the_shadow_cache_the_work_counters_are_equal`).
            assert!(
                close_within(walked.0, walked.1, 3.0 * share),
                "{name}: cells/nodes cpu {:?} gpu {:?}",
                cw,
                gw
            );
            // The split by kind of ray: only the feelers meet the cache,
            // so on lavapipe everything else (the eye rays' closest hits,
            // the reflected and refracted rays') is equal, and the feelers'
            // share differs by what the totals do.
            let (ct, gt) = (cw.totals(), gw.totals());
            if exact {
                assert_eq!(cw.eye, gw.eye, "{name}: the eye rays' work");
                for k in 0..3 {
                    assert_eq!(
                        ct[k] - cw.shadow[k],
                        gt[k] - gw.shadow[k],
                        "{name}: work besides the feelers' cpu {cw:?} gpu {gw:?}"
                    );
                }
            }
            for k in 0..3 {
                assert!(
                    close(cw.eye[k], gw.eye[k]),
                    "{name}: eye share cpu {cw:?} gpu {gw:?}"
                );
                let apart = (cw.shadow[k] as f64 - gw.shadow[k] as f64).abs();
                assert!(
                    apart <= (3.0 * share * ct[k].max(gt[k]) as f64).max(16.0),
                    "{name}: feeler share cpu {cw:?} gpu {gw:?}"
                );
            }
            assert!(
                (cw.eye[0] > 0) == (gw.eye[0] > 0) && gw.eye[0] <= gw.tests,
                "{name}: cpu {cw:?} gpu {gw:?}"
            );
        }
    }
    let mut glass = String::from(
        "[camera]\nfrom = [0, -9, 3]\nat = [0, 0, 0.5]\nup = [0, 0, 1]\nwidth = 64\nheight = 48\n\
         [[light]]\nposition = [4, -5, 8]\n[[light]]\nposition = [-5, -2, 6]\n\
         [material.g]\ncolor = [0.9, 0.9, 1]\nkd = 0.3\nks = 0.4\nshine = 30\nkt = 0.6\nior = 1.3\n",
    );
    for i in 0..12 {
        let (x, y) = ((i % 4) as f64 * 1.3 - 2.0, (i / 4) as f64 * 1.3 - 1.3);
        glass += &format!(
            "[[object]]\ntype = \"sphere\"\ncenter = [{x}, {y}, 0.5]\nradius = 0.55\nmaterial = \"g\"\n"
        );
    }
    glass +=
        "[[object]]\ntype = \"box\"\nmin = [-4, -4, -0.2]\nmax = [4, 4, 0]\nmaterial = \"g\"\n";
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        let p = common::parse(
            &glass,
            &Settings {
                accel,
                ..common::small(64, 48)
            },
        );
        let Some((c, gf)) = render_both(&p, &cached) else {
            return;
        };
        if exact {
            assert_eq!(
                (c.work.tests, c.work.cells, c.work.nodes),
                (gf.work.tests, gf.work.cells, gf.work.nodes),
                "glass {accel:?}"
            );
        } else {
            assert!(close(c.work.tests, gf.work.tests), "glass {accel:?}");
        }
    }
}

/// Ties: coincident copies of spheres, triangles and boxes in other
/// materials (every hit on them a tie) render on the GPU as on the CPU
/// mirror with both structures (bit for bit on lavapipe), and the grid's
/// image is the BVH's: both twins settle a tie by the primitive's rank
/// (query.glsl, `prim_rank`), whatever order the structure walks them in.
#[test]
fn ties_render_alike_on_both_twins_and_structures() {
    let mut text = String::from(
        "[camera]\nfrom = [0, -12, 4]\nat = [0, 0, 0.5]\nup = [0, 0, 1]\nwidth = 64\nheight = 48\n\
         [[light]]\nposition = [4, -5, 8]\n[[light]]\nposition = [-5, -2, 6]\n\
         [material.red]\ncolor = [1, 0.2, 0.2]\nkd = 0.7\nks = 0.3\nshine = 20\n\
         [material.blue]\ncolor = [0.2, 0.3, 1]\nkd = 0.7\n\
         [material.glass]\ncolor = [0.9, 0.9, 1]\nkd = 0.2\nks = 0.3\nshine = 40\nkt = 0.5\nior = 1.3\n",
    );
    let mats = ["red", "blue", "glass"];
    for i in 0..48 {
        let (x, y, z) = (
            (i % 8) as f64 - 3.5,
            (i / 8 % 3) as f64 * 1.5,
            (i / 24) as f64 * 1.2,
        );
        let obj = match i % 3 {
            0 => format!("type = \"sphere\"\ncenter = [{x}, {y}, {z}]\nradius = 0.45\n"),
            1 => format!(
                "type = \"triangle\"\nvertices = [[{x}, {y}, {z}], [{}, {y}, {z}], [{x}, {}, {}]]\n",
                x + 0.8,
                y + 0.3,
                z + 0.8
            ),
            _ => format!(
                "type = \"box\"\nmin = [{}, {}, {}]\nmax = [{}, {}, {}]\n",
                x - 0.3,
                y - 0.3,
                z - 0.3,
                x + 0.3,
                y + 0.3,
                z + 0.3
            ),
        };
        // The primitive, then its copy in the next material.
        for k in 0..2 {
            text += &format!("[[object]]\n{obj}material = \"{}\"\n", mats[(i + k) % 3]);
        }
    }
    let mut frames = Vec::new();
    for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
        let p = common::parse(
            &text,
            &Settings {
                accel,
                ..common::small(64, 48)
            },
        );
        assert_eq!(p.structure(), accel);
        let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
            return;
        };
        assert_close(&format!("ties {accel:?}"), &c, &g);
        frames.push(c);
    }
    for (k, other) in frames.iter().enumerate().skip(1) {
        let differ = frames[0]
            .pixels
            .iter()
            .zip(&other.pixels)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(differ, 0, "grid and structure {k}: {differ} pixels differ");
    }
}

/// `whitted bench` records a case an engine cannot run and goes on: with
/// a device fault injected into every GPU render, the CPU mirror's rows
/// are there, the GPU's failure is a FAILED line and a CSV row with its
/// message, and the exit code is 1.
#[test]
fn bench_goes_on_past_a_failing_engine() {
    if common::gpu().is_none() {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("f.csv");
    let o = whitted()
        .env("WHITTED_GPU_FAULT", "out-of-device-memory")
        .args([
            "-q",
            "bench",
            "--suite",
            "spd",
            "--only",
            "tetra,teapot",
            "--size",
            "1",
            "--runs",
            "2",
            "--warmup",
            "0",
            "--resolution",
            "24x24",
            "--backends",
            "cpu,gpu",
            "--csv",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{out}{}", stderr_of(&o));
    let failed: Vec<&str> = out.lines().filter(|l| l.starts_with("FAILED")).collect();
    assert_eq!(failed.len(), 2, "{out}");
    assert!(
        failed
            .iter()
            .all(|l| l.contains("gpu:") && l.contains("out of device memory")),
        "{out}"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let header = r.headers().unwrap().clone();
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    assert_eq!(rows.len(), 4, "{text}");
    for row in &rows {
        let gpu = row[col("engine")].starts_with("gpu");
        assert_eq!(row[col("failed")].is_empty(), !gpu, "{text}");
        assert_eq!(&row[col("runs")], if gpu { "0" } else { "2" }, "{text}");
        if !gpu {
            assert!(row[col("wall_median_s")].parse::<f64>().unwrap() > 0.0);
        }
    }
}

/// `whitted bench --kernels mega,wavefront --gpu-math exact,fast`: the GPU
/// once per kernel and arithmetic, but never the wavefront with fast
/// arithmetic (it has none); the wavefront traces the megakernel's rays.
#[test]
fn bench_times_each_kernel() {
    let Some(g) = common::gpu() else { return };
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("k.csv");
    let o = whitted()
        .args([
            "-q",
            "bench",
            "--suite",
            "spd",
            "--only",
            "balls",
            "--size",
            "1",
            "--runs",
            "1",
            "--warmup",
            "0",
            "--resolution",
            "24x24",
            "--backends",
            "gpu",
            "--kernels",
            "mega,wavefront",
            "--gpu-math",
            "exact,fast",
            "--csv",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr_of(&o));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let header = r.headers().unwrap().clone();
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    let name = g.info().name.split_whitespace().next().unwrap().to_string();
    let mut engines: Vec<String> = rows.iter().map(|r| r[col("engine")].to_string()).collect();
    engines.sort();
    let want = |s: &str| format!("gpu:{name}{s}");
    assert_eq!(
        engines,
        vec![want(""), want("/fast"), want("/wavefront")],
        "{text}"
    );
    let rays = |e: &str| {
        rows.iter()
            .find(|r| r[col("engine")] == *e)
            .map(|r| r[col("rays")].to_string())
            .unwrap()
    };
    assert_eq!(rays(&want("")), rays(&want("/wavefront")), "{text}");
}

/// Generated scenes (random spheres, a sphereflake, SPD gears with its
/// glass) on every structure, a deep octree among them: the GPU's image
/// is the mirror's within the device's tolerance (bit for bit on
/// lavapipe), and every structure's image is the grid's.
#[test]
fn generated_scenes_match_on_every_structure() {
    let gears = whitted::gen::spd::generate(whitted::gen::spd::SpdScene::Gears, Some(1)).unwrap();
    let scenes = [
        ("random 300", whitted::gen::random_spheres(300, 7)),
        ("random 2000", whitted::gen::random_spheres(2000, 8)),
        ("sphereflake 2", whitted::gen::sphereflake(2)),
        ("gears 1", gears),
    ];
    for (name, scene) in &scenes {
        let mut grid_pixels = None;
        use whitted::pack::octree::Walk;
        for (accel, leaf, levels, walk) in [
            (Accel::Grid, 8, 12, Walk::Neighbour),
            (Accel::Bvh, 8, 12, Walk::Neighbour),
            (Accel::Octree, 8, 12, Walk::Neighbour),
            (Accel::Octree, 1, 16, Walk::Neighbour),
            (Accel::Octree, 8, 12, Walk::Stack),
            (Accel::Octree, 1, 16, Walk::Stack),
            // The hybrid: `leaf` is its --hybrid-cell.
            (Accel::Hybrid, 8, 12, Walk::Neighbour),
            (Accel::Hybrid, 1, 12, Walk::Neighbour),
        ] {
            let mut settings = Settings {
                accel,
                hybrid_cell: leaf,
                ..common::small(64, 48)
            };
            settings.octree = whitted::pack::octree::Params {
                max_leaf: leaf,
                max_levels: levels,
                walk,
            };
            let p = whitted::pack::pack(scene, &settings).unwrap();
            let Some((c, g)) = render_both(&p, &GpuOptions::default()) else {
                return;
            };
            let label = format!("{name} {accel:?} leaf {leaf} levels {levels} {walk:?}");
            assert_close(&label, &c, &g);
            match &grid_pixels {
                None => grid_pixels = Some(c.pixels),
                Some(px) => assert!(*px == c.pixels, "{label}: not the grid's image"),
            }
        }
    }
}

/// The wavefront kernel (`--kernel wavefront`) renders the megakernel's
/// image with the megakernel's ray counts: every scene under every
/// structure, light buffers, jittered samples, corner sampling with SPD
/// counting (weightless rays), workgroup shapes, and a deep tree in small
/// tiles whose queues must grow mid-tile (shade runs again). On lavapipe
/// both are the CPU mirror's image bit for bit. The work counters may
/// differ only by the shadow cache's lifetime (one feeler per invocation
/// in the wavefront's shadow stage).
#[test]
fn wavefront_kernel_gives_the_megakernels_image() {
    use whitted::constants::FLAG_SPD_COUNTING;
    use whitted::gpu::GpuKernel;
    let Some(g) = common::gpu() else { return };
    let exact = g.info().kind == DeviceKind::Cpu;
    let wave = |wg: [u32; 2], tile: u32| GpuOptions {
        kernel: GpuKernel::Wavefront,
        workgroup: wg,
        tile,
        ..Default::default()
    };
    let mut cases: Vec<(String, Packed, GpuOptions)> = Vec::new();
    for f in scene_files() {
        for (accel, shadows) in [
            (Accel::Grid, Shadows::Plain),
            (Accel::Bvh, Shadows::Plain),
            (Accel::Octree, Shadows::LightBuffer),
            (Accel::Hybrid, Shadows::Plain),
        ] {
            let s = Settings {
                accel,
                shadows,
                spp: 2,
                ..common::small(36, 27)
            };
            let name = format!("{} {accel:?} {shadows:?}", f.display());
            cases.push((name, common::load(&f, &s), wave([8, 8], 256)));
        }
    }
    let showcase = common::repo().join("scenes/showcase.toml");
    let mut spd = common::load(
        &showcase,
        &Settings {
            sampling: Sampling::Corners,
            min_weight: 0.0,
            max_depth: 4,
            ..common::small(33, 21)
        },
    );
    spd.globals.flags[0] |= FLAG_SPD_COUNTING;
    cases.push((
        "showcase corners, SPD counting".into(),
        spd,
        wave([32, 1], 16),
    ));
    let deep = common::load(
        &showcase,
        &Settings {
            max_depth: 12,
            min_weight: 0.0,
            ..common::small(40, 30)
        },
    );
    cases.push(("showcase depth 12, tile 8".into(), deep, wave([4, 4], 8)));
    for (name, p, opts) in cases {
        let mega = g.render(&p, &GpuOptions::default(), &|_, _| {}).unwrap();
        let calls = std::sync::atomic::AtomicU64::new(0);
        let f = g
            .render(&p, &opts, &|_, _| {
                calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            })
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(calls.into_inner() >= 1, "{name}: no progress reported");
        assert!(
            bits(&f) == bits(&mega),
            "{name}: wavefront and megakernel differ"
        );
        assert_eq!(f.stats, mega.stats, "{name}: ray counts");
        assert!(f.work.tests > 0, "{name}: no primitive tested");
        // The eye rays' closest hits are the same walks in both kernels
        // (the cache's lifetime touches only the feelers).
        assert_eq!(f.work.eye, mega.work.eye, "{name}: the eye rays' work");
        assert!(
            f.work.shadow[0] > 0 || f.stats.shadow == 0,
            "{name}: no feeler work counted: {:?}",
            f.work
        );
        if exact {
            let cpu = cpu::render(&p, &|_, _| {});
            assert!(
                bits(&f) == bits(&cpu),
                "{name}: wavefront against the CPU mirror"
            );
        }
    }
    common::assert_no_validation_errors();
}

/// `--kernel wavefront` end to end: `render` says so in --stats and
/// writes the megakernel's image; `validate` passes; with `--gpu-math
/// fast` (which the wavefront lacks) it is a usage error, exit 2, no file.
#[test]
fn cli_kernel_wavefront() {
    if common::gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let render = |kernel: &str, extra: &[&str]| {
        let png = dir.path().join(format!("{kernel}.png"));
        let json = dir.path().join(format!("{kernel}.json"));
        let o = whitted()
            .env("WHITTED_VALIDATION", "1")
            .args([
                "render",
                "scenes/showcase.toml",
                "--width",
                "40",
                "--height",
                "30",
            ])
            .args(["--backend", "gpu", "--kernel", kernel, "-q", "-o"])
            .arg(&png)
            .arg("--stats")
            .arg(&json)
            .args(extra)
            .output()
            .unwrap();
        (o, png, json)
    };
    let (o, wave_png, json) = render("wavefront", &[]);
    assert!(o.status.success(), "{}", stderr_of(&o));
    assert!(!stderr_of(&o).contains("vulkan:"), "{}", stderr_of(&o));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(s["gpu_kernel"], "wavefront");
    assert_eq!(s["rays"]["eye"], 40 * 30);
    // The stages' device times add up to the whole (where the device
    // has a clock).
    if let Some(total) = s["seconds"]["gpu"].as_f64() {
        let stages = s["seconds"]["gpu_stages"].as_object().unwrap();
        assert_eq!(stages.len(), 5, "{stages:?}");
        let sum: f64 = stages.values().map(|v| v.as_f64().unwrap()).sum();
        assert!(
            (sum - total).abs() <= 1e-9 * total.max(1.0),
            "{sum} {total}"
        );
        assert!(stages["extend"].as_f64().unwrap() > 0.0);
    }
    let (o, mega_png, mega_json) = render("mega", &[]);
    assert!(o.status.success(), "{}", stderr_of(&o));
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mega_json).unwrap()).unwrap();
    assert_eq!(
        m["seconds"]["gpu_stages"].as_object().map(|o| o.len()),
        Some(0)
    );
    assert_eq!(
        std::fs::read(&wave_png).unwrap(),
        std::fs::read(&mega_png).unwrap()
    );
    whitted()
        .args([
            "validate",
            "scenes/showcase.toml",
            "--width",
            "32",
            "--height",
            "24",
        ])
        .args(["--kernel", "wavefront"])
        .assert()
        .success();
    std::fs::remove_file(&wave_png).unwrap();
    let (o, png, _) = render("wavefront", &["--gpu-math", "fast"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
    assert!(
        stderr_of(&o).contains("--kernel wavefront"),
        "{}",
        stderr_of(&o)
    );
    assert!(!png.exists());
    // A megakernel variant cannot stand in for the wavefront's stages.
    let o = whitted()
        .env("WHITTED_RENDER_SPV", dir.path().join("variant.spv"))
        .args([
            "render",
            "scenes/showcase.toml",
            "--width",
            "8",
            "--height",
            "8",
        ])
        .args(["--backend", "gpu", "--kernel", "wavefront", "-q", "-o"])
        .arg(&png)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
    assert!(
        stderr_of(&o).contains("WHITTED_RENDER_SPV"),
        "{}",
        stderr_of(&o)
    );
    assert!(!png.exists());
}

/// `shaders/calibration.comp`, the plain grid tracer that measures how
/// far the exact kernel is from the simplest one (docs/profiling.md): on
/// a field of opaque spheres under the grid (random spheres without
/// their floor) it traces the exact kernel's rays (each count within 2 %:
/// the two sphere tests part at grazing rays) and shows the same picture
/// (PSNR over 30 dB: another shading formula, not another scene); a scene
/// it does not model comes out magenta, with no ray traced.
#[test]
fn the_calibration_kernel_traces_the_same_rays() {
    let Some(_g) = common::gpu() else { return };
    let dir = tempfile::tempdir().unwrap();
    let spv = dir.path().join("calibration.spv");
    std::fs::write(&spv, whitted::gpu::shaders::CALIBRATION).unwrap();
    // `whitted generate --count 2000` without its floor polygon, 160×120.
    let mut field = whitted::gen::random_spheres(2000, 7);
    assert!(matches!(
        field.objects[0].shape,
        whitted::scene::Shape::Polygon { .. }
    ));
    field.objects.remove(0);
    (field.camera.width, field.camera.height) = (160, 120);
    let nff = whitted::export::to_nff(&field).unwrap();
    let scene = dir.path().join("field.nff");
    std::fs::write(&scene, nff).unwrap();
    let render = |scene: &std::path::Path, calibration: bool, name: &str| {
        let (png, json) = (
            dir.path().join(format!("{name}.png")),
            dir.path().join(format!("{name}.json")),
        );
        let mut c = whitted();
        if calibration {
            c.env("WHITTED_RENDER_SPV", &spv);
        }
        let o = c
            .args(["render", "--backend", "gpu", "--accel", "grid", "-q", "-o"])
            .arg(&png)
            .arg("--stats")
            .arg(&json)
            .arg(scene)
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", stderr_of(&o));
        assert!(
            !stderr_of(&o).contains("vulkan:"),
            "{name}: {}",
            stderr_of(&o)
        );
        let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        (image::open(&png).unwrap().to_rgb8(), s["rays"].clone())
    };
    let (exact, er) = render(&scene, false, "exact");
    let (cal, cr) = render(&scene, true, "calibration");
    for kind in ["eye", "eye_hit", "reflect", "shadow"] {
        let (e, c) = (er[kind].as_f64().unwrap(), cr[kind].as_f64().unwrap());
        assert!(
            e > 0.0 && (c - e).abs() <= 0.02 * e,
            "{kind}: exact {e}, calibration {c}"
        );
    }
    let rgb = |img: &image::RgbImage| -> Vec<[f32; 3]> {
        img.pixels()
            .map(|p| p.0.map(|c| c as f32 / 255.0))
            .collect()
    };
    let psnr = metrics::psnr(&rgb(&exact), &rgb(&cal));
    println!("calibration against exact: rays {cr} and {er}, PSNR {psnr:.1} dB");
    assert!(psnr > 30.0, "PSNR {psnr:.1} dB");
    // Boxes and glass: not modelled.
    let (img, rays) = render(
        &common::repo().join("scenes/showcase.toml"),
        true,
        "showcase",
    );
    assert!(img.pixels().all(|p| p.0 == [255, 0, 255]));
    assert_eq!(rays["eye"], 0);

    // `--kernel calibration` runs the same module; the scenes it cannot
    // render are refused (exit 2, the reason, no image).
    let by_flag = dir.path().join("flag.png");
    whitted()
        .args(["render", "--backend", "gpu", "--accel", "grid", "--kernel"])
        .args(["calibration", "-q", "-o"])
        .arg(&by_flag)
        .arg(&scene)
        .assert()
        .success();
    let by_env = dir.path().join("calibration.png");
    assert_eq!(
        std::fs::read(&by_flag).unwrap(),
        std::fs::read(&by_env).unwrap()
    );
    let refused = |scene: &std::path::Path, why: &str| {
        let png = dir.path().join("refused.png");
        let o = whitted()
            .args(["render", "--backend", "gpu", "--accel", "grid", "--kernel"])
            .args(["calibration", "-o"])
            .arg(&png)
            .arg(scene)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{}", stderr_of(&o));
        let err = stderr_of(&o);
        assert!(
            err.contains("--kernel calibration cannot render this scene"),
            "{err}"
        );
        assert!(err.contains(why), "{err}");
        assert!(!png.exists());
    };
    refused(
        &common::repo().join("scenes/showcase.toml"),
        "unbounded primitives",
    );
    // The same field with a glass material: named.
    field.materials[1].kt = glam::DVec3::splat(0.5);
    let glass = dir.path().join("glass.nff");
    std::fs::write(&glass, whitted::export::to_nff(&field).unwrap()).unwrap();
    refused(&glass, "the scene has refraction");

    // `profile`: the calibration kernel's rows beside the megakernel's,
    // never the best one, never the one saved.
    let (csv_path, cache) = (dir.path().join("p.csv"), dir.path().join("cache"));
    whitted()
        .env("XDG_CACHE_HOME", &cache)
        .args(["profile", "--accel", "grid", "--workgroups", "8x8,16x4"])
        .args([
            "--tiles",
            "full",
            "--kernels",
            "mega,calibration",
            "--repeat",
            "1",
        ])
        .args(["--save", "--csv"])
        .arg(&csv_path)
        .arg(&scene)
        .assert()
        .success();
    let rows: Vec<csv::StringRecord> = csv::Reader::from_path(&csv_path)
        .unwrap()
        .records()
        .map(|x| x.unwrap())
        .collect();
    // Columns: kernel, …, best (9), refused (10).
    assert_eq!(rows.len(), 4);
    assert!(rows.iter().all(|r| r[10].is_empty()), "{rows:?}");
    let best: Vec<_> = rows.iter().filter(|r| &r[9] == "true").collect();
    assert_eq!(best.len(), 1);
    assert_eq!(&best[0][0], "mega");
    assert_eq!(rows.iter().filter(|r| &r[0] == "calibration").count(), 2);
    let saved = std::fs::read_dir(cache.join("whitted/profiles"))
        .unwrap()
        .map(|e| std::fs::read_to_string(e.unwrap().path()).unwrap())
        .collect::<Vec<_>>();
    assert_eq!(saved.len(), 1);
    assert!(
        saved[0].contains("mega") && !saved[0].contains("calibration"),
        "{}",
        saved[0]
    );
}
