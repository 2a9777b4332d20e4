//! Light buffers (Haines & Greenberg 1986): per point light, a direction
//! cube whose cells list the finite primitives that can block a shadow
//! feeler towards the light whose direction (seen from the light) falls in
//! the cell. Traversal: `src/trace/lightbuf.rs` ↔ `shaders/lightbuf.glsl`.
//!
//! Layout: cell `((light·6 + face)·R + iv)·R + iu`, face = 2·axis + (1 when
//! the direction's dominant component is negative); for axis a the cell's
//! coordinates are u = c_{a+1}/|c_a|, v = c_{a+2}/|c_a| (indices mod 3),
//! each of [−1, 1] cut into R equal cells. `start` holds `cells + 1`
//! offsets into `refs` (primitive indices into `prims`, ascending in each
//! cell). R is `Globals::flags.w` (0: no light buffer).
//!
//! Filing is conservative (docs/method.md, "Light buffers"): a feeler from
//! `o` lies within a distance ρ of the ray from the light through `o`
//! (the surface offset moved `o` off the line to the light, and f32
//! rounding bends it), so each primitive's bounds, widened by ρ, are
//! projected onto the faces; the cell range gets one more cell on every
//! side for the f32 rounding of the feeler's cell; a widened box that
//! (widened once more) holds the light goes into every cell.

use super::grid::Bounds;

/// Most cells along a face's side.
pub const RES_MAX: u32 = 64;
/// Fewest cells along a face's side.
pub const RES_MIN: u32 = 4;

/// The resolution for `n` finite primitives: ⌈√n⌉ within
/// [`RES_MIN`, `RES_MAX`], so a cell lists a few primitives' worth of
/// directions (each primitive covers at least the 3 × 3 cells its padding
/// gives it).
pub fn resolution(n: usize) -> u32 {
    ((n as f64).sqrt().ceil() as u32).clamp(RES_MIN, RES_MAX)
}

/// Cells of `lights` light buffers of resolution `res`.
pub fn cells(lights: usize, res: u32) -> u64 {
    lights as u64 * 6 * res as u64 * res as u64
}

/// The cell rectangles of one primitive (`None`: every cell).
type Filed = (u32, Option<Vec<(usize, [u32; 4])>>);

/// A built light buffer.
#[derive(Clone, Debug, Default)]
pub struct LightBuf {
    pub res: u32,
    pub start: Vec<u32>,
    pub refs: Vec<u32>,
}

/// The widening ρ of every box for light `l` (camera-relative, f64):
/// four surface offsets `eps`, plus 10⁻⁵ of the coordinates' magnitude
/// (`scale`: the scene's size and its distance from the camera) for f32
/// rounding of the feeler's origin and direction (about 160 f32 steps).
pub fn widening(l: [f64; 3], eps: f64, scale: f64) -> f64 {
    let mag = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
    (4.0 * eps + 1e-5 * (mag + scale)).max(1e-30)
}

/// The cell rectangles (face, iu0..=iu1, iv0..=iv1) light `l` files box
/// `b` in, widened by `rho`; `None`: every cell.
fn rects(l: [f64; 3], b: &Bounds, rho: f64, res: u32) -> Option<Vec<(usize, [u32; 4])>> {
    let lo: [f64; 3] = std::array::from_fn(|i| b.lo[i] - rho - l[i]);
    let hi: [f64; 3] = std::array::from_fn(|i| b.hi[i] + rho - l[i]);
    if (0..3).all(|i| lo[i] - rho <= 0.0 && hi[i] + rho >= 0.0) {
        return None;
    }
    let r = res as f64;
    let index = |u: f64| ((u + 1.0) * 0.5 * r).floor();
    let range = |ulo: f64, uhi: f64| -> [u32; 2] {
        let a = (index(ulo) - 1.0).clamp(0.0, r - 1.0);
        let b = (index(uhi) + 1.0).clamp(0.0, r - 1.0);
        [a as u32, b as u32]
    };
    let mut out = Vec::new();
    for a in 0..3 {
        for neg in [false, true] {
            // depth along the face's outward axis
            let (d0, d1) = if neg {
                (-hi[a], -lo[a])
            } else {
                (lo[a], hi[a])
            };
            if d1 < rho {
                continue;
            }
            let d0 = d0.max(rho);
            let (i0, i1) = (1.0 / d0, 1.0 / d1);
            let span = |k: usize| {
                let c = [lo[k] * i0, lo[k] * i1, hi[k] * i0, hi[k] * i1];
                let mn = c.iter().copied().fold(f64::INFINITY, f64::min);
                let mx = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                (mn, mx)
            };
            let (u0, u1) = span((a + 1) % 3);
            let (v0, v1) = span((a + 2) % 3);
            // The box's directions miss this face. A margin of two cells
            // keeps the face when they lie just past its edge: a feeler
            // whose f32 dominant axis (a near tie) picks this face lands
            // in its edge cells.
            let m = 1.0 + 2.0 / r;
            if u0 > m || u1 < -m || v0 > m || v1 < -m {
                continue;
            }
            let [iu0, iu1] = range(u0, u1);
            let [iv0, iv1] = range(v0, v1);
            out.push((2 * a + neg as usize, [iu0, iu1, iv0, iv1]));
        }
    }
    Some(out)
}

/// Bytes the build holds per light and primitive while it counts: the
/// primitive's entry (`Filed`, 32 B) and its cell rectangles on the heap
/// (a box seen from a point spans at most three cube faces, 24 B each,
/// with the allocation's own overhead).
pub const FILED_BYTES: u64 = 32 + 3 * 24 + 16;

/// Builds the light buffers of `lights` (camera-relative positions) over
/// `bounds` (the finite primitives' bounds, in `prims` order), or `None`
/// when the references would pass `max_refs` or what the build holds
/// while counting them (`FILED_BYTES` per light and primitive, 8 B per
/// cell) would pass `max_bytes`; both are checked before the allocation.
pub fn build(
    lights: &[[f64; 3]],
    bounds: &[Bounds],
    eps: f64,
    scale: f64,
    max_refs: u64,
    max_bytes: u64,
) -> Option<LightBuf> {
    use rayon::prelude::*;
    let res = resolution(bounds.len());
    let per_light = 6 * (res as usize) * (res as usize);
    let ncells = lights.len() * per_light;
    let transient = (lights.len() as u64)
        .saturating_mul(bounds.len() as u64)
        .saturating_mul(FILED_BYTES)
        .saturating_add((ncells as u64 + 1) * 8);
    if transient > max_bytes {
        return None;
    }
    // Per light, in parallel: the cell rectangles of every primitive.
    let filed: Vec<Vec<Filed>> = lights
        .par_iter()
        .map(|&l| {
            let rho = widening(l, eps, scale);
            bounds
                .iter()
                .enumerate()
                .map(|(i, b)| (i as u32, rects(l, b, rho, res)))
                .collect()
        })
        .collect();
    let mut count = vec![0u64; ncells + 1];
    let mut total = 0u64;
    for (li, list) in filed.iter().enumerate() {
        let base = li * per_light;
        for (_, rs) in list {
            match rs {
                None => {
                    for c in &mut count[base..base + per_light] {
                        *c += 1;
                    }
                    total += per_light as u64;
                }
                Some(rs) => {
                    for &(f, [u0, u1, v0, v1]) in rs {
                        for iv in v0..=v1 {
                            for iu in u0..=u1 {
                                count[base
                                    + (f * res as usize + iv as usize) * res as usize
                                    + iu as usize] += 1;
                            }
                        }
                        total += (u1 - u0 + 1) as u64 * (v1 - v0 + 1) as u64;
                    }
                }
            }
        }
    }
    if total > max_refs || total > u32::MAX as u64 {
        return None;
    }
    let mut start = Vec::with_capacity(ncells + 1);
    let mut acc = 0u32;
    for c in &count[..ncells] {
        start.push(acc);
        acc += *c as u32;
    }
    start.push(acc);
    drop(count);
    let mut next: Vec<u32> = start[..ncells].to_vec();
    let mut refs = vec![0u32; total as usize];
    let mut put = |cell: usize, i: u32| {
        refs[next[cell] as usize] = i;
        next[cell] += 1;
    };
    // Primitives in ascending order, so each cell's list is ascending.
    for (li, list) in filed.iter().enumerate() {
        let base = li * per_light;
        for (i, rs) in list {
            match rs {
                None => (0..per_light).for_each(|c| put(base + c, *i)),
                Some(rs) => {
                    for &(f, [u0, u1, v0, v1]) in rs {
                        for iv in v0..=v1 {
                            for iu in u0..=u1 {
                                put(
                                    base + (f * res as usize + iv as usize) * res as usize
                                        + iu as usize,
                                    *i,
                                );
                            }
                        }
                    }
                }
            }
        }
    }
    Some(LightBuf { res, start, refs })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_around_the_light_is_in_every_cell() {
        let b = Bounds {
            lo: [-1.0; 3],
            hi: [1.0; 3],
        };
        assert!(rects([0.0; 3], &b, 1e-6, 8).is_none());
        // a box touching the light's position, too
        let b = Bounds {
            lo: [0.0, 2.0, 2.0],
            hi: [1.0, 3.0, 3.0],
        };
        assert!(rects([0.0, 2.0, 2.0], &b, 1e-6, 8).is_none());
    }

    #[test]
    fn a_small_box_on_an_axis_covers_the_face_centre_padded() {
        let b = Bounds {
            lo: [9.9, -0.01, -0.01],
            hi: [10.1, 0.01, 0.01],
        };
        let r = rects([0.0; 3], &b, 1e-6, 8).unwrap();
        // face +x only, the four centre cells padded by one: 2..=5
        assert_eq!(r, vec![(0, [2, 5, 2, 5])]);
        let lb = build(&[[0.0; 3]], &[b], 1e-7, 10.0, u64::MAX, u64::MAX).unwrap();
        assert_eq!(lb.res, RES_MIN);
        assert_eq!(lb.start.len(), 6 * 16 + 1);
    }

    /// What the build holds while counting is checked against its
    /// allowance before it allocates: a million primitives and eight
    /// lights (some 1 GB of rectangles) are turned down with 100 MB.
    #[test]
    fn the_build_refuses_what_it_would_hold_beyond_its_allowance() {
        let b = Bounds {
            lo: [9.9, -0.01, -0.01],
            hi: [10.1, 0.01, 0.01],
        };
        let many = vec![b; 1_000_000];
        let lights = [[0.0; 3]; 8];
        // Unbounded references: only the allowance can turn it down.
        assert!(build(&lights, &many, 1e-7, 10.0, u64::MAX, 100 << 20).is_none());
        // One light and ten primitives fit in that allowance.
        assert!(build(&lights[..1], &many[..10], 1e-7, 10.0, u64::MAX, 100 << 20).is_some());
    }
}
