//! The tracer's number type and 3-vector, generic so that the f32 render
//! (the GPU's twin) and the f64 reference are one code.
//!
//! Arithmetic is written out in the same order as the shader's and never
//! fused (`mul_add` is not used: lavapipe never fuses).

use num_traits::Float;
use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub};

/// A float the tracer can run in: f32 (mirrors the GPU) or f64 (reference).
pub trait Real: Float + Debug + Default + Send + Sync + 'static {
    fn of(x: f32) -> Self;
    fn to_f32(self) -> f32;
    /// Truncation towards zero (saturating): the GLSL `int(x)` on the
    /// values the tracer converts.
    fn trunc_i32(self) -> i32;
    /// e^self: in f32 the twin [`exp_f32`] (bit for bit with the shader's
    /// `exp_twin`), in f64 the library's.
    fn exp_t(self) -> Self;
    /// self^y for self > 0: in f32 the twin [`pow_f32`], in f64 the
    /// library's.
    fn pow_t(self, y: Self) -> Self;
    /// The least value above self (self ≥ 0; +∞ stays): the shader's
    /// `next_up` (math.glsl), one more in the bit pattern.
    fn next_up_t(self) -> Self;
}

impl Real for f32 {
    #[inline(always)]
    fn of(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline(always)]
    fn trunc_i32(self) -> i32 {
        self as i32
    }
    #[inline(always)]
    fn exp_t(self) -> Self {
        exp_f32(self)
    }
    #[inline(always)]
    fn pow_t(self, y: Self) -> Self {
        pow_f32(self, y)
    }
    #[inline(always)]
    fn next_up_t(self) -> Self {
        self.next_up()
    }
}

impl Real for f64 {
    #[inline(always)]
    fn of(x: f32) -> Self {
        x as f64
    }
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline(always)]
    fn trunc_i32(self) -> i32 {
        self as i32
    }
    #[inline(always)]
    fn exp_t(self) -> Self {
        self.exp()
    }
    #[inline(always)]
    fn pow_t(self, y: Self) -> Self {
        self.powf(y)
    }
    #[inline(always)]
    fn next_up_t(self) -> Self {
        self.next_up()
    }
}

// exp and log in f32 from +, −, ×, ÷, floor and bit moves alone (Cephes'
// expf and logf: Moshier's minimax polynomials), so that the CPU and the
// shader (math.glsl: exp_twin, log_twin, pow_twin) agree bit for bit on a
// device that rounds IEEE and does not fuse, as lavapipe does. The
// driver's exp and pow differ from any libm by a few ULP (docs/gpu.md).

const LOG2E: f32 = std::f32::consts::LOG2_E;
/// ln 2 = LN2_HI + LN2_LO, LN2_HI with 9 significant bits so that k·LN2_HI
/// is exact for |k| < 2^15.
const LN2_HI: f32 = 0.693_359_4;
const LN2_LO: f32 = -2.121_944_4e-4;

/// e^z, relative error under 2e-7 on (−87, 88); 0 below (no subnormals:
/// GPUs may flush them), +∞ above, NaN for NaN.
#[inline(always)]
pub fn exp_f32(z: f32) -> f32 {
    if z.is_nan() {
        return z;
    }
    if z <= -87.0 {
        return 0.0;
    }
    if z >= 88.0 {
        return f32::INFINITY;
    }
    let k = (z * LOG2E + 0.5).floor();
    let x = z - k * LN2_HI - k * LN2_LO;
    let z2 = x * x;
    let p = ((((0.000_198_756_91 * x + 0.001_398_199_9) * x + 0.008_333_452) * x + 0.041_665_796)
        * x
        + 0.166_666_66)
        * x
        + 0.5;
    let y = p * z2 + x + 1.0;
    // 2^k, k in [−126, 127].
    y * f32::from_bits(((k as i32 + 127) as u32) << 23)
}

/// ln x for x > 0, relative error under 2e-7; subnormals are taken as the
/// smallest normal (their logarithm then errs by less than 1e-6 relative,
/// and pow of them is 0 or 1 in f32 anyway). ln 0 = −∞, ln of a negative
/// number or NaN is NaN.
#[inline(always)]
pub fn log_f32(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x == 0.0 {
        return f32::NEG_INFINITY;
    }
    if x == f32::INFINITY {
        return x;
    }
    let x = x.max(f32::MIN_POSITIVE);
    let bits = x.to_bits();
    // x = m · 2^e with m in [0.5, 1).
    let mut e = ((bits >> 23) & 0xff) as i32 - 126;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f00_0000);
    if m < std::f32::consts::FRAC_1_SQRT_2 {
        e -= 1;
        m = m + m - 1.0;
    } else {
        m -= 1.0;
    }
    let z = m * m;
    let p = (((((((0.070_376_836 * m - 0.115_146_1) * m + 0.116_769_984) * m - 0.124_201_41)
        * m
        + 0.142_493_23)
        * m
        - 0.166_680_57)
        * m
        + 0.200_007_14)
        * m
        - 0.249_999_94)
        * m
        + 0.333_333_3;
    let fe = e as f32;
    let mut y = p * m * z;
    y += LN2_LO * fe;
    y += -0.5 * z;
    let r = m + y;
    r + LN2_HI * fe
}

/// x^y for x > 0 as e^(y·ln x): what the shading's highlights need
/// (x a cosine in (0, 1], y a shininess ≥ 0).
#[inline(always)]
pub fn pow_f32(x: f32, y: f32) -> f32 {
    exp_f32(y * log_f32(x))
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3<F> {
    pub x: F,
    pub y: F,
    pub z: F,
}

#[inline(always)]
pub fn v3<F>(x: F, y: F, z: F) -> V3<F> {
    V3 { x, y, z }
}

impl<F: Real> V3<F> {
    #[inline(always)]
    pub fn zero() -> Self {
        v3(F::zero(), F::zero(), F::zero())
    }
    #[inline(always)]
    pub fn splat(s: F) -> Self {
        v3(s, s, s)
    }
    /// The xyz of a packed vec4.
    #[inline(always)]
    pub fn of(a: &[f32; 4]) -> Self {
        v3(F::of(a[0]), F::of(a[1]), F::of(a[2]))
    }
    #[inline(always)]
    pub fn dot(self, o: Self) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        v3(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    #[inline(always)]
    pub fn length(self) -> F {
        self.dot(self).sqrt()
    }
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self / self.length()
    }
    /// The unit vector along `self` where `normalize` fails: scaled by
    /// its largest component first, so that a length whose square
    /// underflows or overflows still gives the direction; an infinite
    /// component gives the axis it lies on; zero (or a subnormal) or a
    /// NaN gives +z (no direction to keep; any unit vector is a finite
    /// answer). For
    /// gradients (a quadric's normal): the pack fuzz target found one
    /// whose squared length underflowed to zero, and a pixel came out
    /// infinite. Twin: `direction3` in math.glsl.
    pub fn direction(self) -> Self {
        let (x, y, z) = (self.x, self.y, self.z);
        if x.is_nan() || y.is_nan() || z.is_nan() {
            return v3(F::zero(), F::zero(), F::one());
        }
        if x.is_infinite() || y.is_infinite() || z.is_infinite() {
            let s = |c: F| {
                if c.is_infinite() {
                    c.signum()
                } else {
                    F::zero()
                }
            };
            return v3(s(x), s(y), s(z)).normalize();
        }
        // Below the least normal f32, as zero: a device that flushes
        // subnormals (lavapipe) sees zero there.
        let m = x.abs().max(y.abs()).max(z.abs());
        if m < F::of(f32::MIN_POSITIVE) {
            return v3(F::zero(), F::zero(), F::one());
        }
        (self / m).normalize()
    }
    #[inline(always)]
    pub fn mul_elem(self, o: Self) -> Self {
        v3(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    #[inline(always)]
    pub fn max_elem(self) -> F {
        self.x.max(self.y).max(self.z)
    }
    #[inline(always)]
    pub fn get(self, i: usize) -> F {
        // An array index, not a match: a runtime axis must not become a
        // jump table in the inner loops.
        [self.x, self.y, self.z][i]
    }
    #[inline(always)]
    pub fn map(self, f: impl Fn(F) -> F) -> Self {
        v3(f(self.x), f(self.y), f(self.z))
    }
    pub fn to_f32(self) -> [f32; 3] {
        [self.x.to_f32(), self.y.to_f32(), self.z.to_f32()]
    }
}

impl<F: Real> Add for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        v3(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<F: Real> AddAssign for V3<F> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<F: Real> Sub for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        v3(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<F: Real> Neg for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        v3(-self.x, -self.y, -self.z)
    }
}
impl<F: Real> Mul<F> for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: F) -> Self {
        v3(self.x * s, self.y * s, self.z * s)
    }
}
impl<F: Real> MulAssign<F> for V3<F> {
    #[inline(always)]
    fn mul_assign(&mut self, s: F) {
        *self = *self * s;
    }
}
impl<F: Real> Div<F> for V3<F> {
    type Output = Self;
    #[inline(always)]
    fn div(self, s: F) -> Self {
        v3(self.x / s, self.y / s, self.z / s)
    }
}

/// A ray; `d` is unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray<F> {
    pub o: V3<F>,
    pub d: V3<F>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `direction` gives a unit vector where `normalize` gives infinities
    /// or NaNs: lengths whose square underflows or overflows, infinite
    /// components, zero, subnormals and NaNs; elsewhere `normalize`'s
    /// direction.
    #[test]
    fn direction_survives_what_normalize_does_not() {
        let unit = |v: V3<f32>| {
            let l = v.length();
            v.x.is_finite() && v.y.is_finite() && v.z.is_finite() && (l - 1.0).abs() < 1e-6
        };
        let tiny = v3(3e-25f32, -4e-25, 0.0);
        assert!(!unit(tiny.normalize()), "the case is one normalize fails");
        let d = tiny.direction();
        assert!(
            unit(d) && (d.x - 0.6).abs() < 1e-6 && (d.y + 0.8).abs() < 1e-6,
            "{d:?}"
        );
        let huge = v3(3e30f32, 4e30, 0.0);
        assert!(!unit(huge.normalize()));
        assert!(unit(huge.direction()) && (huge.direction().x - 0.6).abs() < 1e-6);
        let inf = v3(f32::NEG_INFINITY, 1.0, f32::INFINITY);
        let d = inf.direction();
        assert!(unit(d) && d.x < 0.0 && d.y == 0.0 && d.z > 0.0, "{d:?}");
        for v in [
            v3(0.0f32, 0.0, 0.0),
            v3(1e-40, 0.0, -1e-41),
            v3(f32::NAN, 1.0, 0.0),
        ] {
            assert_eq!(v.direction(), v3(0.0, 0.0, 1.0), "{v:?}");
        }
        let plain = v3(1.0f32, -2.0, 2.0);
        let d = plain.direction();
        assert!(unit(d) && (d.x - 1.0 / 3.0).abs() < 1e-6 && (d.y + 2.0 / 3.0).abs() < 1e-6);
    }

    fn rel(a: f32, b: f64) -> f64 {
        ((a as f64 - b) / b).abs()
    }

    #[test]
    fn exp_twin_is_within_two_ulp_of_the_true_value() {
        let mut worst = 0.0f64;
        let n = 200_000;
        for i in 0..=n {
            let z = -86.9 + 174.8 * i as f64 / n as f64;
            let z = z as f32;
            worst = worst.max(rel(exp_f32(z), (z as f64).exp()));
        }
        assert!(worst < 2.5e-7, "exp: worst relative error {worst:e}");
        assert_eq!(exp_f32(0.0), 1.0);
        assert_eq!(exp_f32(-90.0), 0.0);
        assert_eq!(exp_f32(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_f32(100.0), f32::INFINITY);
        assert!(exp_f32(f32::NAN).is_nan());
    }

    #[test]
    fn log_and_pow_twins_are_accurate_where_shading_uses_them() {
        let mut worst = 0.0f64;
        for i in 1..=100_000u32 {
            let x = i as f32 / 100_000.0 * 4.0;
            let t = (x as f64).ln();
            if t.abs() > 1e-3 {
                worst = worst.max(rel(log_f32(x), t));
            } else {
                // Near 1 the logarithm is small: absolute error.
                assert!((log_f32(x) as f64 - t).abs() < 1e-9, "{x}");
            }
        }
        assert!(worst < 2.5e-7, "log: worst relative error {worst:e}");
        assert_eq!(log_f32(1.0), 0.0);
        assert_eq!(log_f32(0.0), f32::NEG_INFINITY);
        assert!(log_f32(-1.0).is_nan());
        assert!((log_f32(1e-40) - (f32::MIN_POSITIVE as f64).ln() as f32).abs() < 1e-5);
        // Highlights: cosines in (0, 1], exponents up to 10 000. The error
        // grows with |y·ln x| (as for any pow); visible values (> 1e-6)
        // stay within 3e-6 relative.
        let mut worst = 0.0f64;
        for i in 1..=2000u32 {
            let x = i as f32 / 2000.0;
            for y in [0.0f32, 1.0, 2.5, 10.0, 40.0, 200.0, 1000.0, 10_000.0] {
                let t = (x as f64).powf(y as f64);
                let p = pow_f32(x, y);
                if t > 1e-6 {
                    worst = worst.max(rel(p, t));
                } else {
                    assert!(p < 2e-6, "{x}^{y} = {p}");
                }
            }
        }
        assert!(worst < 3e-6, "pow: worst relative error {worst:e}");
        assert_eq!(pow_f32(1.0, 200.0), 1.0);
        assert_eq!(pow_f32(0.5, 0.0), 1.0);
        assert_eq!(pow_f32(0.5, 1.0), 0.5);
    }
}
