//! Hierarchical shadow volumes [Aila04]: per-pixel stencil work only in tiles a
//! shadow volume's boundary may cross.
//!
//! For every volume (one [`VolumeRange`], between [Aila04]'s BSV and ESV):
//!
//! 1. **Stage 1** ([Aila04 §3.2.1, App. A]). Every set-up piece of the
//!    volume's triangles (the brute-force pass's own setup: clipping, snapping,
//!    fans, zp+ near-cap fans) visits the tiles it can cover. Per tile the
//!    per-shadow-volume (PSV) record holds a count, a boundary flag and a
//!    first-visit stamp. A piece that may cross the tile's 3D box (pixel
//!    rectangle × written depths `[zmin, zmax]`, background ignored) marks the
//!    tile boundary; a piece wholly in front (zpass, zp+) or wholly behind
//!    (zfail) adds its ±1 to the count if it covers the tile's sample pixel.
//!    The test is exact with respect to the rasterizer's arithmetic
//!    (`tile_class.rs`). Open edges of the volume's surface (silhouette edges of
//!    zpass volumes, near-plane cuts) mark the tiles they cross
//!    (`open_edges.rs`, which also proves why one sample per tile suffices).
//!    A non-zero count on a tile that the scissor or depth-bounds window covers
//!    only in part also makes it a boundary tile.
//! 2. **Stage 2** ([Aila04 §3.2.2, §4.1.1]). Boundary tiles get the brute-force
//!    per-pixel rasterization of the volume's pieces, clipped to the tile;
//!    tiles wholly inside get their count added to the tile's offset without
//!    touching pixels; lit tiles get nothing.
//!
//! The hierarchical stencil: per tile an offset and `Smin`/`Smax` of its
//! written pixels' per-pixel counters ([Aila04 §4.1]); a pixel's value is the
//! offset plus its counter (wrapping in 8 bits). The mask resolve reads
//! per-pixel counters only where `Smin ≠ Smax`. With the full-shadow (FS) bit
//! ([Aila04 §4.3.2]) a tile wholly inside a volume with a positive count, or
//! found at a volume's first visit with every written pixel already shadowed,
//! is in shadow for good and skipped by every later volume; without it the
//! result equals the brute-force pass bit for bit (the stencil operations
//! commute and the offsets add what the pixels would have added).
//!
//! Volumes are processed in order; the target is split into bands of 64 pixel
//! rows processed in parallel (with the `parallel` feature), each running both
//! stages for every volume on its own rows.
//!
//! # Sample pixel
//! The first written pixel of the tile in row-major order ([Aila04] allows any
//! point of the tile; by the argument in `open_edges.rs` every pixel centre of
//! a non-boundary tile has the same count).
//!
//! # Bandwidth model ([Aila04 Table 1])
//! `S` is the counter size (1 byte in 8-bit mode, 4 wide). Per-pixel buffers
//! ([`StencilStats::pixel_bytes`]): every fragment stage 2 processes reads its
//! depth (4 bytes, uncompressed) and counter (`S`), every update writes its
//! counter (`S`) — as for brute force; after stage 2 a boundary tile's written
//! counters are read again for `Smin`/`Smax` (`S` each); the resolve reads `S`
//! per written pixel of a tile with `Smin ≠ Smax` (brute force: per written
//! pixel). Per-tile buffers ([`StencilStats::tile_bytes`]): every stage-1 visit
//! reads the tile's depth bounds (8 bytes) and reads and writes its PSV record
//! (`S + 1` bytes: count and flags, so `2·(S + 1)`); the end of a volume reads
//! the PSV record of every tile it reached (`S + 1`) and reads and writes the
//! tile's hierarchical entry (offset, `Smin`, `Smax`: `3·S`, plus a byte for the
//! FS bit: `2·(3·S + 1)`); the resolve reads every written tile's entry
//! (`3·S + 1`).

use crate::coverage::Rect;
use crate::depth_target::DepthTarget;

use crate::clip::MAX_CLIPPED_VERTICES;
use crate::layout::{TileSize, BACKGROUND};
use crate::setup::{Setup, SnappedVertex, SUBPIXEL};
use crate::stencil::counters::{counter_bytes, pass_bytes, tiled_index, Counters, CountersMut};
use crate::stencil::depth_ranges::{union, DepthRanges, EMPTY};
use crate::stencil::fill::{for_each_band, CounterRows};
use crate::stencil::open_edges::{open_edges, push_piece_edges, EdgeRec, Segment};
use crate::stencil::pieces::{volume_polygons, Piece, Window};
use crate::stencil::span::StripExtents;
use crate::stencil::tile_class::{PiecePlane, Side};
use crate::volume_buffer::{headroom, VolumeBuffer, VolumeMethod, VolumeRange};
use crate::{Error, Result, StencilBits, StencilStats, StencilTarget, StencilTests};
use glam::Mat4;

/// Options of a [`HierarchicalStencil`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HierarchicalOptions {
    /// Tile size of the classification and of `Smin`/`Smax` (8×8 in \[Aila04\]).
    pub tile: TileSize,
    /// Counter width of the per-pixel stencil and the tile offsets.
    pub bits: StencilBits,
    /// The full-shadow bit [Aila04 §4.3.2]: faster; may differ from brute force
    /// where rounding gave some volume a negative count, and in 8-bit mode where
    /// the wide count is a non-zero multiple of 256 (see the module documentation).
    pub full_shadow: bool,
}

impl Default for HierarchicalOptions {
    fn default() -> Self {
        HierarchicalOptions {
            tile: TileSize::T8,
            bits: StencilBits::Eight,
            full_shadow: true,
        }
    }
}

/// A tile's classification over a frame ([`HierarchicalStencil::tile_classes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TileClass {
    /// No written pixel (skipped by every volume).
    Background,
    /// Never a boundary tile, and lit at the end.
    Lit,
    /// Never a boundary tile, and in shadow at the end (FS bit, or a uniform non-zero value).
    Shadow,
    /// A boundary tile of at least one volume (per-pixel work).
    Boundary,
}

/// A tile's stage-1 state, kept small (16 bytes) because stage 1 visits
/// millions of (piece, tile) pairs: the depth box (from the eye target, per
/// draw; `zmax` is [`BACKGROUND`] for tiles every volume skips — no written
/// pixel, or the FS bit set) and the PSV record of the volume being drawn.
#[derive(Clone, Copy, Debug, Default)]
struct Hot {
    zmin: f32,
    zmax: f32,
    /// `stamp << 1 | boundary`: the volume (1-based) of the last visit and the boundary flag.
    psv: u32,
    /// Count at the sample pixel.
    count: i32,
}

/// A tile's hierarchical stencil entry and its fixed data.
#[derive(Clone, Copy, Debug, Default)]
struct Cold {
    /// Written (non-background) pixels of the tile.
    written: u32,
    /// In-target pixels of the tile.
    area: u32,
    sample_x: u32,
    sample_y: u32,
    /// Offset added to every per-pixel counter of the tile (wrapped to 8 bits in 8-bit mode).
    base: i32,
    /// Smallest and largest per-pixel counter over the written pixels (without `base`).
    smin: i32,
    smax: i32,
    fs: bool,
    ever_boundary: bool,
}

/// Pieces set up before the bands process them (whole volumes; a batch is one
/// parallel pass, so fewer, larger batches than brute force's).
const H_PIECE_BATCH: usize = 1 << 16;

/// Pixel rows per band (the unit of parallel work and of the top level).
/// Street views crowd most volume pieces into the few rows around the
/// horizon: with 64 rows one band there took half the pass (city street
/// 800×600, 5.1 of 10.4 ms), with 32 the two threads balance.
const BAND_ROWS: usize = 32;

/// Tiles per block of the coarse level: a block holds the smallest `zmin` and
/// largest `zmax` of up to this many tiles of one tile row, so one test can
/// dismiss a piece over all of them.
const BLOCK: usize = 8;

/// A hierarchical stencil buffer [Aila04 §4.1] with the two-stage volume pass.
#[derive(Clone, Debug)]
pub struct HierarchicalStencil {
    options: HierarchicalOptions,
    pixels: StencilTarget,
    hot: Vec<Hot>,
    cold: Vec<Cold>,
    /// Per tile row, per block of [`BLOCK`] tiles: `[min zmin, max zmax]` of its
    /// tiles that volumes visit (`[+∞, BACKGROUND]` when none).
    blocks: Vec<[f32; 2]>,
    /// The same per band of [`BAND_ROWS`] pixel rows: the level above `blocks`.
    bands: Vec<[f32; 2]>,
    /// Per band, runs of its `bands` entries in constant time.
    band_runs: DepthRanges,
    tiles_x: u32,
    tiles_y: u32,
    shift: u32,
    /// The volume pass's lists, kept between draws (empty in between).
    work: Work,
}

/// The lists one [`HierarchicalStencil::draw_volumes`] call fills, kept so
/// that a steady frame allocates nothing. Lists of references are kept empty
/// between calls ([`recycle`]).
#[derive(Default)]
struct Work {
    jobs: Vec<(Mat4, &'static VolumeRange, Window)>,
    /// One per set-up chunk.
    setups: Vec<SetUp>,
    vols: Vec<VolumeJob>,
    pieces: Vec<(&'static Piece, &'static Shape)>,
    open: Vec<&'static Segment>,
    piece_bins: Bins,
    open_bins: Bins,
    /// Per band: its scratch and its counters.
    bands: Vec<(Scratch, StencilStats)>,
}

impl Clone for Work {
    /// Scratch only: a clone starts with empty lists.
    fn clone(&self) -> Self {
        Work::default()
    }
}

impl std::fmt::Debug for Work {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Work").finish_non_exhaustive()
    }
}

/// An empty vector of `U` in `v`'s allocation. For element types of one
/// layout (references differing only in lifetime) the standard library's
/// in-place collection keeps the buffer, so lists of references into
/// per-call data keep their capacity from call to call.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().map(|_| unreachable!("empty")).collect()
}

/// Per-volume pieces and open edges inside one batch.
#[derive(Clone)]
struct VolumeJob {
    job: u32,
    pieces: std::ops::Range<usize>,
    open: std::ops::Range<usize>,
    zfail: bool,
    /// Smallest and largest vertex depth of its pieces: every point of every
    /// piece lies in between.
    zlo: f64,
    zhi: f64,
    /// Pixel columns its pieces can reach (inclusive).
    x0: i64,
    x1: i64,
}

impl HierarchicalStencil {
    /// A cleared target.
    ///
    /// # Errors
    /// [`Error::InvalidSize`] when a side is 0 or too large.
    pub fn new(width: u32, height: u32, options: HierarchicalOptions) -> Result<Self> {
        let pixels = StencilTarget::new(width, height, options.bits)?;
        let shift = options.tile.pixels().trailing_zeros();
        let (tiles_x, tiles_y) = (width.div_ceil(1 << shift), height.div_ceil(1 << shift));
        let n = (tiles_x * tiles_y) as usize;
        Ok(HierarchicalStencil {
            options,
            pixels,
            hot: vec![Hot::default(); n],
            cold: vec![Cold::default(); n],
            blocks: vec![EMPTY; tiles_y as usize * blocks_per_row(tiles_x)],
            bands: vec![
                EMPTY;
                height.div_ceil(BAND_ROWS as u32) as usize * blocks_per_row(tiles_x)
            ],
            band_runs: DepthRanges::default(),
            tiles_x,
            tiles_y,
            shift,
            work: Work::default(),
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.pixels.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.pixels.height()
    }

    /// The options it was made with.
    pub fn options(&self) -> HierarchicalOptions {
        self.options
    }

    /// Tiles across and down.
    pub fn tile_counts(&self) -> (u32, u32) {
        (self.tiles_x, self.tiles_y)
    }

    /// Clears every counter, offset and FS bit.
    pub fn clear(&mut self) {
        self.pixels.clear();
        self.cold.fill(Cold::default());
    }

    fn wrap(&self, v: i32) -> i32 {
        wrap(self.options.bits, v)
    }

    fn cold_of(&self, x: u32, y: u32) -> &Cold {
        &self.cold[((y >> self.shift) * self.tiles_x + (x >> self.shift)) as usize]
    }

    /// The stencil value at `(x, y)`: the tile's offset plus the pixel's counter
    /// (wrapped to `0..=255` in 8-bit mode). Meaningless in tiles whose FS bit
    /// is set ([`HierarchicalStencil::full_shadow`]): later volumes skip them.
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn value(&self, x: u32, y: u32) -> i32 {
        let p = self.pixels.value(x, y);
        self.wrap(self.cold_of(x, y).base.wrapping_add(p))
    }

    /// Whether the tile containing pixel `(x, y)` has its FS bit set.
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn full_shadow(&self, x: u32, y: u32) -> bool {
        assert!(x < self.width() && y < self.height());
        self.cold_of(x, y).fs
    }

    /// Whether pixel `(x, y)` is in shadow: FS bit, or a non-zero value.
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn nonzero(&self, x: u32, y: u32) -> bool {
        self.full_shadow(x, y) || self.value(x, y) != 0
    }

    /// Per tile (row-major) its class over everything drawn since the last clear
    /// (the written pixels are those of the eye target of the last draw).
    pub fn tile_classes(&self) -> Vec<TileClass> {
        let mut out = Vec::new();
        self.tile_classes_into(&mut out);
        out
    }

    /// [`HierarchicalStencil::tile_classes`] into `out` (cleared first).
    pub fn tile_classes_into(&self, out: &mut Vec<TileClass>) {
        out.clear();
        out.extend(self.cold.iter().map(|t| {
            if t.written == 0 {
                TileClass::Background
            } else if t.ever_boundary {
                TileClass::Boundary
            } else if t.fs || self.wrap(t.base.wrapping_add(t.smin)) != 0 {
                TileClass::Shadow
            } else {
                TileClass::Lit
            }
        }));
    }

    /// The mask resolve [Aila04 §4.1.2]: per pixel (row-major, row 0 at the top)
    /// whether it is in shadow, false on `eye`'s background pixels; per-pixel
    /// counters are read only in tiles with `Smin ≠ Smax` (and no FS bit). Adds
    /// the modeled reads to `stats`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `eye` has another size.
    pub fn resolve(
        &self,
        eye: &DepthTarget,
        out: &mut Vec<bool>,
        stats: &mut StencilStats,
    ) -> Result<()> {
        let (w, h) = (self.width(), self.height());
        if (eye.width(), eye.height()) != (w, h) {
            return Err(Error::SizeMismatch {
                expected: (eye.width(), eye.height()),
                got: (w, h),
            });
        }
        let s = counter_bytes(self.options.bits);
        out.clear();
        out.resize((w * h) as usize, false);
        stats.tile_bytes += u64::from(self.tiles_x * self.tiles_y) * (3 * s + 1);
        // Tile rows in parallel: each writes its own pixel rows.
        let rows = (w as usize) << self.shift;
        let row = |(ty, r): (usize, &mut [bool])| self.resolve_tile_row(eye, ty as u32, r);
        #[cfg(feature = "parallel")]
        let read: u64 = {
            use rayon::prelude::*;
            out.par_chunks_mut(rows).enumerate().map(row).sum()
        };
        #[cfg(not(feature = "parallel"))]
        let read: u64 = out.chunks_mut(rows).enumerate().map(row).sum();
        stats.pixel_bytes += read * s;
        Ok(())
    }

    /// [`HierarchicalStencil::resolve`] of tile row `ty` into `out`, its pixel
    /// rows (row-major); returns the per-pixel counters read.
    fn resolve_tile_row(&self, eye: &DepthTarget, ty: u32, out: &mut [bool]) -> u64 {
        let (w, h) = (self.width(), self.height());
        let size = 1u32 << self.shift;
        let y0 = ty * size;
        let mut read = 0;
        for tx in 0..self.tiles_x {
            let t = &self.cold[(ty * self.tiles_x + tx) as usize];
            let uniform = t.fs || t.smin == t.smax;
            let value = t.fs || self.wrap(t.base.wrapping_add(t.smin)) != 0;
            if uniform && !value {
                continue;
            }
            for y in y0..(y0 + size).min(h) {
                let line = &mut out[((y - y0) * w) as usize..][..w as usize];
                for x in tx * size..((tx + 1) * size).min(w) {
                    if eye.depth[eye.layout.pixel_index(x, y)] == BACKGROUND {
                        continue;
                    }
                    line[x as usize] = if uniform {
                        value
                    } else {
                        read += 1;
                        self.wrap(t.base.wrapping_add(self.pixels.value(x, y))) != 0
                    };
                }
            }
        }
        read
    }

    /// Draws shadow volumes as [`StencilTarget::draw_volumes`] does (same
    /// counting rules per [`VolumeMethod`], same `tests`), hierarchically: with
    /// the FS bit off the values equal the brute-force pass's at every written
    /// pixel. Counters: `pixels_processed` = tile area × boundary tiles summed
    /// over volumes; `h_fragments`, `stencil_updates`, `pixels_touched` from the
    /// per-pixel work; `tile_tests`, `tiles_*`, `pixel_bytes`, `tile_bytes`.
    ///
    /// # Errors
    /// As [`StencilTarget::draw_volumes`].
    pub fn draw_volumes(
        &mut self,
        eye: &DepthTarget,
        volumes: &[(Mat4, &VolumeRange)],
        buf: &VolumeBuffer,
        tests: StencilTests,
        stats: &mut StencilStats,
    ) -> Result<()> {
        let (width, height) = (self.width(), self.height());
        let mut work = std::mem::take(&mut self.work);
        let mut jobs = recycle(std::mem::take(&mut work.jobs));
        let mut st = self
            .pixels
            .prepare_into(eye, volumes, buf, tests, &mut jobs)?;
        headroom(&mut jobs);
        self.tile_bounds(eye);
        let geo = Geometry {
            width,
            height,
            shift: self.shift,
            tiles_x: self.tiles_x,
            options: self.options,
        };
        let vp = eye.vp;
        let Work {
            setups,
            vols,
            pieces: piece_list,
            open: open_list,
            piece_bins,
            open_bins,
            bands,
            ..
        } = &mut work;
        setups.resize_with(SETUP_CHUNKS, SetUp::default);
        // Batches of whole volumes of about `H_PIECE_BATCH` triangles; each batch
        // is set up in parallel chunks (in volume order), then both stages run.
        let mut next = 0;
        while next < jobs.len() {
            let (first, mut end, mut est) = (next, next, 0usize);
            while end < jobs.len() && est < H_PIECE_BATCH {
                est += jobs[end].1.index_count as usize / 3;
                end += 1;
            }
            next = end;
            // Chunks of about equal triangle counts: even work, and lists of
            // about equal length.
            let mut bounds = [end; SETUP_CHUNKS + 1];
            bounds[0] = first;
            let (mut acc, mut k) = (0usize, 1usize);
            for (j, job) in jobs.iter().enumerate().take(end).skip(first) {
                while k < SETUP_CHUNKS && acc >= k * est / SETUP_CHUNKS {
                    bounds[k] = j;
                    k += 1;
                }
                acc += job.1.index_count as usize / 3;
            }
            let setup = |(k, out): (usize, &mut SetUp)| {
                set_up(&jobs, bounds[k]..bounds[k + 1], buf, &vp, out)
            };
            #[cfg(feature = "parallel")]
            {
                use rayon::prelude::*;
                setups.par_iter_mut().enumerate().for_each(setup);
            }
            #[cfg(not(feature = "parallel"))]
            setups.iter_mut().enumerate().for_each(setup);
            keep_headroom(setups);
            // One index space over the chunks' pieces and open edges.
            vols.clear();
            let mut pieces: Vec<(&Piece, &Shape)> = recycle(std::mem::take(piece_list));
            let mut open: Vec<&Segment> = recycle(std::mem::take(open_list));
            for p in setups.iter() {
                let (dp, dopen) = (pieces.len(), open.len());
                vols.extend(p.vols.iter().map(|v| VolumeJob {
                    pieces: v.pieces.start + dp..v.pieces.end + dp,
                    open: v.open.start + dopen..v.open.end + dopen,
                    ..v.clone()
                }));
                pieces.extend(p.pieces.iter().zip(&p.shapes));
                open.extend(p.open.iter());
            }
            headroom(vols);
            headroom(&mut pieces);
            headroom(&mut open);
            let lists = (&vols[..], &pieces[..], &open[..]);
            self.flush(
                eye,
                &geo,
                &jobs,
                lists,
                (piece_bins, open_bins, bands),
                &mut st,
            );
            (*piece_list, *open_list) = (recycle(pieces), recycle(open));
        }
        work.jobs = recycle(jobs);
        self.work = work;
        self.pixels.touched_count += st.pixels_touched;
        stats.add(&st);
        Ok(())
    }

    /// Recomputes every tile's depth box, sample pixel and the block level from
    /// `eye`, and resets the PSV records. Tiles with no written pixel or the FS
    /// bit get `zmax = BACKGROUND`, which every volume's depth window rejects.
    fn tile_bounds(&mut self, eye: &DepthTarget) {
        let (w, h, shift, tx_n) = (
            self.width(),
            self.height(),
            self.shift,
            self.tiles_x as usize,
        );
        let size = 1u32 << shift;
        let nb = blocks_per_row(self.tiles_x);
        // The eye target's tiles are ours: its exact incremental bounds
        // and background counts are the tiles' depth boxes and written
        // counts, and a tile's pixels are contiguous in row order.
        let same_tiles = eye.layout.shift == shift;
        let row = |ty: u32, hot: &mut [Hot], cold: &mut [Cold], blocks: &mut [[f32; 2]]| {
            for (tx, (t, c)) in hot.iter_mut().zip(cold.iter_mut()).enumerate() {
                let tx = tx as u32;
                let (mut zmin, mut zmax, mut written) = (f32::INFINITY, BACKGROUND, 0u32);
                let (mut sx, mut sy) = (tx * size, ty * size);
                let (x1, y1) = (((tx + 1) * size).min(w), ((ty + 1) * size).min(h));
                if same_tiles {
                    let i = eye.layout.tile_index(tx, ty);
                    let tb = eye.tiles[i];
                    written = (x1 - sx) * (y1 - sy) - tb.background;
                    if written > 0 {
                        (zmin, zmax) = (tb.zmin, tb.zmax);
                    }
                    if tb.background > 0 && written > 0 {
                        let tp = eye.layout.tile_pixels();
                        let pixels = &eye.depth[i * tp..(i + 1) * tp];
                        if let Some(k) = pixels.iter().position(|&d| d != BACKGROUND) {
                            sx += k as u32 & (size - 1);
                            sy += (k >> shift) as u32;
                        }
                    }
                } else {
                    for y in ty * size..y1 {
                        for x in tx * size..x1 {
                            let d = eye.depth[eye.layout.pixel_index(x, y)];
                            if d != BACKGROUND {
                                if written == 0 {
                                    (sx, sy) = (x, y);
                                }
                                written += 1;
                                zmin = zmin.min(d);
                                zmax = zmax.max(d);
                            }
                        }
                    }
                }
                c.written = written;
                c.area = (x1 - tx * size) * (y1 - ty * size);
                c.sample_x = sx;
                c.sample_y = sy;
                *t = Hot {
                    zmin,
                    zmax: if c.fs { BACKGROUND } else { zmax },
                    psv: 0,
                    count: 0,
                };
            }
            for (b, out) in blocks.iter_mut().enumerate() {
                let ts = &hot[b * BLOCK..((b + 1) * BLOCK).min(hot.len())];
                *out = ts
                    .iter()
                    .filter(|t| t.zmax >= 0.0)
                    .fold(EMPTY, |r, t| union(r, [t.zmin, t.zmax]));
            }
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            self.hot
                .par_chunks_mut(tx_n)
                .zip(self.cold.par_chunks_mut(tx_n))
                .zip(self.blocks.par_chunks_mut(nb))
                .enumerate()
                .for_each(|(ty, ((hot, cold), blocks))| row(ty as u32, hot, cold, blocks));
        }
        #[cfg(not(feature = "parallel"))]
        for (ty, ((hot, cold), blocks)) in self
            .hot
            .chunks_mut(tx_n)
            .zip(self.cold.chunks_mut(tx_n))
            .zip(self.blocks.chunks_mut(nb))
            .enumerate()
        {
            row(ty as u32, hot, cold, blocks);
        }
        let rows_per_band = BAND_ROWS >> shift;
        for (k, out) in self.bands.chunks_mut(nb).enumerate() {
            let rows = &self.blocks[k * rows_per_band * nb..]
                [..(rows_per_band * nb).min(self.blocks.len() - k * rows_per_band * nb)];
            for (b, o) in out.iter_mut().enumerate() {
                *o = rows.chunks(nb).fold(EMPTY, |a, r| union(a, r[b]));
            }
        }
        self.band_runs.build(&self.bands, nb);
    }

    /// Runs both stages for the batch's volumes, bands of 64 rows in parallel.
    #[allow(clippy::type_complexity)]
    fn flush(
        &mut self,
        eye: &DepthTarget,
        geo: &Geometry,
        jobs: &[(Mat4, &VolumeRange, Window)],
        (vols, pieces, open): (&[VolumeJob], &[(&Piece, &Shape)], &[&Segment]),
        (piece_bins, open_bins, band_work): (
            &mut Bins,
            &mut Bins,
            &mut Vec<(Scratch, StencilStats)>,
        ),
        st: &mut StencilStats,
    ) {
        let band_rows = BAND_ROWS;
        let rows_per_band = band_rows >> self.shift as usize;
        let tiles_per_band = rows_per_band * self.tiles_x as usize;
        let blocks_per_band = rows_per_band * blocks_per_row(self.tiles_x);
        let px_chunk = BAND_ROWS * (self.width().div_ceil(8) as usize) * 8;
        let (self_bands, band_runs) = (&self.bands, &self.band_runs);
        let nbands = self.height().div_ceil(band_rows as u32) as usize;
        let piece_rows = || piece_bins.fill(nbands, pieces.iter().map(|(p, _)| (p.y0, p.y1)));
        let open_rows = || open_bins.fill(nbands, open.iter().map(|e| (e.y0, e.y1)));
        // The two binnings are independent (and precede every band).
        #[cfg(feature = "parallel")]
        rayon::join(piece_rows, open_rows);
        #[cfg(not(feature = "parallel"))]
        {
            piece_rows();
            open_rows();
        }
        let (piece_bins, open_bins) = (&*piece_bins, &*open_bins);
        band_work.resize_with(nbands, Default::default);
        let run = |k: usize,
                   counters: CountersMut<'_>,
                   parts: BandParts<'_>,
                   (scratch, bst): &mut (Scratch, StencilStats)| {
            let y0 = (k * band_rows) as i64;
            let band_blocks =
                &self_bands[k * blocks_per_row(geo.tiles_x)..][..blocks_per_row(geo.tiles_x)];
            let mut band = HBand {
                px: CounterRows {
                    counters,
                    touched: parts.touched,
                    width: geo.width,
                    height: geo.height,
                    y0,
                    y1: (y0 + band_rows as i64).min(i64::from(geo.height)) - 1,
                    base: k * px_chunk,
                },
                hot: parts.hot,
                cold: parts.cold,
                blocks: parts.blocks,
                band_blocks,
                band_range: band_blocks.iter().fold(EMPTY, |a, &b| union(a, b)),
                band_runs: (band_runs, k),
                tile0: k * tiles_per_band,
                ty0: (k * rows_per_band) as i64,
                geo,
            };
            *bst = StencilStats::default();
            let (mut bp, mut bo) = (piece_bins.band(k), open_bins.band(k));
            for v in vols {
                let win = &jobs[v.job as usize].2;
                // This band's pieces and open edges of the volume (ascending indices).
                let np = bp.partition_point(|&i| (i as usize) < v.pieces.end);
                let no = bo.partition_point(|&i| (i as usize) < v.open.end);
                let share = BandShare {
                    piece_ids: &bp[..np],
                    pieces,
                    open_ids: &bo[..no],
                    open,
                };
                band.volume(eye, v, win, share, scratch, bst);
                (bp, bo) = (&bp[np..], &bo[no..]);
            }
        };
        let (touched, hot, cold, blocks) = (
            &mut self.pixels.touched,
            &mut self.hot,
            &mut self.cold,
            &mut self.blocks,
        );
        let (px, tiles) = (px_chunk, tiles_per_band);
        macro_rules! run_with {
            ($c:expr, $counters:path) => {
                for_each_band!(
                    |(k, (((((c, touched), hot), cold), blocks), w))| {
                        let parts = BandParts {
                            touched,
                            hot,
                            cold,
                            blocks,
                        };
                        run(k, $counters(c), parts, &mut w[0])
                    },
                    $c => px,
                    touched => px,
                    hot => tiles,
                    cold => tiles,
                    blocks => blocks_per_band,
                    band_work => 1,
                )
            };
        }
        match &mut self.pixels.counters {
            Counters::Eight(c) => run_with!(c, CountersMut::Eight),
            Counters::Wide(c) => run_with!(c, CountersMut::Wide),
        }
        for (_, p) in band_work.iter() {
            st.add(p);
        }
    }
}

/// Indices of items (pieces, open edges) per band of [`BAND_ROWS`] rows, in
/// ascending order: a band walks only what reaches its rows.
#[derive(Default)]
struct Bins {
    start: Vec<usize>,
    ids: Vec<u32>,
    fill: Vec<usize>,
}

impl Bins {
    /// Bins items with inclusive pixel rows `(y0, y1)` into `n` bands (in the
    /// existing buffers).
    fn fill(&mut self, n: usize, rows: impl Iterator<Item = (i64, i64)> + Clone) {
        let band = |y: i64| (y.max(0) as usize / BAND_ROWS).min(n.saturating_sub(1));
        let count = &mut self.start;
        count.clear();
        count.resize(n + 1, 0);
        for (y0, y1) in rows.clone() {
            if y1 >= 0 && y0 <= y1 {
                for k in band(y0)..=band(y1) {
                    count[k + 1] += 1;
                }
            }
        }
        for k in 0..n {
            count[k + 1] += count[k];
        }
        let fill = &mut self.fill;
        fill.clone_from(count);
        let ids = &mut self.ids;
        ids.clear();
        ids.resize(count[n], 0);
        headroom(ids);
        for (i, (y0, y1)) in rows.enumerate() {
            if y1 >= 0 && y0 <= y1 {
                for k in band(y0)..=band(y1) {
                    ids[fill[k]] = i as u32;
                    fill[k] += 1;
                }
            }
        }
    }

    fn band(&self, k: usize) -> &[u32] {
        &self.ids[self.start[k]..self.start[k + 1]]
    }
}

/// Chunks a batch's set-up is split into (for the threads to share).
const SETUP_CHUNKS: usize = 16;

/// Set-up pieces and open edges of some volumes.
#[derive(Default)]
struct SetUp {
    pieces: Vec<Piece>,
    /// Per piece: its plane and strip extents ([`Shape`]).
    shapes: Vec<Shape>,
    open: Vec<Segment>,
    vols: Vec<VolumeJob>,
    /// Directed edges of one volume's pieces (scratch).
    edges: Vec<EdgeRec>,
}

/// Keeps headroom in every chunk's lists ([`headroom`]). Each chunk's lists
/// grow only past the longest it has held: a motion that repeats (a light
/// orbiting, a camera path run back and forth) allocates nothing once each
/// chunk has seen its part of it, and a chunk's list holds at most twice the
/// longest it has held. (Giving every chunk the capacity of the
/// longest, as before, made a scene of one large volume, which one chunk
/// sets up, hold 16 copies of its pieces' room: 975 MB against brute force's
/// 103 MB on a 125k-triangle open mesh.)
fn keep_headroom(setups: &mut [SetUp]) {
    for p in setups.iter_mut() {
        headroom(&mut p.pieces);
        headroom(&mut p.shapes);
        headroom(&mut p.open);
        headroom(&mut p.vols);
        headroom(&mut p.edges);
    }
}

/// Sets up the volumes `jobs[range]` into `out` (cleared first): their fan
/// pieces (as the brute-force pass), zp+ near-cap fans, and open edges.
fn set_up(
    jobs: &[(Mat4, &VolumeRange, Window)],
    range: std::ops::Range<usize>,
    buf: &VolumeBuffer,
    vp: &crate::setup::Viewport,
    out: &mut SetUp,
) {
    out.pieces.clear();
    out.open.clear();
    out.vols.clear();
    let mut edges = std::mem::take(&mut out.edges);
    let mut s = Setup {
        facing: None,
        clipped: false,
        vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
        len: 0,
    };
    for j in range {
        let (m, range, _) = &jobs[j];
        let zfail = range.method == VolumeMethod::ZFail;
        let (p0, o0) = (out.pieces.len(), out.open.len());
        edges.clear();
        volume_polygons(*m, range, buf, vp, &mut s, |poly, zfail| {
            push_h_pieces(poly, zfail, j as u32, &mut out.pieces, &mut edges);
        });
        open_edges(&mut edges, &mut out.open);
        let ps = &out.pieces[p0..];
        let sub = crate::setup::SUBPIXEL;
        out.vols.push(VolumeJob {
            job: j as u32,
            pieces: p0..out.pieces.len(),
            open: o0..out.open.len(),
            zfail,
            zlo: ps.iter().map(|p| p.tri.zlo).fold(f64::INFINITY, f64::min),
            zhi: ps
                .iter()
                .map(|p| p.tri.zhi)
                .fold(f64::NEG_INFINITY, f64::max),
            x0: ps
                .iter()
                .map(|p| p.tri.xmin)
                .min()
                .unwrap_or(0)
                .div_euclid(sub)
                - 1,
            x1: ps
                .iter()
                .map(|p| p.tri.xmax)
                .max()
                .unwrap_or(-sub)
                .div_euclid(sub)
                + 1,
        });
    }
    out.edges = edges;
    out.shapes.clear();
    out.shapes.extend(out.pieces.iter().map(|p| Shape {
        plane: PiecePlane::new(&p.tri),
        strips: StripExtents::new(&p.tri),
    }));
}

/// What stage 1 reads of a piece in every band it reaches, set up once with
/// the piece: its depth plane and its strip extents.
struct Shape {
    plane: PiecePlane,
    strips: StripExtents,
}

/// Blocks of [`BLOCK`] tiles per tile row.
fn blocks_per_row(tiles_x: u32) -> usize {
    (tiles_x as usize).div_ceil(BLOCK)
}

/// Target constants the bands share.
struct Geometry {
    width: u32,
    height: u32,
    shift: u32,
    tiles_x: u32,
    options: HierarchicalOptions,
}

/// Per-band scratch reused across volumes: tiles reached, (piece, tile) pairs for stage 2.
#[derive(Default)]
struct Scratch {
    touched: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    /// Per block column of the band: the piece's side over it (band level).
    sides: Vec<Option<Side>>,
}

/// One band's share of the per-pixel flags and of the tile arrays.
struct BandParts<'a> {
    touched: &'a mut [u8],
    hot: &'a mut [Hot],
    cold: &'a mut [Cold],
    blocks: &'a mut [[f32; 2]],
}

/// One band of 64 pixel rows: its per-pixel counters and its tiles.
struct HBand<'a, 'g> {
    px: CounterRows<'a>,
    hot: &'a mut [Hot],
    cold: &'a mut [Cold],
    blocks: &'a mut [[f32; 2]],
    /// The band level: per block column `[min zmin, max zmax]` over the band.
    band_blocks: &'a [[f32; 2]],
    /// `[min zmin, max zmax]` over the whole band.
    band_range: [f32; 2],
    /// Runs of `band_blocks` (the tables and this band's row in them).
    band_runs: (&'a DepthRanges, usize),
    /// Global index of `hot[0]`.
    tile0: usize,
    /// First tile row of the band.
    ty0: i64,
    geo: &'g Geometry,
}

/// One volume's share of a band: the indices (ascending) of its pieces and
/// open edges that reach the band's rows, into the batch's `pieces` and `open`.
#[derive(Clone, Copy)]
struct BandShare<'a, 'p> {
    piece_ids: &'a [u32],
    pieces: &'a [(&'p Piece, &'p Shape)],
    open_ids: &'a [u32],
    open: &'a [&'p Segment],
}

/// What every stage of one volume in one band reads.
struct VolumeWindow<'w> {
    /// The volume's window.
    win: &'w Window,
    /// The volume's stamp in `Hot::psv` (bit 0: boundary).
    stamp: u32,
    /// Pixel rows of the band inside the window.
    rows: (i64, i64),
    /// The window's depth range, clamped to written depths.
    depth: (f32, f32),
}

/// Inclusive pixel rectangle of tile `idx` (global index) inside the target.
fn tile_rect(g: &Geometry, idx: usize) -> Rect {
    let (tx, ty) = (
        (idx % g.tiles_x as usize) as i64,
        (idx / g.tiles_x as usize) as i64,
    );
    let s = 1i64 << g.shift;
    Rect {
        x0: tx * s,
        x1: (tx * s + s).min(i64::from(g.width)) - 1,
        y0: ty * s,
        y1: (ty * s + s).min(i64::from(g.height)) - 1,
    }
}

impl HBand<'_, '_> {
    /// Both stages of one volume (`v`, in its window `win`) on this band's rows.
    fn volume(
        &mut self,
        eye: &DepthTarget,
        v: &VolumeJob,
        win: &Window,
        share: BandShare<'_, '_>,
        sc: &mut Scratch,
        st: &mut StencilStats,
    ) {
        let BandShare {
            piece_ids,
            pieces,
            open_ids,
            open,
        } = share;
        let (ya, yb) = (self.px.y0.max(win.y0), self.px.y1.min(win.y1));
        if ya > yb {
            return;
        }
        sc.touched.clear();
        sc.pairs.clear();
        // Written depths lie in [0, 1]: skipped tiles (zmax = BACKGROUND) fail `zmax ≥ dlo`.
        let (dlo, dhi) = (win.dlo.max(0.0), win.dhi);
        // The whole volume against the band's tiles under it: dismissed when
        // all of it lies on its uncounted side (a zpass volume hidden behind
        // the visible surface).
        let range = self.depth_range(v.x0.max(win.x0), v.x1.min(win.x1));
        if dismissed(v.zfail, v.zlo, v.zhi, range, dlo, dhi) {
            return;
        }
        let vw = VolumeWindow {
            win,
            stamp: (v.job + 1) << 1,
            rows: (ya, yb),
            depth: (dlo, dhi),
        };
        // Stage 1: classify.
        let mut tests = 0u64;
        for &pi in piece_ids {
            let (p, shape) = pieces[pi as usize];
            tests += self.classify_piece(pi, p, shape, &vw, sc);
        }
        let sbytes = counter_bytes(self.geo.options.bits);
        st.tile_tests += tests;
        st.tile_bytes += tests * (8 + 2 * (sbytes + 1));
        self.mark_open_edges(open_ids.iter().map(|&i| open[i as usize]), &vw, v.zfail);
        self.mark_partial_tiles(&vw, sc);
        // Stage 2: per-pixel work in boundary tiles, then the tiles' counts.
        self.fill_boundary_tiles(eye, pieces, win, sc, st);
        self.update_tiles(eye, sc, st);
    }

    /// Stage 1 for one piece: the band level, the block level, then every tile
    /// the piece can count in: a tile whose depth box lies wholly on the piece's
    /// counted side, under a sample pixel the piece covers, counts `±1` at once;
    /// a tile the piece's plane crosses is marked for per-pixel work (and the
    /// pair kept for stage 2). Returns the tile tests made.
    #[inline(always)]
    fn classify_piece(
        &mut self,
        pi: u32,
        p: &Piece,
        shape: &Shape,
        vw: &VolumeWindow<'_>,
        sc: &mut Scratch,
    ) -> u64 {
        let g = self.geo;
        let fs_on = g.options.full_shadow;
        let shift = g.shift;
        let s = 1i64 << shift;
        let tiles_x = g.tiles_x as i64;
        let nb = blocks_per_row(g.tiles_x) as i64;
        let (win, stamp) = (vw.win, vw.stamp);
        let ((ya, yb), (dlo, dhi)) = (vw.rows, vw.depth);
        let mut tests = 0u64;
        let (y0, y1) = (p.y0.max(ya), p.y1.min(yb));
        if y0 > y1 {
            return tests;
        }
        // Columns of every pixel-centre rectangle the closed triangle can
        // meet, not only of the centres it covers: a sliver between two
        // rows of centres covers none, yet its edges may bound counted
        // pieces, so it must be classified like any other piece.
        let half = SUBPIXEL / 2;
        let px0 = (p.tri.xmin - half).div_euclid(SUBPIXEL).max(0);
        let px1 = ((p.tri.xmax - half).div_euclid(SUBPIXEL) + 1).min(i64::from(g.width) - 1);
        let (px0, px1) = (px0.max(win.x0), px1.min(win.x1));
        if px0 > px1 {
            return tests;
        }
        // The piece by its vertex depths, against the tiles of its columns.
        if dismissed(
            p.zfail,
            p.tri.zlo,
            p.tri.zhi,
            self.depth_range(px0, px1),
            dlo,
            dhi,
        ) {
            return tests;
        }
        let Shape { plane, strips } = shape;
        let narrow = px1 - px0 < 2 * s;
        let counted = if p.zfail { Side::Behind } else { Side::Front };
        let delta = if p.increment { 1 } else { -1 };
        // The band level: the piece over each block column's tiles in the
        // band; `None` where it can be dismissed (no visited tile, or the
        // uncounted side of all of them).
        let (lo, hi) = if narrow {
            (px0, px1)
        } else {
            match strips.extent(y0, y1) {
                Some((lo, hi)) => (lo.max(px0), hi.min(px1)),
                None => return tests,
            }
        };
        if lo > hi {
            return tests;
        }
        let (t0, t1) = (lo >> shift, hi >> shift);
        let (b0, b1) = (t0 / BLOCK as i64, t1 / BLOCK as i64);
        sc.sides.clear();
        let (wy0, wy1) = (
            ((y0 >> shift) * s).max(win.y0),
            ((y1 >> shift) * s + s - 1).min(win.y1),
        );
        // The pixels of tile columns `t0..=t1` in rows `y0..=y1`, inside the
        // window and the target.
        let columns = |t0: i64, t1: i64, y0: i64, y1: i64| Rect {
            x0: (t0 * s).max(win.x0),
            x1: (t1 * s + s - 1).min(win.x1).min(i64::from(g.width) - 1),
            y0,
            y1,
        };
        // First the whole span against the band's depth range.
        let span = columns(t0, t1, wy0, wy1);
        let [z0, z1] = self.band_range;
        if z1 < dlo || z0 > dhi {
            return tests;
        }
        match plane.side(span, z0, z1) {
            Side::Crossing => {}
            side if side == counted => {}
            _ => return tests,
        }
        let mut any = false;
        for b in b0..=b1 {
            let [bz0, bz1] = self.band_blocks[b as usize];
            let side = if bz1 < dlo || bz0 > dhi {
                None
            } else {
                let (bt0, bt1) = (
                    t0.max(b * BLOCK as i64),
                    t1.min(b * BLOCK as i64 + BLOCK as i64 - 1),
                );
                let rect = columns(bt0, bt1, wy0, wy1);
                match plane.side(rect, bz0, bz1) {
                    Side::Crossing => Some(Side::Crossing),
                    side if side == counted => Some(counted),
                    _ => None,
                }
            };
            any |= side.is_some();
            sc.sides.push(side);
        }
        if !any {
            return tests;
        }
        for ty in (y0 >> shift)..=(y1 >> shift) {
            let (lo, hi) = if narrow {
                (px0, px1)
            } else {
                let (ry0, ry1) = ((ty * s).max(y0), (ty * s + s - 1).min(y1));
                match strips.extent(ry0, ry1) {
                    Some((lo, hi)) => (lo.max(px0), hi.min(px1)),
                    None => continue,
                }
            };
            if lo > hi {
                continue;
            }
            // Rows of the tile row inside the window (the rectangles classified).
            let (wy0, wy1) = ((ty * s).max(win.y0), (ty * s + s - 1).min(win.y1));
            let (t0, t1) = (lo >> shift, hi >> shift);
            let row = (ty - self.ty0) * tiles_x;
            let brow = (ty - self.ty0) * nb;
            let mut b = t0 / BLOCK as i64;
            while b * BLOCK as i64 <= t1 {
                let (bt0, bt1) = (
                    t0.max(b * BLOCK as i64),
                    t1.min(b * BLOCK as i64 + BLOCK as i64 - 1),
                );
                b += 1;
                let Some(band_side) = sc.sides[(b - 1 - b0) as usize] else {
                    continue;
                };
                let [bz0, bz1] = self.blocks[(brow + b - 1) as usize];
                if bz1 < dlo || bz0 > dhi {
                    continue;
                }
                // The block level: the piece over these tiles' rectangles.
                let rect = columns(bt0, bt1, wy0, wy1);
                let block_side = if band_side == counted {
                    counted
                } else {
                    plane.side(rect, bz0, bz1)
                };
                if block_side != Side::Crossing && block_side != counted {
                    continue;
                }
                for tx in bt0..=bt1 {
                    let li = (row + tx) as usize;
                    let t = &mut self.hot[li];
                    if t.zmax < dlo || t.zmin > dhi {
                        continue;
                    }
                    tests += 1;
                    if t.psv & !1 != stamp {
                        t.psv = stamp;
                        t.count = 0;
                        sc.touched.push(li as u32);
                        let c = &mut self.cold[li];
                        if fs_on && all_shadowed(c, g.options.bits) {
                            c.fs = true;
                            t.zmax = BACKGROUND;
                            continue;
                        }
                    }
                    if t.psv & 1 != 0 {
                        sc.pairs.push((pi, li as u32));
                        continue;
                    }
                    let r = columns(tx, tx, wy0, wy1);
                    let side = if block_side == counted {
                        counted
                    } else {
                        match plane.side(r, t.zmin, t.zmax) {
                            Side::Crossing => match plane.side_clipped(&p.tri, r, t.zmin, t.zmax) {
                                Some(side) => side,
                                None => continue,
                            },
                            side => side,
                        }
                    };
                    if side == Side::Crossing {
                        t.psv |= 1;
                        sc.pairs.push((pi, li as u32));
                    } else if side == counted {
                        sc.pairs.push((pi, li as u32));
                        let c = &self.cold[li];
                        let (sx, sy) = (
                            i64::from(c.sample_x).clamp(r.x0, r.x1),
                            i64::from(c.sample_y).clamp(r.y0, r.y1),
                        );
                        if plane.covers(&p.tri, sx, sy) {
                            t.count += delta;
                        }
                    }
                }
            }
        }
        tests
    }

    /// Open edges of the volume's surface: a tile an open edge crosses, where
    /// the edge can bound a counted region, needs per-pixel work.
    fn mark_open_edges<'e>(
        &mut self,
        edges: impl Iterator<Item = &'e Segment>,
        vw: &VolumeWindow<'_>,
        zfail: bool,
    ) {
        let g = self.geo;
        let shift = g.shift;
        let s = 1i64 << shift;
        let (win, stamp) = (vw.win, vw.stamp);
        let (ya, yb) = vw.rows;
        for e in edges {
            let (y0, y1) = (e.y0.max(ya), e.y1.min(yb));
            if y0 > y1 {
                continue;
            }
            for ty in (y0 >> shift)..=(y1 >> shift) {
                let (ry0, ry1) = ((ty * s).max(y0), (ty * s + s - 1).min(y1));
                let Some((lo, hi)) = e.columns(ry0, ry1) else {
                    continue;
                };
                let (lo, hi) = (
                    lo.max(win.x0).max(0),
                    hi.min(win.x1).min(i64::from(g.width) - 1),
                );
                if lo > hi {
                    continue;
                }
                for tx in (lo >> shift)..=(hi >> shift) {
                    let idx = (ty as usize) * g.tiles_x as usize + tx as usize;
                    let rect = clip_rect(tile_rect(g, idx), win);
                    let t = &mut self.hot[idx - self.tile0];
                    if t.psv != stamp || t.zmax < 0.0 {
                        continue;
                    }
                    if e.marks(rect, t.zmin, t.zmax, zfail) {
                        t.psv |= 1;
                    }
                }
            }
        }
    }

    /// A count over a tile the window covers only in part needs per-pixel work.
    fn mark_partial_tiles(&mut self, vw: &VolumeWindow<'_>, sc: &Scratch) {
        let (g, win) = (self.geo, vw.win);
        for &li in &sc.touched {
            let r = tile_rect(g, li as usize + self.tile0);
            let t = &mut self.hot[li as usize];
            if t.zmax < 0.0 || t.psv & 1 != 0 || t.count == 0 {
                continue;
            }
            let inside = r.x0 >= win.x0
                && r.x1 <= win.x1
                && r.y0 >= win.y0
                && r.y1 <= win.y1
                && t.zmin >= win.dlo
                && t.zmax <= win.dhi;
            if !inside {
                t.psv |= 1;
            }
        }
    }

    /// Stage 2: the pieces of every boundary tile, pixel by pixel.
    fn fill_boundary_tiles(
        &mut self,
        eye: &DepthTarget,
        pieces: &[(&Piece, &Shape)],
        win: &Window,
        sc: &Scratch,
        st: &mut StencilStats,
    ) {
        let g = self.geo;
        let mut frag = StencilStats::default();
        // A piece's boundary tiles come in tile order: neighbours on one tile
        // row are filled as one rectangle (one set-up for the run).
        let mut run: Option<(u32, u32, Rect)> = None;
        let tiles_x = g.tiles_x as usize;
        for &(pi, li) in &sc.pairs {
            let t = &self.hot[li as usize];
            if t.psv & 1 == 0 || t.zmax < 0.0 {
                continue;
            }
            let idx = li as usize + self.tile0;
            let r = tile_rect(g, idx);
            if let Some((rpi, last, rect)) = &mut run {
                if *rpi == pi && li == *last + 1 && !idx.is_multiple_of(tiles_x) {
                    (*last, rect.x1) = (li, r.x1);
                    continue;
                }
                self.px
                    .fill_piece_within(eye, pieces[*rpi as usize].0, win, *rect, &mut frag);
            }
            run = Some((pi, li, r));
        }
        if let Some((pi, _, rect)) = run {
            self.px
                .fill_piece_within(eye, pieces[pi as usize].0, win, rect, &mut frag);
        }
        st.h_fragments += frag.pixels_processed;
        st.tiles_scanned += frag.tiles_scanned;
        st.stencil_updates += frag.stencil_updates;
        st.pixels_touched += frag.pixels_touched;
        st.pixel_bytes += pass_bytes(g.options.bits, frag.pixels_processed, frag.stencil_updates);
    }

    /// The hierarchical updates: per touched tile, its counters' range after
    /// per-pixel work, or its tile count (or full-shadow bit) otherwise.
    fn update_tiles(&mut self, eye: &DepthTarget, sc: &Scratch, st: &mut StencilStats) {
        let g = self.geo;
        let fs_on = g.options.full_shadow;
        let sbytes = counter_bytes(g.options.bits);
        for &li in &sc.touched {
            let idx = li as usize + self.tile0;
            st.tile_bytes += (sbytes + 1) + 2 * (3 * sbytes + 1);
            let t = self.hot[li as usize];
            if self.cold[li as usize].fs {
                continue;
            }
            if t.psv & 1 != 0 {
                st.tiles_boundary += 1;
                st.pixels_processed += u64::from(self.cold[li as usize].area);
                let (smin, smax, read) = self.pixel_range(eye, idx);
                st.pixel_bytes += read * sbytes;
                let c = &mut self.cold[li as usize];
                c.smin = smin;
                c.smax = smax;
                c.ever_boundary = true;
            } else if t.count != 0 {
                st.tiles_shadow += 1;
                let c = &mut self.cold[li as usize];
                if fs_on && t.count > 0 {
                    c.fs = true;
                    self.hot[li as usize].zmax = BACKGROUND;
                } else {
                    c.base = wrap(g.options.bits, c.base.wrapping_add(t.count));
                }
            } else {
                st.tiles_lit += 1;
            }
        }
    }

    /// `[min zmin, max zmax]` over the band's blocks that pixel columns
    /// `x0..=x1` reach.
    fn depth_range(&self, x0: i64, x1: i64) -> [f32; 2] {
        let w = i64::from(self.geo.width) - 1;
        let (x0, x1) = (x0.clamp(0, w), x1.clamp(0, w));
        let per = (BLOCK as i64) << self.geo.shift;
        let (b0, b1) = ((x0 / per) as usize, (x1 / per) as usize);
        if b0 > b1 {
            return EMPTY;
        }
        let (runs, k) = self.band_runs;
        runs.query(k, self.band_blocks, b0, b1)
    }

    /// `(Smin, Smax, pixels read)` of the per-pixel counters over tile `idx`'s written pixels.
    fn pixel_range(&self, eye: &DepthTarget, idx: usize) -> (i32, i32, u64) {
        let Rect { x0, x1, y0, y1 } = tile_rect(self.geo, idx);
        if self.geo.shift == 3 && eye.layout.shift == 3 && x1 - x0 == 7 && y1 - y0 == 7 {
            // A whole 8×8 tile: 64 contiguous depths and 64 contiguous counters.
            let d0 = eye.layout.pixel_index(x0 as u32, y0 as u32);
            let c0 = tiled_index(self.geo.width, x0 as u32, y0 as u32) - self.px.base;
            let depth: &[f32; 64] = eye.depth[d0..d0 + 64].try_into().expect("64 depths");
            return match &self.px.counters {
                CountersMut::Eight(c) => written_range(depth, &c[c0..c0 + 64], i32::from),
                CountersMut::Wide(c) => written_range(depth, &c[c0..c0 + 64], |v| v),
            };
        }
        let (mut lo, mut hi, mut n) = (i32::MAX, i32::MIN, 0u64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (x, y) = (x as u32, y as u32);
                if eye.depth[eye.layout.pixel_index(x, y)] == BACKGROUND {
                    continue;
                }
                let i = tiled_index(self.geo.width, x, y) - self.px.base;
                let v = match &self.px.counters {
                    CountersMut::Eight(c) => i32::from(c[i]),
                    CountersMut::Wide(c) => c[i],
                };
                lo = lo.min(v);
                hi = hi.max(v);
                n += 1;
            }
        }
        if n == 0 {
            (0, 0, 0)
        } else {
            (lo, hi, n)
        }
    }
}

/// `(min, max, count)` of the counters at the 64 pixels of one tile whose
/// depth is written (`(0, 0, 0)` when none is): branch-free, so it vectorizes.
#[inline(always)]
fn written_range<C: Copy>(depth: &[f32; 64], c: &[C], value: impl Fn(C) -> i32) -> (i32, i32, u64) {
    let c: &[C; 64] = c.try_into().expect("64 counters");
    let (mut lo, mut hi, mut n) = (i32::MAX, i32::MIN, 0u32);
    for k in 0..64 {
        let written = depth[k] != BACKGROUND;
        let v = value(c[k]);
        lo = lo.min(if written { v } else { i32::MAX });
        hi = hi.max(if written { v } else { i32::MIN });
        n += u32::from(written);
    }
    if n == 0 {
        (0, 0, 0)
    } else {
        (lo, hi, u64::from(n))
    }
}

/// Whether geometry whose every point has depth in `[zlo, zhi]` lies wholly on
/// the uncounted side of tiles with written depths in `range` (behind them for
/// zpass and zp+, in front for zfail), or misses the depth window `[dlo, dhi]`
/// of every such tile: its fragments then change no counter there and no edge
/// of it can bound a counted piece (`open_edges.rs`). The f64 fragment depth
/// errs by less than `2⁻⁵⁰` relative inside the piece, far inside the `2⁻⁴⁰`
/// widening; rounding to f32 is monotone.
fn dismissed(zfail: bool, zlo: f64, zhi: f64, range: [f32; 2], dlo: f32, dhi: f32) -> bool {
    let [zmin, zmax] = range;
    if zmax < dlo || zmin > dhi {
        return true;
    }
    const W: f64 = 1.0 / 1_099_511_627_776.0;
    if zfail {
        ((zlo - zlo.abs() * W) as f32) > zmax
    } else {
        ((zhi + zhi.abs() * W) as f32) <= zmin
    }
}

/// `v` wrapped to the counter width.
fn wrap(bits: StencilBits, v: i32) -> i32 {
    match bits {
        StencilBits::Eight => v & 0xFF,
        StencilBits::Wide => v,
    }
}

/// Whether every written pixel of `t` is already in shadow (`Smin > Sclear`,
/// [Aila04 §4.3.2]): wide counters all positive; 8-bit counters all non-zero,
/// known here only for a uniform tile.
fn all_shadowed(t: &Cold, bits: StencilBits) -> bool {
    match bits {
        StencilBits::Wide => t.base.wrapping_add(t.smin) > 0,
        StencilBits::Eight => t.smin == t.smax && wrap(bits, t.base.wrapping_add(t.smin)) != 0,
    }
}

/// A tile's pixel rectangle clipped to the window's.
fn clip_rect(r: Rect, win: &Window) -> Rect {
    r.intersect(win.rect())
}

/// Appends the fan pieces of a snapped polygon (as the brute-force pass does,
/// `stencil::push_pieces`) and the directed edges of those with non-zero area.
fn push_h_pieces(
    poly: &[SnappedVertex],
    zfail: bool,
    job: u32,
    pieces: &mut Vec<Piece>,
    edges: &mut Vec<EdgeRec>,
) {
    let drawn = crate::stencil::pieces::push_pieces(poly, zfail, job, pieces);
    // The fan's pieces (v0, v_i, v_i+1) in order, bit i − 1 of `drawn` when
    // drawn. Two drawn neighbours share the diagonal v0–v_i+1 in opposite
    // directions: the pair cancels in `open_edges` whatever else the volume
    // holds, so neither is pushed (the net count of every edge is unchanged,
    // and so are the open edges).
    let is_drawn = |i: usize| i >= 1 && (drawn >> (i - 1)) & 1 != 0;
    for i in 1..poly.len().saturating_sub(1) {
        if is_drawn(i) {
            let keep = [!is_drawn(i - 1), true, !is_drawn(i + 1)];
            push_piece_edges([poly[0], poly[i], poly[i + 1]], keep, edges);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every drawn fan piece's three edges, as before the fan's cancelling
    /// diagonals were left out.
    fn all_piece_edges(poly: &[SnappedVertex], edges: &mut Vec<EdgeRec>) {
        for i in 1..poly.len().saturating_sub(1) {
            let v = [poly[0], poly[i], poly[i + 1]];
            if crate::edge::Tri::new(v[0], v[1], v[2]).is_some() {
                crate::stencil::open_edges::push_piece_edges(v, [true; 3], edges);
            }
        }
    }

    proptest! {
        /// Leaving out the diagonals two drawn fan pieces share gives the same
        /// open edges, for several polygons of one volume: convex ones, and
        /// ones with repeated, collinear or reflex vertices whose fans hold
        /// undrawn (zero-area) pieces.
        #[test]
        fn fans_leave_the_open_edges_unchanged(
            polys in prop::collection::vec(
                prop::collection::vec((0i64..6, 0i64..6, 0u8..3), 3..9),
                1..4,
            )
        ) {
            let (mut fewer, mut all) = (Vec::new(), Vec::new());
            let mut pieces = Vec::new();
            for poly in &polys {
                let poly: Vec<SnappedVertex> = poly
                    .iter()
                    .map(|&(x, y, z)| SnappedVertex { x: x * SUBPIXEL, y: y * SUBPIXEL, z: 0.25 * f64::from(z) })
                    .collect();
                push_h_pieces(&poly, false, 0, &mut pieces, &mut fewer);
                all_piece_edges(&poly, &mut all);
            }
            prop_assert!(fewer.len() <= all.len());
            let (mut a, mut b) = (Vec::new(), Vec::new());
            open_edges(&mut fewer, &mut a);
            open_edges(&mut all, &mut b);
            prop_assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
    }

    /// A convex pentagon's fan pushes its five sides, not its two diagonals twice.
    #[test]
    fn a_convex_fan_pushes_its_sides() {
        let v = |x: i64, y: i64| SnappedVertex {
            x: x * SUBPIXEL,
            y: y * SUBPIXEL,
            z: 0.5,
        };
        let poly = [v(0, 0), v(10, 0), v(14, 8), v(5, 14), v(-4, 8)];
        let (mut pieces, mut edges) = (Vec::new(), Vec::new());
        push_h_pieces(&poly, false, 0, &mut pieces, &mut edges);
        assert_eq!((pieces.len(), edges.len()), (3, 5));
    }
}
