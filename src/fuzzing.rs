//! The bodies of the fuzz targets (`fuzz/`, docs/reliability.md), kept in
//! the library so that `tests/fuzz_corpus.rs` replays every committed
//! corpus input and every past crash through exactly the code libFuzzer
//! ran, under plain `cargo test`.
//!
//! Each target takes the raw bytes of one input and either returns an
//! [`Outcome`] or panics; a panic is a finding. Besides "no panic, no
//! abort, no hang", each checks what should hold of its result:
//!
//! * a refusal is a [`crate::scene::SceneError`] that names the file
//!   (`FILE: ...` or `FILE:LINE:COL: ...`, the line within the text);
//! * an accepted scene is well formed ([`check_scene`]: finite numbers,
//!   indices in range, a usable camera), packs or is refused by
//!   `pack::pack` with a message, and renders on the CPU mirror at most
//!   [`MAX_SIDE`]×[`MAX_SIDE`] pixels, every pixel finite and
//!   non-negative.
//!
//! The targets: [`toml`] and [`nff`] (scene text), [`obj`] (a `.obj`
//! mesh, as a TOML scene's `file` mesh) and [`pack`] (an `arbitrary`-built
//! scene, written out as TOML, read back, packed and rendered with
//! arbitrary settings).

use crate::budget::Budget;
use crate::pack::{self as packing, Accel, Sampling, Settings};
use crate::scene::{self, Files, Scene, Shape};
use arbitrary::{Arbitrary, Unstructured};
use glam::DVec3;
use std::fmt::Write;
use std::path::Path;

/// Largest image side the targets render.
pub const MAX_SIDE: u32 = 8;

/// Deepest ray tree the targets render.
pub const MAX_DEPTH: u32 = 3;

/// The memory budget the targets pack under (`--memory-limit 32M`): a
/// small input that asks for a huge grid is refused, not allocated.
pub const MEMORY_LIMIT: u64 = 32 << 20;

/// What one input came to.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// The reader refused the input; the message as the CLI prints it.
    Refused(String),
    /// The scene was read but packing refused it (over the memory budget).
    PackRefused(String),
    /// Read, packed and rendered.
    Rendered(Summary),
}

/// What an input that rendered came to.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub objects: usize,
    pub width: u32,
    pub height: u32,
    /// The mean of the image's channels (finite, >= 0).
    pub mean: f64,
}

impl Outcome {
    /// The refusal's message, if this is one.
    pub fn message(&self) -> Option<&str> {
        match self {
            Outcome::Refused(m) | Outcome::PackRefused(m) => Some(m),
            Outcome::Rendered(_) => None,
        }
    }
}

/// Fuzz target `toml`: the bytes as a native TOML scene named `x.toml`;
/// every `.obj` file it names reads as [`OCTAHEDRON`] (from memory).
pub fn toml(data: &[u8]) -> Outcome {
    read_text(data, Path::new("x.toml"))
}

/// Fuzz target `nff`: the bytes as an NFF scene named `x.nff`.
pub fn nff(data: &[u8]) -> Outcome {
    read_text(data, Path::new("x.nff"))
}

/// The `.obj` file every mesh `file` of the `toml` target reads as.
pub const OCTAHEDRON: &str = "\
v 1 0 0
v -1 0 0
v 0 1 0
v 0 -1 0
v 0 0 1
v 0 0 -1
f 1 3 5
f 3 2 5
f 2 4 5
f 4 1 5
f 3 1 6
f 2 3 6
f 4 2 6
f 1 4 6
";

/// The TOML scene round the `obj` target's mesh (`m.obj`, flat).
pub const OBJ_SCENE: &str = "\
[camera]
from = [3, -10, 5]
at = [0, 0, 0]
[[light]]
position = [5, -5, 10]
[[object]]
type = \"mesh\"
file = \"m.obj\"
";

/// Fuzz target `obj`: the bytes as the Wavefront `.obj` file of a mesh
/// in a TOML scene ([`OBJ_SCENE`]), read from memory through the TOML
/// reader's own mesh path; `smooth = true` when the input's length is odd.
/// A refusal must name the `.obj` file and a line within it.
pub fn obj(data: &[u8]) -> Outcome {
    let smooth = data.len() % 2 == 1;
    let text = format!("{OBJ_SCENE}smooth = {smooth}\n");
    let path = Path::new("x.toml");
    match scene::parse_in(&OneFile(data), &text, path, &|_, _| {}) {
        Err(e) => {
            let m = e.to_string();
            let o = refused(&m, path, &text);
            let (_, rest) = m
                .split_once(" m.obj")
                .unwrap_or_else(|| panic!("the error does not name m.obj: {m}"));
            // `m.obj:LINE: ...`, `m.obj:LINE:COL: ...` or `m.obj: ...`.
            let digits: String = rest
                .strip_prefix(':')
                .unwrap_or("")
                .chars()
                .take_while(|c| c.is_ascii_digit())
                .collect();
            if !digits.is_empty() {
                let line: usize = digits
                    .parse()
                    .unwrap_or_else(|_| panic!("a line number beyond usize: {m}"));
                let lines = data.split(|&b| b == b'\n').count();
                assert!(
                    (1..=lines).contains(&line),
                    "line {line} is outside the .obj text ({lines} lines): {m}"
                );
            }
            o
        }
        Ok(s) => {
            check_scene(&s);
            render_small(&s, &small_settings())
        }
    }
}

/// Files in memory: every path reads as the same bytes.
struct OneFile<'a>(&'a [u8]);

impl Files for OneFile<'_> {
    fn read(&self, _: &Path) -> std::io::Result<Vec<u8>> {
        Ok(self.0.to_vec())
    }
    fn size(&self, _: &Path) -> Option<u64> {
        Some(self.0.len() as u64)
    }
}

/// Fuzz target `pack`: the bytes build a [`SceneSpec`] (the `arbitrary`
/// crate), which is written as TOML ([`SceneSpec::to_toml`]), read back,
/// packed and rendered with the spec's settings.
pub fn pack(data: &[u8]) -> Outcome {
    let spec = match SceneSpec::arbitrary_take_rest(Unstructured::new(data)) {
        Ok(s) => s,
        // Too few bytes for even an empty spec: nothing to test.
        Err(_) => return Outcome::Refused("fuzz.toml: not enough input".into()),
    };
    pack_spec(&spec)
}

/// The TOML scene the `pack` target writes for `data` (None when the bytes
/// are too few for a spec).
pub fn pack_toml(data: &[u8]) -> Option<String> {
    SceneSpec::arbitrary_take_rest(Unstructured::new(data))
        .ok()
        .map(|s| s.to_toml())
}

/// The `pack` target on a spec already built.
pub fn pack_spec(spec: &SceneSpec) -> Outcome {
    let text = spec.to_toml();
    match parse_spec_toml(&text) {
        Err(e) => refused(&e.to_string(), Path::new(SPEC_FILE), &text),
        Ok(s) => {
            check_scene(&s);
            render_small(&s, &spec.render.settings())
        }
    }
}

/// Reads `data` as the scene file `path`, as `scene::load` does (not
/// UTF-8 is an error at the bad byte), with [`OCTAHEDRON`] for every
/// `.obj` file it names.
fn read_text(data: &[u8], path: &Path) -> Outcome {
    let text = match scene::text_from_bytes(data.to_vec()) {
        Ok(t) => t,
        Err(e) => {
            let m = e.into_scene_error(path).to_string();
            // The valid text before the bad byte holds its line.
            let valid = match std::str::from_utf8(data) {
                Ok(t) => t,
                Err(u) => std::str::from_utf8(&data[..u.valid_up_to()]).unwrap_or(""),
            };
            return refused(&m, path, valid);
        }
    };
    let text = text.as_str();
    match scene::parse_in(&OneFile(OCTAHEDRON.as_bytes()), text, path, &|_, _| {}) {
        Err(e) => refused(&e.to_string(), path, text),
        Ok(s) => {
            check_scene(&s);
            render_small(&s, &small_settings())
        }
    }
}

/// Checks a reader's error message: `FILE: ...` or `FILE:LINE[:COL]: ...`
/// with the line within `text`, and a non-empty reason.
fn refused(message: &str, path: &Path, text: &str) -> Outcome {
    let name = path.display().to_string();
    let rest = message
        .strip_prefix(&name)
        .unwrap_or_else(|| panic!("the error does not start with the file name: {message}"));
    let rest = rest
        .strip_prefix(':')
        .unwrap_or_else(|| panic!("no `:` after the file name: {message}"));
    // Either " reason" or "LINE:COL: reason" / "LINE: reason".
    if !rest.starts_with(' ') {
        let line: usize = rest
            .split(':')
            .next()
            .and_then(|l| l.parse().ok())
            .unwrap_or_else(|| panic!("no line number after the file name: {message}"));
        let lines = text.lines().count().max(1) + 1;
        assert!(
            (1..=lines).contains(&line),
            "line {line} is outside the text ({lines} lines): {message}"
        );
    }
    let reason = message.rsplit(": ").next().unwrap_or("");
    assert!(!reason.trim().is_empty(), "an empty reason: {message:?}");
    Outcome::Refused(message.to_string())
}

/// Asserts what every scene a reader accepts must satisfy: every number
/// finite, every index in range, a usable camera and image size.
pub fn check_scene(s: &Scene) {
    let fin = |v: DVec3, what: &str| assert!(v.is_finite(), "{what} is not finite: {v}");
    let c = &s.camera;
    fin(c.from, "camera.from");
    fin(c.at, "camera.at");
    fin(c.up, "camera.up");
    assert!(c.at != c.from, "camera at == from");
    assert!(
        c.up.cross(c.at - c.from).length() > 0.0,
        "camera up parallel"
    );
    assert!(c.fov > 0.0 && c.fov < 180.0, "fov {}", c.fov);
    assert!(
        c.width >= 1 && c.height >= 1,
        "image {}x{}",
        c.width,
        c.height
    );
    fin(s.background, "background");
    fin(s.ambient, "ambient");
    for l in &s.lights {
        fin(l.position, "light position");
        fin(l.color, "light color");
        assert!(l.falloff.iter().all(|f| f.is_finite()), "falloff");
    }
    assert!(!s.materials.is_empty(), "no default material");
    for m in &s.materials {
        for v in [m.ka, m.kd, m.kr, m.kt, m.absorption] {
            fin(v, &m.name);
        }
        for x in [m.ksr, m.nr, m.kst, m.nt, m.ior] {
            assert!(x.is_finite(), "material {}: {x}", m.name);
        }
    }
    for (i, o) in s.objects.iter().enumerate() {
        assert!(
            (o.material as usize) < s.materials.len(),
            "object {i}: material {} of {}",
            o.material,
            s.materials.len()
        );
        let pts: Vec<DVec3> = match &o.shape {
            Shape::Sphere { center, radius } => {
                assert!(*radius > 0.0 && radius.is_finite(), "radius {radius}");
                vec![*center]
            }
            Shape::Plane { point, normal } => {
                assert!(*normal != DVec3::ZERO, "object {i}: zero plane normal");
                vec![*point, *normal]
            }
            Shape::Polygon { vertices } => {
                assert!(
                    vertices.len() >= 3,
                    "object {i}: polygon of {}",
                    vertices.len()
                );
                vertices.clone()
            }
            Shape::Triangle { vertices, normals } => {
                let mut p = vertices.to_vec();
                if let Some(n) = normals {
                    p.extend_from_slice(&n[..]);
                }
                p
            }
            Shape::Mesh(m) => {
                assert!(!m.triangles.is_empty(), "object {i}: empty mesh");
                for t in &m.triangles {
                    for &k in t {
                        assert!((k as usize) < m.positions.len(), "object {i}: index {k}");
                    }
                }
                if let Some(n) = &m.normals {
                    assert_eq!(n.len(), m.positions.len(), "object {i}: normals");
                    for v in n {
                        fin(*v, "mesh normal");
                    }
                }
                m.positions.clone()
            }
            Shape::Box { min, max } => {
                assert!(min.cmplt(*max).all(), "object {i}: box {min} {max}");
                vec![*min, *max]
            }
            Shape::Quadric { coefficients, clip } => {
                assert!(coefficients.iter().all(|k| k.is_finite()), "quadric");
                clip.map_or(vec![], |(a, b)| vec![a, b])
            }
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => {
                assert!(base != apex, "object {i}: cone base == apex");
                assert!(base_radius.is_finite() && apex_radius.is_finite(), "cone");
                vec![*base, *apex]
            }
        };
        for p in pts {
            fin(p, "object point");
        }
    }
}

/// Default settings with the fuzzing budget (reading the machine's memory
/// size for every input would cost more than the input).
fn small_settings() -> Settings {
    Settings {
        width: None,
        height: None,
        max_depth: MAX_DEPTH,
        min_weight: 1.0 / 256.0,
        spp: 1,
        sampling: Sampling::Centers,
        grid: None,
        accel: Accel::Auto,
        budget: Budget::bytes(MEMORY_LIMIT),
        offset: None,
        shadows: crate::pack::Shadows::Plain,
        octree: Default::default(),
        hybrid_cell: crate::pack::hybrid::DEFAULT_CELL,
    }
}

/// The name the `pack` target gives the TOML it writes from a spec.
const SPEC_FILE: &str = "fuzz.toml";

/// Reads a spec's TOML as the `pack` target does ([`OCTAHEDRON`] for its
/// meshes).
fn parse_spec_toml(text: &str) -> Result<Scene, scene::SceneError> {
    scene::parse_in(
        &OneFile(OCTAHEDRON.as_bytes()),
        text,
        Path::new(SPEC_FILE),
        &|_, _| {},
    )
}

/// The scene and the settings the `pack` target renders `data` with (None
/// when the bytes are too few for a spec or the reader refuses the
/// scene): for replaying a finding elsewhere, e.g. on a GPU.
pub fn pack_case(data: &[u8]) -> Option<(Scene, Settings)> {
    let spec = SceneSpec::arbitrary_take_rest(Unstructured::new(data)).ok()?;
    let s = parse_spec_toml(&spec.to_toml()).ok()?;
    let settings = small(&s, &spec.render.settings());
    Some((s, settings))
}

/// `settings` cut to the fuzz targets' size, depth and memory limits.
fn small(s: &Scene, settings: &Settings) -> Settings {
    Settings {
        width: Some(settings.width.unwrap_or(s.camera.width).clamp(1, MAX_SIDE)),
        height: Some(
            settings
                .height
                .unwrap_or(s.camera.height)
                .clamp(1, MAX_SIDE),
        ),
        max_depth: settings.max_depth.min(MAX_DEPTH),
        budget: Budget::bytes(MEMORY_LIMIT),
        ..settings.clone()
    }
}

/// Packs `s` for an image of at most [`MAX_SIDE`]² pixels and depth
/// [`MAX_DEPTH`] and renders it on the CPU mirror; checks every pixel.
fn render_small(s: &Scene, settings: &Settings) -> Outcome {
    let settings = small(s, settings);
    let mut p = match packing::pack(s, &settings) {
        Ok(p) => p,
        Err(e) => {
            let m = e.to_string();
            assert!(!m.trim().is_empty(), "an empty refusal");
            return Outcome::PackRefused(m);
        }
    };
    let f = crate::cpu::render(&p, &|_, _| {});
    // Under the BVH, eye rays in packets must give the single rays'
    // image and ray counts, bit for bit (docs/method.md, "Packets of rays").
    let bits = |f: &crate::cpu::Frame| {
        f.pixels
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    if p.structure() == crate::pack::Accel::Bvh {
        let packed = crate::cpu::render_packets::<f32>(&p, 8, &|_, _| {});
        assert!(bits(&packed) == bits(&f), "packets of 8 change the image");
        assert_eq!(packed.stats, f.stats, "packets of 8 change the ray counts");
    }
    // The shadow cache must change no pixel under any structure: every
    // feeler walking the structure gives the same image, bit for bit
    // (docs/method.md, "Shadow cache").
    p.set_shadow_cache(false);
    let walked = crate::cpu::render(&p, &|_, _| {});
    assert!(
        bits(&walked) == bits(&f),
        "the shadow cache changes the image ({:?})",
        p.structure()
    );
    assert_eq!(
        walked.stats, f.stats,
        "the shadow cache changes the ray counts"
    );
    assert_eq!(
        f.pixels.len() as u64,
        f.width as u64 * f.height as u64,
        "pixel count"
    );
    let mut sum = 0.0f64;
    for (i, px) in f.pixels.iter().enumerate() {
        for &c in px {
            assert!(
                c.is_finite() && c >= 0.0,
                "pixel {i} ({}, {}) is {px:?}",
                i as u32 % f.width,
                i as u32 / f.width
            );
            sum += c as f64;
        }
    }
    Outcome::Rendered(Summary {
        objects: s.objects.len(),
        width: f.width,
        height: f.height,
        mean: sum / (3 * f.pixels.len()).max(1) as f64,
    })
}

// ---------------------------------------------------------------------
// The `pack` target's input: a scene spec that `arbitrary` builds from
// bytes, written out as TOML so that the reader decides what is valid.
// Lists are cut to a few entries so that one input runs in milliseconds.

/// Most lights, materials and objects a spec writes.
const MAX_LIGHTS: usize = 4;
const MAX_MATERIALS: usize = 6;
const MAX_OBJECTS: usize = 24;
/// Most vertices of a polygon and positions and triangles of a mesh.
const MAX_POINTS: usize = 16;

/// A number: mostly small ones (the usual scene), some extreme ones (the
/// limits of the f32 checks) and any f64 at all (NaN, infinities,
/// subnormals), which the reader must refuse or accept safely.
#[derive(Arbitrary, Clone, Copy, Debug)]
pub enum Num {
    /// n.
    Int(i8),
    /// n / 16.
    Sixteenth(i16),
    /// m × 10^e, e in -45 ..= 45.
    Sci(i8, i8),
    /// Any f64.
    Bits(f64),
}

impl Num {
    pub fn value(self) -> f64 {
        match self {
            Num::Int(n) => n as f64,
            Num::Sixteenth(n) => n as f64 / 16.0,
            Num::Sci(m, e) => m as f64 * 10f64.powi((e % 46) as i32),
            Num::Bits(x) => x,
        }
    }
}

/// A TOML number (`nan`, `inf` and `-inf` included).
fn num(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        // Debug prints the shortest text that reads back as the same f64,
        // always with a `.` or an exponent (a TOML float).
        format!("{x:?}")
    }
}

fn vec3(v: &[Num; 3]) -> String {
    format!(
        "[{}, {}, {}]",
        num(v[0].value()),
        num(v[1].value()),
        num(v[2].value())
    )
}

/// A colour: a grey or three channels.
#[derive(Arbitrary, Clone, Copy, Debug)]
pub enum Color {
    Grey(Num),
    Rgb([Num; 3]),
}

impl Color {
    fn toml(&self) -> String {
        match self {
            Color::Grey(n) => num(n.value()),
            Color::Rgb(v) => vec3(v),
        }
    }
}

#[derive(Arbitrary, Clone, Debug)]
pub struct CameraSpec {
    pub from: [Num; 3],
    pub at: [Num; 3],
    pub up: Option<[Num; 3]>,
    pub fov: Option<Num>,
}

#[derive(Arbitrary, Clone, Debug)]
pub struct LightSpec {
    pub position: [Num; 3],
    pub color: Option<Color>,
    pub falloff: Option<[Num; 3]>,
}

#[derive(Arbitrary, Clone, Debug)]
pub struct MaterialSpec {
    pub color: Option<Color>,
    pub ka: Option<Color>,
    pub kd: Option<Color>,
    pub ks: Option<Num>,
    pub shine: Option<Num>,
    pub kst: Option<Num>,
    pub shine_t: Option<Num>,
    pub kr: Option<Color>,
    pub kt: Option<Color>,
    pub ior: Option<Num>,
    pub absorption: Option<Color>,
}

/// One object. Polygons are written in a plane by construction (vertices
/// given in 2D), so that most of them pass the planarity check.
#[derive(Arbitrary, Clone, Debug)]
pub enum ShapeSpec {
    Sphere {
        center: [Num; 3],
        radius: Num,
    },
    Plane {
        point: [Num; 3],
        normal: [Num; 3],
    },
    /// Vertices (u, v) in the plane `axis` = `offset` (axis 0, 1 or 2).
    Polygon {
        axis: u8,
        offset: Num,
        vertices: Vec<(Num, Num)>,
    },
    Triangle {
        vertices: [[Num; 3]; 3],
        normals: Option<[[Num; 3]; 3]>,
    },
    Box {
        min: [Num; 3],
        max: [Num; 3],
    },
    Quadric {
        coefficients: [Num; 10],
        clip: Option<([Num; 3], [Num; 3])>,
    },
    Cone {
        base: [Num; 3],
        base_radius: Num,
        apex: [Num; 3],
        apex_radius: Num,
    },
    Cylinder {
        base: [Num; 3],
        apex: [Num; 3],
        radius: Num,
    },
    /// Indices are taken modulo the number of positions.
    Mesh {
        positions: Vec<[Num; 3]>,
        triangles: Vec<[u8; 3]>,
        normals: bool,
        smooth: bool,
    },
}

#[derive(Arbitrary, Clone, Debug)]
pub struct ObjectSpec {
    pub shape: ShapeSpec,
    /// 0: `default`; k: the spec's material k - 1 (modulo their number).
    pub material: u8,
}

/// The render settings (sizes are cut to the targets' limits).
#[derive(Arbitrary, Clone, Debug)]
pub struct RenderSpec {
    pub width: u8,
    pub height: u8,
    pub max_depth: u8,
    pub spp: u8,
    pub corners: bool,
    pub min_weight: u8,
    pub grid: Option<[u8; 3]>,
    /// By its value modulo 5: `auto`'s choice, the BVH, the octree
    /// (neighbour walk, deep and with leaves of one, so that primitives
    /// share leaves), the octree's stack walk, the hybrid (every cell of
    /// two or more primitives a BVH; with `grid` too, which otherwise
    /// means the grid). One byte, as the `bool` it replaced: the committed
    /// corpus reads the same (an odd byte, the BVH then, may now be
    /// another structure).
    pub accel: u8,
}

impl RenderSpec {
    /// The settings: image sides 1 ..= [`MAX_SIDE`], depth 0 ..=
    /// [`MAX_DEPTH`], 1 ..= 4 samples, grid sides 1 ..= 16 when given.
    pub fn settings(&self) -> Settings {
        Settings {
            width: Some(self.width as u32 % MAX_SIDE + 1),
            height: Some(self.height as u32 % MAX_SIDE + 1),
            max_depth: self.max_depth as u32 % (MAX_DEPTH + 1),
            min_weight: self.min_weight as f32 / 1024.0,
            spp: self.spp as u32 % 4 + 1,
            sampling: if self.corners {
                Sampling::Corners
            } else {
                Sampling::Centers
            },
            grid: self.grid.map(|g| g.map(|n| n as u32 % 16 + 1)),
            accel: match (self.grid, self.accel % 5) {
                (Some(_), 4) => Accel::Hybrid,
                (Some(_), _) => Accel::Grid,
                (None, 0) => Accel::Auto,
                (None, 1) => Accel::Bvh,
                (None, 4) => Accel::Hybrid,
                (None, _) => Accel::Octree,
            },
            budget: Budget::bytes(MEMORY_LIMIT),
            offset: None,
            shadows: crate::pack::Shadows::Plain,
            octree: crate::pack::octree::Params {
                max_leaf: 1,
                max_levels: 16,
                walk: if self.accel % 5 == 3 {
                    crate::pack::octree::Walk::Stack
                } else {
                    crate::pack::octree::Walk::Neighbour
                },
            },
            // Every crowded cell of two or more holds a BVH.
            hybrid_cell: 1,
        }
    }
}

/// The `pack` target's input.
#[derive(Arbitrary, Clone, Debug)]
pub struct SceneSpec {
    pub camera: CameraSpec,
    pub background: Option<Color>,
    pub ambient: Option<Color>,
    pub lights: Vec<LightSpec>,
    pub materials: Vec<MaterialSpec>,
    pub objects: Vec<ObjectSpec>,
    pub render: RenderSpec,
}

impl SceneSpec {
    /// The spec as a native TOML scene (at most `MAX_LIGHTS` lights,
    /// `MAX_MATERIALS` materials named `m0`, `m1`, ..., `MAX_OBJECTS`
    /// objects, `MAX_POINTS` points per polygon or mesh).
    pub fn to_toml(&self) -> String {
        let mut t = String::new();
        // Writing to a String cannot fail.
        let mut line = |s: String| {
            t.push_str(&s);
            t.push('\n');
        };
        if let Some(c) = &self.background {
            line(format!("background = {}", c.toml()));
        }
        if let Some(c) = &self.ambient {
            line(format!("ambient = {}", c.toml()));
        }
        let c = &self.camera;
        line("[camera]".into());
        line(format!("from = {}", vec3(&c.from)));
        line(format!("at = {}", vec3(&c.at)));
        if let Some(up) = &c.up {
            line(format!("up = {}", vec3(up)));
        }
        if let Some(f) = c.fov {
            line(format!("fov = {}", num(f.value())));
        }
        let s = self.render.settings();
        line(format!("width = {}", s.width.unwrap_or(1)));
        line(format!("height = {}", s.height.unwrap_or(1)));
        for l in self.lights.iter().take(MAX_LIGHTS) {
            line("[[light]]".into());
            line(format!("position = {}", vec3(&l.position)));
            if let Some(c) = &l.color {
                line(format!("color = {}", c.toml()));
            }
            if let Some(f) = &l.falloff {
                line(format!("falloff = {}", vec3(f)));
            }
        }
        let materials = &self.materials[..self.materials.len().min(MAX_MATERIALS)];
        for (i, m) in materials.iter().enumerate() {
            line(format!("[material.m{i}]"));
            let colors = [
                ("color", &m.color),
                ("ka", &m.ka),
                ("kd", &m.kd),
                ("kr", &m.kr),
                ("kt", &m.kt),
                ("absorption", &m.absorption),
            ];
            for (key, c) in colors {
                if let Some(c) = c {
                    line(format!("{key} = {}", c.toml()));
                }
            }
            let nums = [
                ("ks", m.ks),
                ("shine", m.shine),
                ("kst", m.kst),
                ("shine_t", m.shine_t),
                ("ior", m.ior),
            ];
            for (key, n) in nums {
                if let Some(n) = n {
                    line(format!("{key} = {}", num(n.value())));
                }
            }
        }
        for o in self.objects.iter().take(MAX_OBJECTS) {
            line("[[object]]".into());
            let k = o.material as usize % (materials.len() + 1);
            if k > 0 {
                line(format!("material = \"m{}\"", k - 1));
            }
            write_shape(&o.shape, &mut line);
        }
        t
    }
}

fn write_shape(shape: &ShapeSpec, line: &mut dyn FnMut(String)) {
    let points = |ps: &mut dyn Iterator<Item = String>| {
        let v: Vec<String> = ps.collect();
        format!("[{}]", v.join(", "))
    };
    match shape {
        ShapeSpec::Sphere { center, radius } => {
            line("type = \"sphere\"".into());
            line(format!("center = {}", vec3(center)));
            line(format!("radius = {}", num(radius.value())));
        }
        ShapeSpec::Plane { point, normal } => {
            line("type = \"plane\"".into());
            line(format!("point = {}", vec3(point)));
            line(format!("normal = {}", vec3(normal)));
        }
        ShapeSpec::Polygon {
            axis,
            offset,
            vertices,
        } => {
            line("type = \"polygon\"".into());
            let a = *axis as usize % 3;
            let vs = vertices.iter().take(MAX_POINTS).map(|(u, v)| {
                let mut p = [num(offset.value()), num(u.value()), num(v.value())];
                p.rotate_right(a);
                format!("[{}]", p.join(", "))
            });
            line(format!("vertices = {}", points(&mut vs.into_iter())));
        }
        ShapeSpec::Triangle { vertices, normals } => {
            line("type = \"triangle\"".into());
            line(format!(
                "vertices = {}",
                points(&mut vertices.iter().map(vec3))
            ));
            if let Some(n) = normals {
                line(format!("normals = {}", points(&mut n.iter().map(vec3))));
            }
        }
        ShapeSpec::Box { min, max } => {
            line("type = \"box\"".into());
            line(format!("min = {}", vec3(min)));
            line(format!("max = {}", vec3(max)));
        }
        ShapeSpec::Quadric { coefficients, clip } => {
            line("type = \"quadric\"".into());
            line(format!(
                "coefficients = {}",
                points(&mut coefficients.iter().map(|k| num(k.value())))
            ));
            if let Some((lo, hi)) = clip {
                line(format!(
                    "clip = {{ min = {}, max = {} }}",
                    vec3(lo),
                    vec3(hi)
                ));
            }
        }
        ShapeSpec::Cone {
            base,
            base_radius,
            apex,
            apex_radius,
        } => {
            line("type = \"cone\"".into());
            line(format!("base = {}", vec3(base)));
            line(format!("base_radius = {}", num(base_radius.value())));
            line(format!("apex = {}", vec3(apex)));
            line(format!("apex_radius = {}", num(apex_radius.value())));
        }
        ShapeSpec::Cylinder { base, apex, radius } => {
            line("type = \"cylinder\"".into());
            line(format!("base = {}", vec3(base)));
            line(format!("apex = {}", vec3(apex)));
            line(format!("radius = {}", num(radius.value())));
        }
        ShapeSpec::Mesh {
            positions,
            triangles,
            normals,
            smooth,
        } => {
            line("type = \"mesh\"".into());
            let ps = &positions[..positions.len().min(MAX_POINTS)];
            line(format!("positions = {}", points(&mut ps.iter().map(vec3))));
            let n = ps.len().max(1);
            let mut tris = String::new();
            for (i, t) in triangles.iter().take(MAX_POINTS).enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                let [a, b, c] = t.map(|k| k as usize % n);
                let _ = write!(tris, "{sep}[{a}, {b}, {c}]");
            }
            line(format!("triangles = [{tris}]"));
            if *normals {
                // Each position's normal: the position itself (a sphere's
                // normals when the mesh is round the origin).
                line(format!("normals = {}", points(&mut ps.iter().map(vec3))));
            }
            line(format!("smooth = {smooth}"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn n(x: i8) -> Num {
        Num::Int(x)
    }

    fn v(x: i8, y: i8, z: i8) -> [Num; 3] {
        [n(x), n(y), n(z)]
    }

    fn spec(objects: Vec<ShapeSpec>) -> SceneSpec {
        SceneSpec {
            camera: CameraSpec {
                from: v(0, -8, 3),
                at: v(0, 0, 0),
                up: None,
                fov: None,
            },
            background: None,
            ambient: Some(Color::Grey(Num::Sixteenth(2))),
            lights: vec![LightSpec {
                position: v(5, -5, 10),
                color: None,
                falloff: None,
            }],
            materials: vec![],
            objects: objects
                .into_iter()
                .map(|shape| ObjectSpec { shape, material: 0 })
                .collect(),
            render: RenderSpec {
                width: 7,
                height: 7,
                max_depth: 3,
                spp: 0,
                corners: false,
                min_weight: 4,
                grid: None,
                accel: 0,
            },
        }
    }

    #[test]
    fn numbers_read_back_as_toml() {
        for x in [0.0, -0.0, 1.0, 0.1, 1e300, 5e-324, -2.5e-7, 123456789.0] {
            let t = format!("x = {}", num(x));
            let v: ::toml::Value = ::toml::from_str(&t).unwrap();
            assert_eq!(v["x"].as_float(), Some(x), "{t}");
        }
        let t = format!("a = {}\nb = {}", num(f64::NAN), num(f64::NEG_INFINITY));
        let v: ::toml::Value = ::toml::from_str(&t).unwrap();
        assert!(v["a"].as_float().unwrap().is_nan());
        assert_eq!(v["b"].as_float(), Some(f64::NEG_INFINITY));
    }

    #[test]
    fn every_shape_of_a_spec_reads_back_and_renders() {
        let s = spec(vec![
            ShapeSpec::Sphere {
                center: v(0, 0, 1),
                radius: n(1),
            },
            ShapeSpec::Plane {
                point: v(0, 0, -1),
                normal: v(0, 0, 1),
            },
            ShapeSpec::Polygon {
                axis: 2,
                offset: n(-1),
                vertices: vec![(n(-2), n(-2)), (n(2), n(-2)), (n(0), n(0)), (n(2), n(2))],
            },
            ShapeSpec::Triangle {
                vertices: [v(1, 0, 0), v(2, 0, 0), v(1, 0, 1)],
                normals: Some([v(0, -1, 0), v(0, -1, 0), v(0, -1, 1)]),
            },
            ShapeSpec::Box {
                min: v(-3, 0, 0),
                max: v(-2, 1, 1),
            },
            ShapeSpec::Quadric {
                coefficients: [1, 1, 1, 0, 0, 0, 0, 0, 0, -1].map(n),
                clip: Some((v(-1, -1, -1), v(1, 1, 1))),
            },
            ShapeSpec::Cone {
                base: v(3, 0, 0),
                base_radius: n(1),
                apex: v(3, 0, 2),
                apex_radius: n(0),
            },
            ShapeSpec::Cylinder {
                base: v(-3, 2, 0),
                apex: v(-3, 2, 2),
                radius: Num::Sixteenth(8),
            },
            ShapeSpec::Mesh {
                positions: vec![v(1, 0, 0), v(0, 1, 0), v(0, 0, 1), v(-1, -1, -1)],
                triangles: vec![[0, 1, 2], [0, 1, 3], [1, 2, 7], [0, 2, 3]],
                normals: true,
                smooth: true,
            },
        ]);
        let text = s.to_toml();
        let grid = match pack_spec(&s) {
            Outcome::Rendered(r) => {
                assert_eq!(r.objects, 9, "{text}");
                assert_eq!((r.width, r.height), (8, 8));
                assert!(r.mean > 0.0, "something is lit");
                r
            }
            o => panic!("{o:?}\n{text}"),
        };
        // The same through an explicit grid, the BVH and both octree
        // walks: the same image, so the same mean.
        for (grid_sides, accel) in [(Some([3, 3, 3]), 0), (None, 1), (None, 2), (None, 3)] {
            let mut o = s.clone();
            o.render.grid = grid_sides;
            o.render.accel = accel;
            assert_eq!(pack_spec(&o), Outcome::Rendered(grid.clone()), "{text}");
        }
    }

    #[test]
    fn a_bad_value_is_the_readers_refusal() {
        let mut s = spec(vec![ShapeSpec::Sphere {
            center: v(0, 0, 0),
            radius: Num::Bits(f64::NAN),
        }]);
        s.materials.push(MaterialSpec {
            color: None,
            ka: None,
            kd: None,
            ks: None,
            shine: None,
            kst: None,
            shine_t: None,
            kr: None,
            kt: Some(Color::Grey(n(1))),
            ior: Some(Num::Sixteenth(24)),
            absorption: None,
        });
        let o = pack_spec(&s);
        let m = o.message().expect("refused");
        assert!(m.starts_with("fuzz.toml:"), "{m}");
        assert!(m.contains("radius"), "{m}");
    }

    #[test]
    fn the_targets_take_any_bytes() {
        for data in [
            &b""[..],
            b"\xff\xfe",
            b"[camera",
            b"v\nfrom 0 0 0",
            b"\0\0\0\0",
        ] {
            for f in [toml, nff, pack] {
                let _ = f(data);
            }
        }
        assert!(matches!(toml(b"\xff"), Outcome::Refused(_)));
    }
}
