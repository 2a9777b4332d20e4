//! Checks shared by the TOML and NFF readers. Each returns a message without
//! a location; the reader attaches the position of the offending value.

use glam::DVec3;

/// Relative tolerance for polygon planarity: every vertex must lie within
/// `PLANARITY_TOLERANCE × (largest extent of the polygon)` of its plane.
pub(crate) const PLANARITY_TOLERANCE: f64 = 1e-4;

/// Relative tolerance below which an area counts as zero:
/// `area ≤ AREA_TOLERANCE × extent²`.
pub(crate) const AREA_TOLERANCE: f64 = 1e-12;

/// Largest accepted image width or height.
pub(crate) const MAX_IMAGE_SIZE: i64 = 65536;

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

/// Formats a vector as `[x, y, z]` for messages.
pub(crate) fn fmt_vec(v: DVec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// `NaN` / `inf` / `-inf` are rejected everywhere.
pub(crate) fn finite(x: f64, what: &str) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{what} must be a finite number, got {x}"))
    }
}

pub(crate) fn non_negative(x: f64, what: &str) -> Result<(), String> {
    if x >= 0.0 {
        Ok(())
    } else {
        Err(format!("{what} must be >= 0, got {x}"))
    }
}

pub(crate) fn non_negative3(v: DVec3, what: &str) -> Result<(), String> {
    if v.cmpge(DVec3::ZERO).all() {
        Ok(())
    } else {
        Err(format!("{what} must be >= 0, got {}", fmt_vec(v)))
    }
}

pub(crate) fn sphere_radius(r: f64) -> Result<(), String> {
    if r > 0.0 && r.is_finite() {
        Ok(())
    } else {
        Err(format!("radius must be > 0, got {r}"))
    }
}

pub(crate) fn ior(x: f64) -> Result<(), String> {
    if x > 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(format!("ior must be > 0, got {x}"))
    }
}

pub(crate) fn fov(x: f64) -> Result<(), String> {
    if x > 0.0 && x < 180.0 {
        Ok(())
    } else {
        Err(format!("fov must be in (0, 180) degrees, got {x}"))
    }
}

/// Image width or height: 1 ..= 65536.
pub(crate) fn image_size(n: i64, what: &str) -> Result<u32, String> {
    if (1..=MAX_IMAGE_SIZE).contains(&n) {
        Ok(n as u32)
    } else {
        Err(format!("{what} must be in 1..={MAX_IMAGE_SIZE}, got {n}"))
    }
}

/// Which camera value is to blame.
#[derive(Debug, PartialEq)]
pub(crate) enum CameraFault {
    At,
    Up,
}

/// `from != at`, `up` non-zero and not parallel to `at - from`.
pub(crate) fn camera(from: DVec3, at: DVec3, up: DVec3) -> Result<(), (CameraFault, String)> {
    let dir = at - from;
    if dir == DVec3::ZERO {
        return Err((
            CameraFault::At,
            format!(
                "camera `at` must differ from `from`, both are {}",
                fmt_vec(at)
            ),
        ));
    }
    if up == DVec3::ZERO {
        return Err((CameraFault::Up, "camera `up` must not be zero".into()));
    }
    if up.cross(dir).length() <= 1e-9 * up.length() * dir.length() {
        return Err((
            CameraFault::Up,
            format!(
                "camera `up` {} is parallel to the view direction {}",
                fmt_vec(up),
                fmt_vec(dir)
            ),
        ));
    }
    Ok(())
}

pub(crate) fn nonzero_vector(v: DVec3, what: &str) -> Result<(), String> {
    if v == DVec3::ZERO {
        Err(format!("{what} must not be the zero vector"))
    } else {
        Ok(())
    }
}

pub(crate) fn box_bounds(min: DVec3, max: DVec3) -> Result<(), String> {
    if min.cmplt(max).all() {
        Ok(())
    } else {
        Err(format!(
            "box `min` must be < `max` on every axis, got min {} max {}",
            fmt_vec(min),
            fmt_vec(max)
        ))
    }
}

fn extent(points: &[DVec3]) -> f64 {
    let lo = points.iter().fold(DVec3::INFINITY, |a, &p| a.min(p));
    let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p));
    (hi - lo).max_element()
}

/// A planar polygon: at least 3 vertices, no two consecutive equal (the last
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
    // Newell's method: robust for non-convex polygons.
    let mut normal = DVec3::ZERO;
    for i in 0..n {
        let (a, b) = (v[i] - v[0], v[(i + 1) % n] - v[0]);
        normal += a.cross(b);
    }
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

/// Not all of the quadratic and cross terms A..I zero.
pub(crate) fn quadric(c: &[f64; 10]) -> Result<(), String> {
    if c[..9].iter().all(|&x| x == 0.0) {
        Err("quadric coefficients A..I are all zero: that is not a surface".into())
    } else {
        Ok(())
    }
}

/// Cone or cylinder: distinct ends, radii of one sign (both >= 0, or both
/// <= 0 for an inside-out cone), not both zero.
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
            "cone radii must have the same sign (negative = inside visible), got {r0} and {r1}"
        ));
    }
    Ok(())
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
    }

    #[test]
    fn scalars() {
        assert!(sphere_radius(0.0)
            .unwrap_err()
            .contains("radius must be > 0, got 0"));
        assert!(sphere_radius(f64::NAN).is_err());
        assert!(ior(0.0).is_err() && ior(1.5).is_ok());
        assert!(fov(180.0).is_err() && fov(0.0).is_err() && fov(45.0).is_ok());
        assert_eq!(image_size(65536, "width"), Ok(65536));
        assert!(image_size(0, "width").is_err() && image_size(65537, "h").is_err());
        assert_eq!(
            finite(f64::INFINITY, "x").unwrap_err(),
            "x must be a finite number, got inf"
        );
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
    }
}
