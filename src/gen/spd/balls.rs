//! balls, the "sphereflake" (SPD balls.c): a sphere with nine spheres a
//! third its size on its surface, each with nine of its own, `size` times
//! over; a square floor under it and three lights. Spheres:
//! (9^(size+1) − 1)/8; one polygon.

use super::lib::*;
use crate::scene::Scene;
use std::f64::consts::PI;

pub(super) fn generate(size: u32) -> Scene {
    let mut o = Out::new(
        "balls",
        size,
        [2.1, 1.3, 1.7],
        [0.0; 3],
        [0.0, 0.0, 1.0],
        45.0,
    );
    // The radius of a sphere that would enclose the whole object.
    let radius = 1.0;
    o.light([4.0, 3.0, 2.0]);
    o.light([1.0, -4.0, 4.0]);
    o.light([-3.0, 1.0, 5.0]);
    // Floor polygon, beige.
    o.color([1.0, 0.75, 0.33], 0.2, 0.8, 0.0, 0.0, 0.0, 0.0, 1.0);
    let b = [12.0 * radius, 12.0 * radius, -radius / 2.0];
    o.polygon(&[
        [b[0], b[1], b[2]],
        [-b[0], b[1], b[2]],
        [-b[0], -b[1], b[2]],
        [b[0], -b[1], b[2]],
    ]);
    // The spheres, mirrored.
    o.color([1.0, 0.9, 0.7], 0.0, 0.5, 0.5, 0.5, 37.0, 0.0, 1.0);
    let objset = create_objset();
    output_object(
        &mut o,
        &objset,
        size,
        [0.0, 0.0, 0.0, radius / 2.0],
        [0.0, 0.0, 1.0, 1.0 / 3.0],
    );
    o.finish()
}

/// The sphere at `center` (radius in w), then its nine children:
/// `direction` is the unit vector from the parent's centre (xyz) and the
/// child-to-parent radius ratio (w).
fn output_object(o: &mut Out, objset: &[V4; 9], depth: u32, center: V4, direction: V4) {
    o.sphere(center);
    if depth == 0 {
        return;
    }
    let depth = depth - 1;
    // Rotation from +Z to the new axis (with an epsilon: a child's
    // direction can be a little shorter than 1).
    let mx = if direction[2] >= 0.9999 {
        identity()
    } else if direction[2] <= -0.9999 {
        rotate(Y_AXIS, PI)
    } else {
        let z_axis = [0.0, 0.0, 1.0];
        let mut axis = cross(z_axis, xyz(direction));
        normalize(&mut axis);
        let angle = dot(z_axis, xyz(direction)).acos();
        axis_rotate(axis, angle)
    };
    // Where the children sit, scaled down.
    let scale = center[3] * (1.0 + direction[3]);
    for set in objset {
        let mut child_pt = transform_coord(*set, &mx);
        child_pt[0] = child_pt[0] * scale + center[0];
        child_pt[1] = child_pt[1] * scale + center[1];
        child_pt[2] = child_pt[2] * scale + center[2];
        child_pt[3] = center[3] * direction[3];
        let d = sub(xyz(child_pt), xyz(center));
        let child_dir = [d[0] / scale, d[1] / scale, d[2] / scale, direction[3]];
        output_object(o, objset, depth, child_pt, child_dir);
    }
}

/// The nine directions of a sphere's children about +Z: three trios, each
/// tilted up from the equator, a third of a turn apart.
fn create_objset() -> [V4; 9] {
    let dist = 1.0 / 2.0f64.sqrt();
    let mut trio = [
        [dist, dist, 0.0, 0.0],
        [dist, 0.0, -dist, 0.0],
        [0.0, dist, -dist, 0.0],
    ];
    let mut axis = [1.0, -1.0, 0.0];
    normalize(&mut axis);
    let mx = axis_rotate(axis, (2.0 / 6.0f64.sqrt()).asin());
    for t in &mut trio {
        *t = transform_coord(*t, &mx);
    }
    let mut objset = [[0.0; 4]; 9];
    for set in 0..3 {
        let mx = rotate(Z_AXIS, set as f64 * 2.0 * PI / 3.0);
        for v in 0..3 {
            objset[set * 3 + v] = transform_coord(trio[v], &mx);
        }
    }
    objset
}
