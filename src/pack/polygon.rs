//! How a polygon is packed (docs/method.md, "Polygon"): its plane in
//! `Prim::a`, `[count, drop axis, convex, longest band]` in `Prim::b`, and
//! in `extra` from `Prim::data`:
//!
//! 1. its vertices projected on the plane of the two axes other than the
//!    normal's largest (`axes`), two to a vec4: `(u0, v0, u1, v1)`, ...;
//! 2. for a non-convex polygon of `BAND_MIN_VERTICES` or more, edge bands:
//!    the range of v cut into K bands (`Prim::c` = `[v_min, K / (v_max −
//!    v_min), K, S]`), then, as floats four to a vec4, the K + 1 offsets of
//!    each band's list and the lists of edges (edge j runs from vertex j − 1
//!    to vertex j) whose v range meets the band or its neighbours;
//! 3. from float S of that stream (S = 0: none), the cells (`cells`):
//!    u_min, columns per unit of u, the column count M, and the K × M
//!    codes `CELL_OUT`, `CELL_IN`, `CELL_EDGE`, band by band.
//!
//! The crossings test counts the edges that cross the horizontal line
//! through the hit point; every such edge spans the point's v, so it is in
//! the point's band (the margin of one band absorbs any rounding in
//! computing a band index), and the test over a band's list gives the same
//! parity as the test over all edges, bit for bit, in any float type. A
//! 144-vertex gear face costs a dozen edge tests instead of 144, and none
//! at all for a point in a cell away from every edge.

use crate::constants::{CELL_EDGE, CELL_IN, CELL_OUT};

/// Non-convex polygons with at least this many vertices get edge bands.
pub const BAND_MIN_VERTICES: usize = 16;
/// Most bands a polygon gets.
pub const BANDS_MAX: usize = 256;
/// Bands are given up when their lists would hold more than this many
/// edges per vertex (edges spanning most of the polygon's height).
pub const BAND_REFS_PER_VERTEX: usize = 8;

/// The two axes a polygon is tested in, for the axis its normal drops.
pub fn axes(drop: usize) -> (usize, usize) {
    match drop {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    }
}

/// The band of `y` among `k` bands from `v_min` with `inv_h` bands per unit.
fn band(y: f32, v_min: f32, inv_h: f32, k: usize) -> usize {
    let b = ((y - v_min) * inv_h).floor();
    b.clamp(0.0, (k - 1) as f32) as usize
}

/// The packed form of one polygon: what goes in `extra`, `Prim::c`, and
/// the longest band list (the loop a test makes at most).
pub struct Packed2d {
    pub extra: Vec<[f32; 4]>,
    pub c: [f32; 4],
    pub longest: usize,
}

/// Packs projected vertices `q` (already in f32, as the tracers read them).
pub fn pack(q: &[[f32; 2]], convex: bool) -> Packed2d {
    let n = q.len();
    let mut extra: Vec<[f32; 4]> = q
        .chunks(2)
        .map(|c| {
            let b = c.get(1).copied().unwrap_or([0.0; 2]);
            [c[0][0], c[0][1], b[0], b[1]]
        })
        .collect();
    let plain = Packed2d {
        extra: extra.clone(),
        c: [0.0; 4],
        longest: n,
    };
    if convex || n < BAND_MIN_VERTICES {
        return plain;
    }
    let (lo, hi) = q
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), p| {
            (l.min(p[1]), h.max(p[1]))
        });
    let mut k = (n / 2).clamp(2, BANDS_MAX);
    let lists = loop {
        if hi <= lo || k < 2 {
            return plain;
        }
        let inv_h = k as f32 / (hi - lo);
        if !inv_h.is_finite() {
            return plain;
        }
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); k];
        for j in 0..n {
            let (a, b) = (q[(j + n - 1) % n][1], q[j][1]);
            let b0 = band(a.min(b), lo, inv_h, k).saturating_sub(1);
            let b1 = (band(a.max(b), lo, inv_h, k) + 1).min(k - 1);
            for l in &mut lists[b0..=b1] {
                l.push(j as u32);
            }
        }
        let total: usize = lists.iter().map(Vec::len).sum();
        if total <= BAND_REFS_PER_VERTEX * n {
            break (lists, inv_h);
        }
        k /= 2;
    };
    let (lists, inv_h) = lists;
    let longest = lists.iter().map(Vec::len).max().unwrap_or(0);
    if longest * 2 > n {
        return plain; // no gain
    }
    // Offsets, then the lists, as exact floats (all < 2^24).
    let mut floats: Vec<f32> =
        Vec::with_capacity(k + 1 + lists.iter().map(Vec::len).sum::<usize>());
    let mut at = 0usize;
    floats.push(0.0);
    for l in &lists {
        at += l.len();
        floats.push(at as f32);
    }
    for l in &lists {
        floats.extend(l.iter().map(|&j| j as f32));
    }
    // The cells after the lists: where they start in the stream (Prim::c.w,
    // 0 for none), then u_min, columns per unit, the column count M and
    // the K × M codes.
    let cells_at = floats.len();
    let has_cells = match cells(q, lo, inv_h, k) {
        Some((u_min, inv_w, m, codes)) => {
            floats.extend([u_min, inv_w, m as f32]);
            floats.extend(codes.iter().map(|&c| c as f32));
            true
        }
        None => false,
    };
    extra.extend(floats.chunks(4).map(|c| {
        let mut v = [0.0f32; 4];
        v[..c.len()].copy_from_slice(c);
        v
    }));
    Packed2d {
        extra,
        c: [
            lo,
            inv_h,
            k as f32,
            if has_cells { cells_at as f32 } else { 0.0 },
        ],
        longest,
    }
}

/// Most columns of cells per band.
pub const CELL_COLUMNS_MAX: usize = 64;

/// Classifies the cells of a banded polygon: the K bands cut into M
/// columns over the vertices' u range. A cell that no edge's box comes
/// within a quarter cell of lies wholly inside or wholly outside, and every
/// point the tracers file in it (by the f32 band and column of the hit
/// point, whose rounding moves a point by far less than a quarter cell)
/// gets from the crossings test the parity of the cell's centre: no edge
/// is near enough for the test's rounding to decide a crossing either
/// way. So the code answers for the test, bit for bit; `CELL_EDGE` cells
/// take the test. Returns (u_min, columns per unit, M, codes band-major),
/// or `None` when the u range is empty or not representable.
pub fn cells(
    q: &[[f32; 2]],
    v_min: f32,
    inv_h: f32,
    k: usize,
) -> Option<(f32, f32, usize, Vec<u32>)> {
    let n = q.len();
    let (u_lo, u_hi) = q
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), p| {
            (l.min(p[0]), h.max(p[0]))
        });
    let m = k.min(CELL_COLUMNS_MAX);
    if u_hi <= u_lo || m < 2 {
        return None;
    }
    let inv_w = m as f32 / (u_hi - u_lo);
    if !inv_w.is_finite() || !inv_h.is_finite() {
        return None;
    }
    // Cell (b, c) covers u in u_lo + [c, c + 1] / inv_w, v in v_min + [b,
    // b + 1] / inv_h; each grown by a quarter cell.
    let (w, h) = (1.0 / inv_w as f64, 1.0 / inv_h as f64);
    // Cells near an edge first; the others get their side below.
    let mut codes = vec![CELL_OUT; k * m];
    // Edge j runs from vertex j − 1 to vertex j (a: the previous vertex).
    let mut a = q[n - 1];
    for &b in q {
        let (ul, uh) = (a[0].min(b[0]) as f64, a[0].max(b[0]) as f64);
        let (vl, vh) = (a[1].min(b[1]) as f64, a[1].max(b[1]) as f64);
        // Cells whose grown rectangle meets the edge's box.
        let c0 = (((ul - u_lo as f64) / w - 1.25).floor().max(0.0)) as usize;
        let c1 = (((uh - u_lo as f64) / w + 0.25).floor().max(0.0) as usize).min(m - 1);
        let b0 = (((vl - v_min as f64) / h - 1.25).floor().max(0.0)) as usize;
        let b1 = (((vh - v_min as f64) / h + 0.25).floor().max(0.0) as usize).min(k - 1);
        for bb in b0..=b1 {
            for cc in c0..=c1 {
                codes[bb * m + cc] = CELL_EDGE;
            }
        }
        a = b;
    }
    // Each band's centre line crosses the edges at xs (even-odd, in
    // f64); a clean cell's centre is inside when an odd number of them
    // lie to its right.
    // Each edge is asked only about the bands whose centre lines its v
    // range can reach (a window a band wider on each side than its range,
    // every band where it is not finite), with the same test and the same
    // crossing as a scan of every edge for every band: bands × edges took
    // gears' faces 46 M instructions, more than the BVH build.
    let centre = |bb: usize| v_min as f64 + (bb as f64 + 0.5) * h;
    // The band whose centre line lies at v, fractional, kept within −1..=k.
    let band = |v: f64| ((v - v_min as f64) / h - 0.5).clamp(-1.0, k as f64);
    let mut crossings: Vec<(usize, f64)> = Vec::new();
    let mut a = q[n - 1];
    for &b in q {
        let (ax, ay, bx, by) = (a[0] as f64, a[1] as f64, b[0] as f64, b[1] as f64);
        let (first, last) = if ay.is_finite() && by.is_finite() {
            let (lo, hi) = (band(ay.min(by)), band(ay.max(by)));
            (
                (lo.floor() - 1.0).max(0.0) as usize,
                ((hi.ceil() + 1.0).max(0.0) as usize).min(k - 1),
            )
        } else {
            (0, k - 1)
        };
        for bb in first..=last {
            let py = centre(bb);
            if (ay > py) != (by > py) {
                crossings.push((bb, ax + (py - ay) * (bx - ax) / (by - ay)));
            }
        }
        a = b;
    }
    // Band by band, each band's crossings in increasing order.
    crossings.sort_unstable_by(|p, q| p.0.cmp(&q.0).then(p.1.total_cmp(&q.1)));
    let mut next = 0;
    for bb in 0..k {
        let start = next;
        while next < crossings.len() && crossings[next].0 == bb {
            next += 1;
        }
        let xs = &crossings[start..next];
        let mut left = 0; // crossings at or left of the centre
        for cc in 0..m {
            let i = bb * m + cc;
            let px = u_lo as f64 + (cc as f64 + 0.5) * w;
            while left < xs.len() && xs[left].1 <= px {
                left += 1;
            }
            if codes[i] != CELL_EDGE && (xs.len() - left) % 2 == 1 {
                codes[i] = CELL_IN;
            }
        }
    }
    Some((u_lo, inv_w, m, codes))
}

/// Vertex `j`'s projected coordinates from the pairs at `extra[base..]`.
#[inline(always)]
pub fn vertex(extra: &[[f32; 4]], base: usize, j: usize) -> [f32; 2] {
    let e = &extra[base + j / 2];
    if j.is_multiple_of(2) {
        [e[0], e[1]]
    } else {
        [e[2], e[3]]
    }
}

/// Float `i` of the stream that starts at `extra[base]`.
#[inline(always)]
pub fn float_at(extra: &[[f32; 4]], base: usize, i: usize) -> f32 {
    extra[base + i / 4][i % 4]
}

/// The polygon's vertices back in 3D (camera-relative), from its plane and
/// projected vertices: for messages and test targets, not for tracing.
pub fn vertices_3d(prim: &super::layout::Prim, extra: &[[f32; 4]]) -> Vec<[f32; 3]> {
    let count = prim.b[0] as usize;
    let drop = prim.b[1] as usize;
    let (i0, i1) = axes(drop);
    let n = [prim.a[0], prim.a[1], prim.a[2]];
    (0..count)
        .map(|j| {
            let [u, v] = vertex(extra, prim.data as usize, j);
            let mut p = [0.0f32; 3];
            p[i0] = u;
            p[i1] = v;
            p[drop] = (prim.a[3] - n[i0] * u - n[i1] * v) / n[drop];
            p
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gear-like outline: teeth alternating between two radii.
    fn star(teeth: usize) -> Vec<[f32; 2]> {
        (0..2 * teeth)
            .map(|i| {
                let a = i as f32 * std::f32::consts::PI / teeth as f32;
                let r = if i % 2 == 0 { 1.0 } else { 0.8 };
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    }

    /// Every clean cell's code is the even-odd parity of its centre over
    /// every edge (in f64, the crossing as `cells` computes it): the
    /// per-edge band windows miss no crossing. Random outlines, gears and
    /// band counts from 2 to 120.
    #[test]
    fn clean_cells_have_the_parity_of_their_centre_over_every_edge() {
        use proptest::prelude::*;
        use proptest::test_runner::{Config, TestRunner};
        let check = |q: &[[f32; 2]], k: usize| {
            let (vl, vh) = q
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[1]), h.max(p[1]))
                });
            let inv_h = k as f32 / (vh - vl);
            let Some((u_lo, inv_w, m, codes)) = cells(q, vl, inv_h, k) else {
                return;
            };
            let (w, h) = (1.0 / inv_w as f64, 1.0 / inv_h as f64);
            for bb in 0..k {
                let py = vl as f64 + (bb as f64 + 0.5) * h;
                for cc in 0..m {
                    let px = u_lo as f64 + (cc as f64 + 0.5) * w;
                    let mut right = 0;
                    for j in 0..q.len() {
                        let (a, b) = (q[(j + q.len() - 1) % q.len()], q[j]);
                        let (ax, ay, bx, by) = (a[0] as f64, a[1] as f64, b[0] as f64, b[1] as f64);
                        if (ay > py) != (by > py) && ax + (py - ay) * (bx - ax) / (by - ay) > px {
                            right += 1;
                        }
                    }
                    let code = codes[bb * m + cc];
                    if code != CELL_EDGE {
                        let want = if right % 2 == 1 { CELL_IN } else { CELL_OUT };
                        assert_eq!(code, want, "band {bb} column {cc} of {q:?}");
                    }
                }
            }
        };
        for teeth in [3, 12, 40] {
            for k in [2, 7, 33, 120] {
                check(&star(teeth), k);
            }
        }
        let pt = (-10.0f32..10.0, -10.0f32..10.0).prop_map(|(x, y)| [x, y]);
        let mut runner = TestRunner::new(Config::with_cases(300));
        runner
            .run(
                &(proptest::collection::vec(pt, 3..40), 2usize..120),
                |(q, k)| {
                    check(&q, k);
                    Ok(())
                },
            )
            .unwrap();
    }

    /// Even-odd over all edges, as the tracers do without bands.
    fn crossings(q: &[[f32; 2]], px: f32, py: f32, edges: impl Iterator<Item = usize>) -> bool {
        let n = q.len();
        let mut inside = false;
        for j in edges {
            let (a, b) = (q[(j + n - 1) % n], q[j]);
            if (a[1] > py) != (b[1] > py) {
                let xc = a[0] + (py - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
                if px < xc {
                    inside = !inside;
                }
            }
        }
        inside
    }

    #[test]
    fn a_band_gives_the_parity_of_all_edges() {
        let q = star(72);
        let p = pack(&q, false);
        let [lo, inv_h, k, _] = p.c;
        let k = k as usize;
        assert!(k >= 8, "a gear face gets bands");
        assert!(p.longest * 3 < q.len(), "longest band {}", p.longest);
        let base = q.len().div_ceil(2);
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.4 - 1.2
        };
        for _ in 0..20_000 {
            let (px, py) = (next(), next());
            let b = band(py, lo, inv_h, k);
            let (s, e) = (
                float_at(&p.extra, base, b) as usize,
                float_at(&p.extra, base, b + 1) as usize,
            );
            let edges = (s..e).map(|i| float_at(&p.extra, base, k + 1 + i) as usize);
            assert_eq!(
                crossings(&q, px, py, edges),
                crossings(&q, px, py, 0..q.len()),
                "({px}, {py})"
            );
        }
        // the vertices read back
        for (j, v) in q.iter().enumerate() {
            assert_eq!(vertex(&p.extra, 0, j), *v);
        }
    }

    /// The cells answer as the crossings test over every edge does, for
    /// points on a fine lattice over the polygon (many near the edges)
    /// and vertices, in f32 and f64 as the tracers compute them; most
    /// points in a gear face's box land in a cell that answers without a
    /// test.
    #[test]
    fn a_cell_gives_the_parity_of_all_edges() {
        use crate::pack::layout::Prim;
        use crate::trace::intersect::polygon_cell;
        for q in [star(72), star(24)] {
            let p = pack(&q, false);
            assert!(p.c[3] > 0.0, "a banded face gets cells");
            let prim = Prim {
                b: [q.len() as f32, 2.0, 0.0, p.longest as f32],
                c: p.c,
                data: 0,
                ..Prim::default()
            };
            let (mut answered, mut total) = (0, 0);
            let mut check = |px: f32, py: f32| {
                let code = polygon_cell(&prim, &p.extra, px, py);
                let code64 = polygon_cell(&prim, &p.extra, px as f64, py as f64);
                let all = crossings(&q, px, py, 0..q.len());
                for c in [code, code64] {
                    if c != CELL_EDGE {
                        assert_eq!(c == CELL_IN, all, "({px}, {py}): code {c}");
                    }
                }
                if px.abs() <= 1.0 && py.abs() <= 1.0 {
                    total += 1;
                    if code != CELL_EDGE {
                        answered += 1;
                    }
                }
            };
            for i in 0..=600 {
                for j in 0..=600 {
                    check(-1.2 + 2.4 * i as f32 / 600.0, -1.2 + 2.4 * j as f32 / 600.0);
                }
            }
            for v in &q {
                check(v[0], v[1]);
                check(v[0].next_up(), v[1].next_down());
            }
            check(f32::NAN, 0.0);
            // Within the polygon's box; the rest of the lattice takes the test.
            eprintln!(
                "{} vertices: {answered} of {total} answered by a cell",
                q.len()
            );
            assert!(
                answered * 4 > total,
                "{answered} of {total} answered by a cell"
            );
        }
    }

    #[test]
    fn convex_and_small_polygons_get_no_bands() {
        assert_eq!(pack(&star(72), true).c, [0.0; 4]);
        assert_eq!(pack(&star(4), false).c, [0.0; 4]);
        let p = pack(&star(3), false);
        assert_eq!(p.extra.len(), 3);
    }
}
