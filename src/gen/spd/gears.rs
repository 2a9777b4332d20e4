//! gears (SPD gears.c): size³ meshed gears over a reflective square, five
//! lights. Each gear has 36 teeth: a top and a bottom face of 144 vertices
//! each (concave) and 144 rectangles round its edge; one gear in five is
//! transparent. Polygons: 146 · size³ + 1.

use super::lib::*;
use crate::scene::Scene;
use std::f64::consts::PI;

/// Teeth on a gear (a multiple of 4).
const TEETH: usize = 36;
/// The outer radius is a little short of the full one, so that meshing
/// gears never touch.
const OUTER_EDGE_RATIO: f64 = 0.995;
const INNER_EDGE_RATIO: f64 = 0.9;
/// Width of a gear against its thickness.
const DEPTH_RATIO: f64 = 0.1;

fn edge_diff() -> f64 {
    1.0 - INNER_EDGE_RATIO
}

/// The four corners of one tooth.
fn create_tooth(gear_angle: f64, tooth_angle: f64, center: V3, outer: V3, inner: V3) -> [V3; 4] {
    let at = |angle: f64, p: V3| add(transform_vector(p, &rotate(Z_AXIS, angle)), center);
    [
        at(gear_angle - 0.19 * tooth_angle, outer),
        at(gear_angle + 0.19 * tooth_angle, outer),
        at(gear_angle + 0.3 * tooth_angle, inner),
        at(gear_angle + 0.7 * tooth_angle, inner),
    ]
}

fn create_gear(
    o: &mut Out,
    center: V3,
    offset_angle: f64,
    outer_radius: f64,
    inner_radius: f64,
    thickness: f64,
) {
    let mut outer = [outer_radius, 0.0, 0.0];
    let mut inner = [inner_radius, 0.0, 0.0];
    let tooth_angle = 2.0 * PI / TEETH as f64;
    let mut pts = [[0.0; 3]; 4 * TEETH];
    // Top face.
    for t in 0..TEETH {
        let gear_angle = offset_angle + 2.0 * PI * t as f64 / TEETH as f64;
        let tooth = create_tooth(gear_angle, tooth_angle, center, outer, inner);
        pts[t * 4..t * 4 + 4].copy_from_slice(&tooth);
    }
    o.polygon(&pts);
    // The teeth's sides.
    for s in 0..4 * TEETH {
        let next = (s + 1) % (4 * TEETH);
        let mut side = [pts[s], pts[s], pts[next], pts[next]];
        side[1][2] -= thickness;
        side[2][2] -= thickness;
        o.polygon(&side);
    }
    // Bottom face, the other way round.
    outer[2] = -thickness;
    inner[2] = -thickness;
    for t in 0..TEETH {
        let gear_angle = offset_angle - 2.0 * PI * t as f64 / TEETH as f64;
        let tooth = create_tooth(gear_angle, -tooth_angle, center, outer, inner);
        pts[t * 4..t * 4 + 4].copy_from_slice(&tooth);
    }
    o.polygon(&pts);
}

/// `FRACTION`: the part after the point (of a non-negative number).
fn fraction(a: f64) -> f64 {
    a - (a as i32) as f64
}

pub(super) fn generate(size: u32) -> Scene {
    let mut o = Out::new(
        "gears",
        size,
        [-1.1, -2.1, 2.6],
        [0.0; 3],
        [0.0, 0.0, 1.0],
        45.0,
    );
    o.light([2.0, 4.0, 4.0]);
    o.light([-2.0, 4.0, 3.0]);
    o.light([2.0, -2.5, 2.5]);
    o.light([-1.0, -4.0, 2.0]);
    // Just behind the eye.
    o.light([-1.111, -2.121, 2.626]);
    // Ground polygon, off-white and reflective.
    o.color([1.0, 0.85, 0.7], 0.0, 0.3, 0.6, 0.3, 37.0, 0.0, 0.0);
    o.polygon(&[
        [2.0, 2.0, 0.0],
        [-2.0, 2.0, 0.0],
        [-2.0, -2.0, 0.0],
        [2.0, -2.0, 0.0],
    ]);
    let sf = size as f64;
    let outer_radius = 1.0 / (sf - (size - 1) as f64 * edge_diff() / 2.0);
    let zero = [-1.0 + outer_radius, -1.0 + outer_radius, 1.0];
    let off = outer_radius * (2.0 - edge_diff());
    let offset = [off, off, -1.0 / sf];
    for iz in 0..size as i32 {
        let cz = zero[2] + iz as f64 * offset[2];
        for iy in 0..size as i32 {
            let cy = zero[1] + iy as f64 * offset[1];
            for ix in 0..size as i32 {
                let cx = zero[0] + ix as f64 * offset[0];
                // A pseudo-random colour, its largest channel 1.
                let mut c = [
                    0.01 + fraction((ix * 3 + iy * 2 + iz + 1) as f64 * 5.0 / 7.0),
                    0.01 + fraction((iy * 3 + iz * 2 + ix + 1) as f64 * 3.0 / 7.0),
                    0.01 + fraction((iz * 3 + ix * 2 + iy + 1) as f64 * 2.0 / 7.0),
                ];
                let m = if c[0] > c[1] { c[0] } else { c[1] };
                let m = if m > c[2] { m } else { c[2] };
                for x in &mut c {
                    *x /= m;
                }
                if (ix * 4 + iy * 2 + iz) % 5 == 0 {
                    o.color(c, 0.0, 0.2, 0.0, 0.0, 0.0, 0.8, 1.1);
                } else {
                    o.color(c, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
                }
                let angle = PI * ((ix + iy + iz) % 2) as f64 / TEETH as f64;
                let half = 1.0 / (2.0 * sf);
                let thickness = if DEPTH_RATIO < half {
                    DEPTH_RATIO
                } else {
                    half
                };
                create_gear(
                    &mut o,
                    [cx, cy, cz],
                    angle,
                    OUTER_EDGE_RATIO * outer_radius,
                    (1.0 - edge_diff()) * outer_radius,
                    thickness,
                );
            }
        }
    }
    o.finish()
}
