//! Brute-force stencil pass on the eye depth buffer [Heidmann 1991; Everitt &
//! Kilgard 2002, "Practical and Robust Stenciled Shadow Volumes"].
//!
//! Every volume triangle is rasterized two-sided with the rasterizer's own
//! setup (homogeneous clipping, snapping, fan, top-left rule, standard
//! pixel-centre coverage and the same f64 depth interpolation rounded to f32),
//! so the stencil pass sees exactly the pixels and depths the depth pass would
//! for the same clip-space vertices: a light cap drawn with the eye pass's
//! vertices (same `clip_from_local`, same triangle order) has bit-identical
//! depth to the surface it caps.
//!
//! Depth test: the strict reversed-Z test — a fragment *passes* when its depth
//! is strictly GREATER (nearer) than the stored eye depth; equal depth fails.
//! Background pixels of the eye target (never written) are never touched.
//!
//! Facing is [`crate::Facing`] (counter-clockwise in NDC is front). Volume
//! triangles are wound counter-clockwise seen from outside the volume
//! ([`crate::VolumeBuffer`]), so a front-facing fragment is an entry into the
//! volume along the eye ray, a back-facing one an exit.
//!
//! Per-volume tests ([`StencilTests`], [EK "Exploit Bounds"]): the scissor
//! rectangle [`crate::VolumeRange::scissor`] shrinks every triangle's pixel
//! loop, and the depth-bounds test skips pixels whose stored depth lies outside
//! `[depth_far, depth_near]`. Both are off by default; with conservative bounds
//! they leave the stencil unchanged and only save work.
//!
//! [`crate::VolumeMethod::ZpPlus`] draws the near-plane cross-section of the
//! closed volume as a fan of near-plane triangles counted by winding number,
//! then counts the near-clipped volume with the zpass rule
//! [EK "Zpass vs Zfail", Steiner §3.2.1]; the construction and why it is exact
//! are in `near_cap.rs`.

use crate::coverage::{edge_offsets, pixel_bounds, Coverage};
use crate::depth_target::DepthTarget;
use crate::edge::Tri;
use crate::near_cap::fan_triangle;
use crate::setup::{setup_into, setup_near_plane_into, Setup, SnappedVertex, Viewport, SUBPIXEL};
use crate::span::{band_extent, SpanWalker};
use crate::stencil_run::{run_masks, RunPlane};
use crate::volume_buffer::{VolumeBuffer, VolumeMethod, VolumeRange};
use crate::{Error, Result, MAX_CLIPPED_VERTICES, MAX_TARGET_SIZE};
use glam::{Mat4, Vec4};

/// Width of the stencil counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum StencilBits {
    /// 8-bit counters with wrapping arithmetic, like a GPU stencil buffer
    /// (a count of 256 aliases to 0). Spelled `bits8` (or `eight`) in serde.
    #[default]
    #[cfg_attr(feature = "serde", serde(rename = "bits8", alias = "eight"))]
    Eight,
    /// `i32` counters (wrapping too, but far out of reach): shows where 8 bits
    /// alias. Spelled `wide` in serde.
    Wide,
}

/// Per-volume tests [`StencilTarget::draw_volume`] applies before a fragment's
/// stencil operation [EK "Exploit Bounds"]; both off by default.
///
/// They are meant for bounds that are conservative — every pixel they reject has
/// its visible surface point outside the volume, so the volume's count there is 0
/// (zfail, zp+, and zpass where zpass is legal) — and then leave the stencil
/// unchanged and only save work. Bounds that are too tight change the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StencilTests {
    /// Scissor test: only pixels inside [`VolumeRange::scissor`] (`[x0, y0, x1, y1)`,
    /// row 0 at the top, clamped to the target; [`VolumeRange::FULL_SCISSOR`] is
    /// unbounded) are rasterized; every triangle's pixel loop is shrunk to it, and a
    /// volume with an empty (or inverted) rectangle is not set up at all.
    pub scissor: bool,
    /// Depth-bounds test: a pixel whose stored eye depth `d` lies outside
    /// `[depth_far, depth_near]` (reversed Z, bounds inclusive) is skipped.
    pub depth_bounds: bool,
}

/// Counters of [`StencilTarget::draw_volume`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StencilStats {
    /// Per-pixel stencil operations: fragments covered by a volume triangle (or a
    /// zp+ near-cap fan triangle) on non-background pixels that pass the enabled
    /// [`StencilTests`] — inside the scissor, and inside the depth bounds. Each is
    /// depth-tested. Fragments the tests reject are not counted.
    pub pixels_processed: u64,
    /// Fragments that changed a stencil value (incremented or decremented).
    pub stencil_updates: u64,
    /// Volume triangles submitted (before clipping and culling; zp+ near-cap fan
    /// triangles are not counted).
    pub triangles: u64,
    /// Pixels this call updated for the first time since the target's last
    /// [`StencilTarget::clear`] (or its creation). Summed over the calls on one
    /// target since a clear, it is [`StencilTarget::touched_pixels`]: the number of
    /// distinct pixels whose counter was incremented or decremented at least once
    /// (even if it came back to its old value).
    pub pixels_touched: u64,
    /// Hierarchical stencil only: volume fragments rasterized per pixel inside
    /// boundary tiles (covered, non-background, inside the enabled tests) — the
    /// brute-force count restricted to the boundary tiles. For the hierarchical
    /// stencil `pixels_processed` is instead tile area × boundary tiles, summed
    /// over volumes, as [Aila04 Table 1] counts it.
    pub h_fragments: u64,
    /// Hierarchical stencil only: stage-1 visits of a (volume triangle piece, tile) pair.
    pub tile_tests: u64,
    /// Hierarchical stencil only: tiles a volume reached and classified lit,
    /// summed over volumes.
    pub tiles_lit: u64,
    /// Tiles a volume classified wholly inside it (whole-tile update), summed over volumes.
    pub tiles_shadow: u64,
    /// Tiles a volume classified as boundary (per-pixel work), summed over volumes.
    pub tiles_boundary: u64,
    /// Modeled memory traffic of per-pixel buffers in bytes (depth reads,
    /// stencil reads and writes, the mask resolve's stencil reads); the model is
    /// stated in `hstencil.rs`.
    pub pixel_bytes: u64,
    /// Modeled memory traffic of per-tile buffers in bytes (tile depth bounds,
    /// the PSV records, Smin/Smax/offset and FS bits); 0 for brute force.
    pub tile_bytes: u64,
}

impl StencilStats {
    /// Adds `other` to `self`.
    pub fn add(&mut self, other: &StencilStats) {
        self.pixels_processed += other.pixels_processed;
        self.stencil_updates += other.stencil_updates;
        self.triangles += other.triangles;
        self.pixels_touched += other.pixels_touched;
        self.h_fragments += other.h_fragments;
        self.tile_tests += other.tile_tests;
        self.tiles_lit += other.tiles_lit;
        self.tiles_shadow += other.tiles_shadow;
        self.tiles_boundary += other.tiles_boundary;
        self.pixel_bytes += other.pixel_bytes;
        self.tile_bytes += other.tile_bytes;
    }

    /// Total modeled bandwidth: per-pixel plus per-tile bytes.
    pub fn bandwidth_bytes(&self) -> u64 {
        self.pixel_bytes + self.tile_bytes
    }
}

#[derive(Clone, Debug)]
pub(crate) enum Counters {
    Eight(Vec<u8>),
    Wide(Vec<i32>),
}

/// Where fragments are processed: an inclusive pixel rectangle and an inclusive
/// depth range.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Window {
    pub x0: i64,
    pub x1: i64,
    pub y0: i64,
    pub y1: i64,
    pub dlo: f32,
    pub dhi: f32,
}

/// A `width × height` stencil buffer, row-major from the top row, with a bitmap of
/// the pixels updated since the last clear.
#[derive(Clone, Debug)]
pub struct StencilTarget {
    width: u32,
    height: u32,
    pub(crate) counters: Counters,
    /// One bit per pixel (row-major): updated since the last clear.
    /// 1 per pixel updated since the last clear, else 0 (bytes: branch-free updates).
    pub(crate) touched: Vec<u8>,
    pub(crate) touched_count: u64,
}

impl StencilTarget {
    /// A cleared (all zero) target.
    ///
    /// # Errors
    /// [`Error::InvalidSize`] when a side is 0 or above [`MAX_TARGET_SIZE`].
    pub fn new(width: u32, height: u32, bits: StencilBits) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_TARGET_SIZE || height > MAX_TARGET_SIZE {
            return Err(Error::InvalidSize {
                width,
                height,
                max: MAX_TARGET_SIZE,
            });
        }
        // Padded to whole 8×8 tiles (see `StencilTarget::index`).
        let n = (width.div_ceil(8) * height.div_ceil(8)) as usize * 64;
        let counters = match bits {
            StencilBits::Eight => Counters::Eight(vec![0; n]),
            StencilBits::Wide => Counters::Wide(vec![0; n]),
        };
        Ok(StencilTarget {
            width,
            height,
            counters,
            touched: vec![0; n],
            touched_count: 0,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Counter width.
    pub fn bits(&self) -> StencilBits {
        match self.counters {
            Counters::Eight(_) => StencilBits::Eight,
            Counters::Wide(_) => StencilBits::Wide,
        }
    }

    /// Sets every counter to 0 and forgets which pixels were touched.
    pub fn clear(&mut self) {
        match &mut self.counters {
            Counters::Eight(v) => v.fill(0),
            Counters::Wide(v) => v.fill(0),
        }
        self.touched.fill(0);
        self.touched_count = 0;
    }

    /// Number of distinct pixels whose counter was incremented or decremented at
    /// least once since the last [`StencilTarget::clear`] (or creation), whatever
    /// its value now (a pixel whose count went up and back to 0 is touched). The
    /// sum of [`StencilStats::pixels_touched`] over the draws since then.
    pub fn touched_pixels(&self) -> u64 {
        self.touched_count
    }

    /// Whether the counter at `(x, y)` was updated since the last clear (see
    /// [`StencilTarget::touched_pixels`]).
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn touched(&self, x: u32, y: u32) -> bool {
        let i = self.index(x, y);
        self.touched[i] != 0
    }

    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the target"
        );
        tiled_index(self.width, x, y)
    }

    /// The counter at pixel `(x, y)` (row 0 at the top); with [`StencilBits::Eight`]
    /// the `u8` as `i32` (`0..=255`).
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn value(&self, x: u32, y: u32) -> i32 {
        let i = self.index(x, y);
        match &self.counters {
            Counters::Eight(v) => i32::from(v[i]),
            Counters::Wide(v) => v[i],
        }
    }

    /// Whether the counter at `(x, y)` is non-zero (the pixel is in shadow, if lit at all).
    ///
    /// # Panics
    /// When `(x, y)` is outside the target.
    pub fn nonzero(&self, x: u32, y: u32) -> bool {
        self.value(x, y) != 0
    }

    /// The mask resolve: per pixel (row-major, row 0 at the top) whether the counter
    /// is non-zero, false on `eye`'s background pixels. Adds the stencil reads of the
    /// non-background pixels to `stats.pixel_bytes`.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `eye` has another size.
    pub fn resolve(
        &self,
        eye: &DepthTarget,
        out: &mut Vec<bool>,
        stats: &mut StencilStats,
    ) -> Result<()> {
        if (eye.width(), eye.height()) != (self.width, self.height) {
            return Err(Error::SizeMismatch {
                expected: (eye.width(), eye.height()),
                got: (self.width, self.height),
            });
        }
        out.clear();
        let mut read = 0u64;
        for y in 0..self.height {
            for x in 0..self.width {
                let written = eye.depth[eye.layout.pixel_index(x, y)] != crate::BACKGROUND;
                read += u64::from(written);
                out.push(written && self.nonzero(x, y));
            }
        }
        stats.pixel_bytes += read * counter_bytes(self.bits());
        Ok(())
    }

    /// Rasterizes every triangle of `range` (indices
    /// `first_index..first_index + index_count` of `buf`, local-space positions) with
    /// `clip_from_local`, two-sided, against `eye`'s depth with the strict test (a
    /// fragment passes when strictly nearer than the stored depth):
    ///
    /// - [`VolumeMethod::ZPass`]: passing fragments, front-facing +1, back-facing −1;
    /// - [`VolumeMethod::ZFail`]: failing fragments (not strictly nearer),
    ///   back-facing +1, front-facing −1;
    /// - [`VolumeMethod::ZpPlus`]: the zpass rule, plus the near-plane
    ///   initialization: for every triangle the near plane cuts, a fan triangle in
    ///   the near plane (depth 1), counted +1 front-facing / −1 back-facing where it
    ///   passes, so that the count starts at the number of volumes containing the
    ///   pixel's near-plane point (see the module documentation). The range must be
    ///   the closed volume, as for zfail.
    ///
    /// Background pixels of `eye` are never touched. Edge-on triangles (no facing)
    /// draw nothing (for zp+ their near-plane segment still closes the cap).
    /// `tests` switches the range's scissor and depth-bounds tests on
    /// ([`StencilTests`]); with both off they are ignored.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `eye` has another size; [`Error::IndexOutOfRange`]
    /// when the range reaches past `buf.indices` (`index` is then the index-buffer
    /// position, `len` its length) or an index names a missing position. Errors are
    /// found before anything is drawn.
    pub fn draw_volume(
        &mut self,
        eye: &DepthTarget,
        clip_from_local: Mat4,
        buf: &VolumeBuffer,
        range: &VolumeRange,
        tests: StencilTests,
        stats: &mut StencilStats,
    ) -> Result<()> {
        self.draw_volumes(eye, &[(clip_from_local, range)], buf, tests, stats)
    }

    /// [`StencilTarget::draw_volume`] for many ranges at once, each with its own
    /// `clip_from_local`; the result is the same as drawing them one by one (the
    /// stencil operations commute). The target is split into bands of tile rows
    /// drawn in parallel (one per rayon thread, with the `parallel` feature):
    /// every band sets up every triangle and fills only its own rows.
    ///
    /// # Errors
    /// As [`StencilTarget::draw_volume`], for the first bad range; then nothing is drawn.
    pub fn draw_volumes(
        &mut self,
        eye: &DepthTarget,
        volumes: &[(Mat4, &VolumeRange)],
        buf: &VolumeBuffer,
        tests: StencilTests,
        stats: &mut StencilStats,
    ) -> Result<()> {
        self.draw_volumes_banded(eye, volumes, buf, tests, stats, BAND_TILE_ROWS)
    }

    /// [`StencilTarget::draw_volumes`] with bands of `band_tile_rows` tile rows.
    fn draw_volumes_banded(
        &mut self,
        eye: &DepthTarget,
        volumes: &[(Mat4, &VolumeRange)],
        buf: &VolumeBuffer,
        tests: StencilTests,
        stats: &mut StencilStats,
        band_tile_rows: usize,
    ) -> Result<()> {
        let (jobs, mut st) = self.prepare(eye, volumes, buf, tests)?;
        let tiles_x = self.width.div_ceil(8) as usize;
        let (width, height) = (self.width, self.height);
        // Bands of `band_tile_rows` tile rows; contiguous in the tiled storage.
        let chunk = band_tile_rows * tiles_x * 64;
        let vp = eye.vp;
        let mut pieces: Vec<Piece> = Vec::with_capacity(PIECE_BATCH + MAX_CLIPPED_VERTICES * 2);
        let mut parts: Vec<StencilStats> = Vec::new();
        let mut s = Setup {
            facing: None,
            clipped: false,
            vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
            len: 0,
        };
        let mut flush = |pieces: &mut Vec<Piece>, target: &mut StencilTarget| {
            let draw_band = |k: usize, counters: CountersMut<'_>, touched: &mut [u8]| {
                let y0 = (k * band_tile_rows * 8) as i64;
                let mut band = Band {
                    counters,
                    touched,
                    width,
                    height,
                    y0,
                    y1: (y0 + band_tile_rows as i64 * 8).min(i64::from(height)) - 1,
                    base: k * chunk,
                };
                let mut bst = StencilStats::default();
                for p in pieces.iter() {
                    if p.y1 >= band.y0 && p.y0 <= band.y1 {
                        let win = &jobs[p.job as usize].2;
                        band.fill_tri(eye, &p.tri, win, p.zfail, p.increment, &mut bst);
                    }
                }
                bst
            };
            parts.extend(match &mut target.counters {
                Counters::Eight(c) => run_bands(c, &mut target.touched, chunk, |k, c, t| {
                    draw_band(k, CountersMut::Eight(c), t)
                }),
                Counters::Wide(c) => run_bands(c, &mut target.touched, chunk, |k, c, t| {
                    draw_band(k, CountersMut::Wide(c), t)
                }),
            });
            pieces.clear();
        };
        for (j, (m, range, _)) in jobs.iter().enumerate() {
            volume_polygons(*m, range, buf, &vp, &mut s, |poly, zfail| {
                // Each snapped fan piece counts by its own snapped orientation:
                // snapping can turn a sliver (or a guard-band-clipped piece)
                // over, and the count must be the winding number of what is
                // rasterized.
                push_pieces(poly, zfail, j as u32, &mut pieces);
                if pieces.len() >= PIECE_BATCH {
                    flush(&mut pieces, self);
                }
            });
        }
        if !pieces.is_empty() {
            flush(&mut pieces, self);
        }
        for p in &parts {
            st.pixels_processed += p.pixels_processed;
            st.stencil_updates += p.stencil_updates;
            st.pixels_touched += p.pixels_touched;
        }
        st.pixel_bytes = pass_bytes(self.bits(), st.pixels_processed, st.stencil_updates);
        self.touched_count += st.pixels_touched;
        stats.add(&st);
        Ok(())
    }

    /// What both stencil passes check and derive first: `eye`'s size, every
    /// range's indices (before anything is drawn), each volume with its window
    /// (volumes with an empty one dropped), and the stats with `triangles` set.
    #[allow(clippy::type_complexity)]
    pub(crate) fn prepare<'v>(
        &self,
        eye: &DepthTarget,
        volumes: &[(Mat4, &'v VolumeRange)],
        buf: &VolumeBuffer,
        tests: StencilTests,
    ) -> Result<(Vec<(Mat4, &'v VolumeRange, Window)>, StencilStats)> {
        let mut jobs = Vec::new();
        let st = self.prepare_into(eye, volumes, buf, tests, &mut jobs)?;
        Ok((jobs, st))
    }

    /// [`StencilTarget::prepare`] with the volumes and windows into `jobs`
    /// (cleared first).
    pub(crate) fn prepare_into<'v>(
        &self,
        eye: &DepthTarget,
        volumes: &[(Mat4, &'v VolumeRange)],
        buf: &VolumeBuffer,
        tests: StencilTests,
        jobs: &mut Vec<(Mat4, &'v VolumeRange, Window)>,
    ) -> Result<StencilStats> {
        jobs.clear();
        if (eye.width(), eye.height()) != (self.width, self.height) {
            return Err(Error::SizeMismatch {
                expected: (eye.width(), eye.height()),
                got: (self.width, self.height),
            });
        }
        for (_, range) in volumes {
            check_range(buf, range)?;
        }
        jobs.extend(
            volumes
                .iter()
                .filter_map(|&(m, r)| self.window(r, tests).map(|w| (m, r, w))),
        );
        Ok(StencilStats {
            triangles: volumes.iter().map(|(_, r)| r.index_count as u64 / 3).sum(),
            ..StencilStats::default()
        })
    }

    /// The pixel rectangle and depth range `tests` allow for `range`; `None` when empty.
    pub(crate) fn window(&self, range: &VolumeRange, tests: StencilTests) -> Option<Window> {
        let (w, h) = (self.width, self.height);
        let [x0, y0, x1, y1] = if tests.scissor {
            let [x0, y0, x1, y1] = range.scissor;
            [x0.min(w), y0.min(h), x1.min(w), y1.min(h)]
        } else {
            [0, 0, w, h]
        };
        let (dlo, dhi) = if tests.depth_bounds {
            (range.depth_far, range.depth_near)
        } else {
            (f32::NEG_INFINITY, f32::INFINITY)
        };
        // NaN bounds are empty too (no depth lies within them).
        let depth_empty = !matches!(
            dlo.partial_cmp(&dhi),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        );
        if x0 >= x1 || y0 >= y1 || depth_empty {
            return None;
        }
        Some(Window {
            x0: i64::from(x0),
            x1: i64::from(x1) - 1,
            y0: i64::from(y0),
            y1: i64::from(y1) - 1,
            dlo,
            dhi,
        })
    }
}

/// Mutable counters of one band.
pub(crate) enum CountersMut<'a> {
    Eight(&'a mut [u8]),
    Wide(&'a mut [i32]),
}

/// The rows `y0..=y1` of a [`StencilTarget`]: whole tile rows, whose counters
/// and touched flags are the contiguous slices starting at tiled index `base`.
pub(crate) struct Band<'a> {
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

/// Fan pieces set up before the bands fill them (bounded memory).
pub(crate) const PIECE_BATCH: usize = 4096;

/// A set-up fan piece of a volume triangle (or zp+ near-cap fan triangle): its
/// edge functions, counting rule and direction, rows and volume.
pub(crate) struct Piece {
    pub tri: Tri,
    pub zfail: bool,
    pub increment: bool,
    pub y0: i64,
    pub y1: i64,
    pub job: u32,
}

/// Appends the fan pieces of a snapped polygon (a volume triangle after
/// clipping, or a zp+ near-cap fan triangle), each counted by its own snapped
/// orientation: front-facing pieces (clockwise on screen, i.e. counter-clockwise
/// in NDC with y up) are entries, back-facing ones exits; zpass counts entries
/// +1 and exits −1 in front of the surface, zfail exits +1 and entries −1
/// behind it.
pub(crate) fn push_pieces(poly: &[SnappedVertex], zfail: bool, job: u32, out: &mut Vec<Piece>) {
    for i in 1..poly.len().saturating_sub(1) {
        let (v0, v1, v2) = (poly[0], poly[i], poly[i + 1]);
        // Screen y points down: a negative area is clockwise seen on screen.
        let area = (v1.x - v0.x) * (v2.y - v0.y) - (v1.y - v0.y) * (v2.x - v0.x);
        if let Some(tri) = Tri::new(v0, v1, v2) {
            // Rows whose pixel centres the piece can cover (inclusive, unclamped).
            let half = SUBPIXEL / 2;
            out.push(Piece {
                y0: (tri.ymin - half).div_euclid(SUBPIXEL),
                y1: (tri.ymax - half).div_euclid(SUBPIXEL) + 1,
                tri,
                zfail,
                increment: (area < 0) != zfail,
                job,
            });
        }
    }
}

impl Band<'_> {
    /// Increments (or decrements, `!increment`) every covered non-background pixel of
    /// `tri` inside `win` whose fragment passes (zpass) or fails (zfail) the strict
    /// depth test. Each row walks only its covered span ([`crate::span`]).
    fn fill_tri(
        &mut self,
        eye: &DepthTarget,
        tri: &Tri,
        win: &Window,
        zfail: bool,
        increment: bool,
        st: &mut StencilStats,
    ) {
        let all = (i64::MIN, i64::MAX, i64::MIN, i64::MAX);
        self.fill_tri_within(eye, tri, win, zfail, increment, all, st);
    }

    /// [`Band::fill_tri`] restricted to the inclusive pixel rectangle
    /// `(x0, x1, y0, y1)` (the hierarchical stencil's boundary tiles).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn fill_tri_within(
        &mut self,
        eye: &DepthTarget,
        tri: &Tri,
        win: &Window,
        zfail: bool,
        increment: bool,
        clip: (i64, i64, i64, i64),
        st: &mut StencilStats,
    ) {
        let (w, h) = (self.width, self.height);
        let Some((x0, x1, y0, y1)) = pixel_bounds(tri, Coverage::Standard, w, h) else {
            return;
        };
        let (x0, x1) = (x0.max(win.x0).max(clip.0), x1.min(win.x1).min(clip.1));
        let (y0, y1) = (
            y0.max(win.y0).max(self.y0).max(clip.2),
            y1.min(win.y1).min(self.y1).min(clip.3),
        );
        if x0 > x1 || y0 > y1 {
            return;
        }
        let rect = Rect { x0, x1, y0, y1 };
        let touched = &mut *self.touched;
        let base = self.base;
        macro_rules! fill {
            ($c:expr, $delta:expr) => {
                fill_rows_dispatch(
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

/// Sets up every triangle of `range` with `clip_from_local` (the rasterizer's
/// own clipping and snapping) and hands each snapped polygon to `emit` with its
/// counting rule (`zfail`): the triangle's own (edge-on triangles, with no
/// facing, draw nothing) and, for [`VolumeMethod::ZpPlus`], its near-cap fan
/// triangle (zpass rule; see `near_cap.rs`).
pub(crate) fn volume_polygons(
    clip_from_local: Mat4,
    range: &VolumeRange,
    buf: &VolumeBuffer,
    vp: &Viewport,
    s: &mut Setup,
    mut emit: impl FnMut(&[SnappedVertex], bool),
) {
    let (zfail, near_cap) = match range.method {
        VolumeMethod::ZPass => (false, false),
        VolumeMethod::ZFail => (true, false),
        VolumeMethod::ZpPlus => (false, true),
    };
    for t in buf.indices[range.indices()].chunks_exact(3) {
        let v = [0, 1, 2].map(|k| clip_from_local * Vec4::from_array(buf.positions[t[k] as usize]));
        setup_into(v, vp, s);
        if s.facing.is_some() {
            emit(s.polygon(), zfail);
        }
        if near_cap {
            if let Some(fan) = fan_triangle(v.map(|p| p.as_dvec4())) {
                setup_near_plane_into(fan, vp, s);
                emit(s.polygon(), false);
            }
        }
    }
}

/// Bytes of one stencil counter: 1 for 8 bits, 4 for wide counters.
pub(crate) fn counter_bytes(bits: StencilBits) -> u64 {
    match bits {
        StencilBits::Eight => 1,
        StencilBits::Wide => 4,
    }
}

/// Modeled per-pixel traffic of a stencil pass (see `hstencil.rs`): every processed
/// fragment reads its 4-byte depth and its counter, every update writes the counter.
pub(crate) fn pass_bytes(bits: StencilBits, processed: u64, updates: u64) -> u64 {
    let s = counter_bytes(bits);
    (4 + s) * processed + s * updates
}

/// Checks that `range` names only indices inside `buf` and positions that exist.
fn check_range(buf: &VolumeBuffer, range: &VolumeRange) -> Result<()> {
    let first = range.first_index as usize;
    let ntri = range.index_count as usize / 3;
    let end = first + 3 * ntri;
    if end > buf.indices.len() {
        return Err(Error::IndexOutOfRange {
            triangle: (buf.indices.len().max(first) - first) / 3,
            index: u32::try_from(end - 1).unwrap_or(u32::MAX),
            len: buf.indices.len(),
        });
    }
    let indices = &buf.indices[first..end];
    if let Some(k) = indices
        .iter()
        .position(|&i| i as usize >= buf.positions.len())
    {
        return Err(Error::IndexOutOfRange {
            triangle: k / 3,
            index: indices[k],
            len: buf.positions.len(),
        });
    }
    Ok(())
}

/// Runs `f(k, counters, touched)` on consecutive chunks of `chunk` entries, in
/// parallel with the `parallel` feature; returns each chunk's result in order.
fn run_bands<C: Send, R: Send>(
    counters: &mut [C],
    touched: &mut [u8],
    chunk: usize,
    f: impl Fn(usize, &mut [C], &mut [u8]) -> R + Sync,
) -> Vec<R> {
    let chunk = chunk.max(1);
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        if counters.len() > chunk {
            return counters
                .par_chunks_mut(chunk)
                .zip(touched.par_chunks_mut(chunk))
                .enumerate()
                .map(|(k, (c, t))| f(k, c, t))
                .collect();
        }
    }
    counters
        .chunks_mut(chunk)
        .zip(touched.chunks_mut(chunk))
        .enumerate()
        .map(|(k, (c, t))| f(k, c, t))
        .collect()
}

/// Index of pixel `(x, y)` in a `width`-wide buffer stored in 8×8 tiles, tile
/// rows of 8 pixels contiguous: a volume triangle is mostly a thin sliver, and
/// with row-major storage every pixel row it covers would be another cache line.
#[inline(always)]
pub(crate) fn tiled_index(width: u32, x: u32, y: u32) -> usize {
    let tiles_x = width.div_ceil(8) as usize;
    (((y >> 3) as usize * tiles_x + (x >> 3) as usize) << 6) + (((y & 7) << 3) + (x & 7)) as usize
}

/// Inclusive pixel rectangle of one triangle's loop.
struct Rect {
    x0: i64,
    x1: i64,
    y0: i64,
    y1: i64,
}

/// A stencil counter: adds with wrap-around.
trait Counter: Copy + Default {
    fn wrapping(self, delta: Self) -> Self;
}

impl Counter for u8 {
    #[inline(always)]
    fn wrapping(self, delta: u8) -> u8 {
        self.wrapping_add(delta)
    }
}

impl Counter for i32 {
    #[inline(always)]
    fn wrapping(self, delta: i32) -> i32 {
        self.wrapping_add(delta)
    }
}

/// One triangle's fill in one band: where it writes, what it tests and adds.
struct Fill<'a, C> {
    /// The band's counters and touched flags, from tiled index `base`.
    counters: &'a mut [C],
    touched: &'a mut [u8],
    base: usize,
    width: u32,
    eye: &'a DepthTarget,
    tri: &'a Tri,
    rect: Rect,
    win: &'a Window,
    zfail: bool,
    delta: C,
}

/// [`fill_rows`], in its AVX2 build when the CPU has it: the run kernel
/// ([`crate::stencil_run`]) then inlines into the row loop.
#[inline(always)]
fn fill_rows_dispatch<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    #[cfg(target_arch = "x86_64")]
    if f.eye.isa >= crate::InstructionSet::Avx2 {
        // SAFETY: `fill_rows_avx2` only requires AVX2; the target's level is at
        // most the detected one.
        unsafe { fill_rows_avx2(f, st) };
        return;
    }
    fill_rows(f, st);
}

/// [`fill_rows`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_rows_avx2<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
    fill_rows(f, st);
}

/// The per-pixel loop of [`Band::fill_tri`], monomorphized per counter type:
/// adds `delta` (wrapping) to each covered pixel of `rect` that is not background,
/// lies within the depth window and passes (zpass) or fails (zfail) the strict test.
///
/// Each row's covered span is walked in runs that stay inside one tile row, where
/// the tiled depth buffer is contiguous, with a branch-free body. Edge values are
/// carried as f64: they are integers below 2⁵³ (see `edge.rs`), so stepping them
/// in f64 is exact and the depth `Σ E_i·z_i / area` is bit-identical to the eye
/// pass's.
#[inline(always)]
fn fill_rows<C: Counter>(f: Fill<'_, C>, st: &mut StencilStats) {
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
    let walker = SpanWalker::new(tri, &off, rect.x0, rect.x1, rect.y0);
    let tile = 1i64 << layout.shift;
    let active = |tb: &crate::layout::TileBounds| !(tb.zmax < dlo.max(0.0) || tb.zmin > dhi);
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
    st.stencil_updates += updates;
    st.pixels_touched += first;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{aabb_corners, Coverage, DrawItem, TileSize, AABB_TRIANGLES};
    use glam::{DMat4, Vec3};

    /// Bands (several, drawn in parallel) give the same counters and counts as
    /// one band over the whole target, for every method, zp+ near caps included.
    #[test]
    fn bands_equal_one_band() {
        let (w, h) = (150u32, 420u32);
        // Reversed-Z infinite perspective (fov_y 1 rad, near 0.1) looking down −z
        // from (0.4, 0.3, 2.5), slightly tilted down.
        let f = 1.0 / 0.5f32.tan();
        let proj = Mat4::from_cols(
            Vec4::new(f * h as f32 / w as f32, 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        );
        let (c, sn) = (0.15f32.cos(), 0.15f32.sin());
        let tilt = Mat4::from_cols(
            Vec4::new(1.0, 0.0, 0.0, 0.0),
            Vec4::new(0.0, c, -sn, 0.0),
            Vec4::new(0.0, sn, c, 0.0),
            Vec4::new(0.0, 0.0, 0.0, 1.0),
        );
        let view = proj * tilt * Mat4::from_translation(-Vec3::new(0.4, 0.3, 2.5));
        let mut eye = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        let ground = [
            Vec4::new(-30.0, -1.0, -30.0, 1.0),
            Vec4::new(30.0, -1.0, -30.0, 1.0),
            Vec4::new(30.0, -1.5, 30.0, 1.0),
            Vec4::new(-30.0, -1.5, 30.0, 1.0),
        ];
        let quad = [[0u32, 1, 2], [0, 2, 3]];
        let item = DrawItem {
            clip_from_local: view,
            positions: &ground,
            triangles: &quad,
            object: 0,
        };
        eye.draw(&item, Coverage::Standard).unwrap();
        let mut buf = VolumeBuffer::new();
        let boxes = [
            (Vec3::new(-1.0, -2.0, -3.0), Vec3::new(0.5, 0.2, -1.0)),
            (Vec3::new(-0.2, -1.2, 1.5), Vec3::new(0.6, 0.4, 3.0)), // the eye inside
            (Vec3::new(0.8, -3.0, -9.0), Vec3::new(2.0, -0.5, -2.0)),
        ];
        for (k, (lo, hi)) in boxes.iter().enumerate() {
            let first_vertex = buf.positions.len() as u32;
            buf.positions
                .extend(aabb_corners(*lo, *hi).iter().map(|v| v.to_array()));
            let first_index = buf.indices.len() as u32;
            for t in AABB_TRIANGLES {
                buf.indices.extend(t.map(|i| first_vertex + i));
            }
            for method in [
                VolumeMethod::ZFail,
                VolumeMethod::ZpPlus,
                VolumeMethod::ZPass,
            ] {
                buf.ranges.push(VolumeRange {
                    object: k as u32,
                    segment: 0,
                    world_from_local: DMat4::IDENTITY,
                    method,
                    first_vertex,
                    vertex_count: 8,
                    first_index,
                    index_count: 36,
                    light_cap: first_index..first_index,
                    dark_cap: first_index..first_index,
                    depth_near: 1.0,
                    depth_far: 0.0,
                    scissor: VolumeRange::FULL_SCISSOR,
                });
            }
        }
        let vols: Vec<(Mat4, &VolumeRange)> = buf.ranges.iter().map(|r| (view, r)).collect();
        let draw = |band_tile_rows| {
            let mut s = StencilTarget::new(w, h, StencilBits::Wide).unwrap();
            let mut st = StencilStats::default();
            s.draw_volumes_banded(
                &eye,
                &vols,
                &buf,
                StencilTests::default(),
                &mut st,
                band_tile_rows,
            )
            .unwrap();
            (s, st)
        };
        let (one, st1) = draw(1000);
        for rows in [1, 3, 8] {
            let (many, st) = draw(rows);
            assert_eq!(st, st1, "{rows} tile rows per band");
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        many.value(x, y),
                        one.value(x, y),
                        "pixel ({x}, {y}), {rows} tile rows per band"
                    );
                }
            }
        }
        assert!(st1.stencil_updates > 1000 && one.touched_pixels() > 1000);
    }
}
