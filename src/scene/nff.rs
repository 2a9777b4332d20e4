//! Eric Haines' Neutral File Format (the SPD scenes), read token by token:
//! tokens are separated by any whitespace, newlines mean nothing (a `c`
//! entity on one line or on three reads the same), `#` starts a comment
//! that runs to the end of the line. Conventions are in
//! `docs/scene-format.md`. Every value is checked through the table in
//! `validate.rs`, the same rows as the TOML reader's.

use super::error::SceneError;
use super::validate::{self as v, CameraFault, Part, Quantity, Site};
use super::{Camera, Light, Material, Object, Scene, Shape};
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

/// Image size when there is no `resolution`.
pub(crate) const DEFAULT_RESOLUTION: u32 = 512;

/// Bytes of text between two progress reports.
const PROGRESS_STEP: usize = 1 << 20;

const VIEW_KEYWORDS: &[&str] = &["from", "at", "up", "angle", "hither", "resolution"];

#[derive(Clone, Copy, Debug)]
struct Tok<'a> {
    s: &'a str,
    off: usize,
}

/// The token that starts at or after byte `*off` of `text`; moves `*off`
/// past it. Tokens are read one at a time: an array of them would hold 14
/// M tokens (336 MB) for an NFF of 1 M spheres. Inlined: a token returned
/// through memory and read back whole stalls the store buffer, on every
/// token.
#[inline(always)]
fn scan<'a>(text: &'a str, off: &mut usize) -> Option<Tok<'a>> {
    let bytes = text.as_bytes();
    let mut i = *off;
    // ASCII bytes directly; any other character decoded (Unicode
    // whitespace separates tokens too, as `char::is_whitespace` says).
    let ascii_space = |b: u8| matches!(b, b' ' | b'\t' | b'\n' | 0x0B | 0x0C | b'\r');
    let other_space = |i: usize| {
        let c = text[i..].chars().next().unwrap_or(' ');
        (c.is_whitespace(), c.len_utf8())
    };
    // Separators and comments (`#` to the end of its line) first ...
    loop {
        let Some(&b) = bytes.get(i) else {
            *off = text.len();
            return None;
        };
        if b == b'#' {
            match bytes[i..].iter().position(|&c| c == b'\n') {
                Some(n) => i += n + 1,
                None => {
                    *off = text.len();
                    return None;
                }
            }
        } else if b < 0x80 {
            if !ascii_space(b) {
                break;
            }
            i += 1;
        } else {
            let (space, len) = other_space(i);
            if !space {
                break;
            }
            i += len;
        }
    }
    // ... then the token, up to a separator or a `#` (read again next
    // time: it starts a comment).
    let start = i;
    while let Some(&b) = bytes.get(i) {
        if b < 0x80 {
            if ascii_space(b) || b == b'#' {
                break;
            }
            i += 1;
        } else {
            let (space, len) = other_space(i);
            if space {
                break;
            }
            i += len;
        }
    }
    *off = i;
    Some(Tok {
        s: &text[start..i],
        off: start,
    })
}

/// The token `n` tokens after `tok` (`tok` itself for 0), or `tok` if the
/// text ends first.
fn nth_after<'a>(text: &'a str, tok: Tok<'a>, n: usize) -> Tok<'a> {
    let mut off = tok.off;
    let mut t = tok;
    for _ in 0..=n {
        match scan(text, &mut off) {
            Some(x) => t = x,
            None => return tok,
        }
    }
    t
}

fn parse_number(s: &str) -> Option<f64> {
    s.parse::<f64>().ok()
}

/// Sphere light colour and ambient light for `n` lights: `sqrt(n)/(2n)`
/// (0 when there are no lights).
pub(crate) fn light_intensity(n: usize) -> f64 {
    if n == 0 {
        0.0
    } else {
        (n as f64).sqrt() / (2.0 * n as f64)
    }
}

struct Parser<'a> {
    text: &'a str,
    path: &'a Path,
    /// The token `peek` returns, where the scan goes on, and the last
    /// token taken (an error at the end of the file points there).
    ahead: Option<Tok<'a>>,
    off: usize,
    last: Option<Tok<'a>>,
}

#[derive(Default)]
struct View<'a> {
    from: Option<(DVec3, Tok<'a>)>,
    at: Option<(DVec3, Tok<'a>)>,
    up: Option<(DVec3, Tok<'a>)>,
    angle: Option<(f64, Tok<'a>)>,
    resolution: Option<(u32, u32)>,
}

impl<'a> Parser<'a> {
    fn err(&self, tok: Tok, msg: impl Into<String>) -> SceneError {
        SceneError::at_offset(self.path, self.text, tok.off, msg)
    }

    fn check<T>(&self, tok: Tok, r: Result<T, String>) -> Result<T, SceneError> {
        r.map_err(|m| self.err(tok, m))
    }

    fn new(text: &'a str, path: &'a Path) -> Self {
        Self::new_at(text, path, 0)
    }

    /// A parser whose first token is the one at or after byte `off`.
    fn new_at(text: &'a str, path: &'a Path, mut off: usize) -> Self {
        let ahead = scan(text, &mut off);
        Parser {
            text,
            path,
            ahead,
            off,
            last: None,
        }
    }

    fn peek(&self) -> Option<Tok<'a>> {
        self.ahead
    }

    /// Takes the token `peek` returned.
    fn advance(&mut self) {
        self.last = self.ahead;
        self.ahead = scan(self.text, &mut self.off);
    }

    /// The next token; at the end of the file, an error at the last token.
    /// `expected` describes it, formatted only for an error.
    #[inline(always)]
    fn next(&mut self, entity: &str, expected: &dyn Fn() -> String) -> Result<Tok<'a>, SceneError> {
        match self.peek() {
            Some(t) => {
                self.advance();
                Ok(t)
            }
            None => {
                let msg = format!(
                    "truncated `{entity}` entity at end of file: expected {}",
                    expected()
                );
                Err(match self.last {
                    Some(t) => self.err(t, msg),
                    None => SceneError::at_offset(self.path, self.text, self.text.len(), msg),
                })
            }
        }
    }

    /// The token the last successful [`Parser::next`] took.
    fn taken(&self) -> Tok<'a> {
        self.last.unwrap_or(Tok {
            s: "",
            off: self.text.len(),
        })
    }

    /// The next token as a number, unchecked (NaN and infinities too);
    /// [`Parser::taken`] is its token. `expected` describes it, formatted
    /// only for an error (a 1 M-sphere file reads 11 M numbers). The hot
    /// calls return just the number: a `Result<f64, SceneError>` travels in
    /// registers, a token with it did not (a store-forwarding stall cost
    /// the NFF reader 5%).
    #[inline(always)]
    fn raw_num(&mut self, entity: &str, expected: &dyn Fn() -> String) -> Result<f64, SceneError> {
        let t = self.next(entity, expected)?;
        match parse_number(t.s) {
            Some(x) => Ok(x),
            None => Err(self.err(
                t,
                format!(
                    "expected {} (a number) in `{entity}` entity, found `{}`",
                    expected(),
                    t.s
                ),
            )),
        }
    }

    /// The next number, checked as quantity `q`.
    fn num_of(
        &mut self,
        entity: &str,
        expected: &dyn Fn() -> String,
        q: &Quantity,
    ) -> Result<f64, SceneError> {
        let x = self.raw_num(entity, expected)?;
        if q.accepts(x) {
            Ok(x)
        } else {
            Err(self.rejected(self.taken(), x, q))
        }
    }

    /// `x`, read from `t`, checked as `q`.
    #[inline]
    fn checked(&self, t: Tok, x: f64, q: &Quantity) -> Result<f64, SceneError> {
        if q.accepts(x) {
            Ok(x)
        } else {
            Err(self.rejected(t, x, q))
        }
    }

    /// The error for `x`, read from `t`, out of `q`'s range; a literal
    /// beyond f64 (`1e400`, read as an infinity) is out of range.
    #[cold]
    #[inline(never)]
    fn rejected(&self, t: Tok, x: f64, q: &Quantity) -> SceneError {
        let beyond = x
            .is_infinite()
            .then(|| v::beyond_f64(q.name, t.s))
            .flatten();
        self.err(t, beyond.unwrap_or_else(|| q.rejection(x)))
    }

    fn num(&mut self, entity: &str, expected: &str, q: &Quantity) -> Result<f64, SceneError> {
        self.num_of(entity, &|| expected.to_string(), q)
    }

    /// Three numbers, each checked as `q`, and the vector as a whole if `q`
    /// is a direction. `what` names the vector in syntax errors; the
    /// components are `x y z` or, with `rgb`, `red green blue`.
    fn vec3_of(
        &mut self,
        entity: &str,
        what: &dyn Fn() -> String,
        q: &Quantity,
        rgb: bool,
    ) -> Result<(DVec3, Tok<'a>), SceneError> {
        let names = if rgb {
            ["red", "green", "blue"]
        } else {
            ["x", "y", "z"]
        };
        let x = self.num_of(entity, &|| format!("{} {}", what(), names[0]), q)?;
        let t = self.taken();
        let y = self.num_of(entity, &|| format!("{} {}", what(), names[1]), q)?;
        let z = self.num_of(entity, &|| format!("{} {}", what(), names[2]), q)?;
        let v = DVec3::new(x, y, z);
        if q.range == v::Range::Direction {
            q.check3(v).map_err(|(_, m)| self.err(t, m))?;
        }
        Ok((v, t))
    }

    fn vec3(
        &mut self,
        entity: &str,
        what: &str,
        q: &Quantity,
    ) -> Result<(DVec3, Tok<'a>), SceneError> {
        self.vec3_of(entity, &|| what.to_string(), q, false)
    }

    fn color(
        &mut self,
        entity: &str,
        what: &str,
        q: &Quantity,
    ) -> Result<(DVec3, Tok<'a>), SceneError> {
        self.vec3_of(entity, &|| what.to_string(), q, true)
    }

    /// An integer: `None` when it is an integer beyond i64 (the caller's
    /// range check quotes the token). Integral floats (`2.0`, `1e3`) count.
    fn integer(
        &mut self,
        entity: &str,
        expected: &str,
    ) -> Result<(Option<i64>, Tok<'a>), SceneError> {
        let x = self.raw_num(entity, &|| expected.to_string())?;
        let t = self.taken();
        if let Ok(n) = t.s.parse::<i64>() {
            return Ok((Some(n), t));
        }
        if !x.is_finite() || x.fract() != 0.0 {
            return Err(self.err(t, format!("{expected} must be an integer, got `{}`", t.s)));
        }
        // |x| < 2^63 converts exactly; beyond, it is out of i64's range.
        Ok(((x.abs() < 9.2e18).then_some(x as i64), t))
    }

    /// The vertex count of `p` or `pp`: 3 ..= `MAX_POLYGON_VERTICES`. (A
    /// count the rest of the file cannot fill ends in a truncated entity:
    /// the vertices are read one by one, into a vector that grows with
    /// what is there.)
    fn count(&mut self, entity: &str) -> Result<(usize, Tok<'a>), SceneError> {
        let (n, t) = self.integer(entity, "the vertex count")?;
        match n {
            Some(n) if n < 3 => {
                Err(self.err(t, format!("`{entity}` needs at least 3 vertices, got {n}")))
            }
            Some(n) if n as u64 <= v::MAX_POLYGON_VERTICES as u64 => Ok((n as usize, t)),
            _ => Err(self.err(
                t,
                format!(
                    "`{entity}` vertex count {} is out of range: a polygon has 3 ..= {} vertices",
                    t.s,
                    v::MAX_POLYGON_VERTICES
                ),
            )),
        }
    }

    fn view(&mut self, v_tok: Tok<'a>) -> Result<View<'a>, SceneError> {
        let mut view = View::default();
        while let Some(t) = self.peek() {
            if !VIEW_KEYWORDS.contains(&t.s) {
                break;
            }
            self.advance();
            match t.s {
                "from" => view.from = Some(self.vec3("from", "eye point", &v::FROM)?),
                "at" => view.at = Some(self.vec3("at", "look-at point", &v::AT)?),
                "up" => view.up = Some(self.vec3("up", "up vector", &v::UP)?),
                "angle" => {
                    let fov = self.num("angle", "the field of view in degrees", &v::FOV)?;
                    view.angle = Some((fov, self.taken()));
                }
                "hither" => {
                    self.num("hither", "the hither distance", &v::HITHER)?;
                }
                "resolution" => {
                    let (w, tw) = self.integer("resolution", "the width")?;
                    let (h, th) = self.integer("resolution", "the height")?;
                    let w = self.check(tw, v::WIDTH.check(w, tw.s))?;
                    let h = self.check(th, v::HEIGHT.check(h, th.s))?;
                    view.resolution = Some((w, h));
                }
                _ => unreachable!(),
            }
        }
        for (name, missing) in [
            ("from", view.from.is_none()),
            ("at", view.at.is_none()),
            ("up", view.up.is_none()),
            ("angle", view.angle.is_none()),
        ] {
            if missing {
                return Err(self.err(v_tok, format!("the `v` block has no `{name}`")));
            }
        }
        Ok(view)
    }
}

/// What a pass over the text gives: the scene, or (when asked to locate a
/// light or an object) the keyword of the entity that made it.
enum Outcome<'a> {
    /// The scene, the `at` and `angle` tokens (for camera faults), and
    /// how many objects (those before the `v` block) are still to be
    /// checked against the f32 limits.
    Scene {
        scene: Box<Scene>,
        at: Tok<'a>,
        fov: Tok<'a>,
        unchecked: usize,
    },
    Located(Tok<'a>),
}

/// Parses an NFF scene, calling `progress(bytes done, bytes in all)` every
/// [`PROGRESS_STEP`] bytes.
pub(super) fn parse(
    text: &str,
    path: &Path,
    progress: &dyn Fn(u64, u64),
) -> Result<Scene, SceneError> {
    let Outcome::Scene {
        scene,
        at,
        fov,
        unchecked,
    } = pass(text, path, progress, None)?
    else {
        unreachable!("nothing to locate")
    };
    if let Err(f) = v::scene_limits_but_objects(&scene, unchecked) {
        // Errors are rare: find the offending entity by reading the text
        // again, rather than keeping a position for every object.
        let tok = match f.site {
            Site::CameraAt => at,
            Site::CameraFov => fov,
            site => match pass(text, path, &|_, _| {}, Some(site))? {
                Outcome::Located(t) => value_token(text, t, site),
                Outcome::Scene { .. } => unreachable!("the site is in the scene"),
            },
        };
        return Err(SceneError::at_offset(path, text, tok.off, f.message));
    }
    Ok(*scene)
}

/// The token of the value `site` names, given its entity's keyword.
fn value_token<'a>(text: &'a str, entity: Tok<'a>, site: Site) -> Tok<'a> {
    let n = match (entity.s, site) {
        ("l", _) => 1,
        ("s", Site::Object(_, Part::Point(_))) => 1,
        ("s", Site::Object(_, Part::Size)) => 4,
        ("c", Site::Object(_, Part::Size)) => 4,
        ("c", Site::Object(_, Part::Point(0))) => 1,
        ("c", Site::Object(_, Part::Point(_))) => 5,
        ("p", Site::Object(_, Part::Point(k))) => 2 + 3 * k,
        _ => 0,
    };
    nth_after(text, entity, n)
}

/// What the entities other than `v` make, in the order they come: the
/// whole scene's in one pass, or one stretch's when the text is read in
/// stretches side by side (`parse_stretch`).
struct Entities {
    background: Option<DVec3>,
    lights: Vec<(DVec3, Option<DVec3>)>,
    /// The materials made so far, and each one's key (its eight numbers'
    /// bits; the default material's is never looked up).
    materials: Vec<Material>,
    keys: Vec<[u64; 8]>,
    index: HashMap<[u64; 8], u32>,
    /// The material of the objects that follow: an index into
    /// `materials`, or `INHERITED` in a stretch before its first `f`.
    current: u32,
    objects: Vec<Object>,
}

/// The material of a stretch's objects before its first `f`: whatever
/// the text before the stretch left current.
const INHERITED: u32 = u32::MAX;

impl Entities {
    /// Before the first entity of a file: the default material current.
    fn file() -> Self {
        Entities {
            background: None,
            lights: Vec::new(),
            materials: vec![Material::default()],
            keys: vec![[0; 8]],
            index: HashMap::new(),
            current: 0,
            objects: Vec::new(),
        }
    }

    /// At the start of a stretch: no materials of its own yet.
    fn stretch() -> Self {
        Entities {
            materials: Vec::new(),
            keys: Vec::new(),
            current: INHERITED,
            ..Self::file()
        }
    }

    /// Reads entity `t` (its keyword just taken): any but `v` and the
    /// view's keywords.
    fn read<'a>(&mut self, p: &mut Parser<'a>, t: Tok<'a>) -> Result<(), SceneError> {
        match t.s {
            "b" => self.background = Some(p.color("b", "background", &v::BACKGROUND)?.0),
            "l" => {
                let (pos, _) = p.vec3("l", "light position", &v::LIGHT_POSITION)?;
                let color = match p.peek() {
                    Some(n) if parse_number(n.s).is_some() => {
                        Some(p.color("l", "light colour", &v::LIGHT_COLOR)?.0)
                    }
                    _ => None,
                };
                self.lights.push((pos, color));
            }
            "f" => {
                let (c, _) = p.color("f", "colour", &v::COLOR)?;
                let kd = p.num("f", "Kd", &v::KD)?;
                let ks = p.num("f", "Ks", &v::NFF_KS)?;
                let shine = p.num("f", "Shine", &v::SHINE)?;
                let transmittance = p.num("f", "T", &v::KT)?;
                let ior = p.raw_num("f", &|| "index of refraction".into())?;
                let ior_tok = p.taken();
                // The SPD writes ior 0 for opaque surfaces, where it means
                // nothing: read it as 1. A transparent one needs a real ior.
                let ior = if transmittance == 0.0 && ior == 0.0 {
                    1.0
                } else {
                    ior
                };
                p.checked(ior_tok, ior, &v::IOR)?;
                let key = [c.x, c.y, c.z, kd, ks, shine, transmittance, ior].map(f64::to_bits);
                let (materials, keys) = (&mut self.materials, &mut self.keys);
                self.current = *self.index.entry(key).or_insert_with(|| {
                    materials.push(Material {
                        name: format!("nff{}", materials.len()),
                        ka: kd * c,
                        kd: kd * c,
                        ksr: ks,
                        nr: shine,
                        kst: 0.0,
                        nt: shine,
                        kr: DVec3::splat(ks),
                        kt: DVec3::splat(transmittance),
                        ior,
                        absorption: DVec3::ZERO,
                    });
                    keys.push(key);
                    materials.len() as u32 - 1
                });
            }
            "c" => {
                let (base, _) = p.vec3("c", "base", &v::BASE)?;
                let r0 = p.num("c", "base radius", &v::BASE_RADIUS)?;
                let (apex, _) = p.vec3("c", "apex", &v::APEX)?;
                let r1 = p.num("c", "apex radius", &v::APEX_RADIUS)?;
                p.check(t, v::cone(base, r0, apex, r1))?;
                self.objects.push(Object {
                    shape: Shape::Cone {
                        base,
                        base_radius: r0,
                        apex,
                        apex_radius: r1,
                    },
                    material: self.current,
                });
            }
            "s" => {
                let (center, _) = p.vec3("s", "centre", &v::CENTER)?;
                let radius = p.num("s", "radius", &v::RADIUS)?;
                self.objects.push(Object {
                    shape: Shape::Sphere { center, radius },
                    material: self.current,
                });
            }
            "p" => {
                let (n, _) = p.count("p")?;
                let mut vertices = Vec::with_capacity(n.min(1024));
                let mut toks = Vec::with_capacity(n.min(1024));
                for i in 0..n {
                    let (vx, vt) = p.vec3_of(
                        "p",
                        &|| format!("vertex {} of {n}", i + 1),
                        &v::VERTEX,
                        false,
                    )?;
                    vertices.push(vx);
                    toks.push(vt);
                }
                if let Err(e) = v::polygon(&vertices) {
                    return Err(p.err(e.index.map_or(t, |i| toks[i]), e.message));
                }
                self.objects.push(Object {
                    shape: Shape::Polygon { vertices },
                    material: self.current,
                });
            }
            "pp" => {
                let (n, _) = p.count("pp")?;
                let mut vertices = Vec::with_capacity(n.min(1024));
                let mut normals = Vec::with_capacity(n.min(1024));
                let mut toks = Vec::with_capacity(n.min(1024));
                for i in 0..n {
                    let (vx, vt) = p.vec3_of(
                        "pp",
                        &|| format!("vertex {} of {n}", i + 1),
                        &v::VERTEX,
                        false,
                    )?;
                    let (nv, _) = p.vec3_of(
                        "pp",
                        &|| format!("normal {} of {n}", i + 1),
                        &v::VERTEX_NORMAL,
                        false,
                    )?;
                    vertices.push(vx);
                    normals.push(nv);
                    toks.push(vt);
                }
                if let Err(e) = v::polygon(&vertices) {
                    return Err(p.err(e.index.map_or(t, |i| toks[i]), e.message));
                }
                // A fan; zero-area slivers of a valid polygon are skipped.
                for i in 1..n - 1 {
                    let tri = [vertices[0], vertices[i], vertices[i + 1]];
                    if v::triangle_is_degenerate(&tri) {
                        continue;
                    }
                    self.objects.push(Object {
                        shape: Shape::Triangle {
                            vertices: tri,
                            normals: Some(Box::new([normals[0], normals[i], normals[i + 1]])),
                        },
                        material: self.current,
                    });
                }
            }
            s if s == "v" || VIEW_KEYWORDS.contains(&s) => {
                return Err(p.err(t, format!("`{s}` outside a `v` (viewpoint) block")));
            }
            s => {
                return Err(p.err(
                    t,
                    format!("unknown NFF entity `{s}` (expected v, b, l, f, c, s, p or pp)"),
                ));
            }
        }
        Ok(())
    }

    /// Appends stretch `s`, read after everything in `self`: its
    /// materials found again or added (in the order a single pass would
    /// add them, with the names it would give), its objects' materials
    /// mapped, the material current before its first `f` being `self`'s.
    fn append(&mut self, s: Entities) {
        let mut map = Vec::with_capacity(s.materials.len());
        for (mut m, key) in s.materials.into_iter().zip(s.keys) {
            let (materials, keys) = (&mut self.materials, &mut self.keys);
            map.push(*self.index.entry(key).or_insert_with(|| {
                m.name = format!("nff{}", materials.len());
                materials.push(m);
                keys.push(key);
                materials.len() as u32 - 1
            }));
        }
        let current = self.current;
        self.objects.extend(s.objects.into_iter().map(|mut o| {
            o.material = match o.material {
                INHERITED => current,
                i => map[i as usize],
            };
            o
        }));
        if s.current != INHERITED {
            self.current = map[s.current as usize];
        }
        self.lights.extend(s.lights);
        if s.background.is_some() {
            self.background = s.background;
        }
    }
}

/// Texts shorter than this are read in one pass: below it, reading in
/// stretches side by side saves less than it costs.
const STRETCHES_MIN_BYTES: usize = 1 << 18;

/// Where the stretches a long text is read in begin: the first after a
/// short head (a 64th of the text, where the view is), then `n` of about
/// equal size, each at the start of a line whose first token starts an
/// object or a material (`s`, `p`, `pp`, `c`, `f`). In a valid file such a
/// line always starts an entity; where it does not (a polygon short of
/// vertices), the stretches do not join up and the text is read in one
/// pass after all, which reports the fault (`pass`).
fn stretch_starts(text: &str, n: usize) -> Vec<usize> {
    let bytes = text.as_bytes();
    let head = (text.len() / 64).max(4096);
    let mut starts: Vec<usize> = Vec::new();
    for k in 0..n {
        let mut i = head + (text.len() - head) / n * k;
        if starts.last().is_some_and(|&l| i <= l) {
            continue;
        }
        // The next line start with an entity's keyword, within 64 kB.
        let limit = (i + (1 << 16)).min(text.len());
        while let Some(nl) = bytes[i..limit].iter().position(|&b| b == b'\n') {
            i += nl + 1;
            let rest = &bytes[i..];
            let keyword = ["s", "p", "pp", "c", "f"].iter().any(|w| {
                rest.starts_with(w.as_bytes()) && matches!(rest.get(w.len()), Some(b' ' | b'\t'))
            });
            if keyword {
                starts.push(i);
                break;
            }
        }
    }
    starts
}

/// Reads the stretch of the text whose first entity starts at byte
/// `start`, up to the first entity that starts at or after `stop`, the
/// objects checked against the f32 limits about `origin`. Also returns
/// where it stopped (the next entity's start; `None` at the end of the
/// text). Any fault (or a `v`) is an error, which the caller answers by
/// reading the text in one pass, so that the fault is reported as that
/// pass reports it.
fn parse_stretch(
    text: &str,
    path: &Path,
    start: usize,
    stop: usize,
    origin: DVec3,
) -> Result<(Entities, Option<usize>), SceneError> {
    let mut p = Parser::new_at(text, path, start);
    let mut e = Entities::stretch();
    // Room for the objects of a stretch of spheres written tersely (32
    // bytes each), so that the vector seldom moves as it grows.
    e.objects
        .reserve((stop.min(text.len()) - start.min(text.len())) / 32);
    let mut checked = 0;
    while let Some(t) = p.peek() {
        if t.off >= stop {
            break;
        }
        p.advance();
        e.read(&mut p, t)?;
        while checked < e.objects.len() {
            if let Err((_, m)) = v::object_limits(&e.objects[checked].shape, origin) {
                return Err(p.err(t, m));
            }
            checked += 1;
        }
    }
    Ok((e, p.peek().map(|t| t.off)))
}

/// One pass over the text. With `locate`, stops at the entity that makes
/// that light or object. A long text (without `locate`) is read in
/// stretches side by side once the first stretch has given the view,
/// when they join up (each ends where the next begins); otherwise, and
/// after any fault in one, in one pass.
fn pass<'a>(
    text: &'a str,
    path: &'a Path,
    progress: &dyn Fn(u64, u64),
    locate: Option<Site>,
) -> Result<Outcome<'a>, SceneError> {
    let total = text.len() as u64;
    let mut next_report = 0;
    let mut p = Parser::new(text, path);
    let mut view: Option<View> = None;
    let mut e = Entities::file();
    // Objects are checked against the f32 limits as they are made, once
    // the camera is known (most files start with `v`); `unchecked` came
    // before it and are left to the caller.
    let mut origin: Option<DVec3> = None;
    let (mut unchecked, mut checked) = (0, 0);
    let (find_light, find_object) = match locate {
        Some(Site::Light(i)) => (i, usize::MAX),
        Some(Site::Object(i, _)) => (usize::MAX, i),
        _ => (usize::MAX, usize::MAX),
    };
    let threads = rayon::current_num_threads();
    let starts = if locate.is_none() && text.len() >= STRETCHES_MIN_BYTES && threads > 1 {
        stretch_starts(text, 2 * threads)
    } else {
        Vec::new()
    };
    let mut stop = starts.first().copied().unwrap_or(usize::MAX);

    while let Some(t) = p.peek() {
        if t.off >= stop {
            // The first stretch read: the rest side by side, if the view
            // is known and the first stretch ended where the second begins.
            stop = usize::MAX;
            let Some(origin) = origin.filter(|_| t.off == starts[0]) else {
                continue;
            };
            // Stretch k ends where stretch k + 1 begins, the last at the end.
            let end = |k: usize| starts.get(k + 1).copied();
            let read: Vec<_> = {
                use rayon::prelude::*;
                starts
                    .par_iter()
                    .enumerate()
                    .map(|(k, &start)| {
                        parse_stretch(text, path, start, end(k).unwrap_or(usize::MAX), origin)
                    })
                    .collect()
            };
            let joined = read
                .iter()
                .enumerate()
                .all(|(k, r)| matches!(r, Ok((_, at)) if *at == end(k)));
            if !joined {
                continue;
            }
            let count: usize = read.iter().flatten().map(|(s, _)| s.objects.len()).sum();
            e.objects.reserve(count);
            for (k, r) in read.into_iter().enumerate() {
                e.append(r.expect("checked").0);
                progress(end(k).map_or(total, |x| x as u64), total);
            }
            // The stretches checked their objects and read to the end.
            break;
        }
        if t.off >= next_report {
            progress(t.off as u64, total);
            next_report = t.off + PROGRESS_STEP;
        }
        p.advance();
        if t.s == "v" {
            if view.is_some() {
                return Err(p.err(t, "a second `v` (viewpoint) block"));
            }
            let parsed = p.view(t)?;
            origin = parsed.from.map(|(from, _)| from);
            (unchecked, checked) = (e.objects.len(), e.objects.len());
            view = Some(parsed);
        } else {
            e.read(&mut p, t)?;
        }
        if e.objects.len() > find_object || e.lights.len() > find_light {
            return Ok(Outcome::Located(t));
        }
        if let Some(origin) = origin {
            while checked < e.objects.len() {
                if let Err((part, m)) = v::object_limits(&e.objects[checked].shape, origin) {
                    let site = Site::Object(checked, part);
                    return Err(p.err(value_token(text, t, site), m));
                }
                checked += 1;
            }
        }
    }
    progress(total, total);

    let Some(view) = view else {
        return Err(SceneError::in_file(path, "no `v` (viewpoint) block"));
    };
    let (from, _) = view.from.expect("checked in view()");
    let (at, at_tok) = view.at.expect("checked in view()");
    let (up, up_tok) = view.up.expect("checked in view()");
    let (fov, fov_tok) = view.angle.expect("checked in view()");
    if let Err((fault, msg)) = v::camera(from, at, up) {
        let tok = match fault {
            CameraFault::At => at_tok,
            CameraFault::Up => up_tok,
        };
        return Err(p.err(tok, msg));
    }
    let (width, height) = view
        .resolution
        .unwrap_or((DEFAULT_RESOLUTION, DEFAULT_RESOLUTION));

    let Entities {
        background,
        lights,
        materials,
        objects,
        ..
    } = e;
    let background = background.unwrap_or(DVec3::ZERO);
    let grey = DVec3::splat(light_intensity(lights.len()));
    let scene = Scene {
        camera: Camera {
            from,
            at,
            up,
            fov,
            width,
            height,
        },
        background,
        ambient: grey,
        lights: lights
            .into_iter()
            .map(|(position, color)| Light {
                position,
                color: color.unwrap_or(grey),
                falloff: [1.0, 0.0, 0.0],
            })
            .collect(),
        materials,
        objects,
        source: path.to_path_buf(),
    };
    Ok(Outcome::Scene {
        scene: Box::new(scene),
        at: at_tok,
        fov: fov_tok,
        unchecked,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const VIEW: &str =
        "v\nfrom 0 -10 2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 1\nresolution 320 240\n";

    fn parse_ok(text: &str) -> Scene {
        parse(text, Path::new("t.nff"), &|_, _| {}).unwrap_or_else(|e| panic!("{e}"))
    }

    fn parse_err(text: &str) -> (usize, usize, String) {
        let e = parse(text, Path::new("t.nff"), &|_, _| {}).expect_err("should fail");
        (
            e.line().unwrap(),
            e.column().unwrap(),
            e.message().to_string(),
        )
    }

    /// The byte-at-a-time scanner `scan` replaced (one state machine over
    /// every byte, 2.5x the instructions): the reference it must equal.
    fn scan_reference<'a>(text: &'a str, off: &mut usize) -> Option<Tok<'a>> {
        let bytes = text.as_bytes();
        let mut i = *off;
        let mut start: Option<usize> = None;
        let mut comment = false;
        while i < bytes.len() {
            let b = bytes[i];
            let (space, len) = if b < 0x80 {
                (matches!(b, b' ' | b'\t' | b'\n' | 0x0B | 0x0C | b'\r'), 1)
            } else {
                let c = text[i..].chars().next().unwrap_or(' ');
                (c.is_whitespace(), c.len_utf8())
            };
            if comment {
                if b == b'\n' {
                    comment = false;
                }
            } else if space || b == b'#' {
                if let Some(s) = start {
                    *off = i;
                    return Some(Tok {
                        s: &text[s..i],
                        off: s,
                    });
                }
                comment = b == b'#';
            } else if start.is_none() {
                start = Some(i);
            }
            i += len;
        }
        *off = text.len();
        start.map(|s| Tok {
            s: &text[s..],
            off: s,
        })
    }

    proptest::proptest! {
        /// Token for token (text and offset) and position for position,
        /// `scan` is the reference on text of separators, comments,
        /// Unicode spaces and other characters.
        #[test]
        fn scan_is_the_reference(parts in proptest::collection::vec(
            proptest::prop_oneof![
                proptest::strategy::Just(" ".to_string()),
                proptest::strategy::Just("\n".to_string()),
                proptest::strategy::Just("\t\r\u{b}\u{c}".to_string()),
                proptest::strategy::Just("#".to_string()),
                proptest::strategy::Just("\u{a0}".to_string()),
                proptest::strategy::Just("\u{2003}".to_string()),
                proptest::strategy::Just("é".to_string()),
                proptest::strategy::Just("\u{1F600}".to_string()),
                "[a-z0-9.+-]{1,6}",
            ],
            0..40,
        )) {
            let text: String = parts.concat();
            let (mut a, mut b) = (0, 0);
            loop {
                let (ta, tb) = (scan(&text, &mut a), scan_reference(&text, &mut b));
                proptest::prop_assert_eq!(ta.map(|t| (t.s, t.off)), tb.map(|t| (t.s, t.off)), "{:?}", text);
                proptest::prop_assert_eq!(a, b, "{:?}", text);
                if ta.is_none() {
                    break;
                }
            }
        }
    }

    #[test]
    fn tokens_and_comments() {
        let text = "s 1\t2#c 3\n  4 # x y\n5";
        let mut off = 0;
        let toks: Vec<_> = std::iter::from_fn(|| scan(text, &mut off)).collect();
        let s: Vec<_> = toks.iter().map(|t| t.s).collect();
        assert_eq!(s, ["s", "1", "2", "4", "5"]);
        assert_eq!(toks[3].off, 12);
        // Any Unicode whitespace separates; other characters stay in tokens.
        let text = "s\u{a0}1\u{2003}2\x0b#é 3\né4 é";
        let mut off = 0;
        let toks: Vec<_> = std::iter::from_fn(|| scan(text, &mut off)).collect();
        let s: Vec<_> = toks.iter().map(|t| t.s).collect();
        assert_eq!(s, ["s", "1", "2", "é4", "é"]);
        assert_eq!(&text[toks[3].off..toks[3].off + 3], "é4");
    }

    #[test]
    fn view_block() {
        let s = parse_ok(VIEW);
        assert_eq!(s.camera.from, DVec3::new(0.0, -10.0, 2.0));
        assert_eq!(s.camera.fov, 40.0);
        assert_eq!((s.camera.width, s.camera.height), (320, 240));
        assert_eq!(s.ambient, DVec3::ZERO);
        let s = parse_ok("v from 0 -10 2 at 0 0 0 up 0 0 1 angle 40");
        assert_eq!((s.camera.width, s.camera.height), (512, 512));
    }

    #[test]
    fn light_colour_lookahead() {
        let s = parse_ok(&format!("{VIEW}l 1 2 3\nl 4 5 6 0.5 0.25 1\ns 0 0 0 1\n"));
        let w = 2f64.sqrt() / 4.0;
        assert_eq!(s.lights[0].color, DVec3::splat(w));
        assert_eq!(s.lights[1].color, DVec3::new(0.5, 0.25, 1.0));
        assert_eq!(s.ambient, DVec3::splat(w));
        assert_eq!(s.lights[1].falloff, [1.0, 0.0, 0.0]);
    }

    #[test]
    fn missing_view_items() {
        let (l, c, m) = parse_err("v\nfrom 0 0 1\nat 0 0 0\nangle 30\n");
        assert_eq!((l, c, m.as_str()), (1, 1, "the `v` block has no `up`"));
        let e = parse("s 0 0 0 1\n", Path::new("t.nff"), &|_, _| {}).unwrap_err();
        assert_eq!(e.to_string(), "t.nff: no `v` (viewpoint) block");
        let (l, c, m) = parse_err(&format!("{VIEW}s 0 0 0 1\nangle 3\n"));
        assert_eq!((l, c), (9, 1));
        assert!(m.contains("`angle` outside a `v`"), "{m}");
    }

    #[test]
    fn bad_numbers() {
        let (l, c, m) = parse_err(&format!("{VIEW}s 0 0 x 1\n"));
        assert_eq!((l, c), (8, 7));
        assert_eq!(m, "expected centre z (a number) in `s` entity, found `x`");
        let (l, c, m) = parse_err(&format!("{VIEW}p 2.5\n"));
        assert_eq!((l, c), (8, 3));
        assert!(m.contains("must be an integer"), "{m}");
        let (l, c, m) = parse_err(&format!("{VIEW}p 2\n0 0 0 1 0 0\n"));
        assert_eq!((l, c), (8, 3));
        assert!(m.contains("at least 3 vertices, got 2"), "{m}");
        let (l, c, m) = parse_err("v from 0 0 1 at 0 0 0 up 0 0 1 angle 40 resolution 0 10");
        assert_eq!((l, c), (1, 52));
        assert!(m.contains("width must be in 1..=65536, got 0"), "{m}");
    }

    #[test]
    fn materials_deduplicated() {
        let s = parse_ok(&format!(
            "{VIEW}s 0 0 0 1\nf 1 0 0 0.5 0.5 30 0 1\ns 1 0 0 1\nf 0 1 0 1 0 1 0 1\n\
             s 2 0 0 1\nf 1 0 0 0.5 0.5 30 0 1\ns 3 0 0 1\n"
        ));
        assert_eq!(s.materials.len(), 3);
        let mats: Vec<_> = s.objects.iter().map(|o| o.material).collect();
        assert_eq!(mats, [0, 1, 2, 1]);
    }

    #[test]
    fn empty_file_is_truncation_free_but_needs_view() {
        let e = parse("# only a comment\n", Path::new("t.nff"), &|_, _| {}).unwrap_err();
        assert_eq!(e.line(), None);
        let (l, c, m) = parse_err("v from 0 0");
        assert_eq!((l, c), (1, 10));
        assert_eq!(
            m,
            "truncated `from` entity at end of file: expected eye point z"
        );
    }

    /// A long NFF of every entity kind, deterministic in `seed`: five
    /// materials that recur (so stretches meet materials made before
    /// them), objects before any `f` of their stretch, entities over
    /// several lines, comments and blank lines, lights and backgrounds
    /// between objects.
    fn long_nff(seed: u64, entities: usize) -> String {
        let mut x = seed;
        let mut next = move |n: u64| {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 33) % n
        };
        let mut t = String::from(VIEW);
        t.push_str("l 1 2 3\n");
        for _ in 0..entities {
            let c = |k: u64| k as f64 * 0.37 - 3.0;
            match next(20) {
                0 => {
                    let m = next(5) as f64;
                    t += &format!("f {} 0.5 0.25 0.7 0.3 {} 0 1\n", 0.1 * m, 5.0 + m);
                }
                1 => t += &format!("l {} 4 5 0.5 0.5 0.5\n", c(next(16))),
                2 => {
                    t += &format!(
                        "b 0.{} 0.2 0.3\n# a comment, then a blank line\n\n",
                        next(9)
                    )
                }
                3 | 4 => {
                    let (a, b) = (c(next(16)), c(next(16)));
                    t += &format!(
                        "p 4\n{a} {b} 0\n{} {b} 0\n{} {} 0\n{a} {} 0\n",
                        a + 1.0,
                        a + 1.0,
                        b + 1.0,
                        b + 1.0
                    );
                }
                5 => t += &format!("c\n{} 0 0 0.5\n{} 0 2 0.25\n", c(next(16)), c(next(16))),
                6 => {
                    t += &format!(
                        "pp 3\n0 0 {0} 0 0 1\n1 0 {0} 0 0 1\n0 1 {0} 0 0 1\n",
                        c(next(16))
                    )
                }
                _ => {
                    t += &format!(
                        "s {} {} {} 0.{}\n",
                        c(next(16)),
                        c(next(16)),
                        c(next(16)),
                        1 + next(8)
                    )
                }
            }
        }
        t
    }

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    /// A long text read in stretches side by side gives the scene of one
    /// pass: the same objects, materials (found again across stretches,
    /// numbered and named as one pass does), lights and background.
    #[test]
    fn stretches_read_what_one_pass_reads() {
        for seed in 1..4 {
            let text = long_nff(seed, 30_000);
            assert!(text.len() >= STRETCHES_MIN_BYTES, "{}", text.len());
            // The stretches are really read side by side, and join up.
            let starts = stretch_starts(&text, 8);
            assert!(starts.len() >= 6, "{starts:?}");
            let origin = DVec3::new(0.0, -10.0, 2.0);
            for (k, &start) in starts.iter().enumerate() {
                let end = starts.get(k + 1).copied();
                let (e, at) = parse_stretch(
                    &text,
                    Path::new("t.nff"),
                    start,
                    end.unwrap_or(usize::MAX),
                    origin,
                )
                .unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(at, end);
                assert!(!e.objects.is_empty());
            }
            let one = in_pool(1, || parse_ok(&text));
            let side_by_side = in_pool(4, || parse_ok(&text));
            assert!(one.materials.len() > 3 && one.objects.len() > 20_000);
            assert_eq!(one, side_by_side, "seed {seed}");
            // Windows line ends read the same.
            let crlf = text.replace('\n', "\r\n");
            assert!(stretch_starts(&crlf, 8).len() >= 6);
            assert_eq!(one, in_pool(4, || parse_ok(&crlf)), "seed {seed}, CRLF");
        }
    }

    /// A fault in a long text is reported as one pass reports it, whichever
    /// stretch it falls in, also where it makes the stretches not join up
    /// (a polygon short of a vertex, whose next line starts an entity).
    #[test]
    fn stretches_report_faults_as_one_pass_does() {
        let text = long_nff(7, 30_000);
        let lines: Vec<&str> = text.lines().collect();
        type Fault = fn(&str) -> Option<String>;
        let faults: [(&str, Fault); 4] = [
            ("a bad number", |l| {
                l.starts_with("s ").then(|| "s 1 2 x 0.5".into())
            }),
            ("a short polygon", |l| {
                l.starts_with("p 4").then(|| "p 5".into())
            }),
            ("an unknown entity", |l| {
                l.starts_with("s ").then(|| "q 1 2 3".into())
            }),
            ("a second view", |l| l.starts_with("s ").then(|| "v".into())),
        ];
        for (what, fault) in faults {
            for frac in [0.3, 0.55, 0.9] {
                let mut lines = lines.clone();
                let from = (lines.len() as f64 * frac) as usize;
                let at = (from..lines.len())
                    .find(|&i| fault(lines[i]).is_some())
                    .unwrap();
                let bad = fault(lines[at]).unwrap();
                lines[at] = &bad;
                let bad_text = lines.join("\n");
                let one = in_pool(1, || parse_err(&bad_text));
                let side_by_side = in_pool(4, || parse_err(&bad_text));
                assert_eq!(one, side_by_side, "{what} at {frac}");
                assert!(
                    one.0 >= at,
                    "{what}: line {} before the fault's {}",
                    one.0,
                    at + 1
                );
            }
        }
    }
}
