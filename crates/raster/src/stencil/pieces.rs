//! From shadow volumes to set-up pieces: every volume triangle (and zp+
//! near-cap fan triangle) through the rasterizer's own clipping and snapping,
//! fanned into pieces counted by their own snapped orientation, with the
//! window (scissor rectangle and depth bounds) each volume's fragments may
//! touch.

use super::near_cap::fan_triangle;
use crate::coverage::Rect;
use crate::depth_target::DepthTarget;
use crate::edge::Tri;
use crate::layout::TileBounds;
use crate::setup::{setup_into, setup_near_plane_into, Setup, SnappedVertex, Viewport, SUBPIXEL};
use crate::volume_buffer::{VolumeBuffer, VolumeMethod, VolumeRange};
use crate::{Error, Result};
use glam::{Mat4, Vec4};

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

impl Window {
    /// The window's pixel rectangle.
    #[inline(always)]
    pub fn rect(&self) -> Rect {
        Rect {
            x0: self.x0,
            x1: self.x1,
            y0: self.y0,
            y1: self.y1,
        }
    }

    /// Whether the tile with bounds `tb` may hold written depth inside the
    /// depth window (a tile all background, or outside it, holds none).
    #[inline(always)]
    pub fn reaches(&self, tb: &TileBounds) -> bool {
        !(tb.zmax < self.dlo.max(0.0) || tb.zmin > self.dhi)
    }
}

/// One triangle's fill in one band: where it writes, what it tests and adds.
pub(super) struct Fill<'a, C> {
    /// The band's counters and touched flags, from tiled index `base`.
    pub counters: &'a mut [C],
    pub touched: &'a mut [u8],
    pub base: usize,
    pub width: u32,
    pub eye: &'a DepthTarget,
    pub tri: &'a Tri,
    pub rect: Rect,
    pub win: &'a Window,
    pub zfail: bool,
    pub delta: C,
}

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
/// behind it. Returns which fan pieces were drawn: bit `i − 1` for the piece
/// `(v0, v_i, v_i+1)` (a snapped polygon has at most
/// [`crate::clip::MAX_CLIPPED_VERTICES`] vertices).
pub(crate) fn push_pieces(
    poly: &[SnappedVertex],
    zfail: bool,
    job: u32,
    out: &mut Vec<Piece>,
) -> u32 {
    let mut drawn = 0;
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
            drawn |= 1 << (i - 1);
        }
    }
    drawn
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

/// Checks that `range` names only indices inside `buf` and positions that exist.
pub(crate) fn check_range(buf: &VolumeBuffer, range: &VolumeRange) -> Result<()> {
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
