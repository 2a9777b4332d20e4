//! The Rust twin of `shaders/probe.comp`: each probe mode runs one shader
//! function on thousands of inputs, and the same CPU function (`F = f32`)
//! runs on the same inputs here; the two must agree bit for bit or within
//! the tolerance stated at each comparison (the reasons are in docs/gpu.md,
//! "Probe tolerances").

mod common;

use whitted::constants::*;
use whitted::gpu::{ProbeItem, ProbeMode, ProbeResult};
use whitted::pack::{Accel, Packed, Settings};
use whitted::trace::accel::{closest_hit, transmittance};
use whitted::trace::intersect::{intersect, normals, solve_quadratic, RayPre};
use whitted::trace::math::{v3, Ray, V3};
use whitted::trace::query::Work;
use whitted::trace::sample::{eye_dir, hash, rand01, sample_pos};
use whitted::trace::shade::{reflect_dir, refract_dir};
use whitted::trace::tree::trace_ray;
use whitted::trace::{RayStats, SceneView};

// ------------------------------------------------------------ test scenes

/// Every primitive kind and material feature: spheres (glass with
/// absorption and a transmission highlight, mirror), plane, box, convex
/// and non-convex polygons, flat and smooth triangles, clipped and
/// unclipped quadrics, cone, cylinder; three lights, one with fall-off.
const PROBE_SCENE: &str = r#"
background = [0.1, 0.2, 0.3]
ambient = 0.2

[camera]
from = [0, -10, 4]
at = [0, 0, 1]
fov = 50
width = 64
height = 48

[[light]]
position = [-6, -6, 10]
color = 0.7

[[light]]
position = [6, -3, 6]
color = [0.5, 0.45, 0.4]
falloff = [1, 0.05, 0.002]

[[light]]
position = [0, 4, 1]
color = 0.4

[material.glass]
color = 1
ka = 0
kd = 0.05
ks = 0.6
shine = 150
kst = 0.4
shine_t = 60
kr = 0.1
kt = 0.9
ior = 1.5
absorption = [0.05, 0.2, 0.1]

[material.mirror]
color = 0.9
ka = 0.02
kd = 0.05
ks = 0.8
shine = 200
kr = 0.9

[material.matte]
color = [0.8, 0.6, 0.3]
ks = 0.3
shine = 17.5

[material.tinted]
color = [0.3, 0.9, 0.4]
kt = [0.6, 0.8, 0.5]
ior = 1.0

[[object]]
type = "sphere"
center = [0, 0, 1]
radius = 1
material = "glass"

[[object]]
type = "sphere"
center = [-2.5, 1, 1]
radius = 1
material = "mirror"

[[object]]
type = "sphere"
center = [2.5, 1.5, 0.7]
radius = 0.7
material = "matte"

[[object]]
type = "plane"
point = [0, 0, -0.2]
normal = [0, 0.1, 1]
material = "matte"

[[object]]
type = "box"
min = [-1.2, -3, -0.2]
max = [0, -2, 0.8]
material = "tinted"

[[object]]
type = "polygon"
vertices = [[1, -3, 0], [2, -3, 0], [2.4, -2.4, 0.3], [1.5, -2, 0.5], [0.8, -2.4, 0.3]]
material = "matte"

[[object]]
type = "polygon"
vertices = [[-4, 3, 0], [-2, 3, 0], [-2, 3, 1], [-3, 3, 1], [-3, 3, 2], [-4, 3, 2]]
material = "mirror"

[[object]]
type = "triangle"
vertices = [[3, -1, 0], [4, -1, 0], [3.5, -1.5, 1.2]]
normals = [[0, -1, 0.3], [0.5, -1, 0], [0, -0.6, 1]]
material = "matte"

[[object]]
type = "triangle"
vertices = [[-3.5, -1, 0], [-2.5, -1.2, 0.1], [-3, -1.8, 1]]
material = "tinted"

[[object]]
type = "quadric"
coefficients = [1, 1, -1, 0, 0, 0, 0, -8, 2, 16.75]
clip = { min = [-1.2, 2.8, 0], max = [1.2, 5.2, 2] }
material = "mirror"

[[object]]
type = "quadric"
coefficients = [0.25, 1, 1, 0, 0, 0, -2.5, 1, -3, 8.5]
material = "glass"

[[object]]
type = "cone"
base = [4, 3, 0]
base_radius = 0.8
apex = [4, 3, 1.8]
apex_radius = 0.1
material = "matte"

[[object]]
type = "cylinder"
base = [-4.5, -2, 0]
apex = [-4, -2.5, 1.5]
radius = 0.4
material = "glass"
"#;

struct TestScene {
    name: String,
    packed: Packed,
}

/// The probe scene on the heuristic's grid, two explicit grids and the
/// BVH, and the bundled scenes on each structure.
fn scenes() -> Vec<TestScene> {
    let mut out = Vec::new();
    let base = common::small(64, 48);
    for (name, grid, accel) in [
        ("probe", None, Accel::Grid),
        ("probe 1x1x1", Some([1, 1, 1]), Accel::Grid),
        ("probe 7x5x3", Some([7, 5, 3]), Accel::Grid),
        ("probe bvh", None, Accel::Bvh),
        ("probe octree", None, Accel::Octree),
    ] {
        out.push(TestScene {
            name: name.into(),
            packed: common::parse(
                PROBE_SCENE,
                &Settings {
                    grid,
                    accel,
                    ..base.clone()
                },
            ),
        });
    }
    for s in ["showcase", "mesh", "quadric"] {
        for accel in [Accel::Grid, Accel::Bvh, Accel::Octree, Accel::Hybrid] {
            out.push(TestScene {
                name: format!("{s} {accel:?}"),
                packed: common::load(
                    &common::repo().join(format!("scenes/{s}.toml")),
                    &Settings {
                        accel,
                        ..base.clone()
                    },
                ),
            });
        }
    }
    out
}

// ------------------------------------------------------------ random inputs

/// SplitMix64: deterministic inputs, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn f(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
    fn unit(&mut self) -> [f32; 3] {
        loop {
            let v = [
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            ];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if l > 0.1 && l <= 1.0 {
                return v.map(|c| c / l);
            }
        }
    }
    fn below(&mut self, n: u32) -> u32 {
        (self.next() % n as u64) as u32
    }
}

fn norm(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn xyz(a: &[f32; 4]) -> [f32; 3] {
    [a[0], a[1], a[2]]
}

fn item(o: [f32; 3], d: [f32; 3], tmax: f32, u: [u32; 4]) -> ProbeItem {
    ProbeItem {
        o: [o[0], o[1], o[2], tmax],
        d: [d[0], d[1], d[2], 0.0],
        u,
    }
}

/// A point on or near primitive `p` (its "centre" per kind) and a size.
fn target(p: &Packed, i: usize) -> ([f32; 3], f32) {
    let pr = &p.prims[i];
    match pr.kind() {
        KIND_SPHERE => (xyz(&pr.a), pr.b[0]),
        KIND_TRIANGLE => {
            let c = [0, 1, 2].map(|k| (pr.a[k] + pr.b[k] + pr.c[k]) / 3.0);
            (
                c,
                0.6 * (sub(xyz(&pr.a), c).iter().map(|x| x * x).sum::<f32>()).sqrt(),
            )
        }
        KIND_BOX => {
            let c = [0, 1, 2].map(|k| (pr.a[k] + pr.b[k]) * 0.5);
            (
                c,
                0.7 * (sub(xyz(&pr.b), c).iter().map(|x| x * x).sum::<f32>()).sqrt(),
            )
        }
        KIND_POLYGON => {
            let vs = whitted::pack::polygon::vertices_3d(pr, &p.extra);
            let k = vs.len();
            let c = [0, 1, 2].map(|j| vs.iter().map(|v| v[j]).sum::<f32>() / k as f32);
            (c, 1.0)
        }
        KIND_QUADRIC if pr.a[3] != 0.0 => {
            let c = [0, 1, 2].map(|k| (pr.a[k] + pr.b[k]) * 0.5);
            (c, 1.2)
        }
        KIND_CONE => (xyz(&pr.a), pr.a[3].max(pr.b[3]) * 1.2),
        // Planes and unclipped quadrics: somewhere in front of the camera.
        _ => {
            let g = &p.globals;
            ([0, 1, 2].map(|k| g.cam_forward[k] * 10.0), 3.0)
        }
    }
}

/// A random origin around the scene: the camera, inside the grid, or far out.
fn origin(r: &mut Rng, p: &Packed) -> [f32; 3] {
    let g = &p.globals;
    match r.below(4) {
        0 => [0.0; 3],
        1 | 2 => [0, 1, 2].map(|k| {
            let (lo, hi) = (g.grid_min[k], g.grid_max[k]);
            let pad = (hi - lo) * 0.3 + 0.5;
            r.range(lo - pad, hi + pad)
        }),
        _ => {
            let u = r.unit();
            u.map(|c| c * 30.0)
        }
    }
}

/// Random rays at each primitive plus the edge cases of each kind.
fn intersect_items(p: &Packed, r: &mut Rng, per_prim: usize) -> Vec<ProbeItem> {
    let mut out = Vec::new();
    for i in 0..p.prims.len() {
        let (c, size) = target(p, i);
        let u = [i as u32, 0, 0, 0];
        for k in 0..per_prim {
            let o = origin(r, p);
            let aim = r.unit().map(|x| x * size * 1.3);
            let t = [c[0] + aim[0], c[1] + aim[1], c[2] + aim[2]];
            let d = sub(t, o);
            if d.iter().all(|&x| x == 0.0) {
                continue;
            }
            let tmax = if k % 5 == 0 {
                r.range(0.5, 40.0)
            } else {
                f32::INFINITY
            };
            out.push(item(o, norm(d), tmax, u));
        }
        let pr = &p.prims[i];
        // Origin at the target (inside spheres, boxes, closed quadrics).
        for _ in 0..per_prim / 8 {
            out.push(item(c, r.unit(), f32::INFINITY, u));
        }
        match pr.kind() {
            KIND_SPHERE => {
                // Tangent rays: perpendicular distance exactly r (in f32).
                let rad = pr.b[0];
                for _ in 0..per_prim / 8 {
                    let d = r.unit();
                    let mut n = r.unit();
                    let dn = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
                    n = norm(sub(n, d.map(|x| x * dn)));
                    let o = [0, 1, 2].map(|k| c[k] + n[k] * rad - d[k] * 5.0);
                    out.push(item(o, d, f32::INFINITY, u));
                }
            }
            KIND_BOX => {
                // Axis-parallel rays (zero direction components: ±inf in
                // 1/d) in the slabs and on their faces.
                let (lo, hi) = (xyz(&pr.a), xyz(&pr.b));
                for k in 0..per_prim / 4 {
                    let axis = k % 3;
                    let mut d = [0.0f32; 3];
                    d[axis] = if k % 2 == 0 { 1.0 } else { -1.0 };
                    let mut o = [0, 1, 2].map(|j| r.range(lo[j], hi[j]));
                    if k % 4 == 1 {
                        let j = (axis + 1) % 3;
                        o[j] = if k % 8 == 1 { lo[j] } else { hi[j] };
                    }
                    o[axis] = if d[axis] > 0.0 {
                        lo[axis] - 2.0
                    } else {
                        hi[axis] + 2.0
                    };
                    out.push(item(o, d, f32::INFINITY, u));
                }
            }
            KIND_TRIANGLE | KIND_POLYGON | KIND_PLANE => {
                // Grazing rays: nearly in the plane.
                let n = xyz(&if pr.kind() == KIND_TRIANGLE {
                    let e1 = sub(xyz(&pr.b), xyz(&pr.a));
                    let e2 = sub(xyz(&pr.c), xyz(&pr.a));
                    let n = [
                        e1[1] * e2[2] - e1[2] * e2[1],
                        e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0],
                    ];
                    let n = norm(n);
                    [n[0], n[1], n[2], 0.0]
                } else {
                    pr.a
                });
                for k in 0..per_prim / 8 {
                    let mut d = r.unit();
                    let dn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
                    let tilt = [0.0, 1e-7, 1e-4, 1e-2][k % 4];
                    d = norm([0, 1, 2].map(|j| d[j] - n[j] * dn + n[j] * tilt));
                    let o = [0, 1, 2].map(|j| c[j] - d[j] * 3.0 + n[j] * tilt * 3.0);
                    out.push(item(o, d, f32::INFINITY, u));
                }
                if pr.kind() == KIND_TRIANGLE {
                    // Through the vertices and edge midpoints.
                    let vs = [xyz(&pr.a), xyz(&pr.b), xyz(&pr.c)];
                    for k in 0..6 {
                        let t = if k < 3 {
                            vs[k]
                        } else {
                            [0, 1, 2].map(|j| (vs[k - 3][j] + vs[(k - 2) % 3][j]) * 0.5)
                        };
                        let o = origin(r, p);
                        out.push(item(o, norm(sub(t, o)), f32::INFINITY, u));
                    }
                }
            }
            _ => {}
        }
    }
    out
}

/// Rays for the grid: from the camera, from random points, and along cell
/// boundaries (origins on grid planes, axis-parallel directions).
fn scene_rays(p: &Packed, r: &mut Rng, n: usize) -> Vec<([f32; 3], [f32; 3])> {
    let g = &p.globals;
    let mut out = Vec::new();
    for k in 0..n {
        match k % 4 {
            0 => {
                let x = r.range(0.0, g.image[0] as f32);
                let y = r.range(0.0, g.image[1] as f32);
                let d = eye_dir::<f32>(g, x, y);
                out.push(([0.0; 3], [d.x, d.y, d.z]));
            }
            1 | 2 => {
                let o = origin(r, p);
                let i = r.below(p.prims.len() as u32) as usize;
                let (c, size) = target(p, i);
                let a = r.unit().map(|x| x * size);
                let d = sub([c[0] + a[0], c[1] + a[1], c[2] + a[2]], o);
                if d.iter().any(|&x| x != 0.0) {
                    out.push((o, norm(d)));
                }
            }
            _ => {
                let axis = r.below(3) as usize;
                let mut d = [0.0f32; 3];
                d[axis] = if r.below(2) == 0 { 1.0 } else { -1.0 };
                let mut o = [0, 1, 2].map(|j| r.range(g.grid_min[j], g.grid_max[j]));
                for (j, oj) in o.iter_mut().enumerate() {
                    if j != axis && r.below(2) == 0 && g.grid_dims[j] > 0 {
                        let cell = r.below(g.grid_dims[j] + 1) as f32;
                        *oj = g.grid_min[j] + cell * g.grid_cell[j];
                    }
                }
                o[axis] = if d[axis] > 0.0 {
                    g.grid_min[axis] - 1.0
                } else {
                    g.grid_max[axis] + 1.0
                };
                out.push((o, d));
            }
        }
    }
    out
}

// ------------------------------------------------------------ CPU twins

fn v(a: [f32; 3]) -> V3<f32> {
    v3(a[0], a[1], a[2])
}

fn ray(it: &ProbeItem) -> Ray<f32> {
    Ray {
        o: v(xyz(&it.o)),
        d: v(xyz(&it.d)),
    }
}

fn bits(v: V3<f32>) -> [u32; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// What `probe.comp` computes for `it` in `mode`, computed on the CPU.
fn cpu_probe(p: &Packed, mode: ProbeMode, it: &ProbeItem) -> ProbeResult {
    let s = SceneView::new(p);
    let mut res = ProbeResult::default();
    let mut work = Work::default();
    match mode {
        ProbeMode::Intersect => {
            let r = ray(it);
            let pre = RayPre::new(r.d, true);
            let prim = &p.prims[it.u[0] as usize];
            if let Some(h) = intersect(prim, &p.extra, &r, &pre, it.o[3]) {
                res.a = [1.0, h.t, h.u, h.v];
                let pt = r.o + r.d * h.t;
                let (ng, ns) = normals(prim, &p.extra, pt, &h);
                res.b = [ng.x, ng.y, ng.z, 0.0];
                let b = bits(ns);
                res.u = [b[0], b[1], b[2], 0];
            }
        }
        ProbeMode::Closest => {
            let r = ray(it);
            let pre = RayPre::new(r.d, true);
            res.u[0] = u32::MAX;
            if let Some((h, pi)) = closest_hit(&s, &r, &pre, it.o[3], &mut work) {
                res.a = [1.0, h.t, h.u, h.v];
                res.u[0] = pi;
            }
        }
        ProbeMode::Transmittance => {
            let r = ray(it);
            let pre = RayPre::new(r.d, true);
            let t = transmittance(&s, &r, &pre, it.o[3], usize::MAX, &mut work);
            res.a = [t.x, t.y, t.z, 0.0];
        }
        ProbeMode::Refract => {
            let (i, n) = (v(xyz(&it.d)), v(xyz(&it.o)));
            if let Some(t) = refract_dir(i, n, it.o[3]) {
                res.a = [1.0, t.x, t.y, t.z];
            }
            let rf = reflect_dir(i, n);
            res.b = [rf.x, rf.y, rf.z, 0.0];
        }
        ProbeMode::Trace => {
            let mut st = RayStats::default();
            let c = trace_ray(&s, ray(it), &mut st, &mut work);
            res.a = [c.x, c.y, c.z, 0.0];
            res.u = [
                st.eye_hit as u32,
                st.reflect as u32,
                st.refract as u32,
                st.shadow as u32,
            ];
        }
        ProbeMode::Sample => {
            let d = eye_dir::<f32>(&p.globals, it.o[0], it.o[1]);
            res.a = [d.x, d.y, d.z, rand01(it.u[0], it.u[1], it.u[2])];
            let (x, y) = sample_pos(&p.globals, it.u[0], it.u[1], it.u[2]);
            res.u = [hash(it.u[0]), x.to_bits(), y.to_bits(), 0];
        }
        ProbeMode::Solve => {
            if let Some((t0, t1)) = solve_quadratic(it.o[0], it.o[1], it.o[2]) {
                res.a = [1.0, t0, t1, 0.0];
            }
        }
    }
    res
}

// ------------------------------------------------------------ comparison

/// Distance in units in the last place (0 for equal values, ±0 included;
/// u64::MAX when exactly one is NaN).
fn ulps(a: f32, b: f32) -> u64 {
    if a == b || (a.is_nan() && b.is_nan()) {
        return 0;
    }
    if a.is_nan() || b.is_nan() {
        return u64::MAX;
    }
    let ord = |x: f32| {
        let i = x.to_bits() as i32;
        if i < 0 {
            i64::from(i32::MIN) - i64::from(i)
        } else {
            i64::from(i)
        }
    };
    ord(a).abs_diff(ord(b))
}

/// Agreement of one value: within `max_ulps`, or (for values that result
/// from cancellation, where ULPs of a tiny number mean nothing) within
/// `abs` absolutely.
fn close(a: f32, b: f32, max_ulps: u64, abs: f32) -> bool {
    ulps(a, b) <= max_ulps || (a - b).abs() <= abs
}

/// Tally of one probe comparison.
#[derive(Default)]
struct Tally {
    items: usize,
    /// Items where a discrete outcome differs (hit/miss, primitive,
    /// refract/TIR, ray counts).
    flips: usize,
    /// Items where values differ beyond tolerance with the same outcome.
    bad: usize,
    max_ulps: u64,
    first_bad: Option<String>,
}

impl Tally {
    fn flip(&mut self, msg: impl FnOnce() -> String) {
        self.flips += 1;
        if self.first_bad.is_none() && self.flips > 0 {
            self.first_bad = Some(format!("outcome: {}", msg()));
        }
    }
    fn value(&mut self, ok: bool, u: u64, msg: impl FnOnce() -> String) {
        if u != u64::MAX {
            self.max_ulps = self.max_ulps.max(u);
        }
        if !ok {
            self.bad += 1;
            if self.first_bad.is_none() || self.bad == 1 {
                self.first_bad = Some(format!("value: {}", msg()));
            }
        }
    }
    /// `max_flip_fraction`: outcomes may differ only on this share of
    /// items (rays on a boundary, where one rounding decides).
    fn check(&self, what: &str, max_flip_fraction: f64) {
        println!(
            "{what}: {} items, {} outcome flips, {} values over tolerance, max {} ulps",
            self.items, self.flips, self.bad, self.max_ulps
        );
        assert!(self.items > 0, "{what}: no items");
        assert_eq!(
            self.bad,
            0,
            "{what}: {}",
            self.first_bad.as_deref().unwrap_or("")
        );
        let allowed = (self.items as f64 * max_flip_fraction).floor() as usize;
        assert!(
            self.flips <= allowed,
            "{what}: {} of {} outcomes differ (allowed {allowed}); first: {}",
            self.flips,
            self.items,
            self.first_bad.as_deref().unwrap_or("")
        );
    }
}

fn run(
    p: &Packed,
    mode: ProbeMode,
    items: &[ProbeItem],
) -> Option<Vec<(ProbeResult, ProbeResult)>> {
    let g = common::gpu()?;
    let gpu = g
        .probe(p, mode, items)
        .unwrap_or_else(|e| panic!("probe {mode:?}: {e}"));
    common::assert_no_validation_errors();
    assert_eq!(gpu.len(), items.len());
    Some(
        items
            .iter()
            .zip(gpu)
            .map(|(it, gr)| (cpu_probe(p, mode, it), gr))
            .collect(),
    )
}

// Tolerances (docs/gpu.md, "Probe tolerances", gives each reason).
//
// On a CPU Vulkan device (lavapipe: LLVM, IEEE division and square root,
// never fused, `precise` keeps the order) every function is bit for bit
// the CPU's, the shading included (exp and pow are the twins in math.glsl,
// not the driver's): 0 ULPs and no differing outcome, and the tests demand
// exactly that. A hardware GPU may divide
// and take square roots to 2.5 ULP (the Vulkan minimum), so there the
// geometric values get `ulps_geometry()` and rays on a boundary may flip.

/// True when the device must match bit for bit.
fn exact() -> bool {
    common::gpu().is_some_and(|g| g.info().kind == whitted::gpu::DeviceKind::Cpu)
}

/// ULPs allowed for t, barycentrics, normals, directions, roots.
fn ulps_geometry() -> u64 {
    if exact() {
        0
    } else {
        64
    }
}

/// Absolute slack for values near 0 that come from cancellation (only
/// where ULPs are allowed at all).
fn abs_geometry() -> f32 {
    if exact() {
        0.0
    } else {
        1e-5
    }
}

/// Share of items whose discrete outcome (hit or miss, which primitive,
/// refraction or TIR) may differ: `boundary` on a hardware GPU, 0 exact.
fn flips(boundary: f64) -> f64 {
    if exact() {
        0.0
    } else {
        boundary
    }
}

// ------------------------------------------------------------ tests

#[test]
fn intersect_routines_match() {
    if common::gpu().is_none() {
        return;
    }
    let mut r = Rng(1);
    // The primitives do not depend on the structure: one packing of each.
    let all = scenes();
    for sc in all
        .iter()
        .filter(|s| s.name == "probe" || s.name.ends_with("Grid"))
    {
        let items = intersect_items(&sc.packed, &mut r, 160);
        let Some(res) = run(&sc.packed, ProbeMode::Intersect, &items) else {
            return;
        };
        let mut per_kind: Vec<Tally> = (0..7).map(|_| Tally::default()).collect();
        for (it, (c, g)) in items.iter().zip(&res) {
            let kind = sc.packed.prims[it.u[0] as usize].kind() as usize;
            let t = &mut per_kind[kind];
            t.items += 1;
            let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
            if c.a[0] != g.a[0] {
                t.flip(msg);
                continue;
            }
            if c.a[0] == 0.0 {
                continue;
            }
            // A hit at a different root is an outcome flip too.
            if ulps(c.a[1], g.a[1]) > 4096 {
                t.flip(msg);
                continue;
            }
            for k in 1..4 {
                let u = ulps(c.a[k], g.a[k]);
                t.value(
                    close(
                        c.a[k],
                        g.a[k],
                        ulps_geometry(),
                        abs_geometry() * c.a[1].max(1.0),
                    ),
                    u,
                    msg,
                );
            }
            for k in 0..3 {
                let u = ulps(c.b[k], g.b[k]);
                t.value(
                    close(c.b[k], g.b[k], ulps_geometry(), abs_geometry()),
                    u,
                    msg,
                );
                let (cs, gs) = (f32::from_bits(c.u[k]), f32::from_bits(g.u[k]));
                t.value(
                    close(cs, gs, ulps_geometry(), abs_geometry()),
                    ulps(cs, gs),
                    msg,
                );
            }
        }
        let names = [
            "sphere", "plane", "triangle", "polygon", "box", "quadric", "cone",
        ];
        for (k, t) in per_kind.iter().enumerate() {
            if t.items > 0 {
                // 1%: tangent, grazing and edge rays are built to sit on the
                // boundary, where either answer is right.
                t.check(&format!("{} intersect {}", sc.name, names[k]), flips(0.01));
            }
        }
    }
}

#[test]
fn solve_quadratic_matches() {
    let mut r = Rng(2);
    let mut items = Vec::new();
    for k in 0..4000 {
        let (a, b, c) = match k % 5 {
            // From roots: (t - r0)(t - r1) scaled.
            0 | 1 => {
                let (r0, r1, s) = (
                    r.range(-50.0, 50.0),
                    r.range(-50.0, 50.0),
                    r.range(0.01, 10.0),
                );
                (s, -s * (r0 + r1), s * r0 * r1)
            }
            // Random, many without real roots.
            2 => (r.range(-2.0, 2.0), r.range(-5.0, 5.0), r.range(-5.0, 5.0)),
            // Nearly linear: |a| tiny against |b|.
            3 => (r.range(-1e-9, 1e-9), r.range(-3.0, 3.0), r.range(-3.0, 3.0)),
            // Double roots, zero coefficients.
            _ => {
                let t = r.range(-4.0, 4.0);
                [
                    (1.0, -2.0 * t, t * t),
                    (0.0, 0.0, 1.0),
                    (1.0, 0.0, 0.0),
                    (0.0, 2.0, 3.0),
                ][k % 4]
            }
        };
        items.push(item([a, b, c], [0.0; 3], 0.0, [0; 4]));
    }
    let p = common::parse(PROBE_SCENE, &common::small(8, 8));
    let Some(res) = run(&p, ProbeMode::Solve, &items) else {
        return;
    };
    let mut t = Tally::default();
    for (it, (c, g)) in items.iter().zip(&res) {
        t.items += 1;
        let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
        if c.a[0] != g.a[0] {
            t.flip(msg);
            continue;
        }
        for k in 1..3 {
            // Cancellation-free: a square root and two divisions.
            let tol = if exact() { 0 } else { 8 };
            t.value(close(c.a[k], g.a[k], tol, 0.0), ulps(c.a[k], g.a[k]), msg);
        }
    }
    // A discriminant exactly at 0 may round either way: 0.5%.
    t.check("solve_quadratic", flips(0.005));
}

#[test]
fn refraction_and_reflection_match() {
    let mut r = Rng(3);
    let mut items = Vec::new();
    for k in 0..4000 {
        let n = r.unit();
        let mut i = r.unit();
        let d = i[0] * n[0] + i[1] * n[1] + i[2] * n[2];
        if d > 0.0 {
            i = i.map(|x| -x);
        }
        let eta = [1.0 / 1.5, 1.5, 1.0, 1.0 / 1.33, 2.4, r.range(0.3, 3.0)][k % 6];
        items.push(item(n, i, eta, [0; 4]));
    }
    // Exactly at normal incidence and grazing.
    items.push(item([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 1.5, [0; 4]));
    items.push(item([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 1.5, [0; 4]));
    let p = common::parse(PROBE_SCENE, &common::small(8, 8));
    let Some(res) = run(&p, ProbeMode::Refract, &items) else {
        return;
    };
    let mut t = Tally::default();
    for (it, (c, g)) in items.iter().zip(&res) {
        t.items += 1;
        let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
        let (tol, abs) = if exact() { (0, 0.0) } else { (16, 1e-6) };
        for k in 0..3 {
            t.value(close(c.b[k], g.b[k], tol, abs), ulps(c.b[k], g.b[k]), msg);
        }
        if c.a[0] != g.a[0] {
            t.flip(msg);
            continue;
        }
        for k in 1..4 {
            t.value(close(c.a[k], g.a[k], tol, abs), ulps(c.a[k], g.a[k]), msg);
        }
    }
    // Only at the critical angle (k exactly 0) may TIR differ: 0.1%.
    t.check("refract_dir/reflect_dir", flips(0.001));
}

#[test]
fn sampling_matches() {
    let mut r = Rng(4);
    for spp in [1, 4, 6] {
        let p = common::parse(
            PROBE_SCENE,
            &Settings {
                spp,
                ..common::small(64, 48)
            },
        );
        let g = &p.globals;
        let mut items = Vec::new();
        for k in 0..3000u32 {
            let x = r.range(0.0, g.image[0] as f32);
            let y = r.range(0.0, g.image[1] as f32);
            let px = r.below(g.image[0]);
            // In range: sample_pos computes the pixel index py·W + px.
            let py = r.below(g.image[1]);
            let s = if k % 16 == 0 { spp - 1 } else { r.below(spp) };
            items.push(item([x, y, 0.0], [0.0; 3], 0.0, [px, py, s, 0]));
        }
        // Integer corners, the hash on edge values.
        items.push(item([0.0, 0.0, 0.0], [0.0; 3], 0.0, [0, 0, 0, 0]));
        items.push(item([64.0, 48.0, 0.0], [0.0; 3], 0.0, [63, 47, spp - 1, 0]));
        let Some(res) = run(&p, ProbeMode::Sample, &items) else {
            return;
        };
        let mut ints = Tally::default();
        let mut dirs = Tally::default();
        for (it, (c, g)) in items.iter().zip(&res) {
            ints.items += 1;
            dirs.items += 1;
            let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
            // The integer hash and rand01's exactly representable steps:
            // bit for bit on every device.
            ints.value(c.u[0] == g.u[0], 0, msg);
            ints.value(
                c.a[3].to_bits() == g.a[3].to_bits(),
                ulps(c.a[3], g.a[3]),
                msg,
            );
            // sample_pos: px + (s mod nx + ξ)/nx divides by nx (3 at 6
            // samples per pixel): bit for bit on a CPU device; on a GPU the
            // division may take 2.5 ULP of a value under 1, and the sum one
            // rounding more: 4 ULP of the result.
            let tol_pos = if exact() { 0 } else { 4 };
            for k in 1..3 {
                let (a, b) = (f32::from_bits(c.u[k]), f32::from_bits(g.u[k]));
                ints.value(close(a, b, tol_pos, 0.0), ulps(a, b), msg);
            }
            // eye_dir: sx = x/W·2 − 1 cancels near the image's centre, so a
            // GPU's division error (2.5 ULP of a value near 0.5) stays as an
            // absolute error of about 2^-23 in sx and sy, times the basis
            // lengths, then one normalize (sqrt + division, 4 ULP). Exact on
            // a CPU device.
            let basis = |v: &[f32; 4]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let slack =
                4.0 * f32::EPSILON * (basis(&p.globals.cam_right) + basis(&p.globals.cam_up));
            for k in 0..3 {
                let (tol, abs) = if exact() { (0, 0.0) } else { (4, slack) };
                dirs.value(close(c.a[k], g.a[k], tol, abs), ulps(c.a[k], g.a[k]), msg);
            }
        }
        ints.check(&format!("hash/rand01/sample_pos (spp {spp})"), 0.0);
        dirs.check(&format!("eye_dir (spp {spp})"), 0.0);
    }
}

#[test]
fn closest_hit_matches() {
    if common::gpu().is_none() {
        return;
    }
    let mut r = Rng(5);
    for sc in scenes() {
        let mut items: Vec<ProbeItem> = scene_rays(&sc.packed, &mut r, 3000)
            .into_iter()
            .enumerate()
            .map(|(k, (o, d))| {
                item(
                    o,
                    d,
                    if k % 7 == 0 {
                        r.range(0.5, 20.0)
                    } else {
                        f32::INFINITY
                    },
                    [0; 4],
                )
            })
            .collect();
        items.truncate(3000);
        let Some(res) = run(&sc.packed, ProbeMode::Closest, &items) else {
            return;
        };
        let mut t = Tally::default();
        for (it, (c, g)) in items.iter().zip(&res) {
            t.items += 1;
            let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
            if c.u[0] != g.u[0] {
                t.flip(msg);
                continue;
            }
            for k in 1..4 {
                t.value(
                    close(
                        c.a[k],
                        g.a[k],
                        ulps_geometry(),
                        abs_geometry() * c.a[1].max(1.0),
                    ),
                    ulps(c.a[k], g.a[k]),
                    msg,
                );
            }
        }
        // Rays along cell boundaries and shared edges: 0.5%.
        t.check(&format!("{} closest_hit", sc.name), flips(0.005));
    }
}

#[test]
fn transmittance_matches() {
    if common::gpu().is_none() {
        return;
    }
    let mut r = Rng(6);
    for sc in scenes() {
        let p = &sc.packed;
        let mut items = Vec::new();
        for (k, (o, d)) in scene_rays(p, &mut r, 2000).into_iter().enumerate() {
            // Shadow feelers to the lights, and random segments.
            if k % 2 == 0 && !p.lights.is_empty() {
                let l = xyz(&p.lights[k / 2 % p.lights.len()].pos);
                let ld = sub(l, o);
                let dist = (ld[0] * ld[0] + ld[1] * ld[1] + ld[2] * ld[2]).sqrt();
                if dist > 0.0 {
                    items.push(item(o, ld.map(|x| x / dist), dist, [0; 4]));
                    continue;
                }
            }
            items.push(item(o, d, r.range(0.1, 30.0), [0; 4]));
        }
        let Some(res) = run(p, ProbeMode::Transmittance, &items) else {
            return;
        };
        let mut t = Tally::default();
        for (it, (c, g)) in items.iter().zip(&res) {
            t.items += 1;
            let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
            // Products of the same k_t in the same order: exact, unless a
            // crossing at the segment's end flips.
            if (0..3).any(|k| c.a[k] != g.a[k]) {
                t.flip(msg);
            }
        }
        t.check(&format!("{} transmittance", sc.name), flips(0.005));
    }
}

#[test]
fn full_trace_matches() {
    if common::gpu().is_none() {
        return;
    }
    let mut r = Rng(7);
    for sc in scenes() {
        let p = &sc.packed;
        let items: Vec<ProbeItem> = scene_rays(p, &mut r, 2000)
            .into_iter()
            .map(|(o, d)| item(o, d, 0.0, [0; 4]))
            .collect();
        let Some(res) = run(p, ProbeMode::Trace, &items) else {
            return;
        };
        let mut t = Tally::default();
        for (it, (c, g)) in items.iter().zip(&res) {
            t.items += 1;
            let msg = || format!("{it:?}\n  cpu {c:?}\n  gpu {g:?}");
            // The ray tree's shape (its ray counts) is exact on a CPU
            // device: pow and exp only feed colours, never decisions.
            if c.u != g.u {
                t.flip(msg);
                continue;
            }
            for k in 0..3 {
                // Exact on a CPU device. On hardware the tree's divisions
                // and square roots (2.5 ULP) reach the colour through many
                // products and the twins' exp (a highlight's exponent
                // multiplies its argument's error): relative 1e-4,
                // absolute 1e-5.
                let (a, b) = (c.a[k], g.a[k]);
                let ok = if exact() {
                    a.to_bits() == b.to_bits()
                } else {
                    (a - b).abs() <= 1e-5 + 1e-4 * a.abs().max(b.abs())
                };
                t.value(ok, ulps(a, b), msg);
            }
        }
        // A ray tree differs as a whole when one of its rays flips: 1%.
        t.check(&format!("{} trace_ray", sc.name), flips(0.01));
    }
}
