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
    assert_err(&e, 7, 8, "mesh ");
    assert!(
        e.message()
            .ends_with("broken.obj:4: vertex index 7 is out of range: 3 defined before this line"),
        "{e}"
    );
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
    assert_err(&e, 6, 7, "box min must be < max");
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
    assert_err(&e, 4, 6, "camera.up must not be the zero vector");
    let e = toml_err("[camera]\nfrom = [0, 0, 3]\nat = [0, 0, 0]\nup = [0, 0, 1]\n");
    assert_err(&e, 4, 6, "parallel to the view direction");
    let e = toml_err(&format!("{CAMERA}fov = 0\n"));
    assert_err(&e, 4, 7, "fov must be in (0, 180) degrees, got 0");
    let e = toml_err(&format!("{CAMERA}width = 0\n"));
    assert_err(&e, 4, 9, "camera.width must be in 1..=65536, got 0");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n"
    ));
    assert_err(&e, 7, 10, "normal must not be the zero vector");
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
            .starts_with("/definitely/not/here.toml: cannot read: No such file or directory"),
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
    assert_err(&e, 8, 5, "center must be a finite number, got NaN");
    let e = nff_err(&format!("{NFF_VIEW}c 0 0 0 1\n 0 0 inf 1\n"));
    assert_err(&e, 9, 6, "apex must be a finite number, got inf");
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
    assert_err(&e, 11, 7, "vertex normal must not be the zero vector");
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

// ------------------------------------------ one table for both formats

/// The NFF view of these tests as a TOML camera: the same camera, so that
/// camera-relative messages agree too.
const TOML_CAM: &str =
    "[camera]\nfrom = [0, -10, 2]\nat = [0, 0, 0]\nfov = 30\nwidth = 400\nheight = 300\n";

/// `text` with one `@` marking where an error must point: the text
/// without it, and the marker's 1-based line and column.
fn marked(text: &str) -> (String, usize, usize) {
    let i = text.find('@').expect("a marker");
    let before = &text[..i];
    let line = before.matches('\n').count() + 1;
    let col = before[before.rfind('\n').map_or(0, |j| j + 1)..]
        .chars()
        .count()
        + 1;
    (text.replacen('@', "", 1), line, col)
}

fn sphere_toml(center: &str, radius: &str) -> String {
    format!("{TOML_CAM}[[object]]\ntype = \"sphere\"\ncenter = {center}\nradius = {radius}\n")
}

fn material_toml(keys: &str) -> String {
    format!("{TOML_CAM}[material.m]\n{keys}\n")
}

/// (NFF text, TOML text, the message both must give): the same bad value
/// in each format, `@` where the error must point.
fn cross_format_cases() -> Vec<(String, String, &'static str)> {
    let n = |body: &str| format!("{NFF_VIEW}{body}\n");
    let view = |from: &str, at: &str, up: &str, angle: &str, res: &str| {
        format!("v\nfrom {from}\nat {at}\nup {up}\nangle {angle}\nresolution {res}\n")
    };
    let cam = |keys: &str| format!("[camera]\n{keys}\n");
    vec![
        // material coefficients: NFF `f r g b Kd Ks Shine T ior`
        (n("f 1 1 1 @-0.5 0 1 0 0"), material_toml("kd = @-0.5"), "kd must be >= 0, got -0.5"),
        (
            n("f 1 1 1 @2e6 0 1 0 0"),
            material_toml("kd = @2e6"),
            "kd must be at most 1e6, got 2e6: larger factors can overflow f32 in the shading sums",
        ),
        (n("f 1 @-0.1 1 0.5 0 1 0 0"), material_toml("color = [1, @-0.1, 1]"), "color must be >= 0, got -0.1"),
        (n("f 1 1 1 0.5 0 @-3 0 0"), material_toml("shine = @-3"), "shine must be >= 0, got -3"),
        (
            n("f 1 1 1 0.5 0 @1e7 0 0"),
            material_toml("shine = @1e7"),
            "shine must be at most 1e6, got 1e7: a sharper highlight is finer than f32 can resolve",
        ),
        (
            n("f 1 1 1 0.5 0 1 @1.5 1.5"),
            material_toml("kt = @1.5"),
            "kt must be at most 1, got 1.5: a surface cannot pass on more light than it receives",
        ),
        (n("f 1 1 1 0.5 0 1 @-0.25 1"), material_toml("kt = @-0.25"), "kt must be >= 0, got -0.25"),
        (n("f 1 1 1 0.5 0 1 0.5 @-1.5"), material_toml("kt = 0.5\nior = @-1.5"), "ior must be > 0, got -1.5"),
        (
            n("f 1 1 1 0.5 0 1 0.5 @1e19"),
            material_toml("ior = @1e19"),
            "ior must be at most 1e18 in magnitude, got 1e19: beyond it its square overflows f32",
        ),
        (n("f 1 1 1 0.5 0 1 0.5 @nan"), material_toml("ior = @nan"), "ior must be a finite number, got NaN"),
        // background and lights
        (
            n("b 0 @-1 0"),
            format!("background = [0, @-1, 0]\n{TOML_CAM}"),
            "background must be >= 0, got -1",
        ),
        (
            n("l 0 0 9 @-1 1 1"),
            format!("{TOML_CAM}[[light]]\nposition = [0, 0, 9]\ncolor = [@-1, 1, 1]\n"),
            "light color must be >= 0, got -1",
        ),
        (
            n("l 0 0 9 1 @1e39 1"),
            format!("{TOML_CAM}[[light]]\nposition = [0, 0, 9]\ncolor = [1, @1e39, 1]\n"),
            "light color must be at most 1e6, got 1e39",
        ),
        // sphere values
        (n("s 0 0 0 @0"), sphere_toml("[0, 0, 0]", "@0"), "radius must be > 0, got 0"),
        (n("s 0 0 0 @-1"), sphere_toml("[0, 0, 0]", "@-1"), "radius must be > 0, got -1"),
        (
            n("s 0 0 0 @1e-120"),
            sphere_toml("[0, 0, 0]", "@1e-120"),
            "radius must be at least 1e-18 in magnitude, got 1e-120: below it its square underflows f32",
        ),
        (
            n("s 0 0 0 @5e-324"),
            sphere_toml("[0, 0, 0]", "@5e-324"),
            "radius must be at least 1e-18 in magnitude, got 5e-324",
        ),
        (
            n("s 0 0 0 @1e20"),
            sphere_toml("[0, 0, 0]", "@1e20"),
            "radius must be at most 1e18 in magnitude, got 1e20: beyond it its square overflows f32",
        ),
        (n("s 0 0 0 @nan"), sphere_toml("[0, 0, 0]", "@nan"), "radius must be a finite number, got NaN"),
        (n("s 0 @inf 0 1"), sphere_toml("[0, @inf, 0]", "1"), "center must be a finite number, got inf"),
        // cones
        (
            n("@c 0 0 0 1 0 0 1 -1"),
            format!(
                "{TOML_CAM}[[object]]\ntype = @\"cone\"\nbase = [0, 0, 0]\nbase_radius = 1\n\
                 apex = [0, 0, 1]\napex_radius = -1\n"
            ),
            "cone radii must have the same sign (negative = inside visible), got 1 and -1",
        ),
        (
            n("c 0 0 0 @1e-19 0 0 1 0"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"cone\"\nbase = [0, 0, 0]\nbase_radius = @1e-19\n\
                 apex = [0, 0, 1]\napex_radius = 0\n"
            ),
            "base_radius must be at least 1e-18 in magnitude, got 1e-19",
        ),
        // polygons and normals
        (
            n("@p 3 0 0 0 1 1 1 2 2 2"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"polygon\"\nvertices = @[[0, 0, 0], [1, 1, 1], [2, 2, 2]]\n"
            ),
            "degenerate polygon: its area is zero (all vertices on a line)",
        ),
        (
            n("p 5 0 0 0 1 0 0 1 1 0 @0.5 1.5 0.5 0 1 0"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"polygon\"\n\
                 vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], @[0.5, 1.5, 0.5], [0, 1, 0]]\n"
            ),
            "polygon is not planar: vertex 4 is",
        ),
        (
            n("pp 3 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 @0 0 0"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"triangle\"\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n\
                 normals = [[0, 0, 1], [0, 0, 1], @[0, 0, 0]]\n"
            ),
            "vertex normal must not be the zero vector",
        ),
        // the camera
        (
            view("0 -10 2", "0 0 0", "@0 0 0", "30", "400 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nup = @[0, 0, 0]"),
            "camera.up must not be the zero vector",
        ),
        (
            view("0 -10 2", "0 0 0", "@0 0 1e-19", "30", "400 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nup = @[0, 0, 1e-19]"),
            "camera.up length must be at least 1e-18 in magnitude, got 1e-19",
        ),
        (
            view("0 -10 2", "0 0 0", "0 0 1", "@180", "400 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nfov = @180"),
            "camera.fov must be in (0, 180) degrees, got 180",
        ),
        (
            view("0 -10 2", "0 0 0", "0 0 1", "30", "@0 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nwidth = @0"),
            "camera.width must be in 1..=65536, got 0",
        ),
        (
            view("0 -10 2", "0 0 0", "0 0 1", "30", "400 @70000"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nheight = @70000"),
            "camera.height must be in 1..=65536, got 70000",
        ),
        (
            view("0 -10 2", "0 0 2", "@0 1 0", "30", "400 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 2]\nup = @[0, 1, 0]"),
            "camera.up [0, 1, 0] is parallel to the view direction [0, 10, 0]",
        ),
        // f32 limits (scene-wide): the same camera in both
        (
            n("s 0 1e6 0 @1e-9"),
            sphere_toml("[0, 1e6, 0]", "@1e-9"),
            "sphere radius 1e-9 is too small for f32 at 1e6 from the camera: it needs at least 0.9537",
        ),
        (
            n("s @0 2e18 0 1"),
            sphere_toml("@[0, 2e18, 0]", "1"),
            "center [0, 2e18, 0] is 2e18 from the camera along an axis: camera-relative \
             coordinates must be within ±1e18",
        ),
        (
            n("s @1e39 0 0 1"),
            sphere_toml("@[1e39, 0, 0]", "1"),
            "center [1e39, 0, 0] is 1e39 from the camera",
        ),
        (
            n("l @0 2e18 0"),
            format!("{TOML_CAM}[[light]]\nposition = @[0, 2e18, 0]\n"),
            "light position [0, 2e18, 0] is 2e18 from the camera",
        ),
        (
            view("0 -10 2", "@0 1e19 0", "0 0 1", "30", "400 300"),
            cam("from = [0, -10, 2]\nat = @[0, 1e19, 0]\nfov = 30\nheight = 300"),
            "camera.at [0, 1e19, 0] is 1e19 from the camera",
        ),
        (
            view("0 -10 2", "0 0 0", "0 0 1", "@1e-5", "400 300"),
            cam("from = [0, -10, 2]\nat = [0, 0, 0]\nfov = @1e-5\nwidth = 400\nheight = 300"),
            "camera.fov 1e-5° is too narrow for f32 at height 300",
        ),
        (
            n("c 0 1e6 0 @1e-9 0 1e6 1 1e-9"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"cone\"\nbase = [0, 1e6, 0]\nbase_radius = @1e-9\n\
                 apex = [0, 1e6, 1]\napex_radius = 1e-9\n"
            ),
            "cone size (min of largest radius, length) 1e-9 is too small for f32",
        ),
        (
            n("@p 3 0 1e6 0 1e-3 1e6 0 0 1e6 1e-3"),
            format!(
                "{TOML_CAM}[[object]]\ntype = \"polygon\"\n\
                 vertices = @[[0, 1e6, 0], [1e-3, 1e6, 0], [0, 1e6, 1e-3]]\n"
            ),
            "polygon width (area / extent) 0.0005 is too small for f32",
        ),
    ]
}

#[test]
fn same_bad_value_same_message_in_both_formats() {
    let cases = cross_format_cases();
    assert!(cases.len() >= 35, "{}", cases.len());
    for (nff, toml, want) in cases {
        let (nff, nl, nc) = marked(&nff);
        let (toml, tl, tc) = marked(&toml);
        let en = scene::parse_str(&nff, Path::new("bad.nff")).expect_err(&nff);
        let et = scene::parse_str(&toml, Path::new("bad.toml")).expect_err(&toml);
        assert_eq!(
            en.message(),
            et.message(),
            "NFF and TOML disagree:\n{nff}\n---\n{toml}"
        );
        assert!(en.message().starts_with(want), "{en}\nwant: {want}");
        assert_eq!(
            (en.line(), en.column()),
            (Some(nl), Some(nc)),
            "NFF location: {en}\n{nff}"
        );
        assert_eq!(
            (et.line(), et.column()),
            (Some(tl), Some(tc)),
            "TOML location: {et}\n{toml}"
        );
    }
}

// ------------------------------------------------------------ f32 limits

/// A sphere of `radius` with centre `y` along the view, in both formats
/// (camera at [0, -10, 2]); `Ok` if both load, else both messages agree.
fn sphere_both(y: f64, radius: f64) -> Result<(), String> {
    let nff = format!("{NFF_VIEW}s 0 {y:?} 2 {radius:?}\n");
    let toml = sphere_toml(&format!("[0, {y:?}, 2]"), &format!("{radius:?}"));
    let a = scene::parse_str(&nff, Path::new("a.nff")).map(|_| ());
    let b = scene::parse_str(&toml, Path::new("a.toml")).map(|_| ());
    match (a, b) {
        (Ok(()), Ok(())) => Ok(()),
        (Err(a), Err(b)) => {
            assert_eq!(a.message(), b.message());
            Err(a.message().to_string())
        }
        (a, b) => panic!("formats disagree: {a:?} {b:?}"),
    }
}

#[test]
fn vanishing_radius_both_sides_of_the_limit() {
    use whitted::scene::{MIN_MAGNITUDE, MIN_SIZE_REL};
    // distance = the largest camera-relative coordinate of the sphere's
    // bounds: centre y + 10 + radius
    for centre in [1e3, 1e6, 1e12, 1e17] {
        let d = centre + 10.0;
        let limit = MIN_SIZE_REL * d;
        sphere_both(centre, limit * 1.001).unwrap();
        let e = sphere_both(centre, limit * 0.999).unwrap_err();
        assert!(e.contains("is too small for f32"), "{e}");
    }
    // at the camera the absolute limit governs
    let nff = |r: f64| format!("v from 0 0 0 at 0 1 0 up 0 0 1 angle 30\ns 0 0 0 {r:?}\n");
    assert!(scene::parse_str(&nff(MIN_MAGNITUDE), Path::new("a.nff")).is_ok());
    let e = scene::parse_str(&nff(MIN_MAGNITUDE * 0.99), Path::new("a.nff")).unwrap_err();
    assert!(
        e.message().starts_with("radius must be at least 1e-18"),
        "{e}"
    );
    // the brief's examples: 1e-9 at 1e6 fails, 1e-3 at 1e3 loads
    assert!(sphere_both(1e6, 1e-9).is_err());
    assert!(sphere_both(1e3, 1e-3).is_ok());
}

#[test]
fn coordinate_overflow_both_sides_of_the_limit() {
    use whitted::scene::MAX_MAGNITUDE;
    // camera-relative y of the centre is y + 10
    sphere_both(MAX_MAGNITUDE - 10.0, 1e12).unwrap();
    let e = sphere_both(MAX_MAGNITUDE * 1.0001, 1e12).unwrap_err();
    assert!(
        e.contains("camera-relative coordinates must be within ±1e18"),
        "{e}"
    );
    // far from the origin but near the camera: fine
    toml_ok(
        "[camera]\nfrom = [1e30, 0, 0]\nat = [1e30, 1, 0]\n\
         [[object]]\ntype = \"sphere\"\ncenter = [1e30, 1e16, 0]\nradius = 1e15\n",
    );
    // a radius at the largest magnitude loads
    sphere_both(0.0, MAX_MAGNITUDE).unwrap();
    assert!(sphere_both(0.0, MAX_MAGNITUDE * 1.0001).is_err());
}

#[test]
fn sizes_of_other_primitives_against_distance() {
    // a box 1e4 away needs sides >= 2^-20 * 1e4 = 0.0095
    let boxed = |side: f64| {
        format!(
            "{TOML_CAM}[[object]]\ntype = \"box\"\nmin = [0, 9990, 0]\nmax = [1, 9991, {side:?}]\n"
        )
    };
    toml_ok(&boxed(0.01));
    let e = toml_err(&boxed(0.009));
    assert_err(
        &e,
        9,
        7,
        "box smallest side 0.009 is too small for f32 at 10000",
    );
    // a mesh is judged as a whole, not by its triangles
    let mesh = |s: f64| {
        format!(
            "{TOML_CAM}[[object]]\ntype = \"mesh\"\n\
             positions = [[0, 1e6, 0], [{s:?}, 1e6, 0], [0, 1e6, {s:?}], [1, 1e6, 1]]\n\
             triangles = [[0, 1, 2], [1, 3, 2]]\n"
        )
    };
    toml_ok(&mesh(1e-3));
    let e = toml_err(&mesh(0.5).replace("[1, 1e6, 1]", "[0.5, 1e6, 0.5]"));
    assert_err(&e, 9, 13, "mesh extent 0.5 is too small for f32 at 1e6");
    // a clipped quadric by its clip box; an unclipped one has no size
    let quadric = |clip: &str| {
        format!(
            "{TOML_CAM}[[object]]\ntype = \"quadric\"\n\
             coefficients = [1, 1, 1, 0, 0, 0, 0, 0, 0, -1]\n{clip}"
        )
    };
    toml_ok(&quadric(""));
    toml_ok(&quadric("clip = { min = [-1, -1, -1], max = [1, 1, 1] }\n"));
    let e = toml_err(&quadric(
        "clip = { min = [-1, 1e7, -1], max = [1, 10000001.5, 1] }\n",
    ));
    assert_err(
        &e,
        10,
        8,
        "quadric clip box's smallest side 1.5 is too small",
    );
    // a quadric far from the camera: coefficients overflow, or A..I vanish
    let far = |from: &str| {
        format!(
            "[camera]\nfrom = [{from}, 0, 0]\nat = [{from}, 1, 0]\n[[object]]\ntype = \"quadric\"\n\
             coefficients = [1, 1, 1, 0, 0, 0, 0, 0, 0, -1]\n"
        )
    };
    toml_ok(&far("1e20"));
    assert_err(
        &toml_err(&far("1e200")),
        6,
        16,
        "quadric coefficients overflow",
    );
    assert_err(
        &toml_err(&far("1e50")),
        6,
        16,
        "quadric coefficients A..I vanish in f32",
    );
}

#[test]
fn narrowest_field_of_view_both_sides() {
    use whitted::scene::MIN_SIZE_REL;
    // 2·tan(fov/2)/height >= 2^-20, at height 300
    let limit = (MIN_SIZE_REL * 300.0 / 2.0).atan().to_degrees() * 2.0;
    let nff =
        |fov: f64| format!("v from 0 -10 2 at 0 0 0 up 0 0 1 angle {fov:?} resolution 400 300\n");
    assert!(scene::parse_str(&nff(limit * 1.001), Path::new("a.nff")).is_ok());
    let e = scene::parse_str(&nff(limit * 0.999), Path::new("a.nff")).unwrap_err();
    assert_err(&e, 1, 40, "too narrow for f32 at height 300");
}

#[test]
fn nff_objects_before_the_view_are_checked_too() {
    // checked after the camera is known, and located by reading again
    let e = nff_err(&format!("l 0 2 0\ns 0 1 0 1\ns 0 1e6 0 1e-9\n{NFF_VIEW}"));
    assert_err(&e, 3, 11, "sphere radius 1e-9 is too small for f32");
    let e = nff_err(&format!(
        "s 0 1 0 1\nl 0 2e18 0\n{NFF_VIEW}s 0 1e6 0 1e-9\n"
    ));
    assert_err(&e, 10, 11, "sphere radius 1e-9 is too small for f32");
    let e = nff_err(&format!("s 0 1 0 1\nl 0 2e18 0\n{NFF_VIEW}"));
    assert_err(
        &e,
        2,
        3,
        "light position [0, 2e18, 0] is 2e18 from the camera",
    );
}

#[test]
fn check_f32_limits_for_scenes_built_in_code() {
    let mut s = nff_ok(&format!("{NFF_VIEW}s 0 0 0 1\n"));
    assert!(scene::check_f32_limits(&s).is_ok());
    s.objects[0].shape = Shape::Sphere {
        center: v(0.0, 1e6, 0.0),
        radius: 1e-9,
    };
    let e = scene::check_f32_limits(&s).unwrap_err();
    assert_eq!(e.line(), None);
    assert!(
        e.message()
            .starts_with("object 0: sphere radius 1e-9 is too small"),
        "{e}"
    );
}

// --------------------------------------------------------------- messages

#[test]
fn io_errors_name_the_path_once() {
    let dir = tempfile::tempdir().unwrap();
    let e = scene::load(dir.path()).unwrap_err();
    let text = e.to_string();
    let path = dir.path().display().to_string();
    assert_eq!(text.matches(&path).count(), 1, "{text}");
    assert!(
        text.starts_with(&format!("{path}: cannot read: ")),
        "{text}"
    );
    // the OS error once
    assert_eq!(text.matches("os error").count(), 1, "{text}");

    let p = dir.path().join("bin.toml");
    std::fs::write(&p, b"[camera]\nfrom = [0, 0, 1]\n# caf\xe9\n").unwrap();
    let e = scene::load(&p).unwrap_err();
    assert_err(&e, 3, 6, "not UTF-8 text: invalid byte 0xe9");

    // a missing .obj: the scene location, then the .obj path once
    let s = write(
        dir.path(),
        "m.toml",
        &format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"gone.obj\"\n"),
    );
    let e = scene::load(&s).unwrap_err();
    let msg = e.message();
    assert_eq!(msg.matches("gone.obj").count(), 1, "{msg}");
    assert_eq!(msg.matches("os error").count(), 1, "{msg}");
}

#[test]
fn integers_beyond_i64_are_out_of_range() {
    let e = nff_err("v from 0 0 1 at 0 0 0 up 0 1 0 angle 40 resolution 18446744073709551615 2\n");
    assert_err(
        &e,
        1,
        52,
        "camera.width must be in 1..=65536, got 18446744073709551615",
    );
    let e = nff_err("v from 0 0 1 at 0 0 0 up 0 1 0 angle 40 resolution 8 -99999999999999999999\n");
    assert_err(
        &e,
        1,
        54,
        "camera.height must be in 1..=65536, got -99999999999999999999",
    );
    let e = nff_err("v from 0 0 1 at 0 0 0 up 0 1 0 angle 40 resolution 8 2.5\n");
    assert_err(&e, 1, 54, "the height must be an integer, got `2.5`");
    let e = toml_err(&format!("{CAMERA}width = 18446744073709551615\n"));
    assert_err(&e, 4, 9, "integer out of range: TOML integers are 64-bit");
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"mesh\"\npositions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n\
         triangles = [[0, 1, 99999999999999999999]]\n"
    ));
    assert_err(&e, 7, 21, "integer out of range");
    // an NFF count beyond what the file holds fails at once, at the count
    let e = nff_err(&format!("{NFF_VIEW}p 18446744073709551615\n0 0 0\n"));
    assert_err(
        &e,
        8,
        3,
        "`p` vertex count 18446744073709551615 is out of range: a polygon has 3 ..= 16777216 vertices",
    );
    let e = nff_err(&format!("{NFF_VIEW}pp 16777217\n0 0 0 0 0 1\n"));
    assert_err(&e, 8, 4, "`pp` vertex count 16777217 is out of range");
    // a plausible count with too few vertices is a truncated entity
    let e = nff_err(&format!("{NFF_VIEW}pp 16777216\n0 0 0 0 0 1\n"));
    assert_err(
        &e,
        9,
        11,
        "truncated `pp` entity at end of file: expected vertex 2 of 16777216 x",
    );
}

#[test]
fn numbers_beyond_f64_are_out_of_range() {
    let e = nff_err(&format!("{NFF_VIEW}s 0 0 0 1e400\n"));
    assert_err(
        &e,
        8,
        9,
        "radius `1e400` is out of range: beyond f64 (magnitudes up to 1.7976931348623157e308)",
    );
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1_0e400\n"
    ));
    assert_err(
        &e,
        7,
        10,
        "radius `-1_0e400` is out of range: beyond f64 (magnitudes up to 1.7976931348623157e308)",
    );
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1e400\n"
    ));
    assert_err(
        &e,
        7,
        10,
        "number out of range: 1e400 is beyond f64 (magnitudes up to 1.7976931348623157e308)",
    );
    // TOML's type names say what they mean
    let e = toml_err(&format!("{CAMERA}width = 2.5\n"));
    assert_err(
        &e,
        4,
        9,
        "invalid type: floating point `2.5`, expected an integer",
    );
}

#[test]
fn zero_cylinder_radius_is_named_as_such() {
    let e = toml_err(&format!(
        "{CAMERA}[[object]]\ntype = \"cylinder\"\nbase = [0, 0, 0]\napex = [0, 0, 1]\nradius = 0\n"
    ));
    assert_err(&e, 8, 10, "cylinder radius must not be 0");
}

#[test]
fn falloff_all_zero_is_refused() {
    let e = toml_err(&format!(
        "{CAMERA}[[light]]\nposition = [0, 0, 9]\nfalloff = [0, 0, 0]\n"
    ));
    assert_err(&e, 6, 11, "falloff must not be [0, 0, 0]");
    let s = toml_ok(&format!(
        "{CAMERA}[[light]]\nposition = [0, 0, 9]\nfalloff = [0, 0, 1e-6]\n"
    ));
    assert_eq!(s.lights[0].falloff, [0.0, 0.0, 1e-6]);
}

#[test]
fn obj_errors_name_the_obj_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene_with = |obj: &str| {
        write(dir.path(), "x.obj", obj);
        write(
            dir.path(),
            "s.toml",
            &format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"x.obj\"\n"),
        )
    };
    let obj = dir.path().join("x.obj").display().to_string();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    for (text, want) in [
        (
            format!("{tri}f 1 2 9\n"),
            ":4: vertex index 9 is out of range: 3 defined before this line",
        ),
        (
            format!("{tri}f 1 2 -9\n"),
            ":4: vertex index -9 is out of range",
        ),
        (
            format!("{tri}f 0 1 2\n"),
            ":4: vertex index 0: .obj indices start at 1",
        ),
        (
            "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n".to_string(),
            ":2: vertex: `nan` is not a finite",
        ),
        (
            "v 0 0 0\nv 1 1e39 0\nv 0 1 0\nf 1 2 3\n".to_string(),
            ":2: vertex: `1e39` is not a finite single-precision number",
        ),
        (
            format!("{tri}vn 0 0 -inf\nf 1//1 2//1 3//1\n"),
            ":4: normal: `-inf` is not a finite",
        ),
        (
            format!("{tri}f 1 2 3x\n"),
            ":4: face vertex `3x`: `3x` is not an index",
        ),
        (
            format!("{tri}f 1 1 2\n"),
            ": it contains no triangles with non-zero area",
        ),
    ] {
        let e = scene::load(&scene_with(&text)).unwrap_err();
        assert_eq!((e.line(), e.column()), (Some(6), Some(8)), "{e}");
        assert!(
            e.message().starts_with(&format!("mesh {obj}{want}")),
            "{text:?}: {e}"
        );
    }
    // a vertex beyond the f32 limits: the .obj line is named too
    let e = scene::load(&scene_with(&format!(
        "{tri}v 2e18 0 0\nv 0 2e18 0\nf 1 4 5\n"
    )))
    .unwrap_err();
    assert_err(&e, 6, 8, "mesh position [");
    assert!(e.message().contains("from the camera along an axis"), "{e}");
    assert!(e.message().ends_with(&format!("(in {obj}:4)")), "{e}");
    // not UTF-8: the .obj line and column
    std::fs::write(dir.path().join("x.obj"), b"v 0 0 0\nv 1 0\xff 0\n").unwrap();
    let e = scene::load(&dir.path().join("s.toml")).unwrap_err();
    assert_err(
        &e,
        6,
        8,
        &format!("mesh {obj}:2:6: not UTF-8 text: invalid byte 0xff"),
    );
    // degenerate faces are dropped, the rest loads
    let s = scene::load(&scene_with(&format!("{tri}v 2 0 0\nf 1 2 4\nf 1 2 3\n"))).unwrap();
    let Shape::Mesh(m) = &s.objects[0].shape else {
        panic!()
    };
    assert_eq!(m.triangles.len(), 1);
}

// ---------------------------------------------------------------- progress

#[test]
fn nff_progress_reaches_the_total() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from(NFF_VIEW);
    for i in 0..120_000 {
        text.push_str(&format!("s {} 0 0 0.25\n", i % 1000));
    }
    let p = write(dir.path(), "big.nff", &text);
    let calls = std::cell::RefCell::new(Vec::new());
    let s = scene::load_with_progress(&p, &|d, t| calls.borrow_mut().push((d, t))).unwrap();
    assert_eq!(s.objects.len(), 120_000);
    let calls = calls.into_inner();
    let total = text.len() as u64;
    assert!(calls.len() >= 3, "{calls:?}");
    assert!(calls.iter().all(|&(_, t)| t == total), "{calls:?}");
    assert!(calls.windows(2).all(|w| w[0].0 <= w[1].0), "{calls:?}");
    assert_eq!(*calls.last().unwrap(), (total, total));
}

#[test]
fn toml_progress_counts_obj_files() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "q.obj", QUAD_OBJ);
    let text = format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"q.obj\"\n");
    let p = write(dir.path(), "s.toml", &text);
    let calls = std::cell::RefCell::new(Vec::new());
    scene::load_with_progress(&p, &|d, t| calls.borrow_mut().push((d, t))).unwrap();
    let calls = calls.into_inner();
    let (n, m) = (text.len() as u64, std::fs::metadata(obj).unwrap().len());
    assert_eq!(calls.first(), Some(&(0, n)));
    assert!(calls.contains(&(n, n + m)), "{calls:?}");
    assert_eq!(calls.last(), Some(&(n + m, n + m)));
}

// --------------------------------------------------------- hostile input

mod hostile {
    use super::*;
    use proptest::prelude::*;

    const NFF_WORDS: &[&str] = &[
        "v",
        "from",
        "at",
        "up",
        "angle",
        "hither",
        "resolution",
        "b",
        "l",
        "f",
        "c",
        "s",
        "p",
        "pp",
        "#",
        "\n",
        "0",
        "1",
        "-1",
        "2.5",
        "1e39",
        "1e-320",
        "5e-324",
        "1e20",
        "nan",
        "inf",
        "-inf",
        "18446744073709551615",
        "3",
        "4",
        "1e6",
        "x",
        "é",
        "\u{a0}",
    ];

    fn nff_text() -> impl Strategy<Value = String> {
        let view = "v from 0 -10 2 at 0 0 0 up 0 0 1 angle 30 resolution 8 8\n";
        (
            any::<bool>(),
            proptest::collection::vec(proptest::sample::select(NFF_WORDS), 0..60),
        )
            .prop_map(move |(with_view, words)| {
                let body = words.join(" ");
                if with_view {
                    format!("{view}{body}")
                } else {
                    body
                }
            })
    }

    const TOML_LINES: &[&str] = &[
        "[camera]",
        "from = [0, -8, 3]",
        "at = [0, 0, 0]",
        "up = [0, 0, 0]",
        "fov = 1e-9",
        "width = 18446744073709551615",
        "height = -1",
        "[[light]]",
        "position = [1e39, 0, 0]",
        "color = nan",
        "falloff = [0, 0, 0]",
        "[material.m]",
        "kd = -1",
        "ior = 5e-324",
        "[[object]]",
        "type = \"sphere\"",
        "type = \"cone\"",
        "type = \"mesh\"",
        "type = \"quadric\"",
        "center = [0, 1e6, 0]",
        "radius = 1e-9",
        "radius = 1e20",
        "base = [0, 0, 0]",
        "apex = [0, 0, 0]",
        "base_radius = -1",
        "apex_radius = 1",
        "coefficients = [1, 1, 1, 0, 0, 0, 0, 0, 0, -1]",
        "positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]",
        "triangles = [[0, 1, 2], [0, 0, 9]]",
        "material = \"m\"",
        "= = =",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Any NFF text loads or fails with a located error; never panics.
        #[test]
        fn nff_text_never_panics(text in nff_text()) {
            if let Err(e) = scene::parse_str(&text, Path::new("p.nff")) {
                prop_assert!(!e.message().is_empty());
            }
        }

        /// Any TOML text loads or fails with an error; never panics.
        #[test]
        fn toml_text_never_panics(
            lines in proptest::collection::vec(proptest::sample::select(TOML_LINES), 0..30)
        ) {
            let text = lines.join("\n");
            if let Err(e) = scene::parse_str(&text, Path::new("p.toml")) {
                prop_assert!(!e.message().is_empty());
            }
        }

        /// Any bytes as an NFF file: no panic (UTF-8 errors included).
        #[test]
        fn arbitrary_text_never_panics(text in ".{0,200}") {
            let _ = scene::parse_str(&text, Path::new("p.nff"));
            let _ = scene::parse_str(&text, Path::new("p.toml"));
        }
    }
}

mod hostile_obj {
    use super::*;
    use proptest::prelude::*;

    const OBJ_LINES: &[&str] = &[
        "v 0 0 0",
        "v 1 0 0",
        "v 0 1 0",
        "v 0 0 1",
        "v 1e39 0 0",
        "v nan 0 0",
        "v 0 0 0 0",
        "v 1 2 3 1e-40",
        "v 1 2 3 0.5 0.5 0.5",
        "v 1 2",
        "vn 0 0 1",
        "vn 0 0 0",
        "vn inf 0 0",
        "vt 0 0",
        "f 1 2 3",
        "f 1 2 3 4",
        "f -1 -2 -3",
        "f 0 1 2",
        "f 1/1/1 2/1/1 3/1/1",
        "f 1//1 2//1 3//1",
        "f 99999999999999999999 1 2",
        "f 1 2",
        "f",
        "o x",
        "g",
        "usemtl m",
        "mtllib a.mtl",
        "l 1 2",
        "p 1",
        "# c",
        "",
        "s 1",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Any .obj text loads or fails with an error at the `file` value;
        /// never panics.
        #[test]
        fn obj_text_never_panics(
            lines in proptest::collection::vec(proptest::sample::select(OBJ_LINES), 0..24),
            smooth in any::<bool>(),
        ) {
            let dir = tempfile::tempdir().unwrap();
            write(dir.path(), "m.obj", &lines.join("\n"));
            let scene = write(
                dir.path(),
                "s.toml",
                &format!("{CAMERA}[[object]]\ntype = \"mesh\"\nfile = \"m.obj\"\nsmooth = {smooth}\n"),
            );
            if let Err(e) = scene::load(&scene) {
                prop_assert_eq!((e.line(), e.column()), (Some(6), Some(8)), "{}", e);
                prop_assert!(e.message().contains("m.obj"), "{}", e);
            }
        }
    }
}
