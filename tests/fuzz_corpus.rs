//! Replays the committed fuzz corpus (`fuzz/corpus/TARGET/`) and every past
//! finding (`tests/fuzz_regressions/TARGET/`) through the fuzz targets'
//! bodies, `whitted::fuzzing`: the code libFuzzer ran, under plain
//! `cargo test`. None may panic; docs/reliability.md has the fuzzing runs.
//! The findings' expected outcomes are asserted in `regressions` below.

use std::path::{Path, PathBuf};
use whitted::fuzzing::{self, Outcome};

type Target = fn(&[u8]) -> Outcome;

const TARGETS: [(&str, Target); 4] = [
    ("toml", fuzzing::toml),
    ("nff", fuzzing::nff),
    ("obj", fuzzing::obj),
    ("pack", fuzzing::pack),
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The files of `dir`, sorted (none when it does not exist).
fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = entries
        .map(|e| e.expect("a readable directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    v
}

/// Runs every file of `dir` through `target`; returns the outcomes.
fn replay(dir: &Path, target: Target) -> Vec<(PathBuf, Outcome)> {
    files(dir)
        .into_iter()
        .map(|p| {
            let data = std::fs::read(&p).unwrap();
            let o = std::panic::catch_unwind(|| target(&data))
                .unwrap_or_else(|_| panic!("{} panicked (see above)", p.display()));
            (p, o)
        })
        .collect()
}

fn corpus(name: &str) {
    let target = TARGETS.iter().find(|t| t.0 == name).unwrap().1;
    let dir = root().join("fuzz/corpus").join(name);
    let out = replay(&dir, target);
    assert!(
        out.len() >= 10,
        "{}: {} inputs; the committed corpus is missing",
        dir.display(),
        out.len()
    );
    // A corpus that only ever reaches the reader's refusals tests little.
    let rendered = out
        .iter()
        .filter(|(_, o)| matches!(o, Outcome::Rendered(_)))
        .count();
    assert!(rendered > 0, "{name}: no input of the corpus renders");
}

#[test]
fn toml_corpus() {
    corpus("toml");
}

#[test]
fn nff_corpus() {
    corpus("nff");
}

#[test]
fn obj_corpus() {
    corpus("obj");
}

#[test]
fn pack_corpus() {
    corpus("pack");
}

/// Every finding replays without a panic (the specific outcomes are
/// asserted one by one below).
#[test]
fn regressions_replay() {
    for (name, target) in TARGETS {
        replay(&root().join("tests/fuzz_regressions").join(name), target);
    }
}

/// The outcome of the finding `tests/fuzz_regressions/TARGET/NAME`.
fn finding(target: &str, name: &str) -> Outcome {
    let f = TARGETS.iter().find(|t| t.0 == target).unwrap().1;
    let p = root()
        .join("tests/fuzz_regressions")
        .join(target)
        .join(name);
    f(&std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
}

/// toml: a control character in a comment made the toml crate's error
/// message empty (`x.toml:1:23: `).
#[test]
fn control_character_in_a_toml_comment() {
    let o = finding("toml", "control-char-in-comment.toml");
    assert_eq!(
        o.message(),
        Some("x.toml:1:23: control character U+0017 is not allowed in TOML text (only tab is)")
    );
}

/// obj: face indices that tobj 4 multiplies unchecked (a relative index
/// before the first normal or texture coordinate wraps to near 2^64; a
/// huge positive one overflows the multiplication) panicked inside tobj
/// (in a release build: an out-of-bounds panic or a wrong normal). The
/// loader now refuses them first, at their line.
#[test]
fn obj_face_indices_tobj_cannot_take() {
    let cases = [
        (
            "crash-67e57b81.obj",
            // The file's first problem is the line before the face.
            "mesh m.obj:5: normal: `1e390` is not a finite single-precision number",
        ),
        (
            "relative-normal-before-first.obj",
            "mesh m.obj:5: normal index -4 is out of range: 1 defined before this line",
        ),
        (
            "normal-index-overflows.obj",
            "mesh m.obj:5: normal index 6148914691236517206 is out of range: 1 defined before this line",
        ),
        (
            "relative-texcoord-before-any.obj",
            "mesh m.obj:4: texture coordinate index -1 is out of range: 0 defined before this line",
        ),
        (
            "texcoord-index-beyond-file.obj",
            "mesh m.obj:4: texture coordinate index 9223372036854775807 is out of range: the file has 63 bytes",
        ),
    ];
    for (name, want) in cases {
        let o = finding("obj", name);
        let m = o.message().unwrap_or_else(|| panic!("{name}: {o:?}"));
        assert!(m.starts_with("x.toml:8:8: "), "{name}: {m}");
        assert!(m.contains(want), "{name}: {m}");
    }
}

/// pack: a camera whose `up` was subnormal (1.25e-321) passed the reader,
/// and the harness's own check found `up × (at − from)` zero: the cross
/// product underflowed. The reader now refuses such an `up` by its
/// length, naming it (src/scene/validate.rs), and tests parallelism on
/// vectors scaled to a largest component of 1.
#[test]
fn a_subnormal_camera_up() {
    let o = finding("pack", "camera-up-subnormal.bin");
    let m = o.message().unwrap_or_else(|| panic!("{o:?}"));
    assert!(m.starts_with("fuzz.toml:4:6: camera.up"), "{m}");
    assert!(m.contains("1.25e-321"), "{m}");
}

/// pack: eye rays in packets changed the image (the target checks them
/// against single rays bit for bit). A feeler from a hit on an unbounded
/// plane 10^12 away passed 441 units from a sphere of radius 25; the
/// shadow cache's direct test of that sphere, in f32, reported a hit
/// through cancellation where the BVH walk culls the sphere by its
/// boxes, so a pixel depended on which feeler had gone before. Under the
/// BVH the cache now answers only where the walk would test its blocker
/// (`bvh::bvh_leaf_admits`): the input renders, packets and all.
#[test]
fn a_cached_blocker_far_from_the_feeler() {
    let o = finding("pack", "shadow-cache-far-feeler.bin");
    assert!(matches!(o, Outcome::Rendered(_)), "{o:?}");
}

/// pack: a pixel came out infinite. A quadric with a coefficient of
/// 1.24e29, hit where its gradient's components are about 10^-25: their
/// squares underflowed, the normal was the gradient divided by a length
/// of zero, and the diffuse term was infinite. The quadric's normal is
/// now the gradient scaled by its largest component before it is
/// normalised (`V3::direction`, `direction3` in math.glsl): every pixel
/// finite.
#[test]
fn a_quadric_gradient_whose_square_underflows() {
    let o = finding("pack", "quadric-normal-underflow.bin");
    assert!(matches!(o, Outcome::Rendered(_)), "{o:?}");
}

/// nff (a corpus input, once the targets also rendered every structure
/// with the shadow cache off and compared): a sphereflake with one sphere
/// of radius 5.6·10^16. Under the grid a feeler from that sphere's
/// surface, 5·10^16 away, met the floor polygon cached by an earlier
/// feeler: its f32 test reported a hit (the hit point's error is some
/// 10^9 units) the grid's walk never reaches, so the cache changed
/// pixels. Under the grid, the octree and the hybrid the cache now
/// answers only for feelers that start near the structure's box
/// (`accel::cache_admits`): the input renders, the same with the cache
/// off.
#[test]
fn a_cached_blocker_for_a_feeler_from_a_giant() {
    let o = finding("nff", "shadow-cache-giant-feeler.nff");
    assert!(matches!(o, Outcome::Rendered(_)), "{o:?}");
}

/// nff (10 minutes of fuzzing after the fix above): SPD rings with two
/// cylinders stretched to 10^5 times their width. A feeler passing beside
/// the grid's box met one cached: its f32 test reported a hit half a unit
/// off the cylinder's surface, outside the box, where the walk, which
/// clips the feeler to the box, tests nothing. The cache now also needs
/// the walks' own clipping to keep the feeler (`accel::cache_admits`).
#[test]
fn a_cached_blocker_for_a_feeler_beside_the_grid() {
    let o = finding("nff", "shadow-cache-long-cylinder.nff");
    assert!(matches!(o, Outcome::Rendered(_)), "{o:?}");
}

/// nff (2026-12-08, machine D): a needle cone, 455 long with radii 0 and
/// 0.056, seen across its length from 3 units: its f32 test reported a
/// root made up by cancellation, 0.017 off its axis (900 times its radius
/// there) and outside its boxes. The eye rays in packets tested it before
/// the hit that let the single ray's walk cull its leaf, so packets of 8
/// changed the image (the target's bit-for-bit check). A cone's hit must
/// now lie within a tolerance of its side (`pack::cone_tolerance`).
#[test]
fn a_needle_cone_s_made_up_root() {
    let o = finding("nff", "packets-needle-cone.nff");
    assert!(matches!(o, Outcome::Rendered(_)), "{o:?}");
}
