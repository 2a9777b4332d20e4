//! Light buffers (Haines & Greenberg 1986): per point light, a direction
//! cube whose cells list the finite primitives that can block a shadow
//! feeler towards the light whose direction (seen from the light) falls in
//! the cell. Traversal: `src/trace/lightbuf.rs` ↔ `shaders/lightbuf.glsl`.
//!
//! Layout: cell `((light·6 + face)·R + iv)·R + iu`, face = 2·axis + (1 when
//! the direction's dominant component is negative); for axis a the cell's
//! coordinates are u = c_{a+1}/|c_a|, v = c_{a+2}/|c_a| (indices mod 3).
//! Each face is cut into R × R cells over its *window*: the rectangle of
//! u, v that the primitives seen through that face cover (the whole face
//! where a primitive surrounds the light), so that a light far from the
//! scene spends its cells where the scene is. `start` holds `cells + 1`
//! offsets into `refs`, then per light and face the window's f32 words
//! `[u0, su, v0, sv]`: iu = ⌊(u − u0)·su⌋ (su = 0: nothing seen through
//! that face). `refs` holds a pair per reference, the primitive's index
//! into `prims` and the f32 bits of its least depth along the face's axis
//! (its widened box's, rounded down), each cell's pairs nearest the light
//! first (primitive order on ties): a feeler stops at the first pair
//! deeper than its own origin, which nothing beyond can block. R is
//! `Globals::flags.w` (0: no light buffer).
//!
//! Filing is conservative (docs/method.md, "Light buffers"): a feeler from
//! `o` lies within a distance ρ of the ray from the light through `o`
//! (the surface offset moved `o` off the line to the light, and f32
//! rounding bends it), so each primitive's bounds, widened by ρ, are
//! projected onto the faces; the windows and spans are widened by
//! `U_ERR` for the f32 rounding of the feeler's u and v, and each cell
//! range gets one more cell on every side for that of its cell index; a
//! widened box that (widened once more) holds the light goes into every
//! cell.

use super::grid::Bounds;

/// Most cells along a face's side.
pub const RES_MAX: u32 = 128;
/// Fewest cells along a face's side.
pub const RES_MIN: u32 = 4;

/// The resolution for `n` finite primitives: ⌈2√n⌉ within
/// [`RES_MIN`, `RES_MAX`], so that a window's cells outnumber the
/// primitives seen through it (each primitive covers at least the 3 × 3
/// cells its padding gives it).
pub fn resolution(n: usize) -> u32 {
    ((2.0 * (n as f64).sqrt()).ceil() as u32).clamp(RES_MIN, RES_MAX)
}

/// Cells of `lights` light buffers of resolution `res`.
pub fn cells(lights: usize, res: u32) -> u64 {
    lights as u64 * 6 * res as u64 * res as u64
}

/// Per face, the primitive's span of u and v (clamped to [−1, 1]) and its
/// least depth along the face's axis; `None`: every cell.
type Spans = Option<Vec<(usize, [f64; 4], f64)>>;

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

/// The spans light `l` sees box `b` in, widened by `rho`, per face; `None`:
/// every cell.
fn spans(l: [f64; 3], b: &Bounds, rho: f64, res: u32) -> Spans {
    let lo: [f64; 3] = std::array::from_fn(|i| b.lo[i] - rho - l[i]);
    let hi: [f64; 3] = std::array::from_fn(|i| b.hi[i] + rho - l[i]);
    if (0..3).all(|i| lo[i] - rho <= 0.0 && hi[i] + rho >= 0.0) {
        return None;
    }
    let r = res as f64;
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
            let c = |x: f64| x.clamp(-1.0, 1.0);
            out.push((2 * a + neg as usize, [c(u0), c(u1), c(v0), c(v1)], d0));
        }
    }
    Some(out)
}

/// How far a feeler's f32 u (or v) may lie from its exact value: u =
/// c_b / |c_a| after c = o − L, three roundings of at most 2⁻²⁴ each of
/// |u| ≤ 1, then the subtraction of the window's origin, 2⁻²⁴ of at most
/// 2 more; 2⁻²⁰ is over twice their sum. The spans already hold every
/// direction a blocker can lie in (widened by ρ); the windows and the
/// cell ranges are widened by this too, so that however narrow a window
/// (a small scene far from its light: cells of 10⁻⁷ in u), a feeler's f32
/// cell is one its blockers are filed in.
pub const U_ERR: f64 = 1.0 / (1u64 << 20) as f64;

/// A face's window: the f32 origin and cells per unit of u and v
/// (`[u0, su, v0, sv]`), from the union of its spans widened by
/// `U_ERR`; an empty face's scale is 0.
fn window(span: Option<[f64; 4]>, res: u32) -> [f32; 4] {
    match span {
        None => [0.0; 4],
        Some([u0, u1, v0, v1]) => {
            let s = |a: f64, b: f64| (res as f64 / (b - a + 2.0 * U_ERR)) as f32;
            [
                (u0 - U_ERR) as f32,
                s(u0, u1),
                (v0 - U_ERR) as f32,
                s(v0, v1),
            ]
        }
    }
}

/// The cell index range of span a..b (widened by `U_ERR`) under window
/// origin `o`, scale `s` (f32 values): one more cell each side for the
/// rounding of the feeler's cell index itself, clamped.
fn range(a: f64, b: f64, o: f32, s: f32, res: u32) -> [u32; 2] {
    let r = res as f64;
    let (a, b) = (a - U_ERR, b + U_ERR);
    let idx = |u: f64| ((u - o as f64) * s as f64).floor();
    let x = (idx(a) - 1.0).clamp(0.0, r - 1.0);
    let y = (idx(b) + 1.0).clamp(0.0, r - 1.0);
    [x as u32, y as u32]
}

/// Bytes the build holds per light and primitive while it counts: the
/// primitive's spans on the heap, then its cell rectangles (a box seen
/// from a point spans at most three cube faces, 48 and 32 B each, with
/// the allocations' own overhead).
pub const FILED_BYTES: u64 = 2 * 24 + 3 * (48 + 32) + 32;

/// One primitive's cell rectangles for one light: (face, iu0..=iu1,
/// iv0..=iv1, least depth), or `None`: every cell at depth 0.
type Rects = Option<Vec<(usize, [u32; 4], f32)>>;

/// `d` rounded down to an f32.
fn f32_down(d: f64) -> f32 {
    let f = d as f32;
    if f as f64 > d {
        f.next_down()
    } else {
        f
    }
}

/// Calls `f` with each cell (within one light's `6·res²`) that the
/// rectangle (face, iu0..=iu1, iv0..=iv1) covers; every cell for `None`.
fn for_each_cell(res: u32, rect: Option<(usize, [u32; 4])>, mut f: impl FnMut(usize)) {
    let res = res as usize;
    match rect {
        None => (0..6 * res * res).for_each(f),
        Some((face, [u0, u1, v0, v1])) => {
            for iv in v0 as usize..=v1 as usize {
                for iu in u0 as usize..=u1 as usize {
                    f((face * res + iv) * res + iu);
                }
            }
        }
    }
}

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
    // Per light, in parallel: every primitive's spans, each face's window
    // (the union of its spans; every face whole where a primitive is in
    // every cell), then the spans as cell rectangles under the windows.
    let filed: Vec<(Vec<Rects>, [[f32; 4]; 6])> = lights
        .par_iter()
        .map(|&l| {
            let rho = widening(l, eps, scale);
            let sp: Vec<Spans> = bounds.iter().map(|b| spans(l, b, rho, res)).collect();
            let mut win: [Option<[f64; 4]>; 6] = [None; 6];
            for x in sp.iter().flatten() {
                for &(f, [u0, u1, v0, v1], _) in x {
                    win[f] = Some(match win[f] {
                        None => [u0, u1, v0, v1],
                        Some(w) => [w[0].min(u0), w[1].max(u1), w[2].min(v0), w[3].max(v1)],
                    });
                }
            }
            if sp.iter().any(|x| x.is_none()) {
                win = [Some([-1.0, 1.0, -1.0, 1.0]); 6];
            }
            let win = win.map(|w| window(w, res));
            let rects = sp
                .into_iter()
                .map(|x| {
                    x.map(|v| {
                        v.into_iter()
                            .map(|(f, [u0, u1, v0, v1], d0)| {
                                let w = win[f];
                                let [a, b] = range(u0, u1, w[0], w[1], res);
                                let [c, d] = range(v0, v1, w[2], w[3], res);
                                (f, [a, b, c, d], f32_down(d0))
                            })
                            .collect()
                    })
                })
                .collect();
            (rects, win)
        })
        .collect();
    // Each light's references per cell, counted in parallel and checked
    // against the allowance before anything is filed.
    let counts: Vec<Vec<u32>> = filed
        .par_iter()
        .map(|(list, _)| {
            let mut count = vec![0u32; per_light];
            for r in list {
                match r {
                    None => for_each_cell(res, None, |c| count[c] += 1),
                    Some(rs) => {
                        for &(face, rect, _) in rs {
                            for_each_cell(res, Some((face, rect)), |c| count[c] += 1);
                        }
                    }
                }
            }
            count
        })
        .collect();
    let total: u64 = counts.iter().flatten().map(|&c| c as u64).sum();
    if total > max_refs || total > u32::MAX as u64 {
        return None;
    }
    let mut start = Vec::with_capacity(ncells + 1 + lights.len() * 24);
    let mut acc = 0u32;
    for c in counts.iter().flatten() {
        start.push(acc);
        acc += c;
    }
    start.push(acc);
    // Each light's stretch of the references, the lights in parallel. Its
    // primitives' rectangles are filed nearest the light first (primitive
    // order on ties; a primitive in every cell at depth 0), so that each
    // cell's list comes out in that order without a sort of its own.
    // A reference: the primitive and the f32 bits of its least depth.
    let mut entries = vec![[0u32; 2]; total as usize];
    let mut chunks = Vec::with_capacity(lights.len());
    let mut rest = entries.as_mut_slice();
    for li in 0..lights.len() {
        let n = start[(li + 1) * per_light] - start[li * per_light];
        let (head, tail) = rest.split_at_mut(n as usize);
        chunks.push(head);
        rest = tail;
    }
    chunks
        .into_par_iter()
        .zip(filed.par_iter())
        .enumerate()
        .for_each(|(li, (chunk, (list, _)))| {
            // Where each cell's list goes next, within the light's stretch.
            let own = &start[li * per_light..(li + 1) * per_light];
            let mut next: Vec<u32> = own.iter().map(|&o| o - own[0]).collect();
            // (depth, primitive, rectangle; u32::MAX: every cell)
            let mut order: Vec<(f32, u32, u32)> = Vec::with_capacity(list.len() * 2);
            for (i, r) in list.iter().enumerate() {
                match r {
                    None => order.push((0.0, i as u32, u32::MAX)),
                    Some(rs) => order.extend(
                        rs.iter()
                            .enumerate()
                            .map(|(k, &(_, _, d))| (d, i as u32, k as u32)),
                    ),
                }
            }
            order.sort_unstable_by(|a, b| {
                a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2))
            });
            for &(d, i, k) in &order {
                let rect = list[i as usize].as_ref().map(|rs| {
                    let (face, rect, _) = rs[k as usize];
                    (face, rect)
                });
                for_each_cell(res, rect, |c| {
                    chunk[next[c] as usize] = [i, d.to_bits()];
                    next[c] += 1;
                });
            }
        });
    for (_, win) in &filed {
        for w in win {
            start.extend(w.iter().map(|x| x.to_bits()));
        }
    }
    let refs = entries.into_flattened();
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
        assert!(spans([0.0; 3], &b, 1e-6, 8).is_none());
        // a box touching the light's position, too
        let b = Bounds {
            lo: [0.0, 2.0, 2.0],
            hi: [1.0, 3.0, 3.0],
        };
        assert!(spans([0.0, 2.0, 2.0], &b, 1e-6, 8).is_none());
    }

    #[test]
    fn a_small_box_on_an_axis_is_its_face_s_window() {
        let b = Bounds {
            lo: [9.9, -0.01, -0.01],
            hi: [10.1, 0.01, 0.01],
        };
        let rho = widening([0.0; 3], 1e-7, 10.0);
        let sp = spans([0.0; 3], &b, rho, RES_MIN).unwrap();
        // face +x only, u and v within ±0.01/9.9 widened
        assert_eq!(sp.len(), 1);
        let (face, [u0, u1, v0, v1], d0) = sp[0];
        assert_eq!(face, 0);
        assert!(u0 < -0.01 / 9.9 && u0 > -0.0011 && u1 > 0.01 / 9.9 && u1 < 0.0011);
        assert_eq!((u0, u1), (v0, v1));
        assert_eq!(d0, 9.9 - rho);
        let lb = build(&[[0.0; 3]], &[b], 1e-7, 10.0, u64::MAX, u64::MAX).unwrap();
        assert_eq!(lb.res, RES_MIN);
        // the offsets, then four words per face
        assert_eq!(lb.start.len(), 6 * 16 + 1 + 24);
        let win = |f: usize, k: usize| f32::from_bits(lb.start[6 * 16 + 1 + 4 * f + k]);
        // face +x spreads its 4 × 4 cells over the box's directions, widened
        // by the feeler's f32 error on each side
        assert!((win(0, 0) as f64 - (u0 - U_ERR)).abs() < 1e-9);
        let scale = 4.0 / (u1 - u0 + 2.0 * U_ERR);
        assert!((win(0, 1) as f64 - scale).abs() < 1e-6 * scale);
        // the other faces see nothing
        assert!((1..6).all(|f| win(f, 1) == 0.0 && win(f, 3) == 0.0));
        // every cell of face +x lists the box (padding), the others none
        assert_eq!(lb.start[16], 16);
        assert_eq!(lb.refs.len(), 2 * 16);
        assert!(lb
            .refs
            .chunks(2)
            .all(|p| p[0] == 0 && f32::from_bits(p[1]) as f64 <= d0));
    }

    #[test]
    fn each_cell_lists_the_nearest_first() {
        let at = |x: f64| Bounds {
            lo: [x - 0.1, -0.01, -0.01],
            hi: [x + 0.1, 0.01, 0.01],
        };
        // primitive 0 the farthest from the light, 2 the nearest
        let lb = build(
            &[[0.0; 3]],
            &[at(10.0), at(5.0), at(2.0)],
            1e-7,
            10.0,
            u64::MAX,
            u64::MAX,
        )
        .unwrap();
        let cell = |c: usize| {
            let (a, b) = (lb.start[c] as usize, lb.start[c + 1] as usize);
            lb.refs[2 * a..2 * b]
                .chunks(2)
                .map(|p| p[0])
                .collect::<Vec<_>>()
        };
        // the window is the nearest box's (widest) span: the centre cells
        // list all three, nearest first
        let centre = 2 * 4 + 2;
        assert_eq!(cell(centre), vec![2, 1, 0]);
        let depths: Vec<f32> = (0..lb.refs.len() / 2)
            .map(|k| f32::from_bits(lb.refs[2 * k + 1]))
            .collect();
        for c in 0..16 {
            let (a, b) = (lb.start[c] as usize, lb.start[c + 1] as usize);
            assert!(depths[a..b].windows(2).all(|w| w[0] <= w[1]), "cell {c}");
        }
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
