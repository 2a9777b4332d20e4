//! Runs POV-Ray 3.7 on a scene written by `export::to_pov` and reads its
//! image back as a linear [`Frame`], for `whitted bench --vs povray` and the
//! image comparison in `tests/povray.rs` (docs/povray.md).
//!
//! POV-Ray runs headless (`-D`), without anti-aliasing (`-A`: one ray
//! through each pixel centre, like `--spp 1`) or with the corner sampling
//! of `--sampling corners` ([`Options::sampling`]), and writes a 16-bit PNG with
//! `File_Gamma=1.0`: with the exported `assumed_gamma 1.0` the file holds
//! round(65535 · clamp(v, 0, 1)) of the linear radiance v, so the frame read
//! back compares with ours in the same (linear) encoding.

use crate::cpu::Frame;
use crate::pack::Sampling;
use anyhow::{bail, Context, Result};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// The POV-Ray executable (`povray` on `PATH`).
pub const EXECUTABLE: &str = "povray";

/// Largest image edge POV-Ray accepts from us (`+W`, `+H`); the same bound
/// as a scene's camera (docs/scene-format.md).
pub const MAX_EDGE: u32 = 65536;

/// Largest `+WT` (POV-Ray's own limit on render threads).
pub const MAX_THREADS: u32 = 512;

/// One POV-Ray run: the image, read back as linear RGB, and what it cost.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Linear RGB in [0, 1] (POV-Ray clips), row-major from the top left.
    /// `frame.seconds` is `wall_seconds`; `stats` stay zero.
    pub frame: Frame,
    /// Wall time of the whole `povray` process: start-up, parse, bounding,
    /// render and PNG write.
    pub wall_seconds: f64,
    /// POV-Ray's own report (`Parse Time`, `Bounding Time`, `Trace Time`),
    /// when it printed one.
    pub parse_seconds: Option<f64>,
    pub bounding_seconds: Option<f64>,
    pub trace_seconds: Option<f64>,
}

/// POV-Ray's version line (`POV-Ray 3.7.0.10...`), or an error when it
/// cannot be run.
pub fn version() -> Result<String> {
    let out = Command::new(EXECUTABLE)
        .arg("--version")
        .output()
        .with_context(|| format!("cannot run `{EXECUTABLE}` (is POV-Ray installed?)"))?;
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    text.lines()
        .find(|l| l.starts_with("POV-Ray "))
        .map(|l| l.trim().to_string())
        .with_context(|| format!("`{EXECUTABLE} --version` printed no version line"))
}

/// Whether `povray` can be run at all.
pub fn available() -> bool {
    version().is_ok()
}

/// How to run POV-Ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    /// Render threads (`+WT`): 2 on the project's 2-core machines.
    pub threads: u32,
    /// `Centers`: no anti-aliasing (`-A`), one ray through each pixel
    /// centre, our default. `Corners`: adaptive anti-aliasing with threshold
    /// 0, one level, no jitter (`+A0.0 +AM2 +R1 -J`), which traces the
    /// (W+1)×(H+1) pixel corners and averages each pixel's four: our
    /// `--sampling corners` (the SPD's convention).
    pub sampling: Sampling,
}

impl Options {
    /// `width × height`, pixel centres, one thread per core.
    pub fn new(width: u32, height: u32) -> Self {
        Options {
            width,
            height,
            threads: std::thread::available_parallelism()
                .map_or(1, |n| n.get() as u32)
                .min(MAX_THREADS),
            sampling: Sampling::Centers,
        }
    }
}

/// Renders `pov_path` with POV-Ray as `opts` says (no display) and returns
/// the image and the time taken. The PNG goes to a temporary directory,
/// deleted afterwards.
pub fn render(pov_path: &Path, opts: &Options) -> Result<Rendered> {
    let Options {
        width,
        height,
        threads,
        ..
    } = *opts;
    if width == 0 || height == 0 || width > MAX_EDGE || height > MAX_EDGE {
        bail!("image size {width}x{height} is outside 1..={MAX_EDGE} on each side");
    }
    if threads == 0 || threads > MAX_THREADS {
        bail!("POV-Ray threads must be in 1..={MAX_THREADS}, got {threads}");
    }
    let input = pov_path
        .canonicalize()
        .with_context(|| format!("{}: cannot read", pov_path.display()))?;
    // POV-Ray's default I/O policy allows writing under /tmp and the
    // current directory: run it inside a fresh temporary directory.
    let dir = tempfile::Builder::new()
        .prefix("whitted-povray-")
        .tempdir()
        .context("cannot create a temporary directory for POV-Ray")?;
    let out_name = "povray.png";
    let t0 = Instant::now();
    let out = command(&input, out_name, opts)
        .current_dir(dir.path())
        .output()
        .with_context(|| format!("cannot run `{EXECUTABLE}` (is POV-Ray installed?)"))?;
    let wall_seconds = t0.elapsed().as_secs_f64();
    let log =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    let png = dir.path().join(out_name);
    if !out.status.success() || !png.exists() {
        bail!(
            "{}: POV-Ray failed ({}):\n{}",
            pov_path.display(),
            out.status,
            tail(&log, 20)
        );
    }
    let img = image::open(&png)
        .with_context(|| format!("cannot read POV-Ray's image {}", png.display()))?
        .to_rgb32f();
    if img.dimensions() != (width, height) {
        bail!(
            "POV-Ray wrote a {}x{} image, expected {width}x{height}",
            img.width(),
            img.height()
        );
    }
    let pixels = img.pixels().map(|p| p.0).collect();
    Ok(Rendered {
        frame: Frame {
            width,
            height,
            pixels,
            seconds: wall_seconds,
            ..Default::default()
        },
        wall_seconds,
        parse_seconds: reported_seconds(&log, "Parse Time:"),
        bounding_seconds: reported_seconds(&log, "Bounding Time:"),
        trace_seconds: reported_seconds(&log, "Trace Time:"),
    })
}

/// The POV-Ray command line for `input` (absolute, or relative to the
/// directory it runs in) writing `output` (16-bit linear PNG) as `opts`
/// says. Run it in a directory POV-Ray may write to (its default I/O
/// policy allows the current directory and /tmp).
pub fn command(input: &Path, output: &str, opts: &Options) -> Command {
    let mut c = Command::new(EXECUTABLE);
    c.arg(format!("+I{}", input.display()))
        .arg(format!("+O{output}"))
        .arg(format!("+W{}", opts.width))
        .arg(format!("+H{}", opts.height))
        .arg(format!("+WT{}", opts.threads))
        .args(match opts.sampling {
            Sampling::Centers => &["-A"][..],
            Sampling::Corners => &["+A0.0", "+AM2", "+R1", "-J"][..],
        })
        // Full quality and no alpha whatever a user's povray.ini says.
        .args(["-D", "+Q9", "-UA", "+FN16", "File_Gamma=1.0", "-P", "-V"]);
    c
}

/// The seconds in POV-Ray's `LABEL  0 hours  0 minutes  1 seconds (1.234 seconds)`.
fn reported_seconds(log: &str, label: &str) -> Option<f64> {
    let line = log.lines().find(|l| l.trim_start().starts_with(label))?;
    let open = line.rfind('(')?;
    let rest = &line[open + 1..];
    rest.split_whitespace().next()?.parse().ok()
}

fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_povray_time_report() {
        let log =
            "Parser Time\n  Parse Time:       0 hours  0 minutes  0 seconds (0.012 seconds)\n\
                   \n  Trace Time:       0 hours  1 minutes  2 seconds (62.5 seconds)\n";
        assert_eq!(reported_seconds(log, "Parse Time:"), Some(0.012));
        assert_eq!(reported_seconds(log, "Trace Time:"), Some(62.5));
        assert_eq!(reported_seconds(log, "Bounding Time:"), None);
    }

    #[test]
    fn refuses_bad_sizes_before_running() {
        let p = Path::new("nonexistent.pov");
        for (w, h, t) in [(0, 10, 1), (10, 0, 1), (MAX_EDGE + 1, 1, 1), (10, 10, 0)] {
            let o = Options {
                threads: t,
                ..Options::new(w, h)
            };
            assert!(render(p, &o).is_err());
        }
        let e = render(p, &Options::new(0, 10)).unwrap_err().to_string();
        assert!(e.contains("0x10"), "{e}");
        // Good sizes reach the file check.
        let e = render(p, &Options::new(4, 4)).unwrap_err().to_string();
        assert!(e.contains("nonexistent.pov"), "{e}");
    }
}
