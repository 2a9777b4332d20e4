//! mount (SPD mount.c): a fractal mountain by Carpenter's midpoint
//! subdivision on a square grid, with a pyramid of four glass spheres in
//! front of it and one light. Triangles: 2 · 4^size; four spheres.
//!
//! The heights come from the SPD's own hash and Gaussian generator
//! (`hash_rand`, `lib::gauss_rand`), so the mountain is the original's
//! point for point. The hash is the SPD's old one, which repeats at low
//! resolutions: its author kept it "for consistency with previously
//! published results", and so do we.

use super::lib::*;
use crate::scene::Scene;
use std::f64::consts::PI;

/// Fractal dimension, between 2 and 3: the variance of the heights.
const FRACTAL_DIMENSION: f64 = 2.2;
/// Which mountain.
const MOUNTAIN_NO: i64 = 21;
/// Lower-left corner and width of the mountain's square.
const X_CORNER: f64 = -1.0;
const Y_CORNER: f64 = -1.0;
const WIDTH: f64 = 2.0;
/// The SPD's √2 for the middle point's rise: its literal, not `SQRT_2`
/// (they differ in the eighth digit, and so would the mountain).
#[allow(clippy::approx_constant)]
const SQRT_2_SPD: f64 = 1.4142136;

/// `shl` as the C's `(unsigned long)a << n` computes it on x86-64 once
/// masked by 0xffff: a negative `n` (the C leaves it undefined; it happens
/// only above size 7) shifts by n mod 64 ≥ 48, leaving no low bits.
fn shl(a: u64, n: i32) -> u64 {
    if n < 0 {
        0
    } else {
        a << n
    }
}

/// The SPD's original hash of a grid point and the size: the seed of its
/// height's random number.
fn hash_rand(a: u32, b: u32, c: u32) -> i64 {
    let (a, b, c) = (a as u64, b as u64, c as i32);
    (shl(a, 23 - c)
        .wrapping_add(shl(b, 15 - c))
        .wrapping_add(shl(a, 7 - c))
        & 0xffff) as i64
}

struct Mountain {
    size: u32,
    fnum_pts: f64,
    roughness: f64,
}

impl Mountain {
    fn gauss(&self, a: u32, b: u32) -> f64 {
        gauss_rand(MOUNTAIN_NO + hash_rand(a, b, self.size))
    }

    /// One square of the grid: split in four while `width` > 1, else two
    /// triangles. Heights at its lower-left, lower-right, upper-right and
    /// upper-left corners.
    fn grow(&self, o: &mut Out, width: u32, ll_x: u32, ll_y: u32, z: [f64; 4]) {
        let [ll, lr, ur, ul] = z;
        if width == 1 {
            let f = self.fnum_pts;
            let l_fx = X_CORNER + ll_x as f64 * WIDTH / f;
            let r_fx = X_CORNER + (ll_x + 1) as f64 * WIDTH / f;
            let l_fy = Y_CORNER + ll_y as f64 * WIDTH / f;
            let u_fy = Y_CORNER + (ll_y + 1) as f64 * WIDTH / f;
            let corners = [
                [l_fx, l_fy, ll],
                [r_fx, l_fy, lr],
                [r_fx, u_fy, ur],
                [l_fx, u_fy, ul],
            ];
            for tri in 0..2 {
                let v = [0, 1, 2].map(|k| corners[(k + tri * 2) % 4]);
                o.polygon(&v);
            }
            return;
        }
        let half = width >> 1;
        let hside = half as f64 * WIDTH / self.fnum_pts;
        let rise = hside * self.roughness;
        let lower = (ll + lr) / 2.0 + rise * self.gauss(ll_x + half, ll_y);
        let right = (lr + ur) / 2.0 + rise * self.gauss(ll_x + width, ll_y + half);
        let upper = (ur + ul) / 2.0 + rise * self.gauss(ll_x + half, ll_y + width);
        let left = (ul + ll) / 2.0 + rise * self.gauss(ll_x, ll_y + half);
        let middle =
            (ll + lr + ur + ul) / 4.0 + SQRT_2_SPD * rise * self.gauss(ll_x + half, ll_y + half);
        self.grow(o, half, ll_x, ll_y, [ll, lower, middle, left]);
        self.grow(o, half, ll_x + half, ll_y, [lower, lr, right, middle]);
        self.grow(
            o,
            half,
            ll_x + half,
            ll_y + half,
            [middle, right, ur, upper],
        );
        self.grow(o, half, ll_x, ll_y + half, [left, middle, upper, ul]);
    }
}

/// The pyramid of four spheres (radius `center[3]`) standing on `center`.
fn create_spheres(o: &mut Out, center: V4) {
    let mut axis = [1.0, 1.0, 0.0];
    normalize(&mut axis);
    let angle = (-1.0f64 / 3.0).acos();
    // The top sphere.
    let pt = [0.0, 0.0, center[3] * (3.0f64 / 2.0).sqrt()];
    let mut sphere = center;
    sphere[0] += pt[0];
    sphere[1] += pt[1];
    sphere[2] += pt[2];
    o.sphere(sphere);
    // The three below it.
    let new_pt = transform_vector(pt, &axis_rotate(axis, angle));
    for i in 0..3 {
        let mx = rotate(Z_AXIS, i as f64 * 2.0 * PI / 3.0);
        let p = add(transform_vector(new_pt, &mx), xyz(center));
        o.sphere([p[0], p[1], p[2], sphere[3]]);
    }
}

pub(super) fn generate(size: u32) -> Scene {
    let mut o = Out::new(
        "mount",
        size,
        [-1.6, 1.6, 1.7],
        [0.0; 3],
        [0.0, 0.0, 1.0],
        45.0,
    );
    o.light([-100.0, -100.0, 100.0]);
    // Crystal spheres, clear white.
    o.color([1.0, 1.0, 1.0], 0.0, 0.1, 0.1, 0.4, 6.7, 0.9, 1.5);
    create_spheres(&mut o, [-0.8, 0.8, 1.0, 0.17]);
    // The mountain, grey.
    o.color([0.5, 0.45, 0.35], 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let num_pts = 1u32 << size;
    let ratio = 2.0 / (2.0f64.ln() / (FRACTAL_DIMENSION - 1.0)).exp();
    let m = Mountain {
        size,
        fnum_pts: num_pts as f64,
        roughness: (ratio * ratio - 1.0).sqrt(),
    };
    m.grow(&mut o, num_pts, 0, 0, [0.0; 4]);
    o.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_old_hash() {
        // ((a << 17) + (b << 9) + (a << 1)) & 0xffff at size 6.
        assert_eq!(
            hash_rand(3, 5, 6),
            ((3 << 17) + (5 << 9) + (3 << 1)) & 0xffff
        );
        assert_eq!(hash_rand(32, 0, 6), 64);
        // Above size 7 the third term drops out.
        assert_eq!(hash_rand(1, 1, 9), ((1 << 14) + (1 << 6)) & 0xffff);
    }
}
