//! Wavefront `.obj` meshes, read with `tobj` (faces triangulated as fans,
//! one index per vertex so normals line up with positions). Every model in
//! the file is merged into one [`Mesh`]; materials (`mtllib`, `usemtl`) and
//! texture coordinates are ignored. Zero-area triangles, common in real
//! files (the poles of the teapot), are dropped.

use super::validate::triangle_is_degenerate;
use super::Mesh;
use glam::DVec3;
use std::path::Path;

/// Reads `obj_path`. With `smooth`, the mesh gets per-vertex normals: the
/// file's normals where it has them, else area-weighted averages of the face
/// normals. The error message names the file and the reason; the caller
/// locates it in the scene file.
pub(super) fn load_mesh(obj_path: &Path, smooth: bool) -> Result<Mesh, String> {
    let text = std::fs::read_to_string(obj_path)
        .map_err(|e| format!("cannot read mesh {}: {e}", obj_path.display()))?;
    parse_obj(&text, obj_path, smooth)
}

/// Parses the text of an `.obj` file (`obj_path` is only for messages).
pub(super) fn parse_obj(text: &str, obj_path: &Path, smooth: bool) -> Result<Mesh, String> {
    let bad = |reason: String| format!("bad mesh {}: {reason}", obj_path.display());
    // `..Default::default()` covers the fields some tobj features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
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
                    "vertex {} of object `{}` is not finite",
                    positions.len() - base + 1,
                    model.name
                )));
            }
            positions.push(v);
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
        return Err(bad("it contains no triangles with non-zero area".into()));
    }
    Ok(Mesh {
        positions,
        normals: smooth.then_some(normals),
        triangles,
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
        let m = parse_obj(OCTA, Path::new("o.obj"), false).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangles.len(), 8);
        // single_index renumbers vertices in order of first use
        let first = m.triangles[0].map(|i| m.positions[i as usize]);
        assert_eq!(first, [DVec3::X, DVec3::Y, DVec3::Z]);
        assert_eq!(m.normals, None);
    }

    #[test]
    fn smooth_octahedron_computes_vertex_normals() {
        let m = parse_obj(OCTA, Path::new("o.obj"), true).unwrap();
        let n = m.normals.unwrap();
        assert_eq!(n.len(), 6);
        for (p, n) in m.positions.iter().zip(&n) {
            assert!((*p - *n).length() < 1e-12, "{p} vs {n}");
        }
    }

    #[test]
    fn file_normals_are_used_and_quads_triangulated() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 2\nf 1//1 2//1 3//1 4//1\n";
        let m = parse_obj(text, Path::new("q.obj"), true).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert_eq!(m.normals.unwrap(), vec![DVec3::Z; m.positions.len()]);
    }

    #[test]
    fn models_are_merged_and_degenerates_dropped() {
        let text = "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 2 0 1\nf 4 5 6\nf 4 5 7\n";
        let m = parse_obj(text, Path::new("m.obj"), false).unwrap();
        assert_eq!(m.positions.len(), 7);
        assert_eq!(m.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    }

    #[test]
    fn malformed_and_empty_files() {
        let e = parse_obj(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            Path::new("x.obj"),
            false,
        )
        .unwrap_err();
        assert!(e.starts_with("bad mesh x.obj: "), "{e}");
        assert!(e.contains("out of bounds"), "{e}");
        let e = parse_obj("# nothing\n", Path::new("e.obj"), false).unwrap_err();
        assert!(e.contains("no triangles"), "{e}");
        let e = load_mesh(Path::new("/nonexistent/dir/none.obj"), false).unwrap_err();
        assert!(
            e.starts_with("cannot read mesh /nonexistent/dir/none.obj: "),
            "{e}"
        );
    }
}
