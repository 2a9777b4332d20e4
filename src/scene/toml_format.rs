//! The native scene format: TOML, read with serde. Every table denies
//! unknown keys, and every value that is checked keeps its span, so each
//! error points at the offending value. The reference is
//! `docs/scene-format.md`.

use super::error::SceneError;
use super::validate::{self, CameraFault};
use super::{obj, Camera, Light, Material, Mesh, Object, Scene, Shape};
use glam::DVec3;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;
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

    fn num(&self, n: &Num, what: &str) -> Result<f64, SceneError> {
        self.check(n.span(), validate::finite(*n.get_ref(), what))
    }

    fn opt_num(&self, n: &Option<Num>, what: &str, default: f64) -> Result<f64, SceneError> {
        n.as_ref().map_or(Ok(default), |n| self.num(n, what))
    }

    /// Exactly three numbers.
    fn vec3(&self, v: &Vector, what: &str) -> Result<DVec3, SceneError> {
        match v.get_ref() {
            NumOrList::Num(_) => Err(self.err(
                v.span(),
                format!("{what} must be an array of 3 numbers, got a single number"),
            )),
            NumOrList::List(xs) => {
                if xs.len() != 3 {
                    return Err(self.err(
                        v.span(),
                        format!("{what} must have 3 components, got {}", xs.len()),
                    ));
                }
                let mut out = [0.0; 3];
                for (o, x) in out.iter_mut().zip(xs) {
                    *o = self.num(x, what)?;
                }
                Ok(DVec3::from_array(out))
            }
        }
    }

    fn opt_vec3(
        &self,
        v: &Option<Vector>,
        what: &str,
        default: DVec3,
    ) -> Result<DVec3, SceneError> {
        v.as_ref().map_or(Ok(default), |v| self.vec3(v, what))
    }

    /// Three numbers, or one number meaning all three (a grey).
    fn color(&self, v: &Vector, what: &str) -> Result<DVec3, SceneError> {
        match v.get_ref() {
            NumOrList::Num(x) => Ok(DVec3::splat(
                self.check(v.span(), validate::finite(*x, what))?,
            )),
            NumOrList::List(_) => self.vec3(v, what),
        }
    }

    fn opt_color(
        &self,
        v: &Option<Vector>,
        what: &str,
        default: DVec3,
    ) -> Result<DVec3, SceneError> {
        v.as_ref().map_or(Ok(default), |v| self.color(v, what))
    }

    fn non_negative_color(
        &self,
        v: &Option<Vector>,
        what: &str,
        default: DVec3,
    ) -> Result<DVec3, SceneError> {
        let c = self.opt_color(v, what, default)?;
        if let Some(v) = v {
            self.check(v.span(), validate::non_negative3(c, what))?;
        }
        Ok(c)
    }

    fn non_negative_num(
        &self,
        n: &Option<Num>,
        what: &str,
        default: f64,
    ) -> Result<f64, SceneError> {
        let x = self.opt_num(n, what, default)?;
        if let Some(n) = n {
            self.check(n.span(), validate::non_negative(x, what))?;
        }
        Ok(x)
    }

    fn points(&self, v: &Spanned<Vec<Vector>>, what: &str) -> Result<Vec<DVec3>, SceneError> {
        v.get_ref().iter().map(|p| self.vec3(p, what)).collect()
    }

    fn camera(&self, c: &CameraIn) -> Result<Camera, SceneError> {
        let from = self.vec3(&c.from, "camera.from")?;
        let at = self.vec3(&c.at, "camera.at")?;
        let up = self.opt_vec3(&c.up, "camera.up", defaults::UP)?;
        if let Err((fault, msg)) = validate::camera(from, at, up) {
            let span = match (fault, &c.up) {
                (CameraFault::Up, Some(up)) => up.span(),
                (CameraFault::Up, None) => {
                    let msg = format!("{msg} (the default `up`); set camera.up");
                    return Err(self.err(c.at.span(), msg));
                }
                (CameraFault::At, _) => c.at.span(),
            };
            return Err(self.err(span, msg));
        }
        let fov = self.opt_num(&c.fov, "camera.fov", defaults::FOV)?;
        if let Some(f) = &c.fov {
            self.check(f.span(), validate::fov(fov))?;
        }
        let size = |v: &Option<Spanned<i64>>, what: &str, default: i64| match v {
            None => Ok(default as u32),
            Some(n) => self.check(n.span(), validate::image_size(*n.get_ref(), what)),
        };
        Ok(Camera {
            from,
            at,
            up,
            fov,
            width: size(&c.width, "camera.width", defaults::WIDTH)?,
            height: size(&c.height, "camera.height", defaults::HEIGHT)?,
        })
    }

    fn light(&self, l: &LightIn) -> Result<Light, SceneError> {
        let falloff = self.opt_vec3(&l.falloff, "falloff", DVec3::from_array(defaults::FALLOFF))?;
        if let Some(f) = &l.falloff {
            self.check(f.span(), validate::non_negative3(falloff, "falloff"))?;
        }
        Ok(Light {
            position: self.vec3(&l.position, "light position")?,
            color: self.non_negative_color(&l.color, "light color", defaults::LIGHT_COLOR)?,
            falloff: falloff.to_array(),
        })
    }

    fn material(&self, name: &str, m: &MaterialIn) -> Result<Material, SceneError> {
        let color = self.non_negative_color(&m.color, "color", defaults::COLOR)?;
        let ka = self.non_negative_color(&m.ka, "ka", DVec3::splat(defaults::KA))?;
        let kd = self.non_negative_color(&m.kd, "kd", DVec3::splat(defaults::KD))?;
        let ior = self.opt_num(&m.ior, "ior", defaults::IOR)?;
        if let Some(i) = &m.ior {
            self.check(i.span(), validate::ior(ior))?;
        }
        Ok(Material {
            name: name.to_string(),
            ka: ka * color,
            kd: kd * color,
            ksr: self.non_negative_num(&m.ks, "ks", defaults::KS)?,
            nr: self.non_negative_num(&m.shine, "shine", defaults::SHINE)?,
            kst: self.non_negative_num(&m.kst, "kst", defaults::KST)?,
            nt: self.non_negative_num(&m.shine_t, "shine_t", defaults::SHINE_T)?,
            kr: self.non_negative_color(&m.kr, "kr", DVec3::splat(defaults::KR))?,
            kt: self.non_negative_color(&m.kt, "kt", DVec3::splat(defaults::KT))?,
            ior,
            absorption: self.non_negative_color(
                &m.absorption,
                "absorption",
                DVec3::splat(defaults::ABSORPTION),
            )?,
        })
    }

    fn shape(&self, o: &ObjectIn) -> Result<Shape, SceneError> {
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
                let center = self.vec3(req!(center), "center")?;
                let r = req!(radius);
                let radius = self.num(r, "radius")?;
                self.check(r.span(), validate::sphere_radius(radius))?;
                Shape::Sphere { center, radius }
            }
            "plane" => {
                let point = self.vec3(req!(point), "point")?;
                let n = req!(normal);
                let normal = self.vec3(n, "normal")?;
                self.check(n.span(), validate::nonzero_vector(normal, "plane normal"))?;
                Shape::Plane { point, normal }
            }
            "polygon" => {
                let v = req!(vertices);
                let vertices = self.points(v, "vertex")?;
                if let Err(e) = validate::polygon(&vertices) {
                    let span = e.index.map_or(v.span(), |i| v.get_ref()[i].span());
                    return Err(self.err(span, e.message));
                }
                Shape::Polygon { vertices }
            }
            "triangle" => {
                let v = req!(vertices);
                let vertices: [DVec3; 3] =
                    self.points(v, "vertex")?.try_into().map_err(|p: Vec<_>| {
                        self.err(
                            v.span(),
                            format!("a triangle needs 3 vertices, got {}", p.len()),
                        )
                    })?;
                self.check(v.span(), validate::triangle(&vertices))?;
                let normals = match &o.normals {
                    None => None,
                    Some(n) => {
                        let ns: [DVec3; 3] =
                            self.points(n, "normal")?.try_into().map_err(|p: Vec<_>| {
                                self.err(
                                    n.span(),
                                    format!("a triangle needs 3 normals, got {}", p.len()),
                                )
                            })?;
                        for (i, x) in ns.iter().enumerate() {
                            self.check(
                                n.get_ref()[i].span(),
                                validate::nonzero_vector(*x, "a vertex normal"),
                            )?;
                        }
                        Some(Box::new(ns))
                    }
                };
                Shape::Triangle { vertices, normals }
            }
            "box" => {
                let min = self.vec3(req!(min), "min")?;
                let max = self.vec3(req!(max), "max")?;
                self.check(req!(min).span(), validate::box_bounds(min, max))?;
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
                    *o = self.num(x, "quadric coefficient")?;
                }
                self.check(c.span(), validate::quadric(&coefficients))?;
                let clip = match &o.clip {
                    None => None,
                    Some(clip) => {
                        let c = clip.get_ref();
                        let min = self.vec3(&c.min, "clip.min")?;
                        let max = self.vec3(&c.max, "clip.max")?;
                        self.check(c.min.span(), validate::box_bounds(min, max))?;
                        Some((min, max))
                    }
                };
                Shape::Quadric { coefficients, clip }
            }
            "cone" | "cylinder" => {
                let base = self.vec3(req!(base), "base")?;
                let apex = self.vec3(req!(apex), "apex")?;
                let (base_radius, apex_radius) = if kind == "cone" {
                    (
                        self.num(req!(base_radius), "base_radius")?,
                        self.num(req!(apex_radius), "apex_radius")?,
                    )
                } else {
                    let r = self.num(req!(radius), "radius")?;
                    (r, r)
                };
                self.check(
                    o.kind.span(),
                    validate::cone(base, base_radius, apex, apex_radius),
                )?;
                Shape::Cone {
                    base,
                    base_radius,
                    apex,
                    apex_radius,
                }
            }
            "mesh" => Shape::Mesh(Box::new(self.mesh(o)?)),
            _ => unreachable!("every name in SHAPE_KEYS is handled"),
        })
    }

    fn mesh(&self, o: &ObjectIn) -> Result<Mesh, SceneError> {
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
            let dir = self.path.parent().unwrap_or(Path::new(""));
            let obj_path = dir.join(file.get_ref());
            return obj::load_mesh(&obj_path, smooth).map_err(|m| self.err(file.span(), m));
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
        let positions = self.points(p, "mesh position")?;
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
            self.check(
                tri.span(),
                validate::triangle(&idx.map(|i| positions[i as usize])),
            )?;
            triangles.push(idx);
        }
        if triangles.is_empty() {
            return Err(self.err(t.span(), "a mesh needs at least one triangle"));
        }
        let normals = match &o.normals {
            Some(n) => {
                let ns = self.points(n, "mesh normal")?;
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
                for (i, x) in ns.iter().enumerate() {
                    self.check(
                        n.get_ref()[i].span(),
                        validate::nonzero_vector(*x, "a vertex normal"),
                    )?;
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
}

/// Parses the native format. `path` is used for messages and to resolve
/// `.obj` files (relative to its directory).
pub(super) fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let input: SceneIn = toml::from_str(text).map_err(|e| {
        let msg = e.message().trim_end().to_string();
        match e.span() {
            Some(span) => SceneError::at_offset(path, text, span.start, msg),
            None => SceneError::in_file(path, msg),
        }
    })?;
    let cx = Ctx { text, path };
    let camera = cx.camera(&input.camera)?;
    let background = cx.opt_color(&input.background, "background", defaults::BACKGROUND)?;
    let ambient = cx.opt_color(&input.ambient, "ambient", defaults::AMBIENT)?;
    if let Some(a) = &input.ambient {
        cx.check(a.span(), validate::non_negative3(ambient, "ambient"))?;
    }
    if let Some(b) = &input.background {
        cx.check(b.span(), validate::non_negative3(background, "background"))?;
    }
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
        let shape = cx.shape(o)?;
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
    Ok(Scene {
        camera,
        background,
        ambient,
        lights,
        materials,
        objects,
        source: path.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAM: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\n";

    fn parse_ok(text: &str) -> Scene {
        parse(text, Path::new("t.toml")).unwrap_or_else(|e| panic!("{e}"))
    }

    fn parse_err(text: &str) -> (usize, usize, String) {
        let e = parse(text, Path::new("t.toml")).expect_err("should fail");
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
