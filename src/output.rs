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

/// 8-bit value of a linear channel under `enc`.
pub fn to_u8(v: f32, enc: Encoding) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v };
    let e = match enc {
        Encoding::Srgb => srgb(v),
        Encoding::Linear => v.clamp(0.0, 1.0),
    };
    (e * 255.0).round() as u8
}

pub fn to_rgb8(f: &Frame, enc: Encoding) -> image::RgbImage {
    let mut img = image::RgbImage::new(f.width, f.height);
    for (i, p) in img.pixels_mut().enumerate() {
        let c = f.pixels[i];
        *p = image::Rgb([to_u8(c[0], enc), to_u8(c[1], enc), to_u8(c[2], enc)]);
    }
    img
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
    let mut buf = std::io::Cursor::new(Vec::new());
    match format {
        Format::Png => to_rgb8(f, enc)
            .write_to(&mut buf, image::ImageFormat::Png)
            .context("cannot encode PNG")?,
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
    }
}
