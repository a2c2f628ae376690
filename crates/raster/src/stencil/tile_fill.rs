//! The brute-force fill by 8×8 tiles: each piece visits the tiles of its
//! tile rows it can reach, classifies each against its edges and evaluates a
//! partial tile's pixels a whole 8-pixel row at a time in fixed-width,
//! branch-free loops the compiler vectorizes (one AVX-512 register of f64
//! lanes per row), as llvmpipe bins its fragments in blocks [Mesa llvmpipe,
//! `lp_rast_tri.c`]. Volume triangles are long slivers a few pixels wide;
//! walking them a row span at a time cost a span computation and one or two
//! short runs per pixel row (city_16384 `street` walks about 30 M spans a
//! frame), where a tile costs one classification and eight vector rows.
//!
//! The results are those of the span walk ([`super::fill`]) bit for bit:
//! coverage is the same exact test `E_i + off_i ≥ 0` on the same integer edge
//! values (held in f64, exact below 2⁵³), the depth the same
//! `((E_0·z_0 + E_1·z_1) + E_2·z_2)·inv` rounded to f32, and the counters
//! (processed, updated, touched, scanned tiles) count the same fragments. A
//! unit test checks it on every build this CPU runs.
//!
//! It needs the eye target's tiles to be the counters' 8×8 tiles; other tile
//! sizes take the span walk.

use super::counters::{tiled_index, Counter, StencilStats};
use super::pieces::Fill;
use super::span::StripExtents;
use crate::coverage::{edge_offsets, Coverage};
use crate::layout::BACKGROUND;
use crate::setup::SUBPIXEL;

/// Tile edge of the counters and of the eye targets this fill serves.
const T: usize = 8;

/// Per-piece constants of the tile evaluation.
struct Plane<C> {
    /// Negated coverage offsets `−off_i` (the top-left rule), as f64.
    noff: [f64; 3],
    /// Per lane `k` the edge steps `k·a_i·SUBPIXEL` (exact).
    kstep: [[f64; T]; 3],
    /// The edge steps per row (exact).
    stepy: [f64; 3],
    z: [f64; 3],
    inv: f64,
    dlo: f32,
    dhi: f32,
    zfail: bool,
    delta: C,
}

/// Pixels of a tile.
const TILE: usize = T * T;

/// One tile's share of a piece: the raw edge values at its first pixel, the
/// columns (bit `k`: lane `k`) and rows (`rows.0..=rows.1`) inside the
/// piece's window, whether every pixel of the tile is covered.
#[derive(Clone, Copy)]
struct Block {
    e: [f64; 3],
    lanes: u32,
    rows: (usize, usize),
    full: bool,
}

/// Per-lane counts of a piece's tiles, summed once at its end: fragments
/// processed, updates, first touches.
#[derive(Default)]
struct Counts {
    processed: [u32; T],
    updates: [u32; T],
    first: [u32; T],
}

/// Fills one tile: all eight rows, those outside `b.rows` masked off (the
/// pieces nearly always span the tile's rows; a fixed trip count unrolls),
/// each row a fixed-width, branch-free loop.
#[inline(always)]
fn fill_block<C: Counter>(
    p: &Plane<C>,
    b: Block,
    depth: &[f32; TILE],
    counters: &mut [C; TILE],
    touched: &mut [u8; TILE],
    n: &mut Counts,
) {
    let Block {
        e,
        lanes,
        rows,
        full,
    } = b;
    let eligible: [bool; T] = std::array::from_fn(|k| (lanes >> k) & 1 != 0);
    let zero = C::default();
    let (z0, z1, z2, inv) = (p.z[0], p.z[1], p.z[2], p.inv);
    // Per lane the edge values of the current row, stepped a row at a time:
    // sums of exact integers below 2⁵³, so equal to the span walk's.
    let mut ev: [[f64; T]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|k| e[i] + p.kstep[i][k]));
    for r in 0..T {
        let row_ok = (r >= rows.0) & (r <= rows.1);
        let d: &[f32; T] = depth[r * T..r * T + T].try_into().expect("tile row");
        let c: &mut [C; T] = (&mut counters[r * T..r * T + T])
            .try_into()
            .expect("tile row");
        let t: &mut [u8; T] = (&mut touched[r * T..r * T + T])
            .try_into()
            .expect("tile row");
        let mut cout = [zero; T];
        let mut tout = [0u8; T];
        for k in 0..T {
            let (a, b, cc) = (ev[0][k], ev[1][k], ev[2][k]);
            // `E_i + off_i ≥ 0`, exact in integers: `E_i ≥ −off_i`.
            let covered = row_ok
                & eligible[k]
                & (full | ((a >= p.noff[0]) & (b >= p.noff[1]) & (cc >= p.noff[2])));
            let zp = ((a * z0 + b * z1 + cc * z2) * inv) as f32;
            let dk = d[k];
            let ins = covered & (dk != BACKGROUND) & (dk >= p.dlo) & (dk <= p.dhi);
            // Strict reversed-Z test: pass iff strictly nearer.
            let upd = ins & ((zp > dk) ^ p.zfail);
            n.processed[k] += u32::from(ins);
            n.updates[k] += u32::from(upd);
            n.first[k] += u32::from(upd & (t[k] == 0));
            tout[k] = t[k] | u8::from(upd);
            cout[k] = c[k].wrapping(if upd { p.delta } else { zero });
        }
        *c = cout;
        *t = tout;
        for (row, dy) in ev.iter_mut().zip(p.stepy) {
            for v in row.iter_mut() {
                *v += dy;
            }
        }
    }
}

/// [`super::fill`]'s per-piece fill by tiles (the eye target's tiles must be
/// 8×8): the same fragments, tests, updates and counters as the span walk.
#[inline(always)]
pub(super) fn fill_tiles<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    let Fill {
        counters,
        touched,
        base,
        width,
        eye,
        tri,
        rect,
        win,
        zfail,
        delta,
    } = f;
    let layout = eye.layout;
    debug_assert_eq!(1usize << layout.shift, T);
    let off = edge_offsets(tri, Coverage::Standard);
    let step_x = tri.e.map(|e| e.a * SUBPIXEL);
    let step_y = tri.e.map(|e| e.b * SUBPIXEL);
    let plane = Plane {
        noff: off.map(|o| -o as f64),
        kstep: step_x.map(|s| std::array::from_fn(|k| (k as i64 * s) as f64)),
        stepy: step_y.map(|s| s as f64),
        z: tri.z,
        inv: tri.inv_area,
        dlo: win.dlo,
        dhi: win.dhi,
        zfail,
        delta,
    };
    // Over a whole tile from its first pixel, the largest and smallest
    // change of each edge value plus its offset: the tile is missed when an
    // edge stays negative, wholly covered when all stay non-negative.
    let last = (T - 1) as i64;
    let reach_max: [i64; 3] =
        std::array::from_fn(|i| (last * step_x[i]).max(0) + (last * step_y[i]).max(0) + off[i]);
    let reach_min: [i64; 3] =
        std::array::from_fn(|i| (last * step_x[i]).min(0) + (last * step_y[i]).min(0) + off[i]);
    let step_tile = step_x.map(|s| s * T as i64);
    let tiles_x = i64::from(layout.tiles_x);
    let strips = StripExtents::new(tri);
    // Per lane at most one count per pixel of a 1/8 of the target: no
    // overflow.
    let mut n = Counts::default();
    let mut scanned = 0u64;
    for ty in rect.y0 >> 3..=rect.y1 >> 3 {
        let y0 = ty << 3;
        let ya = rect.y0.max(y0);
        let yb = rect.y1.min(y0 + 7);
        // The tiles the span walk scans on these rows (counted as it counts
        // them: narrow pieces keep their own columns, others the widened
        // extent) and the columns the piece can reach there (the tight extent).
        let ext = strips.extents(ya, yb);
        let (wlo, whi) = if rect.x1 - rect.x0 < 32 {
            (rect.x0, rect.x1)
        } else {
            ext.map_or((1, 0), |(wide, _)| wide)
        };
        let (wlo, whi) = (wlo.max(rect.x0), whi.min(rect.x1));
        scanned += ((whi.max(-1) >> 3).min(tiles_x - 1) - (wlo.max(0) >> 3) + 1).max(0) as u64;
        let (lo, hi) = ext.map_or((1, 0), |(_, tight)| tight);
        let (lo, hi) = (lo.max(rect.x0), hi.min(rect.x1));
        let (t0, t1) = (lo.max(0) >> 3, (hi.max(-1) >> 3).min(tiles_x - 1));
        if t0 > t1 {
            continue;
        }
        let rows = ((ya - y0) as usize, (yb - y0) as usize);
        // Edge values at the first pixel of tile t0, stepped a tile at a time.
        let mut e: [i64; 3] = std::array::from_fn(|i| tri.e[i].at_pixel(t0 << 3, y0));
        for tx in t0..=t1 {
            let et = e;
            for i in 0..3 {
                e[i] += step_tile[i];
            }
            let tb = &eye.tiles[layout.tile_index(tx as u32, ty as u32)];
            if !win.reaches(tb) || (0..3).any(|i| et[i] + reach_max[i] < 0) {
                continue;
            }
            let x0 = tx << 3;
            let (px0, px1) = (lo.max(x0) - x0, hi.min(x0 + 7) - x0);
            let block = Block {
                e: et.map(|v| v as f64),
                lanes: ((2u32 << px1) - 1) & !((1u32 << px0) - 1),
                rows,
                full: (0..3).all(|i| et[i] + reach_min[i] >= 0),
            };
            let di = layout.pixel_index(x0 as u32, y0 as u32);
            let ci = tiled_index(width, x0 as u32, y0 as u32) - base;
            fill_block(
                &plane,
                block,
                (&eye.depth[di..di + TILE]).try_into().expect("a tile"),
                (&mut counters[ci..ci + TILE]).try_into().expect("a tile"),
                (&mut touched[ci..ci + TILE]).try_into().expect("a tile"),
                &mut n,
            );
        }
    }
    let sum = |v: [u32; T]| v.iter().map(|&c| u64::from(c)).sum::<u64>();
    st.pixels_processed += sum(n.processed);
    st.tiles_scanned += scanned;
    st.stencil_updates += sum(n.updates);
    st.pixels_touched += sum(n.first);
}

#[cfg(test)]
mod tests {
    use super::super::counters::Counter;
    use super::super::fill::{fill_piece_dispatch, fill_rows};
    use super::super::pieces::{Fill, Window};
    use super::*;
    use crate::coverage::{pixel_bounds, Rect};
    use crate::edge::Tri;
    use crate::setup::SnappedVertex;
    use crate::{Coverage, DepthTarget, InstructionSet, TileSize};
    use glam::Vec4;

    /// xorshift in [0, 1).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }

        fn below(&mut self, n: i64) -> i64 {
            (self.next() * n as f64) as i64
        }
    }

    /// An eye target with depth over part of it (the rest background), and
    /// the clip-space triangles drawn.
    fn eye(w: u32, h: u32, rng: &mut Rng) -> (DepthTarget, Vec<[Vec4; 3]>) {
        let mut eye = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        let mut drawn = Vec::new();
        for k in 0..40 {
            let v: Vec<Vec4> = (0..3)
                .map(|_| {
                    let z = 0.1 + 0.8 * rng.next() as f32;
                    Vec4::new(
                        rng.next() as f32 * 2.4 - 1.2,
                        rng.next() as f32 * 2.4 - 1.2,
                        z,
                        1.0,
                    )
                })
                .collect();
            let item = crate::DrawItem {
                clip_from_local: glam::Mat4::IDENTITY,
                positions: &v,
                triangles: &[[0, 1, 2], [0, 2, 1]],
                object: k,
                cull: crate::CullMode::None,
            };
            eye.draw(&item, Coverage::Standard).unwrap();
            drawn.push([v[0], v[1], v[2]]);
        }
        (eye, drawn)
    }

    /// The first fan piece of a drawn triangle, set up as the eye pass set it
    /// up: its depth equals the stored depth where it won.
    fn cap(eye: &DepthTarget, v: [Vec4; 3]) -> Option<Tri> {
        let mut s = crate::setup::Setup {
            facing: None,
            clipped: false,
            vertices: [SnappedVertex::default(); crate::clip::MAX_CLIPPED_VERTICES],
            len: 0,
        };
        crate::setup::setup_into(v, &eye.vp, &mut s);
        let p = s.polygon();
        (p.len() >= 3).then(|| Tri::new(p[0], p[1], p[2])).flatten()
    }

    /// A piece: tiny, medium, or a long sliver reaching past the target.
    fn piece(w: u32, h: u32, rng: &mut Rng) -> Option<Tri> {
        let s = SUBPIXEL;
        let (wi, hi) = (i64::from(w) * s, i64::from(h) * s);
        let v0 = SnappedVertex {
            x: rng.below(wi + 2 * s) - s,
            y: rng.below(hi + 2 * s) - s,
            z: rng.next(),
        };
        let reach = match rng.below(3) {
            0 => 3 * s,
            1 => 40 * s,
            _ => 4 * wi,
        };
        let near = |v: SnappedVertex, r: i64, rng: &mut Rng| SnappedVertex {
            x: v.x + rng.below(2 * r) - r,
            y: v.y + rng.below(2 * r) - r,
            z: rng.next(),
        };
        let v1 = near(v0, reach, rng);
        // Slivers: the third vertex a few pixels from the first or second.
        let v2 = near(if rng.below(2) == 0 { v0 } else { v1 }, 5 * s, rng);
        Tri::new(v0, v1, v2)
    }

    /// Counters, touched flags and stats of filling `tri` with `f`.
    fn run<C: Counter + PartialEq + std::fmt::Debug>(
        eye: &DepthTarget,
        tri: &Tri,
        win: &Window,
        rect: Rect,
        zfail: bool,
        delta: C,
        tiles: bool,
    ) -> (Vec<C>, Vec<u8>, StencilStats) {
        let (w, h) = (eye.width(), eye.height());
        let n = (w.div_ceil(8) * h.div_ceil(8)) as usize * 64;
        // Counters start non-zero where it matters: wrapping arithmetic.
        let mut counters = vec![delta; n];
        let mut touched: Vec<u8> = (0..n).map(|i| (i % 3 == 0) as u8).collect();
        let mut st = StencilStats::default();
        let f = Fill {
            counters: &mut counters,
            touched: &mut touched,
            base: 0,
            width: w,
            eye,
            tri,
            rect,
            win,
            zfail,
            delta,
        };
        if tiles {
            fill_piece_dispatch(f, &mut st);
        } else {
            fill_rows(f, &mut st);
        }
        (counters, touched, st)
    }

    /// The fill by tiles, in every build this CPU runs, equals the portable
    /// span walk: counters, touched flags and all four counts, for pieces
    /// tiny to long, windows, depth bounds, clips, both rules and both
    /// counter widths.
    #[test]
    fn tiles_equal_the_span_walk() {
        let (w, h) = (173u32, 101u32);
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let (mut eye, drawn) = eye(w, h, &mut rng);
        let levels: Vec<InstructionSet> = [
            InstructionSet::Portable,
            InstructionSet::Avx2,
            InstructionSet::Avx512,
        ]
        .into_iter()
        .filter(|&l| l <= InstructionSet::detected())
        .collect();
        let (mut processed, mut partial) = (0u64, 0u64);
        for k in 0..3000 {
            // Every seventh piece caps a drawn triangle: depth ties.
            let tri = if k % 7 == 0 {
                cap(&eye, drawn[k % drawn.len()])
            } else {
                piece(w, h, &mut rng)
            };
            let Some(tri) = tri else {
                continue;
            };
            let Some(covered) = pixel_bounds(&tri, Coverage::Standard, w, h) else {
                continue;
            };
            let (x0, y0) = (rng.below(i64::from(w) / 2), rng.below(i64::from(h) / 2));
            let wide = k % 3 == 0;
            // Depth bounds on stored depths, so the inclusive ends matter.
            let mut stored = || loop {
                let d = eye.depth[rng.below(eye.depth.len() as i64) as usize];
                if d != crate::BACKGROUND {
                    break d;
                }
            };
            let (da, db) = (stored(), stored());
            let win = Window {
                x0: if wide { 0 } else { x0 },
                x1: if wide {
                    i64::from(w) - 1
                } else {
                    x0 + rng.below(i64::from(w))
                },
                y0: if wide { 0 } else { y0 },
                y1: if wide {
                    i64::from(h) - 1
                } else {
                    y0 + rng.below(i64::from(h))
                },
                dlo: if k % 2 == 0 {
                    f32::NEG_INFINITY
                } else {
                    da.min(db)
                },
                dhi: if k % 2 == 0 {
                    f32::INFINITY
                } else {
                    da.max(db)
                },
            };
            // A band's rows, and sometimes a boundary tile's clip.
            let rows = Rect {
                y0: rng.below(i64::from(h) / 2),
                y1: i64::from(h) - 1 - rng.below(i64::from(h) / 4),
                ..Rect::ALL
            };
            let clip = if k % 5 == 0 {
                let (cx, cy) = (rng.below(i64::from(w)) & !7, rng.below(i64::from(h)) & !7);
                Rect {
                    x0: cx,
                    x1: cx + 7,
                    y0: cy,
                    y1: cy + 7,
                }
            } else {
                Rect::ALL
            };
            let rect = covered
                .intersect(win.rect())
                .intersect(rows)
                .intersect(clip);
            if rect.is_empty() {
                continue;
            }
            let zfail = k % 4 < 2;
            let level = levels[k % levels.len()];
            eye.set_instruction_set(level);
            if k % 2 == 0 {
                let delta = if k % 8 < 4 { 1u8 } else { u8::MAX };
                let a = run(&eye, &tri, &win, rect, zfail, delta, true);
                let b = run(&eye, &tri, &win, rect, zfail, delta, false);
                assert_eq!(a, b, "piece {k}, {level:?}");
                processed += a.2.pixels_processed;
                partial += u64::from(a.2.stencil_updates < a.2.pixels_processed);
            } else {
                let delta = if k % 8 < 4 { 1i32 } else { -1 };
                let a = run(&eye, &tri, &win, rect, zfail, delta, true);
                let b = run(&eye, &tri, &win, rect, zfail, delta, false);
                assert_eq!(a, b, "piece {k}, {level:?}");
                processed += a.2.pixels_processed;
            }
        }
        // The cases reach real work: fragments, and pieces only partly updating.
        assert!(processed > 20_000, "{processed}");
        assert!(partial > 20, "{partial}");
    }
}
