//! Options shared by `render` and `validate`, and their parsers.

use crate::gpu::{self, GpuOptions};
use crate::pack::{Sampling, Settings};
use clap::Args;

/// The image size (`render`, `validate`, `export`).
#[derive(Args, Clone, Debug)]
pub struct SizeOpts {
    /// Image width in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub height: Option<u32>,
}

/// How deep the ray tree goes (`render`, `validate`, `export`).
#[derive(Args, Clone, Debug)]
pub struct DepthOpts {
    /// Generations of reflection/refraction (0 = local model only).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=crate::constants::MAX_DEPTH_LIMIT as i64))]
    pub max_depth: u32,
    /// Adaptive depth control: a branch stops when its accumulated weight
    /// (largest channel) falls under this; 0 switches it off.
    #[arg(long, default_value_t = 1.0 / 256.0, value_parser = parse_weight)]
    pub min_weight: f32,
}

#[derive(Args, Clone, Debug)]
pub struct RenderOpts {
    #[command(flatten)]
    pub size: SizeOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
    /// Samples per pixel: stratified, jittered by a per-pixel hash
    /// (reproducible). 1 = the pixel centre.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub spp: u32,
    /// Pixel centres (with --spp jitter), or SPD's (W+1)×(H+1) corner rays.
    #[arg(long, value_enum, default_value_t = Sampling::Centers)]
    pub sampling: Sampling,
    /// Override the voxel grid resolution, e.g. 64x64x32.
    #[arg(long, value_parser = parse_grid, value_name = "NXxNYxNZ")]
    pub grid: Option<[u32; 3]>,
    /// Worker threads for the CPU backend (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

impl RenderOpts {
    pub fn settings(&self) -> Settings {
        Settings {
            width: self.size.width,
            height: self.size.height,
            max_depth: self.depth.max_depth,
            min_weight: self.depth.min_weight,
            spp: self.spp,
            sampling: self.sampling,
            grid: self.grid,
            ..Settings::default()
        }
    }
}

#[derive(Args, Clone, Debug)]
pub struct GpuArgs {
    /// Vulkan device index (see `whitted devices`); default: the best one
    /// (discrete > integrated > virtual > CPU).
    #[arg(long, value_name = "N")]
    pub device: Option<usize>,
    /// Edge of a GPU dispatch tile in lattice samples: one submission per
    /// tile, so none runs long.
    #[arg(long, value_name = "N", default_value_t = gpu::DEFAULT_TILE,
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub tile: u32,
    /// GPU workgroup shape (specialization constants of the shader).
    #[arg(long, value_name = "WxH", default_value = "8x8", value_parser = parse_workgroup)]
    pub workgroup: [u32; 2],
}

impl GpuArgs {
    pub fn options(&self) -> GpuOptions {
        GpuOptions {
            device: self.device,
            real_gpu_only: false,
            tile: self.tile,
            workgroup: self.workgroup,
            staging: false,
        }
    }
}

pub fn parse_workgroup(s: &str) -> Result<[u32; 2], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let bad = || format!("expected WxH such as 8x8 (each 1 to 1024), got '{s}'");
    if parts.len() != 2 {
        return Err(bad());
    }
    let mut out = [0u32; 2];
    for (i, p) in parts.iter().enumerate() {
        out[i] = p
            .parse()
            .ok()
            .filter(|n| (1..=1024).contains(n))
            .ok_or_else(bad)?;
    }
    Ok(out)
}

pub fn parse_weight(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("must be a number in [0, 1], got '{s}'"))?;
    if !v.is_finite() || !(0.0..=1.0).contains(&v) {
        return Err(format!("must be a number in [0, 1], got {s}"));
    }
    Ok(v)
}

pub fn parse_grid(s: &str) -> Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let max = crate::constants::GRID_MAX_DIM;
    if parts.len() != 3 {
        return Err(format!("expected NXxNYxNZ such as 64x64x32, got '{s}'"));
    }
    let mut out = [0u32; 3];
    for (i, p) in parts.iter().enumerate() {
        out[i] = p
            .parse()
            .ok()
            .filter(|&n| (1..=max).contains(&n))
            .ok_or_else(|| format!("'{p}' in '{s}' is not a whole number from 1 to {max}"))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_take_good_values_and_refuse_the_rest() {
        assert_eq!(parse_workgroup("16x4"), Ok([16, 4]));
        assert!(parse_workgroup("0x4").is_err());
        assert!(parse_workgroup("8").is_err());
        assert_eq!(parse_grid("1x2x1023"), Ok([1, 2, 1023]));
        assert!(parse_grid("1x2x1024").unwrap_err().contains("1 to 1023"));
        assert!(parse_grid("18446744073709551616x1x1").is_err());
        assert_eq!(parse_weight("0"), Ok(0.0));
        assert!(parse_weight("1.5").is_err());
        assert!(parse_weight("nan").is_err());
        assert!(parse_weight("x").unwrap_err().contains("'x'"));
    }
}
