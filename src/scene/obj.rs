//! Wavefront `.obj` meshes, read with `tobj` (faces triangulated as fans,
//! one index per vertex so normals line up with positions). Every model in
//! the file is merged into one [`Mesh`]; materials (`mtllib`, `usemtl`) and
//! texture coordinates are ignored. Zero-area triangles, common in real
//! files (the poles of the teapot), are dropped.

use super::validate::{fmt_num, triangle_is_degenerate};
use super::{read_text, utf8_message, Mesh, ReadError};
use glam::DVec3;
use std::io::{BufRead, Read};
use std::path::Path;

/// Bytes of text between two progress reports.
const PROGRESS_STEP: usize = 1 << 20;

/// Reads `obj_path`, calling `progress(bytes read)` now and then; returns
/// the mesh and the file's size. With `smooth`, the mesh gets per-vertex
/// normals: the file's normals where it has them, else area-weighted
/// averages of the face normals. The error message names the file (and the
/// line where there is one) and the reason; the caller locates it in the
/// scene file.
pub(super) fn load_mesh(
    obj_path: &Path,
    smooth: bool,
    progress: &dyn Fn(u64),
) -> Result<(Mesh, u64), String> {
    let text = read_text(obj_path).map_err(|e| match e {
        ReadError::Io(e) => format!("cannot read mesh {}: {e}", obj_path.display()),
        ReadError::Utf8 { line, column, byte } => format!(
            "mesh {}:{line}:{column}: {}",
            obj_path.display(),
            utf8_message(byte)
        ),
    })?;
    let mesh = parse_obj(&text, obj_path, smooth, progress)?;
    Ok((mesh, text.len() as u64))
}

/// The text as a `BufRead` that reports how far it has been read.
struct Counting<'a> {
    data: &'a [u8],
    pos: usize,
    next: usize,
    report: &'a dyn Fn(u64),
}

impl Read for Counting<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = (&self.data[self.pos..]).read(buf)?;
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for Counting<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.data[self.pos..])
    }
    fn consume(&mut self, n: usize) {
        self.pos += n;
        if self.pos >= self.next {
            (self.report)(self.pos as u64);
            self.next = self.pos + PROGRESS_STEP;
        }
    }
}

/// Parses the text of an `.obj` file (`obj_path` is only for messages).
pub(super) fn parse_obj(
    text: &str,
    obj_path: &Path,
    smooth: bool,
    progress: &dyn Fn(u64),
) -> Result<Mesh, String> {
    // A problem found after tobj (or by it) is located by reading the
    // text again line by line: no cost while all is well.
    let bad = |reason: String| match find_problem(text) {
        Some((line, why)) => format!("mesh {}:{line}: {why}", obj_path.display()),
        None => format!("mesh {}: {reason}", obj_path.display()),
    };
    // `..Default::default()` covers the fields some tobj features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = Counting {
        data: text.as_bytes(),
        pos: 0,
        next: PROGRESS_STEP,
        report: progress,
    };
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Ok((Vec::new(), Default::default()))
    })
    .map_err(|e| bad(e.to_string()))?;

    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut triangles = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = positions.len();
        let start = triangles.len();
        for p in m.positions.chunks_exact(3) {
            let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            if !v.is_finite() {
                return Err(bad(format!(
                    "object `{}` has a non-finite vertex",
                    model.name
                )));
            }
            positions.push(v);
        }
        if m.normals.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!(
                "object `{}` has a non-finite normal",
                model.name
            )));
        }
        let offset = u32::try_from(base).map_err(|_| bad("too many vertices".into()))?;
        for t in m.indices.chunks_exact(3) {
            let tri = [t[0] + offset, t[1] + offset, t[2] + offset];
            let corners = tri.map(|i| positions[i as usize]);
            if !triangle_is_degenerate(&corners) {
                triangles.push(tri);
            }
        }
        if smooth {
            let count = positions.len() - base;
            let computed = smooth_normals(&positions[base..], &triangles[start..], offset);
            if m.normals.len() == 3 * count {
                for (i, n) in m.normals.chunks_exact(3).enumerate() {
                    let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
                    let n = n.normalize_or_zero();
                    normals.push(if n == DVec3::ZERO { computed[i] } else { n });
                }
            } else {
                normals.extend(computed);
            }
        }
    }
    if triangles.is_empty() {
        return Err(format!(
            "mesh {}: it contains no triangles with non-zero area",
            obj_path.display()
        ));
    }
    progress(text.len() as u64);
    Ok(Mesh {
        positions,
        normals: smooth.then_some(normals),
        triangles,
    })
}

/// `n` numbers of a `v`, `vn` or `vt` line as tobj reads them (f32).
fn floats<'a>(
    words: &mut impl Iterator<Item = &'a str>,
    n: usize,
    what: &str,
) -> Result<Vec<f32>, String> {
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let Some(w) = words.next() else {
            return Err(format!("a {what} needs {n} numbers, got {}", out.len()));
        };
        let x: f32 = w
            .parse()
            .map_err(|_| format!("{what}: `{w}` is not a number"))?;
        if !x.is_finite() {
            return Err(format!(
                "{what}: `{w}` is not a finite single-precision number (.obj files are read \
                 in f32: magnitudes up to {})",
                fmt_num(f32::MAX as f64)
            ));
        }
        out.push(x);
    }
    Ok(out)
}

/// The first line (1-based) with a problem tobj or this loader would
/// stop at, and what it is. Follows tobj 4's reading of `v`, `vn`, `vt`
/// and `f` lines (relative indices included); other lines are ignored.
fn find_problem(text: &str) -> Option<(usize, String)> {
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let r = match words.next() {
            Some("v") => vertex(&mut words).map(|_| nv += 1),
            Some("vn") => floats(&mut words, 3, "normal").map(|_| nvn += 1),
            Some("vt") => floats(&mut words, 2, "texture coordinate").map(|_| nvt += 1),
            Some("f") => words.try_for_each(|w| face_vertex(w, [nv, nvt, nvn])),
            _ => Ok(()),
        };
        if let Err(why) = r {
            return Some((i + 1, why));
        }
    }
    None
}

/// A `v` line after its keyword: x y z, then nothing, w, or r g b.
fn vertex<'a>(words: &mut impl Iterator<Item = &'a str>) -> Result<[f32; 3], String> {
    let p = floats(words, 3, "vertex")?;
    let rest: Vec<&str> = words.collect();
    match rest.len() {
        0 | 3 => Ok([p[0], p[1], p[2]]),
        1 => {
            let w = floats(&mut rest.into_iter(), 1, "vertex weight")?[0];
            if w == 0.0 {
                return Err("vertex weight w is 0 (x, y and z are divided by it)".into());
            }
            let q = [p[0] / w, p[1] / w, p[2] / w];
            if q.iter().any(|x| !x.is_finite()) {
                return Err(format!(
                    "vertex divided by its weight {w} is beyond f32's range"
                ));
            }
            Ok(q)
        }
        n => Err(format!(
            "a vertex has x y z, then nothing, a weight w or a colour r g b; got {n} more numbers"
        )),
    }
}

/// One `v/vt/vn` of an `f` line, against the counts defined so far.
fn face_vertex(w: &str, counts: [usize; 3]) -> Result<(), String> {
    const WHAT: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let parts: Vec<&str> = w.split('/').collect();
    if parts.len() > 3 {
        return Err(format!(
            "face vertex `{w}` has more than 3 indices (v/vt/vn)"
        ));
    }
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() {
            continue;
        }
        let Ok(x) = part.parse::<i64>() else {
            return Err(match part.parse::<f64>() {
                Ok(_)
                    if part
                        .bytes()
                        .all(|b| b.is_ascii_digit() || b == b'-' || b == b'+') =>
                {
                    format!("{} index {part} is out of range", WHAT[k])
                }
                _ => format!("face vertex `{w}`: `{part}` is not an index"),
            });
        };
        let n = counts[k];
        let (name, defined) = (WHAT[k], format!("{n} defined before this line"));
        if x == 0 {
            return Err(format!("{name} index 0: .obj indices start at 1"));
        }
        // Texture and normal indices are only read where the file has some.
        if k > 0 && n == 0 {
            continue;
        }
        if x > n as i64 || x < -(n as i64) {
            return Err(format!("{name} index {x} is out of range: {defined}"));
        }
    }
    Ok(())
}

/// The 1-based line of the first `v` line of `obj_path` that reads as
/// `p` (for messages about a vertex the loader kept).
pub(super) fn vertex_line(obj_path: &Path, p: DVec3) -> Option<usize> {
    let text = std::fs::read_to_string(obj_path).ok()?;
    text.lines().enumerate().find_map(|(i, line)| {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            return None;
        }
        let q = vertex(&mut words).ok()?;
        (DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) == p).then_some(i + 1)
    })
}

/// Area-weighted vertex normals of `positions` (whose first vertex has index
/// `offset` in `triangles`). Vertices no triangle uses get +Z.
pub(super) fn smooth_normals(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    offset: u32,
) -> Vec<DVec3> {
    let mut acc = vec![DVec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| (i - offset) as usize);
        // |cross| is twice the area: the sum is area-weighted.
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        acc[a] += n;
        acc[b] += n;
        acc[c] += n;
    }
    acc.into_iter()
        .map(|n| {
            let n = n.normalize_or_zero();
            if n == DVec3::ZERO {
                DVec3::Z
            } else {
                n
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const OCTA: &str = "\
# octahedron
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

    #[test]
    fn flat_octahedron() {
        let m = parse_obj(OCTA, Path::new("o.obj"), false, &|_| {}).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangles.len(), 8);
        // single_index renumbers vertices in order of first use
        let first = m.triangles[0].map(|i| m.positions[i as usize]);
        assert_eq!(first, [DVec3::X, DVec3::Y, DVec3::Z]);
        assert_eq!(m.normals, None);
    }

    #[test]
    fn smooth_octahedron_computes_vertex_normals() {
        let m = parse_obj(OCTA, Path::new("o.obj"), true, &|_| {}).unwrap();
        let n = m.normals.unwrap();
        assert_eq!(n.len(), 6);
        for (p, n) in m.positions.iter().zip(&n) {
            assert!((*p - *n).length() < 1e-12, "{p} vs {n}");
        }
    }

    #[test]
    fn file_normals_are_used_and_quads_triangulated() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 2\nf 1//1 2//1 3//1 4//1\n";
        let m = parse_obj(text, Path::new("q.obj"), true, &|_| {}).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert_eq!(m.normals.unwrap(), vec![DVec3::Z; m.positions.len()]);
    }

    #[test]
    fn models_are_merged_and_degenerates_dropped() {
        let text = "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 2 0 1\nf 4 5 6\nf 4 5 7\n";
        let m = parse_obj(text, Path::new("m.obj"), false, &|_| {}).unwrap();
        assert_eq!(m.positions.len(), 7);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    }

    #[test]
    fn malformed_and_empty_files() {
        let err = |text: &str| parse_obj(text, Path::new("x.obj"), false, &|_| {}).unwrap_err();
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        // (text, expected message) — each error names the file and line
        let cases = [
            (
                format!("{tri}f 1 2 9\n"),
                "mesh x.obj:4: vertex index 9 is out of range: 3 defined before this line",
            ),
            (
                format!("{tri}f 1 2 -4\n"),
                "mesh x.obj:4: vertex index -4 is out of range: 3 defined before this line",
            ),
            (
                format!("{tri}f 0 1 2\n"),
                "mesh x.obj:4: vertex index 0: .obj indices start at 1",
            ),
            (
                format!("{tri}f 1 2 18446744073709551616\n"),
                "mesh x.obj:4: vertex index 18446744073709551616 is out of range",
            ),
            (
                format!("{tri}f 1 2 x\n"),
                "mesh x.obj:4: face vertex `x`: `x` is not an index",
            ),
            (
                "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n".to_string(),
                "mesh x.obj:2: vertex: `1e39` is not a finite single-precision number",
            ),
            (
                "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_string(),
                "mesh x.obj:1: vertex: `nan` is not a finite",
            ),
            (
                format!("{tri}vn 0 inf 1\nf 1//1 2//1 3//1\n"),
                "mesh x.obj:4: normal: `inf` is not a finite",
            ),
            (
                format!("{tri}vn 0 0 1\nf 1//1 2//1 3//2\n"),
                "mesh x.obj:5: normal index 2 is out of range: 1 defined before this line",
            ),
            (
                "v 0 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_string(),
                "mesh x.obj:1: vertex weight w is 0",
            ),
            (
                "v 0 0\nf 1 2 3\n".to_string(),
                "mesh x.obj:1: a vertex needs 3 numbers, got 2",
            ),
            (
                format!("{tri}f 1 2 2\n"),
                "mesh x.obj: it contains no triangles with non-zero area",
            ),
            (
                "# nothing\n".to_string(),
                "mesh x.obj: it contains no triangles with non-zero area",
            ),
        ];
        for (text, expected) in cases {
            let e = err(&text);
            assert!(
                e.starts_with(expected),
                "{text:?}:\n got {e}\nwant {expected}"
            );
        }
        let e = load_mesh(Path::new("/nonexistent/dir/none.obj"), false, &|_| {}).unwrap_err();
        assert!(
            e.starts_with("cannot read mesh /nonexistent/dir/none.obj: No such file"),
            "{e}"
        );
    }

    #[test]
    fn progress_is_reported_and_ends_at_the_size() {
        let text = OCTA.replace("# octahedron", &"# padding\n".repeat(300_000));
        let seen = std::cell::RefCell::new(Vec::new());
        parse_obj(&text, Path::new("o.obj"), false, &|n| {
            seen.borrow_mut().push(n)
        })
        .unwrap();
        let seen = seen.into_inner();
        assert!(seen.len() >= 3, "{seen:?}");
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
        assert_eq!(*seen.last().unwrap(), text.len() as u64);
    }
}
