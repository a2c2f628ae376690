//! Triangle setup: facing from the 2D-homogeneous determinant, homogeneous
//! clipping ([`crate::clip`]), projection and snapping to the fixed-point grid.
//!
//! Snapping: screen coordinates (pixels, row 0 at the top) are rounded to
//! multiples of `1/`[`SUBPIXEL`] pixel and stored as `i64`. All later coverage
//! decisions are exact integer arithmetic on these snapped vertices.

use crate::clip::{clip_planes, clip_triangle, ClipOutcome, MAX_CLIPPED_VERTICES};
use crate::{GUARD_BAND_PX, MAX_TARGET_SIZE};
use glam::{DVec4, Vec4};

/// Sub-pixel steps per pixel (8 bits of sub-pixel precision).
pub const SUBPIXEL: i64 = 256;

/// Which side of a triangle the view sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Facing {
    /// Counter-clockwise in normalized device coordinates (y up): the front (GL convention).
    Front,
    /// Clockwise in normalized device coordinates.
    Back,
}

/// A vertex after clipping and snapping.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SnappedVertex {
    /// x in 1/[`SUBPIXEL`] pixels, 0 at the left edge of the target.
    pub x: i64,
    /// y in 1/[`SUBPIXEL`] pixels, 0 at the top edge of the target.
    pub y: i64,
    /// Depth `z/w` (reversed Z: 1 at the near plane, 0 at infinity), in f64.
    pub z: f64,
}

/// The result of setting up one triangle.
#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// Facing of the visible part, `None` for an edge-on (zero-determinant) triangle.
    pub facing: Option<Facing>,
    /// Whether a clip plane cut the triangle.
    pub clipped: bool,
    /// The clipped, snapped convex polygon (a fan from vertex 0), `len` of them valid;
    /// `len == 0` when nothing is left.
    pub vertices: [SnappedVertex; MAX_CLIPPED_VERTICES],
    /// Number of valid entries in `vertices`.
    pub len: usize,
}

impl Setup {
    /// The valid vertices.
    pub fn polygon(&self) -> &[SnappedVertex] {
        &self.vertices[..self.len]
    }
}

/// Viewport constants shared by setup and traversal.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Viewport {
    pub width: u32,
    pub height: u32,
    planes: [DVec4; 6],
}

impl Viewport {
    pub fn new(width: u32, height: u32) -> Self {
        debug_assert!(width <= MAX_TARGET_SIZE && height <= MAX_TARGET_SIZE);
        let gx = 1.0 + 2.0 * GUARD_BAND_PX / width as f64;
        let gy = 1.0 + 2.0 * GUARD_BAND_PX / height as f64;
        Viewport {
            width,
            height,
            planes: clip_planes(gx, gy),
        }
    }
}

/// Largest snapped coordinate magnitude: (2^15 pixels) · SUBPIXEL.
const SNAP_LIMIT: f64 = (1i64 << 23) as f64;

/// Facing of the triangle with clip-space vertices `v` (any w, including 0 and negative):
/// the sign of `det[x y w]`, evaluated in f64.
#[inline]
pub fn facing(v: [Vec4; 3]) -> Option<Facing> {
    facing_f64(v.map(|p| p.as_dvec4()))
}

/// [`facing`] of f64 clip-space vertices.
#[inline(always)]
pub(crate) fn facing_f64(d: [DVec4; 3]) -> Option<Facing> {
    let det = d[0].x * (d[1].y * d[2].w - d[2].y * d[1].w)
        - d[1].x * (d[0].y * d[2].w - d[2].y * d[0].w)
        + d[2].x * (d[0].y * d[1].w - d[1].y * d[0].w);
    if det > 0.0 {
        Some(Facing::Front)
    } else if det < 0.0 {
        Some(Facing::Back)
    } else {
        None
    }
}

/// Sets up a triangle given in clip space for a `width × height` target.
///
/// Returns the facing and the clipped, snapped polygon. Degenerate (edge-on)
/// triangles and triangles wholly outside a clip plane come back with `len == 0`.
///
/// # Panics
/// In debug builds, when a side exceeds [`MAX_TARGET_SIZE`].
pub fn setup_triangle(v: [Vec4; 3], width: u32, height: u32) -> Setup {
    setup_with(v, &Viewport::new(width, height))
}

pub(crate) fn setup_with(v: [Vec4; 3], vp: &Viewport) -> Setup {
    let mut s = Setup {
        facing: None,
        clipped: false,
        vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
        len: 0,
    };
    setup_into(v, vp, &mut s);
    s
}

/// Projects and snaps a clip-space vertex with `w > 0`; false for `w ≤ 0` (only the
/// zero vector gets here with it).
#[inline(always)]
fn snap(p: DVec4, vp: &Viewport, out: &mut SnappedVertex) -> bool {
    if p.w.is_nan() || p.w <= 0.0 {
        return false;
    }
    let (hw, hh) = (0.5 * vp.width as f64, 0.5 * vp.height as f64);
    let sub = SUBPIXEL as f64;
    let x = ((p.x / p.w + 1.0) * hw * sub).round();
    let y = ((1.0 - p.y / p.w) * hh * sub).round();
    *out = SnappedVertex {
        x: x.clamp(-SNAP_LIMIT, SNAP_LIMIT) as i64,
        y: y.clamp(-SNAP_LIMIT, SNAP_LIMIT) as i64,
        z: (p.z / p.w).clamp(0.0, 1.0),
    };
    true
}

/// [`setup_triangle`] into caller-owned storage (no copies of the polygon).
#[inline(always)]
pub(crate) fn setup_into(v: [Vec4; 3], vp: &Viewport, s: &mut Setup) {
    setup_planes(v.map(|p| p.as_dvec4()), &vp.planes, vp, s);
}

/// [`setup_into`] for a triangle given in f64 clip coordinates that lies in the near
/// plane (`z = w` up to rounding, as [`crate::clip::near_segment`] makes them): it is
/// clipped against the far and guard-band planes only, so the near-plane points keep
/// exactly the values they have as vertices of near-clipped triangles.
pub(crate) fn setup_near_plane_into(d: [DVec4; 3], vp: &Viewport, s: &mut Setup) {
    let p = &vp.planes;
    setup_planes(d, &[p[1], p[2], p[3], p[4], p[5]], vp, s);
}

#[inline(always)]
fn setup_planes<const N: usize>(d: [DVec4; 3], planes: &[DVec4; N], vp: &Viewport, s: &mut Setup) {
    s.facing = facing_f64(d);
    s.clipped = false;
    s.len = 0;
    if s.facing.is_none() {
        return;
    }
    let inside = d.iter().all(|p| planes.iter().all(|pl| pl.dot(*p) >= 0.0));
    if inside {
        for (p, out) in d.iter().zip(&mut s.vertices) {
            if !snap(*p, vp, out) {
                return;
            }
        }
        s.len = 3;
        return;
    }
    let (outcome, poly) = clip_triangle(d, planes);
    if outcome == ClipOutcome::Culled {
        return;
    }
    s.clipped = outcome == ClipOutcome::Clipped;
    for i in 0..poly.len {
        if !snap(poly.v[i], vp, &mut s.vertices[i]) {
            return;
        }
    }
    s.len = poly.len;
}

/// Most vertices a mesh may have to use the per-vertex cache of [`VertexCache`]
/// (a box's eight: the cache is built, moved and cleared once per mesh, so it is
/// kept small).
pub(crate) const CACHE_VERTICES: usize = 8;

/// Per-vertex setup of a small mesh (a box): clip position, whether the vertex lies
/// inside every clip plane, and its snapped position. A triangle whose three
/// vertices are inside takes them from here instead of recomputing them — the same
/// values [`setup_into`] computes.
pub(crate) struct VertexCache {
    clip: [Vec4; CACHE_VERTICES],
    inside: [bool; CACHE_VERTICES],
    snapped: [SnappedVertex; CACHE_VERTICES],
    len: usize,
}

impl VertexCache {
    /// Vertices processed together, lane by lane.
    const L: usize = 8;

    /// An empty cache, to fill in place with [`VertexCache::transform_into`]
    /// (the cache is a few hundred bytes: built where it is used, not moved).
    #[inline(always)]
    pub fn empty() -> Self {
        VertexCache {
            clip: [Vec4::ZERO; CACHE_VERTICES],
            inside: [false; CACHE_VERTICES],
            snapped: [SnappedVertex::default(); CACHE_VERTICES],
            len: 0,
        }
    }

    /// Stage 1: the clip positions of `positions` (at most [`CACHE_VERTICES`]),
    /// the glam product of [`setup_into`] (so the same values). Enough for the
    /// screen bounds of a mesh; [`VertexCache::snap`] completes the cache.
    #[inline(always)]
    pub fn transform_into(&mut self, m: &glam::Mat4, positions: &[Vec4]) {
        debug_assert!(positions.len() <= CACHE_VERTICES);
        self.len = positions.len();
        for (o, p) in self.clip.iter_mut().zip(positions) {
            *o = *m * *p;
        }
    }

    /// The clip positions.
    #[inline(always)]
    pub fn clip(&self) -> &[Vec4] {
        &self.clip[..self.len]
    }

    /// Stage 2: whether each vertex lies inside every clip plane, and its snapped
    /// position — [`snap`] and the plane tests of `DVec4::dot`, written lane by
    /// lane, eight vertices at a time (the last chunk padded with copies of its
    /// first vertex) so that the compiler vectorizes them; the values are the same.
    #[inline(always)]
    pub fn snap(&mut self, vp: &Viewport) {
        const L: usize = VertexCache::L;
        let (hw, hh) = (0.5 * vp.width as f64, 0.5 * vp.height as f64);
        let sub = SUBPIXEL as f64;
        for base in (0..self.len).step_by(L) {
            let n = (self.len - base).min(L);
            let v = |k: usize| self.clip[base + if k < n { k } else { 0 }];
            let x: [f64; L] = std::array::from_fn(|k| v(k).x as f64);
            let y: [f64; L] = std::array::from_fn(|k| v(k).y as f64);
            let z: [f64; L] = std::array::from_fn(|k| v(k).z as f64);
            let w: [f64; L] = std::array::from_fn(|k| v(k).w as f64);
            let mut inside = [true; L];
            for pl in &vp.planes {
                for k in 0..L {
                    // `DVec4::dot`: ((x·x' + y·y') + z·z') + w·w'.
                    let d = pl.x * x[k] + pl.y * y[k] + pl.z * z[k] + pl.w * w[k];
                    inside[k] &= d >= 0.0;
                }
            }
            let mut sx = [0i64; L];
            let mut sy = [0i64; L];
            let mut sz = [0f64; L];
            for k in 0..L {
                inside[k] &= !(w[k].is_nan() || w[k] <= 0.0);
                let fx = ((x[k] / w[k] + 1.0) * hw * sub).round();
                let fy = ((1.0 - y[k] / w[k]) * hh * sub).round();
                sx[k] = fx.clamp(-SNAP_LIMIT, SNAP_LIMIT) as i64;
                sy[k] = fy.clamp(-SNAP_LIMIT, SNAP_LIMIT) as i64;
                sz[k] = (z[k] / w[k]).clamp(0.0, 1.0);
            }
            for k in 0..n {
                self.inside[base + k] = inside[k];
                self.snapped[base + k] = SnappedVertex {
                    x: sx[k],
                    y: sy[k],
                    z: sz[k],
                };
            }
        }
    }

    /// Facing of the triangle with (checked) vertex indices `t`.
    #[inline(always)]
    pub fn facing(&self, t: [u32; 3]) -> Option<Facing> {
        facing(t.map(|i| self.clip[i as usize]))
    }

    /// [`setup_into`] for the triangle with (checked) vertex indices `t`, whose
    /// facing [`VertexCache::facing`] is `f`.
    #[inline(always)]
    pub fn setup(&self, t: [u32; 3], f: Option<Facing>, vp: &Viewport, s: &mut Setup) {
        let [a, b, c] = t.map(|i| i as usize);
        if self.inside[a] && self.inside[b] && self.inside[c] {
            s.facing = f;
            s.clipped = false;
            s.len = 0;
            if s.facing.is_some() {
                s.vertices[0] = self.snapped[a];
                s.vertices[1] = self.snapped[b];
                s.vertices[2] = self.snapped[c];
                s.len = 3;
            }
        } else {
            setup_into([self.clip[a], self.clip[b], self.clip[c]], vp, s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_follows_ndc_winding_and_w_sign() {
        let a = Vec4::new(0.0, 0.0, 0.5, 1.0);
        let b = Vec4::new(1.0, 0.0, 0.5, 1.0);
        let c = Vec4::new(0.0, 1.0, 0.5, 1.0);
        assert_eq!(facing([a, b, c]), Some(Facing::Front));
        assert_eq!(facing([a, c, b]), Some(Facing::Back));
        assert_eq!(facing([a, b, a]), None);
        // Scaling a vertex by a positive factor keeps facing.
        assert_eq!(facing([a * 3.0, b, c * 0.5]), Some(Facing::Front));
    }

    #[test]
    fn snapping_centres_pixels() {
        let s = setup_triangle(
            [
                Vec4::new(-1.0, 1.0, 0.5, 1.0),
                Vec4::new(1.0, 1.0, 0.5, 1.0),
                Vec4::new(-1.0, -1.0, 0.5, 1.0),
            ],
            16,
            8,
        );
        assert_eq!(s.len, 3);
        assert_eq!((s.vertices[0].x, s.vertices[0].y), (0, 0));
        assert_eq!((s.vertices[1].x, s.vertices[1].y), (16 * SUBPIXEL, 0));
        assert_eq!((s.vertices[2].x, s.vertices[2].y), (0, 8 * SUBPIXEL));
        assert_eq!(s.vertices[0].z, 0.5);
    }

    #[test]
    fn w_zero_vertex_after_near_clip_does_not_divide() {
        // A vertex at infinity perpendicular to the view (clip w = 0, x ≠ 0).
        let s = setup_triangle(
            [
                Vec4::new(0.0, 0.0, 0.5, 1.0),
                Vec4::new(0.5, 0.2, 0.5, 1.0),
                Vec4::new(1.0, 0.0, 0.0, 0.0),
            ],
            64,
            64,
        );
        assert!(s.len >= 3);
        for v in s.polygon() {
            assert!(v.x.abs() < 1 << 23 && v.z.is_finite());
        }
    }
}
