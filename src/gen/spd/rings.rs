//! rings (SPD rings.c): objects of six pentagonal rings (cylinders joined
//! by spheres through the midpoints of a dodecahedron's edges) stacked in a
//! pyramid that the viewer looks down from its point, a wall behind it and
//! three lights. Layer k (1..=size) holds k² objects of 30 cylinders and
//! 30 spheres: 5·size·(size+1)·(2·size+1) of each, and one polygon.

use super::lib::*;
use crate::scene::Scene;
use std::f64::consts::PI;

/// Above 1, lower layers spread out more.
const SPREAD_OUT: f64 = 1.0;
/// Radius of the cylinders and spheres.
const RADIUS: f64 = 0.07412;

/// The 30 points the rings run through, scaled to fit a unit sphere: one
/// pentagon in the XY plane, five more turned onto the dodecahedron.
fn create_dodec(minor_radius: f64) -> [V3; 30] {
    let mut v = [[0.0; 3]; 30];
    let scale = 1.0 / (1.0 + minor_radius);
    for (k, p) in v.iter_mut().take(5).enumerate() {
        let a = k as f64 * 2.0 * PI / 5.0;
        *p = [scale * a.cos(), scale * a.sin(), 0.0];
    }
    // The angle between two adjacent faces of a dodecahedron.
    let x_rotation = 2.0 * ((PI / 3.0).cos() / (PI / 5.0).sin()).acos();
    let x_matrix = rotate(X_AXIS, x_rotation);
    for pentagon in 1..6 {
        let z_rotation = PI * (2.0 * (pentagon - 1) as f64 + 1.0) / 5.0;
        let z_matrix = rotate(Z_AXIS, z_rotation);
        for k in 0..5 {
            let t = transform_point(v[k], &x_matrix);
            v[5 * pentagon + k] = transform_point(t, &z_matrix);
        }
    }
    v
}

pub(super) fn generate(size: u32) -> Scene {
    let spread = 1.0 / (PI / 8.0).sin();
    let (y_diff, xz_diff) = if SPREAD_OUT <= spread {
        (spread / SPREAD_OUT, 1.0)
    } else {
        (1.0, SPREAD_OUT / spread)
    };
    let from = [-1.0, -spread, 0.5];
    let at = [from[0], from[1] + 1.0, from[2]];
    let mut o = Out::new("rings", size, from, at, [0.0, 0.0, 1.0], 45.0);
    o.light([3.0, -spread, 3.0]);
    o.light([-4.0, -spread, 1.0]);
    o.light([2.0, -spread, -4.0]);
    // The wall, white, just filling the 45° view (+1%).
    o.color([1.0, 1.0, 1.0], 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let wy = y_diff * (size + 1) as f64;
    let wx = 1.01 * (wy - from[1]) * (PI / 8.0).tan();
    let wz = wx;
    o.polygon(&[
        [wx + from[0], wy, wz + from[2]],
        [-wx + from[0], wy, wz + from[2]],
        [-wx + from[0], wy, -wz + from[2]],
        [wx + from[0], wy, -wz + from[2]],
    ]);
    // Red, green, blue and their complements.
    let ring_color = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 0.0],
    ];
    let dodec = create_dodec(RADIUS);
    for depth in 0..size as i32 {
        let oy = y_diff * (depth + 1) as f64;
        for objz in 0..=depth {
            let oz = xz_diff * (2 * objz - depth) as f64;
            for objx in 0..=depth {
                let ox = xz_diff * (2 * objx - depth) as f64;
                let offset = [ox, oy, oz];
                for elem in 0..30 {
                    let b = add(dodec[elem], offset);
                    let prev = if elem % 5 == 0 {
                        // A new ring: its colour.
                        o.color(ring_color[elem / 5], 0.0, 0.5, 0.2, 0.3, 37.0, 0.0, 0.0);
                        elem + 4
                    } else {
                        elem - 1
                    };
                    let a = add(dodec[prev], offset);
                    let base = [b[0], b[1], b[2], RADIUS];
                    o.cylcone(base, [a[0], a[1], a[2], RADIUS]);
                    o.sphere(base);
                }
            }
        }
    }
    o.finish()
}
