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

use super::counters::{
    counter_bytes, pass_bytes, tiled_index, Counters, CountersMut, StencilBits, StencilStats,
    StencilTests,
};
use super::fill::{for_each_band, CounterRows, BAND_TILE_ROWS};
use super::pieces::{check_range, push_pieces, volume_polygons, Piece, Window, PIECE_BATCH};
use crate::clip::MAX_CLIPPED_VERTICES;
use crate::depth_target::DepthTarget;
use crate::setup::{Setup, SnappedVertex};
use crate::volume_buffer::{VolumeBuffer, VolumeRange};
use crate::{Error, Result, MAX_TARGET_SIZE};
use glam::Mat4;

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
    /// - [`VolumeMethod::ZPass`](crate::VolumeMethod::ZPass): passing fragments, front-facing +1, back-facing −1;
    /// - [`VolumeMethod::ZFail`](crate::VolumeMethod::ZFail): failing fragments (not strictly nearer),
    ///   back-facing +1, front-facing −1;
    /// - [`VolumeMethod::ZpPlus`](crate::VolumeMethod::ZpPlus): the zpass rule, plus the near-plane
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
        // Per band, its counters summed over the batches.
        let mut band_stats =
            vec![StencilStats::default(); (height as usize).div_ceil(band_tile_rows * 8)];
        let mut s = Setup {
            facing: None,
            clipped: false,
            vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
            len: 0,
        };
        let mut flush = |pieces: &mut Vec<Piece>, target: &mut StencilTarget| {
            let draw_band = |k: usize, counters: CountersMut<'_>, touched: &mut [u8]| {
                let y0 = (k * band_tile_rows * 8) as i64;
                let mut band = CounterRows {
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
                        band.fill_piece(eye, p, win, &mut bst);
                    }
                }
                bst
            };
            macro_rules! run_with {
                ($c:expr, $counters:path) => {
                    for_each_band!(
                        |(k, ((c, t), s))| s[0].add(&draw_band(k, $counters(c), t)),
                        $c => chunk,
                        target.touched => chunk,
                        band_stats => 1,
                    )
                };
            }
            match &mut target.counters {
                Counters::Eight(c) => run_with!(c, CountersMut::Eight),
                Counters::Wide(c) => run_with!(c, CountersMut::Wide),
            }
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
        for p in &band_stats {
            st.pixels_processed += p.pixels_processed;
            st.tiles_scanned += p.tiles_scanned;
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
            range.scissor
        } else {
            VolumeRange::FULL_SCISSOR
        };
        // The band applies whatever the tests.
        let [bx0, by0, bx1, by1] = range.band;
        let [x0, y0, x1, y1] = [
            x0.max(bx0).min(w),
            y0.max(by0).min(h),
            x1.min(bx1).min(w),
            y1.min(by1).min(h),
        ];
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::VolumeMethod;
    use crate::{aabb_corners, Coverage, DrawItem, TileSize, AABB_TRIANGLES};
    use glam::Vec4;
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
            cull: crate::CullMode::None,
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
                    object: k as u64,
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
                    band: VolumeRange::FULL_SCISSOR,
                    planes: [None, None],
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
