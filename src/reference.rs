//! The reference image a render's error is measured against (`whitted
//! reference`, `whitted chart`, `whitted stability`): the CPU tracer in
//! f64, many stratified samples per pixel, deep recursion and no adaptive
//! cut-off. It is slow, so it is cached on disk, keyed by a hash of the
//! scene's content and the settings (docs/accuracy.md).
//!
//! The reference shares the packed scene with the f32 render (the packed
//! data are f32 either way): it measures the error of the tracer's
//! arithmetic, sampling and truncation, not the rounding of the scene's
//! coordinates into f32 (which the packer rebases near the camera, see
//! docs/method.md).

use crate::constants::MAX_DEPTH_LIMIT;
use crate::cpu::Frame;
use crate::pack::{Accel, Counting, Sampling, Settings};
use crate::run::{self, Precision};
use crate::scene::Scene;
use anyhow::{anyhow, Context, Result};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Bumped whenever the tracer's output for a given scene and settings
/// changes, so that no cached reference outlives the code that made it.
pub const REVISION: u32 = 1;

/// How a reference is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RefSettings {
    pub width: u32,
    pub height: u32,
    /// Stratified, jittered samples per pixel.
    pub spp: u32,
    /// Generations of reflection and refraction.
    pub max_depth: u32,
    /// Pixel centres (stratified and jittered when spp > 1) or the SPD's
    /// corners: the converged reference uses centres; `whitted chart`
    /// also asks for references through the same samples as a test.
    pub sampling: Sampling,
}

impl RefSettings {
    /// The defaults: 64 samples per pixel (8 × 8 strata), the deepest tree
    /// the tracer allows, for an image of `width × height`.
    pub fn new(width: u32, height: u32) -> RefSettings {
        RefSettings {
            width,
            height,
            spp: 64,
            max_depth: MAX_DEPTH_LIMIT,
            sampling: Sampling::Centers,
        }
    }

    /// The render settings: f64 is chosen by the caller (`Precision`);
    /// no adaptive cut-off; the acceleration structure does not change the
    /// image (docs/method.md), so `auto`.
    pub fn settings(&self, budget: crate::budget::Budget) -> Settings {
        Settings {
            width: Some(self.width),
            height: Some(self.height),
            max_depth: self.max_depth,
            min_weight: 0.0,
            spp: self.spp,
            sampling: self.sampling,
            grid: None,
            accel: Accel::Auto,
            budget,
            offset: None,
            shadows: crate::pack::Shadows::Plain,
            octree: Default::default(),
            hybrid_cell: crate::pack::hybrid::DEFAULT_CELL,
        }
    }
}

/// Where references are cached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Cache {
    /// `$XDG_CACHE_HOME/whitted/references` or `~/.cache/whitted/references`.
    Default,
    /// This folder.
    Dir(PathBuf),
    /// Nothing read or written.
    Off,
}

impl Cache {
    /// The folder, if any (Default without a home directory: none).
    pub fn dir(&self) -> Option<PathBuf> {
        match self {
            Cache::Default => crate::gpu::pipeline::cache_dir().map(|d| d.join("references")),
            Cache::Dir(d) => Some(d.clone()),
            Cache::Off => None,
        }
    }
}

/// A writer that feeds a hash, so that a large scene's description is
/// hashed without being held in memory.
struct HashWriter(Sha256);

impl std::fmt::Write for HashWriter {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.update(s.as_bytes());
        Ok(())
    }
}

/// The cache key: SHA-256 over the revision, the crate's version, the
/// settings and the scene's content (every number in it, exactly: `Debug`
/// prints floats in their shortest exact form). The scene's file name is
/// left out: the same scene under another name shares its reference, and
/// any edit to it (or to an `.obj` it names) makes a new one.
pub fn key(scene: &Scene, rs: &RefSettings) -> String {
    use std::fmt::Write;
    let mut h = HashWriter(Sha256::new());
    let _ = write!(
        h,
        "whitted reference r{REVISION} v{}\n{rs:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n",
        env!("CARGO_PKG_VERSION"),
        scene.camera,
        scene.background,
        scene.ambient,
        scene.lights,
        scene.materials,
    );
    for o in &scene.objects {
        let _ = writeln!(h, "{o:?}");
    }
    let digest = h.0.finalize();
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// A reference image and where it came from.
#[derive(Clone, Debug)]
pub struct Reference {
    pub frame: Frame,
    /// The cache file (read or written), if the cache is on.
    pub path: Option<PathBuf>,
    /// True when it was read from the cache rather than rendered.
    pub cached: bool,
}

/// The reference of `scene` for `rs`: from the cache when it is there and
/// readable, otherwise rendered (progress: done, total tiles) and stored.
/// A cache that cannot be read or written never fails the call: it costs a
/// render, with a warning.
pub fn get(
    scene: &Scene,
    rs: &RefSettings,
    cache: &Cache,
    budget: crate::budget::Budget,
    threads: Option<u32>,
    progress: run::Progress,
) -> Result<Reference> {
    let path = cache
        .dir()
        .map(|d| d.join(format!("{}.exr", key(scene, rs))));
    if let Some(p) = &path {
        if p.exists() {
            match read_exr(p, rs) {
                Ok(frame) => {
                    log::debug!("reference from the cache: {}", p.display());
                    return Ok(Reference {
                        frame,
                        path: path.clone(),
                        cached: true,
                    });
                }
                Err(e) => log::warn!("{e:#}; rendering the reference again"),
            }
        }
    }
    let frame = render(scene, rs, budget, threads, progress)?;
    if let Some(p) = &path {
        let stored = p
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .map_err(|e| anyhow!("{}: {e}", p.display()))
            .and_then(|_| crate::output::write(&frame, p, crate::output::Encoding::Linear));
        if let Err(e) = stored {
            log::warn!("cannot cache the reference: {e:#}");
        }
    }
    Ok(Reference {
        frame,
        path,
        cached: false,
    })
}

/// Renders the reference (no cache).
pub fn render(
    scene: &Scene,
    rs: &RefSettings,
    budget: crate::budget::Budget,
    threads: Option<u32>,
    progress: run::Progress,
) -> Result<Frame> {
    let packed = run::pack(scene, &rs.settings(budget), Counting::Traced)?;
    run::render_cpu(
        &packed,
        threads,
        Precision::F64,
        crate::cpu::DEFAULT_PACKET,
        progress,
    )
}

/// Reads a cached reference; it must have the expected size.
fn read_exr(path: &Path, rs: &RefSettings) -> Result<Frame> {
    let img = image::open(path)
        .with_context(|| format!("{}: unreadable cached reference", path.display()))?
        .into_rgb32f();
    if img.dimensions() != (rs.width, rs.height) {
        return Err(anyhow!(
            "{}: cached reference is {}x{}, expected {}x{}",
            path.display(),
            img.width(),
            img.height(),
            rs.width,
            rs.height
        ));
    }
    let pixels = img
        .as_raw()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    Ok(Frame {
        width: rs.width,
        height: rs.height,
        pixels,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        crate::scene::parse_str(
            "[camera]\nfrom=[0,-5,0]\nat=[0,0,0]\nup=[0,0,1]\nfov=40\nwidth=16\nheight=12\n\
             [[light]]\nposition=[3,-3,5]\n[material.m]\ncolor=[0.8,0.2,0.2]\nkd=0.8\nkr=0.3\n\
             [[object]]\ntype=\"sphere\"\ncenter=[0,0,0]\nradius=1\nmaterial=\"m\"\n",
            Path::new("k.toml"),
        )
        .unwrap()
    }

    #[test]
    fn the_key_follows_content_and_settings_not_the_name() {
        let s = scene();
        let rs = RefSettings::new(16, 12);
        let k = key(&s, &rs);
        assert_eq!(k.len(), 64);
        let mut renamed = s.clone();
        renamed.source = PathBuf::from("elsewhere/other.toml");
        assert_eq!(key(&renamed, &rs), k);
        let mut moved = s.clone();
        moved.lights[0].position.x += 1e-9;
        assert_ne!(key(&moved, &rs), k);
        assert_ne!(key(&s, &RefSettings { spp: 16, ..rs }), k);
    }

    #[test]
    fn the_cache_returns_what_was_rendered_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let s = scene();
        let rs = RefSettings {
            spp: 4,
            ..RefSettings::new(16, 12)
        };
        let cache = Cache::Dir(dir.path().join("refs"));
        let budget = crate::budget::Budget::system();
        let a = get(&s, &rs, &cache, budget, Some(1), &|_, _| {}).unwrap();
        assert!(!a.cached);
        assert!(a.path.as_ref().unwrap().exists());
        let b = get(&s, &rs, &cache, budget, Some(1), &|_, _| {}).unwrap();
        assert!(b.cached);
        assert_eq!(a.frame.pixels, b.frame.pixels);
        // A corrupt file costs a render, not the call.
        std::fs::write(a.path.as_ref().unwrap(), b"not an image").unwrap();
        let c = get(&s, &rs, &cache, budget, Some(1), &|_, _| {}).unwrap();
        assert!(!c.cached);
        assert_eq!(c.frame.pixels, a.frame.pixels);
        // The reference differs from the f32 one-sample render, but not much.
        let p = run::pack(
            &s,
            &Settings {
                width: Some(16),
                height: Some(12),
                ..Default::default()
            },
            Counting::Traced,
        )
        .unwrap();
        let f = run::render_cpu(&p, Some(1), Precision::F32, 1, &|_, _| {}).unwrap();
        let e = crate::metrics::Accuracy::of(&a.frame, &f);
        assert!(e.rmse > 0.0 && e.rmse < 0.2, "{e:?}");
    }
}
