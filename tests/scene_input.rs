//! Scene input: the native TOML format, `.obj` meshes and NFF, good and bad.

use glam::DVec3;
use std::path::{Path, PathBuf};
use whitted::scene::{self, Material, Scene, SceneError, Shape};

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn toml_ok(text: &str) -> Scene {
    scene::parse_str(text, Path::new("scenes/test.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn nff_ok(text: &str) -> Scene {
    scene::parse_str(text, Path::new("test.nff")).unwrap_or_else(|e| panic!("{e}"))
}

/// Asserts the error is at `line:col` and its message contains `fragment`.
fn assert_err(err: &SceneError, line: usize, col: usize, fragment: &str) {
    assert_eq!(
        (err.line(), err.column()),
        (Some(line), Some(col)),
        "wrong position for: {err}"
    );
    assert!(
        err.message().contains(fragment),
        "message lacks {fragment:?}: {err}"
    );
}

fn toml_err(text: &str) -> SceneError {
    scene::parse_str(text, Path::new("scenes/bad.toml")).expect_err("should not parse")
}

fn nff_err(text: &str) -> SceneError {
    scene::parse_str(text, Path::new("bad.nff")).expect_err("should not parse")
}

const CAMERA: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\n";

// ---------------------------------------------------------------- TOML, good

#[test]
fn minimal_toml_scene_loads_with_defaults() {
    let s = toml_ok(
        "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\n\n\
         [[light]]\nposition = [5, -5, 10]\n\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 1]\nradius = 1\n",
    );
    assert_eq!(s.camera.from, v(0.0, -8.0, 3.0));
    assert_eq!(s.camera.at, DVec3::ZERO);
    assert_eq!(s.camera.up, v(0.0, 0.0, 1.0));
    assert_eq!(s.camera.fov, 45.0);
    assert_eq!((s.camera.width, s.camera.height), (640, 480));
    assert_eq!(s.background, DVec3::ZERO);
    assert_eq!(s.ambient, DVec3::ONE);
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.lights[0].position, v(5.0, -5.0, 10.0));
    assert_eq!(s.lights[0].color, DVec3::ONE);
    assert_eq!(s.lights[0].falloff, [1.0, 0.0, 0.0]);
    assert_eq!(s.materials, vec![Material::default()]);
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.objects[0].material, 0);
    assert_eq!(
        s.objects[0].shape,
        Shape::Sphere {
            center: v(0.0, 0.0, 1.0),
            radius: 1.0
        }
    );
    assert_eq!(s.source, PathBuf::from("scenes/test.toml"));
}

#[test]
fn material_keys_and_their_defaults() {
    let s = toml_ok(&format!(
        "{CAMERA}[material.glass]\ncolor = [1, 0.5, 0.25]\nka = 0.2\nkd = 0.4\nks = 0.5\n\
         shine = 50\nkst = 0.3\nshine_t = 60\nkr = [0.1, 0.2, 0.3]\nkt = 0.9\nior = 1.5\n\
         absorption = 0.05\n[material.plain]\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"glass\"\n"
    ));
    // index 0 is always the built-in default; the others in name order
    assert_eq!(s.materials.len(), 3);
    assert_eq!(s.materials[0], Material::default());
    let g = &s.materials[1];
    assert_eq!(g.name, "glass");
    assert_eq!(g.ka, v(0.2, 0.1, 0.05));
    assert_eq!(g.kd, v(0.4, 0.2, 0.1));
    assert_eq!((g.ksr, g.nr, g.kst, g.nt), (0.5, 50.0, 0.3, 60.0));
    assert_eq!(g.kr, v(0.1, 0.2, 0.3));
    assert_eq!(g.kt, DVec3::splat(0.9));
    assert_eq!(g.ior, 1.5);
    assert_eq!(g.absorption, DVec3::splat(0.05));
    let p = &s.materials[2];
    assert_eq!(p.name, "plain");
    assert_eq!((p.ka, p.kd), (DVec3::splat(0.1), DVec3::splat(0.9)));
    assert_eq!(
        (p.ksr, p.nr, p.kst, p.nt, p.ior),
        (0.0, 20.0, 0.0, 20.0, 1.0)
    );
    assert_eq!(
        (p.kr, p.kt, p.absorption),
        (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO)
    );
    assert_eq!(s.objects[0].material, 1);
}

#[test]
fn every_shape_type() {
    let s = toml_ok(&format!(
        r#"{CAMERA}
[[object]]
type = "sphere"
center = [1, 2, 3]
radius = 0.5

[[object]]
type = "plane"
point = [0, 0, -1]
normal = [0, 0, 2]

[[object]]
type = "polygon"
vertices = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]]

[[object]]
type = "triangle"
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
normals = [[0, 0, 1], [0, 0.1, 1], [0.1, 0, 1]]

[[object]]
type = "triangle"
vertices = [[0, 0, 1], [1, 0, 1], [0, 1, 1]]

[[object]]
type = "box"
min = [-1, -1, -1]
max = [1, 2, 3]

[[object]]
type = "quadric"
coefficients = [1, 1, -1, 0, 0, 0, 0, 0, 0, -0.25]
clip = {{ min = [-2, -2, -1], max = [2, 2, 1] }}

[[object]]
type = "quadric"
coefficients = [1, 1, 0, 0, 0, 0, 0, 0, -1, 0]

[[object]]
type = "cone"
base = [0, 0, 0]
base_radius = 1
apex = [0, 0, 2]
apex_radius = 0.25

[[object]]
type = "cylinder"
base = [0, 0, 0]
apex = [0, 0, 2]
radius = 0.5

[[object]]
type = "mesh"
positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
triangles = [[0, 1, 2], [0, 2, 3]]
normals = [[0, 0, 1], [0, 0, 1], [-1, 0, 0], [-1, 0, 0]]
"#
    ));
    let shapes: Vec<&Shape> = s.objects.iter().map(|o| &o.shape).collect();
    assert_eq!(shapes.len(), 11);
    assert_eq!(
        *shapes[0],
        Shape::Sphere {
            center: v(1.0, 2.0, 3.0),
            radius: 0.5
        }
    );
    assert_eq!(
        *shapes[1],
        Shape::Plane {
            point: v(0.0, 0.0, -1.0),
            normal: v(0.0, 0.0, 2.0)
        }
    );
    let Shape::Polygon { vertices } = shapes[2] else {
        panic!("{:?}", shapes[2])
    };
    assert_eq!(vertices.len(), 6);
    assert_eq!(vertices[4], v(1.0, 2.0, 0.0));
    assert_eq!(
        *shapes[3],
        Shape::Triangle {
            vertices: [DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: Some(Box::new([DVec3::Z, v(0.0, 0.1, 1.0), v(0.1, 0.0, 1.0)])),
        }
    );
    assert!(matches!(shapes[4], Shape::Triangle { normals: None, .. }));
    assert_eq!(
        *shapes[5],
        Shape::Box {
            min: DVec3::splat(-1.0),
            max: v(1.0, 2.0, 3.0)
        }
    );
    assert_eq!(
        *shapes[6],
        Shape::Quadric {
            coefficients: [1.0, 1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.25],
            clip: Some((v(-2.0, -2.0, -1.0), v(2.0, 2.0, 1.0))),
        }
    );
    assert!(matches!(shapes[7], Shape::Quadric { clip: None, .. }));
    assert_eq!(
        *shapes[8],
        Shape::Cone {
            base: DVec3::ZERO,
            base_radius: 1.0,
            apex: v(0.0, 0.0, 2.0),
            apex_radius: 0.25
        }
    );
    assert_eq!(
        *shapes[9],
        Shape::Cone {
            base: DVec3::ZERO,
            base_radius: 0.5,
            apex: v(0.0, 0.0, 2.0),
            apex_radius: 0.5
        }
    );
    let Shape::Mesh(m) = shapes[10] else {
        panic!("{:?}", shapes[10])
    };
    assert_eq!(m.positions.len(), 4);
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.normals.as_ref().unwrap()[2], v(-1.0, 0.0, 0.0));
    assert!(s.objects.iter().all(|o| o.material == 0));
}

// ------------------------------------------------------------------ .obj

const QUAD_OBJ: &str = "# a unit quad in z = 0, as one face\n\
    v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
    o second\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 5 6 7\n";

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn obj_mesh_relative_to_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "models/quad.obj", QUAD_OBJ);
    let scene_path = write(
        dir.path(),
        "scene.toml",
        &format!(
            "{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"models/quad.obj\"\n\
             [[object]]\ntype = \"mesh\"\nfile = \"models/quad.obj\"\nsmooth = true\n"
        ),
    );
    let s = scene::load(&scene_path).unwrap_or_else(|e| panic!("{e}"));
    let Shape::Mesh(flat) = &s.objects[0].shape else {
        panic!("not a mesh")
    };
    // the quad is triangulated, the two models are merged
    assert_eq!(flat.triangles.len(), 3);
    assert_eq!(flat.positions.len(), 7);
    assert_eq!(flat.normals, None);
    let Shape::Mesh(smooth) = &s.objects[1].shape else {
        panic!("not a mesh")
    };
    let normals = smooth.normals.as_ref().unwrap();
    assert_eq!(normals.len(), 7);
    for n in normals {
        assert!((*n - DVec3::Z).length() < 1e-12, "{n}");
    }
}

#[test]
fn missing_obj_points_at_the_file_value() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = write(
        dir.path(),
        "scene.toml",
        &format!("{CAMERA}\n[[object]]\ntype = \"mesh\"\nfile = \"nothere.obj\"\n"),
    );
    let e = scene::load(&scene_path).unwrap_err();
    assert_err(&e, 7, 8, "cannot read mesh");
    assert!(e.message().contains("nothere.obj"), "{e}");
    assert_eq!(e.file(), scene_path);
    assert!(e
        .to_string()
        .starts_with(&format!("{}:7:8: ", scene_path.display())));
}

#[test]
fn malformed_obj_points_at_the_file_value() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "broken.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
    );
    let scene_path = write(
        dir.path(),
        "scene.toml",
        &format!("{CAMERA}[[object]]\ntype = \"mesh\"\nsmooth = true\nfile = \"broken.obj\"\n"),
    );
    let e = scene::load(&scene_path).unwrap_err();
    assert_err(&e, 7, 8, "bad mesh");
    assert!(e.message().contains("broken.obj"), "{e}");
    assert!(e.message().contains("out of bounds"), "{e}");
}

// ----------------------------------------------------------------- TOML, bad

#[test]
fn unknown_key() {
    let e = toml_err(&format!(
        "{CAMERA}\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradus = 1\n"
    ));
    assert_err(&e, 8, 1, "unknown field `radus`, expected one of");
    assert!(
        e.to_string()
            .starts_with("scenes/bad.toml:8:1: unknown field `radus`"),
        "{e}"
    );
    let e = toml_err(&format!(
        "{CAMERA}[[light]]\nposition = [0, 0, 9]\nintensity = 2\n"
    ));
    assert_err(&e, 6, 1, "unknown field `intensity`");
}

#[test]
fn missing_required_fields() {
    // the camera table has no `at`: reported at its header
    let e = toml_err("background = 0.5\n[camera]\nfrom = [0, -8, 3]\n");
    assert_err(&e, 2, 1, "missing field `at`");
    // no camera at all
    let e = toml_err("background = 0.5\n");
    assert_err(&e, 1, 1, "missing field `camera`");
    // a sphere without radius: reported at its `type`
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\n"
    ));
    assert_err(&e, 5, 8, "a sphere needs `radius`");
    // an object without type: reported at its header
    let e = toml_err(&format!("{CAMERA}\n[[object]]\ncenter = [0, 0, 0]\n"));
    assert_err(&e, 5, 1, "missing field `type`");
    // a light without position
    let e = toml_err(&format!("{CAMERA}[[light]]\ncolor = 1\n"));
    assert_err(&e, 4, 1, "missing field `position`");
}

#[test]
fn nan_and_inf_are_rejected_at_the_value() {
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = nan\n"
    ));
    assert_err(&e, 7, 10, "radius must be a finite number, got NaN");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, inf, 0]\nradius = 1\n"
    ));
    assert_err(&e, 6, 14, "center must be a finite number, got inf");
    let e = toml_err(&format!("{CAMERA}[material.m]\nior = -inf\n"));
    assert_err(&e, 5, 7, "ior must be a finite number, got -inf");
    let e = toml_err(&format!("background = [0, nan, 0]\n{CAMERA}"));
    assert_err(&e, 1, 18, "background must be a finite number, got NaN");
}

#[test]
fn zero_radius() {
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0\n"
    ));
    assert_err(&e, 7, 10, "radius must be > 0, got 0");
    assert_eq!(
        e.to_string(),
        "scenes/bad.toml:7:10: radius must be > 0, got 0"
    );
}

#[test]
fn degenerate_polygon() {
    // all on a line
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"polygon\"\nvertices = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]\n"
    ));
    assert_err(&e, 6, 12, "degenerate polygon: its area is zero");
    // two consecutive vertices equal: points at the repeated vertex
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"polygon\"\n\
         vertices = [[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]]\n"
    ));
    assert_err(&e, 6, 35, "vertices 2 and 3 are equal");
    // not planar: points at the vertex furthest off the plane
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"polygon\"\n\
         vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0.5, 1.5, 0.5], [0, 1, 0]]\n"
    ));
    assert_err(&e, 6, 46, "not planar: vertex 4 is");
    // fewer than 3 vertices
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"polygon\"\nvertices = [[0, 0, 0], [1, 0, 0]]\n"
    ));
    assert_err(&e, 6, 12, "at least 3 vertices, got 2");
    // a zero-area triangle
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"triangle\"\nvertices = [[0, 0, 0], [1, 1, 1], [2, 2, 2]]\n"
    ));
    assert_err(&e, 6, 12, "degenerate triangle");
}

#[test]
fn ior_must_be_positive() {
    let e = toml_err(&format!("{CAMERA}[material.glass]\nkt = 0.9\nior = 0\n"));
    assert_err(&e, 6, 7, "ior must be > 0, got 0");
    let e = toml_err(&format!("{CAMERA}[material.glass]\nior = -1.5\n"));
    assert_err(&e, 5, 7, "ior must be > 0, got -1.5");
}

#[test]
fn other_toml_constraints() {
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 0, 1]\n"
    ));
    assert_err(&e, 6, 7, "box `min` must be < `max`");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"gold\"\n"
    ));
    assert_err(&e, 8, 12, "unknown material \"gold\"");
    let e = toml_err(&format!("{CAMERA}[[object]]\ntype = \"torus\"\n"));
    assert_err(&e, 5, 8, "unknown object type \"torus\"");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"quadric\"\ncoefficients = [0, 0, 0, 0, 0, 0, 0, 0, 0, 1]\n"
    ));
    assert_err(&e, 6, 16, "A..I are all zero");
    let e = toml_err(&format!("{CAMERA}up = [0, 0, 0]\n"));
    assert_err(&e, 4, 6, "camera `up` must not be zero");
    let e = toml_err("[camera]\nfrom = [0, 0, 3]\nat = [0, 0, 0]\nup = [0, 0, 1]\n");
    assert_err(&e, 4, 6, "parallel to the view direction");
    let e = toml_err(&format!("{CAMERA}fov = 0\n"));
    assert_err(&e, 4, 7, "fov must be in (0, 180) degrees, got 0");
    let e = toml_err(&format!("{CAMERA}width = 0\n"));
    assert_err(&e, 4, 9, "camera.width must be in 1..=65536, got 0");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n"
    ));
    assert_err(&e, 7, 10, "plane normal must not be the zero vector");
    let e = toml_err(&format!("{CAMERA}[material.m]\nabsorption = -0.5\n"));
    assert_err(&e, 5, 14, "absorption must be >= 0");
    let e = toml_err(&format!("{CAMERA}[material.m]\nshine = \"high\"\n"));
    assert_err(&e, 5, 9, "invalid type: string \"high\"");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = 1\nradius = 1\n"
    ));
    assert_err(&e, 6, 10, "center must be an array of 3 numbers");
    let e = toml_err(&format!("{CAMERA}camera = 1\n"));
    assert_err(&e, 4, 1, "unknown field `camera`");
    // a TOML syntax error keeps its position too
    let e = toml_err("[camera\nfrom = [0, 0, 1]\n");
    assert_eq!(e.line(), Some(1));
}

#[test]
fn missing_scene_file_is_an_io_error() {
    let e = scene::load(Path::new("/definitely/not/here.toml")).unwrap_err();
    assert_eq!(e.line(), None);
    assert!(
        e.to_string()
            .starts_with("/definitely/not/here.toml: cannot read /definitely/not/here.toml: "),
        "{e}"
    );
}

// ---------------------------------------------------------------------- NFF

const NFF_VIEW: &str =
    "v\nfrom 0 -10 2\nat 0 0 0\nup 0 0 1\nangle 30\nhither 1\nresolution 400 300\n";

#[test]
fn nff_view_and_background() {
    let s = nff_ok(&format!("{NFF_VIEW}b 0.1 0.2 0.3\n"));
    assert_eq!(s.camera.from, v(0.0, -10.0, 2.0));
    assert_eq!(s.camera.at, DVec3::ZERO);
    assert_eq!(s.camera.up, DVec3::Z);
    assert_eq!(s.camera.fov, 30.0);
    assert_eq!((s.camera.width, s.camera.height), (400, 300));
    assert_eq!(s.background, v(0.1, 0.2, 0.3));
    // no lights: no ambient
    assert_eq!(s.ambient, DVec3::ZERO);
    let s = nff_ok("v from 0 -10 2 at 0 0 0 up 0 0 1 angle 30 hither 0.1");
    assert_eq!((s.camera.width, s.camera.height), (512, 512));
}

#[test]
fn nff_light_colour_rule() {
    let s = nff_ok(&format!(
        "{NFF_VIEW}l 1 2 3\nl 4 5 6 0.9 0.8 0.7\nl 7 8 9\ns 0 0 0 1\n"
    ));
    let w = 3f64.sqrt() / 6.0; // sqrt(L)/(2L) with L = 3
    assert_eq!(s.lights.len(), 3);
    assert_eq!(s.lights[0].position, v(1.0, 2.0, 3.0));
    assert_eq!(s.lights[0].color, DVec3::splat(w));
    assert_eq!(s.lights[1].color, v(0.9, 0.8, 0.7));
    assert_eq!(s.lights[2].position, v(7.0, 8.0, 9.0));
    assert_eq!(s.lights[2].color, DVec3::splat(w));
    assert_eq!(s.ambient, DVec3::splat(w));
    assert!(s.lights.iter().all(|l| l.falloff == [1.0, 0.0, 0.0]));
    let one = nff_ok(&format!("{NFF_VIEW}l 1 2 3\n"));
    assert_eq!(one.lights[0].color, DVec3::splat(0.5));
    assert_eq!(one.ambient, DVec3::splat(0.5));
}

#[test]
fn nff_f_mapping_and_default_material() {
    let s = nff_ok(&format!(
        "{NFF_VIEW}s 0 0 0 1\nf 1 0.5 0.25 0.6 0.3 12 0.2 1.33\ns 0 0 3 1\n\
         f 1 0.5 0.25 0.6 0.3 12 0.2 1.33\ns 0 0 6 1\n"
    ));
    assert_eq!(s.materials.len(), 2, "identical `f` lines share a material");
    assert_eq!(s.materials[0], Material::default());
    let m = &s.materials[1];
    let c = v(1.0, 0.5, 0.25);
    assert_eq!(m.ka, c * 0.6);
    assert_eq!(m.kd, c * 0.6);
    assert_eq!(m.ksr, 0.3);
    assert_eq!(m.nr, 12.0);
    assert_eq!(m.kr, DVec3::splat(0.3));
    assert_eq!(m.kt, DVec3::splat(0.2));
    assert_eq!(m.ior, 1.33);
    assert_eq!(m.kst, 0.0);
    assert_eq!(m.absorption, DVec3::ZERO);
    let mats: Vec<u32> = s.objects.iter().map(|o| o.material).collect();
    assert_eq!(mats, [0, 1, 1]);
}

#[test]
fn nff_cone_on_one_line_or_three() {
    let one = nff_ok(&format!("{NFF_VIEW}c 0 0 0 1 0 0 2 0.5\n"));
    let three = nff_ok(&format!("{NFF_VIEW}c\n0 0 0 1\n0 0 2 0.5\n"));
    let expected = Shape::Cone {
        base: DVec3::ZERO,
        base_radius: 1.0,
        apex: v(0.0, 0.0, 2.0),
        apex_radius: 0.5,
    };
    assert_eq!(one.objects[0].shape, expected);
    assert_eq!(three.objects[0].shape, expected);
    let cyl = nff_ok(&format!("{NFF_VIEW}c 0 0 0 0.3\n  1 1 1 0.3\n"));
    assert!(matches!(
        cyl.objects[0].shape,
        Shape::Cone { base_radius: r0, apex_radius: r1, .. } if r0 == 0.3 && r1 == 0.3
    ));
}

#[test]
fn nff_polygons_and_patches() {
    let s = nff_ok(&format!(
        "{NFF_VIEW}p 3\n0 0 0\n1 0 0\n0 1 0\n\
         p 4 0 0 1 1 0 1 1 1 1 0 1 1\n\
         pp 3\n0 0 0 0 0 1\n1 0 0 0 0.1 1\n0 1 0 0.1 0 1\n\
         pp 4\n0 0 2 0 0 1\n1 0 2 0 0 1\n1 1 2 0 0 1\n0 1 2 0 0 1\n"
    ));
    assert_eq!(s.objects.len(), 5);
    assert_eq!(
        s.objects[0].shape,
        Shape::Polygon {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y]
        }
    );
    let Shape::Polygon { vertices } = &s.objects[1].shape else {
        panic!("{:?}", s.objects[1].shape)
    };
    assert_eq!(vertices.len(), 4);
    assert_eq!(
        s.objects[2].shape,
        Shape::Triangle {
            vertices: [DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: Some(Box::new([DVec3::Z, v(0.0, 0.1, 1.0), v(0.1, 0.0, 1.0)])),
        }
    );
    // pp 4 is fanned from its first vertex
    assert_eq!(
        s.objects[3].shape,
        Shape::Triangle {
            vertices: [v(0.0, 0.0, 2.0), v(1.0, 0.0, 2.0), v(1.0, 1.0, 2.0)],
            normals: Some(Box::new([DVec3::Z; 3])),
        }
    );
    assert_eq!(
        s.objects[4].shape,
        Shape::Triangle {
            vertices: [v(0.0, 0.0, 2.0), v(1.0, 1.0, 2.0), v(0.0, 1.0, 2.0)],
            normals: Some(Box::new([DVec3::Z; 3])),
        }
    );
}

#[test]
fn nff_comments() {
    let s = nff_ok(&format!(
        "# a comment line\n{NFF_VIEW}s 0 0 0 1 # a sphere\n# s 9 9 9 9\ns 1#comment right after\n 2 3 4\n"
    ));
    assert_eq!(s.objects.len(), 2);
    assert_eq!(
        s.objects[1].shape,
        Shape::Sphere {
            center: v(1.0, 2.0, 3.0),
            radius: 4.0
        }
    );
}

// ----------------------------------------------------------------- NFF, bad

#[test]
fn nff_truncated_entity() {
    let e = nff_err(&format!("{NFF_VIEW}s 0 0 0 1\ns 1 2\n   3\n"));
    assert_err(
        &e,
        10,
        4,
        "truncated `s` entity at end of file: expected radius",
    );
    let e = nff_err(&format!("{NFF_VIEW}f 1 1 1 0.5 0.5 3 0\n"));
    assert_err(
        &e,
        8,
        19,
        "truncated `f` entity at end of file: expected index of refraction",
    );
    let e = nff_err(&format!("{NFF_VIEW}p 4\n0 0 0\n1 0 0\n1 1 0\n"));
    assert_err(
        &e,
        11,
        5,
        "truncated `p` entity at end of file: expected vertex 4 of 4 x",
    );
}

#[test]
fn nff_unknown_entity_and_bad_number() {
    let e = nff_err(&format!("{NFF_VIEW}s 0 0 0 1\nsphere 0 0 0 1\n"));
    assert_err(&e, 9, 1, "unknown NFF entity `sphere`");
    let e = nff_err(&format!("{NFF_VIEW}l 1 2 three\n"));
    assert_err(
        &e,
        8,
        7,
        "expected light position z (a number) in `l` entity, found `three`",
    );
    // one number short: the next entity's keyword is where a number was due
    let e = nff_err(&format!("{NFF_VIEW}s 0 0 1\ns 0 0 0 1\n"));
    assert_err(
        &e,
        9,
        1,
        "expected radius (a number) in `s` entity, found `s`",
    );
}

#[test]
fn nff_nan_and_inf() {
    let e = nff_err(&format!("{NFF_VIEW}s 0 nan 0 1\n"));
    assert_err(&e, 8, 5, "must be a finite number, got `nan`");
    let e = nff_err(&format!("{NFF_VIEW}c 0 0 0 1\n 0 0 inf 1\n"));
    assert_err(
        &e,
        9,
        6,
        "apex z in `c` entity must be a finite number, got `inf`",
    );
}

#[test]
fn nff_zero_radius() {
    let e = nff_err(&format!("{NFF_VIEW}s 0 0 0 1\ns 1 1 1 0\n"));
    assert_err(&e, 9, 9, "radius must be > 0, got 0");
    assert_eq!(e.to_string(), "bad.nff:9:9: radius must be > 0, got 0");
}

#[test]
fn nff_degenerate_polygon() {
    let e = nff_err(&format!("{NFF_VIEW}p 3\n0 0 0\n1 1 1\n2 2 2\n"));
    assert_err(&e, 8, 1, "degenerate polygon: its area is zero");
    let e = nff_err(&format!("{NFF_VIEW}p 4\n0 0 0\n1 0 0\n1 0 0\n0 1 0\n"));
    assert_err(&e, 11, 1, "vertices 2 and 3 are equal");
    let e = nff_err(&format!(
        "{NFF_VIEW}pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 0\n"
    ));
    assert_err(&e, 11, 7, "a vertex normal must not be the zero vector");
}

#[test]
fn nff_ior_must_be_positive() {
    let e = nff_err(&format!("{NFF_VIEW}f 1 1 1 0.5 0.5 3 0.5 0\n"));
    assert_err(&e, 8, 23, "ior must be > 0, got 0");
    let e = nff_err(&format!("{NFF_VIEW}f 1 1 1 0.5 0.5 3 0.5 -1.5\n"));
    assert_err(&e, 8, 23, "ior must be > 0, got -1.5");
}

#[test]
fn nff_opaque_ior_zero_reads_as_one() {
    // The SPD's generators write `T = 0, ior = 0` for opaque surfaces.
    let s = nff_ok(&format!("{NFF_VIEW}f 1 1 1 0.5 0.5 3 0 0\ns 0 0 0 1\n"));
    assert_eq!(s.materials[s.objects[0].material as usize].ior, 1.0);
}

#[test]
fn nff_view_errors() {
    let e = nff_err("v\nfrom 0 0 5\nat 0 0 0\nup 0 0 1\nangle 40\n");
    assert_err(&e, 4, 4, "parallel to the view direction");
    let e = nff_err("v\nfrom 0 0 5\nat 0 1 0\nup 0 0 1\nangle 180\n");
    assert_err(&e, 5, 7, "fov must be in (0, 180) degrees, got 180");
    let e = nff_err("v\nfrom 0 -5 0\nat 0 0 0\nup 0 0 1\n");
    assert_err(&e, 1, 1, "the `v` block has no `angle`");
    let e = nff_err("s 0 0 0 1\n");
    assert_eq!(e.to_string(), "bad.nff: no `v` (viewpoint) block");
}

#[test]
fn nff_file_loads_through_load() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "x.NFF",
        &format!("{NFF_VIEW}l 0 0 9\ns 0 0 0 1\n"),
    );
    let s = scene::load(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.source, p);
}

// ------------------------------------------------------------ example scenes

#[test]
fn example_scenes_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml" || e == "nff") {
            let s = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(!s.objects.is_empty(), "{}", path.display());
            assert!(!s.lights.is_empty(), "{}", path.display());
            names.push(path.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    names.sort();
    for expected in ["mesh.toml", "quadric.toml", "showcase.toml"] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing: {names:?}"
        );
    }
}

#[test]
fn showcase_has_glass_and_mirror() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/showcase.toml");
    let s = scene::load(&path).unwrap();
    let glass = s.materials.iter().find(|m| m.name == "glass").unwrap();
    assert_eq!(glass.ior, 1.5);
    assert_eq!(glass.kt, DVec3::splat(0.9));
    assert!(glass.absorption.max_element() > 0.0);
    assert!(s
        .materials
        .iter()
        .any(|m| m.name == "mirror" && m.kr.x > 0.5));
    assert_eq!(s.lights.len(), 2);
}

#[test]
fn mesh_scene_is_smooth() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/mesh.toml");
    let s = scene::load(&path).unwrap();
    let Some(Shape::Mesh(m)) = s
        .objects
        .iter()
        .map(|o| &o.shape)
        .find(|sh| matches!(sh, Shape::Mesh(m) if m.positions.len() == 42))
    else {
        panic!("no icosphere")
    };
    assert_eq!(m.triangles.len(), 80);
    let n = m.normals.as_ref().unwrap();
    for (p, n) in m.positions.iter().zip(n) {
        // a unit sphere's vertex normal is (nearly) its position
        assert!((*p - *n).length() < 0.05, "{p} {n}");
    }
}
