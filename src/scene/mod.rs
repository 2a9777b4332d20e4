//! The high-level scene: what a scene file says, in f64, before packing.
//!
//! `load` reads a native TOML scene (`.toml`) or Eric Haines' Neutral File
//! Format (`.nff`), validates it and returns a [`Scene`]. Every error names
//! the file, the line and the column ([`SceneError`]). Nothing downstream of
//! `pack::pack` looks at a `Scene` again.

use glam::DVec3;
use std::path::{Path, PathBuf};

mod error;
mod nff;
mod obj;
mod toml_format;
mod validate;

pub use error::SceneError;
/// The numeric limits of scene values (`docs/scene-format.md`, "Valid
/// values" and "f32 limits").
pub use validate::{MAX_EXPONENT, MAX_FACTOR, MAX_MAGNITUDE, MIN_MAGNITUDE, MIN_SIZE_REL};

/// Camera. `fov` is the vertical field of view, edge to edge, in degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub from: DVec3,
    pub at: DVec3,
    pub up: DVec3,
    pub fov: f64,
    pub width: u32,
    pub height: u32,
}

/// A point light. Fall-off f(d) = min(1, 1/(c1 + c2·d + c3·d²)); the default
/// `[1, 0, 0]` is no fall-off.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    pub position: DVec3,
    pub color: DVec3,
    pub falloff: [f64; 3],
}

/// Every coefficient of the local model
/// I_L = k_a I_a + Σ I_i f(d) S_i [k_d (N·L) + k_sr (V·R_L)^n_r + k_st (V·T_L)^n_t]
/// plus the global terms k_r, k_t, the index of refraction and the
/// absorption coefficient (per unit length) inside the medium.
/// `ka` and `kd` are already multiplied by the material's colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub ka: DVec3,
    pub kd: DVec3,
    pub ksr: f64,
    pub nr: f64,
    pub kst: f64,
    pub nt: f64,
    pub kr: DVec3,
    pub kt: DVec3,
    pub ior: f64,
    pub absorption: DVec3,
}

impl Default for Material {
    /// Matte white: k_a = 0.1, k_d = 0.9, nothing else.
    fn default() -> Self {
        Material {
            name: "default".into(),
            ka: DVec3::splat(0.1),
            kd: DVec3::splat(0.9),
            ksr: 0.0,
            nr: 1.0,
            kst: 0.0,
            nt: 1.0,
            kr: DVec3::ZERO,
            kt: DVec3::ZERO,
            ior: 1.0,
            absorption: DVec3::ZERO,
        }
    }
}

/// A triangle mesh: shared vertices, optional per-vertex normals.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    /// Same length as `positions` when present (smooth shading).
    pub normals: Option<Vec<DVec3>>,
    pub triangles: Vec<[u32; 3]>,
}

/// The primitives of the seed.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// The plane through `point` with (not necessarily unit) `normal`.
    Plane {
        point: DVec3,
        normal: DVec3,
    },
    /// Planar polygon, convex or not, vertices in order.
    Polygon {
        vertices: Vec<DVec3>,
    },
    /// One triangle, optionally with vertex normals (NFF `pp`).
    Triangle {
        vertices: [DVec3; 3],
        normals: Option<Box<[DVec3; 3]>>,
    },
    Mesh(Box<Mesh>),
    /// Axis-aligned box by its two corners (min < max on each axis).
    Box {
        min: DVec3,
        max: DVec3,
    },
    /// A x² + B y² + C z² + D xy + E xz + F yz + G x + H y + I z + J = 0
    /// (POV-Ray's order), optionally clipped to a box. Unclipped quadrics
    /// stay outside the voxel grid.
    Quadric {
        coefficients: [f64; 10],
        clip: Option<(DVec3, DVec3)>,
    },
    /// NFF `c`: open truncated cone (or cylinder) from `base` (radius
    /// `base_radius`) to `apex` (radius `apex_radius`). Negative radii (both)
    /// mean the inside is the visible side: the geometric normal points in.
    Cone {
        base: DVec3,
        base_radius: f64,
        apex: DVec3,
        apex_radius: f64,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub shape: Shape,
    /// Index into `Scene::materials`.
    pub material: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub camera: Camera,
    pub background: DVec3,
    /// I_a, the ambient light.
    pub ambient: DVec3,
    pub lights: Vec<Light>,
    pub materials: Vec<Material>,
    pub objects: Vec<Object>,
    /// Where the scene came from (for messages).
    pub source: PathBuf,
}

/// Reads a scene file: `.nff` is NFF, anything else is the native TOML format.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_progress(path, &|_, _| {})
}

/// [`load`], calling `progress(done, total)` now and then (about every
/// MiB of text) while the readers work, so that a caller can show a bar
/// for a slow input. Both are byte counts: of the scene file, plus, for a
/// TOML scene, of the `.obj` files it names (`total` grows to include them
/// once the TOML text is parsed; the TOML parse itself reports nothing in
/// between). The last call has `done == total`.
pub fn load_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Scene, SceneError> {
    let text = read_text(path).map_err(|e| e.into_scene_error(path))?;
    parse_with_progress(&text, path, progress)
}

/// Parses scene text as if it came from `path` (the extension picks the format).
pub fn parse_str(text: &str, path: &Path) -> Result<Scene, SceneError> {
    parse_with_progress(text, path, &|_, _| {})
}

fn parse_with_progress(
    text: &str,
    path: &Path,
    progress: &dyn Fn(u64, u64),
) -> Result<Scene, SceneError> {
    let is_nff = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("nff"));
    if is_nff {
        nff::parse(text, path, progress)
    } else {
        toml_format::parse(text, path, progress)
    }
}

/// Checks a scene built in code against the scene-wide f32 limits the
/// readers apply after parsing (`docs/scene-format.md`, "f32 limits"). The
/// error has no position: it names the object or light by its index.
pub fn check_f32_limits(scene: &Scene) -> Result<(), SceneError> {
    validate::scene_limits(scene).map_err(|f| {
        let site = match f.site {
            validate::Site::CameraAt | validate::Site::CameraFov => "camera".to_string(),
            validate::Site::Light(i) => format!("light {i}"),
            validate::Site::Object(i, _) => format!("object {i}"),
        };
        SceneError::in_file(&scene.source, format!("{site}: {}", f.message))
    })
}

/// Why a text file could not be read.
pub(crate) enum ReadError {
    Io(std::io::Error),
    /// Not UTF-8: where the first bad byte is (1-based), and the byte.
    Utf8 {
        line: usize,
        column: usize,
        byte: u8,
    },
}

impl ReadError {
    /// As an error in the scene file `path`.
    fn into_scene_error(self, path: &Path) -> SceneError {
        match self {
            ReadError::Io(e) => SceneError::io(path, &e),
            ReadError::Utf8 { line, column, byte } => {
                SceneError::at(path, line, column, utf8_message(byte))
            }
        }
    }
}

pub(crate) fn utf8_message(byte: u8) -> String {
    format!("not UTF-8 text: invalid byte 0x{byte:02x}")
}

/// Reads a whole text file; invalid UTF-8 is reported at its position.
pub(crate) fn read_text(path: &Path) -> Result<String, ReadError> {
    let bytes = std::fs::read(path).map_err(ReadError::Io)?;
    String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // Valid by definition: the bytes before `valid_up_to`.
        let before = std::str::from_utf8(&bytes[..offset]).unwrap_or_default();
        let (line, column) = error::line_col(before, offset);
        ReadError::Utf8 {
            line,
            column,
            byte: bytes[offset],
        }
    })
}
