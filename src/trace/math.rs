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
