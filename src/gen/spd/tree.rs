//! tree (SPD tree.c): a tree grown by Aono and Kunii's method (IEEE CG&A,
//! May 1984), each branch a cone capped by a sphere and forking in two,
//! `size` times; a square field under it and seven lights. Cones and
//! spheres: 2^(size+1) − 1 each; one polygon.

use super::lib::*;
use crate::scene::Scene;
use std::f64::consts::PI;

// The shape of the tree.
const BR_ANGLE_0: f64 = 40.0;
const BR_ANGLE_1: f64 = 25.0;
const BR_CONTR_0: f64 = 0.65;
const BR_CONTR_1: f64 = 0.70;
const BR_DIAMETER: f64 = 0.67;
const DIV_ANGLE: f64 = 140.0;
const WIDTH_HEIGHT_RATIO: f64 = 0.15;

/// A branch along +Z from 0 to 1 in the frame `cur`, then its two
/// children.
fn grow_tree(o: &mut Out, rst: &[Matrix; 2], cur: &Matrix, scale: f64, depth: u32) {
    let b = transform_point([0.0, 0.0, 0.0], cur);
    let base = [b[0], b[1], b[2], scale * WIDTH_HEIGHT_RATIO];
    let a = transform_point([0.0, 0.0, 1.0], cur);
    let apex = [a[0], a[1], a[2], base[3] * BR_DIAMETER];
    o.cylcone(base, apex);
    o.sphere(apex);
    if depth > 0 {
        for m in rst {
            let next = multiply(m, cur);
            grow_tree(o, rst, &next, scale * BR_DIAMETER, depth - 1);
        }
    }
}

/// Each branch's frame relative to its parent: turned by the branching
/// angle about X and the divergence about Z, shrunk, moved to the tip.
fn branch_matrices() -> [Matrix; 2] {
    let mut rst = [zero_matrix(); 2];
    for (i, m) in rst.iter_mut().enumerate() {
        let (branch_angle, divergence, contraction) = if i == 0 {
            (BR_ANGLE_0, 90.0, BR_CONTR_0)
        } else {
            (BR_ANGLE_1, DIV_ANGLE + 90.0, BR_CONTR_1)
        };
        let t1 = rotate(X_AXIS, branch_angle * PI / 180.0);
        let t2 = rotate(Z_AXIS, divergence * PI / 180.0);
        let r = multiply(&t1, &t2);
        let mut st = identity();
        st[0][0] = contraction;
        st[1][1] = contraction;
        st[2][2] = contraction;
        st[3][2] = 1.0;
        *m = multiply(&r, &st);
    }
    rst
}

pub(super) fn generate(size: u32) -> Scene {
    let mut o = Out::new(
        "tree",
        size,
        [4.5, 0.4, 2.0],
        [0.0, 0.0, 1.5],
        [0.0, 0.0, 1.0],
        45.0,
    );
    for l in [
        [-5.0, 5.0, 50.0],
        [30.0, -30.0, 30.0],
        [-40.0, -30.0, 20.0],
        [10.0, 30.0, 40.0],
        [-30.0, 40.0, 10.0],
        [50.0, 25.0, 20.0],
        [-10.0, -60.0, 30.0],
    ] {
        o.light(l);
    }
    // The field, green.
    o.color([0.2, 0.7, 0.2], 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    o.polygon(&[
        [50.0, 50.0, 0.0],
        [-50.0, 50.0, 0.0],
        [-50.0, -50.0, 0.0],
        [50.0, -50.0, 0.0],
    ]);
    // The tree, brown.
    o.color([0.55, 0.4, 0.2], 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    grow_tree(&mut o, &branch_matrices(), &identity(), 1.0, size);
    o.finish()
}
