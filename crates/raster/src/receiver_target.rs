//! Receiver marking for the light pass [Steiner §4.3.1; Bittner et al. 2011,
//! "Shadow caster culling for efficient shadow mapping"]: the eye's visible
//! surface points, projected into the light view, mark the light pixels they
//! fall on, keeping per pixel the farthest (smallest reversed-Z) receiver depth.
//!
//! A point marks every pixel whose closed square lies within
//! [`RECEIVER_EPS_PX`] pixels (Euclidean) of its projection.
//!
//! On request ([`ReceiverTarget::set_track_nearest`]) the target also keeps
//! the nearest receiver depth per pixel: with the farthest it bounds the
//! depths of the receivers over the pixel, which fragment-receiver clamping
//! reads [Steiner §4.4.1, Fig. 4.16].

use crate::depth_target::DepthTarget;

use crate::layout::Layout;
use crate::{Error, Result};
use glam::{DVec4, Mat4, Vec4};

/// Footprint of a receiver point, in pixels: it covers the f32 rounding of the
/// projection (below 2⁻¹⁰ px at 16384 px) with a wide margin.
pub const RECEIVER_EPS_PX: f64 = 1.0 / 64.0;

/// The farthest receiver depth per pixel of a light view (+∞ where unmarked),
/// and on request the nearest.
#[derive(Clone, Debug)]
pub struct ReceiverTarget {
    pub(crate) layout: Layout,
    pub(crate) depth: Vec<f32>,
    /// Per pixel the nearest (largest reversed-Z) marked depth, −∞ where
    /// unmarked; empty unless [`ReceiverTarget::set_track_nearest`] is on.
    near: Vec<f32>,
    /// Per tile the nearest marked depth (as `near`).
    tile_near: Vec<f32>,
    /// Per tile the smallest (farthest) marked depth, +∞ where none: a query
    /// sample can pass only at or in front of it, so a triangle wholly behind
    /// it skips the tile.
    pub(crate) tile_min: Vec<f32>,
    /// Per point of a parallel marking: its one pixel and depth, or a flag.
    #[cfg_attr(not(feature = "parallel"), allow(dead_code))]
    scratch: Vec<(u32, f32)>,
}

impl ReceiverTarget {
    /// An unmarked receiver target with the size and tiling of `target`.
    pub fn for_target(target: &DepthTarget) -> Self {
        ReceiverTarget::unmarked(target.layout, target.depth.len(), target.tiles.len())
    }

    /// An unmarked target of `layout`, `pixels` and `tiles` long (the
    /// padded tile-major sizes), without nearest depths.
    fn unmarked(layout: Layout, pixels: usize, tiles: usize) -> Self {
        ReceiverTarget {
            layout,
            depth: vec![f32::INFINITY; pixels],
            near: Vec::new(),
            tile_near: Vec::new(),
            tile_min: vec![f32::INFINITY; tiles],
            scratch: Vec::new(),
        }
    }

    /// An unmarked target with this one's size, tiling and nearest-depth
    /// tracking: a second target to mark part of one set of receivers in,
    /// in parallel, then [`ReceiverTarget::absorb`] it.
    pub fn unmarked_like(&self) -> Self {
        let mut r = ReceiverTarget::unmarked(self.layout, self.depth.len(), self.tile_min.len());
        r.set_track_nearest(self.tracks_nearest());
        r
    }

    /// Takes `other`'s marks into this target and unmarks `other`: per pixel
    /// the farther of the farthest depths and the nearer of the nearest.
    /// Marks are minima and maxima, so marking receivers partly here and
    /// partly in `other`, then absorbing, gives the marks of marking all of
    /// them here. Only `other`'s marked tiles are read.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when the two differ in size or tiling, or one
    /// tracks the nearest depths and the other does not.
    pub fn absorb(&mut self, other: &mut ReceiverTarget) -> Result<()> {
        let (a, b) = (self.layout, other.layout);
        if (a.width, a.height, a.shift) != (b.width, b.height, b.shift)
            || self.tracks_nearest() != other.tracks_nearest()
        {
            return Err(Error::SizeMismatch {
                expected: self.size(),
                got: other.size(),
            });
        }
        let n = a.tile_pixels();
        let tracking = self.tracks_nearest();
        for t in 0..self.tile_min.len() {
            if other.tile_min[t] == f32::INFINITY {
                continue;
            }
            let px = t * n..(t + 1) * n;
            for (d, &o) in self.depth[px.clone()]
                .iter_mut()
                .zip(&other.depth[px.clone()])
            {
                *d = d.min(o);
            }
            self.tile_min[t] = self.tile_min[t].min(other.tile_min[t]);
            if tracking {
                for (d, &o) in self.near[px.clone()].iter_mut().zip(&other.near[px]) {
                    *d = d.max(o);
                }
                self.tile_near[t] = self.tile_near[t].max(other.tile_near[t]);
            }
        }
        other.clear();
        Ok(())
    }

    /// Keeps (`true`) or stops keeping the nearest receiver depth per pixel
    /// beside the farthest, from the next mark on. Turning it on unmarks the
    /// target; off frees the nearest depths.
    pub fn set_track_nearest(&mut self, on: bool) {
        if on == self.tracks_nearest() {
            return;
        }
        if on {
            self.clear();
            self.near = vec![f32::NEG_INFINITY; self.depth.len()];
            self.tile_near = vec![f32::NEG_INFINITY; self.tile_min.len()];
        } else {
            self.near = Vec::new();
            self.tile_near = Vec::new();
        }
    }

    /// Whether the nearest receiver depth per pixel is kept.
    pub fn tracks_nearest(&self) -> bool {
        !self.near.is_empty()
    }

    /// The nearest receiver depth at pixel `(x, y)`, `None` when unmarked or
    /// when the nearest depths are not kept.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the target.
    pub fn nearest_at(&self, x: u32, y: u32) -> Option<f32> {
        assert!(x < self.layout.width && y < self.layout.height);
        let d = *self.near.get(self.layout.pixel_index(x, y))?;
        (d != f32::NEG_INFINITY).then_some(d)
    }

    /// Calls `f` with every tile of the inclusive rectangle `x0..=x1 ×
    /// y0..=y1` (cut to the target) that holds a mark, as [`TileMarks`].
    pub fn for_each_tile_in(
        &self,
        (x0, x1): (u32, u32),
        (y0, y1): (u32, u32),
        mut f: impl FnMut(&TileMarks<'_>),
    ) {
        let l = self.layout;
        if l.width == 0 || l.height == 0 {
            return;
        }
        let (x1, y1) = (x1.min(l.width - 1), y1.min(l.height - 1));
        if x0 > x1 || y0 > y1 {
            return;
        }
        for ty in y0 >> l.shift..=y1 >> l.shift {
            for tx in x0 >> l.shift..=x1 >> l.shift {
                let t = l.tile_index(tx, ty);
                let far = self.tile_min[t];
                if far == f32::INFINITY {
                    continue;
                }
                let (rx0, rx1, ry0, ry1) = l.tile_rect(tx, ty);
                f(&TileMarks {
                    target: self,
                    x: (rx0.max(x0), rx1.min(x1)),
                    y: (ry0.max(y0), ry1.min(y1)),
                    far,
                    near: self.tile_near.get(t).copied().unwrap_or(f32::INFINITY),
                });
            }
        }
    }

    /// Calls `f(x, y, farthest, nearest)` for every marked pixel of the
    /// inclusive rectangle `x0..=x1 × y0..=y1` (cut to the target), tile by
    /// tile, skipping tiles with no mark. Without
    /// [`ReceiverTarget::set_track_nearest`] the nearest depth passed is +∞
    /// (unknown: as near as can be).
    pub fn for_each_marked_in(
        &self,
        xs: (u32, u32),
        ys: (u32, u32),
        mut f: impl FnMut(u32, u32, f32, f32),
    ) {
        self.for_each_tile_in(xs, ys, |t| t.for_each_marked(&mut f));
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.layout.width, self.layout.height)
    }

    /// Unmarks every pixel (touching only the tiles that hold a mark, so a
    /// target reused across frames costs what was marked, not its size).
    pub fn clear(&mut self) {
        let n = self.layout.tile_pixels();
        for (t, m) in self.tile_min.iter_mut().enumerate() {
            if *m != f32::INFINITY {
                self.depth[t * n..(t + 1) * n].fill(f32::INFINITY);
                if let Some(near) = self.near.get_mut(t * n..(t + 1) * n) {
                    near.fill(f32::NEG_INFINITY);
                    self.tile_near[t] = f32::NEG_INFINITY;
                }
                *m = f32::INFINITY;
            }
        }
    }

    /// The farthest receiver depth at pixel `(x, y)`, `None` when unmarked.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the target.
    pub fn at(&self, x: u32, y: u32) -> Option<f32> {
        assert!(x < self.layout.width && y < self.layout.height);
        let d = self.depth[self.layout.pixel_index(x, y)];
        (d != f32::INFINITY).then_some(d)
    }

    /// Per pixel, row-major from the top row, the farthest receiver depth
    /// (`+∞` where unmarked), into `out` (cleared first): what a host backend
    /// uploads (as a texture, say) to restrict its queries.
    pub fn rows_into(&self, out: &mut Vec<f32>) {
        let (w, h) = self.size();
        out.clear();
        out.reserve((w * h) as usize);
        for y in 0..h {
            out.extend((0..w).map(|x| self.depth[self.layout.pixel_index(x, y)]));
        }
    }

    /// The receiver target of `target`'s size marked from row-major depths
    /// (`+∞` where unmarked), as [`ReceiverTarget::rows_into`] gives them.
    ///
    /// # Errors
    /// [`Error::MaskLength`] when `rows` does not hold one depth per pixel.
    pub fn from_rows(target: &DepthTarget, rows: &[f32]) -> Result<Self> {
        let mut r = ReceiverTarget::for_target(target);
        let (w, h) = r.size();
        if rows.len() != (w * h) as usize {
            return Err(Error::MaskLength {
                expected: (w * h) as usize,
                got: rows.len(),
                width: w,
                height: h,
            });
        }
        for y in 0..h {
            for x in 0..w {
                let z = rows[(y * w + x) as usize];
                if z != f32::INFINITY {
                    r.mark_pixel(r.layout.pixel_index(x, y), z, z);
                }
            }
        }
        Ok(r)
    }

    /// The tile rows `r0..r1` holding every marked pixel, `None` when none is
    /// marked (for [`DepthTarget::set_draw_rows`]).
    pub fn marked_rows(&self) -> Option<(u32, u32)> {
        let tx = self.layout.tiles_x as usize;
        let mut rows = self
            .tile_min
            .chunks(tx)
            .enumerate()
            .filter(|(_, r)| r.iter().any(|z| *z != f32::INFINITY))
            .map(|(k, _)| k as u32);
        let first = rows.next()?;
        let last = rows.next_back().unwrap_or(first);
        Some((first, last + 1))
    }

    /// Marks the points `clip_from_local · p`; points with clip w ≤ 0 (behind the
    /// light's centre of projection) are skipped. Returns the number of pixels marked
    /// (counting repeats).
    pub fn mark_points(&mut self, clip_from_local: Mat4, points: &[Vec4]) -> u64 {
        self.mark_points_within(clip_from_local, points, RECEIVER_EPS_PX)
    }

    /// [`ReceiverTarget::mark_points`] with footprint `eps_px` instead of
    /// [`RECEIVER_EPS_PX`]: 0 marks only the pixels whose closed square holds
    /// the f64 projection — the point-sampled (aggressive) receivers, which the
    /// projection's rounding can put one pixel off.
    pub fn mark_points_within(
        &mut self,
        clip_from_local: Mat4,
        points: &[Vec4],
        eps_px: f64,
    ) -> u64 {
        let pr = Projector::new(self.layout, clip_from_local, eps_px);
        #[cfg(feature = "parallel")]
        if points.len() >= PARALLEL_POINTS && rayon::current_num_threads() > 1 {
            return self.mark_parallel(&pr, points);
        }
        points.iter().map(|p| self.mark_one(&pr, p)).sum()
    }

    /// Marks the pixels of one point's footprint; returns how many.
    fn mark_one(&mut self, pr: &Projector, p: &Vec4) -> u64 {
        let Some(f) = pr.project(p) else {
            return 0;
        };
        let (l, eps) = (self.layout, pr.eps);
        let mut n = 0;
        for y in f.y0..=f.y1 {
            for x in f.x0..=f.x1 {
                let dx = (x as f64 - f.px).max(f.px - (x as f64 + 1.0)).max(0.0);
                let dy = (y as f64 - f.py).max(f.py - (y as f64 + 1.0)).max(0.0);
                if dx * dx + dy * dy <= eps * eps {
                    self.mark_pixel(l.pixel_index(x, y), f.z, f.z);
                    n += 1;
                }
            }
        }
        n
    }

    /// Marks pixel `i` (tile-major index) with a receiver depth range:
    /// `far` (smallest reversed-Z) and `near`.
    #[inline(always)]
    pub(crate) fn mark_pixel(&mut self, i: usize, far: f32, near: f32) {
        // Tile-major storage: a pixel's tile is its index over the tile size.
        let t = i >> (2 * self.layout.shift);
        // (Selects, one `minss` each, not the NaN-aware `min`: stored
        // depths are never NaN, and a NaN `far` marks nothing either way.)
        let (d, m) = (self.depth[i], self.tile_min[t]);
        self.depth[i] = if far < d { far } else { d };
        self.tile_min[t] = if far < m { far } else { m };
        if let Some(n) = self.near.get_mut(i) {
            *n = n.max(near);
            self.tile_near[t] = self.tile_near[t].max(near);
        }
    }

    /// Many points: the projections run in parallel, each point's footprint
    /// reduced to its one pixel (the common case) or flagged; then the pixel
    /// minima are taken in order, and flagged points marked one by one. The
    /// minima do not depend on order, so the result is the sequential one.
    #[cfg(feature = "parallel")]
    fn mark_parallel(&mut self, pr: &Projector, points: &[Vec4]) -> u64 {
        use rayon::prelude::*;
        const NONE: u32 = u32::MAX;
        const MANY: u32 = u32::MAX - 1;
        let l = self.layout;
        let mut one = std::mem::take(&mut self.scratch);
        one.resize(points.len(), (NONE, 0.0));
        one.par_iter_mut()
            .zip(points.par_iter())
            .with_min_len(4096)
            .for_each(|(o, p)| {
                *o = match pr.project(p) {
                    None => (NONE, 0.0),
                    Some(f) if f.x0 == f.x1 && f.y0 == f.y1 => {
                        let dx = (f.x0 as f64 - f.px)
                            .max(f.px - (f.x0 as f64 + 1.0))
                            .max(0.0);
                        let dy = (f.y0 as f64 - f.py)
                            .max(f.py - (f.y0 as f64 + 1.0))
                            .max(0.0);
                        if dx * dx + dy * dy <= pr.eps * pr.eps {
                            (l.pixel_index(f.x0, f.y0) as u32, f.z)
                        } else {
                            (NONE, 0.0)
                        }
                    }
                    Some(_) => (MANY, 0.0),
                }
            });
        let mut n = 0;
        for (k, &(i, z)) in one.iter().enumerate() {
            match i {
                NONE => {}
                MANY => n += self.mark_one(pr, &points[k]),
                _ => {
                    self.mark_pixel(i as usize, z, z);
                    n += 1;
                }
            }
        }
        self.scratch = one;
        n
    }

    /// Marks receiver segments: for each `(a, b)` (local points, clip
    /// `clip_from_local · p`), every pixel whose closed square lies within
    /// `eps_px` of the projected segment — a superset: the square widened by
    /// `eps_px` (plus [`SEGMENT_SLACK_PX`]) on each side meets it — with the
    /// farthest depth of the part of the segment within its widened square
    /// (and, with [`ReceiverTarget::set_track_nearest`] on, its nearest):
    /// depth z/w is affine along the projected segment. For receiver points
    /// lying on a segment (a row of eye pixels on one plane), this marks
    /// every pixel [`ReceiverTarget::mark_points_within`] would mark for
    /// them at a depth no nearer, with two projections per segment instead
    /// of one per point: the projective map keeps the points on the
    /// projected segment. A segment of any length marks as tightly as its
    /// pieces would, so a whole row of eye pixels on one plane is one
    /// segment. The part of a segment behind the centre of projection (clip
    /// w ≤ 0) or off the target is clipped away first, in homogeneous
    /// coordinates. Returns the number of pixels marked (counting repeats).
    pub fn mark_segments_within(
        &mut self,
        clip_from_local: Mat4,
        segments: impl IntoIterator<Item = (Vec4, Vec4)>,
        eps_px: f64,
    ) -> u64 {
        let pr = Projector::new(self.layout, clip_from_local, eps_px);
        let mut n = 0;
        // The pieces of one run of eye pixels come in order, each starting
        // at the end of the one before: that end is projected once.
        let mut last: Option<([u32; 4], ClipEnd)> = None;
        for (a, b) in segments {
            let bits = |v: Vec4| v.to_array().map(f32::to_bits);
            let ea = match last {
                Some((k, e)) if k == bits(a) => e,
                _ => pr.clip_end(&a),
            };
            let eb = pr.clip_end(&b);
            last = Some((bits(b), eb));
            n += self.mark_segment(&pr, pr.clip_ends(&ea, &eb));
        }
        n
    }

    /// Marks one clipped segment's pixels; returns how many.
    fn mark_segment(&mut self, pr: &Projector, segment: Option<Segment>) -> u64 {
        match segment {
            None => 0,
            Some(Segment::Everywhere(z)) => {
                // Near depths reach the light: unbounded.
                for i in 0..self.depth.len() {
                    self.mark_pixel(i, z, f32::INFINITY);
                }
                self.depth.len() as u64
            }
            Some(Segment::Span(span)) => {
                let l = self.layout;
                let mut n = 0;
                pr.for_each_span_pixel(&span, |x, y, far, near| {
                    self.mark_pixel(l.pixel_index(x, y), far, near);
                    n += 1;
                });
                n
            }
        }
    }
}

/// The marks of one tile within a rectangle ([`ReceiverTarget::for_each_tile_in`]).
pub struct TileMarks<'a> {
    target: &'a ReceiverTarget,
    /// Inclusive pixel columns of the tile within the rectangle.
    pub x: (u32, u32),
    /// Inclusive pixel rows of the tile within the rectangle.
    pub y: (u32, u32),
    /// The farthest marked depth of the whole tile.
    pub far: f32,
    /// The nearest marked depth of the whole tile (+∞ without
    /// [`ReceiverTarget::set_track_nearest`]).
    pub near: f32,
}

impl TileMarks<'_> {
    /// Calls `f(x, y, farthest, nearest)` for every marked pixel of the
    /// tile within the rectangle (nearest +∞ when not kept).
    pub fn for_each_marked(&self, mut f: impl FnMut(u32, u32, f32, f32)) {
        let r = self.target;
        for y in self.y.0..=self.y.1 {
            for x in self.x.0..=self.x.1 {
                let i = r.layout.pixel_index(x, y);
                let far = r.depth[i];
                if far != f32::INFINITY {
                    f(x, y, far, r.near.get(i).copied().unwrap_or(f32::INFINITY));
                }
            }
        }
    }
}

/// Extra widening of a segment's footprint, in pixels: covers the rounding
/// of the segment clip and of the band intersections (far below it for
/// targets up to [`crate::MAX_TARGET_SIZE`]), and receiver points computed
/// one by one lying off their segment by rounding.
pub const SEGMENT_SLACK_PX: f64 = 1.0 / 4096.0;

/// Points above which marking projects in parallel.
#[cfg(feature = "parallel")]
const PARALLEL_POINTS: usize = 1 << 16;

/// A clipped, projected receiver segment.
enum Segment {
    /// Ends in pixel coordinates and their depths.
    Span(SpanEnds),
    /// Reaches the centre of projection: marks every pixel at this depth.
    Everywhere(f32),
}

/// A segment end: its clip-space point and, when no clip plane cuts the
/// region there, its projection (pixel coordinates and depth).
#[derive(Clone, Copy)]
struct ClipEnd {
    c: DVec4,
    projected: Option<(f64, f64, f64)>,
}

/// The ends of a clipped, projected segment: pixel coordinates `p`, `q`
/// and their depths.
struct SpanEnds {
    p: (f64, f64),
    q: (f64, f64),
    zp: f64,
    zq: f64,
}

/// A point's projection and the pixel range its footprint may reach.
struct Footprint {
    px: f64,
    py: f64,
    z: f32,
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
}

/// Projects points into a receiver target's pixels.
pub(crate) struct Projector {
    pub(crate) m: Mat4,
    pub(crate) w: f64,
    pub(crate) h: f64,
    pub(crate) eps: f64,
    /// Clip-space reject bounds: a margin of two pixels (plus eps) per side.
    pub(crate) mx: f64,
    pub(crate) my: f64,
}

impl Projector {
    pub(crate) fn new(l: Layout, m: Mat4, eps_px: f64) -> Self {
        let (w, h) = (l.width as f64, l.height as f64);
        let eps = eps_px.max(0.0);
        Projector {
            m,
            w,
            h,
            eps,
            mx: 1.0 + 2.0 * (2.0 + eps) / w,
            my: 1.0 + 2.0 * (2.0 + eps) / h,
        }
    }

    /// The clip planes `(sx, sy, m)` of the region `|x| ≤ mx·w, |y| ≤ my·w`:
    /// inside, `m·w − (sx·x + sy·y) ≥ 0`.
    pub(crate) fn planes(&self) -> [(f64, f64, f64); 4] {
        [
            (1.0, 0.0, self.mx),
            (-1.0, 0.0, self.mx),
            (0.0, 1.0, self.my),
            (0.0, -1.0, self.my),
        ]
    }

    /// A segment end in clip space, projected when no plane cuts it there.
    #[inline(always)]
    fn clip_end(&self, p: &Vec4) -> ClipEnd {
        let c = (self.m * *p).as_dvec4();
        let inside = c.w > 0.0
            && self.planes().iter().all(|&(sx, sy, m)| {
                let f = m * c.w - (sx * c.x + sy * c.y);
                f.is_finite() && f >= 0.0
            });
        let projected = inside
            .then(|| self.project_clip(c))
            .filter(|p| p.0.is_finite() && p.1.is_finite());
        ClipEnd { c, projected }
    }

    /// Pixel coordinates and depth of the clip-space point `c`.
    #[inline(always)]
    pub(crate) fn project_clip(&self, c: DVec4) -> (f64, f64, f64) {
        let iw = 1.0 / c.w;
        (
            (c.x * iw + 1.0) * (0.5 * self.w),
            (1.0 - c.y * iw) * (0.5 * self.h),
            c.z * iw,
        )
    }

    /// The segment `a b` clipped to the region `|x| ≤ mx·w, |y| ≤ my·w`
    /// (which implies w ≥ 0) in clip space, projected: its ends in pixel
    /// coordinates and its farthest depth; `None` when nothing is left. An
    /// end no plane cuts is the end's own projection (the common case,
    /// taken without clipping).
    #[inline(always)]
    fn clip_ends(&self, a: &ClipEnd, b: &ClipEnd) -> Option<Segment> {
        if let (Some(p), Some(q)) = (a.projected, b.projected) {
            return Some(Segment::Span(SpanEnds {
                p: (p.0, p.1),
                q: (q.0, q.1),
                zp: p.2,
                zq: q.2,
            }));
        }
        self.clip_cut(a.c, b.c)
    }

    /// [`Projector::clip_ends`] where a plane may cut the segment.
    fn clip_cut(&self, c0: DVec4, c1: DVec4) -> Option<Segment> {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (sx, sy, m) in self.planes() {
            let f = |c: DVec4| m * c.w - (sx * c.x + sy * c.y);
            let (f0, f1) = (f(c0), f(c1));
            if !(f0.is_finite() && f1.is_finite()) || (f0 < 0.0 && f1 < 0.0) {
                return None;
            }
            if f0 < 0.0 {
                t0 = t0.max(f0 / (f0 - f1));
            } else if f1 < 0.0 {
                t1 = t1.min(f0 / (f0 - f1));
            }
        }
        if t0 > t1 {
            return None;
        }
        let end = |t: f64| {
            let c = match t {
                0.0 => c0,
                1.0 => c1,
                _ => c0 + (c1 - c0) * t,
            };
            let (x, y, z) = self.project_clip(c);
            (x, y, z, c.w)
        };
        let (p, q) = (end(t0), end(t1));
        if p.3 > 0.0 && q.3 > 0.0 {
            let finite = [p.0, p.1, q.0, q.1].iter().all(|v| v.is_finite());
            return finite.then_some(Segment::Span(SpanEnds {
                p: (p.0, p.1),
                q: (q.0, q.1),
                zp: p.2,
                zq: q.2,
            }));
        }
        // An end at the centre of projection (x = y = w = 0: the segment
        // runs into the light): points near it project anywhere, at depths
        // no farther than the other end's.
        let far = if p.3 > 0.0 { p.2 } else { q.2 };
        (far.is_finite() && (p.3 > 0.0 || q.3 > 0.0)).then_some(Segment::Everywhere(far as f32))
    }

    /// Calls `mark(x, y, far, near)` for every pixel whose square, widened
    /// by the footprint and [`SEGMENT_SLACK_PX`], the projected segment
    /// meets ([`ReceiverTarget::mark_segments_within`]), row by row.
    #[inline(always)]
    fn for_each_span_pixel(&self, span: &SpanEnds, mut mark: impl FnMut(u32, u32, f32, f32)) {
        let SpanEnds { p, q, zp, zq } = *span;
        let e = self.eps + SEGMENT_SLACK_PX;
        // Depth along the projected segment is affine in its screen
        // parameter (a line's image in normalized device coordinates is a
        // line): a pixel's depths are those of the part of the segment
        // within its widened square: a long segment marks each pixel as
        // tightly as its pieces would.
        let (dx, dz) = (q.0 - p.0, zq - zp);
        // Reciprocals once a segment: a product errs by an ulp or two of the
        // quotient, far inside the slack.
        let (dy, rdx) = (q.1 - p.1, 1.0 / dx);
        let rdy = 1.0 / dy;
        // Rows whose widened band [y − e, y + 1 + e] the segment meets.
        let (ylo, yhi) = (p.1.min(q.1), p.1.max(q.1));
        let y0 = (-floor(1.0 + e - ylo)).max(0.0);
        let y1 = floor(yhi + e).min(self.h - 1.0);
        if y0 > y1 {
            return;
        }
        for y in y0 as u32..=y1 as u32 {
            // The segment's x extent within the band.
            let (b0, b1) = (y as f64 - e, y as f64 + 1.0 + e);
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            if dy == 0.0 {
                if p.1 < b0 || p.1 > b1 {
                    continue;
                }
            } else if ylo < b0 || yhi > b1 {
                // (Wholly inside the band, the clip below gives 0 and 1
                // exactly: rounding is monotone. Skipped.)
                let (ta, tb) = ((b0 - p.1) * rdy, (b1 - p.1) * rdy);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
                if t0 > t1 {
                    continue;
                }
            }
            let (xa, xb) = (p.0 + t0 * (q.0 - p.0), p.0 + t1 * (q.0 - p.0));
            let (xlo, xhi) = (xa.min(xb), xa.max(xb));
            let x0 = (-floor(1.0 + e - xlo)).max(0.0);
            let x1 = floor(xhi + e).min(self.w - 1.0);
            if x0 > x1 {
                continue;
            }
            for x in x0 as u32..=x1 as u32 {
                let (mut u0, mut u1) = (t0, t1);
                if dx != 0.0 {
                    let xf = f64::from(x);
                    let (ta, tb) = ((xf - e - p.0) * rdx, (xf + 1.0 + e - p.0) * rdx);
                    u0 = u0.max(ta.min(tb));
                    u1 = u1.min(ta.max(tb));
                    if u0 > u1 {
                        // Rounding at the band's edge: the row's part.
                        (u0, u1) = (t0, t1);
                    }
                }
                let (za, zb) = (zp + dz * u0, zp + dz * u1);
                let (far, nearest) = (za.min(zb) as f32, za.max(zb) as f32);
                mark(x, y, far, nearest);
            }
        }
    }

    /// The footprint of `p`, `None` when it marks nothing (behind the centre
    /// of projection, off the target, not finite).
    #[inline(always)]
    fn project(&self, p: &Vec4) -> Option<Footprint> {
        let c = (self.m * *p).as_dvec4();
        let outside = c.x.abs() > self.mx * c.w || c.y.abs() > self.my * c.w;
        if c.w.is_nan() || c.w <= 0.0 || outside {
            return None;
        }
        // One division: the reciprocal's rounding (a few ulps of the
        // projection) is far inside the footprint's margin.
        let (px, py, z) = self.project_clip(c);
        if !(px.is_finite() && py.is_finite()) {
            return None;
        }
        let eps = self.eps;
        // Pixel squares [x, x + 1] within eps: ceil(px − eps − 1) ..= floor(px + eps).
        let x0 = (-floor(1.0 + eps - px)).max(0.0);
        let x1 = floor(px + eps).min(self.w - 1.0);
        let y0 = (-floor(1.0 + eps - py)).max(0.0);
        let y1 = floor(py + eps).min(self.h - 1.0);
        if x0 > x1 || y0 > y1 {
            return None;
        }
        Some(Footprint {
            px,
            py,
            z: z as f32,
            x0: x0 as u32,
            x1: x1 as u32,
            y0: y0 as u32,
            y1: y1 as u32,
        })
    }
}

/// `v.floor()` for |v| < 2⁵¹, without the libm call the baseline x86-64
/// target makes (the marking loop calls it four times per point and view)
/// and without integer conversions: adding and subtracting 1.5 · 2⁵²
/// rounds `v` to an integer (to nearest, either sign), stepped down by a
/// select where that is above `v`. (A version that branched on the sign
/// made city_16384 bird's light pass about 8 % slower.)
#[inline(always)]
pub(crate) fn floor(v: f64) -> f64 {
    const ROUND: f64 = 6_755_399_441_055_744.0; // 1.5 · 2⁵²
    let t = (v + ROUND) - ROUND;
    t - if t > v { 1.0 } else { 0.0 }
}

impl DepthTarget {
    /// Restricts draws to the tiles `receivers` marks (`None`: every tile),
    /// from now until the next call, across clears: the other tiles hold
    /// bounds nearer than any depth (`zmin = zmax = +∞`, no background), so
    /// every draw's hierarchical-z test rejects them and their pixels stay
    /// background. For a light view, whose queries count samples only over
    /// receiver-marked pixels (a query's floor there is the receivers' own
    /// `+∞`): occluders are drawn only where a query can pass, and a face
    /// with a few receivers draws a few tiles. A hidden tile's bounds are
    /// not its pixels' ([`DepthTarget::tile_bounds`]); queries without
    /// receivers would see them as occluded.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `receivers` is not this target's size.
    pub fn set_draw_tiles(&mut self, receivers: Option<&ReceiverTarget>) -> Result<()> {
        let Some(r) = receivers else {
            self.hide_tiles(std::iter::empty());
            return Ok(());
        };
        if r.size() != (self.width(), self.height()) {
            return Err(Error::SizeMismatch {
                expected: (self.width(), self.height()),
                got: r.size(),
            });
        }
        let unmarked = (r.tile_min.iter().enumerate())
            .filter(|(_, z)| **z == f32::INFINITY)
            .map(|(t, _)| t as u32);
        self.hide_tiles(unmarked);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth_target::tests::draw_pair;
    use crate::TileSize;

    /// Draws skip the tiles without receivers, which stay background across
    /// clears; the marked tiles get what an unrestricted draw writes; `None`
    /// gives every tile back.
    #[test]
    fn draw_tiles_restrict_draws_to_marked_tiles() {
        let mut full = DepthTarget::new(37, 29, TileSize::T8, false).unwrap();
        draw_pair(&mut full);
        let mut marks = ReceiverTarget::for_target(&full);
        let points = [
            Vec4::new(-0.9, -0.9, 0.5, 1.0),
            Vec4::new(0.3, 0.2, 0.5, 1.0),
        ];
        marks.mark_points(Mat4::IDENTITY, &points);
        let mut t = DepthTarget::new(37, 29, TileSize::T8, false).unwrap();
        t.set_draw_tiles(Some(&marks)).unwrap();
        t.clear();
        draw_pair(&mut t);
        let l = t.layout;
        let (mut kept, mut skipped) = (0, 0);
        for y in 0..29 {
            for x in 0..37 {
                let marked = marks.tile_min[l.tile_index(x >> 3, y >> 3)] != f32::INFINITY;
                if marked {
                    assert_eq!(t.depth_at(x, y), full.depth_at(x, y), "({x}, {y})");
                    kept += usize::from(full.depth_at(x, y).is_some());
                } else {
                    assert_eq!(t.depth_at(x, y), None, "({x}, {y}) is hidden");
                    skipped += usize::from(full.depth_at(x, y).is_some());
                }
            }
        }
        assert!(kept > 0 && skipped > 0, "{kept} kept, {skipped} skipped");
        let small = DepthTarget::new(36, 29, TileSize::T8, false).unwrap();
        let other = ReceiverTarget::for_target(&small);
        assert!(t.set_draw_tiles(Some(&other)).is_err());
        t.set_draw_tiles(None).unwrap();
        t.clear();
        draw_pair(&mut t);
        assert_eq!(t.depth_rows(), full.depth_rows());
        assert_eq!(t.tiles, full.tiles, "every tile's bounds back");
    }

    /// The marking's floor is `f64::floor` over the pixel range and its
    /// margins: integers, halves, values just off an integer, both zeros.
    #[test]
    fn floor_matches_std() {
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e-300, -1e-300];
        for big in [1e6, 2f64.powi(40), 2f64.powi(50)] {
            values.extend([big + 0.5, -big - 0.5, big.next_down(), -big.next_up()]);
        }
        for k in -20_000i32..20_000 {
            let v = f64::from(k) * 0.37;
            values.extend([
                v,
                v.next_up(),
                v.next_down(),
                v.round(),
                v.round().next_down(),
            ]);
        }
        for v in values {
            assert_eq!(floor(v), v.floor(), "floor({v:e})");
        }
    }

    /// The per-tile bound is the farthest marked depth of the tile's pixels
    /// (+∞ for tiles with none), after any sequence of marks.
    #[test]
    fn tile_bounds_are_the_farthest_marked_depth() {
        let t = DepthTarget::new(37, 29, TileSize::T8, false).unwrap();
        let mut r = ReceiverTarget::for_target(&t);
        r.set_track_nearest(true);
        let points: Vec<Vec4> = (0..200)
            .map(|k| {
                let f = k as f32;
                // The left half only: the right tiles stay unmarked.
                let (x, y) = (-(f * 0.37).sin().abs(), (f * 0.91).cos());
                Vec4::new(x, y, 0.1 + (f * 0.13).sin().abs() * 0.8, 1.0)
            })
            .collect();
        r.mark_points(Mat4::IDENTITY, &points[..120]);
        r.mark_points(Mat4::IDENTITY, &points[120..]);
        let (tx_n, ty_n) = t.tile_counts();
        let mut marked_tiles = 0;
        for ty in 0..ty_n {
            for tx in 0..tx_n {
                let (mut m, mut near) = (f32::INFINITY, f32::NEG_INFINITY);
                for y in ty * 8..((ty + 1) * 8).min(29) {
                    for x in tx * 8..((tx + 1) * 8).min(37) {
                        m = m.min(r.at(x, y).unwrap_or(f32::INFINITY));
                        near = near.max(r.nearest_at(x, y).unwrap_or(f32::NEG_INFINITY));
                    }
                }
                assert_eq!(r.tile_near[r.layout.tile_index(tx, ty)], near);
                assert_eq!(
                    r.tile_min[r.layout.tile_index(tx, ty)],
                    m,
                    "tile ({tx}, {ty})"
                );
                marked_tiles += usize::from(m.is_finite());
            }
        }
        assert!(marked_tiles > 5 && marked_tiles < (tx_n * ty_n) as usize);
        let rows: Vec<u32> = (0..ty_n)
            .filter(|&ty| (0..tx_n).any(|tx| r.tile_min[r.layout.tile_index(tx, ty)].is_finite()))
            .collect();
        assert_eq!(r.marked_rows(), Some((rows[0], rows[rows.len() - 1] + 1)));
        r.clear();
        assert_eq!(r.marked_rows(), None);
        assert!(r.tile_min.iter().all(|z| z.is_infinite()));
        assert!(r.tile_near.iter().all(|z| *z == f32::NEG_INFINITY));
    }

    #[test]
    fn marks_pixels_near_the_point_keeping_the_farthest() {
        let t = DepthTarget::new(8, 8, TileSize::T4, false).unwrap();
        let mut r = ReceiverTarget::for_target(&t);
        // Pixel centre of (2, 5): x = 2.5 → ndc −0.375; y = 5.5 → ndc −0.375.
        r.mark_points(Mat4::IDENTITY, &[Vec4::new(-0.375, -0.375, 0.5, 1.0)]);
        r.mark_points(Mat4::IDENTITY, &[Vec4::new(-0.375, -0.375, 0.25, 1.0)]);
        assert_eq!(r.at(2, 5), Some(0.25));
        assert_eq!(r.at(3, 5), None);
        // A point on the corner shared by four pixels marks all four.
        r.mark_points(Mat4::IDENTITY, &[Vec4::new(0.0, 0.0, 0.5, 1.0)]);
        for (x, y) in [(3, 3), (4, 3), (3, 4), (4, 4)] {
            assert_eq!(r.at(x, y), Some(0.5));
        }
        assert_eq!(r.at(5, 4), None);
    }

    /// A long segment marks each pixel at the depths of its own part there
    /// (affine along it), not at the whole segment's farthest: with or
    /// without nearest depths kept, so one segment per row of eye pixels
    /// is as tight as many short pieces.
    #[test]
    fn long_segments_mark_each_pixel_at_its_part() {
        let (w, h) = (64u32, 8u32);
        let t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        let ndc = |px: f32| 2.0 * px / w as f32 - 1.0;
        let y = 1.0 - 2.0 * 3.5 / h as f32;
        let (za, zb) = (0.9f64, 0.1f64);
        // From the centre of pixel 0 to that of pixel w − 1, depth falling.
        let (a, b) = (
            Vec4::new(ndc(0.5), y, za as f32, 1.0),
            Vec4::new(ndc(w as f32 - 0.5), y, zb as f32, 1.0),
        );
        let z_at = |px: f64| {
            let s = ((px - 0.5) / (f64::from(w) - 1.0)).clamp(0.0, 1.0);
            za + (zb - za) * s
        };
        let e = RECEIVER_EPS_PX + SEGMENT_SLACK_PX;
        for track in [false, true] {
            let mut r = ReceiverTarget::for_target(&t);
            r.set_track_nearest(track);
            r.mark_segments_within(Mat4::IDENTITY, [(a, b)], RECEIVER_EPS_PX);
            for x in 0..w {
                let x0 = f64::from(x);
                let (far, near) = (z_at(x0 + 1.0 + e), z_at(x0 - e));
                let got = r.at(x, 3).expect("marked");
                assert!(
                    (f64::from(got) - far).abs() < 1e-6,
                    "pixel {x}: {got} vs {far}"
                );
                if track {
                    let n = r.nearest_at(x, 3).expect("marked");
                    assert!(
                        (f64::from(n) - near).abs() < 1e-6,
                        "pixel {x}: {n} vs {near}"
                    );
                }
            }
        }
    }

    /// The parallel path (many points) marks exactly what the sequential
    /// one does, repeats counted alike.
    #[cfg(feature = "parallel")]
    #[test]
    fn parallel_marking_equals_sequential() {
        let t = DepthTarget::new(97, 61, TileSize::T8, false).unwrap();
        let n = PARALLEL_POINTS * 2 + 17;
        let points: Vec<Vec4> = (0..n)
            .map(|k| {
                let f = k as f32;
                let w = 0.5 + (f * 0.017).sin().abs();
                let (x, y) = ((f * 0.37).sin() * 1.1, (f * 0.91).cos() * 1.1);
                Vec4::new(x * w, y * w, (f * 0.13).sin().abs() * w, w)
            })
            .collect();
        for eps in [0.0, RECEIVER_EPS_PX, 0.6] {
            let mut a = ReceiverTarget::for_target(&t);
            let mut b = ReceiverTarget::for_target(&t);
            let m = Mat4::from_scale(glam::Vec3::new(1.0, 1.0, 1.0));
            let na = a.mark_points_within(m, &points, eps);
            let nb: u64 = points
                .chunks(1000)
                .map(|c| b.mark_points_within(m, c, eps))
                .sum();
            assert_eq!(na, nb, "eps {eps}");
            assert_eq!(a.depth, b.depth, "eps {eps}");
            assert_eq!(a.tile_min, b.tile_min, "eps {eps}");
            assert!(na > n as u64 / 2);
        }
    }

    /// Absorbing needs one size and one tracking mode.
    #[test]
    fn absorb_rejects_other_targets() {
        let t = DepthTarget::new(29, 21, TileSize::T8, false).unwrap();
        let u = DepthTarget::new(30, 21, TileSize::T8, false).unwrap();
        let mut a = ReceiverTarget::for_target(&t);
        assert!(a.absorb(&mut ReceiverTarget::for_target(&u)).is_err());
        let mut b = a.unmarked_like();
        b.set_track_nearest(true);
        assert!(a.absorb(&mut b).is_err());
        assert!(a.absorb(&mut a.unmarked_like()).is_ok());
    }

    /// A segment's ends and depths, or the "everywhere" depth, as bits.
    fn segment_bits(s: Option<Segment>) -> Option<Vec<u64>> {
        s.map(|s| match s {
            Segment::Span(e) => [e.p.0, e.p.1, e.q.0, e.q.1, e.zp, e.zq]
                .map(f64::to_bits)
                .to_vec(),
            Segment::Everywhere(z) => vec![u64::from(z.to_bits())],
        })
    }

    proptest::proptest! {
        /// Pieces that share their ends, marked in one call (each shared
        /// end projected once, uncut segments not clipped), mark what each
        /// piece marks in a call of its own, and an uncut segment's ends
        /// are those the clip computes: chains reaching behind the centre
        /// of projection and off the target too.
        #[test]
        fn chained_pieces_mark_as_single_pieces(
            pts in proptest::collection::vec(
                (-1.6f32..1.6, -1.6f32..1.6, 0.0f32..1.0, -0.2f32..2.0),
                2..30,
            ),
            track in proptest::bool::ANY,
        ) {
            let t = DepthTarget::new(29, 21, TileSize::T8, false).unwrap();
            let points: Vec<Vec4> = pts
                .iter()
                .map(|&(x, y, z, w)| Vec4::new(x * w, y * w, z * w, w))
                .collect();
            let pieces: Vec<(Vec4, Vec4)> = points.windows(2).map(|p| (p[0], p[1])).collect();
            let mut chained = ReceiverTarget::for_target(&t);
            let mut single = ReceiverTarget::for_target(&t);
            chained.set_track_nearest(track);
            single.set_track_nearest(track);
            let eps = RECEIVER_EPS_PX;
            let n = chained.mark_segments_within(Mat4::IDENTITY, pieces.iter().copied(), eps);
            let m: u64 = pieces
                .iter()
                .map(|&p| single.mark_segments_within(Mat4::IDENTITY, [p], eps))
                .sum();
            proptest::prop_assert_eq!(n, m);
            proptest::prop_assert_eq!(&chained.depth, &single.depth);
            proptest::prop_assert_eq!(&chained.near, &single.near);
            proptest::prop_assert_eq!(&chained.tile_min, &single.tile_min);
            // Split between two targets, then absorbed: the same marks, and
            // the absorbed target unmarked.
            let half = pieces.len() / 2;
            let mut first = ReceiverTarget::for_target(&t);
            first.set_track_nearest(track);
            let mut second = first.unmarked_like();
            first.mark_segments_within(Mat4::IDENTITY, pieces[..half].iter().copied(), eps);
            second.mark_segments_within(Mat4::IDENTITY, pieces[half..].iter().copied(), eps);
            first.absorb(&mut second).unwrap();
            proptest::prop_assert_eq!(&first.depth, &chained.depth);
            proptest::prop_assert_eq!(&first.near, &chained.near);
            proptest::prop_assert_eq!(&first.tile_min, &chained.tile_min);
            proptest::prop_assert_eq!(&first.tile_near, &chained.tile_near);
            proptest::prop_assert!(second.depth.iter().all(|z| z.is_infinite()));
            proptest::prop_assert!(second.near.iter().all(|z| *z == f32::NEG_INFINITY));
            proptest::prop_assert!(second.tile_min.iter().all(|z| z.is_infinite()));
            let pr = Projector::new(t.layout, Mat4::IDENTITY, eps);
            for (a, b) in pieces {
                let (ea, eb) = (pr.clip_end(&a), pr.clip_end(&b));
                proptest::prop_assert_eq!(
                    segment_bits(pr.clip_ends(&ea, &eb)),
                    segment_bits(pr.clip_cut(ea.c, eb.c))
                );
            }
        }

        /// Marking equals its definition, pixel by pixel: the farthest depth
        /// of the points whose projection lies within `eps` of the pixel's
        /// closed square (points off-target by up to 3 px, behind the centre
        /// of projection, on pixel edges); `clear` unmarks everything.
        #[test]
        fn marks_match_the_definition(
            pts in proptest::collection::vec(
                (-1.4f32..1.4, -1.4f32..1.4, 0.0f32..1.0, -0.2f32..2.0, proptest::bool::ANY),
                1..40,
            ),
            eps_k in 0usize..3,
        ) {
            let eps = [0.0, RECEIVER_EPS_PX, 0.7][eps_k];
            let (w, h) = (23u32, 17u32);
            let t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
            let mut r = ReceiverTarget::for_target(&t);
            r.set_track_nearest(true);
            // Some points snapped to pixel edges (ndc multiples of 2/w).
            let points: Vec<Vec4> = pts
                .iter()
                .map(|&(x, y, z, pw, snap)| {
                    let (x, y) = if snap {
                        ((x * w as f32 * 0.5).round() * 2.0 / w as f32, (y * h as f32 * 0.5).round() * 2.0 / h as f32)
                    } else {
                        (x, y)
                    };
                    Vec4::new(x * pw, y * pw, z * pw, pw)
                })
                .collect();
            r.mark_points_within(Mat4::IDENTITY, &points, eps);
            for y in 0..h {
                for x in 0..w {
                    let (mut want, mut near) = (f32::INFINITY, f32::NEG_INFINITY);
                    for p in &points {
                        let c = p.as_dvec4();
                        if c.w <= 0.0 {
                            continue;
                        }
                        // The projection in the marking's own f64 arithmetic.
                        let iw = 1.0 / c.w;
                        let px = (c.x * iw + 1.0) * (0.5 * f64::from(w));
                        let py = (1.0 - c.y * iw) * (0.5 * f64::from(h));
                        let dx = (f64::from(x) - px).max(px - f64::from(x + 1)).max(0.0);
                        let dy = (f64::from(y) - py).max(py - f64::from(y + 1)).max(0.0);
                        if dx * dx + dy * dy <= eps * eps {
                            want = want.min((c.z * iw) as f32);
                            near = near.max((c.z * iw) as f32);
                        }
                    }
                    proptest::prop_assert_eq!(r.at(x, y), (want != f32::INFINITY).then_some(want), "pixel ({}, {})", x, y);
                    proptest::prop_assert_eq!(r.nearest_at(x, y), (near != f32::NEG_INFINITY).then_some(near), "pixel ({}, {})", x, y);
                    let mut seen = None;
                    r.for_each_marked_in((x, x), (y, y), |_, _, f, n| seen = Some((f, n)));
                    proptest::prop_assert_eq!(seen, r.at(x, y).zip(r.nearest_at(x, y)));
                }
            }
            r.clear();
            proptest::prop_assert!(r.depth.iter().all(|z| z.is_infinite()));
            proptest::prop_assert!(r.near.iter().all(|z| *z == f32::NEG_INFINITY));
            proptest::prop_assert!(r.tile_min.iter().all(|z| z.is_infinite()));
        }
    }
}
