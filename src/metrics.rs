//! Image metrics: max and mean absolute error, RMSE, PSNR, mean FLIP, the
//! error of a render against a reference (`Accuracy`: `whitted chart`,
//! `whitted stability`), and the CPU-mirror-versus-GPU comparison
//! (`compare`) with its tolerances.
//! The tolerances live here, in one place, for `whitted validate` and the
//! tests; docs/gpu.md gives the reason for each.

use crate::cpu::Frame;
use crate::output::{self, Encoding};
use crate::trace::RayStats;

/// Largest absolute difference over all channels.
pub fn max_abs(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    pairs(a, b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// Mean absolute difference over all channels.
pub fn mean_abs(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let n = (a.len() * 3).max(1) as f64;
    pairs(a, b).map(|(x, y)| (x - y).abs()).sum::<f64>() / n
}

/// Root mean square difference over all channels.
pub fn rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let n = (a.len() * 3).max(1) as f64;
    (pairs(a, b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / n).sqrt()
}

/// Peak signal-to-noise ratio in dB for a peak of 1 (linear radiance, the
/// display's white): 10·log10(1/MSE); +∞ for identical images.
pub fn psnr(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    psnr_of_rmse(rmse(a, b))
}

/// PSNR (peak 1) of an RMSE already computed.
pub fn psnr_of_rmse(e: f64) -> f64 {
    if e == 0.0 {
        f64::INFINITY
    } else {
        -20.0 * e.log10()
    }
}

fn pairs<'a>(a: &'a [[f32; 3]], b: &'a [[f32; 3]]) -> impl Iterator<Item = (f64, f64)> + 'a {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] as f64, q[i] as f64)))
}

/// NVIDIA's FLIP (LDR) between two 8-bit sRGB images (`width × height`,
/// RGB, row-major): the per-pixel error map in [0, 1] and its mean.
/// 67 pixels per degree (FLIP's default viewing condition).
pub fn flip(reference: &[u8], test: &[u8], width: u32, height: u32) -> (Vec<f32>, f64) {
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let mean = nv_flip::FlipPool::from_image(&map).mean() as f64;
    (map.to_vec(), mean)
}

/// One display step: a pixel is "off" when a channel differs from the
/// reference by more than this (linear radiance, white = 1).
pub const STEP: f64 = 1.0 / 255.0;

/// The error of a render against a reference of the same size (linear
/// radiance throughout, except FLIP, which sees the 8-bit sRGB images).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Accuracy {
    /// Root mean square difference over all channels.
    pub rmse: f64,
    /// 10·log10(1/MSE) for a peak of 1; +∞ for identical images.
    pub psnr: f64,
    /// Mean FLIP of the 8-bit sRGB images (0: identical, 1: opposite).
    pub mean_flip: f64,
    /// The largest channel difference and its pixel (x right, y down from
    /// the top-left); a NaN pixel is the worst there is (+∞).
    pub worst: f64,
    pub worst_x: u32,
    pub worst_y: u32,
    /// Fraction of pixels with a channel more than [`STEP`] off.
    pub fraction_over_step: f64,
    /// Pixels with a NaN or infinite channel in the test image.
    pub non_finite: u64,
}

impl Accuracy {
    /// `test` against `reference`; panics when their sizes differ (a
    /// caller's bug: both come from the same settings).
    pub fn of(reference: &Frame, test: &Frame) -> Accuracy {
        assert_eq!(
            (reference.width, reference.height),
            (test.width, test.height),
            "frames of different sizes"
        );
        let (a, b) = (&reference.pixels, &test.pixels);
        let mut acc = Accuracy::default();
        let mut over = 0u64;
        let mut worst_i = 0usize;
        for (i, (p, q)) in a.iter().zip(b).enumerate() {
            let mut e = 0.0f64;
            for c in 0..3 {
                let d = (p[c] as f64 - q[c] as f64).abs();
                // NaN compares false: make it the worst.
                e = if d.is_nan() { f64::INFINITY } else { e.max(d) };
            }
            if !q.iter().all(|v| v.is_finite()) {
                acc.non_finite += 1;
                e = f64::INFINITY;
            }
            if e > STEP {
                over += 1;
            }
            if e > acc.worst {
                acc.worst = e;
                worst_i = i;
            }
        }
        let w = reference.width.max(1) as usize;
        acc.worst_x = (worst_i % w) as u32;
        acc.worst_y = (worst_i / w) as u32;
        acc.fraction_over_step = over as f64 / a.len().max(1) as f64;
        acc.rmse = rmse(a, b);
        acc.psnr = psnr_of_rmse(acc.rmse);
        let ra = output::to_rgb8(reference, Encoding::Srgb);
        let rb = output::to_rgb8(test, Encoding::Srgb);
        acc.mean_flip = flip(ra.as_raw(), rb.as_raw(), reference.width, reference.height).1;
        acc
    }

    /// One line for a terminal.
    pub fn summary(&self) -> String {
        format!(
            "RMSE {:.3e}, PSNR {:.2} dB, mean FLIP {:.4}, worst {:.4} at ({}, {}), \
             {:.3}% of pixels over 1/255{}",
            self.rmse,
            self.psnr,
            self.mean_flip,
            self.worst,
            self.worst_x,
            self.worst_y,
            self.fraction_over_step * 100.0,
            if self.non_finite > 0 {
                format!(", {} non-finite pixels", self.non_finite)
            } else {
                String::new()
            }
        )
    }
}

/// Image and ray-count tolerances of the CPU-mirror-versus-GPU check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// A pixel is "over" when a channel differs by more than this (linear).
    pub pixel: f64,
    /// Largest fraction of pixels that may be over.
    pub fraction_over: f64,
    /// Largest mean FLIP (8-bit sRGB images).
    pub mean_flip: f64,
    /// Largest relative difference of each ray count...
    pub rays_relative: f64,
    /// ...or absolute difference, whichever is larger.
    pub rays_absolute: u64,
}

impl Default for Tolerance {
    fn default() -> Self {
        Tolerance {
            pixel: 1e-3,
            // A square root one ULP off moves 1.4-1.8 % of SPD balls'
            // pixels (chains of convex mirrors) over `pixel`, at 64² and
            // 256² alike; an NVIDIA H200 moved 1.6 % (docs/gpu.md).
            fraction_over: 3e-2,
            mean_flip: 2e-3,
            // The same ULP changes 17 of SPD rings' 17 168 shadow rays at
            // 64² (0.1 %; the H200 20), fewer in proportion at 256².
            rays_relative: 2.5e-3,
            rays_absolute: 8,
        }
    }
}

impl Tolerance {
    /// No difference at all: every pixel bit for bit and every ray count
    /// equal.
    pub fn exact() -> Tolerance {
        Tolerance {
            pixel: 0.0,
            fraction_over: 0.0,
            mean_flip: 0.0,
            rays_relative: 0.0,
            rays_absolute: 0,
        }
    }

    /// The tolerance for a device of kind `kind` running the exact shader
    /// (docs/gpu.md, "Tolerances"): on a CPU device (lavapipe) none, since
    /// it never fuses multiply-add, keeps the `precise` order and shares
    /// the CPU's libm-grade pow, exp and sqrt; on a real GPU the default,
    /// since GLSL lets division, sqrt, pow and exp differ by a few ULP.
    pub fn for_device(kind: crate::gpu::DeviceKind) -> Tolerance {
        if kind == crate::gpu::DeviceKind::Cpu {
            Tolerance::exact()
        } else {
            Tolerance::default()
        }
    }
    /// The tolerance for a device of kind `kind` running the render kernel
    /// `math`: the exact kernel's is `for_device`'s; the fast kernel's is
    /// the default on every device, lavapipe included, since arithmetic the
    /// driver may reorder and fuse differs from the mirror's in the last
    /// bits wherever it runs (docs/gpu.md, "Exact and fast shader
    /// arithmetic").
    pub fn for_kernel(kind: crate::gpu::DeviceKind, math: crate::gpu::GpuMath) -> Tolerance {
        match math {
            crate::gpu::GpuMath::Exact => Tolerance::for_device(kind),
            crate::gpu::GpuMath::Fast => Tolerance::default(),
        }
    }
}

/// One ray kind's counts on both sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RayDiff {
    pub kind: &'static str,
    pub reference: u64,
    pub test: u64,
}

impl RayDiff {
    pub fn diff(&self) -> i64 {
        self.test as i64 - self.reference as i64
    }
}

/// Everything `whitted validate` prints.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Comparison {
    pub width: u32,
    pub height: u32,
    pub max_abs: f64,
    pub mean_abs: f64,
    pub rmse: f64,
    pub psnr: f64,
    pub mean_flip: f64,
    pub pixels_over: usize,
    pub fraction_over: f64,
    pub rays: Vec<RayDiff>,
    /// Per pixel: largest channel difference (for the difference image).
    #[serde(skip)]
    pub pixel_error: Vec<f32>,
    pub tolerance_pixel: f64,
    /// What is over tolerance; empty when the check passes.
    pub failures: Vec<String>,
}

impl Comparison {
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// The difference image: each pixel's largest channel error through
    /// FLIP's magma colour map, scaled so that the pixel tolerance sits at
    /// the middle (black: equal; past the middle: over tolerance).
    pub fn diff_image(&self) -> image::RgbImage {
        let lut = nv_flip::magma_lut().to_vec();
        let mut img = image::RgbImage::new(self.width, self.height);
        for (i, p) in img.pixels_mut().enumerate() {
            let v = (self.pixel_error[i] as f64 / self.tolerance_pixel * 0.5).clamp(0.0, 1.0);
            let k = (v * 255.0).round() as usize * 3;
            *p = image::Rgb([lut[k], lut[k + 1], lut[k + 2]]);
        }
        img
    }
}

fn ray_diffs(r: &RayStats, t: &RayStats) -> Vec<RayDiff> {
    let d = |kind, a, b| RayDiff {
        kind,
        reference: a,
        test: b,
    };
    vec![
        d("eye", r.eye, t.eye),
        d("eye_hit", r.eye_hit, t.eye_hit),
        d("reflect", r.reflect, t.reflect),
        d("refract", r.refract, t.refract),
        d("shadow", r.shadow, t.shadow),
    ]
}

/// Compares `test` (the GPU's frame) against `reference` (the CPU mirror's).
pub fn compare(reference: &Frame, test: &Frame, tol: &Tolerance) -> Comparison {
    assert_eq!(
        (reference.width, reference.height),
        (test.width, test.height),
        "frames of different sizes"
    );
    let (a, b) = (&reference.pixels, &test.pixels);
    let pixel_error: Vec<f32> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).abs()).fold(0.0, f32::max))
        .collect();
    let pixels_over = pixel_error
        .iter()
        .filter(|&&e| e as f64 > tol.pixel || e.is_nan())
        .count();
    let fraction_over = pixels_over as f64 / a.len().max(1) as f64;
    let ra = output::to_rgb8(reference, Encoding::Srgb);
    let rb = output::to_rgb8(test, Encoding::Srgb);
    let (_, mean_flip) = flip(ra.as_raw(), rb.as_raw(), reference.width, reference.height);
    let rays = ray_diffs(&reference.stats, &test.stats);
    let e = rmse(a, b);
    let mut failures = Vec::new();
    if fraction_over > tol.fraction_over {
        failures.push(format!(
            "{:.3}% of pixels differ by more than {} (limit {:.3}%)",
            fraction_over * 100.0,
            tol.pixel,
            tol.fraction_over * 100.0
        ));
    }
    if mean_flip > tol.mean_flip || mean_flip.is_nan() {
        failures.push(format!(
            "mean FLIP {mean_flip:.5} (limit {})",
            tol.mean_flip
        ));
    }
    for r in &rays {
        let allowed = ((r.reference as f64 * tol.rays_relative) as u64).max(tol.rays_absolute);
        if r.diff().unsigned_abs() > allowed {
            failures.push(format!(
                "{} rays: {} on the GPU, {} on the CPU (limit ±{allowed})",
                r.kind, r.test, r.reference
            ));
        }
    }
    Comparison {
        width: reference.width,
        height: reference.height,
        max_abs: max_abs(a, b),
        mean_abs: mean_abs(a, b),
        rmse: e,
        psnr: psnr_of_rmse(e),
        mean_flip,
        pixels_over,
        fraction_over,
        rays,
        pixel_error,
        tolerance_pixel: tol.pixel,
        failures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(pixels: Vec<[f32; 3]>, w: u32, h: u32) -> Frame {
        Frame {
            width: w,
            height: h,
            pixels,
            ..Default::default()
        }
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = vec![[0.2, 0.5, 0.9]; 64];
        assert_eq!(max_abs(&a, &a), 0.0);
        assert_eq!(mean_abs(&a, &a), 0.0);
        assert_eq!(rmse(&a, &a), 0.0);
        assert_eq!(psnr(&a, &a), f64::INFINITY);
        let f = frame(a, 8, 8);
        let c = compare(&f, &f, &Tolerance::default());
        assert!(c.passed(), "{:?}", c.failures);
        assert_eq!(c.mean_flip, 0.0);
        assert_eq!(c.pixels_over, 0);
    }

    /// The hardware tolerance admits what amplified rounding does (a few
    /// per cent of pixels a few 8-bit steps off, as SPD balls under a
    /// square root one ULP off) and still fails a systematic error (every
    /// pixel's shading 1 % off) and a broken region (6 % of pixels wrong).
    #[test]
    fn the_hardware_tolerance_admits_amplified_rounding_not_errors() {
        let (w, h) = (64u32, 64u32);
        let base: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
                [0.2 + 0.6 * x, 0.3 + 0.4 * y, 0.5]
            })
            .collect();
        let a = frame(base.clone(), w, h);
        // Every 50th pixel off by 5e-3 (2 %), one by 2e-2.
        let mut noisy = base.clone();
        for (i, p) in noisy.iter_mut().enumerate().step_by(50) {
            p[0] += if i == 0 { 2e-2 } else { 5e-3 };
        }
        let c = compare(&a, &frame(noisy, w, h), &Tolerance::default());
        assert!(c.passed(), "{:?}", c.failures);
        // Shading 1 % too bright everywhere.
        let bright: Vec<[f32; 3]> = base.iter().map(|p| p.map(|v| v * 1.01)).collect();
        let c = compare(&a, &frame(bright, w, h), &Tolerance::default());
        assert!(!c.passed(), "a systematic error passed");
        // A block of 6 % of the pixels black.
        let mut hole = base.clone();
        for p in hole.iter_mut().take((w * h) as usize * 6 / 100) {
            *p = [0.0; 3];
        }
        let c = compare(&a, &frame(hole, w, h), &Tolerance::default());
        assert!(!c.passed(), "a broken region passed");
    }

    #[test]
    fn known_errors() {
        let a = vec![[0.0f32; 3]; 4];
        let mut b = a.clone();
        b[0] = [0.5, 0.0, 0.0];
        b[3] = [0.0, 0.0, 0.1];
        assert!((max_abs(&a, &b) - 0.5).abs() < 1e-9);
        assert!((mean_abs(&a, &b) - 0.6 / 12.0).abs() < 1e-7);
        let mse = (0.25 + 0.01) / 12.0;
        assert!((rmse(&a, &b) - f64::sqrt(mse)).abs() < 1e-7);
        assert!((psnr(&a, &b) - 10.0 * (1.0 / mse).log10()).abs() < 1e-5);
    }

    #[test]
    fn psnr_of_a_uniform_offset() {
        // RMSE 0.01 → 40 dB.
        let a = vec![[0.5f32; 3]; 16];
        let b = vec![[0.51f32; 3]; 16];
        assert!((psnr(&a, &b) - 40.0).abs() < 1e-3);
    }

    #[test]
    fn flip_sees_a_difference_and_not_equality() {
        let (w, h) = (32, 32);
        let a: Vec<u8> = (0..w * h * 3).map(|i| (i % 251) as u8).collect();
        let (map, mean) = flip(&a, &a, w, h);
        assert_eq!(map.len(), (w * h) as usize);
        assert!(mean.abs() < 1e-6, "{mean}");
        let b: Vec<u8> = a.iter().map(|&v| 255 - v).collect();
        let (_, mean) = flip(&a, &b, w, h);
        assert!(mean > 0.1, "{mean}");
    }

    #[test]
    fn accuracy_finds_the_worst_pixel_and_counts_steps() {
        let (w, h) = (8u32, 4u32);
        let a = frame(vec![[0.25f32; 3]; 32], w, h);
        let same = Accuracy::of(&a, &a);
        assert_eq!(same.rmse, 0.0);
        assert_eq!(same.psnr, f64::INFINITY);
        assert_eq!(
            (same.worst, same.fraction_over_step, same.non_finite),
            (0.0, 0.0, 0)
        );
        let mut b = a.clone();
        b.pixels[3 * 8 + 5][1] = 0.75; // (5, 3): 0.5 off
        b.pixels[1][0] = 0.25 + 0.5 / 255.0; // under one step
        b.pixels[2][2] = 0.25 + 2.0 / 255.0; // over one step
        let e = Accuracy::of(&a, &b);
        assert!((e.worst - 0.5).abs() < 1e-7, "{e:?}");
        assert_eq!((e.worst_x, e.worst_y), (5, 3));
        assert_eq!(e.fraction_over_step, 2.0 / 32.0);
        assert!(e.mean_flip > 0.0 && e.psnr.is_finite());
        b.pixels[9][0] = f32::NAN;
        let e = Accuracy::of(&a, &b);
        assert_eq!((e.worst, e.worst_x, e.worst_y), (f64::INFINITY, 1, 1));
        assert_eq!(e.non_finite, 1);
        assert!(e.summary().contains("1 non-finite"));
    }

    #[test]
    fn comparison_fails_over_tolerance() {
        let (w, h) = (16u32, 16u32);
        let a = vec![[0.3f32; 3]; (w * h) as usize];
        let mut b = a.clone();
        for p in b.iter_mut().take(10) {
            *p = [1.0, 0.0, 0.0];
        }
        let fa = frame(a, w, h);
        let mut fb = frame(b, w, h);
        fb.stats.shadow = 100;
        let c = compare(&fa, &fb, &Tolerance::default());
        assert_eq!(c.pixels_over, 10);
        assert!(!c.passed());
        assert!(c.failures.iter().any(|f| f.contains("of pixels")));
        assert!(c.failures.iter().any(|f| f.contains("FLIP")));
        assert!(c.failures.iter().any(|f| f.contains("shadow rays")));
        let img = c.diff_image();
        assert_eq!(img.dimensions(), (w, h));
        assert_ne!(img.get_pixel(0, 0), img.get_pixel(15, 15));
    }

    #[test]
    fn only_the_exact_kernel_on_a_cpu_device_is_held_to_bit_equality() {
        use crate::gpu::{DeviceKind, GpuMath};
        assert_eq!(
            Tolerance::for_kernel(DeviceKind::Cpu, GpuMath::Exact),
            Tolerance::exact()
        );
        for kind in [DeviceKind::Cpu, DeviceKind::Discrete] {
            assert_eq!(
                Tolerance::for_kernel(kind, GpuMath::Fast),
                Tolerance::default()
            );
        }
        assert_eq!(
            Tolerance::for_kernel(DeviceKind::Discrete, GpuMath::Exact),
            Tolerance::default()
        );
    }
}
