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
//! Not here (yet): per-volume scissor and depth-bounds tests
//! ([`crate::VolumeRange::scissor`], `depth_near`, `depth_far` are ignored), and
//! zp+ near-plane initialization: [`crate::VolumeMethod::ZpPlus`] is counted
//! with the zfail rule, which needs the same closed volume.

use crate::coverage::{edge_offsets, pixel_bounds, pixel_depth, Coverage};
use crate::depth_target::{DepthTarget, BACKGROUND};
use crate::edge::for_each_fan_tri;
use crate::setup::{setup_into, Facing, Setup, SnappedVertex, SUBPIXEL};
use crate::volume_buffer::{VolumeBuffer, VolumeMethod, VolumeRange};
use crate::{Error, Result, MAX_CLIPPED_VERTICES, MAX_TARGET_SIZE};
use glam::{Mat4, Vec4};

/// Width of the stencil counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum StencilBits {
    /// 8-bit counters with wrapping arithmetic, like a GPU stencil buffer
    /// (a count of 256 aliases to 0).
    #[default]
    Eight,
    /// `i32` counters (wrapping too, but far out of reach): shows where 8 bits alias.
    Wide,
}

/// Counters of [`StencilTarget::draw_volume`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StencilStats {
    /// Per-pixel stencil operations: covered fragments on non-background pixels
    /// (each is depth-tested).
    pub pixels_processed: u64,
    /// Fragments that changed a stencil value (incremented or decremented).
    pub stencil_updates: u64,
    /// Volume triangles submitted (before clipping and culling).
    pub triangles: u64,
}

impl StencilStats {
    /// Adds `other` to `self`.
    pub fn add(&mut self, other: &StencilStats) {
        self.pixels_processed += other.pixels_processed;
        self.stencil_updates += other.stencil_updates;
        self.triangles += other.triangles;
    }
}

#[derive(Clone, Debug)]
enum Counters {
    Eight(Vec<u8>),
    Wide(Vec<i32>),
}

/// A `width × height` stencil buffer, row-major from the top row.
#[derive(Clone, Debug)]
pub struct StencilTarget {
    width: u32,
    height: u32,
    counters: Counters,
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
        let n = width as usize * height as usize;
        let counters = match bits {
            StencilBits::Eight => Counters::Eight(vec![0; n]),
            StencilBits::Wide => Counters::Wide(vec![0; n]),
        };
        Ok(StencilTarget {
            width,
            height,
            counters,
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

    /// Sets every counter to 0.
    pub fn clear(&mut self) {
        match &mut self.counters {
            Counters::Eight(v) => v.fill(0),
            Counters::Wide(v) => v.fill(0),
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the target"
        );
        y as usize * self.width as usize + x as usize
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

    /// Rasterizes every triangle of `range` (indices
    /// `first_index..first_index + index_count` of `buf`, local-space positions) with
    /// `clip_from_local`, two-sided, against `eye`'s depth with the strict test (a
    /// fragment passes when strictly nearer than the stored depth):
    ///
    /// - [`VolumeMethod::ZPass`]: passing fragments, front-facing +1, back-facing −1;
    /// - [`VolumeMethod::ZFail`]: failing fragments (not strictly nearer),
    ///   back-facing +1, front-facing −1;
    /// - [`VolumeMethod::ZpPlus`]: counted as zfail until zp+ initialization exists.
    ///
    /// Background pixels of `eye` are never touched. Edge-on triangles (no facing)
    /// draw nothing. The range's scissor and depth bounds are ignored.
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
        stats: &mut StencilStats,
    ) -> Result<()> {
        if (eye.width(), eye.height()) != (self.width, self.height) {
            return Err(Error::SizeMismatch {
                expected: (eye.width(), eye.height()),
                got: (self.width, self.height),
            });
        }
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
        let zfail = match range.method {
            VolumeMethod::ZPass => false,
            VolumeMethod::ZFail | VolumeMethod::ZpPlus => true,
        };
        let mut s = Setup {
            facing: None,
            clipped: false,
            vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
            len: 0,
        };
        let vp = eye.vp;
        let mut st = StencilStats::default();
        for t in indices.chunks_exact(3) {
            st.triangles += 1;
            let v =
                [0, 1, 2].map(|k| clip_from_local * Vec4::from_array(buf.positions[t[k] as usize]));
            setup_into(v, &vp, &mut s);
            let Some(facing) = s.facing else { continue };
            // Which fragments count, and by how much.
            let increment = matches!(
                (zfail, facing),
                (false, Facing::Front) | (true, Facing::Back)
            );
            self.fill_polygon(eye, s.polygon(), zfail, increment, &mut st);
        }
        stats.add(&st);
        Ok(())
    }

    /// Increments (or decrements, `!increment`) every covered non-background pixel of the snapped polygon
    /// whose fragment passes (zpass) or fails (zfail) the strict depth test.
    fn fill_polygon(
        &mut self,
        eye: &DepthTarget,
        poly: &[SnappedVertex],
        zfail: bool,
        increment: bool,
        st: &mut StencilStats,
    ) {
        let (w, h) = (self.width, self.height);
        let layout = eye.layout;
        let depth = &eye.depth;
        let counters = &mut self.counters;
        for_each_fan_tri(poly, |tri| {
            let Some((x0, x1, y0, y1)) = pixel_bounds(tri, Coverage::Standard, w, h) else {
                return;
            };
            let off = edge_offsets(tri, Coverage::Standard);
            let step = tri.e.map(|e| e.a * SUBPIXEL);
            for y in y0..=y1 {
                let mut e = tri.e.map(|e| e.at_pixel(x0, y));
                for x in x0..=x1 {
                    let covered = e[0] + off[0] >= 0 && e[1] + off[1] >= 0 && e[2] + off[2] >= 0;
                    if covered {
                        let d = depth[layout.pixel_index(x as u32, y as u32)];
                        if d != BACKGROUND {
                            st.pixels_processed += 1;
                            let z = pixel_depth(tri, Coverage::Standard, e);
                            // Strict reversed-Z test: pass iff strictly nearer.
                            if (z > d) != zfail {
                                st.stencil_updates += 1;
                                let i = y as usize * w as usize + x as usize;
                                match (&mut *counters, increment) {
                                    (Counters::Eight(c), true) => c[i] = c[i].wrapping_add(1),
                                    (Counters::Eight(c), false) => c[i] = c[i].wrapping_sub(1),
                                    (Counters::Wide(c), true) => c[i] = c[i].wrapping_add(1),
                                    (Counters::Wide(c), false) => c[i] = c[i].wrapping_sub(1),
                                }
                            }
                        }
                    }
                    for (e, s) in e.iter_mut().zip(&step) {
                        *e += s;
                    }
                }
            }
        });
    }
}
