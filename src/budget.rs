//! The memory budget: what a run will allocate, estimated before it does,
//! against a limit (docs/budget.md).
//!
//! [`Need`] counts what a render allocates, in 64-bit bytes: the loaded
//! scene, the packed primitives, the grid's cells and references (counted
//! exactly by the grid's counting pass before its filing pass), and the
//! frame (the image, the traced samples and the buffers the backends fill
//! them through). [`Budget`] holds the limit: by default
//! [`DEFAULT_SHARE_PERCENT`] of the machine's physical memory, or what
//! `--memory-limit` says ([`Budget::parse`]). `pack::pack` checks the
//! estimate at the start (the image and the primitives, before anything
//! large exists) and again when the grid's size is known; a run over
//! budget is refused with a [`BudgetError`] that names what is too big.
//!
//! The GPU's buffers are listed by [`gpu_buffers`], which the GPU backend
//! checks against the device's `maxStorageBufferRange` and heap.

use crate::pack::grid::{WALK_PRIM_BYTES, WALK_REF_BYTES};
use std::fmt;

/// Share of physical memory a run may use by default. The estimate counts
/// the large arrays whitted allocates, not the allocator's slack, the
/// loader's transient buffers, the program itself or the rest of the
/// machine; half leaves room for all of them, so a run the budget admits
/// does not swap the machine or meet the out-of-memory killer.
pub const DEFAULT_SHARE_PERCENT: u32 = 50;

/// The limit when physical memory cannot be read (not Linux, no /proc).
pub const FALLBACK_LIMIT: u64 = 4 << 30;

/// Where the limit came from (said in every refusal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A share of physical memory: the default, or `--memory-limit 75%`.
    Share { percent: u32, of: u64 },
    /// `--memory-limit SIZE`.
    Flag,
    /// Physical memory unknown: [`FALLBACK_LIMIT`].
    Fallback,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::Share { percent, of } => {
                write!(f, "{percent}% of {} of memory", fmt_bytes(*of))
            }
            Origin::Flag => write!(f, "as asked"),
            Origin::Fallback => write!(f, "the default where the memory size is unknown"),
        }
    }
}

/// A memory limit in bytes and where it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    limit: u64,
    origin: Origin,
}

impl Default for Budget {
    /// [`Budget::system`].
    fn default() -> Self {
        Budget::system()
    }
}

impl Budget {
    /// [`DEFAULT_SHARE_PERCENT`] of [`physical_memory`], or
    /// [`FALLBACK_LIMIT`] where that is unknown.
    pub fn system() -> Budget {
        Budget::share(DEFAULT_SHARE_PERCENT)
    }

    /// `percent`% of physical memory ([`FALLBACK_LIMIT`] where unknown).
    pub fn share(percent: u32) -> Budget {
        match physical_memory() {
            Some(of) => Budget {
                limit: (of as u128 * percent as u128 / 100).min(u64::MAX as u128) as u64,
                origin: Origin::Share { percent, of },
            },
            None => Budget {
                limit: FALLBACK_LIMIT,
                origin: Origin::Fallback,
            },
        }
    }

    /// Exactly `limit` bytes (`--memory-limit SIZE`).
    pub fn bytes(limit: u64) -> Budget {
        Budget {
            limit,
            origin: Origin::Flag,
        }
    }

    /// No limit but the 64-bit byte count (library callers that budget
    /// themselves).
    pub fn unlimited() -> Budget {
        Budget::bytes(u64::MAX)
    }

    /// `--memory-limit`'s argument: a size ([`parse_size`]) or a share of
    /// physical memory such as `75%` (1 to 100).
    pub fn parse(s: &str) -> Result<Budget, String> {
        let t = s.trim();
        if let Some(p) = t.strip_suffix('%') {
            let percent: u32 = p
                .trim()
                .parse()
                .ok()
                .filter(|p| (1..=100).contains(p))
                .ok_or_else(|| format!("'{s}': a share of memory is 1% to 100%"))?;
            return Ok(Budget::share(percent));
        }
        parse_size(t).map(Budget::bytes)
    }

    pub fn limit(&self) -> u64 {
        self.limit
    }

    pub fn origin(&self) -> Origin {
        self.origin
    }

    /// Whether `need` fits.
    pub fn fits(&self, need: &Need) -> bool {
        need.peak() <= self.limit
    }

    /// `Ok` when `need` fits; otherwise the refusal, naming the largest item.
    pub fn check(&self, need: &Need) -> Result<(), BudgetError> {
        let total = need.peak();
        if total <= self.limit {
            return Ok(());
        }
        let item = need
            .items()
            .into_iter()
            .max_by_key(|i| i.bytes)
            .expect("a need has items");
        Err(BudgetError {
            item,
            total,
            limit: self.limit,
            origin: self.origin,
            need: Box::new(*need),
        })
    }
}

/// Physical memory this process may use: the smaller of the machine's
/// (`MemTotal` in /proc/meminfo) and its control group's limit (cgroup v2
/// `memory.max`, v1 `memory.limit_in_bytes`). `None` where neither exists.
pub fn physical_memory() -> Option<u64> {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| meminfo_total(&s));
    let cgroup = [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ]
    .iter()
    .filter_map(|p| std::fs::read_to_string(p).ok())
    .filter_map(|s| s.trim().parse::<u64>().ok())
    .min();
    match (total, cgroup) {
        (Some(t), Some(c)) => Some(t.min(c)),
        (t, c) => t.or(c),
    }
}

/// `MemTotal` of a /proc/meminfo text, in bytes.
fn meminfo_total(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut words = line["MemTotal:".len()..].split_whitespace();
    let n: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => n.checked_mul(1024),
        None => Some(n),
        Some(_) => None,
    }
}

/// A size such as `512M`, `4GiB`, `1.5G`, `800MB` or `1000000`: a number
/// (a fraction allowed), then a unit. `K`, `M`, `G`, `T` and `KiB` ...
/// `TiB` are powers of 1024 (as in `ulimit`, Docker and systemd); `KB` ...
/// `TB` powers of 1000; `B` or none, bytes. Case-insensitive.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let bad =
        || format!("'{s}' is not a size: expected a number and a unit, such as 512M, 4GiB or 1.5G");
    if num.is_empty() {
        return Err(bad());
    }
    let mult: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kib" => 1 << 10,
        "m" | "mib" => 1 << 20,
        "g" | "gib" => 1 << 30,
        "t" | "tib" => 1 << 40,
        "kb" => 1_000,
        "mb" => 1_000_000,
        "gb" => 1_000_000_000,
        "tb" => 1_000_000_000_000,
        _ => return Err(bad()),
    };
    let bytes = match num.split_once('.') {
        None => num
            .parse::<u64>()
            .ok()
            .and_then(|n| n.checked_mul(mult))
            .ok_or_else(|| format!("'{s}' is more than 2^64 bytes"))?,
        Some(_) => {
            let v: f64 = num.parse().map_err(|_| bad())?;
            let b = v * mult as f64;
            if b >= u64::MAX as f64 {
                return Err(format!("'{s}' is more than 2^64 bytes"));
            }
            b.round() as u64
        }
    };
    if bytes == 0 {
        return Err(format!("'{s}': the limit must be more than 0 bytes"));
    }
    Ok(bytes)
}

/// Bytes in binary units: `512 B`, `1.5 KiB`, `9.6 GiB`.
pub fn fmt_bytes(b: u64) -> String {
    const UNITS: [&str; 6] = ["KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    if b < 1024 {
        return format!("{b} B");
    }
    let mut v = b as f64 / 1024.0;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if v < 10.0 {
        format!("{v:.1} {}", UNITS[u])
    } else {
        format!("{v:.0} {}", UNITS[u])
    }
}

/// A count in decimal units: `950`, `12 k`, `2.4 G`.
pub fn fmt_count(n: u64) -> String {
    const UNITS: [&str; 6] = ["k", "M", "G", "T", "P", "E"];
    if n < 1000 {
        return n.to_string();
    }
    let mut v = n as f64 / 1000.0;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < UNITS.len() {
        v /= 1000.0;
        u += 1;
    }
    if v < 10.0 {
        format!("{v:.1} {}", UNITS[u])
    } else {
        format!("{v:.0} {}", UNITS[u])
    }
}

/// What a part of the estimate is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum What {
    /// The frame: image, samples and the backends' buffers for them.
    Image,
    /// The scene as loaded (alive while it is packed).
    Scene,
    /// The packed primitives and their extra data.
    Primitives,
    /// The grid: per-cell offsets and empty-space distances, and the
    /// references (one per primitive per cell it overlaps).
    Grid,
    /// The BVH: its build's working arrays and its nodes.
    Bvh,
    /// The octree: its nodes (two words each, counted as cells) and the
    /// references of its leaves.
    Octree,
}

impl What {
    /// The start of a refusal: "the image needs" (... 9.6 GiB).
    pub fn needs(self) -> &'static str {
        match self {
            What::Image => "the image needs",
            What::Scene => "the loaded scene needs",
            What::Primitives => "the packed primitives need",
            What::Grid => "the grid needs",
            What::Bvh => "the BVH needs",
            What::Octree => "the octree needs",
        }
    }
    /// The unit of the count ("for 2.4 G references").
    pub fn unit(self) -> &'static str {
        match self {
            What::Image => "samples",
            What::Scene => "objects",
            What::Primitives => "primitives",
            What::Grid => "references",
            What::Bvh => "primitives",
            What::Octree => "references",
        }
    }
}

/// One part of the estimate: bytes at the run's peak, for `count` things.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Item {
    pub what: What,
    pub count: u64,
    pub bytes: u64,
}

/// A run over budget.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct BudgetError {
    /// The largest part of the estimate.
    pub item: Item,
    /// The whole estimate.
    pub total: u64,
    pub limit: u64,
    pub origin: Origin,
    /// What it was estimated from.
    pub need: Box<Need>,
}

impl BudgetError {
    /// Always the user's to fix (a smaller image or scene, or a larger
    /// limit): the CLI exits with 2.
    pub fn is_user_error(&self) -> bool {
        true
    }
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let i = &self.item;
        write!(f, "{} {} for ", i.what.needs(), fmt_bytes(i.bytes))?;
        if i.what == What::Grid {
            write!(f, "{} cells and ", fmt_count(self.need.cells))?;
        }
        if i.what == What::Octree {
            write!(f, "{} node words and ", fmt_count(self.need.cells))?;
        }
        write!(f, "{} {}", fmt_count(i.count), i.what.unit())?;
        if fmt_bytes(i.bytes) != fmt_bytes(self.total) {
            write!(f, ", {} in all", fmt_bytes(self.total))?;
        }
        let hint = match i.what {
            What::Image => ", or render a smaller image",
            What::Grid if self.need.explicit_grid => ", or choose a coarser --grid",
            What::Octree => ", or a larger --octree-leaf or fewer --octree-levels",
            _ => "",
        };
        write!(
            f,
            " (limit {}, {}; raise it with --memory-limit{hint})",
            fmt_bytes(self.limit),
            self.origin
        )
    }
}

/// Bytes one lattice sample costs while the frame is rendered: on the CPU
/// the lattice (12), which each band of tiles writes in place; on the GPU
/// the readback buffer (16) then the lattice read from it (12). The larger.
pub const SAMPLE_BYTES: u64 = 28;
/// Bytes one pixel costs besides its sample: writing an .exr or .hdr
/// copies the pixels (12); corner sampling resolves the (W+1)×(H+1)
/// lattice into the W×H image in place (`cpu::resolve_corners_in_place`).
pub const RESOLVED_PIXEL_BYTES: u64 = 12;

/// Bytes per bounded primitive while it is packed: the builder's
/// primitive and bounds (`(Prim, Bounds)`, 128), the bounds the grid is
/// built from (48) and its cell range (8).
const BOUNDED_PACK_BYTES: u64 = 128 + 48 + 8;
/// Bytes per packed primitive: the array (64) and, while it moves into
/// huge pages (`pack::pages`), its copy.
const PRIM_BYTES: u64 = 64;
/// Bytes per `extra` entry (a vec4).
const EXTRA_BYTES: u64 = 16;
/// Bytes per grid cell that stay: the offset (4) and the empty-space
/// distance (1).
const CELL_BYTES: u64 = 5;
/// Bytes per grid cell while the grid is built: the offsets, the filing
/// cursor (4), the distance transform's bytes (1), and the copy into huge
/// pages of the offsets and distances (5).
const CELL_BUILD_BYTES: u64 = 5 + 4 + 1 + 5;
/// Bytes per reference: a u32 (and its copy into huge pages while packing).
const REF_BYTES: u64 = 4;

/// What a run allocates, in counts; [`Need::peak`] turns them into bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Need {
    /// Image width and height.
    pub width: u32,
    pub height: u32,
    /// SPD corner sampling: a (W+1)×(H+1) lattice, then a W×H image.
    pub corners: bool,
    /// Objects in the loaded scene and their bytes.
    pub scene_objects: u64,
    pub scene_bytes: u64,
    /// Packed primitives, those of them in the grid, `extra` entries.
    pub prims: u64,
    pub bounded: u64,
    pub extra: u64,
    /// Grid cells and references (0 until the counting pass).
    pub cells: u64,
    pub refs: u64,
    /// The grid's resolution came from `--grid` (for the refusal's hint).
    pub explicit_grid: bool,
    /// The BVH is built over the `bounded` primitives instead of the grid
    /// (then `cells` and `refs` stay 0).
    pub bvh: bool,
    /// The octree is built instead of the grid: `cells` counts its node
    /// words, `refs` its leaves' references.
    pub octree: bool,
}

impl Need {
    /// Samples traced into the frame's lattice.
    pub fn lattice(&self) -> u64 {
        let c = self.corners as u64;
        (self.width as u64 + c) * (self.height as u64 + c)
    }

    /// The frame's bytes: the lattice's samples, the CPU's per-band
    /// records (counted per tile: more), and the copied image.
    pub fn frame_bytes(&self) -> u64 {
        let tile = crate::cpu::TILE as u64;
        let c = self.corners as u64;
        let tiles =
            (self.width as u64 + c).div_ceil(tile) * (self.height as u64 + c).div_ceil(tile);
        let record = std::mem::size_of::<crate::cpu::BandResult>() as u64;
        let pixels = self.width as u64 * self.height as u64;
        self.lattice()
            .saturating_mul(SAMPLE_BYTES)
            .saturating_add(tiles.saturating_mul(record))
            .saturating_add(pixels.saturating_mul(RESOLVED_PIXEL_BYTES))
    }

    /// Bytes of the grid's cells and references that stay for the render.
    pub fn grid_bytes(&self) -> u64 {
        self.cells
            .saturating_mul(CELL_BYTES)
            .saturating_add(self.refs.saturating_mul(self.ref_bytes()))
    }

    /// Bytes of the BVH's nodes that stay for the render (at most).
    pub fn bvh_bytes(&self) -> u64 {
        if self.bvh {
            self.bounded
                .saturating_mul(crate::pack::bvh::BYTES_PER_PRIM)
        } else {
            0
        }
    }

    /// Bytes of the BVH's build (its working arrays and the nodes).
    fn bvh_build_bytes(&self) -> u64 {
        if self.bvh {
            self.bounded
                .saturating_mul(crate::pack::bvh::BUILD_BYTES_PER_PRIM)
        } else {
            0
        }
    }

    /// Whether the grid's walk arrays are counted (`pack::grid::Walk`):
    /// for the grid and the hybrid, whose grid files them too (and drops
    /// them before the render: counted all the same).
    fn walk(&self) -> bool {
        !self.bvh && !self.octree
    }

    /// Bytes a reference keeps for the render: its u32, and under the
    /// grid its walk bits.
    fn ref_bytes(&self) -> u64 {
        REF_BYTES + if self.walk() { WALK_REF_BYTES } else { 0 }
    }

    /// Bytes of the grid walk's arrays that stay for the render (their
    /// references' bits are in `grid_bytes`).
    fn walk_prim_bytes(&self) -> u64 {
        if self.walk() {
            self.bounded.saturating_mul(WALK_PRIM_BYTES)
        } else {
            0
        }
    }

    /// The packed scene's bytes that stay for the render.
    fn packed_bytes(&self) -> u64 {
        self.prims
            .saturating_mul(PRIM_BYTES)
            .saturating_add(self.extra.saturating_mul(EXTRA_BYTES))
            .saturating_add(self.grid_bytes())
            .saturating_add(self.walk_prim_bytes())
            .saturating_add(self.bvh_bytes())
    }

    /// Bytes at the peak of packing: the loaded scene, the builder's
    /// arrays, the grid being built and the copies into huge pages.
    pub fn pack_peak(&self) -> u64 {
        self.scene_bytes
            .saturating_add(self.bounded.saturating_mul(BOUNDED_PACK_BYTES))
            .saturating_add(self.prims.saturating_mul(2 * PRIM_BYTES))
            .saturating_add(self.extra.saturating_mul(2 * EXTRA_BYTES))
            .saturating_add(self.cells.saturating_mul(CELL_BUILD_BYTES))
            .saturating_add(self.refs.saturating_mul(2 * self.ref_bytes()))
            .saturating_add(self.walk_prim_bytes().saturating_mul(2))
            .saturating_add(self.bvh_build_bytes())
    }

    /// Bytes at the peak of rendering: the packed scene and the frame.
    pub fn render_peak(&self) -> u64 {
        self.packed_bytes().saturating_add(self.frame_bytes())
    }

    /// The run's estimated peak: the larger of packing's and rendering's.
    pub fn peak(&self) -> u64 {
        self.pack_peak().max(self.render_peak())
    }

    /// Each part at its own peak (for naming the largest).
    pub fn items(&self) -> Vec<Item> {
        let mut items = vec![
            Item {
                what: What::Image,
                count: self.lattice(),
                bytes: self.frame_bytes(),
            },
            Item {
                what: What::Scene,
                count: self.scene_objects,
                bytes: self.scene_bytes,
            },
            Item {
                what: What::Primitives,
                count: self.prims,
                bytes: self
                    .bounded
                    .saturating_mul(BOUNDED_PACK_BYTES)
                    .saturating_add(self.prims.saturating_mul(2 * PRIM_BYTES))
                    .saturating_add(self.extra.saturating_mul(2 * EXTRA_BYTES)),
            },
            Item {
                what: if self.octree {
                    What::Octree
                } else {
                    What::Grid
                },
                count: self.refs,
                bytes: self
                    .cells
                    .saturating_mul(CELL_BUILD_BYTES)
                    .saturating_add(self.refs.saturating_mul(2 * self.ref_bytes()))
                    .saturating_add(self.walk_prim_bytes().saturating_mul(2)),
            },
        ];
        if self.bvh {
            items.push(Item {
                what: What::Bvh,
                count: self.bounded,
                bytes: self.bvh_build_bytes(),
            });
        }
        items
    }

    /// The most references a grid of `cells` cells may have within
    /// `budget` (0 when the cells alone do not fit).
    pub fn max_refs(&self, budget: &Budget, cells: u64) -> u64 {
        let base = Need {
            cells,
            refs: 0,
            ..*self
        };
        let l = budget.limit();
        let (pack, render) = (base.pack_peak(), base.render_peak());
        if pack > l || render > l {
            return 0;
        }
        let r = self.ref_bytes();
        ((l - pack) / (2 * r)).min((l - render) / r)
    }
}

/// Bytes of each buffer the GPU backend binds for `p` with `lattice`
/// output samples (one vec4 each), in binding order (the BVH's is 11);
/// the GPU checks each against `maxStorageBufferRange` and their sum
/// against its heap.
pub fn gpu_buffers(p: &crate::pack::Packed, lattice: u64) -> [(&'static str, u64); 11] {
    fn size<T>(s: &[T]) -> u64 {
        std::mem::size_of_val(s) as u64
    }
    [
        ("globals", std::mem::size_of_val(&p.globals) as u64),
        ("prims", size(&p.prims)),
        ("extra", size(&p.extra)),
        ("materials", size(&p.materials)),
        ("lights", size(&p.lights)),
        ("cell_start", size(&p.cell_start)),
        ("refs", size(&p.refs)),
        ("bvh", size(&p.bvh)),
        ("lb_start", size(&p.lb_start)),
        ("lb_refs", size(&p.lb_refs)),
        ("output samples", lattice.saturating_mul(16)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_binary_and_decimal_units() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("4GiB"), Ok(4 << 30));
        assert_eq!(parse_size("4 gib"), Ok(4 << 30));
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("800MB"), Ok(800_000_000));
        assert_eq!(parse_size("1000000"), Ok(1_000_000));
        assert_eq!(parse_size("64k"), Ok(65536));
        assert_eq!(parse_size("2T"), Ok(2 << 40));
        assert_eq!(parse_size("16EiB").ok(), None, "past 2^64");
        assert_eq!(parse_size("16777216T").ok(), None, "past 2^64");
        for bad in [
            "", "M", "1.2.3G", "12X", "-5M", "0", "0.0G", ".", "nan", "1e9",
        ] {
            assert!(parse_size(bad).is_err(), "{bad:?}");
        }
        let e = parse_size("12X").unwrap_err();
        assert!(e.contains("'12X'") && e.contains("512M"), "{e}");
    }

    #[test]
    fn limits_parse_as_sizes_or_shares() {
        assert_eq!(Budget::parse("1G").unwrap(), Budget::bytes(1 << 30));
        let half = Budget::parse("50%").unwrap();
        assert_eq!(half, Budget::system());
        match (half.origin(), physical_memory()) {
            (Origin::Share { percent: 50, of }, Some(m)) => {
                assert_eq!(of, m);
                assert_eq!(half.limit(), m / 2);
            }
            (Origin::Fallback, None) => assert_eq!(half.limit(), FALLBACK_LIMIT),
            other => panic!("{other:?}"),
        }
        for bad in ["0%", "101%", "x%", "%"] {
            assert!(Budget::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn meminfo_is_read_in_bytes() {
        let t = "MemTotal:       24683584 kB\nMemFree:        10370404 kB\n";
        assert_eq!(meminfo_total(t), Some(24_683_584 * 1024));
        assert_eq!(meminfo_total("MemFree: 5 kB\n"), None);
        assert_eq!(meminfo_total("MemTotal: x kB\n"), None);
    }

    #[test]
    fn formats() {
        assert_eq!(fmt_bytes(512), "512 B");
        assert_eq!(fmt_bytes(1536), "1.5 KiB");
        assert_eq!(fmt_bytes(12 << 30), "12 GiB");
        assert_eq!(fmt_bytes(u64::MAX), "16 EiB");
        assert_eq!(fmt_count(950), "950");
        assert_eq!(fmt_count(2_400_000_000), "2.4 G");
        assert_eq!(fmt_count(u64::MAX), "18 E");
    }

    #[test]
    fn the_largest_image_is_counted_in_64_bits_and_refused() {
        let need = Need {
            width: 65536,
            height: 65536,
            corners: true,
            ..Need::default()
        };
        assert_eq!(need.lattice(), 65537 * 65537);
        assert!(need.lattice() > u32::MAX as u64);
        assert!(need.frame_bytes() > 65537 * 65537 * SAMPLE_BYTES);
        let b = Budget::bytes(12 << 30);
        let e = b.check(&need).unwrap_err();
        assert_eq!(e.item.what, What::Image);
        let msg = e.to_string();
        assert!(
            msg.starts_with("the image needs ")
                && msg.contains("for 4.3 G samples")
                && msg.contains("(limit 12 GiB, as asked; raise it with --memory-limit, or render a smaller image)"),
            "{msg}"
        );
        assert!(Budget::unlimited().check(&need).is_ok());
    }

    #[test]
    fn a_refusal_names_the_largest_part() {
        let need = Need {
            width: 100,
            height: 100,
            prims: 1000,
            bounded: 1000,
            cells: 1 << 20,
            refs: 2_400_000_000,
            explicit_grid: true,
            ..Need::default()
        };
        let e = Budget::bytes(1 << 30).check(&need).unwrap_err();
        assert_eq!(e.item.what, What::Grid);
        assert_eq!(e.total, need.peak());
        let msg = e.to_string();
        assert_eq!(
            msg,
            "the grid needs 22 GiB for 1.0 M cells and 2.4 G references (limit 1.0 GiB, \
             as asked; raise it with --memory-limit, or choose a coarser --grid)"
        );
    }

    #[test]
    fn an_octree_refusal_names_the_octree_and_its_knobs() {
        let need = Need {
            width: 100,
            height: 100,
            prims: 1000,
            bounded: 1000,
            cells: 1 << 20,
            refs: 2_400_000_000,
            octree: true,
            ..Need::default()
        };
        let e = Budget::bytes(1 << 30).check(&need).unwrap_err();
        assert_eq!(e.item.what, What::Octree);
        assert_eq!(
            e.to_string(),
            "the octree needs 18 GiB for 1.0 M node words and 2.4 G references (limit \
             1.0 GiB, as asked; raise it with --memory-limit, or a larger --octree-leaf or \
             fewer --octree-levels)"
        );
    }

    #[test]
    fn max_refs_is_the_most_that_fits() {
        let need = Need {
            width: 64,
            height: 64,
            prims: 10_000,
            bounded: 10_000,
            ..Need::default()
        };
        let b = Budget::bytes(64 << 20);
        let cells = 30_000;
        let r = need.max_refs(&b, cells);
        assert!(r > 0);
        let at = |refs| Need {
            cells,
            refs,
            ..need
        };
        assert!(b.fits(&at(r)));
        assert!(!b.fits(&at(r + 1)));
        // cells alone over the limit: nothing fits
        assert_eq!(need.max_refs(&b, 1 << 30), 0);
    }
}
