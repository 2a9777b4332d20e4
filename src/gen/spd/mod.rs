//! Eric Haines' Standard Procedural Databases (SPD, 1987): the seven
//! scenes ray tracers have been compared on since, generated at any size
//! factor from ports of the SPD's own C programs (one file each here;
//! their shared library in `lib.rs`). At its default size each scene is the
//! one the SPD's program writes as NFF: the same primitives in the same
//! order, the same camera, lights and surfaces (`tests/spd.rs` checks
//! this against the original files when they are at hand).
//!
//! What the SPD specifies and what it leaves to the renderer (light
//! intensities, ambient light) is in docs/spd.md, with the SPD's testing
//! procedure (`pack::Preset::Spd`) and its ray statistics.

mod balls;
mod gears;
mod lib;
mod mount;
mod rings;
mod teapot;
mod tetra;
mod tree;

use crate::scene::Scene;
use std::fmt;
use std::str::FromStr;

/// One of the SPD's seven scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpdScene {
    Balls,
    Gears,
    Mount,
    Rings,
    Teapot,
    Tetra,
    Tree,
}

/// The most primitives a generator makes. Beyond this the scene would take
/// gigabytes before it is packed; the size factors grow the count
/// exponentially, so one step more is often eight times as much.
pub const MAX_PRIMITIVES: u64 = 1 << 24;

/// Why a scene cannot be generated at the size asked for.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpdError {
    #[error("{scene}: size {size} is too small (the smallest size factor is 1)")]
    TooSmall { scene: SpdScene, size: u32 },
    #[error(
        "{scene}: size {size} would make {} primitives, more than the {} a generator makes \
         (the largest size is {largest}: {} primitives)",
        count_text(*.count), group(MAX_PRIMITIVES), group(*.largest_count)
    )]
    TooLarge {
        scene: SpdScene,
        size: u32,
        /// The count, or None when it does not fit in 64 bits.
        count: Option<u64>,
        largest: u32,
        largest_count: u64,
    },
}

fn count_text(c: Option<u64>) -> String {
    c.map_or_else(|| "more than 2^64".to_string(), group)
}

/// 1234567 → "1 234 567".
fn group(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(ch);
    }
    out
}

impl SpdScene {
    pub const ALL: [SpdScene; 7] = [
        SpdScene::Balls,
        SpdScene::Gears,
        SpdScene::Mount,
        SpdScene::Rings,
        SpdScene::Teapot,
        SpdScene::Tetra,
        SpdScene::Tree,
    ];

    /// The name the SPD gives it (its program's name).
    pub fn name(self) -> &'static str {
        match self {
            SpdScene::Balls => "balls",
            SpdScene::Gears => "gears",
            SpdScene::Mount => "mount",
            SpdScene::Rings => "rings",
            SpdScene::Teapot => "teapot",
            SpdScene::Tetra => "tetra",
            SpdScene::Tree => "tree",
        }
    }

    /// One line on what it is and how the size factor scales it.
    pub fn about(self) -> &'static str {
        match self {
            SpdScene::Balls => {
                "sphereflake: shiny spheres each sprouting nine a third their size, over a floor; \
                 (9^(size+1) - 1)/8 spheres"
            }
            SpdScene::Gears => {
                "size³ meshed gears with 144-vertex faces, some transparent, over a mirror floor; \
                 146·size³ + 1 polygons"
            }
            SpdScene::Mount => {
                "fractal mountain with four glass spheres in front; 2·4^size triangles"
            }
            SpdScene::Rings => {
                "pyramid of objects of six pentagonal rings (cylinders and spheres) before a \
                 wall; 5·size·(size+1)·(2·size+1) cylinders and as many spheres"
            }
            SpdScene::Teapot => {
                "Newell's teapot of smooth triangles on a checkerboard; 64·size² - 8·size \
                 triangles, size² squares (the SPD's statistics are for size 12)"
            }
            SpdScene::Tetra => "recursive tetrahedral pyramid, mostly background; 4^size triangles",
            SpdScene::Tree => {
                "tree of cones and spheres over a field, seven lights; 2^(size+1) - 1 cones and \
                 as many spheres"
            }
        }
    }

    /// The size factor the SPD's program uses by default, the size of its
    /// published statistics (except the teapot's, published for 12).
    pub fn default_size(self) -> u32 {
        match self {
            SpdScene::Balls => 4,
            SpdScene::Gears => 4,
            SpdScene::Mount => 6,
            SpdScene::Rings => 7,
            SpdScene::Teapot => 6,
            SpdScene::Tetra => 6,
            SpdScene::Tree => 11,
        }
    }

    /// The SPD's published ray statistics (its Readme, "Database
    /// Analysis"), for the 513 × 513 eye rays of its testing procedure:
    /// the size they are for (the default, but 12 for the teapot) and the
    /// eye rays that hit, reflected, refracted and shadow rays
    /// (docs/spd.md, "The ray statistics").
    pub fn published_stats(self) -> (u32, [u64; 4]) {
        match self {
            SpdScene::Balls => (4, [263_169, 175_095, 0, 954_368]),
            SpdScene::Gears => (4, [245_086, 304_643, 207_564, 2_246_955]),
            SpdScene::Mount => (6, [173_125, 354_769, 354_769, 412_922]),
            SpdScene::Rings => (7, [263_169, 315_236, 0, 1_085_002]),
            SpdScene::Teapot => (12, [161_120, 225_248, 0, 407_656]),
            SpdScene::Tetra => (6, [49_788, 0, 0, 46_112]),
            SpdScene::Tree => (11, [169_836, 0, 0, 1_097_419]),
        }
    }

    /// The number of primitives (scene objects, an NFF entity each) at
    /// `size`, or None when it does not fit in 64 bits.
    pub fn primitive_count(self, size: u32) -> Option<u64> {
        let n = size as u64;
        let pow = |b: u64, e: u64| b.checked_pow(u32::try_from(e).ok()?);
        match self {
            SpdScene::Balls => Some((pow(9, n + 1)? - 1) / 8 + 1),
            SpdScene::Gears => pow(n, 3)?.checked_mul(146)?.checked_add(1),
            SpdScene::Mount => pow(4, n)?.checked_mul(2)?.checked_add(4),
            SpdScene::Rings => (5 * n)
                .checked_mul(n + 1)?
                .checked_mul(2 * n + 1)?
                .checked_mul(2)?
                .checked_add(1),
            SpdScene::Teapot => {
                // The two cusps drop 8·size triangles; at size 1 the
                // whole lid top and bottom go (the SPD warns about 1),
                // and four more triangles have zero area.
                let tris = if n == 1 {
                    52
                } else {
                    n.checked_mul(n)?.checked_mul(64)? - 8 * n
                };
                tris.checked_add(n * n)
            }
            SpdScene::Tetra => pow(4, n),
            SpdScene::Tree => pow(2, n + 1)?
                .checked_sub(1)?
                .checked_mul(2)?
                .checked_add(1),
        }
    }

    /// The largest size whose scene stays within `MAX_PRIMITIVES`.
    pub fn largest_size(self) -> u32 {
        let mut s = 1;
        while self
            .primitive_count(s + 1)
            .is_some_and(|c| c <= MAX_PRIMITIVES)
        {
            s += 1;
        }
        s
    }
}

impl fmt::Display for SpdScene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Not one of the SPD's scenes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown SPD scene `{0}` (expected balls, gears, mount, rings, teapot, tetra or tree)")]
pub struct UnknownScene(pub String);

impl FromStr for SpdScene {
    type Err = UnknownScene;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SpdScene::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| UnknownScene(s.to_string()))
    }
}

/// The SPD scene at size factor `size` (None: its default). Sizes under 1
/// and sizes past `MAX_PRIMITIVES` are refused before anything is built.
pub fn generate(scene: SpdScene, size: Option<u32>) -> Result<Scene, SpdError> {
    let size = size.unwrap_or(scene.default_size());
    if size < 1 {
        return Err(SpdError::TooSmall { scene, size });
    }
    let count = scene.primitive_count(size);
    if count.is_none_or(|c| c > MAX_PRIMITIVES) {
        let largest = scene.largest_size();
        return Err(SpdError::TooLarge {
            scene,
            size,
            count,
            largest,
            largest_count: scene.primitive_count(largest).unwrap_or(0),
        });
    }
    Ok(match scene {
        SpdScene::Balls => balls::generate(size),
        SpdScene::Gears => gears::generate(size),
        SpdScene::Mount => mount::generate(size),
        SpdScene::Rings => rings::generate(size),
        SpdScene::Teapot => teapot::generate(size),
        SpdScene::Tetra => tetra::generate(size),
        SpdScene::Tree => tree::generate(size),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for s in SpdScene::ALL {
            assert_eq!(s.to_string().parse::<SpdScene>(), Ok(s));
        }
        assert_eq!("Teapot".parse::<SpdScene>(), Ok(SpdScene::Teapot));
        let e = "teapots".parse::<SpdScene>().unwrap_err();
        assert!(e.to_string().contains("`teapots`"), "{e}");
    }

    #[test]
    fn counts_at_the_default_sizes_are_the_spds() {
        // The "total prim." row of the SPD's table (the teapot's at 12).
        let table = [
            (SpdScene::Balls, 7382),
            (SpdScene::Gears, 9345),
            (SpdScene::Mount, 8196),
            (SpdScene::Rings, 8401),
            (SpdScene::Tetra, 4096),
            (SpdScene::Tree, 8191),
        ];
        for (s, n) in table {
            assert_eq!(s.primitive_count(s.default_size()), Some(n), "{s}");
        }
        assert_eq!(SpdScene::Teapot.primitive_count(12), Some(9264));
    }

    #[test]
    fn absurd_sizes_are_refused_with_the_count() {
        let e = generate(SpdScene::Balls, Some(9)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("435 848 051 primitives"), "{text}");
        assert!(text.contains("largest size is 7: 5 380 841"), "{text}");
        let e = generate(SpdScene::Tree, Some(4_000_000_000)).unwrap_err();
        assert!(e.to_string().contains("more than 2^64"), "{e}");
        assert_eq!(
            generate(SpdScene::Gears, Some(0)).unwrap_err(),
            SpdError::TooSmall {
                scene: SpdScene::Gears,
                size: 0
            }
        );
        for s in SpdScene::ALL {
            let l = s.largest_size();
            assert!(s.primitive_count(l).unwrap() <= MAX_PRIMITIVES, "{s}");
            assert!(s.primitive_count(l + 1).is_none_or(|c| c > MAX_PRIMITIVES));
            assert!(l >= s.default_size(), "{s}");
        }
    }
}
