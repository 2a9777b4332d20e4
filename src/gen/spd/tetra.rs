//! tetra (SPD tetra.c): a recursive tetrahedral pyramid (the scene of
//! Glassner 1984 and Kay & Kajiya 1986), one light; mostly background.
//! Triangles: 4^size.

use super::lib::*;
use crate::scene::Scene;

/// A tetrahedron in the cube of half-side `c[3]` about `c`: four faces at
/// depth 1, else four tetrahedra half the size at alternate corners.
fn create_tetra(o: &mut Out, depth: u32, c: V4) {
    let corners = || {
        let mut v = Vec::with_capacity(4);
        for x in [-1.0f64, 1.0] {
            for y in [-1.0f64, 1.0] {
                for z in [-1.0f64, 1.0] {
                    if x * y * z == 1.0 {
                        v.push([x, y, z]);
                    }
                }
            }
        }
        v
    };
    if depth <= 1 {
        let p: Vec<V3> = corners()
            .into_iter()
            .map(|[x, y, z]| [c[0] + x * c[3], c[1] + y * c[3], c[2] + z * c[3]])
            .collect();
        // Faces 0 1 2, 3 2 1, 2 3 0, 1 0 3.
        for face in 0..4 {
            let mut ord = [0, 1, 2].map(|k| (face + k) % 4);
            if face % 2 == 1 {
                ord.swap(0, 2);
            }
            o.polygon(&ord.map(|k| p[k]));
        }
    } else {
        for [x, y, z] in corners() {
            let sub = [
                c[0] + x * c[3] / 2.0,
                c[1] + y * c[3] / 2.0,
                c[2] + z * c[3] / 2.0,
                c[3] / 2.0,
            ];
            create_tetra(o, depth - 1, sub);
        }
    }
}

pub(super) fn generate(size: u32) -> Scene {
    let mut o = Out::new(
        "tetra",
        size,
        [1.022846, -3.177154, -2.174512],
        [-0.004103, -0.004103, 0.216539],
        [-0.816497, -0.816497, 0.816497],
        45.0,
    );
    o.light([2.0, -18.0, -5.0]);
    // Red.
    o.color([1.0, 0.2, 0.2], 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    create_tetra(&mut o, size, [0.0, 0.0, 0.0, 1.0]);
    o.finish()
}
