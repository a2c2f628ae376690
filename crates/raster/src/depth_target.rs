//! The depth target: an f32 depth buffer in tile-major layout with per-tile
//! hierarchical z (zmin, zmax over written pixels, background count) and an
//! optional primitive-id target [Greene et al. 1993, "Hierarchical Z-buffer
//! visibility"].
//!
//! Background (never written) pixels hold [`BACKGROUND`] (−1, below every
//! legal depth), so the GREATER write test and the GEQUAL query test treat them
//! as "no surface" without a branch; tile bounds ignore them.
//!
//! `impl DepthTarget` is spread over three files, one per concern: this one
//! holds the storage and its accessors (size, settings, clearing, reading
//! pixels and tile bounds), `draw.rs` the drawing of occluders and
//! `query.rs` the occlusion queries. Each of those two files is one
//! algorithm built on the storage, so each imports `depth_target` and this
//! module imports neither: the dependency runs one way, and a change to the
//! drawing or the queries never touches the storage's file.

use crate::hiz::RowSkip;
use crate::isa::InstructionSet;
use crate::layout::{Layout, TileBounds, TileRows, TileSize, BACKGROUND};
use crate::setup::Viewport;
use crate::stats::RasterStats;
use crate::{Error, Result, MAX_TARGET_SIZE};
use std::ops::Range;

/// Primitive id of a background pixel.
pub const NO_ID: (u32, u32) = (u32::MAX, u32::MAX);

/// Which triangles a draw skips by their [`Facing`](crate::Facing) (GL's
/// `glCullFace`), per draw ([`DrawItem::cull`](crate::DrawItem::cull)).
/// Queries never cull.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum CullMode {
    /// Every triangle is drawn.
    #[default]
    None,
    /// Only [`Facing::Front`](crate::Facing::Front) triangles are drawn (back-facing and edge-on ones
    /// are counted as culled). For closed meshes seen from outside this drops
    /// only surfaces hidden behind their own front faces; a mesh the eye is in,
    /// or one the near plane cuts, occludes less (never more) than with
    /// [`CullMode::None`], so occlusion culling stays conservative.
    Back,
    /// Only [`Facing::Back`](crate::Facing::Back) triangles are drawn: the
    /// front faces of a mesh seen in a mirror (a transform of negative
    /// determinant), or of an inside-out one; as [`CullMode::Back`] otherwise.
    Front,
}

impl CullMode {
    /// Whether a draw skips a triangle of `facing` (`None`: edge-on, or
    /// degenerate after snapping; skipped by either culling mode).
    #[inline(always)]
    pub fn skips(self, facing: Option<crate::Facing>) -> bool {
        use crate::Facing;
        match self {
            CullMode::None => false,
            CullMode::Back => facing != Some(Facing::Front),
            CullMode::Front => facing != Some(Facing::Back),
        }
    }
}

/// A depth buffer with hierarchical z and an optional primitive-id buffer.
///
/// Reversed Z: depth 1 at the near plane, 0 at infinity; a draw writes where its
/// depth is GREATER than the stored one (or equal with a smaller id when the id
/// target is enabled); queries count GEQUAL samples.
#[derive(Clone, Debug)]
pub struct DepthTarget {
    pub(crate) vp: Viewport,
    pub(crate) layout: Layout,
    pub(crate) depth: Vec<f32>,
    pub(crate) ids: Option<Vec<u64>>,
    pub(crate) tiles: Vec<TileBounds>,
    pub(crate) stats: RasterStats,
    pub(crate) threads: usize,
    /// Tile rows `r0..r1` that [`DepthTarget::draw`] writes (all when `None`).
    pub(crate) draw_rows: Option<(u32, u32)>,
    /// Tiles draws skip ([`DepthTarget::set_draw_tiles`]), ascending; each
    /// clear hides them again.
    hidden: Vec<u32>,
    /// The kernels' instruction set: the detected one, or a lower cap.
    pub(crate) isa: InstructionSet,
    /// Scratch of [`DepthTarget::draw`]'s hidden-row test (kept, not rebuilt per mesh).
    pub(crate) skip: Box<RowSkip>,
    /// Buffers of [`DepthTarget::draw_batch`] (kept: no allocation per batch).
    #[cfg_attr(not(feature = "parallel"), allow(dead_code))]
    pub(crate) batch: crate::batch_scratch::BatchScratch,
    /// Buffers of [`DepthTarget::draw_convex`].
    pub(crate) convex: crate::whole_draw::ConvexScratch,
    /// Buffers of [`DepthTarget::draw_closed`].
    pub(crate) closed: crate::whole_draw::ClosedScratch,
}

impl DepthTarget {
    /// A cleared `width × height` target with the given tile size, with a primitive-id
    /// target when `with_ids`.
    ///
    /// # Errors
    /// [`Error::InvalidSize`] when a side is 0 or above [`MAX_TARGET_SIZE`];
    /// [`Error::OutOfMemory`] when its buffers cannot be allocated.
    pub fn new(width: u32, height: u32, tile: TileSize, with_ids: bool) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_TARGET_SIZE || height > MAX_TARGET_SIZE {
            return Err(Error::InvalidSize {
                width,
                height,
                max: MAX_TARGET_SIZE,
            });
        }
        let shift = tile.shift();
        let s = 1u32 << shift;
        let layout = Layout {
            width,
            height,
            tiles_x: width.div_ceil(s),
            tiles_y: height.div_ceil(s),
            shift,
        };
        let n_tiles = (layout.tiles_x * layout.tiles_y) as usize;
        let n = n_tiles * layout.tile_pixels();
        let size = (width, height);
        let mut t = DepthTarget {
            vp: Viewport::new(width, height),
            layout,
            depth: crate::error::try_filled(n, BACKGROUND, "depth", size)?,
            ids: if with_ids {
                Some(crate::error::try_filled(
                    n,
                    u64::MAX,
                    "primitive ids",
                    size,
                )?)
            } else {
                None
            },
            tiles: Vec::new(),
            stats: RasterStats::default(),
            threads: 0,
            draw_rows: None,
            // Room for every tile from the start: a target made ahead of
            // its first view (a light pass's group that has not drawn yet)
            // allocates nothing when it does. (The vertex stage of larger
            // meshes is the drawing thread's, `dispatch.rs`.)
            hidden: Vec::with_capacity(n_tiles),
            isa: InstructionSet::detected(),
            skip: Box::new(RowSkip::new()),
            batch: Default::default(),
            convex: crate::whole_draw::ConvexScratch::with_room(n_tiles),
            closed: Default::default(),
        };
        t.clear();
        Ok(t)
    }

    /// Whether the target keeps primitive ids.
    pub fn has_ids(&self) -> bool {
        self.ids.is_some()
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.layout.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.layout.height
    }

    /// Tile edge length in pixels.
    pub fn tile_pixels(&self) -> u32 {
        1 << self.layout.shift
    }

    /// The tile size.
    pub fn tile_size(&self) -> TileSize {
        match self.layout.shift {
            2 => TileSize::T4,
            3 => TileSize::T8,
            _ => TileSize::T16,
        }
    }

    /// Number of tiles horizontally and vertically.
    pub fn tile_counts(&self) -> (u32, u32) {
        (self.layout.tiles_x, self.layout.tiles_y)
    }

    /// Restricts [`DepthTarget::draw`] and [`DepthTarget::draw_batch`] to
    /// the tile rows `r0..r1` (clamped to
    /// the target; `None`: every row): the rest keeps its depth. For a target
    /// whose depth matters only there — a light view, whose queries count
    /// samples only over receiver-marked pixels, draws its occluders only in
    /// the rows holding receivers. Queries are not restricted.
    pub fn set_draw_rows(&mut self, rows: Option<(u32, u32)>) {
        self.draw_rows = rows.map(|(a, b)| {
            let b = b.min(self.layout.tiles_y);
            (a.min(b), b)
        });
    }

    /// Hides the tiles of tile columns `columns` in tile rows `rows`
    /// (clamped to the target; an empty range: none) from draws and queries
    /// until the next call, across clears, as [`DepthTarget::set_draw_tiles`]
    /// hides unmarked tiles: their bounds read as covered at infinite
    /// nearness, so no draw writes and no query counts a sample there. For
    /// one traversal per part of the view, each on its own target (the parts
    /// then joined with [`DepthTarget::take_part_from`]). It holds for tiles
    /// still cleared now and for every tile from the next clear on.
    pub fn set_hidden_part(&mut self, columns: Range<u32>, rows: Range<u32>) {
        let (columns, rows) = self.tile_part(columns, rows);
        let tx = self.layout.tiles_x;
        let tiles = rows.flat_map(move |ty| columns.clone().map(move |c| ty * tx + c));
        self.hide_tiles(tiles);
    }

    /// Replaces the tiles of tile columns `columns` in tile rows `rows`
    /// (clamped to the target) with `src`'s — depth, primitive ids and tile
    /// bounds — and adds `src`'s counters (taken) to this target's: what one
    /// traversal per part of the view joins. Tiles this target hides keep
    /// their hiding for the next clear.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `src` differs in size, tile size or in
    /// having primitive ids.
    pub fn take_part_from(
        &mut self,
        src: &mut DepthTarget,
        columns: Range<u32>,
        rows: Range<u32>,
    ) -> Result<()> {
        let l = self.layout;
        if src.layout != l || src.ids.is_some() != self.ids.is_some() {
            return Err(Error::SizeMismatch {
                expected: (self.width(), self.height()),
                got: (src.width(), src.height()),
            });
        }
        let (columns, rows) = self.tile_part(columns, rows);
        let tp = l.tile_pixels();
        for ty in rows {
            // The part's tiles of one row are contiguous, and so are their pixels.
            let tiles =
                (ty * l.tiles_x + columns.start) as usize..(ty * l.tiles_x + columns.end) as usize;
            let pixels = tiles.start * tp..tiles.end * tp;
            self.depth[pixels.clone()].copy_from_slice(&src.depth[pixels.clone()]);
            if let (Some(d), Some(s)) = (&mut self.ids, &src.ids) {
                d[pixels.clone()].copy_from_slice(&s[pixels]);
            }
            self.tiles[tiles.clone()].copy_from_slice(&src.tiles[tiles]);
        }
        self.stats.add(&src.take_stats());
        Ok(())
    }

    /// Tile `columns` and `rows` clamped to the target (empty when reversed).
    fn tile_part(&self, columns: Range<u32>, rows: Range<u32>) -> (Range<u32>, Range<u32>) {
        let l = self.layout;
        let clamp = |r: Range<u32>, n: u32| r.start.min(n)..r.end.min(n).max(r.start.min(n));
        (clamp(columns, l.tiles_x), clamp(rows, l.tiles_y))
    }

    /// Hides `tiles` (tile indices, ascending) from draws from now until the
    /// next call, across clears, after giving back the tiles hidden before:
    /// what [`DepthTarget::set_draw_tiles`] (beside the receiver target)
    /// sets.
    pub(crate) fn hide_tiles(&mut self, tiles: impl Iterator<Item = u32>) {
        self.show_hidden();
        self.hidden.clear();
        // Room for every tile at once: later views allocate nothing.
        self.hidden.reserve(self.tiles.len());
        self.hidden.extend(tiles);
        self.hide();
    }

    /// Gives the hidden tiles their cleared bounds back (their pixels, never
    /// written while hidden, are background).
    fn show_hidden(&mut self) {
        let l = self.layout;
        for &t in &self.hidden {
            let t = t as usize;
            let tb = &mut self.tiles[t];
            if tb.background == 0 && tb.zmin == f32::INFINITY {
                *tb = TileBounds {
                    zmin: f32::INFINITY,
                    zmax: BACKGROUND,
                    background: l.tile_area(t),
                };
            }
        }
    }

    /// Hides the listed tiles that hold background only (after a clear,
    /// every one).
    fn hide(&mut self) {
        let l = self.layout;
        for &t in &self.hidden {
            let t = t as usize;
            let area = l.tile_area(t);
            let tb = &mut self.tiles[t];
            if tb.background == area {
                *tb = TileBounds {
                    zmin: f32::INFINITY,
                    zmax: f32::INFINITY,
                    background: 0,
                };
            }
        }
    }

    /// Caps the instruction set of the kernels that draw into, query and
    /// stencil against this target (default: the detected level; a cap above
    /// it runs the detected level). Every level gives bit-identical results:
    /// the cap is for comparing builds, or for ruling one out.
    pub fn set_instruction_set(&mut self, cap: InstructionSet) {
        self.isa = cap.capped();
    }

    /// The instruction set the kernels run at ([`DepthTarget::set_instruction_set`]).
    pub fn instruction_set(&self) -> InstructionSet {
        self.isa
    }

    /// Limits batch draws and queries to `threads` rayon workers (0 = rayon's pool size,
    /// 1 = single-threaded). The output never depends on it.
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads;
    }

    /// Resets every pixel to background (and every id to [`NO_ID`]); the
    /// tiles [`DepthTarget::set_draw_tiles`] hid stay hidden.
    pub fn clear(&mut self) {
        self.show_hidden();
        self.clear_all();
        self.hide();
    }

    fn clear_all(&mut self) {
        let l = self.layout;
        if self.tiles.len() == (l.tiles_x * l.tiles_y) as usize {
            // Only tiles written since the last clear need it: a tile's first write
            // overwrites a background pixel, which lowers its background count below
            // its area, and only a clear raises it back.
            let tp = l.tile_pixels();
            let s = 1u32 << l.shift;
            let mut t = 0usize;
            for ty in 0..l.tiles_y {
                let h = if ty + 1 < l.tiles_y {
                    s
                } else {
                    l.height - ty * s
                };
                for tx in 0..l.tiles_x {
                    let w = if tx + 1 < l.tiles_x {
                        s
                    } else {
                        l.width - tx * s
                    };
                    let tb = &mut self.tiles[t];
                    if tb.background != w * h {
                        self.depth[t * tp..(t + 1) * tp].fill(BACKGROUND);
                        if let Some(ids) = &mut self.ids {
                            ids[t * tp..(t + 1) * tp].fill(u64::MAX);
                        }
                        *tb = TileBounds {
                            zmin: f32::INFINITY,
                            zmax: BACKGROUND,
                            background: w * h,
                        };
                    }
                    t += 1;
                }
            }
            return;
        }
        self.depth.fill(BACKGROUND);
        if let Some(ids) = &mut self.ids {
            ids.fill(u64::MAX);
        }
        let l = self.layout;
        self.tiles.clear();
        self.tiles
            .extend((0..(l.tiles_x * l.tiles_y) as usize).map(|t| TileBounds {
                zmin: f32::INFINITY,
                zmax: BACKGROUND,
                background: l.tile_area(t),
            }));
    }

    /// Replaces every pixel's depth with `depth` (row-major, row 0 at the
    /// top, `width × height` values, reversed Z), every id with [`NO_ID`],
    /// and recomputes every tile's bounds: a depth buffer made elsewhere (a
    /// host's depth pre-pass, reduced to this size) for queries to test
    /// against. A value that is not above 0 (0: nothing drawn, or infinitely
    /// far; NaN too) is background. The statistics are untouched and the
    /// tiles [`DepthTarget::set_draw_tiles`] hid stay hidden.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `depth` does not hold `width × height`
    /// values.
    pub fn load_rows(&mut self, depth: &[f32]) -> Result<()> {
        let l = self.layout;
        let (w, h) = (l.width as usize, l.height as usize);
        if depth.len() != w * h {
            return Err(Error::SizeMismatch {
                expected: (l.width, l.height),
                got: (depth.len().min(u32::MAX as usize) as u32, 1),
            });
        }
        self.show_hidden();
        let s = 1u32 << l.shift;
        for (y, row) in depth.chunks_exact(w).enumerate() {
            for tx in 0..l.tiles_x {
                let x0 = tx * s;
                let n = s.min(l.width - x0) as usize;
                let i = l.pixel_index(x0, y as u32);
                let src = &row[x0 as usize..x0 as usize + n];
                for (d, &v) in self.depth[i..i + n].iter_mut().zip(src) {
                    *d = if v > 0.0 { v } else { BACKGROUND };
                }
            }
        }
        if let Some(ids) = &mut self.ids {
            ids.fill(u64::MAX);
        }
        let mut rows = TileRows::of(
            l,
            (0, l.tiles_y),
            &mut self.depth,
            self.ids.as_deref_mut(),
            &mut self.tiles,
        );
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                rows.refresh_tile(tx, ty);
            }
        }
        self.hide();
        Ok(())
    }

    /// Depth at pixel `(x, y)` (row 0 at the top); `None` for background.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the target.
    pub fn depth_at(&self, x: u32, y: u32) -> Option<f32> {
        assert!(
            x < self.width() && y < self.height(),
            "pixel ({x}, {y}) outside the target"
        );
        let d = self.depth[self.layout.pixel_index(x, y)];
        (d != BACKGROUND).then_some(d)
    }

    /// Primitive id `(object, triangle)` at pixel `(x, y)`; `None` for background or
    /// when the target has no id buffer.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the target.
    pub fn id_at(&self, x: u32, y: u32) -> Option<(u32, u32)> {
        assert!(
            x < self.width() && y < self.height(),
            "pixel ({x}, {y}) outside the target"
        );
        let id = self.ids.as_ref()?[self.layout.pixel_index(x, y)];
        (id != u64::MAX).then_some(((id >> 32) as u32, id as u32))
    }

    /// Calls `f(x, depth, id)` for every pixel of row `y`, left to right
    /// ([`BACKGROUND`] depth and `None` id for background; `None` ids without
    /// an id buffer): the bulk form of [`DepthTarget::depth_at`] and
    /// [`DepthTarget::id_at`], walking the tile-major buffers in order.
    ///
    /// # Panics
    /// When `y` lies outside the target.
    #[inline]
    pub fn for_each_in_row(&self, y: u32, mut f: impl FnMut(u32, f32, Option<(u32, u32)>)) {
        assert!(y < self.height(), "row {y} outside the target");
        let l = self.layout;
        let s = 1u32 << l.shift;
        for tx in 0..l.tiles_x {
            let x0 = tx * s;
            let n = s.min(l.width - x0) as usize;
            let i = l.pixel_index(x0, y);
            let ids = self.ids.as_ref().map(|v| &v[i..i + n]);
            for (k, &d) in self.depth[i..i + n].iter().enumerate() {
                let id = ids
                    .map(|v| v[k])
                    .filter(|&id| id != u64::MAX)
                    .map(|id| ((id >> 32) as u32, id as u32));
                f(x0 + k as u32, d, id);
            }
        }
    }

    /// Calls `f(x0, x1, id)` for every run of pixels `x0..x1` of row `y`
    /// that hold one id (`None` for background, and for the whole row
    /// without an id buffer), left to right: [`DepthTarget::for_each_in_row`]
    /// for consumers that decide once per visible triangle. Whole tile rows
    /// of the current run's id are skipped with one branch-free compare.
    ///
    /// # Panics
    /// When `y` lies outside the target.
    pub fn for_each_id_run_in_row(&self, y: u32, mut f: impl FnMut(u32, u32, Option<(u32, u32)>)) {
        assert!(y < self.height(), "row {y} outside the target");
        let l = self.layout;
        let decode = |id: u64| (id != u64::MAX).then_some(((id >> 32) as u32, id as u32));
        let Some(ids) = &self.ids else {
            f(0, l.width, None);
            return;
        };
        let s = 1u32 << l.shift;
        let mut cur = ids[l.pixel_index(0, y)];
        let mut start = 0;
        for tx in 0..l.tiles_x {
            let x0 = tx * s;
            let i = l.pixel_index(x0, y);
            let row = &ids[i..i + s.min(l.width - x0) as usize];
            if row.iter().fold(0, |a, &v| a | (v ^ cur)) == 0 {
                continue;
            }
            for (k, &v) in row.iter().enumerate() {
                if v != cur {
                    let x = x0 + k as u32;
                    f(start, x, decode(cur));
                    (cur, start) = (v, x);
                }
            }
        }
        f(start, l.width, decode(cur));
    }

    /// Depths in row-major order (row 0 at the top), [`BACKGROUND`] for background.
    pub fn depth_rows(&self) -> Vec<f32> {
        let mut out = Vec::new();
        self.depth_rows_into(&mut out);
        out
    }

    /// [`DepthTarget::depth_rows`] into `out` (cleared first; its buffer
    /// reused).
    pub fn depth_rows_into(&self, out: &mut Vec<f32>) {
        let (w, h) = (self.width(), self.height());
        out.clear();
        out.reserve((w * h) as usize);
        let l = self.layout;
        let s = 1u32 << l.shift;
        for y in 0..h {
            // A tile row's pixels are contiguous within each tile.
            for tx in 0..l.tiles_x {
                let i = l.pixel_index(tx * s, y);
                let n = s.min(w - tx * s) as usize;
                out.extend_from_slice(&self.depth[i..i + n]);
            }
        }
    }

    /// Hierarchical-z bounds `(zmin, zmax)` of the written pixels of tile `(tx, ty)`;
    /// `None` when all its pixels are background.
    ///
    /// # Panics
    /// When the tile lies outside the target.
    pub fn tile_bounds(&self, tx: u32, ty: u32) -> Option<(f32, f32)> {
        assert!(tx < self.layout.tiles_x && ty < self.layout.tiles_y);
        let t = self.tiles[self.layout.tile_index(tx, ty)];
        (t.zmax != BACKGROUND).then_some((t.zmin, t.zmax))
    }

    /// Number of background pixels in tile `(tx, ty)`.
    ///
    /// # Panics
    /// When the tile lies outside the target.
    pub fn tile_background(&self, tx: u32, ty: u32) -> u32 {
        assert!(tx < self.layout.tiles_x && ty < self.layout.tiles_y);
        self.tiles[self.layout.tile_index(tx, ty)].background
    }

    /// Turns every pixel with `keep == false` into background (depth
    /// [`BACKGROUND`], id [`NO_ID`] when the id target exists) and recomputes the
    /// hierarchical-z bounds of every changed tile from its pixels, so they are
    /// exactly what drawing only the kept pixels would have produced.
    ///
    /// This is the computation mask of [ChanDurand04 computation mask]: stencil passes skip
    /// background pixels and tiles without written depth, so a masked eye target
    /// makes shadow-volume rasterization work only at the kept (shadow-silhouette)
    /// pixels. `keep` is row-major, row 0 at the top, one entry per pixel.
    ///
    /// # Errors
    /// [`Error::MaskLength`] when `keep` does not hold `width × height` entries
    /// (the target is then unchanged).
    pub fn keep_only(&mut self, keep: &[bool]) -> Result<()> {
        let l = self.layout;
        self.check_mask(keep)?;
        let mut band = TileRows {
            layout: l,
            ty0: 0,
            ty1: l.tiles_y,
            depth: &mut self.depth,
            ids: self.ids.as_deref_mut(),
            tiles: &mut self.tiles,
        };
        for ty in 0..l.tiles_y {
            for tx in 0..l.tiles_x {
                let (x0, x1, y0, y1) = l.tile_rect(tx, ty);
                let mut changed = false;
                for y in y0..=y1 {
                    let row = &keep[(y * l.width) as usize..][..l.width as usize];
                    for x in x0..=x1 {
                        if row[x as usize] {
                            continue;
                        }
                        let i = l.pixel_index(x, y);
                        if band.depth[i] != BACKGROUND {
                            band.depth[i] = BACKGROUND;
                            changed = true;
                        }
                        if let Some(ids) = band.ids.as_deref_mut() {
                            ids[i] = u64::MAX;
                        }
                    }
                }
                if changed {
                    band.refresh_tile(tx, ty);
                }
            }
        }
        Ok(())
    }

    /// [`Error::MaskLength`] unless `keep` holds one entry per pixel.
    fn check_mask(&self, keep: &[bool]) -> Result<()> {
        let l = self.layout;
        let n = l.width as usize * l.height as usize;
        if keep.len() != n {
            return Err(Error::MaskLength {
                expected: n,
                got: keep.len(),
                width: l.width,
                height: l.height,
            });
        }
        Ok(())
    }

    /// Makes this target (of `src`'s size and tile size) a copy of `src`'s
    /// depth in which every pixel with `keep == false` is background, with
    /// the hierarchical-z bounds of every tile recomputed from its pixels:
    /// what [`DepthTarget::keep_only`] makes of a clone of `src`, without
    /// the clone's allocations or its primitive ids (this target's ids, if
    /// any, are left as they were). Tile rows are copied in parallel with
    /// the `parallel` feature.
    ///
    /// A stencil pass skips background pixels and tiles without written
    /// depth, so on this copy it works only at the kept pixels: the
    /// pipeline keeps those a light can shadow.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when the targets' sizes or tile sizes differ,
    /// [`Error::MaskLength`] when `keep` does not hold `width × height`
    /// entries (the target is then unchanged).
    pub fn copy_kept_from(&mut self, src: &DepthTarget, keep: &[bool]) -> Result<()> {
        let l = self.layout;
        if src.layout != l {
            return Err(Error::SizeMismatch {
                expected: (self.width(), self.height()),
                got: (src.width(), src.height()),
            });
        }
        self.check_mask(keep)?;
        let (tx_n, tp) = (l.tiles_x as usize, l.tile_pixels());
        // One tile row: its pixels and bounds copied, then per tile with
        // a written pixel, the dropped pixels made background and, when
        // one was written, its bounds recomputed.
        let row = |ty: u32,
                   (depth, tiles): (&mut [f32], &mut [TileBounds]),
                   (from, bounds): (&[f32], &[TileBounds])| {
            depth.copy_from_slice(from);
            tiles.copy_from_slice(bounds);
            let mut band = TileRows {
                layout: l,
                ty0: ty,
                ty1: ty + 1,
                depth,
                ids: None,
                tiles,
            };
            for tx in 0..l.tiles_x {
                if bounds[tx as usize].zmax == BACKGROUND {
                    continue;
                }
                let (x0, x1, y0, y1) = l.tile_rect(tx, ty);
                let n = (x1 - x0 + 1) as usize;
                let mut lost = false;
                for y in y0..=y1 {
                    let keep = &keep[(y * l.width + x0) as usize..][..n];
                    if all_kept(keep) {
                        continue;
                    }
                    // Tile-major: the tile's row `y` is contiguous.
                    let at = tx as usize * tp + (((y - y0) << l.shift) as usize);
                    for (d, &k) in band.depth[at..at + n].iter_mut().zip(keep) {
                        lost |= !k & (*d != BACKGROUND);
                        if !k {
                            *d = BACKGROUND;
                        }
                    }
                }
                if lost {
                    band.refresh_tile(tx, ty);
                }
            }
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            self.depth
                .par_chunks_mut(tx_n * tp)
                .zip(self.tiles.par_chunks_mut(tx_n))
                .zip(
                    src.depth
                        .par_chunks(tx_n * tp)
                        .zip(src.tiles.par_chunks(tx_n)),
                )
                .enumerate()
                .for_each(|(ty, (to, from))| row(ty as u32, to, from));
        }
        #[cfg(not(feature = "parallel"))]
        for (ty, (to, from)) in self
            .depth
            .chunks_mut(tx_n * tp)
            .zip(self.tiles.chunks_mut(tx_n))
            .zip(src.depth.chunks(tx_n * tp).zip(src.tiles.chunks(tx_n)))
            .enumerate()
        {
            row(ty as u32, to, from);
        }
        self.vp = src.vp;
        Ok(())
    }

    /// Counters accumulated since the last call; resets them.
    pub fn take_stats(&mut self) -> RasterStats {
        std::mem::take(&mut self.stats)
    }

    /// Counters accumulated since the last [`DepthTarget::take_stats`].
    pub fn stats(&self) -> RasterStats {
        self.stats
    }
}

/// Whether every entry of `keep` is true: eight at a time as one word.
#[inline(always)]
fn all_kept(keep: &[bool]) -> bool {
    let mut words = keep.chunks_exact(8);
    let all = words.by_ref().all(|w| {
        let w: [u8; 8] = std::array::from_fn(|i| u8::from(w[i]));
        u64::from_ne_bytes(w) == 0x0101_0101_0101_0101
    });
    all && words.remainder().iter().all(|&k| k)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    use crate::{Coverage, DrawItem};
    use glam::{Mat4, Vec3, Vec4};

    /// Two overlapping triangles with sloped depth over a target whose size is not
    /// a multiple of the tile size.
    fn drawn(with_ids: bool) -> DepthTarget {
        let mut t = DepthTarget::new(37, 29, TileSize::T8, with_ids).unwrap();
        draw_pair(&mut t);
        t
    }

    /// A drawn target's depth read out row by row and loaded into another
    /// gives the same pixels and tile bounds; a buffer of the wrong length
    /// is refused.
    #[test]
    fn loaded_rows_equal_the_drawn_target() {
        let a = drawn(true);
        let (w, h) = (a.width(), a.height());
        let rows: Vec<f32> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| a.depth_at(x, y).unwrap_or(0.0))
            .collect();
        assert!(rows.contains(&0.0) && rows.iter().any(|&d| d > 0.0));
        let mut b = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        draw_pair(&mut b);
        b.load_rows(&vec![0.5; (w * h) as usize]).unwrap();
        b.load_rows(&rows).unwrap();
        for y in 0..h {
            for x in 0..w {
                assert_eq!(a.depth_at(x, y), b.depth_at(x, y), "({x}, {y})");
                assert_eq!(b.id_at(x, y), None);
            }
        }
        let (tx, ty) = a.tile_counts();
        for (x, y) in (0..ty).flat_map(|y| (0..tx).map(move |x| (x, y))) {
            assert_eq!(a.tile_bounds(x, y), b.tile_bounds(x, y));
            assert_eq!(a.tile_background(x, y), b.tile_background(x, y));
        }
        assert!(b.load_rows(&rows[1..]).is_err());
    }

    /// A xorshift generator of values in `[-1, 1)` from `seed` (the
    /// rasterizer's randomized tests).
    pub(crate) fn signed_unit(mut s: u64) -> impl FnMut() -> f32 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        }
    }

    /// Two overlapping triangles with sloped depth into `t` (also used by the
    /// receiver target's tests).
    pub(crate) fn draw_pair(t: &mut DepthTarget) {
        let positions = [
            Vec4::new(-1.2, -1.1, 0.2, 1.0),
            Vec4::new(0.9, -0.8, 0.7, 1.0),
            Vec4::new(-0.3, 1.0, 0.4, 1.0),
            Vec4::new(-0.5, 0.9, 0.9, 1.0),
            Vec4::new(0.2, -0.95, 0.1, 1.0),
            Vec4::new(0.6, 0.5, 0.3, 1.0),
        ];
        let triangles = [[0, 1, 2], [3, 4, 5]];
        t.draw(
            &DrawItem {
                clip_from_local: Mat4::IDENTITY,
                positions: &positions,
                triangles: &triangles,
                object: 3,
                cull: crate::CullMode::None,
            },
            Coverage::Standard,
        )
        .unwrap();
    }

    /// Two targets, each hiding the other's half of the tiles (split by
    /// rows, then by columns), draw the same meshes; the first then takes
    /// the second's half: depth, ids and tile bounds equal one whole
    /// target's. Hidden tiles are never written, and a query counts no
    /// sample there.
    #[test]
    fn halves_hiding_each_others_tiles_join_to_the_whole() {
        use crate::QueryOptions;
        let new = || DepthTarget::new(37, 29, TileSize::T8, true).unwrap();
        let mut full = new();
        draw_pair(&mut full);
        let (tx, ty) = full.tile_counts();
        let near = (Vec3::new(-1.0, -1.0, 0.95), Vec3::new(1.0, 1.0, 0.99));
        let query = |t: &mut DepthTarget| {
            t.query_aabb(
                Mat4::IDENTITY,
                near.0,
                near.1,
                &QueryOptions::default(),
                None,
            )
            .unwrap()
        };
        let mut all_hidden = new();
        all_hidden.set_hidden_part(0..tx, 0..ty);
        assert!(query(&mut full) > 0);
        assert_eq!(query(&mut all_hidden), 0);
        // (first half's columns, rows), (second half's columns, rows).
        let splits = [
            ((0..tx, 0..2), (0..tx, 2..ty)),
            ((0..2, 0..ty), (2..tx, 0..ty)),
        ];
        for ((c0, r0), (c1, r1)) in splits {
            let (mut first, mut second) = (new(), new());
            first.set_hidden_part(c1.clone(), r1.clone());
            second.set_hidden_part(c0.clone(), r0.clone());
            for t in [&mut first, &mut second] {
                t.clear();
                draw_pair(t);
            }
            // Pixels drawn in each half.
            let mut drawn = [0, 0];
            for y in 0..29 {
                for x in 0..37 {
                    let in_first = c0.contains(&(x >> 3)) && r0.contains(&(y >> 3));
                    let (part, other) = match in_first {
                        true => (&first, &second),
                        false => (&second, &first),
                    };
                    assert_eq!(part.depth_at(x, y), full.depth_at(x, y), "({x}, {y})");
                    assert_eq!(other.depth_at(x, y), None, "({x}, {y}) is hidden");
                    drawn[usize::from(in_first)] += usize::from(full.depth_at(x, y).is_some());
                }
            }
            assert!(drawn[0] > 0 && drawn[1] > 0, "{drawn:?}");
            first.set_hidden_part(0..0, 0..0);
            first.take_part_from(&mut second, c1, r1).unwrap();
            assert_eq!(first.depth_rows(), full.depth_rows());
            for y in 0..29 {
                for x in 0..37 {
                    assert_eq!(first.id_at(x, y), full.id_at(x, y), "({x}, {y})");
                }
            }
            assert_eq!(first.tiles, full.tiles);
        }
        let mut other = DepthTarget::new(36, 29, TileSize::T8, true).unwrap();
        assert!(full.take_part_from(&mut other, 0..tx, 0..1).is_err());
    }

    /// A new target hides every tile in the storage it was made with: a
    /// target made ahead of its first view allocates nothing when it draws
    /// (the `steady_alloc` test's light-pass groups).
    #[test]
    fn a_new_target_has_room_for_its_draw_scratch() {
        let mut t = DepthTarget::new(100, 60, TileSize::T8, false).unwrap();
        let at = t.hidden.as_ptr();
        t.hide_tiles(0..t.tiles.len() as u32);
        assert_eq!(t.hidden.len(), t.tiles.len());
        assert_eq!(t.hidden.as_ptr(), at);
    }

    /// Row walks give `depth_at`/`id_at` pixel by pixel, with and without ids,
    /// on a target whose sides are not multiples of the tile.
    #[test]
    fn row_walks_match_pixel_accessors() {
        for with_ids in [false, true] {
            let t = drawn(with_ids);
            let mut background = 0;
            for y in 0..t.height() {
                let mut next = 0;
                t.for_each_in_row(y, |x, d, id| {
                    assert_eq!(x, next);
                    next += 1;
                    assert_eq!((d != BACKGROUND).then_some(d), t.depth_at(x, y));
                    assert_eq!(id, t.id_at(x, y));
                    background += usize::from(d == BACKGROUND);
                });
                assert_eq!(next, t.width());
            }
            assert!(background > 0 && background < 37 * 29);
        }
    }

    /// Id runs tile each row left to right, neighbours differ, and every
    /// pixel of a run has the run's id; without ids a row is one run.
    #[test]
    fn id_runs_match_pixel_accessors() {
        for with_ids in [false, true] {
            let t = drawn(with_ids);
            let mut runs = 0;
            for y in 0..t.height() {
                let mut next = 0;
                let mut last = None;
                t.for_each_id_run_in_row(y, |x0, x1, id| {
                    assert_eq!(x0, next);
                    assert!(x1 > x0);
                    assert_ne!(last, Some(id), "neighbouring runs of one id");
                    for x in x0..x1 {
                        assert_eq!(id, t.id_at(x, y), "({x}, {y})");
                    }
                    (next, last) = (x1, Some(id));
                    runs += 1;
                });
                assert_eq!(next, t.width());
            }
            if with_ids {
                assert!(runs > t.height() as usize, "the drawn triangles split rows");
            } else {
                assert_eq!(runs, t.height() as usize);
            }
        }
    }

    /// Bounds recomputed directly from the pixels of every tile.
    fn recomputed(t: &DepthTarget) -> Vec<(Option<(f32, f32)>, u32)> {
        let (tx_n, ty_n) = t.tile_counts();
        let mut out = Vec::new();
        for ty in 0..ty_n {
            for tx in 0..tx_n {
                let (x0, x1, y0, y1) = t.layout.tile_rect(tx, ty);
                let (mut lo, mut hi, mut bg) = (f32::INFINITY, f32::NEG_INFINITY, 0);
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        match t.depth_at(x, y) {
                            Some(d) => {
                                lo = lo.min(d);
                                hi = hi.max(d);
                            }
                            None => bg += 1,
                        }
                    }
                }
                out.push(((hi > f32::NEG_INFINITY).then_some((lo, hi)), bg));
            }
        }
        out
    }

    fn stored(t: &DepthTarget) -> Vec<(Option<(f32, f32)>, u32)> {
        let (tx_n, ty_n) = t.tile_counts();
        (0..ty_n)
            .flat_map(|ty| (0..tx_n).map(move |tx| (tx, ty)))
            .map(|(tx, ty)| (t.tile_bounds(tx, ty), t.tile_background(tx, ty)))
            .collect()
    }

    #[test]
    fn keep_only_masks_pixels_and_recomputes_tile_bounds() {
        for with_ids in [false, true] {
            let full = drawn(with_ids);
            let (w, h) = (full.width(), full.height());
            // A scattered pattern plus a block of whole tiles dropped.
            let keep: Vec<bool> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| (x * 7 + y * 13) % 5 != 0 && !(x < 16 && (8..16).contains(&y)))
                .collect();
            let mut t = full.clone();
            t.keep_only(&keep).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let k = keep[(y * w + x) as usize];
                    let want = if k { full.depth_at(x, y) } else { None };
                    assert_eq!(t.depth_at(x, y), want, "pixel ({x}, {y})");
                    if with_ids {
                        let want = if k { full.id_at(x, y) } else { None };
                        assert_eq!(t.id_at(x, y), want, "id at ({x}, {y})");
                    }
                }
            }
            assert_eq!(stored(&t), recomputed(&t));
            // Tiles the block covered are all background now.
            assert_eq!(t.tile_bounds(0, 1), None);
            assert_eq!(t.tile_background(1, 1), 64);
            // Some tile changed its bounds (the mask did something).
            assert_ne!(stored(&t), stored(&full));
            // Keeping everything changes nothing.
            let mut same = full.clone();
            same.keep_only(&vec![true; (w * h) as usize]).unwrap();
            assert_eq!(same.depth_rows(), full.depth_rows());
            assert_eq!(stored(&same), stored(&full));
            // Keeping nothing leaves all-background tiles, as after a clear.
            let mut none = full.clone();
            none.keep_only(&vec![false; (w * h) as usize]).unwrap();
            let mut cleared = full.clone();
            cleared.clear();
            assert_eq!(stored(&none), stored(&cleared));
            assert!(none.depth_rows().iter().all(|&d| d == BACKGROUND));
            assert!(stored(&none).iter().all(|(b, _)| b.is_none()));
            // A wrong length is an error and leaves the target alone.
            let mut bad = full.clone();
            assert_eq!(
                bad.keep_only(&keep[1..]),
                Err(Error::MaskLength {
                    expected: (w * h) as usize,
                    got: (w * h) as usize - 1,
                    width: w,
                    height: h,
                })
            );
            assert_eq!(bad.depth_rows(), full.depth_rows());
        }
    }

    #[test]
    fn copying_the_kept_pixels_equals_keeping_them_in_a_clone() {
        let full = drawn(true);
        let (w, h) = (full.width(), full.height());
        // Reused across masks: each copy replaces the last one wholly.
        let mut copy = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        for m in [3, 5, 1000] {
            let keep: Vec<bool> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| (x * 7 + y * 13) % m != 0 && !(x < 16 && (8..16).contains(&y)))
                .collect();
            let mut want = full.clone();
            want.keep_only(&keep).unwrap();
            copy.copy_kept_from(&full, &keep).unwrap();
            assert_eq!(copy.depth_rows(), want.depth_rows(), "mask {m}");
            assert_eq!(stored(&copy), stored(&want), "mask {m}");
            assert_ne!(stored(&copy), stored(&full), "mask {m}: it masked");
        }
        // Every kept: the source's depth and bounds.
        copy.copy_kept_from(&full, &vec![true; (w * h) as usize])
            .unwrap();
        assert_eq!(copy.depth_rows(), full.depth_rows());
        assert_eq!(stored(&copy), stored(&full));
        // A wrong length or size is an error.
        assert!(matches!(
            copy.copy_kept_from(&full, &[true; 3]),
            Err(Error::MaskLength { got: 3, .. })
        ));
        let other = DepthTarget::new(w + 1, h, TileSize::T8, false).unwrap();
        assert!(matches!(
            copy.copy_kept_from(&other, &vec![true; ((w + 1) * h) as usize]),
            Err(Error::SizeMismatch { .. })
        ));
    }

    #[test]
    fn keep_only_matches_drawing_only_the_kept_pixels_of_a_whole_tile_region() {
        // Masking whole tiles: the kept tiles' bounds equal the unmasked drawing's.
        let full = drawn(true);
        let (w, h) = (full.width(), full.height());
        let keep: Vec<bool> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| (x / 8 + y / 8) % 2 == 0)
            .collect();
        let mut t = full.clone();
        t.keep_only(&keep).unwrap();
        let (tx_n, ty_n) = t.tile_counts();
        for ty in 0..ty_n {
            for tx in 0..tx_n {
                if (tx + ty) % 2 == 0 {
                    assert_eq!(t.tile_bounds(tx, ty), full.tile_bounds(tx, ty));
                    assert_eq!(t.tile_background(tx, ty), full.tile_background(tx, ty));
                } else {
                    assert_eq!(t.tile_bounds(tx, ty), None);
                    let (x0, x1, y0, y1) = t.layout.tile_rect(tx, ty);
                    assert_eq!(t.tile_background(tx, ty), (x1 - x0 + 1) * (y1 - y0 + 1));
                }
            }
        }
    }

    /// A target capped at any level draws, queries and counts exactly what a
    /// portable-capped one does (the public side of dispatch's bit-for-bit test).
    #[test]
    fn every_instruction_set_cap_gives_the_same_target() {
        use crate::{InstructionSet, QueryOptions};
        use glam::{Mat4, Vec3, Vec4};
        let persp = Mat4::from_cols(
            Vec4::new(1.2, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.6, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        );
        let run = |cap: InstructionSet| {
            let mut t = DepthTarget::new(301, 203, TileSize::T8, true).unwrap();
            t.set_instruction_set(cap);
            assert!(
                t.instruction_set() <= cap && t.instruction_set() <= InstructionSet::detected()
            );
            let mut rnd = signed_unit(0x2545_f491_4f6c_dd1d);
            let mut answers = Vec::new();
            for k in 0..200u32 {
                let v: Vec<Vec4> = (0..3)
                    .map(|_| Vec4::new(3.0 * rnd(), 3.0 * rnd(), -2.0 - 4.0 * rnd().abs(), 1.0))
                    .collect();
                let item = DrawItem {
                    clip_from_local: persp,
                    positions: &v,
                    triangles: &[[0, 1, 2]],
                    object: k,
                    cull: crate::CullMode::None,
                };
                t.draw(&item, Coverage::Standard).unwrap();
                let lo = Vec3::new(2.0 * rnd(), 2.0 * rnd(), -3.0 - 3.0 * rnd().abs());
                let hi = lo + Vec3::splat(0.05 + 0.3 * rnd().abs());
                answers.push(
                    t.query_aabb(persp, lo, hi, &QueryOptions::default(), None)
                        .unwrap(),
                );
            }
            let pixels: Vec<_> = (0..203)
                .flat_map(|y| (0..301).map(move |x| (x, y)))
                .map(|(x, y)| (t.depth_at(x, y).map(f32::to_bits), t.id_at(x, y)))
                .collect();
            (pixels, answers, t.stats())
        };
        let portable = run(InstructionSet::Portable);
        assert!(portable.1.iter().any(|&n| n > 0) && portable.1.contains(&0));
        for cap in [InstructionSet::Avx2, InstructionSet::Avx512] {
            assert!(
                run(cap) == portable,
                "{cap} differs from the portable build"
            );
        }
    }
}
