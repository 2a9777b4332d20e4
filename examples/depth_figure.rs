//! The classic figure: scenes/showcase.toml at --max-depth 0, 1, 2, 3 side
//! by side, written to docs/depth.png (the README shows it).
//!
//! cargo run --release --example depth_figure

use std::path::Path;
use whitted::output::{self, Encoding};
use whitted::pack::{self, Settings};
use whitted::{cpu, scene};

fn main() -> anyhow::Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = scene::load(&root.join("scenes/showcase.toml"))?;
    let (w, h) = (400u32, 300u32);
    let mut fig = image::RgbImage::new(4 * w + 3 * 4, h);
    for depth in 0..4u32 {
        let settings = Settings {
            width: Some(w),
            height: Some(h),
            max_depth: depth,
            spp: 4,
            ..Settings::default()
        };
        let f = cpu::render(&pack::pack(&s, &settings).expect("fits"), &|_, _| {});
        let img = output::to_rgb8(&f, Encoding::Srgb);
        image::imageops::replace(&mut fig, &img, (depth * (w + 4)) as i64, 0);
    }
    fig.save(root.join("docs/depth.png"))?;
    Ok(())
}
