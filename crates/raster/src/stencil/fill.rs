//! Filling pieces into a band of counters: by 8×8 tiles ([`fill_tiles`],
//! when the eye target's tiles are 8×8) or by the per-row span walk (other
//! tile sizes), each with the strict depth test against the eye target and the
//! counting rule, built for the eye target's instruction-set level; and the
//! one runner that fills bands in parallel.

use super::counters::{tiled_index, Counter, CountersMut, StencilStats};
use super::pieces::{Fill, Piece, Window};
use super::run::{run_masks, RunPlane};
use super::span::{band_extent, SpanWalker};
use super::tile_fill::fill_tiles;
use crate::coverage::{edge_offsets, pixel_bounds, Coverage, Rect};
use crate::depth_target::DepthTarget;
use crate::setup::SUBPIXEL;

/// The rows `y0..=y1` of a [`StencilTarget`]: whole tile rows, whose counters
/// and touched flags are the contiguous slices starting at tiled index `base`.
pub(crate) struct CounterRows<'a> {
    pub counters: CountersMut<'a>,
    pub touched: &'a mut [u8],
    pub width: u32,
    pub height: u32,
    pub y0: i64,
    pub y1: i64,
    pub base: usize,
}

/// Tiles rows per band of [`StencilTarget::draw_volumes`] (64 pixel rows: small
/// enough that the bands balance across threads, large enough that a band's
/// share of a volume triangle is more than a few rows).
pub(crate) const BAND_TILE_ROWS: usize = 8;

impl CounterRows<'_> {
    /// Increments (or decrements, `!piece.increment`) every covered
    /// non-background pixel of `piece` inside `win` whose fragment passes (zpass)
    /// or fails (`piece.zfail`) the strict depth test. Each row walks only its
    /// covered span ([`crate::span`]).
    pub(crate) fn fill_piece(
        &mut self,
        eye: &DepthTarget,
        piece: &Piece,
        win: &Window,
        st: &mut StencilStats,
    ) {
        self.fill_piece_within(eye, piece, win, Rect::ALL, st);
    }

    /// [`CounterRows::fill_piece`] restricted to the pixels of `clip` (the
    /// hierarchical stencil's boundary tiles).
    pub(crate) fn fill_piece_within(
        &mut self,
        eye: &DepthTarget,
        piece: &Piece,
        win: &Window,
        clip: Rect,
        st: &mut StencilStats,
    ) {
        let Piece {
            ref tri,
            zfail,
            increment,
            ..
        } = *piece;
        let (w, h) = (self.width, self.height);
        let Some(covered) = pixel_bounds(tri, Coverage::Standard, w, h) else {
            return;
        };
        let rows = Rect {
            y0: self.y0,
            y1: self.y1,
            ..Rect::ALL
        };
        let rect = covered
            .intersect(win.rect())
            .intersect(rows)
            .intersect(clip);
        if rect.is_empty() {
            return;
        }
        let touched = &mut *self.touched;
        let base = self.base;
        macro_rules! fill {
            ($c:expr, $delta:expr) => {
                fill_piece_dispatch(
                    Fill {
                        counters: $c,
                        touched,
                        base,
                        width: w,
                        eye,
                        tri,
                        rect,
                        win,
                        zfail,
                        delta: $delta,
                    },
                    st,
                )
            };
        }
        match &mut self.counters {
            CountersMut::Eight(c) => fill!(c, if increment { 1 } else { u8::MAX }),
            CountersMut::Wide(c) => fill!(c, if increment { 1 } else { -1 }),
        }
    }
}

/// The band runner of both stencil passes: `for_each_band!(f, s₀ => n₀, s₁ =>
/// n₁, …)` calls `f((k, (((c₀, c₁), c₂), …)))` for every band `k`, where `cᵢ`
/// is the `k`-th chunk of `nᵢ` entries of slice `sᵢ` (the slices hold the same
/// number of chunks), in parallel with the `parallel` feature and in band order
/// without it. Bands own disjoint rows, so the result is the same either way.
/// Each band is its own task (`with_max_len(1)`): bands differ in work by
/// far more than rayon's default halving balances.
macro_rules! for_each_band {
    ($f:expr, $s0:expr => $n0:expr $(, $s:expr => $n:expr)* $(,)?) => {{
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            $s0.par_chunks_mut($n0)$(.zip($s.par_chunks_mut($n)))*.enumerate().with_max_len(1).for_each($f);
        }
        #[cfg(not(feature = "parallel"))]
        {
            $s0.chunks_mut($n0)$(.zip($s.chunks_mut($n)))*.enumerate().for_each($f);
        }
    }};
}
pub(crate) use for_each_band;

/// The fill of one piece: by 8×8 tiles ([`fill_tiles`]) when the eye target's
/// tiles are the counters' 8×8 tiles, else by row spans ([`fill_rows`]); each
/// in the build of the target's instruction-set level (the same results).
#[inline(always)]
pub(super) fn fill_piece_dispatch<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    let tiles = f.eye.layout.shift == 3;
    #[cfg(target_arch = "x86_64")]
    match f.eye.isa.capped() {
        crate::InstructionSet::Avx512 if tiles => {
            // SAFETY: `capped` is at most the detected level: this CPU has
            // AVX-512 F/VL/BW/DQ and AVX2.
            unsafe { fill_tiles_avx512(f, st) };
            return;
        }
        crate::InstructionSet::Avx512 | crate::InstructionSet::Avx2 => {
            // SAFETY: as above, this CPU has AVX2.
            unsafe {
                if tiles {
                    fill_tiles_avx2(f, st)
                } else {
                    fill_rows_avx2(f, st)
                }
            };
            return;
        }
        crate::InstructionSet::Portable => {}
    }
    if tiles {
        fill_tiles(f, st);
    } else {
        fill_rows(f, st);
    }
}

/// [`fill_rows`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_rows_avx2<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    fill_rows(f, st);
}

/// [`fill_tiles`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_tiles_avx2<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    fill_tiles(f, st);
}

/// [`fill_tiles`] compiled with AVX-512 enabled: a tile row of f64 lanes is
/// one register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2")]
unsafe fn fill_tiles_avx512<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    fill_tiles(f, st);
}

/// The per-pixel loop of [`CounterRows::fill_piece`], monomorphized per counter type:
/// adds `delta` (wrapping) to each covered pixel of `rect` that is not background,
/// lies within the depth window and passes (zpass) or fails (zfail) the strict test.
///
/// Each row's covered span is walked in runs that stay inside one tile row, where
/// the tiled depth buffer is contiguous, with a branch-free body. Edge values are
/// carried as f64: they are integers below 2⁵³ (see `edge.rs`), so stepping them
/// in f64 is exact and the depth `Σ E_i·z_i / area` is bit-identical to the eye
/// pass's.
#[inline(always)]
pub(super) fn fill_rows<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
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
    let avx2 = eye.isa >= crate::InstructionSet::Avx2;
    let layout = eye.layout;
    let depth = &eye.depth;
    let off = edge_offsets(tri, Coverage::Standard);
    let step = tri.e.map(|e| (e.a * SUBPIXEL) as f64);
    let run = (1i64 << layout.shift).min(8);
    let (z, inv) = (tri.z, tri.inv_area);
    let (dlo, dhi) = (win.dlo, win.dhi);
    let zero = C::default();
    let (mut processed, mut updates, mut first) = (0u64, 0u64, 0u64);
    let mut scanned = 0u64;
    let walker = SpanWalker::new(tri, &off, rect.x0, rect.x1, rect.y0);
    let tile = 1i64 << layout.shift;
    let active = |tb: &crate::layout::TileBounds| win.reaches(tb);
    let mut band_lo = rect.x0;
    let mut band_hi = rect.x1;
    for y in rect.y0..=rect.y1 {
        if y == rect.y0 || y & (tile - 1) == 0 {
            // A new band of tile rows: the columns the triangle can reach there,
            // narrowed to the first and last tile with written depth inside
            // the window; the band is skipped when there is none.
            let yb = rect.y1.min(y | (tile - 1));
            let (ty, tiles_x) = ((y >> layout.shift) as u32, layout.tiles_x as i64);
            // Narrow pieces: their own columns are as good as the band's extent.
            let (mut lo, mut hi) = if rect.x1 - rect.x0 < 32 {
                (rect.x0, rect.x1)
            } else {
                band_extent(tri, y, yb).unwrap_or((1, 0))
            };
            lo = lo.max(rect.x0);
            hi = hi.min(rect.x1);
            let (mut t0, mut t1) = (lo.max(0) >> layout.shift, hi.max(-1) >> layout.shift);
            t1 = t1.min(tiles_x - 1);
            scanned += (t1 - t0 + 1).max(0) as u64;
            while t0 <= t1 && !active(&eye.tiles[layout.tile_index(t0 as u32, ty)]) {
                t0 += 1;
            }
            while t1 >= t0 && !active(&eye.tiles[layout.tile_index(t1 as u32, ty)]) {
                t1 -= 1;
            }
            band_lo = lo.max(t0 * tile);
            band_hi = hi.min(t1 * tile + tile - 1);
        }
        if band_lo > band_hi {
            continue;
        }
        let Some((a0, b0, e0)) = walker.span(y) else {
            continue;
        };
        let (a, b) = (a0.max(band_lo), b0.min(band_hi));
        if a > b {
            continue;
        }
        let e_a = [0, 1, 2].map(|i| e0[i] + step[i] * (a - a0) as f64);
        let ty = (y >> layout.shift) as u32;
        let mut x = a;
        while x <= b {
            // The run x..=xe lies in one tile row of the depth and of the
            // stencil: contiguous in both.
            let xe = b.min(x | (run - 1));
            let n = (xe - x + 1) as usize;
            // Skip runs in tiles with no written depth inside the window
            // (all background, or outside the depth bounds).
            let tb = &eye.tiles[layout.tile_index((x >> layout.shift) as u32, ty)];
            if !active(tb) {
                x = xe + 1;
                continue;
            }
            let di = layout.pixel_index(x as u32, y as u32);
            let ds = &depth[di..di + n];
            let i0 = tiled_index(width, x as u32, y as u32) - base;
            let cs = &mut counters[i0..i0 + n];
            let ts = &mut touched[i0..i0 + n];
            // Edge values at the run's first pixel (exact integers).
            let k0 = (x - a) as f64;
            let plane = RunPlane {
                e: [0, 1, 2].map(|i| e_a[i] + step[i] * k0),
                step,
                z,
                inv,
                dlo,
                dhi,
                zfail,
            };
            let (ins, upd) = run_masks(avx2, &plane, ds);
            processed += u64::from(ins.count_ones());
            updates += u64::from(upd.count_ones());
            if upd == (1 << n) - 1 {
                // Every pixel of the run updates (a branch-free, vectorizable loop).
                for (c, t) in cs.iter_mut().zip(ts.iter_mut()) {
                    first += u64::from(*t == 0);
                    *t = 1;
                    *c = c.wrapping(delta);
                }
            } else if upd != 0 {
                for (k, (c, t)) in cs.iter_mut().zip(ts.iter_mut()).enumerate() {
                    let u = (upd >> k) & 1 != 0;
                    first += u64::from(u & (*t == 0));
                    *t |= u8::from(u);
                    *c = c.wrapping(if u { delta } else { zero });
                }
            }
            x = xe + 1;
        }
    }
    st.pixels_processed += processed;
    st.tiles_scanned += scanned;
    st.stencil_updates += updates;
    st.pixels_touched += first;
}
