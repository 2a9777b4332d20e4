//! Every check on scene values, shared by the TOML, NFF and OBJ readers.
//!
//! [`Quantity`] constants form one table: each scene quantity, its valid
//! range and so its message. Both readers check a value through the same
//! row, so the same bad value gives the same message in both formats; only
//! the location differs. [`scene_limits`] runs after parsing and checks what
//! depends on the whole scene: the packer works camera-relative in f32
//! (`src/pack/mod.rs`), so a value that survives f64 can still overflow,
//! underflow or vanish there. The table and the rules are documented in
//! `docs/scene-format.md` ("Valid values" and "f32 limits"); a test below
//! keeps the two in step.
//!
//! Each check returns a message without a location; the reader attaches the
//! position of the offending value.

use super::{Scene, Shape};
use glam::DVec3;

/// Relative tolerance for polygon planarity: every vertex must lie within
/// `PLANARITY_TOLERANCE × (largest extent of the polygon)` of its plane.
pub(crate) const PLANARITY_TOLERANCE: f64 = 1e-4;

/// Relative tolerance below which an area counts as zero:
/// `area ≤ AREA_TOLERANCE × extent²`.
pub(crate) const AREA_TOLERANCE: f64 = 1e-12;

/// Largest accepted image width or height.
pub(crate) const MAX_IMAGE_SIZE: i64 = 65536;

/// Most vertices of one polygon: the packer stores the count as an f32,
/// exact up to 2²⁴.
pub(crate) const MAX_POLYGON_VERTICES: usize = 1 << 24;

/// Largest magnitude of a length, a camera-relative coordinate, an index of
/// refraction or an absorption coefficient: squares and dot products of
/// three such values (≤ 3·10³⁶) stay below f32's 3.4·10³⁸.
pub const MAX_MAGNITUDE: f64 = 1e18;

/// Smallest non-zero length (radius, size of a primitive, length of a
/// direction) or index of refraction: squares stay normal f32 numbers
/// (≥ 10⁻³⁶ > f32::MIN_POSITIVE ≈ 1.2·10⁻³⁸).
pub const MIN_MAGNITUDE: f64 = 1e-18;

/// Largest colour component, light intensity or shading coefficient (other
/// than k_r and k_t). A shaded value is at most a product of three such
/// factors (light × colour × coefficient) per light, and the ray tree of
/// `MAX_DEPTH_LIMIT` = 16 generations sums at most 2¹⁷ of them: 10¹⁸ · 7 ·
/// 2¹⁷ · lights stays below f32::MAX for up to 10¹⁴ lights.
pub const MAX_FACTOR: f64 = 1e6;

/// Largest Phong exponent: with n ≤ 10⁶ the highlight (cos θ)ⁿ is still
/// wider than the f32 resolution of cos θ near 1, and (1 + 10⁻⁶)ⁿ ≤ e keeps
/// a cosine rounded above 1 from blowing up.
pub const MAX_EXPONENT: f64 = 1e6;

/// A primitive vanishes in f32 when its size is below this fraction of its
/// distance from the camera (2⁻²⁰ ≈ 9.5·10⁻⁷: 8 to 16 f32 units in the last
/// place of its coordinates). `docs/scene-format.md`, "f32 limits".
pub const MIN_SIZE_REL: f64 = 1.0 / 1_048_576.0;

/// The range of one quantity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Range {
    /// Any finite number: coordinates (their camera-relative limit is a
    /// scene-wide check) and quadric coefficients.
    Finite,
    /// `0 ..= MAX_FACTOR`: colours, intensities, shading coefficients.
    Factor,
    /// `0 ..= 1`: the ray tree's weights k_r, k_t (a surface cannot pass on
    /// more than it receives, and weights above 1 grow with every bounce).
    Fraction,
    /// `0 ..= MAX_EXPONENT`: Phong exponents.
    Exponent,
    /// `MIN_MAGNITUDE ..= MAX_MAGNITUDE`: radii, the index of refraction.
    Positive,
    /// `0 ..= MAX_MAGNITUDE`: absorption.
    NonNegative,
    /// 0, or `MIN_MAGNITUDE ..= MAX_MAGNITUDE`: fall-off coefficients.
    ZeroOrPositive,
    /// 0, or a magnitude in `MIN_MAGNITUDE ..= MAX_MAGNITUDE` of either
    /// sign: cone radii (negative = inside visible).
    SignedLength,
    /// A vector used as a direction: finite, its largest component's
    /// magnitude in `MIN_MAGNITUDE ..= MAX_MAGNITUDE`.
    Direction,
    /// The vertical field of view: `0 < x < 180` degrees.
    Fov,
}

/// One row of the table: a scene quantity, named as in messages (the TOML
/// key; `docs/scene-format.md` maps NFF fields to these names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Quantity {
    pub name: &'static str,
    pub range: Range,
}

const fn q(name: &'static str, range: Range) -> Quantity {
    Quantity { name, range }
}

use Range::*;

pub(crate) const FROM: Quantity = q("camera.from", Finite);
pub(crate) const AT: Quantity = q("camera.at", Finite);
pub(crate) const UP: Quantity = q("camera.up", Direction);
pub(crate) const FOV: Quantity = q("camera.fov", Fov);
pub(crate) const HITHER: Quantity = q("hither", Finite);
pub(crate) const BACKGROUND: Quantity = q("background", Factor);
pub(crate) const AMBIENT: Quantity = q("ambient", Factor);
pub(crate) const LIGHT_POSITION: Quantity = q("light position", Finite);
pub(crate) const LIGHT_COLOR: Quantity = q("light color", Factor);
pub(crate) const FALLOFF: Quantity = q("falloff", ZeroOrPositive);
pub(crate) const COLOR: Quantity = q("color", Factor);
pub(crate) const KA: Quantity = q("ka", Factor);
pub(crate) const KD: Quantity = q("kd", Factor);
pub(crate) const KS: Quantity = q("ks", Factor);
pub(crate) const SHINE: Quantity = q("shine", Exponent);
pub(crate) const KST: Quantity = q("kst", Factor);
pub(crate) const SHINE_T: Quantity = q("shine_t", Exponent);
pub(crate) const KR: Quantity = q("kr", Fraction);
pub(crate) const KT: Quantity = q("kt", Fraction);
/// NFF's `Ks` is both k_s and k_r, so it has k_r's range.
pub(crate) const NFF_KS: Quantity = q("Ks (ks and kr)", Fraction);
pub(crate) const IOR: Quantity = q("ior", Positive);
pub(crate) const ABSORPTION: Quantity = q("absorption", NonNegative);
pub(crate) const CENTER: Quantity = q("center", Finite);
pub(crate) const RADIUS: Quantity = q("radius", Positive);
pub(crate) const POINT: Quantity = q("point", Finite);
pub(crate) const NORMAL: Quantity = q("normal", Direction);
pub(crate) const VERTEX: Quantity = q("vertex", Finite);
pub(crate) const VERTEX_NORMAL: Quantity = q("vertex normal", Direction);
pub(crate) const MIN: Quantity = q("min", Finite);
pub(crate) const MAX: Quantity = q("max", Finite);
pub(crate) const COEFFICIENT: Quantity = q("quadric coefficient", Finite);
pub(crate) const CLIP_MIN: Quantity = q("clip.min", Finite);
pub(crate) const CLIP_MAX: Quantity = q("clip.max", Finite);
pub(crate) const BASE: Quantity = q("base", Finite);
pub(crate) const APEX: Quantity = q("apex", Finite);
pub(crate) const BASE_RADIUS: Quantity = q("base_radius", SignedLength);
pub(crate) const APEX_RADIUS: Quantity = q("apex_radius", SignedLength);
pub(crate) const CYLINDER_RADIUS: Quantity = q("cylinder radius", SignedLength);
pub(crate) const MESH_POSITION: Quantity = q("mesh position", Finite);
pub(crate) const MESH_NORMAL: Quantity = q("mesh normal", Direction);

/// Every row, for the documentation test.
#[cfg(test)]
pub(crate) const TABLE: &[Quantity] = &[
    FROM,
    AT,
    UP,
    FOV,
    HITHER,
    BACKGROUND,
    AMBIENT,
    LIGHT_POSITION,
    LIGHT_COLOR,
    FALLOFF,
    COLOR,
    KA,
    KD,
    KS,
    SHINE,
    KST,
    SHINE_T,
    KR,
    KT,
    NFF_KS,
    IOR,
    ABSORPTION,
    CENTER,
    RADIUS,
    POINT,
    NORMAL,
    VERTEX,
    VERTEX_NORMAL,
    MIN,
    MAX,
    COEFFICIENT,
    CLIP_MIN,
    CLIP_MAX,
    BASE,
    APEX,
    BASE_RADIUS,
    APEX_RADIUS,
    CYLINDER_RADIUS,
    MESH_POSITION,
    MESH_NORMAL,
];

/// An integer quantity and its inclusive range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct IntQuantity {
    pub name: &'static str,
    pub min: i64,
    pub max: i64,
}

pub(crate) const WIDTH: IntQuantity = IntQuantity {
    name: "camera.width",
    min: 1,
    max: MAX_IMAGE_SIZE,
};
pub(crate) const HEIGHT: IntQuantity = IntQuantity {
    name: "camera.height",
    min: 1,
    max: MAX_IMAGE_SIZE,
};

impl IntQuantity {
    /// `n` (written `text` in the file, so that a value beyond i64 is
    /// quoted as written) must be in range.
    pub fn check(&self, n: Option<i64>, text: &str) -> Result<u32, String> {
        match n {
            Some(n) if (self.min..=self.max).contains(&n) => Ok(n as u32),
            _ => Err(format!(
                "{} must be in {}..={}, got {text}",
                self.name, self.min, self.max
            )),
        }
    }
}

/// Formats a number for messages: plain where that is short, else in
/// exponent form (`1e18`, `5e-324`).
pub(crate) fn fmt_num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e6).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A derived number (a threshold) to 4 significant digits.
fn fmt_approx(x: f64) -> String {
    let s = format!("{x:.3e}");
    let rounded: f64 = s.parse().unwrap_or(x);
    fmt_num(rounded)
}

/// Formats a vector as `[x, y, z]` for messages.
pub(crate) fn fmt_vec(v: DVec3) -> String {
    format!("[{}, {}, {}]", fmt_num(v.x), fmt_num(v.y), fmt_num(v.z))
}

impl Quantity {
    /// Checks one number (one component of a vector quantity).
    #[inline]
    pub fn check(&self, x: f64) -> Result<f64, String> {
        if self.accepts(x) {
            Ok(x)
        } else {
            Err(self.rejection(x))
        }
    }

    /// Whether `x` is in range (NaN and infinities never are). Inlined
    /// into the readers' loops; the message is built apart, only for an
    /// error.
    #[inline]
    pub fn accepts(&self, x: f64) -> bool {
        match self.range {
            Finite | Direction => x.is_finite(),
            Factor => (0.0..=MAX_FACTOR).contains(&x),
            Fraction => (0.0..=1.0).contains(&x),
            Exponent => (0.0..=MAX_EXPONENT).contains(&x),
            Positive => (MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&x),
            NonNegative => (0.0..=MAX_MAGNITUDE).contains(&x),
            ZeroOrPositive => x == 0.0 || (MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&x),
            SignedLength => x == 0.0 || (MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&x.abs()),
            Fov => x > 0.0 && x < 180.0,
        }
    }

    /// Why `x` is out of range (`accepts(x)` is false).
    #[cold]
    #[inline(never)]
    pub fn rejection(&self, x: f64) -> String {
        match self.verdict(x) {
            Err(m) => m,
            Ok(_) => format!("{} is out of range, got {}", self.name, fmt_num(x)),
        }
    }

    fn verdict(&self, x: f64) -> Result<f64, String> {
        let name = self.name;
        if !x.is_finite() {
            return Err(format!(
                "{name} must be a finite number, got {}",
                fmt_num(x)
            ));
        }
        // (largest value, why it is the largest) of the ranges with a
        // lower bound of 0; the others return here.
        let (hi, why) = match self.range {
            Finite | Direction => return Ok(x),
            Fov if x > 0.0 && x < 180.0 => return Ok(x),
            Fov => {
                return Err(format!(
                    "{name} must be in (0, 180) degrees, got {}",
                    fmt_num(x)
                ))
            }
            ZeroOrPositive | SignedLength if x == 0.0 => return Ok(x),
            SignedLength => return magnitude(name, x.abs(), x).map(|_| x),
            Positive | ZeroOrPositive => (MAX_MAGNITUDE, ""),
            NonNegative => (MAX_MAGNITUDE, "beyond it f32 arithmetic overflows"),
            Factor => (
                MAX_FACTOR,
                "larger factors can overflow f32 in the shading sums",
            ),
            Fraction => (
                1.0,
                "a surface cannot pass on more light than it receives \
                 (the ray tree's weights would grow with every bounce)",
            ),
            Exponent => (
                MAX_EXPONENT,
                "a sharper highlight is finer than f32 can resolve",
            ),
        };
        let zero_ok = self.range != Positive;
        if x < 0.0 || (x == 0.0 && !zero_ok) {
            let bound = if zero_ok { ">= 0" } else { "> 0" };
            return Err(format!("{name} must be {bound}, got {}", fmt_num(x)));
        }
        if why.is_empty() {
            // 0 (where allowed) or a magnitude in MIN ..= MAX
            return if x == 0.0 {
                Ok(x)
            } else {
                magnitude(name, x, x).map(|_| x)
            };
        }
        if x > hi {
            return Err(format!(
                "{name} must be at most {}, got {}: {why}",
                fmt_num(hi),
                fmt_num(x)
            ));
        }
        Ok(x)
    }

    /// Checks each component of a vector quantity; on error, the index of
    /// the component to blame (a direction's length is blamed on its first
    /// component).
    pub fn check3(&self, v: DVec3) -> Result<DVec3, (usize, String)> {
        for (i, x) in v.to_array().into_iter().enumerate() {
            self.check(x).map_err(|m| (i, m))?;
        }
        if self.range == Direction {
            let m = v.abs().max_element();
            if m == 0.0 {
                return Err((0, format!("{} must not be the zero vector", self.name)));
            }
            if !(MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&m) {
                magnitude(&format!("{} length", self.name), m, m).map_err(|e| (0, e))?;
            }
        }
        Ok(v)
    }
}

/// The message for a number written finite (`1e400`, as `text`) that
/// reads as an infinity.
pub(crate) fn beyond_f64(name: &str, text: &str) -> Option<String> {
    text.bytes().any(|b| b.is_ascii_digit()).then(|| {
        format!(
            "{name} `{text}` is out of range: beyond f64 (magnitudes up to {:e})",
            f64::MAX
        )
    })
}

/// `m` (the magnitude of `x`, > 0) must be in `MIN_MAGNITUDE ..= MAX_MAGNITUDE`.
fn magnitude(name: &str, m: f64, x: f64) -> Result<(), String> {
    // Formatted only for an error: a 1 M-sphere NFF checks 2 M of these.
    let (bound, limit, why) = if m > MAX_MAGNITUDE {
        ("most", MAX_MAGNITUDE, "beyond it its square overflows f32")
    } else if m < MIN_MAGNITUDE && m > 0.0 {
        ("least", MIN_MAGNITUDE, "below it its square underflows f32")
    } else {
        return Ok(());
    };
    Err(format!(
        "{name} must be at {bound} {} in magnitude, got {}: {why}",
        fmt_num(limit),
        fmt_num(x)
    ))
}

/// A problem with a list of points: the message and, where one point is to
/// blame, its index.
#[derive(Debug, PartialEq)]
pub(crate) struct PointsError {
    pub index: Option<usize>,
    pub message: String,
}

fn points_err(index: Option<usize>, message: String) -> PointsError {
    PointsError { index, message }
}

/// Which camera value is to blame.
#[derive(Debug, PartialEq)]
pub(crate) enum CameraFault {
    At,
    Up,
}

/// `from != at`, `up` not parallel to `at - from` (`up` itself is checked
/// as a [`Direction`]).
pub(crate) fn camera(from: DVec3, at: DVec3, up: DVec3) -> Result<(), (CameraFault, String)> {
    let dir = at - from;
    if dir == DVec3::ZERO {
        return Err((
            CameraFault::At,
            format!(
                "camera.at must differ from camera.from, both are {}",
                fmt_vec(at)
            ),
        ));
    }
    if up == DVec3::ZERO {
        return Err((
            CameraFault::Up,
            "camera.up must not be the zero vector".into(),
        ));
    }
    // Both scaled to a largest component of 1: no overflow or underflow.
    let (u, d) = (up / up.abs().max_element(), dir / dir.abs().max_element());
    if u.cross(d).length() <= 1e-9 * u.length() * d.length() {
        return Err((
            CameraFault::Up,
            format!(
                "camera.up {} is parallel to the view direction {}",
                fmt_vec(up),
                fmt_vec(dir)
            ),
        ));
    }
    Ok(())
}

/// Falloff `[c1, c2, c3]` (each already checked): not all zero.
pub(crate) fn falloff(f: DVec3) -> Result<(), String> {
    if f == DVec3::ZERO {
        Err("falloff must not be [0, 0, 0] (f(d) would be 1/0); [1, 0, 0] is no fall-off".into())
    } else {
        Ok(())
    }
}

pub(crate) fn box_bounds(min: DVec3, max: DVec3) -> Result<(), String> {
    if min.cmplt(max).all() {
        Ok(())
    } else {
        Err(format!(
            "box min must be < max on every axis, got min {} max {}",
            fmt_vec(min),
            fmt_vec(max)
        ))
    }
}

fn bounds(points: &[DVec3]) -> (DVec3, DVec3) {
    let lo = points.iter().fold(DVec3::INFINITY, |a, &p| a.min(p));
    let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p));
    (lo, hi)
}

fn extent(points: &[DVec3]) -> f64 {
    let (lo, hi) = bounds(points);
    (hi - lo).max_element()
}

/// Twice the area vector of a polygon (Newell's method: robust for
/// non-convex polygons).
fn area_vector(v: &[DVec3]) -> DVec3 {
    let mut normal = DVec3::ZERO;
    for i in 0..v.len() {
        let (a, b) = (v[i] - v[0], v[(i + 1) % v.len()] - v[0]);
        normal += a.cross(b);
    }
    normal
}

/// A planar polygon: 3 ..= [`MAX_POLYGON_VERTICES`] vertices, no two consecutive equal (the last
/// and the first count as consecutive), non-zero area, all vertices within
/// [`PLANARITY_TOLERANCE`] (relative) of one plane.
pub(crate) fn polygon(v: &[DVec3]) -> Result<(), PointsError> {
    let n = v.len();
    if n < 3 {
        return Err(points_err(
            None,
            format!("a polygon needs at least 3 vertices, got {n}"),
        ));
    }
    if n > MAX_POLYGON_VERTICES {
        return Err(points_err(
            None,
            format!("a polygon has at most {MAX_POLYGON_VERTICES} vertices, got {n}"),
        ));
    }
    for i in 0..n {
        let j = (i + 1) % n;
        if v[i] == v[j] {
            let (a, b) = if j == 0 { (n - 1, 0) } else { (i, j) };
            return Err(points_err(
                Some(if j == 0 { a } else { b }),
                format!(
                    "degenerate polygon: vertices {} and {} are equal ({})",
                    a + 1,
                    b + 1,
                    fmt_vec(v[i])
                ),
            ));
        }
    }
    let normal = area_vector(v);
    let size = extent(v);
    let area = normal.length() / 2.0;
    if area <= AREA_TOLERANCE * size * size {
        return Err(points_err(
            None,
            "degenerate polygon: its area is zero (all vertices on a line)".into(),
        ));
    }
    let unit = normal / normal.length();
    let centroid = v.iter().copied().sum::<DVec3>() / n as f64;
    let mut worst = (0, 0.0f64);
    for (i, p) in v.iter().enumerate() {
        let d = (*p - centroid).dot(unit).abs();
        if d > worst.1 {
            worst = (i, d);
        }
    }
    if worst.1 > PLANARITY_TOLERANCE * size {
        return Err(points_err(
            Some(worst.0),
            format!(
                "polygon is not planar: vertex {} is {:.3e} off the plane (tolerance {:.3e})",
                worst.0 + 1,
                worst.1,
                PLANARITY_TOLERANCE * size
            ),
        ));
    }
    Ok(())
}

/// A triangle with non-zero area.
pub(crate) fn triangle(v: &[DVec3; 3]) -> Result<(), String> {
    if triangle_is_degenerate(v) {
        Err(format!(
            "degenerate triangle (zero area): {}, {}, {}",
            fmt_vec(v[0]),
            fmt_vec(v[1]),
            fmt_vec(v[2])
        ))
    } else {
        Ok(())
    }
}

pub(crate) fn triangle_is_degenerate(v: &[DVec3; 3]) -> bool {
    let size = extent(v);
    let area = (v[1] - v[0]).cross(v[2] - v[0]).length() / 2.0;
    area.is_nan() || area <= AREA_TOLERANCE * size * size
}

/// Not all of the quadratic and linear terms A..I zero.
pub(crate) fn quadric(c: &[f64; 10]) -> Result<(), String> {
    if c[..9].iter().all(|&x| x == 0.0) {
        Err("quadric coefficients A..I are all zero: that is not a surface".into())
    } else {
        Ok(())
    }
}

/// Cone or cylinder (radii already checked as [`SignedLength`]): distinct
/// ends, radii of one sign (both >= 0, or both <= 0 for an inside-out cone),
/// not both zero.
pub(crate) fn cone(base: DVec3, r0: f64, apex: DVec3, r1: f64) -> Result<(), String> {
    if base == apex {
        return Err(format!(
            "cone base and apex are the same point {}",
            fmt_vec(base)
        ));
    }
    if r0 == 0.0 && r1 == 0.0 {
        return Err("cone radii are both zero".into());
    }
    if (r0 > 0.0 && r1 < 0.0) || (r0 < 0.0 && r1 > 0.0) {
        return Err(format!(
            "cone radii must have the same sign (negative = inside visible), got {} and {}",
            fmt_num(r0),
            fmt_num(r1)
        ));
    }
    Ok(())
}

// ------------------------------------------------------- scene-wide: f32

/// Which value of the scene a scene-wide fault is about.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Site {
    /// `camera.at` (its distance from `from`).
    CameraAt,
    /// `camera.fov` (the angle between neighbouring pixels' rays).
    CameraFov,
    /// The position of light `i`.
    Light(usize),
    /// Object `i` of `Scene::objects`, and which of its values.
    Object(usize, Part),
}

/// Which value of an object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Part {
    /// Its `k`-th defining point, in the order the formats write them:
    /// sphere centre; plane point; polygon, triangle or mesh vertex `k`;
    /// box min, max; clip min, max; cone base, apex.
    Point(usize),
    /// Its size (a sphere's radius, a box's smallest side, ...).
    Size,
    /// A quadric's coefficients.
    Coefficients,
}

/// A scene-wide fault: where and what.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Fault {
    pub site: Site,
    pub message: String,
}

/// The checks that need the whole scene, in f32 as the packer will see it
/// (coordinates relative to `camera.from`), with the rules of
/// `docs/scene-format.md`, "f32 limits":
///
/// 1. every camera-relative coordinate (of `at`, lights, and every point
///    that defines a primitive) is within ±[`MAX_MAGNITUDE`];
/// 2. every bounded primitive's size is at least [`MIN_MAGNITUDE`] and at
///    least [`MIN_SIZE_REL`] × its distance from the camera (the largest
///    camera-relative coordinate of its bounds): smaller, f32 cannot
///    resolve it;
/// 3. neighbouring pixels' rays differ by at least [`MIN_SIZE_REL`]
///    radians, and a quadric re-expressed relative to the camera keeps
///    finite coefficients and a non-zero A..I in f32.
///
/// Values are assumed to have passed their [`Quantity`] checks.
pub(crate) fn scene_limits(scene: &Scene) -> Result<(), Fault> {
    scene_limits_but_objects(scene, scene.objects.len())
}

/// [`scene_limits`] for the camera, the lights and only the first
/// `objects` objects: a reader that checked the others as it made them
/// (with [`object_limits`], while they were in cache) leaves them out.
pub(crate) fn scene_limits_but_objects(scene: &Scene, objects: usize) -> Result<(), Fault> {
    let cam = &scene.camera;
    let origin = cam.from;
    let fault = |site, message| Fault { site, message };
    let at = cam.at - origin;
    coordinate("camera.at", at, cam.at).map_err(|m| fault(Site::CameraAt, m))?;
    if at.abs().max_element() < MIN_MAGNITUDE {
        return Err(fault(
            Site::CameraAt,
            format!(
                "camera.at must be at least {} from camera.from on some axis, got {}",
                fmt_num(MIN_MAGNITUDE),
                fmt_vec(at)
            ),
        ));
    }
    let pixel = 2.0 * (cam.fov.to_radians() * 0.5).tan() / cam.height as f64;
    if pixel < MIN_SIZE_REL {
        return Err(fault(
            Site::CameraFov,
            format!(
                "camera.fov {}° is too narrow for f32 at height {}: neighbouring pixels' rays \
                 would differ by {} rad, f32 directions need at least {} (2^-20)",
                fmt_num(cam.fov),
                cam.height,
                fmt_approx(pixel),
                fmt_approx(MIN_SIZE_REL)
            ),
        ));
    }
    for (i, l) in scene.lights.iter().enumerate() {
        coordinate("light position", l.position - origin, l.position)
            .map_err(|m| fault(Site::Light(i), m))?;
    }
    for (i, o) in scene.objects[..objects].iter().enumerate() {
        object_limits(&o.shape, origin).map_err(|(part, m)| fault(Site::Object(i, part), m))?;
    }
    Ok(())
}

/// Rule 1 for one point: `rel` = `abs` − camera.
fn coordinate(what: &str, rel: DVec3, abs: DVec3) -> Result<(), String> {
    let m = rel.abs().max_element();
    if m <= MAX_MAGNITUDE {
        return Ok(());
    }
    Err(format!(
        "{what} {} is {} from the camera along an axis: camera-relative coordinates must be \
         within ±{}, or f32 arithmetic on them overflows",
        fmt_vec(abs),
        fmt_num(m),
        fmt_num(MAX_MAGNITUDE)
    ))
}

/// Rule 1 for every point; returns their camera-relative bounds.
fn points_limits(
    what: &str,
    pts: impl Iterator<Item = DVec3>,
    origin: DVec3,
) -> Result<(DVec3, DVec3), (Part, String)> {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for (k, p) in pts.enumerate() {
        let rel = p - origin;
        coordinate(what, rel, p).map_err(|m| (Part::Point(k), m))?;
        lo = lo.min(rel);
        hi = hi.max(rel);
    }
    Ok((lo, hi))
}

/// Rule 2: `size` (described by `what`, e.g. "radius") against the distance
/// of bounds `lo..hi` from the camera. A size the file gives (`given`: a
/// radius, a side) is quoted exactly, a derived one (area / extent) to 4
/// digits.
fn resolvable(
    kind: &str,
    what: &str,
    (size, given): (f64, bool),
    lo: DVec3,
    hi: DVec3,
) -> Result<(), String> {
    let distance = lo.abs().max(hi.abs()).max_element();
    let need = MIN_MAGNITUDE.max(MIN_SIZE_REL * distance);
    if size >= need {
        return Ok(());
    }
    Err(format!(
        "{kind} {what} {} is too small for f32 at {} from the camera: it needs at least {} \
         (2^-20 of the distance, and at least {}), or the {kind} vanishes",
        if given {
            fmt_num(size)
        } else {
            fmt_approx(size)
        },
        fmt_approx(distance),
        fmt_approx(need),
        fmt_num(MIN_MAGNITUDE)
    ))
}

/// Rules 1 and 2 (and the quadric's rule 3) for one object, with the
/// camera at `origin`: on failure, which of its values and why.
pub(crate) fn object_limits(shape: &Shape, origin: DVec3) -> Result<(), (Part, String)> {
    if let Shape::Sphere { center, radius } = shape {
        // Most primitives are spheres: accept them without building
        // anything. The same arithmetic as below: the largest |coordinate|
        // of the bounds c ± r is max |c_i| + r.
        let m = (*center - origin).abs().max_element();
        if m <= MAX_MAGNITUDE && *radius >= MIN_MAGNITUDE.max(MIN_SIZE_REL * (m + radius)) {
            return Ok(());
        }
    }
    let size =
        |kind, what, s, (lo, hi)| resolvable(kind, what, s, lo, hi).map_err(|m| (Part::Size, m));
    // (a size, whether the file gives it as it is)
    let given = |s: f64| (s, true);
    let derived = |s: f64| (s, false);
    match shape {
        Shape::Sphere { center, radius } => {
            let (c, _) = points_limits("center", std::iter::once(*center), origin)?;
            size(
                "sphere",
                "radius",
                given(*radius),
                (c - *radius, c + *radius),
            )
        }
        Shape::Plane { point, .. } => {
            points_limits("point", std::iter::once(*point), origin).map(|_| ())
        }
        Shape::Polygon { vertices } => {
            let b = points_limits("vertex", vertices.iter().copied(), origin)?;
            let rel: Vec<DVec3> = vertices.iter().map(|&p| p - origin).collect();
            let width = area_vector(&rel).length() / 2.0 / extent(&rel);
            size("polygon", "width (area / extent)", derived(width), b)
        }
        Shape::Triangle { vertices, .. } => {
            let b = points_limits("vertex", vertices.iter().copied(), origin)?;
            let rel = vertices.map(|p| p - origin);
            let width = (rel[1] - rel[0]).cross(rel[2] - rel[0]).length() / 2.0 / extent(&rel);
            size("triangle", "width (area / extent)", derived(width), b)
        }
        Shape::Mesh(m) => {
            // Each triangle may be tiny (its neighbours share its rounded
            // vertices, so the surface stays closed): the mesh as a whole
            // must be resolvable.
            let b = points_limits("mesh position", m.positions.iter().copied(), origin)?;
            size("mesh", "extent", given((b.1 - b.0).max_element()), b)
        }
        Shape::Box { min, max } => {
            let b = points_limits("box corner", [*min, *max].into_iter(), origin)?;
            size(
                "box",
                "smallest side",
                given((*max - *min).min_element()),
                b,
            )
        }
        Shape::Quadric { coefficients, clip } => {
            let k = crate::pack::relative_quadric(coefficients, origin);
            if k.iter().any(|x| !x.is_finite()) {
                return Err((
                    Part::Coefficients,
                    format!(
                        "quadric coefficients overflow when re-expressed relative to the camera \
                         at {}: move the quadric (or the camera) nearer the origin",
                        fmt_vec(origin)
                    ),
                ));
            }
            if k[..9].iter().all(|&x| x as f32 == 0.0) {
                return Err((
                    Part::Coefficients,
                    "quadric coefficients A..I vanish in f32 next to J when re-expressed \
                     relative to the camera: the surface is too far away for its size"
                        .into(),
                ));
            }
            match clip {
                Some((lo, hi)) => {
                    let b = points_limits("clip corner", [*lo, *hi].into_iter(), origin)?;
                    size(
                        "quadric",
                        "clip box's smallest side",
                        given((*hi - *lo).min_element()),
                        b,
                    )
                }
                None => Ok(()),
            }
        }
        Shape::Cone {
            base,
            base_radius,
            apex,
            apex_radius,
        } => {
            let (r0, r1) = (base_radius.abs(), apex_radius.abs());
            let (b, _) = points_limits("base", std::iter::once(*base), origin)?;
            let (a, _) = points_limits("apex", std::iter::once(*apex), origin)
                .map_err(|(_, m)| (Part::Point(1), m))?;
            let len = (a - b).length();
            let (lo, hi) = ((b - r0).min(a - r1), (b + r0).max(a + r1));
            size(
                "cone",
                "size (min of largest radius, length)",
                derived(r0.max(r1).min(len)),
                (lo, hi),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn polygons() {
        let sq = [d(0., 0., 0.), d(1., 0., 0.), d(1., 1., 0.), d(0., 1., 0.)];
        assert!(polygon(&sq).is_ok());
        // non-convex L shape
        let l = [
            d(0., 0., 1.),
            d(2., 0., 1.),
            d(2., 1., 1.),
            d(1., 1., 1.),
            d(1., 2., 1.),
            d(0., 2., 1.),
        ];
        assert!(polygon(&l).is_ok());
        assert_eq!(polygon(&sq[..2]).unwrap_err().index, None);
        let dup = [d(0., 0., 0.), d(1., 0., 0.), d(1., 0., 0.), d(0., 1., 0.)];
        assert_eq!(polygon(&dup).unwrap_err().index, Some(2));
        let wrap = [d(0., 0., 0.), d(1., 0., 0.), d(0., 1., 0.), d(0., 0., 0.)];
        let e = polygon(&wrap).unwrap_err();
        assert_eq!(e.index, Some(3));
        assert!(e.message.contains("vertices 4 and 1"), "{}", e.message);
        let line = [d(0., 0., 0.), d(1., 0., 0.), d(2., 0., 0.)];
        assert!(polygon(&line).unwrap_err().message.contains("area is zero"));
        let bent = [d(0., 0., 0.), d(1., 0., 0.), d(1., 1., 0.), d(0., 1., 0.3)];
        let e = polygon(&bent).unwrap_err();
        assert!(e.message.contains("not planar"), "{}", e.message);
        // tiny noise is tolerated
        let noisy = [d(0., 0., 0.), d(1., 0., 0.), d(1., 1., 1e-7), d(0., 1., 0.)];
        assert!(polygon(&noisy).is_ok());
    }

    #[test]
    fn camera_checks() {
        let z = d(0., 0., 1.);
        assert!(camera(d(0., -8., 3.), DVec3::ZERO, z).is_ok());
        assert_eq!(camera(z, z, z).unwrap_err().0, CameraFault::At);
        assert_eq!(
            camera(DVec3::ZERO, z, DVec3::ZERO).unwrap_err().0,
            CameraFault::Up
        );
        assert_eq!(
            camera(DVec3::ZERO, z, -z * 3.).unwrap_err().0,
            CameraFault::Up
        );
        // huge and tiny vectors are compared without overflow
        assert!(camera(DVec3::ZERO, d(1e300, 0., 0.), d(0., 0., 1e-300)).is_ok());
        assert!(camera(DVec3::ZERO, d(1e300, 0., 0.), d(1e-300, 0., 0.)).is_err());
    }

    #[test]
    fn ranges_at_both_sides_of_each_limit() {
        // (quantity, largest accepted below, smallest refused above, ...)
        assert!(KD.check(0.0).is_ok() && KD.check(MAX_FACTOR).is_ok());
        assert!(KD.check(MAX_FACTOR * (1.0 + 1e-15)).is_err());
        assert_eq!(KD.check(-0.5).unwrap_err(), "kd must be >= 0, got -0.5");
        assert_eq!(
            KD.check(1.5e6).unwrap_err(),
            "kd must be at most 1e6, got 1.5e6: larger factors can overflow f32 in the shading sums"
        );
        assert!(KR.check(1.0).is_ok());
        assert!(KR
            .check(1.0 + 1e-12)
            .unwrap_err()
            .starts_with("kr must be at most 1, got"));
        assert!(SHINE.check(MAX_EXPONENT).is_ok() && SHINE.check(2e6).is_err());
        assert!(RADIUS.check(MIN_MAGNITUDE).is_ok() && RADIUS.check(MAX_MAGNITUDE).is_ok());
        assert_eq!(RADIUS.check(0.0).unwrap_err(), "radius must be > 0, got 0");
        assert_eq!(
            RADIUS.check(5e-324).unwrap_err(),
            "radius must be at least 1e-18 in magnitude, got 5e-324: below it its square underflows f32"
        );
        assert!(RADIUS.check(1e-120).is_err() && RADIUS.check(0.99e-18).is_err());
        assert_eq!(
            RADIUS.check(1e20).unwrap_err(),
            "radius must be at most 1e18 in magnitude, got 1e20: beyond it its square overflows f32"
        );
        assert!(RADIUS.check(1.01e18).is_err());
        assert_eq!(
            RADIUS.check(f64::NAN).unwrap_err(),
            "radius must be a finite number, got NaN"
        );
        assert!(IOR.check(1.5).is_ok() && IOR.check(-1.5).is_err());
        assert!(ABSORPTION.check(1e-30).is_ok() && ABSORPTION.check(2e18).is_err());
        assert_eq!(
            ABSORPTION.check(-1.0).unwrap_err(),
            "absorption must be >= 0, got -1"
        );
        assert_eq!(
            FALLOFF.check(-1.0).unwrap_err(),
            "falloff must be >= 0, got -1"
        );
        assert!(FALLOFF.check(0.0).is_ok() && FALLOFF.check(1e-19).is_err());
        assert!(BASE_RADIUS.check(-1.0).is_ok() && BASE_RADIUS.check(0.0).is_ok());
        assert!(BASE_RADIUS.check(-2e18).is_err() && BASE_RADIUS.check(-1e-19).is_err());
        assert!(FOV.check(179.9).is_ok() && FOV.check(180.0).is_err() && FOV.check(0.0).is_err());
        assert!(CENTER.check(1e300).is_ok() && CENTER.check(f64::INFINITY).is_err());
        assert_eq!(WIDTH.check(Some(65536), "65536"), Ok(65536));
        assert_eq!(
            WIDTH.check(None, "18446744073709551615").unwrap_err(),
            "camera.width must be in 1..=65536, got 18446744073709551615"
        );
        assert!(HEIGHT.check(Some(0), "0").is_err());
    }

    /// The inlined test and the messages agree on every row.
    #[test]
    fn accepts_agrees_with_the_messages() {
        let xs = [
            f64::NEG_INFINITY,
            -2e18,
            -1.0,
            -1e-19,
            -0.0,
            0.0,
            1e-19,
            1e-18,
            0.5,
            1.0,
            1.5,
            179.9,
            180.0,
            1e6,
            1.5e6,
            1e18,
            2e18,
            f64::INFINITY,
            f64::NAN,
        ];
        for q in TABLE {
            for x in xs {
                assert_eq!(q.accepts(x), q.verdict(x).is_ok(), "{} {x}", q.name);
                if !q.accepts(x) {
                    assert!(
                        !q.rejection(x).contains("is out of range"),
                        "{} {x}",
                        q.name
                    );
                }
            }
        }
    }

    #[test]
    fn directions() {
        assert!(UP.check3(d(0., 0., 1e-18)).is_ok());
        assert_eq!(
            UP.check3(DVec3::ZERO).unwrap_err(),
            (0, "camera.up must not be the zero vector".to_string())
        );
        let (_, m) = NORMAL.check3(d(0., 1e-19, 0.)).unwrap_err();
        assert!(m.starts_with("normal length must be at least 1e-18"), "{m}");
        assert!(NORMAL.check3(d(0., 0., 2e18)).is_err());
        assert_eq!(NORMAL.check3(d(0., f64::NAN, 0.)).unwrap_err().0, 1);
    }

    #[test]
    fn numbers_in_messages() {
        assert_eq!(fmt_num(1e18), "1e18");
        assert_eq!(fmt_num(0.5), "0.5");
        assert_eq!(fmt_num(-3.0), "-3");
        assert_eq!(fmt_num(5e-324), "5e-324");
        assert_eq!(fmt_approx(MIN_SIZE_REL * 1e6), "0.9537");
        assert_eq!(fmt_vec(d(1e39, 0., -1.)), "[1e39, 0, -1]");
    }

    #[test]
    fn scalars() {
        assert!(box_bounds(DVec3::ZERO, d(1., 1., 0.)).is_err());
        assert!(box_bounds(DVec3::ZERO, DVec3::ONE).is_ok());
        let mut q = [0.0; 10];
        q[9] = 1.0;
        assert!(quadric(&q).is_err());
        q[0] = 1.0;
        assert!(quadric(&q).is_ok());
        assert!(cone(DVec3::ZERO, 1.0, DVec3::Z, 0.0).is_ok());
        assert!(cone(DVec3::ZERO, -1.0, DVec3::Z, -1.0).is_ok());
        assert!(cone(DVec3::ZERO, 1.0, DVec3::Z, -1.0).is_err());
        assert!(cone(DVec3::ZERO, 1.0, DVec3::ZERO, 1.0).is_err());
        assert!(triangle(&[DVec3::ZERO, DVec3::X, DVec3::X * 2.0]).is_err());
        assert!(triangle(&[DVec3::ZERO, DVec3::X, DVec3::Y]).is_ok());
        assert!(falloff(DVec3::ZERO).is_err() && falloff(DVec3::Z).is_ok());
    }

    /// Every row of the table is documented in docs/scene-format.md with
    /// its range, in the "Valid values" table.
    #[test]
    fn the_table_is_documented() {
        let doc = include_str!("../../docs/scene-format.md");
        let start = doc
            .find("## Valid values")
            .expect("a 'Valid values' section");
        let section = &doc[start..];
        let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
        // The range cell of the row that documents `name`.
        let range_cell = |name: &str| {
            let row = section
                .lines()
                .find(|l| l.starts_with(&format!("| `{name}` ")))
                .unwrap_or_else(|| panic!("no row for `{name}` in the Valid values table"));
            row.split('|').nth(2).unwrap_or("").trim().to_string()
        };
        let (big, small) = (format!("{MAX_MAGNITUDE:e}"), format!("{MIN_MAGNITUDE:e}"));
        let range_text = |r: Range| match r {
            Finite => "finite".to_string(),
            Factor => format!("0 ..= {MAX_FACTOR:e}"),
            Fraction => "0 ..= 1".into(),
            Exponent => format!("0 ..= {MAX_EXPONENT:e}"),
            Positive => format!("{small} ..= {big}"),
            NonNegative => format!("0 ..= {big}"),
            ZeroOrPositive => format!("0, or {small} ..= {big}"),
            SignedLength => format!("0, or ±({small} ..= {big})"),
            Direction => "direction".into(),
            Fov => "0 < x < 180".into(),
        };
        for q in TABLE {
            assert_eq!(
                range_cell(q.name),
                range_text(q.range),
                "row of `{}`",
                q.name
            );
        }
        for q in [WIDTH, HEIGHT] {
            assert_eq!(range_cell(q.name), format!("{} ..= {}", q.min, q.max));
        }
    }
}
