//! Sampling: the counter-based hash and eye-ray directions. Twin of
//! `shaders/sample.glsl`; integer arithmetic, so both sides agree exactly.

use super::math::{Real, V3};
use crate::pack::layout::Globals;

/// lowbias32 (Chris Wellons): a 32-bit integer hash with good avalanche.
#[inline(always)]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A reproducible number in [0, 1) for (pixel, sample, dimension).
#[inline(always)]
pub fn rand01(pixel: u32, sample: u32, dim: u32) -> f32 {
    let h = hash(pixel ^ hash(sample.wrapping_mul(2).wrapping_add(dim) ^ 0x9e37_79b9));
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Position of sample `s` inside pixel (px, py), in pixel units from the
/// image's top-left corner: the centre, or a jittered stratum of an
/// `nx × ny` grid.
#[inline(always)]
pub fn sample_pos(g: &Globals, px: u32, py: u32, s: u32) -> (f32, f32) {
    if g.image[3] == crate::constants::SAMPLING_JITTER {
        let (nx, ny) = (g.trace[2], g.trace[3]);
        let pixel = py * g.image[0] + px;
        let sx = (s % nx) as f32 + rand01(pixel, s, 0);
        let sy = (s / nx) as f32 + rand01(pixel, s, 1);
        (px as f32 + sx / nx as f32, py as f32 + sy / ny as f32)
    } else {
        (px as f32 + 0.5, py as f32 + 0.5)
    }
}

/// Unit direction of the eye ray through image position (x, y) (pixel
/// units; (0, 0) is the top-left corner, (width, height) the bottom-right).
#[inline(always)]
pub fn eye_dir<F: Real>(g: &Globals, x: f32, y: f32) -> V3<F> {
    let sx = x / g.image[0] as f32 * 2.0 - 1.0;
    let sy = 1.0 - y / g.image[1] as f32 * 2.0;
    let f = V3::<F>::of(&g.cam_forward);
    let r = V3::<F>::of(&g.cam_right);
    let u = V3::<F>::of(&g.cam_up);
    (f + r * F::of(sx) + u * F::of(sy)).normalize()
}

/// Strata for `spp` samples: nx × ny = spp, as close to square as the
/// divisors of spp allow (nx ≥ ny; a prime spp gives spp × 1).
pub fn strata(spp: u32) -> (u32, u32) {
    let spp = spp.max(1);
    let mut ny = (spp as f64).sqrt().floor() as u32;
    while ny > 1 && !spp.is_multiple_of(ny) {
        ny -= 1;
    }
    (spp / ny.max(1), ny.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strata_cover_spp() {
        for spp in 1..100 {
            let (nx, ny) = strata(spp);
            assert_eq!(nx * ny, spp);
            assert!(nx >= ny);
        }
        assert_eq!(strata(16), (4, 4));
        assert_eq!(strata(8), (4, 2));
    }

    #[test]
    fn rand_is_uniform_enough() {
        let n = 100_000;
        let mut buckets = [0u32; 10];
        for i in 0..n {
            let r = rand01(i, 3, 0);
            assert!((0.0..1.0).contains(&r));
            buckets[(r * 10.0) as usize] += 1;
        }
        for b in buckets {
            assert!((b as i64 - 10_000).abs() < 500, "{buckets:?}");
        }
        assert_ne!(rand01(5, 0, 0), rand01(5, 0, 1));
        assert_ne!(rand01(5, 0, 0), rand01(5, 1, 0));
    }
}
