//! Eric Haines' Neutral File Format (the SPD scenes), read token by token:
//! tokens are separated by any whitespace, newlines mean nothing (a `c`
//! entity on one line or on three reads the same), `#` starts a comment
//! that runs to the end of the line. Conventions are in
//! `docs/scene-format.md`.

use super::error::SceneError;
use super::validate::{self, CameraFault};
use super::{Camera, Light, Material, Object, Scene, Shape};
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

/// Image size when there is no `resolution`.
pub(crate) const DEFAULT_RESOLUTION: u32 = 512;

const VIEW_KEYWORDS: &[&str] = &["from", "at", "up", "angle", "hither", "resolution"];

#[derive(Clone, Copy, Debug)]
struct Tok<'a> {
    s: &'a str,
    off: usize,
}

/// The token that starts at or after byte `*off` of `text`; moves `*off`
/// past it. Tokens are read one at a time: an array of them would hold 14
/// M tokens (336 MB) for an NFF of 1 M spheres.
fn scan<'a>(text: &'a str, off: &mut usize) -> Option<Tok<'a>> {
    let bytes = text.as_bytes();
    let mut i = *off;
    let mut start: Option<usize> = None;
    let mut comment = false;
    while i < bytes.len() {
        // ASCII bytes directly; any other character decoded (Unicode
        // whitespace separates tokens too, as `char::is_whitespace` says).
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
                // A `#` right after a token is read again: it starts a comment.
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
        let mut off = 0;
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

    fn num(&mut self, entity: &str, expected: &str) -> Result<(f64, Tok<'a>), SceneError> {
        self.num_of(entity, &|| expected.to_string())
    }

    /// `num` with a description formatted only for an error (a 1 M-sphere
    /// file reads 4 M numbers).
    fn num_of(
        &mut self,
        entity: &str,
        expected: &dyn Fn() -> String,
    ) -> Result<(f64, Tok<'a>), SceneError> {
        let t = self.next(entity, expected)?;
        let Some(x) = parse_number(t.s) else {
            let expected = expected();
            return Err(self.err(
                t,
                format!(
                    "expected {expected} (a number) in `{entity}` entity, found `{}`",
                    t.s
                ),
            ));
        };
        if !x.is_finite() {
            return Err(self.err(
                t,
                format!(
                    "{} in `{entity}` entity must be a finite number, got `{}`",
                    expected(),
                    t.s
                ),
            ));
        }
        Ok((x, t))
    }

    fn vec3(&mut self, entity: &str, what: &str) -> Result<(DVec3, Tok<'a>), SceneError> {
        self.vec3_of(entity, &|| what.to_string())
    }

    fn vec3_of(
        &mut self,
        entity: &str,
        what: &dyn Fn() -> String,
    ) -> Result<(DVec3, Tok<'a>), SceneError> {
        let (x, t) = self.num_of(entity, &|| format!("{} x", what()))?;
        let (y, _) = self.num_of(entity, &|| format!("{} y", what()))?;
        let (z, _) = self.num_of(entity, &|| format!("{} z", what()))?;
        Ok((DVec3::new(x, y, z), t))
    }

    fn color(&mut self, entity: &str, what: &str) -> Result<(DVec3, Tok<'a>), SceneError> {
        let (r, t) = self.num_of(entity, &|| format!("{what} red"))?;
        let (g, _) = self.num_of(entity, &|| format!("{what} green"))?;
        let (b, _) = self.num_of(entity, &|| format!("{what} blue"))?;
        Ok((DVec3::new(r, g, b), t))
    }

    fn integer(&mut self, entity: &str, expected: &str) -> Result<(i64, Tok<'a>), SceneError> {
        let (x, t) = self.num(entity, expected)?;
        if x.fract() != 0.0 || x.abs() > 1e15 {
            return Err(self.err(t, format!("{expected} must be an integer, got `{}`", t.s)));
        }
        Ok((x as i64, t))
    }

    fn count(&mut self, entity: &str) -> Result<(usize, Tok<'a>), SceneError> {
        let (n, t) = self.integer(entity, "the vertex count")?;
        if n < 3 {
            return Err(self.err(t, format!("`{entity}` needs at least 3 vertices, got {n}")));
        }
        Ok((n as usize, t))
    }

    fn view(&mut self, v_tok: Tok<'a>) -> Result<View<'a>, SceneError> {
        let mut view = View::default();
        while let Some(t) = self.peek() {
            if !VIEW_KEYWORDS.contains(&t.s) {
                break;
            }
            self.advance();
            match t.s {
                "from" => view.from = Some(self.vec3("from", "eye point")?),
                "at" => view.at = Some(self.vec3("at", "look-at point")?),
                "up" => view.up = Some(self.vec3("up", "up vector")?),
                "angle" => view.angle = Some(self.num("angle", "the field of view in degrees")?),
                "hither" => {
                    self.num("hither", "the hither distance")?;
                }
                "resolution" => {
                    let (w, tw) = self.integer("resolution", "the width")?;
                    let (h, th) = self.integer("resolution", "the height")?;
                    let w = self.check(tw, validate::image_size(w, "width"))?;
                    let h = self.check(th, validate::image_size(h, "height"))?;
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

/// Parses an NFF scene.
pub(super) fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let mut p = Parser::new(text, path);
    let mut view: Option<View> = None;
    let mut background = DVec3::ZERO;
    let mut lights: Vec<(DVec3, Option<DVec3>)> = Vec::new();
    let mut materials = vec![Material::default()];
    let mut material_index: HashMap<[u64; 8], u32> = HashMap::new();
    let mut current = 0u32;
    let mut objects = Vec::new();

    while let Some(t) = p.peek() {
        p.advance();
        match t.s {
            "v" => {
                if view.is_some() {
                    return Err(p.err(t, "a second `v` (viewpoint) block"));
                }
                view = Some(p.view(t)?);
            }
            "b" => background = p.color("b", "background")?.0,
            "l" => {
                let (pos, _) = p.vec3("l", "light position")?;
                let color = match p.peek() {
                    Some(n) if parse_number(n.s).is_some() => Some(p.color("l", "light colour")?.0),
                    _ => None,
                };
                lights.push((pos, color));
            }
            "f" => {
                let (c, _) = p.color("f", "colour")?;
                let (kd, _) = p.num("f", "Kd")?;
                let (ks, _) = p.num("f", "Ks")?;
                let (shine, _) = p.num("f", "Shine")?;
                let (transmittance, _) = p.num("f", "T")?;
                let (ior, ior_tok) = p.num("f", "index of refraction")?;
                // The SPD writes ior 0 for opaque surfaces, where it means
                // nothing: read it as 1. A transparent one needs a real ior.
                let ior = if transmittance == 0.0 && ior == 0.0 {
                    1.0
                } else {
                    ior
                };
                p.check(ior_tok, validate::ior(ior))?;
                let key = [c.x, c.y, c.z, kd, ks, shine, transmittance, ior].map(f64::to_bits);
                current = *material_index.entry(key).or_insert_with(|| {
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
                    materials.len() as u32 - 1
                });
            }
            "c" => {
                let (base, _) = p.vec3("c", "base")?;
                let (r0, _) = p.num("c", "base radius")?;
                let (apex, _) = p.vec3("c", "apex")?;
                let (r1, _) = p.num("c", "apex radius")?;
                p.check(t, validate::cone(base, r0, apex, r1))?;
                objects.push(Object {
                    shape: Shape::Cone {
                        base,
                        base_radius: r0,
                        apex,
                        apex_radius: r1,
                    },
                    material: current,
                });
            }
            "s" => {
                let (center, _) = p.vec3("s", "centre")?;
                let (radius, rt) = p.num("s", "radius")?;
                p.check(rt, validate::sphere_radius(radius))?;
                objects.push(Object {
                    shape: Shape::Sphere { center, radius },
                    material: current,
                });
            }
            "p" => {
                let (n, _) = p.count("p")?;
                let mut vertices = Vec::with_capacity(n.min(1024));
                let mut toks = Vec::with_capacity(n.min(1024));
                for i in 0..n {
                    let (v, vt) = p.vec3_of("p", &|| format!("vertex {} of {n}", i + 1))?;
                    vertices.push(v);
                    toks.push(vt);
                }
                if let Err(e) = validate::polygon(&vertices) {
                    return Err(p.err(e.index.map_or(t, |i| toks[i]), e.message));
                }
                objects.push(Object {
                    shape: Shape::Polygon { vertices },
                    material: current,
                });
            }
            "pp" => {
                let (n, _) = p.count("pp")?;
                let mut vertices = Vec::with_capacity(n.min(1024));
                let mut normals = Vec::with_capacity(n.min(1024));
                let mut toks = Vec::with_capacity(n.min(1024));
                for i in 0..n {
                    let (v, vt) = p.vec3_of("pp", &|| format!("vertex {} of {n}", i + 1))?;
                    let (nv, nt) = p.vec3_of("pp", &|| format!("normal {} of {n}", i + 1))?;
                    p.check(nt, validate::nonzero_vector(nv, "a vertex normal"))?;
                    vertices.push(v);
                    normals.push(nv);
                    toks.push(vt);
                }
                if let Err(e) = validate::polygon(&vertices) {
                    return Err(p.err(e.index.map_or(t, |i| toks[i]), e.message));
                }
                // A fan; zero-area slivers of a valid polygon are skipped.
                for i in 1..n - 1 {
                    let tri = [vertices[0], vertices[i], vertices[i + 1]];
                    if validate::triangle_is_degenerate(&tri) {
                        continue;
                    }
                    objects.push(Object {
                        shape: Shape::Triangle {
                            vertices: tri,
                            normals: Some(Box::new([normals[0], normals[i], normals[i + 1]])),
                        },
                        material: current,
                    });
                }
            }
            s if VIEW_KEYWORDS.contains(&s) => {
                return Err(p.err(t, format!("`{s}` outside a `v` (viewpoint) block")));
            }
            s => {
                return Err(p.err(
                    t,
                    format!("unknown NFF entity `{s}` (expected v, b, l, f, c, s, p or pp)"),
                ));
            }
        }
    }

    let Some(view) = view else {
        return Err(SceneError::in_file(path, "no `v` (viewpoint) block"));
    };
    let (from, _) = view.from.expect("checked in view()");
    let (at, at_tok) = view.at.expect("checked in view()");
    let (up, up_tok) = view.up.expect("checked in view()");
    let (fov, fov_tok) = view.angle.expect("checked in view()");
    if let Err((fault, msg)) = validate::camera(from, at, up) {
        let tok = match fault {
            CameraFault::At => at_tok,
            CameraFault::Up => up_tok,
        };
        return Err(p.err(tok, msg));
    }
    p.check(fov_tok, validate::fov(fov))?;
    let (width, height) = view
        .resolution
        .unwrap_or((DEFAULT_RESOLUTION, DEFAULT_RESOLUTION));

    let grey = DVec3::splat(light_intensity(lights.len()));
    Ok(Scene {
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const VIEW: &str =
        "v\nfrom 0 -10 2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 1\nresolution 320 240\n";

    fn parse_ok(text: &str) -> Scene {
        parse(text, Path::new("t.nff")).unwrap_or_else(|e| panic!("{e}"))
    }

    fn parse_err(text: &str) -> (usize, usize, String) {
        let e = parse(text, Path::new("t.nff")).expect_err("should fail");
        (
            e.line().unwrap(),
            e.column().unwrap(),
            e.message().to_string(),
        )
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
        let e = parse("s 0 0 0 1\n", Path::new("t.nff")).unwrap_err();
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
        let e = parse("# only a comment\n", Path::new("t.nff")).unwrap_err();
        assert_eq!(e.line(), None);
        let (l, c, m) = parse_err("v from 0 0");
        assert_eq!((l, c), (1, 10));
        assert_eq!(
            m,
            "truncated `from` entity at end of file: expected eye point z"
        );
    }
}
