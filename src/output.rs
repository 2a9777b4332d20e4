//! Frame → file: PNG (sRGB-encoded, or the clamped linear values with
//! `--encoding linear`), or .exr / .hdr keeping linear floats. Files are
//! written through `files::write_atomically`, so a failed write never leaves
//! half a file; `-` writes PNG to standard output.

use crate::cpu::Frame;
use crate::files::Dest;
use anyhow::{bail, Context, Result};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Encoding {
    /// sRGB transfer curve (what image viewers expect).
    #[default]
    Srgb,
    /// round(255 · clamp(v, 0, 1)): the linear values, for comparisons.
    Linear,
    /// A 16-bit PNG of round(65535 · clamp(v, 0, 1)): the linear values
    /// at 16 bits, as POV-Ray's `+FN16 File_Gamma=1.0` writes them (what
    /// `whitted bench` compares: cheaper to write than an .exr). Where
    /// 8 bits are asked for, as `Linear`.
    Linear16,
}

/// The sRGB transfer function of a linear value in [0, 1].
pub fn srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// 8-bit value of a linear channel under `enc`, by the definition: the
/// transfer function, then round(255 · e): the reference `to_u8` equals.
pub fn to_u8_direct(v: f32, enc: Encoding) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v };
    let e = match enc {
        Encoding::Srgb => srgb(v),
        Encoding::Linear | Encoding::Linear16 => v.clamp(0.0, 1.0),
    };
    (e * 255.0).round() as u8
}

/// 16-bit value of a linear channel: round(65535 · clamp(v, 0, 1)), a NaN
/// as 0 (`Encoding::Linear16`).
pub fn to_u16_linear(v: f32) -> u16 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * 65535.0).round() as u16
}

/// Entry k − 1: the least f32 whose sRGB code is at least k
/// (k = 1..=255). The code of `v` is then the number of thresholds at
/// most `v`: `to_u8_direct`'s value, exactly, for every f32 (a NaN counts
/// none: 0), since that is monotone in `v` (tests: around every threshold,
/// and, ignored by default for its 1 G values, every f32 from 0 to 1).
fn srgb_thresholds() -> &'static [f32; 255] {
    static T: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let code = |bits: u32| to_u8_direct(f32::from_bits(bits), Encoding::Srgb);
        let one = 1f32.to_bits();
        std::array::from_fn(|i| {
            let k = i as u8 + 1;
            // Least bit pattern in 0..=1.0 (ordered like the values) whose
            // code reaches k: code(one) = 255 ≥ k.
            let (mut lo, mut hi) = (0u32, one);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if code(mid) >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        })
    })
}

/// The sRGB code of the least f32 of each block of 2¹⁶ (by bit pattern)
/// from 0 to 1: the first threshold to compare a value of that block with.
fn srgb_block_codes() -> &'static [u8] {
    static B: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    B.get_or_init(|| {
        let t = srgb_thresholds();
        (0..=1f32.to_bits() >> 16)
            .map(|b| t.partition_point(|&x| x <= f32::from_bits(b << 16)) as u8)
            .collect()
    })
}

/// 8-bit value of a linear channel under `enc`: `to_u8_direct`'s, the
/// sRGB one by counting code thresholds from its block's first code (a
/// block of 2¹⁶ f32 spans at most about one code) rather than by a
/// `powf`: 2.4 M of those for a 1024 × 768 image took 24 ms of output.
#[inline]
pub fn to_u8(v: f32, enc: Encoding) -> u8 {
    match enc {
        Encoding::Srgb => {
            if v.is_nan() || v <= 0.0 {
                return 0;
            }
            if v >= 1.0 {
                return 255;
            }
            let t = srgb_thresholds();
            let mut code = srgb_block_codes()[(v.to_bits() >> 16) as usize];
            while code < 255 && t[code as usize] <= v {
                code += 1;
            }
            code
        }
        Encoding::Linear | Encoding::Linear16 => to_u8_direct(v, enc),
    }
}

/// Writes each pixel's three samples, `B` bytes each as `sample` gives
/// them, into `out` (3·B bytes a pixel, in the frame's order), in rows of
/// pixels on every core: at 512² the serial loop took 2.8 ms of SPD
/// balls' 110 ms wall time, in parallel 1.4-2.7 ms here.
fn fill_rows<const B: usize>(f: &Frame, out: &mut [u8], sample: impl Fn(f32) -> [u8; B] + Sync) {
    use rayon::prelude::*;
    let w = (f.width as usize).max(1);
    out.par_chunks_mut(3 * B * w)
        .zip(f.pixels.par_chunks(w))
        .for_each(|(out, px)| {
            for (o, c) in out.chunks_exact_mut(3 * B).zip(px) {
                for (k, &v) in c.iter().enumerate() {
                    o[B * k..B * (k + 1)].copy_from_slice(&sample(v));
                }
            }
        });
}

pub fn to_rgb8(f: &Frame, enc: Encoding) -> image::RgbImage {
    let mut img = image::RgbImage::new(f.width, f.height);
    fill_rows(f, &mut img, |v| [to_u8(v, enc)]);
    img
}

/// The frame's linear values at 16 bits (`to_u16_linear`), big-endian as
/// PNG stores them.
fn to_rgb16_be(f: &Frame) -> Vec<u8> {
    let mut data = vec![0u8; 6 * f.pixels.len()];
    fill_rows(f, &mut data, |v| to_u16_linear(v).to_be_bytes());
    data
}

/// RGB samples (`depth` bits each, big-endian) as PNG into `out`, with the
/// compression and filters the image crate's encoder uses by default
/// (fdeflate's fast mode, each row's filter chosen adaptively): the same
/// file, without the copies that wrapper makes. At 512² and 16 bits (what
/// `whitted bench` writes) the output step took 8-9 ms of an SPD render's
/// 110-200 ms wall (BENCHMARKS.md).
fn encode_png(f: &Frame, depth: png::BitDepth, data: &[u8], out: &mut Vec<u8>) -> Result<()> {
    let mut e = png::Encoder::new(out, f.width, f.height);
    e.set_color(png::ColorType::Rgb);
    e.set_depth(depth);
    e.set_compression(png::Compression::Fast);
    e.set_filter(png::Filter::Adaptive);
    let mut w = e.write_header().context("cannot encode PNG")?;
    w.write_image_data(data).context("cannot encode PNG")?;
    w.finish().context("cannot encode PNG")
}

/// Kinds of output a path asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Exr,
    Hdr,
}

pub fn format_of(path: &Path) -> Result<Format> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    Ok(match ext.as_deref() {
        Some("png") => Format::Png,
        Some("exr") => Format::Exr,
        Some("hdr") => Format::Hdr,
        _ => bail!(
            "{}: unknown output format (use .png, .exr or .hdr)",
            path.display()
        ),
    })
}

/// Encodes `f` in `format`.
pub fn encode(f: &Frame, format: Format, enc: Encoding, w: &mut dyn std::io::Write) -> Result<()> {
    if f.pixels.len() as u64 != f.width as u64 * f.height as u64 {
        bail!(
            "a {}x{} frame with {} pixels: frame size does not match its pixels",
            f.width,
            f.height,
            f.pixels.len()
        );
    }
    let mut buf = std::io::Cursor::new(Vec::new());
    match format {
        Format::Png if enc == Encoding::Linear16 => {
            encode_png(f, png::BitDepth::Sixteen, &to_rgb16_be(f), buf.get_mut())?
        }
        Format::Png => encode_png(f, png::BitDepth::Eight, &to_rgb8(f, enc), buf.get_mut())?,
        Format::Exr | Format::Hdr => {
            let data: Vec<f32> = f.pixels.iter().flatten().copied().collect();
            let img = image::Rgb32FImage::from_raw(f.width, f.height, data)
                .context("frame size does not match its pixels")?;
            let fmt = if format == Format::Exr {
                image::ImageFormat::OpenExr
            } else {
                image::ImageFormat::Hdr
            };
            image::DynamicImage::ImageRgb32F(img)
                .write_to(&mut buf, fmt)
                .context("cannot encode the image")?;
        }
    }
    w.write_all(buf.get_ref())?;
    Ok(())
}

/// Writes `f` to `dest`: a file (atomically; the format from its
/// extension) or standard output (PNG).
pub fn write_to(f: &Frame, dest: &Dest, enc: Encoding) -> Result<()> {
    let format = match dest {
        Dest::File(p) => format_of(p)?,
        Dest::Stdout => Format::Png,
    };
    let mut bytes = Vec::new();
    encode(f, format, enc, &mut bytes)?;
    crate::files::write_bytes(dest, &bytes)
}

/// Writes `f` to `path` atomically.
pub fn write(f: &Frame, path: &Path, enc: Encoding) -> Result<()> {
    write_to(f, &Dest::File(path.to_path_buf()), enc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodings() {
        assert_eq!(to_u8(0.5, Encoding::Linear), 128);
        assert_eq!(to_u8(0.5, Encoding::Srgb), 188);
        assert_eq!(to_u8(2.0, Encoding::Srgb), 255);
        assert_eq!(to_u8(-1.0, Encoding::Linear), 0);
        assert_eq!(to_u8(f32::NAN, Encoding::Linear), 0);
        assert_eq!(to_u8(f32::NAN, Encoding::Srgb), 0);
        assert_eq!(to_u8(f32::INFINITY, Encoding::Srgb), 255);
        assert_eq!(to_u8(f32::NEG_INFINITY, Encoding::Srgb), 0);
        assert_eq!(to_u8(-0.0, Encoding::Srgb), 0);
    }

    /// A frame of these pixels and nothing else.
    fn frame(width: u32, height: u32, pixels: Vec<[f32; 3]>) -> Frame {
        Frame {
            width,
            height,
            pixels,
            stats: Default::default(),
            work: Default::default(),
            seconds: 0.0,
            device_seconds: None,
            phases: Vec::new(),
            device_stages: Vec::new(),
        }
    }

    /// `--encoding linear16` writes a 16-bit PNG whose samples read back
    /// as round(65535 · clamp(v, 0, 1)), a NaN as 0, channel by channel.
    #[test]
    fn linear16_png_holds_the_linear_values_at_16_bits() {
        let vals = [
            0.0,
            0.25,
            1.0 / 3.0,
            0.999_99,
            1.0,
            2.0,
            -1.0,
            f32::NAN,
            1e-6,
        ];
        let pixels: Vec<[f32; 3]> = vals.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let f = frame(3, 1, pixels);
        let mut bytes = Vec::new();
        encode(&f, Format::Png, Encoding::Linear16, &mut bytes).unwrap();
        let img = image::load_from_memory(&bytes).unwrap();
        let rgb = img.as_rgb16().expect("a 16-bit RGB PNG");
        let got: Vec<u16> = rgb.pixels().flat_map(|p| p.0).collect();
        let want = [0, 16384, 21845, 65534, 65535, 65535, 0, 0, 0];
        assert_eq!(got, want);
        assert_eq!(to_u8(0.5, Encoding::Linear16), 128);
    }

    /// Both PNG depths written row by row on every core (`to_rgb16_be`,
    /// `to_rgb8`) read back pixel for pixel in place; a frame whose pixels
    /// do not fill it is refused, not written short.
    #[test]
    fn png_rows_read_back_in_place_at_both_depths() {
        let (w, h) = (7u32, 5u32);
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let v = i as f32 / (w * h) as f32;
                [v, 1.0 - v, (i % 3) as f32 * 0.4]
            })
            .collect();
        let mut f = frame(w, h, pixels.clone());
        let mut bytes = Vec::new();
        encode(&f, Format::Png, Encoding::Linear16, &mut bytes).unwrap();
        let img = image::load_from_memory(&bytes).unwrap();
        let got: Vec<u16> = img.as_rgb16().unwrap().pixels().flat_map(|p| p.0).collect();
        let want: Vec<u16> = pixels.iter().flatten().map(|&v| to_u16_linear(v)).collect();
        assert_eq!(got, want);
        for enc in [Encoding::Srgb, Encoding::Linear] {
            bytes.clear();
            encode(&f, Format::Png, enc, &mut bytes).unwrap();
            let img = image::load_from_memory(&bytes).unwrap();
            let got: Vec<u8> = img.as_rgb8().unwrap().pixels().flat_map(|p| p.0).collect();
            let want: Vec<u8> = pixels.iter().flatten().map(|&v| to_u8(v, enc)).collect();
            assert_eq!(got, want, "{enc:?}");
        }
        f.pixels.pop();
        for (format, enc) in [
            (Format::Png, Encoding::Linear16),
            (Format::Png, Encoding::Srgb),
            (Format::Exr, Encoding::Srgb),
        ] {
            bytes.clear();
            assert!(
                encode(&f, format, enc, &mut bytes).is_err(),
                "{format:?} {enc:?}"
            );
            assert!(bytes.is_empty(), "nothing written");
        }
    }

    /// Every f32 from 0 to 1 (1.07 G of them; about 2 s in a release
    /// build, far longer in the test profile: `cargo test --release --lib
    /// every_srgb_code -- --ignored`). Run 2026-12-03: no difference.
    #[test]
    #[ignore]
    fn every_srgb_code_by_threshold_is_the_direct_one() {
        use rayon::prelude::*;
        let bad = (0..=1f32.to_bits())
            .into_par_iter()
            .filter(|&b| {
                let v = f32::from_bits(b);
                to_u8(v, Encoding::Srgb) != to_u8_direct(v, Encoding::Srgb)
            })
            .count();
        assert_eq!(bad, 0);
    }

    /// The thresholds give the code `powf` gives: within 4096 steps of f32
    /// either side of every threshold (where a code changes, and where a
    /// `powf` not monotone to the last bit could make them differ), and at
    /// every 4096th f32 from −2 to 2 in between.
    #[test]
    fn srgb_codes_by_threshold_are_the_direct_ones() {
        let t = srgb_thresholds();
        assert!(t.windows(2).all(|w| w[0] < w[1]), "thresholds increase");
        let check = |v: f32| {
            assert_eq!(
                to_u8(v, Encoding::Srgb),
                to_u8_direct(v, Encoding::Srgb),
                "{v:e} ({:#x})",
                v.to_bits()
            );
        };
        for &x in t.iter() {
            let b = x.to_bits();
            for bits in b.saturating_sub(4096)..=b + 4096 {
                check(f32::from_bits(bits));
            }
        }
        for bits in (0..=2f32.to_bits()).step_by(4096) {
            check(f32::from_bits(bits));
            check(-f32::from_bits(bits));
        }
        // Each threshold is where its code starts (and below 0, above 1,
        // NaN: the clamped ends, checked in `encodings`).
        for (i, &x) in t.iter().enumerate() {
            assert_eq!(to_u8_direct(x, Encoding::Srgb), i as u8 + 1);
            assert_eq!(to_u8_direct(x.next_down(), Encoding::Srgb), i as u8);
        }
    }
}
