//! Tile traversal [McCormack & McNamara 2000, "Tiled polygon traversal using
//! half-plane edge functions"]: for each tile under the triangle's pixel bounds,
//! the edge functions at the tile's corner pixel centres reject or wholly
//! accept the tile, hierarchical z rejects it (or, for queries, counts it
//! whole), and only the remaining tiles get per-pixel work.

use crate::coverage::{
    depth_range, edge_offsets, f32_down, f32_up, Coverage, DepthPick, Rect, PLANE_EPS,
};
use crate::edge::Tri;
use crate::hiz::RowSkip;
use crate::layout::{Layout, TileBounds, TileRows, BACKGROUND};
use crate::setup::{Viewport, SUBPIXEL};
use crate::stats::RasterStats;

/// Tile classification against the triangle's edges.
struct TileClass {
    /// Raw edge values at the tile's first pixel centre.
    e00: [i64; 3],
    /// Raw edge values at the four corner pixel centres.
    corners: [[i64; 3]; 4],
    /// Every in-target pixel of the tile is covered.
    full: bool,
}

/// Classifies the in-target pixel rectangle `(x0, x1, y0, y1)`; `None` when no pixel
/// can be covered.
#[inline(always)]
fn classify(tri: &Tri, off: &[i64; 3], r: (u32, u32, u32, u32)) -> Option<TileClass> {
    let (x0, x1, y0, y1) = (r.0 as i64, r.1 as i64, r.2 as i64, r.3 as i64);
    let mut e00 = [0i64; 3];
    let mut corners = [[0i64; 3]; 4];
    let mut full = true;
    for i in 0..3 {
        let e = &tri.e[i];
        let v = e.at_pixel(x0, y0);
        let dx = e.a * SUBPIXEL * (x1 - x0);
        let dy = e.b * SUBPIXEL * (y1 - y0);
        let vmax = v + dx.max(0) + dy.max(0) + off[i];
        if vmax < 0 {
            return None;
        }
        let vmin = v + dx.min(0) + dy.min(0) + off[i];
        full &= vmin >= 0;
        e00[i] = v;
        corners[0][i] = v;
        corners[1][i] = v + dx;
        corners[2][i] = v + dy;
        corners[3][i] = v + dx + dy;
    }
    Some(TileClass { e00, corners, full })
}

/// Tile range `(tx0, tx1, ty0, ty1)` (inclusive) of a pixel range.
#[inline]
fn tiles_of(l: &Layout, p: Rect) -> (u32, u32, u32, u32) {
    let s = l.shift;
    (
        (p.x0 as u32) >> s,
        (p.x1 as u32) >> s,
        (p.y0 as u32) >> s,
        (p.y1 as u32) >> s,
    )
}

/// Largest tile edge, in pixels.
const MAX_TILE: usize = 16;

/// Per-triangle constants of traversal.
struct Prep {
    pb: Rect,
    off: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
    offf: [f64; 3],
    stepf: [f64; 3],
    /// Per lane `k` of a tile row the edge steps `k·step_x` (exact), computed once
    /// per triangle rather than per tile.
    kstep: [[f64; MAX_TILE]; 3],
    /// The edge steps per row, `step_y` in f64 (exact).
    stepyf: [f64; 3],
    /// The triangle is small: use the vertex depth range for every tile.
    single_tile: bool,
    /// The conservative coverages' constants ([`cons_pick`]); `None` for the
    /// standard coverage.
    cons: Option<(f64, bool)>,
    /// Bounds of every depth it produces.
    zlo: f32,
    zhi: f32,
    tiles: (u32, u32, u32, u32),
}

#[inline(always)]
fn prep(tri: &Tri, pb: Rect, cov: Coverage, l: &Layout) -> Prep {
    let off = edge_offsets(tri, cov);
    let step_x = tri.e.map(|e| e.a * SUBPIXEL);
    let step_y = tri.e.map(|e| e.b * SUBPIXEL);
    let tiles = tiles_of(l, pb);
    Prep {
        pb,
        off,
        step_x,
        step_y,
        offf: off.map(|o| o as f64),
        stepf: step_x.map(|o| o as f64),
        kstep: step_x.map(|o| std::array::from_fn(|k| k as f64 * o as f64)),
        stepyf: step_y.map(|o| o as f64),
        // Small triangles (at most two tiles across): the vertex depth range is
        // nearly as tight as the per-tile corner range and much cheaper.
        single_tile: (pb.x1 - pb.x0) < 2 << l.shift && (pb.y1 - pb.y0) < 2 << l.shift,
        cons: (cov != Coverage::Standard).then(|| cons_pick(tri, cov)),
        zlo: f32_down(tri.zlo),
        zhi: f32_up(tri.zhi),
        tiles,
    }
}

/// The first `n` pixels of one row of a tile, as the per-pixel row loops see
/// them.
#[derive(Clone, Copy)]
struct RowSpan {
    /// Raw edge values at the first pixel (exact integers held in f64: all
    /// below 2⁵³).
    e: [f64; 3],
    /// Pixels in the row, at most [`MAX_TILE`].
    n: usize,
    /// Every in-target pixel of the tile is covered ([`TileClass::full`]).
    full: bool,
}

/// Per pixel of a [`RowSpan`]: its depth and whether it is covered.
struct RowSamples {
    zs: [f32; MAX_TILE],
    mask: [bool; MAX_TILE],
}

impl RowSamples {
    #[inline(always)]
    fn new() -> Self {
        RowSamples {
            zs: [0.0; MAX_TILE],
            mask: [false; MAX_TILE],
        }
    }
}

/// Coverage mask and depth of the `n ≤ N` pixels of `row` into `out`.
#[inline(always)]
fn eval_row_n<const N: usize>(tri: &Tri, p: &Prep, row: RowSpan, out: &mut RowSamples) {
    let RowSpan { e, n, full } = row;
    let (zs, mask) = (&mut out.zs, &mut out.mask);
    let (z0, z1, z2, inv) = (tri.z[0], tri.z[1], tri.z[2], tri.inv_area);
    if full {
        // Every pixel of the tile is covered: depth only.
        for k in 0..N {
            let kf = k as f64;
            let a = e[0] + kf * p.stepf[0];
            let b = e[1] + kf * p.stepf[1];
            let c = e[2] + kf * p.stepf[2];
            mask[k] = k < n;
            zs[k] = ((a * z0 + b * z1 + c * z2) * inv) as f32;
        }
        return;
    }
    for k in 0..N {
        let kf = k as f64;
        let a = e[0] + kf * p.stepf[0];
        let b = e[1] + kf * p.stepf[1];
        let c = e[2] + kf * p.stepf[2];
        mask[k] = k < n && (a + p.offf[0]).min(b + p.offf[1]).min(c + p.offf[2]) >= 0.0;
        // Bit-identical to `Tri::depth` (same operations in the same order).
        zs[k] = ((a * z0 + b * z1 + c * z2) * inv) as f32;
    }
}

/// Coverage mask and depth of the pixels of `row` (see [`eval_row_n`]).
#[inline(always)]
fn eval_row(tri: &Tri, cov: Coverage, p: &Prep, row: RowSpan, out: &mut RowSamples) {
    let n = row.n;
    if cov == Coverage::Standard {
        if n <= 4 {
            eval_row_n::<4>(tri, p, row, out)
        } else if n <= 8 {
            eval_row_n::<8>(tri, p, row, out)
        } else {
            eval_row_n::<16>(tri, p, row, out)
        }
    } else if n <= 4 {
        eval_row_cons_n::<4>(tri, cov, p, row, out)
    } else if n <= 8 {
        eval_row_cons_n::<8>(tri, cov, p, row, out)
    } else {
        eval_row_cons_n::<16>(tri, cov, p, row, out)
    }
}

/// [`eval_row_n`] for the conservative coverages: per pixel the nearest or
/// farthest depth over the pixel square, as [`pixel_depth`] computes it —
/// the same f64 operations in the same order on the same (exact integer)
/// edge values, so bit-identical — in fixed-width loops the compiler can
/// vectorize (the per-pixel scalar form cost ~20 ns a pixel).
#[inline(always)]
fn eval_row_cons_n<const N: usize>(
    tri: &Tri,
    cov: Coverage,
    p: &Prep,
    row: RowSpan,
    out: &mut RowSamples,
) {
    let RowSpan { e, n, full } = row;
    let (zs, mask) = (&mut out.zs, &mut out.mask);
    // Set by `prep` for every conservative coverage.
    let (half, nearest) = p.cons.unwrap_or_else(|| cons_pick(tri, cov));
    for k in 0..N {
        let kf = k as f64;
        let a = e[0] + kf * p.stepf[0];
        let b = e[1] + kf * p.stepf[1];
        let c = e[2] + kf * p.stepf[2];
        mask[k] = k < n && (full || (a + p.offf[0]).min(b + p.offf[1]).min(c + p.offf[2]) >= 0.0);
        zs[k] = cons_depth(tri, half, nearest, a, b, c);
    }
}

/// The conservative coverages' per-triangle constants: half the depth change
/// over a pixel square (with the plane allowance), and whether the nearest
/// depth is picked.
#[inline(always)]
fn cons_pick(tri: &Tri, cov: Coverage) -> (f64, bool) {
    let half = 0.5 * (tri.dzdx.abs() + tri.dzdy.abs()) * (1.0 + PLANE_EPS);
    let nearest = matches!(
        cov,
        Coverage::Outer(DepthPick::Nearest) | Coverage::Inner(DepthPick::Nearest)
    );
    (half, nearest)
}

/// The nearest (or farthest) depth over the pixel square whose centre has the
/// raw edge values `(a, b, c)`, as [`pixel_depth`] computes it: the one
/// expression every conservative row loop uses.
#[inline(always)]
fn cons_depth(tri: &Tri, half: f64, nearest: bool, a: f64, b: f64, c: f64) -> f32 {
    let (z0, z1, z2, inv) = (tri.z[0], tri.z[1], tri.z[2], tri.inv_area);
    let zc = (a * z0 + b * z1 + c * z2) * inv;
    let slack = PLANE_EPS * ((a.abs() * z0 + b.abs() * z1 + c.abs() * z2) * inv);
    if nearest {
        f32_up((zc + half + slack).min(tri.zhi))
    } else {
        f32_down((zc - half - slack).max(tri.zlo))
    }
}

/// Per-lane edge steps `k·step` of a tile row ([`Prep::kstep`]), and whether lane
/// `k` of a row of width `T` lies in `lanes.0..=lanes.1`.
#[inline(always)]
fn lane_setup<const T: usize>(
    p: &Prep,
    lanes: (usize, usize),
) -> (&[[f64; MAX_TILE]; 3], [u32; T]) {
    // One bit per lane, spread by shifts (no per-lane compare-and-convert).
    let bits = ((2u32 << lanes.1) - 1) & !((1u32 << lanes.0) - 1);
    (&p.kstep, std::array::from_fn(|k| (bits >> k) & 1))
}

/// Whole rows of one tile for the fixed-width row loops ([`rows_std`],
/// [`rows_query`]).
#[derive(Clone, Copy)]
struct TileSpan {
    /// Raw edge values at lane 0 of the first row.
    e: [f64; 3],
    /// The lanes (pixel columns of the tile) inside the triangle's pixel
    /// bounds, `lanes.0..=lanes.1`.
    lanes: (usize, usize),
    /// Every in-target pixel of the tile is covered ([`TileClass::full`]).
    full: bool,
}

/// Accumulated results of [`rows_std`].
#[derive(Default)]
struct RowAcc {
    tested: u32,
    written: u32,
    bg_written: u32,
    new_min: f32,
    new_max: f32,
    hit_min: bool,
}

/// GREATER writes (no id target) of the whole tile rows of width `T` in
/// `depth` over `span`, at the standard depth or, with `p.cons`, at the
/// conservative coverages' ([`cons_depth`]): fixed-width, branch-free loops the
/// compiler vectorizes. `no_test`: every covered pixel wins; `zmin`: the
/// tile's minimum depth before the draw (overwriting it asks for a rescan).
/// The arithmetic is that of [`eval_row_n`], so results are bit-identical.
#[inline(always)]
fn rows_std<const T: usize>(
    tri: &Tri,
    p: &Prep,
    span: TileSpan,
    no_test: bool,
    depth: &mut [f32],
    zmin: f32,
    acc: &mut RowAcc,
) {
    let TileSpan { mut e, lanes, full } = span;
    let stepy = p.stepyf;
    let (z0, z1, z2, inv) = (tri.z[0], tri.z[1], tri.z[2], tri.inv_area);
    let (kstep, eligible) = lane_setup::<T>(p, lanes);
    let fullm = full as u32;
    let no_testm = no_test as u32;
    // Per-lane accumulators over all rows, reduced once at the end. Plain
    // comparisons and selects (no NaN-aware min/max, no short-circuit) so the loop
    // vectorizes; masks are 0/1 integers.
    let mut tested = [0u32; T];
    let mut written = [0u32; T];
    let mut bgw = [0u32; T];
    let mut hit = [0u32; T];
    let mut vmax = [acc.new_max; T];
    let mut vmin = [acc.new_min; T];
    for row in depth.chunks_exact_mut(T) {
        let row: &mut [f32; T] = row.try_into().expect("tile row");
        // The new row is built apart (a bitwise merge, not a select) and stored
        // whole: `row[k] = if win { z } else { d }` compiles to a masked store
        // (vmaskmovps), slow on AMD and never forwarded to the next triangle's
        // loads of the same row.
        let mut out = [0f32; T];
        for k in 0..T {
            let a = e[0] + kstep[0][k];
            let b = e[1] + kstep[1][k];
            let c = e[2] + kstep[2][k];
            let inside = ((a + p.offf[0] >= 0.0) as u32)
                & ((b + p.offf[1] >= 0.0) as u32)
                & ((c + p.offf[2] >= 0.0) as u32);
            let m = eligible[k] & (fullm | inside);
            let z = match p.cons {
                None => ((a * z0 + b * z1 + c * z2) * inv) as f32,
                Some((half, nearest)) => cons_depth(tri, half, nearest, a, b, c),
            };
            let d = row[k];
            let win = m & (no_testm | ((z > d) as u32));
            tested[k] += m;
            written[k] += win;
            // Bitwise merge (win ? z : d).
            let (zb, db) = (z.to_bits(), d.to_bits());
            out[k] = f32::from_bits(db ^ ((db ^ zb) & 0u32.wrapping_sub(win)));
            vmax[k] = if win != 0 && z > vmax[k] { z } else { vmax[k] };
            let from_bg = win & ((d == BACKGROUND) as u32);
            bgw[k] += from_bg;
            vmin[k] = if from_bg != 0 && z < vmin[k] {
                z
            } else {
                vmin[k]
            };
            hit[k] |= win & ((d == zmin) as u32);
        }
        *row = out;
        for i in 0..3 {
            e[i] += stepy[i];
        }
    }
    for k in 0..T {
        acc.tested += tested[k];
        acc.written += written[k];
        acc.bg_written += bgw[k];
        acc.hit_min |= hit[k] != 0;
        if vmax[k] > acc.new_max {
            acc.new_max = vmax[k];
        }
        if vmin[k] < acc.new_min {
            acc.new_min = vmin[k];
        }
    }
}

/// Standard-coverage writes over whole tile rows, every lane covered and
/// winning (a full-width tile nearer than all it holds): the depths of
/// [`rows_std`], bit for bit, without tests; returns their minimum and maximum.
/// `e` holds the raw edge values at the tile's first pixel.
#[inline(always)]
fn rows_fill<const T: usize>(
    tri: &Tri,
    p: &Prep,
    mut e: [f64; 3],
    depth: &mut [f32],
) -> (f32, f32) {
    let stepy = p.stepyf;
    let (z0, z1, z2, inv) = (tri.z[0], tri.z[1], tri.z[2], tri.inv_area);
    let (kstep, _) = lane_setup::<T>(p, (0, T - 1));
    let mut vmin = [f32::INFINITY; T];
    let mut vmax = [f32::NEG_INFINITY; T];
    for row in depth.chunks_exact_mut(T) {
        let row: &mut [f32; T] = row.try_into().expect("tile row");
        let mut out = [0f32; T];
        for k in 0..T {
            let a = e[0] + kstep[0][k];
            let b = e[1] + kstep[1][k];
            let c = e[2] + kstep[2][k];
            let z = ((a * z0 + b * z1 + c * z2) * inv) as f32;
            out[k] = z;
            // Plain selects, so the loop vectorizes.
            vmin[k] = if z < vmin[k] { z } else { vmin[k] };
            vmax[k] = if z > vmax[k] { z } else { vmax[k] };
        }
        *row = out;
        for i in 0..3 {
            e[i] += stepy[i];
        }
    }
    let zmin = vmin.iter().fold(f32::INFINITY, |m, &v| m.min(v));
    let zmax = vmax.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
    (zmin, zmax)
}

/// Standard-coverage GEQUAL sample count over the whole tile rows in `depth`
/// (see [`rows_std`]), restricted by `receivers` (same rows) when given; adds
/// the samples tested to `tested`.
#[inline(always)]
fn rows_query<const T: usize>(
    tri: &Tri,
    p: &Prep,
    span: TileSpan,
    depth: &[f32],
    receivers: Option<&[f32]>,
    tested: &mut u64,
) -> u64 {
    let TileSpan { mut e, lanes, full } = span;
    let stepy = p.stepyf;
    let (z0, z1, z2, inv) = (tri.z[0], tri.z[1], tri.z[2], tri.inv_area);
    let (kstep, eligible) = lane_setup::<T>(p, lanes);
    let mut pass = 0u32;
    let mut te = 0u32;
    for (r, row) in depth.chunks_exact(T).enumerate() {
        let row: &[f32; T] = row.try_into().expect("tile row");
        let rec: [f32; T] = match receivers {
            Some(rv) => rv[r * T..r * T + T].try_into().expect("tile row"),
            None => [f32::NEG_INFINITY; T],
        };
        for k in 0..T {
            let a = e[0] + kstep[0][k];
            let b = e[1] + kstep[1][k];
            let c = e[2] + kstep[2][k];
            let inside = ((a + p.offf[0] >= 0.0) as u32)
                & ((b + p.offf[1] >= 0.0) as u32)
                & ((c + p.offf[2] >= 0.0) as u32);
            let m = eligible[k] & ((full as u32) | inside);
            let z = ((a * z0 + b * z1 + c * z2) * inv) as f32;
            te += m;
            pass += m & ((z >= row[k]) as u32) & ((z >= rec[k]) as u32);
        }
        for i in 0..3 {
            e[i] += stepy[i];
        }
    }
    *tested += u64::from(te);
    u64::from(pass)
}

/// Rasterizes `tri`, whose pixel bounds ([`pixel_bounds`]) are `pb`, into `band`
/// with the GREATER test (ties broken by smaller `id` when the band has an id
/// buffer).
#[inline(always)]
pub(crate) fn draw_tri(
    band: &mut TileRows,
    tri: &Tri,
    pb: Rect,
    cov: Coverage,
    id: u64,
    skip: &RowSkip,
    st: &mut RasterStats,
) {
    // The common case (standard coverage, no id target) gets a copy of its own
    // with the other paths compiled out: a lean tile loop spills less.
    if cov == Coverage::Standard && band.ids.is_none() {
        draw_tri_as::<true>(band, tri, pb, Coverage::Standard, id, skip, st)
    } else {
        draw_tri_as::<false>(band, tri, pb, cov, id, skip, st)
    }
}

/// [`draw_tri`]; `FAST`: the coverage is standard and there is no id target.
#[inline(always)]
fn draw_tri_as<const FAST: bool>(
    band: &mut TileRows,
    tri: &Tri,
    pb: Rect,
    cov: Coverage,
    id: u64,
    skip: &RowSkip,
    st: &mut RasterStats,
) {
    let l = band.layout;
    let p = prep(tri, pb, cov, &l);
    let (tx0, tx1, ty0, ty1) = p.tiles;
    let base_tile = band.tile_base();
    let mut samples = RowSamples::new();
    for ty in ty0.max(band.ty0)..ty1.min(band.ty1 - 1) + 1 {
        if skip.hides(ty) {
            continue;
        }
        for tx in tx0..tx1 + 1 {
            st.tiles_touched += 1;
            let t = l.tile_index(tx, ty) - base_tile;
            let tb: TileBounds = band.tiles[t];
            if tb.background == 0 && p.zhi < tb.zmin {
                st.tiles_rejected_hiz += 1;
                continue;
            }
            let rect = l.tile_rect(tx, ty);
            let Some(c) = classify(tri, &p.off, rect) else {
                st.tiles_rejected_edges += 1;
                continue;
            };
            let (lo, hi) = if p.single_tile || (tb.background > 0 && !c.full) {
                (p.zlo, p.zhi)
            } else {
                depth_range(tri, cov, &c.corners)
            };
            if tb.background == 0 && hi < tb.zmin {
                st.tiles_rejected_hiz += 1;
                continue;
            }
            if c.full {
                st.tiles_accepted_whole += 1;
            }
            // Pixels of this tile inside the triangle's pixel bounds.
            let px0 = rect.0.max(p.pb.x0 as u32);
            let px1 = rect.1.min(p.pb.x1 as u32);
            let py0 = rect.2.max(p.pb.y0 as u32);
            let py1 = rect.3.min(p.pb.y1 as u32);
            let n = (px1 - px0 + 1) as usize;
            let no_test = c.full && lo > tb.zmax;
            let tile_base = t << (2 * l.shift);
            let mut written = 0u64;
            let mut tested = 0u64;
            // Incremental tile bounds: writes only raise depths, so zmin changes only
            // when background is covered (new minimum candidates) or a pixel holding
            // the old minimum is overwritten (then the tile is rescanned).
            let mut bg_written = 0u32;
            let mut new_min = f32::INFINITY;
            let mut new_max = tb.zmax;
            let mut rescan = false;
            let mut erow: [f64; 3] = std::array::from_fn(|i| {
                (c.e00[i]
                    + p.step_x[i] * (px0 - rect.0) as i64
                    + p.step_y[i] * (py0 - rect.2) as i64) as f64
            });
            let stepyf = p.stepyf;
            if no_test && FAST && (px0, px1, py0, py1) == rect && px1 - px0 + 1 == 1 << l.shift {
                // Every in-target pixel is covered and nearer than all the tile
                // holds: write the plane; the tile's bounds become those of the new
                // depths (what the incremental update or a rescan would give).
                let e0: [f64; 3] = std::array::from_fn(|i| c.e00[i] as f64);
                let tw = 1usize << l.shift;
                let depth = &mut band.depth[tile_base..tile_base + (py1 - py0 + 1) as usize * tw];
                let (zmin, zmax) = match l.shift {
                    2 => rows_fill::<4>(tri, &p, e0, depth),
                    3 => rows_fill::<8>(tri, &p, e0, depth),
                    _ => rows_fill::<16>(tri, &p, e0, depth),
                };
                let n = u64::from((px1 - px0 + 1) * (py1 - py0 + 1));
                st.pixels_tested += n;
                st.pixels_written += n;
                band.tiles[t] = TileBounds {
                    zmin,
                    zmax,
                    background: 0,
                };
                continue;
            }
            if FAST || band.ids.is_none() {
                // Whole tile rows, fixed width (any coverage without ids: the
                // conservative depth per pixel is `eval_row_cons_n`'s).
                let mut acc = RowAcc {
                    new_min: f32::INFINITY,
                    new_max: tb.zmax,
                    ..RowAcc::default()
                };
                let e0: [f64; 3] = std::array::from_fn(|i| {
                    (c.e00[i] + p.step_y[i] * (py0 - rect.2) as i64) as f64
                });
                let span = TileSpan {
                    e: e0,
                    lanes: ((px0 - rect.0) as usize, (px1 - rect.0) as usize),
                    full: c.full,
                };
                let tw = 1usize << l.shift;
                let start = tile_base + (py0 - rect.2) as usize * tw;
                let depth = &mut band.depth[start..start + (py1 - py0 + 1) as usize * tw];
                match l.shift {
                    2 => rows_std::<4>(tri, &p, span, no_test, depth, tb.zmin, &mut acc),
                    3 => rows_std::<8>(tri, &p, span, no_test, depth, tb.zmin, &mut acc),
                    _ => rows_std::<16>(tri, &p, span, no_test, depth, tb.zmin, &mut acc),
                }
                tested = u64::from(acc.tested);
                written = u64::from(acc.written);
                bg_written = acc.bg_written;
                new_min = acc.new_min;
                new_max = acc.new_max;
                rescan = acc.hit_min;
            } else if let Some(all_ids) = band.ids.as_deref_mut() {
                // An id target: per row, ties go to the smaller id.
                for y in py0..py1 + 1 {
                    let span = RowSpan {
                        e: erow,
                        n,
                        full: c.full,
                    };
                    eval_row(tri, cov, &p, span, &mut samples);
                    let (zs, mask) = (&samples.zs, &samples.mask);
                    let row = tile_base + (((y - rect.2) << l.shift) + (px0 - rect.0)) as usize;
                    let depth = &mut band.depth[row..row + n];
                    let ids = &mut all_ids[row..row + n];
                    for k in 0..n {
                        let (z, d) = (zs[k], depth[k]);
                        let m = mask[k];
                        tested += u64::from(m);
                        let win = m && (no_test || z > d || (z == d && id < ids[k]));
                        if win {
                            depth[k] = z;
                            ids[k] = id;
                            written += 1;
                            new_max = new_max.max(z);
                            if d == BACKGROUND {
                                bg_written += 1;
                                new_min = new_min.min(z);
                            } else if d == tb.zmin {
                                rescan = true;
                            }
                        }
                    }
                    for i in 0..3 {
                        erow[i] += stepyf[i];
                    }
                }
            }
            st.pixels_tested += tested;
            st.pixels_written += written;
            if rescan {
                band.refresh_tile(tx, ty);
            } else if written > 0 {
                band.tiles[t] = TileBounds {
                    zmin: tb.zmin.min(new_min),
                    zmax: new_max,
                    background: tb.background - bg_written,
                };
            }
        }
    }
}

/// Read-only view of a target for queries.
pub(crate) struct QueryView<'a> {
    /// The target's viewport (setup of the query geometry).
    pub vp: &'a Viewport,
    pub layout: Layout,
    pub depth: &'a [f32],
    pub tiles: &'a [TileBounds],
    /// Farthest receiver depth per pixel (same layout), +∞ where unmarked.
    pub receivers: Option<&'a [f32]>,
    /// Per tile the farthest receiver depth of its pixels, +∞ where none.
    pub receiver_tiles: Option<&'a [f32]>,
}

/// Any-samples shortcut for standard coverage: whether the pixel under the
/// triangle's centroid (in pixel bounds `pb`) is covered and passes. The edge
/// values and depth are those traversal computes there (exact integers;
/// [`Tri::depth`], which the row loops match bit for bit), so a pass here is a
/// pass traversal would find; a miss decides nothing.
#[inline(always)]
pub(crate) fn probe_passes(v: &QueryView, tri: &Tri, pb: Rect, st: &mut RasterStats) -> bool {
    let sum = |f: fn(&crate::edge::Edge) -> i64| tri.e.iter().map(f).sum::<i64>();
    let x = sum(|e| e.ox).div_euclid(3 * SUBPIXEL);
    let y = sum(|e| e.oy).div_euclid(3 * SUBPIXEL);
    if x < pb.x0 || x > pb.x1 || y < pb.y0 || y > pb.y1 {
        return false;
    }
    let off = edge_offsets(tri, Coverage::Standard);
    let e = tri.e.map(|e| e.at_pixel(x, y));
    if (0..3).any(|i| e[i] + off[i] < 0) {
        return false;
    }
    st.pixels_tested += 1;
    let z = tri.depth(e[0], e[1], e[2]) as f32;
    // In the target, as `pb` is.
    let k = v.layout.pixel_index(x as u32, y as u32);
    z >= v.depth[k] && v.receivers.is_none_or(|r| z >= r[k])
}

/// Counts the covered samples of `tri` passing GEQUAL (and the receiver restriction),
/// stopping once the count reaches `limit` (then it may exceed it: a tile's or a
/// row's passes are added whole). `pb` are the triangle's pixel bounds
/// ([`pixel_bounds`]).
#[inline(always)]
pub(crate) fn query_tri(
    v: &QueryView,
    tri: &Tri,
    pb: Rect,
    cov: Coverage,
    limit: u64,
    st: &mut RasterStats,
) -> u64 {
    // Standard coverage gets a copy of its own (see `draw_tri`).
    if cov == Coverage::Standard {
        query_tri_as::<true>(v, tri, pb, Coverage::Standard, limit, st)
    } else {
        query_tri_as::<false>(v, tri, pb, cov, limit, st)
    }
}

/// [`query_tri`]; `STANDARD`: the coverage is standard.
#[inline(always)]
fn query_tri_as<const STANDARD: bool>(
    v: &QueryView,
    tri: &Tri,
    pb: Rect,
    cov: Coverage,
    limit: u64,
    st: &mut RasterStats,
) -> u64 {
    let l = v.layout;
    let p = prep(tri, pb, cov, &l);
    let (tx0, tx1, ty0, ty1) = p.tiles;
    let mut count = 0u64;
    let mut samples = RowSamples::new();
    for ty in ty0..ty1 + 1 {
        for tx in tx0..tx1 + 1 {
            st.tiles_touched += 1;
            let t = l.tile_index(tx, ty);
            let tb = v.tiles[t];
            // A sample passes only at or in front of the stored depth and,
            // with receivers, of the tile's farthest receiver.
            let floor = match v.receiver_tiles {
                Some(r) => tb.zmin_all().max(r[t]),
                None => tb.zmin_all(),
            };
            if p.zhi < floor {
                st.tiles_rejected_hiz += 1;
                continue;
            }
            let rect = l.tile_rect(tx, ty);
            let Some(c) = classify(tri, &p.off, rect) else {
                st.tiles_rejected_edges += 1;
                continue;
            };
            let (lo, hi) = if p.single_tile {
                (p.zlo, p.zhi)
            } else {
                depth_range(tri, cov, &c.corners)
            };
            if hi < floor {
                st.tiles_rejected_hiz += 1;
                continue;
            }
            if c.full {
                st.tiles_accepted_whole += 1;
                if v.receivers.is_none() && lo >= tb.zmax {
                    st.tiles_query_accepted_whole += 1;
                    count += ((rect.1 - rect.0 + 1) * (rect.3 - rect.2 + 1)) as u64;
                    if count >= limit {
                        return count;
                    }
                    continue;
                }
            }
            let px0 = rect.0.max(p.pb.x0 as u32);
            let px1 = rect.1.min(p.pb.x1 as u32);
            let py0 = rect.2.max(p.pb.y0 as u32);
            let py1 = rect.3.min(p.pb.y1 as u32);
            let n = (px1 - px0 + 1) as usize;
            let tile_base = t << (2 * l.shift);
            let mut erow: [f64; 3] = std::array::from_fn(|i| {
                (c.e00[i]
                    + p.step_x[i] * (px0 - rect.0) as i64
                    + p.step_y[i] * (py0 - rect.2) as i64) as f64
            });
            let stepyf = p.stepyf;
            if STANDARD {
                let e0: [f64; 3] = std::array::from_fn(|i| {
                    (c.e00[i] + p.step_y[i] * (py0 - rect.2) as i64) as f64
                });
                let span = TileSpan {
                    e: e0,
                    lanes: ((px0 - rect.0) as usize, (px1 - rect.0) as usize),
                    full: c.full,
                };
                let tw = 1usize << l.shift;
                let start = tile_base + (py0 - rect.2) as usize * tw;
                let end = start + (py1 - py0 + 1) as usize * tw;
                let depth = &v.depth[start..end];
                let rec = v.receivers.map(|r| &r[start..end]);
                let mut tested = 0u64;
                let pass = match l.shift {
                    2 => rows_query::<4>(tri, &p, span, depth, rec, &mut tested),
                    3 => rows_query::<8>(tri, &p, span, depth, rec, &mut tested),
                    _ => rows_query::<16>(tri, &p, span, depth, rec, &mut tested),
                };
                st.pixels_tested += tested;
                count += pass;
                if count >= limit {
                    return count;
                }
                continue;
            }
            for y in py0..py1 + 1 {
                let span = RowSpan {
                    e: erow,
                    n,
                    full: c.full,
                };
                eval_row(tri, cov, &p, span, &mut samples);
                let (zs, mask) = (&samples.zs, &samples.mask);
                let row = tile_base + (((y - rect.2) << l.shift) + (px0 - rect.0)) as usize;
                let depth = &v.depth[row..row + n];
                let mut pass = 0u64;
                let mut tested = 0u64;
                match v.receivers {
                    None => {
                        for k in 0..n {
                            tested += u64::from(mask[k]);
                            pass += u64::from(mask[k] && zs[k] >= depth[k]);
                        }
                    }
                    Some(r) => {
                        let r = &r[row..row + n];
                        for k in 0..n {
                            tested += u64::from(mask[k]);
                            pass += u64::from(mask[k] && zs[k] >= depth[k] && zs[k] >= r[k]);
                        }
                    }
                }
                st.pixels_tested += tested;
                count += pass;
                if count >= limit {
                    return count;
                }
                for i in 0..3 {
                    erow[i] += stepyf[i];
                }
            }
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coverage::pixel_depth;

    /// Conservative draws through the fixed-width rows (no id target) write
    /// the depths and tile bounds of the per-row path (an id target), bit for
    /// bit, on every coverage and tile size.
    #[test]
    fn conservative_rows_equal_the_row_path() {
        use crate::{DrawItem, TileSize};
        use glam::{Mat4, Vec4};
        let mut seed = 11u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        for tile in [TileSize::T4, TileSize::T8, TileSize::T16] {
            for cov in [
                Coverage::Inner(DepthPick::Farthest),
                Coverage::Outer(DepthPick::Nearest),
                Coverage::Inner(DepthPick::Nearest),
                Coverage::Outer(DepthPick::Farthest),
            ] {
                let (w, h) = (91u32, 67u32);
                let mut rows = crate::DepthTarget::new(w, h, tile, false).unwrap();
                let mut per_row = crate::DepthTarget::new(w, h, tile, true).unwrap();
                for k in 0..300u32 {
                    // Small to large triangles, in front of each other.
                    let s = [0.05f32, 0.4, 2.0][k as usize % 3];
                    let c = (rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0);
                    let v: Vec<Vec4> = (0..3)
                        .map(|_| {
                            let p = (c.0 + s * (rnd() - 0.5), c.1 + s * (rnd() - 0.5));
                            Vec4::new(p.0, p.1, 0.05 + 0.9 * rnd(), 1.0)
                        })
                        .collect();
                    let item = DrawItem {
                        clip_from_local: Mat4::IDENTITY,
                        positions: &v,
                        triangles: &[[0, 1, 2], [0, 2, 1]],
                        object: k,
                        cull: crate::CullMode::None,
                    };
                    rows.draw(&item, cov).unwrap();
                    per_row.draw(&item, cov).unwrap();
                }
                let bits = |t: &crate::DepthTarget| {
                    t.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>()
                };
                assert_eq!(bits(&rows), bits(&per_row), "{tile:?} {cov:?}");
                assert_eq!(rows.tiles, per_row.tiles, "{tile:?} {cov:?}");
                let written = rows
                    .depth
                    .iter()
                    .filter(|&&d| d != crate::BACKGROUND)
                    .count();
                assert!(written > (w * h / 2) as usize, "{written}");
            }
        }
    }

    /// Conservative rows give `pixel_depth` bit for bit on every covered pixel.
    #[test]
    fn conservative_rows_match_pixel_depth() {
        use crate::setup::{SnappedVertex, SUBPIXEL};
        let l = crate::depth_target::DepthTarget::new(64, 64, crate::TileSize::T8, false)
            .unwrap()
            .layout;
        let mut seed = 3u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut covered = 0;
        for _ in 0..300 {
            let v = [0, 1, 2].map(|_| SnappedVertex {
                x: (rnd() * 64.0 * SUBPIXEL as f64) as i64,
                y: (rnd() * 64.0 * SUBPIXEL as f64) as i64,
                z: rnd(),
            });
            let Some(tri) = Tri::new(v[0], v[1], v[2]) else {
                continue;
            };
            let pb = Rect {
                x0: tri.xmin,
                x1: tri.xmax,
                y0: tri.ymin,
                y1: tri.ymax,
            };
            for cov in [
                Coverage::Inner(DepthPick::Farthest),
                Coverage::Outer(DepthPick::Nearest),
                Coverage::Inner(DepthPick::Nearest),
                Coverage::Outer(DepthPick::Farthest),
            ] {
                let p = prep(&tri, pb, cov, &l);
                for y in 0..64i64 {
                    let e = tri.e.map(|ed| ed.at_pixel(0, y));
                    let mut samples = RowSamples::new();
                    let span = RowSpan {
                        e: e.map(|v| v as f64),
                        n: 16,
                        full: false,
                    };
                    eval_row(&tri, cov, &p, span, &mut samples);
                    let (zs, mask) = (samples.zs, samples.mask);
                    for k in 0..16 {
                        let ek = [0, 1, 2].map(|i| e[i] + k as i64 * p.step_x[i]);
                        let inside = (0..3).all(|i| ek[i] + p.off[i] >= 0);
                        assert_eq!(mask[k], inside);
                        if inside {
                            covered += 1;
                            assert_eq!(zs[k].to_bits(), pixel_depth(&tri, cov, ek).to_bits());
                        }
                    }
                }
            }
        }
        assert!(covered > 1000, "{covered}");
    }
}
