//! Outputs never destroy inputs or each other, are checked before any work,
//! get the modes a user expects, and leave nothing behind when a run fails
//! or is interrupted (issue 7; docs/reliability.md).

use assert_cmd::Command;
use std::path::{Path, PathBuf};

fn whitted() -> Command {
    Command::cargo_bin("whitted").unwrap()
}

const SCENE: &str = "[camera]\nfrom = [0, -8, 3]\nat = [0, 0, 0]\nwidth = 32\nheight = 24\n\n\
[[light]]\nposition = [5, -5, 10]\n\n[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 1]\nradius = 1\n";

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs `args` in `dir`, expects exit 2 with `fragment` on stderr, and
/// checks that the directory is unchanged (byte for byte).
fn refused(dir: &Path, args: &[&str], fragment: &str) {
    let before: Vec<(String, Vec<u8>)> = listing(dir)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(dir.join(&n)).unwrap_or_default();
            (n, b)
        })
        .collect();
    let out = whitted().current_dir(dir).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        err.contains(fragment),
        "{args:?}: expected '{fragment}' in: {err}"
    );
    assert_eq!(
        err.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "one error line: {err}"
    );
    let after: Vec<(String, Vec<u8>)> = listing(dir)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(dir.join(&n)).unwrap_or_default();
            (n, b)
        })
        .collect();
    assert_eq!(before, after, "{args:?} changed the directory");
}

#[test]
fn outputs_never_overwrite_inputs_or_each_other() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "scene.toml", SCENE);
    write(d.path(), "scene.png", SCENE); // a TOML scene named .png
    write(d.path(), "old.png", "keep");
    let r = ["render", "--backend", "cpu"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["scene.toml", "--stats", "scene.toml"], "writes .json"),
        (
            vec!["scene.toml", "-o", "a.png", "--stats", "a.png"],
            "writes .json",
        ),
        (
            vec!["scene.png", "-o", "scene.png"],
            "would overwrite the input",
        ),
        (
            vec!["scene.png", "-o", "./scene.png"],
            "would overwrite the input",
        ),
        (
            vec!["scene.toml", "-o", "-", "--stats", "-"],
            "both write to standard output",
        ),
        (
            vec!["scene.toml", "-o", "scene.toml"],
            "writes .png, .exr or .hdr",
        ),
        (
            vec!["scene.toml", "-o", "no/such/dir/x.png"],
            "does not exist",
        ),
        (
            vec!["scene.toml", "-o", "x.png", "--stats", "no/dir/s.json"],
            "does not exist",
        ),
        (vec!["scene.toml", "-o", "."], "writes .png"),
    ];
    for (args, fragment) in cases {
        let all: Vec<&str> = r.iter().copied().chain(args).collect();
        refused(d.path(), &all, fragment);
    }
    // the same for validate's and the other commands' outputs
    refused(
        d.path(),
        &["validate", "scene.toml", "--json", "scene.toml"],
        "writes .json",
    );
    write(d.path(), "s.json", "{}");
    refused(
        d.path(),
        &[
            "validate",
            "scene.toml",
            "--json",
            "s.json",
            "--diff",
            "d.exr",
        ],
        "--diff writes .png",
    );
    refused(
        d.path(),
        &["generate", "--count", "10", "-o", "x.toml"],
        "writes .nff",
    );
    refused(
        d.path(),
        &["export", "scene.toml", "-o", "scene.toml"],
        ".pov or .nff",
    );
    refused(
        d.path(),
        &["export", "scene.toml", "-o", "x.pov", "--width", "0"],
        "0",
    );
    refused(
        d.path(),
        &[
            "export",
            "scene.toml",
            "-o",
            "x.pov",
            "--max-depth",
            "4294967295",
        ],
        "4294967295",
    );
}

#[cfg(unix)]
#[test]
fn hard_links_to_the_scene_are_inputs_too() {
    let d = tempfile::tempdir().unwrap();
    let s = write(d.path(), "s.toml", SCENE);
    std::fs::hard_link(&s, d.path().join("s.json")).unwrap();
    refused(
        d.path(),
        &["render", "s.toml", "-o", "x.png", "--stats", "s.json"],
        "would overwrite the input",
    );
}

#[test]
fn dash_writes_png_to_standard_output() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "s.toml", SCENE);
    let out = whitted()
        .current_dir(d.path())
        .args(["-q", "render", "s.toml", "--backend", "cpu", "-o", "-"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let img = image::load_from_memory(&out.stdout).unwrap();
    assert_eq!((img.width(), img.height()), (32, 24));
    assert_eq!(listing(d.path()), ["s.toml"], "no file named -");
    // generate and export too
    let out = whitted()
        .args(["generate", "--count", "3", "-o", "-"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).matches("\ns ").count(),
        3
    );
}

#[cfg(unix)]
#[test]
fn modes_follow_the_umask_or_the_replaced_file() {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "s.toml", SCENE);
    let bin = assert_cmd::cargo::cargo_bin("whitted");
    let run = |umask: &str, out: &str| {
        let st = std::process::Command::new("sh")
            .current_dir(d.path())
            .arg("-c")
            .arg(format!(
                "umask {umask}; exec '{}' -q render s.toml --backend cpu -o {out} --stats {out}.json",
                bin.display()
            ))
            .status()
            .unwrap();
        assert!(st.success());
    };
    let mode = |p: &str| {
        std::fs::metadata(d.path().join(p))
            .unwrap()
            .permissions()
            .mode()
            & 0o777
    };
    run("022", "a.png");
    assert_eq!(mode("a.png"), 0o644);
    assert_eq!(mode("a.png.json"), 0o644);
    run("027", "b.png");
    assert_eq!(mode("b.png"), 0o640);
    // rendering over an existing file keeps its mode
    std::fs::set_permissions(
        d.path().join("a.png"),
        std::fs::Permissions::from_mode(0o664),
    )
    .unwrap();
    run("077", "a.png");
    assert_eq!(mode("a.png"), 0o664);
}

/// SIGINT while the output is being written: exit 130, no temporary file,
/// the old output untouched.
#[cfg(unix)]
#[test]
fn an_interrupted_write_leaves_nothing_behind() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "s.toml", SCENE);
    write(d.path(), "out.png", "old");
    let bin = assert_cmd::cargo::cargo_bin("whitted");
    for signal in ["INT", "TERM"] {
        let mut child = std::process::Command::new(&bin)
            .current_dir(d.path())
            .env("WHITTED_TEST_WRITE_DELAY_MS", "20000")
            .args([
                "-q",
                "render",
                "s.toml",
                "--backend",
                "cpu",
                "-o",
                "out.png",
            ])
            .spawn()
            .unwrap();
        // Wait for the temporary file to appear (the render is done then).
        let t0 = std::time::Instant::now();
        while !listing(d.path()).iter().any(|n| n.starts_with(".whitted-")) {
            assert!(t0.elapsed().as_secs() < 60, "no temporary file appeared");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        std::process::Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        let st = child.wait().unwrap();
        assert_eq!(st.code(), Some(130), "SIG{signal}");
        assert_eq!(listing(d.path()), ["out.png", "s.toml"], "SIG{signal}");
        assert_eq!(std::fs::read(d.path().join("out.png")).unwrap(), b"old");
    }
}

/// A panic is reported as an internal error with exit code 3 (not Rust's
/// 101), and asks for a report.
#[test]
fn a_panic_exits_3_with_a_request_to_report_it() {
    let out = whitted()
        .env("WHITTED_TEST_PANIC", "1")
        .args(["devices"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with("internal error: WHITTED_TEST_PANIC is set"),
        "{err}"
    );
    assert!(err.contains("please report it"), "{err}");
}
