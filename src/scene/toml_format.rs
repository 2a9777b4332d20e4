//! The native scene format: TOML, read with serde. Every table denies
//! unknown keys, and every value that is checked keeps its span, so each
//! error points at the offending value. The reference is
//! `docs/scene-format.md`.

use super::error::SceneError;
use super::validate::{self as v, CameraFault, Fault, Part, Quantity, Site};
use super::{obj, Camera, Light, Material, Mesh, Object, Scene, Shape};
use glam::DVec3;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Defaults of the native format (documented in `docs/scene-format.md`).
pub(crate) mod defaults {
    use glam::DVec3;
    pub const UP: DVec3 = DVec3::Z;
    pub const FOV: f64 = 45.0;
    pub const WIDTH: i64 = 640;
    pub const HEIGHT: i64 = 480;
    pub const BACKGROUND: DVec3 = DVec3::ZERO;
    pub const AMBIENT: DVec3 = DVec3::ONE;
    pub const LIGHT_COLOR: DVec3 = DVec3::ONE;
    pub const FALLOFF: [f64; 3] = [1.0, 0.0, 0.0];
    pub const COLOR: DVec3 = DVec3::ONE;
    pub const KA: f64 = 0.1;
    pub const KD: f64 = 0.9;
    pub const KS: f64 = 0.0;
    pub const SHINE: f64 = 20.0;
    pub const KST: f64 = 0.0;
    pub const SHINE_T: f64 = 20.0;
    pub const KR: f64 = 0.0;
    pub const KT: f64 = 0.0;
    pub const IOR: f64 = 1.0;
    pub const ABSORPTION: f64 = 0.0;
}

/// The name of the material objects without `material` get; a
/// `[material.default]` table replaces the built-in one.
pub(crate) const DEFAULT_MATERIAL: &str = "default";

type Num = Spanned<f64>;
type Vector = Spanned<NumOrList>;
/// `[[i, j, k], ...]` with a span for every list and index.
type Indices = Spanned<Vec<Spanned<Vec<Spanned<i64>>>>>;

/// A number, or an array of numbers each with its own span.
#[derive(Debug)]
enum NumOrList {
    Num(f64),
    List(Vec<Num>),
}

impl<'de> Deserialize<'de> for NumOrList {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = NumOrList;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of numbers")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<NumOrList, E> {
                Ok(NumOrList::Num(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<NumOrList, E> {
                Ok(NumOrList::Num(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<NumOrList, E> {
                Ok(NumOrList::Num(x as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<NumOrList, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element::<Num>()? {
                    v.push(x);
                }
                Ok(NumOrList::List(v))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneIn {
    camera: CameraIn,
    background: Option<Vector>,
    ambient: Option<Vector>,
    #[serde(default)]
    light: Vec<LightIn>,
    #[serde(default)]
    material: BTreeMap<String, MaterialIn>,
    #[serde(default)]
    object: Vec<ObjectIn>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraIn {
    from: Vector,
    at: Vector,
    up: Option<Vector>,
    fov: Option<Num>,
    width: Option<Spanned<i64>>,
    height: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightIn {
    position: Vector,
    color: Option<Vector>,
    falloff: Option<Vector>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialIn {
    color: Option<Vector>,
    ka: Option<Vector>,
    kd: Option<Vector>,
    ks: Option<Num>,
    shine: Option<Num>,
    kst: Option<Num>,
    shine_t: Option<Num>,
    kr: Option<Vector>,
    kt: Option<Vector>,
    ior: Option<Num>,
    absorption: Option<Vector>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ClipIn {
    min: Vector,
    max: Vector,
}

/// One `[[object]]`: the union of every shape's keys; which apply is
/// checked against `type` afterwards.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectIn {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    material: Option<Spanned<String>>,
    center: Option<Vector>,
    radius: Option<Num>,
    point: Option<Vector>,
    normal: Option<Vector>,
    vertices: Option<Spanned<Vec<Vector>>>,
    normals: Option<Spanned<Vec<Vector>>>,
    min: Option<Vector>,
    max: Option<Vector>,
    coefficients: Option<Spanned<Vec<Num>>>,
    clip: Option<Spanned<ClipIn>>,
    base: Option<Vector>,
    base_radius: Option<Num>,
    apex: Option<Vector>,
    apex_radius: Option<Num>,
    file: Option<Spanned<String>>,
    smooth: Option<Spanned<bool>>,
    positions: Option<Spanned<Vec<Vector>>>,
    triangles: Option<Indices>,
}

impl ObjectIn {
    /// The shape keys present, with the spans of their values.
    fn present_keys(&self) -> Vec<(&'static str, Range<usize>)> {
        let mut keys = Vec::new();
        macro_rules! key {
            ($($f:ident),*) => {$(
                if let Some(v) = &self.$f {
                    keys.push((stringify!($f), v.span()));
                }
            )*};
        }
        key!(
            center,
            radius,
            point,
            normal,
            vertices,
            normals,
            min,
            max,
            coefficients,
            clip,
            base,
            base_radius,
            apex,
            apex_radius,
            file,
            smooth,
            positions,
            triangles
        );
        keys
    }
}

/// The object types and the keys each accepts (besides `type`, `material`).
const SHAPE_KEYS: &[(&str, &[&str])] = &[
    ("sphere", &["center", "radius"]),
    ("plane", &["point", "normal"]),
    ("polygon", &["vertices"]),
    ("triangle", &["vertices", "normals"]),
    ("box", &["min", "max"]),
    ("quadric", &["coefficients", "clip"]),
    ("cone", &["base", "base_radius", "apex", "apex_radius"]),
    ("cylinder", &["base", "apex", "radius"]),
    (
        "mesh",
        &["file", "smooth", "positions", "triangles", "normals"],
    ),
];

struct Ctx<'a> {
    text: &'a str,
    path: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, span: Range<usize>, msg: impl Into<String>) -> SceneError {
        SceneError::at_offset(self.path, self.text, span.start, msg)
    }

    fn check<T>(&self, span: Range<usize>, r: Result<T, String>) -> Result<T, SceneError> {
        r.map_err(|m| self.err(span, m))
    }

    fn num(&self, n: &Num, q: &Quantity) -> Result<f64, SceneError> {
        let x = *n.get_ref();
        if x.is_infinite() {
            // toml reads some literals beyond f64 (`-1_0e400`) as infinities
            let written = self.text.get(n.span()).unwrap_or("");
            if let Some(m) = v::beyond_f64(q.name, written) {
                return Err(self.err(n.span(), m));
            }
        }
        self.check(n.span(), q.check(x))
    }

    fn opt_num(&self, n: &Option<Num>, q: &Quantity, default: f64) -> Result<f64, SceneError> {
        n.as_ref().map_or(Ok(default), |n| self.num(n, q))
    }

    /// Exactly three numbers, each checked as `q` (at its own span), and
    /// the vector as a whole if `q` is a direction.
    fn vec3(&self, v: &Vector, q: &Quantity) -> Result<DVec3, SceneError> {
        let name = q.name;
        match v.get_ref() {
            NumOrList::Num(_) => Err(self.err(
                v.span(),
                format!("{name} must be an array of 3 numbers, got a single number"),
            )),
            NumOrList::List(xs) => {
                if xs.len() != 3 {
                    return Err(self.err(
                        v.span(),
                        format!("{name} must have 3 components, got {}", xs.len()),
                    ));
                }
                let mut out = [0.0; 3];
                for (o, x) in out.iter_mut().zip(xs) {
                    *o = self.num(x, q)?;
                }
                let out = DVec3::from_array(out);
                if q.range == v::Range::Direction {
                    q.check3(out).map_err(|(_, m)| self.err(v.span(), m))?;
                }
                Ok(out)
            }
        }
    }

    fn opt_vec3(
        &self,
        v: &Option<Vector>,
        q: &Quantity,
        default: DVec3,
    ) -> Result<DVec3, SceneError> {
        v.as_ref().map_or(Ok(default), |v| self.vec3(v, q))
    }

    /// Three numbers, or one number meaning all three (a grey).
    fn color(&self, v: &Vector, q: &Quantity) -> Result<DVec3, SceneError> {
        match v.get_ref() {
            NumOrList::Num(x) => Ok(DVec3::splat(self.check(v.span(), q.check(*x))?)),
            NumOrList::List(_) => self.vec3(v, q),
        }
    }

    fn opt_color(
        &self,
        v: &Option<Vector>,
        q: &Quantity,
        default: DVec3,
    ) -> Result<DVec3, SceneError> {
        v.as_ref().map_or(Ok(default), |v| self.color(v, q))
    }

    fn points(&self, v: &Spanned<Vec<Vector>>, q: &Quantity) -> Result<Vec<DVec3>, SceneError> {
        v.get_ref().iter().map(|p| self.vec3(p, q)).collect()
    }

    fn camera(&self, c: &CameraIn) -> Result<Camera, SceneError> {
        let from = self.vec3(&c.from, &v::FROM)?;
        let at = self.vec3(&c.at, &v::AT)?;
        let up = self.opt_vec3(&c.up, &v::UP, defaults::UP)?;
        if let Err((fault, msg)) = v::camera(from, at, up) {
            let span = match (fault, &c.up) {
                (CameraFault::Up, Some(up)) => up.span(),
                (CameraFault::Up, None) => {
                    let msg = format!("{msg} (the default camera.up); set camera.up");
                    return Err(self.err(c.at.span(), msg));
                }
                (CameraFault::At, _) => c.at.span(),
            };
            return Err(self.err(span, msg));
        }
        let fov = self.opt_num(&c.fov, &v::FOV, defaults::FOV)?;
        let size = |n: &Option<Spanned<i64>>, q: &v::IntQuantity, default: i64| match n {
            None => Ok(default as u32),
            Some(n) => {
                let x = *n.get_ref();
                self.check(n.span(), q.check(Some(x), &x.to_string()))
            }
        };
        Ok(Camera {
            from,
            at,
            up,
            fov,
            width: size(&c.width, &v::WIDTH, defaults::WIDTH)?,
            height: size(&c.height, &v::HEIGHT, defaults::HEIGHT)?,
        })
    }

    fn light(&self, l: &LightIn) -> Result<Light, SceneError> {
        let falloff = self.opt_vec3(
            &l.falloff,
            &v::FALLOFF,
            DVec3::from_array(defaults::FALLOFF),
        )?;
        if let Some(f) = &l.falloff {
            self.check(f.span(), v::falloff(falloff))?;
        }
        Ok(Light {
            position: self.vec3(&l.position, &v::LIGHT_POSITION)?,
            color: self.opt_color(&l.color, &v::LIGHT_COLOR, defaults::LIGHT_COLOR)?,
            falloff: falloff.to_array(),
        })
    }

    fn material(&self, name: &str, m: &MaterialIn) -> Result<Material, SceneError> {
        let color = self.opt_color(&m.color, &v::COLOR, defaults::COLOR)?;
        let ka = self.opt_color(&m.ka, &v::KA, DVec3::splat(defaults::KA))?;
        let kd = self.opt_color(&m.kd, &v::KD, DVec3::splat(defaults::KD))?;
        Ok(Material {
            name: name.to_string(),
            ka: ka * color,
            kd: kd * color,
            ksr: self.opt_num(&m.ks, &v::KS, defaults::KS)?,
            nr: self.opt_num(&m.shine, &v::SHINE, defaults::SHINE)?,
            kst: self.opt_num(&m.kst, &v::KST, defaults::KST)?,
            nt: self.opt_num(&m.shine_t, &v::SHINE_T, defaults::SHINE_T)?,
            kr: self.opt_color(&m.kr, &v::KR, DVec3::splat(defaults::KR))?,
            kt: self.opt_color(&m.kt, &v::KT, DVec3::splat(defaults::KT))?,
            ior: self.opt_num(&m.ior, &v::IOR, defaults::IOR)?,
            absorption: self.opt_color(
                &m.absorption,
                &v::ABSORPTION,
                DVec3::splat(defaults::ABSORPTION),
            )?,
        })
    }

    fn shape(&self, o: &ObjectIn, progress: &mut MeshProgress) -> Result<Shape, SceneError> {
        let kind = o.kind.get_ref().as_str();
        let Some(&(_, allowed)) = SHAPE_KEYS.iter().find(|(k, _)| *k == kind) else {
            let names: Vec<_> = SHAPE_KEYS.iter().map(|(k, _)| format!("\"{k}\"")).collect();
            return Err(self.err(
                o.kind.span(),
                format!(
                    "unknown object type \"{kind}\", expected one of {}",
                    names.join(", ")
                ),
            ));
        };
        for (key, span) in o.present_keys() {
            if !allowed.contains(&key) {
                return Err(self.err(
                    span,
                    format!(
                        "`{key}` does not apply to a {kind} (its keys: `type`, `material`, `{}`)",
                        allowed.join("`, `")
                    ),
                ));
            }
        }
        macro_rules! req {
            ($f:ident) => {
                o.$f.as_ref().ok_or_else(|| {
                    self.err(
                        o.kind.span(),
                        format!("a {kind} needs `{}`", stringify!($f)),
                    )
                })?
            };
        }
        Ok(match kind {
            "sphere" => {
                let center = self.vec3(req!(center), &v::CENTER)?;
                let radius = self.num(req!(radius), &v::RADIUS)?;
                Shape::Sphere { center, radius }
            }
            "plane" => {
                let point = self.vec3(req!(point), &v::POINT)?;
                let normal = self.vec3(req!(normal), &v::NORMAL)?;
                Shape::Plane { point, normal }
            }
            "polygon" => {
                let vs = req!(vertices);
                let vertices = self.points(vs, &v::VERTEX)?;
                if let Err(e) = v::polygon(&vertices) {
                    let span = e.index.map_or(vs.span(), |i| vs.get_ref()[i].span());
                    return Err(self.err(span, e.message));
                }
                Shape::Polygon { vertices }
            }
            "triangle" => {
                let vs = req!(vertices);
                let vertices: [DVec3; 3] =
                    self.points(vs, &v::VERTEX)?
                        .try_into()
                        .map_err(|p: Vec<_>| {
                            self.err(
                                vs.span(),
                                format!("a triangle needs 3 vertices, got {}", p.len()),
                            )
                        })?;
                self.check(vs.span(), v::triangle(&vertices))?;
                let normals = match &o.normals {
                    None => None,
                    Some(n) => {
                        let ns: [DVec3; 3] = self
                            .points(n, &v::VERTEX_NORMAL)?
                            .try_into()
                            .map_err(|p: Vec<_>| {
                                self.err(
                                    n.span(),
                                    format!("a triangle needs 3 normals, got {}", p.len()),
                                )
                            })?;
                        Some(Box::new(ns))
                    }
                };
                Shape::Triangle { vertices, normals }
            }
            "box" => {
                let min = self.vec3(req!(min), &v::MIN)?;
                let max = self.vec3(req!(max), &v::MAX)?;
                self.check(req!(min).span(), v::box_bounds(min, max))?;
                Shape::Box { min, max }
            }
            "quadric" => {
                let c = req!(coefficients);
                if c.get_ref().len() != 10 {
                    return Err(self.err(
                        c.span(),
                        format!(
                            "quadric coefficients must be 10 numbers [A,B,C,D,E,F,G,H,I,J], got {}",
                            c.get_ref().len()
                        ),
                    ));
                }
                let mut coefficients = [0.0; 10];
                for (o, x) in coefficients.iter_mut().zip(c.get_ref()) {
                    *o = self.num(x, &v::COEFFICIENT)?;
                }
                self.check(c.span(), v::quadric(&coefficients))?;
                let clip = match &o.clip {
                    None => None,
                    Some(clip) => {
                        let c = clip.get_ref();
                        let min = self.vec3(&c.min, &v::CLIP_MIN)?;
                        let max = self.vec3(&c.max, &v::CLIP_MAX)?;
                        self.check(c.min.span(), v::box_bounds(min, max))?;
                        Some((min, max))
                    }
                };
                Shape::Quadric { coefficients, clip }
            }
            "cone" | "cylinder" => {
                let base = self.vec3(req!(base), &v::BASE)?;
                let apex = self.vec3(req!(apex), &v::APEX)?;
                let (base_radius, apex_radius) = if kind == "cone" {
                    (
                        self.num(req!(base_radius), &v::BASE_RADIUS)?,
                        self.num(req!(apex_radius), &v::APEX_RADIUS)?,
                    )
                } else {
                    let r = self.num(req!(radius), &v::CYLINDER_RADIUS)?;
                    if r == 0.0 {
                        let msg = "cylinder radius must not be 0";
                        return Err(self.err(req!(radius).span(), msg));
                    }
                    (r, r)
                };
                self.check(o.kind.span(), v::cone(base, base_radius, apex, apex_radius))?;
                Shape::Cone {
                    base,
                    base_radius,
                    apex,
                    apex_radius,
                }
            }
            "mesh" => Shape::Mesh(Box::new(self.mesh(o, progress)?)),
            _ => unreachable!("every name in SHAPE_KEYS is handled"),
        })
    }

    /// The `.obj` file a mesh object names, relative to the scene's directory.
    fn obj_path(&self, file: &Spanned<String>) -> PathBuf {
        let dir = self.path.parent().unwrap_or(Path::new(""));
        dir.join(file.get_ref())
    }

    fn mesh(&self, o: &ObjectIn, progress: &mut MeshProgress) -> Result<Mesh, SceneError> {
        let smooth = o.smooth.as_ref().is_some_and(|s| *s.get_ref());
        if let Some(file) = &o.file {
            for (key, span) in o.present_keys() {
                if matches!(key, "positions" | "triangles" | "normals") {
                    return Err(self.err(
                        span,
                        format!("`{key}` cannot be combined with `file` (an .obj mesh)"),
                    ));
                }
            }
            let done = progress.done;
            let report = |n: u64| (progress.report)(done + n, progress.total);
            let (mesh, bytes) = obj::load_mesh(&self.obj_path(file), smooth, &report)
                .map_err(|m| self.err(file.span(), m))?;
            progress.done += bytes;
            return Ok(mesh);
        }
        let kind_span = o.kind.span();
        let p = o.positions.as_ref().ok_or_else(|| {
            self.err(
                kind_span.clone(),
                "a mesh needs `file` or `positions` and `triangles`",
            )
        })?;
        let t = o.triangles.as_ref().ok_or_else(|| {
            self.err(
                kind_span.clone(),
                "a mesh needs `triangles` along with `positions`",
            )
        })?;
        let positions = self.points(p, &v::MESH_POSITION)?;
        if positions.len() > u32::MAX as usize {
            return Err(self.err(p.span(), "too many positions"));
        }
        let mut triangles = Vec::with_capacity(t.get_ref().len());
        for tri in t.get_ref() {
            if tri.get_ref().len() != 3 {
                return Err(self.err(
                    tri.span(),
                    format!(
                        "a triangle must have 3 indices, got {}",
                        tri.get_ref().len()
                    ),
                ));
            }
            let mut idx = [0u32; 3];
            for (o, i) in idx.iter_mut().zip(tri.get_ref()) {
                let n = *i.get_ref();
                if n < 0 || n as usize >= positions.len() {
                    return Err(self.err(
                        i.span(),
                        format!(
                            "vertex index {n} out of range: there are {} positions (indices start at 0)",
                            positions.len()
                        ),
                    ));
                }
                *o = n as u32;
            }
            self.check(tri.span(), v::triangle(&idx.map(|i| positions[i as usize])))?;
            triangles.push(idx);
        }
        if triangles.is_empty() {
            return Err(self.err(t.span(), "a mesh needs at least one triangle"));
        }
        let normals = match &o.normals {
            Some(n) => {
                let ns = self.points(n, &v::MESH_NORMAL)?;
                if ns.len() != positions.len() {
                    return Err(self.err(
                        n.span(),
                        format!(
                            "a mesh needs one normal per position: {} positions, {} normals",
                            positions.len(),
                            ns.len()
                        ),
                    ));
                }
                Some(ns)
            }
            None if smooth => Some(obj::smooth_normals(&positions, &triangles, 0)),
            None => None,
        };
        Ok(Mesh {
            positions,
            normals,
            triangles,
        })
    }

    /// Where a scene-wide fault points: the value it is about.
    fn site_error(&self, input: &SceneIn, scene: &Scene, f: Fault) -> SceneError {
        let cam = &input.camera;
        let span = match f.site {
            Site::CameraAt => cam.at.span(),
            Site::CameraFov => cam
                .fov
                .as_ref()
                .map(|x| x.span())
                .or(cam.height.as_ref().map(|x| x.span()))
                .unwrap_or(cam.at.span()),
            Site::Light(i) => input.light[i].position.span(),
            Site::Object(i, part) => {
                let o = &input.object[i];
                if let (Some(file), Part::Point(k), Shape::Mesh(m)) =
                    (&o.file, part, &scene.objects[i].shape)
                {
                    // A vertex of an .obj file: name its line there too.
                    let obj = self.obj_path(file);
                    let line = obj::vertex_line(&obj, m.positions[k])
                        .map_or(String::new(), |l| format!(":{l}"));
                    let msg = format!("{} (in {}{line})", f.message, obj.display());
                    return self.err(file.span(), msg);
                }
                object_span(o, part)
            }
        };
        self.err(span, f.message)
    }
}

/// The span of an object's value `part` (see [`Part`]), else of its `type`.
fn object_span(o: &ObjectIn, part: Part) -> Range<usize> {
    let span = |v: &Option<Vector>| v.as_ref().map(|v| v.span());
    let element = |v: &Option<Spanned<Vec<Vector>>>, k: usize| {
        v.as_ref()
            .map(|v| v.get_ref().get(k).map_or(v.span(), |x| x.span()))
    };
    let clip = |k: usize| {
        o.clip.as_ref().map(|c| {
            let c = c.get_ref();
            if k == 0 {
                c.min.span()
            } else {
                c.max.span()
            }
        })
    };
    let found = match (o.kind.get_ref().as_str(), part) {
        ("sphere", Part::Point(_)) => span(&o.center),
        ("sphere", Part::Size) => o.radius.as_ref().map(|r| r.span()),
        ("plane", _) => span(&o.point),
        ("polygon" | "triangle", Part::Point(k)) => element(&o.vertices, k),
        ("polygon" | "triangle", _) => o.vertices.as_ref().map(|v| v.span()),
        ("box", Part::Point(1)) => span(&o.max),
        ("box", _) => span(&o.min),
        ("quadric", Part::Point(k)) => clip(k),
        ("quadric", Part::Size) => o.clip.as_ref().map(|c| c.span()),
        ("quadric", Part::Coefficients) => o.coefficients.as_ref().map(|c| c.span()),
        ("cone" | "cylinder", Part::Point(1)) => span(&o.apex),
        ("cone" | "cylinder", Part::Point(_)) => span(&o.base),
        ("cylinder", Part::Size) => o.radius.as_ref().map(|r| r.span()),
        ("cone", Part::Size) => o.base_radius.as_ref().map(|r| r.span()),
        ("mesh", Part::Point(k)) => element(&o.positions, k),
        ("mesh", _) => o
            .positions
            .as_ref()
            .map(|p| p.span())
            .or(o.file.as_ref().map(|f| f.span())),
        _ => None,
    };
    found.unwrap_or(o.kind.span())
}

/// Progress over the scene text and the `.obj` files it names.
struct MeshProgress<'a> {
    report: &'a dyn Fn(u64, u64),
    done: u64,
    total: u64,
}

/// toml's message, made clearer where it is terse: an integer beyond i64
/// or a float beyond f64 is out of range (`value` is the text it points
/// at), and `i64`, `f64` are named as what they mean.
fn toml_message(msg: &str, value: &str) -> String {
    let msg = msg.trim_end();
    if msg.starts_with("number too large to fit in target type")
        || msg.starts_with("number too small to fit in target type")
    {
        return format!(
            "integer out of range: TOML integers are 64-bit, {} ..= {}",
            i64::MIN,
            i64::MAX
        );
    }
    if msg == "invalid floating-point number" {
        let number: String = value
            .chars()
            .take_while(|c| !c.is_whitespace() && !matches!(c, ',' | ']' | '}' | '#'))
            .filter(|&c| c != '_')
            .collect();
        if number.parse::<f64>().is_ok_and(f64::is_infinite) {
            return format!(
                "number out of range: {number} is beyond f64 (magnitudes up to {:e})",
                f64::MAX
            );
        }
    }
    msg.replace("expected i64", "expected an integer")
        .replace("expected f64", "expected a number")
}

/// Parses the native format. `path` is used for messages and to resolve
/// `.obj` files (relative to its directory).
pub(super) fn parse(
    text: &str,
    path: &Path,
    progress: &dyn Fn(u64, u64),
) -> Result<Scene, SceneError> {
    progress(0, text.len() as u64);
    let input: SceneIn = toml::from_str(text).map_err(|e| {
        let value = e.span().map_or("", |r| text.get(r.start..).unwrap_or(""));
        let msg = toml_message(e.message(), value);
        match e.span() {
            Some(span) => SceneError::at_offset(path, text, span.start, msg),
            None => SceneError::in_file(path, msg),
        }
    })?;
    let cx = Ctx { text, path };
    // The .obj files join the total now that their names are known (a
    // missing one counts 0 and fails when it is read).
    let obj_bytes: u64 = input
        .object
        .iter()
        .filter_map(|o| o.file.as_ref())
        .map(|f| std::fs::metadata(cx.obj_path(f)).map_or(0, |m| m.len()))
        .sum();
    let mut meshes = MeshProgress {
        report: progress,
        done: text.len() as u64,
        total: text.len() as u64 + obj_bytes,
    };
    progress(meshes.done, meshes.total);

    let camera = cx.camera(&input.camera)?;
    let background = cx.opt_color(&input.background, &v::BACKGROUND, defaults::BACKGROUND)?;
    let ambient = cx.opt_color(&input.ambient, &v::AMBIENT, defaults::AMBIENT)?;
    let lights = input
        .light
        .iter()
        .map(|l| cx.light(l))
        .collect::<Result<Vec<_>, _>>()?;

    // Index 0 is always the default material (the user's `[material.default]`
    // if there is one); the others follow in name order.
    let mut materials = vec![match input.material.get(DEFAULT_MATERIAL) {
        Some(m) => cx.material(DEFAULT_MATERIAL, m)?,
        None => Material::default(),
    }];
    let mut index = BTreeMap::new();
    index.insert(DEFAULT_MATERIAL, 0u32);
    for (name, m) in &input.material {
        if name != DEFAULT_MATERIAL {
            index.insert(name.as_str(), materials.len() as u32);
            materials.push(cx.material(name, m)?);
        }
    }

    let mut objects = Vec::with_capacity(input.object.len());
    for o in &input.object {
        let shape = cx.shape(o, &mut meshes)?;
        let material = match &o.material {
            None => 0,
            Some(name) => *index.get(name.get_ref().as_str()).ok_or_else(|| {
                let mut known: Vec<_> = index.keys().map(|k| format!("\"{k}\"")).collect();
                known.sort();
                cx.err(
                    name.span(),
                    format!(
                        "unknown material \"{}\" (defined: {})",
                        name.get_ref(),
                        known.join(", ")
                    ),
                )
            })?,
        };
        objects.push(Object { shape, material });
    }
    let scene = Scene {
        camera,
        background,
        ambient,
        lights,
        materials,
        objects,
        source: path.to_path_buf(),
    };
    if let Err(f) = v::scene_limits(&scene) {
        return Err(cx.site_error(&input, &scene, f));
    }
    progress(meshes.total, meshes.total);
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAM: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\n";

    fn parse_ok(text: &str) -> Scene {
        parse(text, Path::new("t.toml"), &|_, _| {}).unwrap_or_else(|e| panic!("{e}"))
    }

    fn parse_err(text: &str) -> (usize, usize, String) {
        let e = parse(text, Path::new("t.toml"), &|_, _| {}).expect_err("should fail");
        (
            e.line().unwrap(),
            e.column().unwrap(),
            e.message().to_string(),
        )
    }

    #[test]
    fn defaults() {
        let s = parse_ok(CAM);
        assert_eq!(s.camera.up, DVec3::Z);
        assert_eq!(s.camera.fov, 45.0);
        assert_eq!((s.camera.width, s.camera.height), (640, 480));
        assert_eq!(s.background, DVec3::ZERO);
        assert_eq!(s.ambient, DVec3::ONE);
        assert_eq!(s.materials, vec![Material::default()]);
        assert!(s.lights.is_empty() && s.objects.is_empty());
    }

    #[test]
    fn scalar_or_list_values() {
        let s = parse_ok(&format!(
            "ambient = 0.5\n{CAM}[[light]]\nposition = [1, 2, 3]\ncolor = 0.25\n\
             [material.m]\ncolor = [1, 0.5, 0]\nka = 0.2\nkd = [1, 1, 0.5]\nkr = 0.3\n"
        ));
        assert_eq!(s.ambient, DVec3::splat(0.5));
        assert_eq!(s.lights[0].color, DVec3::splat(0.25));
        assert_eq!(s.lights[0].falloff, [1.0, 0.0, 0.0]);
        let m = &s.materials[1];
        assert_eq!(m.name, "m");
        assert_eq!(m.ka, DVec3::new(0.2, 0.1, 0.0));
        assert_eq!(m.kd, DVec3::new(1.0, 0.5, 0.0));
        assert_eq!(m.kr, DVec3::splat(0.3));
        assert_eq!(
            (m.ksr, m.nr, m.kst, m.nt, m.ior),
            (0.0, 20.0, 0.0, 20.0, 1.0)
        );
    }

    #[test]
    fn user_default_material_replaces_builtin() {
        let s = parse_ok(&format!(
            "{CAM}[material.default]\nkd = 0.5\n[material.b]\n[material.a]\n\
             [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n\
             [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"b\"\n"
        ));
        let names: Vec<_> = s.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["default", "a", "b"]);
        assert_eq!(s.materials[0].kd, DVec3::splat(0.5));
        assert_eq!(s.objects[0].material, 0);
        assert_eq!(s.objects[1].material, 2);
    }

    #[test]
    fn key_of_another_shape_is_an_error() {
        let (l, c, m) = parse_err(&format!(
            "{CAM}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nnormal = [0, 0, 1]\n"
        ));
        assert_eq!((l, c), (8, 10));
        assert!(m.contains("`normal` does not apply to a sphere"), "{m}");
    }

    #[test]
    fn missing_shape_key_points_at_type() {
        let (l, c, m) = parse_err(&format!("{CAM}[[object]]\ntype = \"sphere\"\nradius = 1\n"));
        assert_eq!((l, c, m.as_str()), (5, 8, "a sphere needs `center`"));
    }

    #[test]
    fn wrong_arity_and_element_errors() {
        let (l, c, m) = parse_err("[camera]\nfrom = [0, 1]\nat = [0, 0, 0]\n");
        assert_eq!((l, c), (2, 8));
        assert!(
            m.contains("camera.from must have 3 components, got 2"),
            "{m}"
        );
        let (l, c, m) = parse_err("[camera]\nfrom = [0, 1, -inf]\nat = [0, 0, 0]\n");
        assert_eq!((l, c), (2, 15));
        assert_eq!(m, "camera.from must be a finite number, got -inf");
    }

    #[test]
    fn camera_checks_point_at_values() {
        let (l, c, m) = parse_err("[camera]\nfrom = [0, 0, 5]\nat = [0, 0, 0]\n");
        assert_eq!((l, c), (3, 6));
        assert!(m.contains("parallel") && m.contains("set camera.up"), "{m}");
        let (l, c, m) = parse_err(&format!("{CAM}fov = 180\n"));
        assert_eq!((l, c), (4, 7));
        assert!(m.contains("fov must be in (0, 180)"), "{m}");
        let (l, c, m) = parse_err(&format!("{CAM}height = 70000\n"));
        assert_eq!((l, c), (4, 10));
        assert!(
            m.contains("camera.height must be in 1..=65536, got 70000"),
            "{m}"
        );
        let (l, c, _) = parse_err("[camera]\nfrom = [1, 1, 1]\nat = [1, 1, 1]\n");
        assert_eq!((l, c), (3, 6));
    }

    #[test]
    fn inline_mesh() {
        let s = parse_ok(&format!(
            "{CAM}[[object]]\ntype = \"mesh\"\nsmooth = true\n\
             positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\n\
             triangles = [[0, 1, 2], [0, 1, 3]]\n"
        ));
        let Shape::Mesh(m) = &s.objects[0].shape else {
            panic!("not a mesh")
        };
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 3]]);
        assert_eq!(m.normals.as_ref().unwrap().len(), 4);
        let (l, c, m) = parse_err(&format!(
            "{CAM}[[object]]\ntype = \"mesh\"\npositions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n\
             triangles = [[0, 1, 3]]\n"
        ));
        assert_eq!((l, c), (7, 21));
        assert!(m.contains("vertex index 3 out of range"), "{m}");
    }
}
