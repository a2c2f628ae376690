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
#[cfg(any(test, feature = "test-util"))]
pub fn setup_triangle(v: [Vec4; 3], width: u32, height: u32) -> Setup {
    setup_with(v, &Viewport::new(width, height))
}

#[cfg(any(test, feature = "test-util"))]
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
#[derive(Clone, Debug)]
pub(crate) struct VertexCache {
    /// Clip positions, lane by lane: vertex k in lane k; lanes from `len` on hold
    /// copies of vertex 0 (they change no bound, outcode or flag).
    clip: Lanes,
    inside: [bool; CACHE_VERTICES],
    snapped: [SnappedVertex; CACHE_VERTICES],
    len: usize,
}

/// Clip-space x, y, z and w of up to eight vertices, one vertex per lane.
pub(crate) type Lanes = [[f32; CACHE_VERTICES]; 4];

/// `m · p(k)` for the eight lanes — the glam product `Mat4 * Vec4`
/// (`((X·x + Y·y) + Z·z) + W·w` by columns, no fused operations), so the same
/// values, computed across vertices so that the compiler vectorizes it.
#[inline(always)]
pub(crate) fn transform_lanes(m: &glam::Mat4, p: impl Fn(usize) -> Vec4) -> Lanes {
    const L: usize = CACHE_VERTICES;
    // Plain loops into initialized arrays (`array::map` and `from_fn` went through
    // the stack here).
    let mut pos = [[0f32; L]; 4];
    for (k, v) in (0..L).map(p).enumerate() {
        pos[0][k] = v.x;
        pos[1][k] = v.y;
        pos[2][k] = v.z;
        pos[3][k] = v.w;
    }
    let cols = [m.x_axis, m.y_axis, m.z_axis, m.w_axis];
    let mut out = [[0f32; L]; 4];
    for i in 0..4 {
        let c = [cols[0][i], cols[1][i], cols[2][i], cols[3][i]];
        for k in 0..L {
            out[i][k] = c[0] * pos[0][k] + c[1] * pos[1][k] + c[2] * pos[2][k] + c[3] * pos[3][k];
        }
    }
    out
}

/// [`Lanes`] in f64.
pub(crate) type Wide = [[f64; CACHE_VERTICES]; 4];

/// The lanes in f64 (exact).
#[inline(always)]
pub(crate) fn widen(l: &Lanes) -> Wide {
    let mut out = [[0f64; CACHE_VERTICES]; 4];
    for i in 0..4 {
        for k in 0..CACHE_VERTICES {
            out[i][k] = f64::from(l[i][k]);
        }
    }
    out
}

impl VertexCache {
    /// An empty cache, to fill in place with [`VertexCache::transform_into`]
    /// (the cache is a few hundred bytes: built where it is used, not moved).
    #[inline(always)]
    pub fn empty() -> Self {
        VertexCache {
            clip: [[0.0; CACHE_VERTICES]; 4],
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
        let n = positions.len();
        self.len = n;
        if n > 0 {
            self.clip = transform_lanes(m, |k| positions[if k < n { k } else { 0 }]);
        }
    }

    /// [`VertexCache::transform_into`] of the eight corners of the box `(min, max)`
    /// in the order of [`crate::item::aabb_corners`] (the same values).
    #[inline(always)]
    pub fn transform_box(&mut self, m: &glam::Mat4, min: glam::Vec3, max: glam::Vec3) {
        self.len = 8;
        self.clip = transform_lanes(m, |c| {
            Vec4::new(
                if c & 1 != 0 { max.x } else { min.x },
                if c & 2 != 0 { max.y } else { min.y },
                if c & 4 != 0 { max.z } else { min.z },
                1.0,
            )
        });
    }

    /// The clip positions, lane by lane, and how many lanes are vertices.
    #[inline(always)]
    pub fn lanes(&self) -> (&Lanes, usize) {
        (&self.clip, self.len)
    }

    /// The clip position of vertex `i`.
    #[inline(always)]
    fn at(&self, i: usize) -> Vec4 {
        let c = &self.clip;
        Vec4::new(c[0][i], c[1][i], c[2][i], c[3][i])
    }

    /// Stage 2: whether each vertex lies inside every clip plane, and its snapped
    /// position — [`snap`] and the plane tests of `DVec4::dot`, written lane by
    /// lane over the eight lanes so that the compiler vectorizes them; the values
    /// are the same.
    #[inline(always)]
    pub fn snap(&mut self, vp: &Viewport) {
        const L: usize = CACHE_VERTICES;
        let (hw, hh) = (0.5 * vp.width as f64, 0.5 * vp.height as f64);
        let sub = SUBPIXEL as f64;
        let n = self.len;
        let [x, y, z, w] = widen(&self.clip);
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
            self.inside[k] = inside[k];
            self.snapped[k] = SnappedVertex {
                x: sx[k],
                y: sy[k],
                z: sz[k],
            };
        }
    }
}

impl VertexStage for VertexCache {
    const FRONT_FIRST: bool = true;

    #[inline(always)]
    fn clip(&self, i: usize) -> Vec4 {
        self.at(i)
    }

    #[inline(always)]
    fn inside(&self, i: usize) -> bool {
        self.inside[i]
    }

    #[inline(always)]
    fn snapped(&self, i: usize) -> SnappedVertex {
        self.snapped[i]
    }
}

/// A mesh's vertex stage done once per vertex: each vertex's clip position,
/// whether it lies inside every clip plane, and its snapped position. A
/// triangle reads its three vertices from here instead of transforming,
/// plane-testing and snapping them itself, which a welded mesh would do about
/// six times per vertex. The values are those [`setup_into`] computes.
pub(crate) trait VertexStage {
    /// Whether [`crate::item::setup_item`] sets up the front faces before the
    /// back faces (two passes over the triangles; worth it for boxes, whose
    /// facings are kept, not for large meshes).
    const FRONT_FIRST: bool;

    /// The clip position of vertex `i`.
    fn clip(&self, i: usize) -> Vec4;

    /// Whether vertex `i` lies inside every clip plane (with `w > 0`).
    fn inside(&self, i: usize) -> bool;

    /// The snapped position of vertex `i` (meaningful when it is inside).
    fn snapped(&self, i: usize) -> SnappedVertex;

    /// Facing of the triangle with (checked) vertex indices `t`.
    #[inline(always)]
    fn facing(&self, t: [u32; 3]) -> Option<Facing> {
        facing(t.map(|i| self.clip(i as usize)))
    }

    /// [`setup_into`] for the triangle with (checked) vertex indices `t`, whose
    /// facing [`VertexStage::facing`] is `f`.
    #[inline(always)]
    fn setup(&self, t: [u32; 3], f: Option<Facing>, vp: &Viewport, s: &mut Setup) {
        let [a, b, c] = t.map(|i| i as usize);
        if self.inside(a) && self.inside(b) && self.inside(c) {
            s.facing = f;
            s.clipped = false;
            s.len = 0;
            if s.facing.is_some() {
                s.vertices[0] = self.snapped(a);
                s.vertices[1] = self.snapped(b);
                s.vertices[2] = self.snapped(c);
                s.len = 3;
            }
        } else {
            setup_into([self.clip(a), self.clip(b), self.clip(c)], vp, s);
        }
    }
}

/// Most vertices a mesh may have for [`MeshVertices`]: its storage is 42
/// bytes a vertex per band drawing the mesh (about 10 MiB at this size); a
/// larger mesh is set up triangle by triangle, with no storage of its own.
pub(crate) const MESH_VERTICES_MAX: usize = 1 << 18;

/// Vertices [`MeshVertices`] holds room for from its first mesh on (42 KiB).
const MESH_VERTICES_MIN: usize = 1 << 10;

/// The vertex stage of a mesh larger than a box ([`VertexStage`]), in storage
/// kept from mesh to mesh: one [`VertexCache`] per eight vertices, each filled
/// by its own vectorized code (so with its values).
#[derive(Clone, Debug, Default)]
pub(crate) struct MeshVertices {
    chunks: Vec<VertexCache>,
}

impl MeshVertices {
    /// Storage with room for a mesh of [`MESH_VERTICES_MIN`] vertices.
    pub fn with_room() -> Self {
        let mut chunks = Vec::new();
        chunks.resize_with(MESH_VERTICES_MIN / CACHE_VERTICES, VertexCache::empty);
        MeshVertices { chunks }
    }

    /// Whether a mesh of `vertices` vertices and `triangles` triangles is worth
    /// a per-vertex stage: more vertices than a [`VertexCache`] holds, and not
    /// more than its triangles have corners (a mesh drawn from a slice of a
    /// larger shared vertex buffer would transform vertices it never uses),
    /// nor than [`MESH_VERTICES_MAX`] (the stage's storage stays small).
    #[inline(always)]
    pub fn pays(vertices: usize, triangles: usize) -> bool {
        vertices > CACHE_VERTICES && vertices <= 3 * triangles && vertices <= MESH_VERTICES_MAX
    }

    /// Transforms, plane-tests and snaps every vertex of `positions` under
    /// `m` for the viewport `vp`.
    #[inline(always)]
    pub fn fill(&mut self, m: &glam::Mat4, positions: &[Vec4], vp: &Viewport) {
        let n = positions.len().div_ceil(CACHE_VERTICES);
        if self.chunks.len() < n {
            // Room for any mesh up to `MESH_VERTICES_MIN` vertices from the
            // first fill on: which thread draws the largest mesh changes
            // from frame to frame, and a steady frame allocates nothing.
            // (Never shortened.)
            let room = n.max(MESH_VERTICES_MIN / CACHE_VERTICES);
            self.chunks.resize_with(room, VertexCache::empty);
        }
        for (cache, chunk) in self.chunks.iter_mut().zip(positions.chunks(CACHE_VERTICES)) {
            cache.transform_into(m, chunk);
            cache.snap(vp);
        }
    }

    /// Vertices the storage holds without growing.
    #[cfg(test)]
    pub fn room(&self) -> usize {
        self.chunks.len() * CACHE_VERTICES
    }

    /// The chunk holding vertex `i`, and its lane there.
    #[inline(always)]
    fn chunk(&self, i: usize) -> (&VertexCache, usize) {
        (&self.chunks[i / CACHE_VERTICES], i % CACHE_VERTICES)
    }
}

/// A vertex's stage is its chunk's.
impl VertexStage for MeshVertices {
    const FRONT_FIRST: bool = false;

    #[inline(always)]
    fn clip(&self, i: usize) -> Vec4 {
        let (c, k) = self.chunk(i);
        c.clip(k)
    }

    #[inline(always)]
    fn inside(&self, i: usize) -> bool {
        let (c, k) = self.chunk(i);
        c.inside(k)
    }

    #[inline(always)]
    fn snapped(&self, i: usize) -> SnappedVertex {
        let (c, k) = self.chunk(i);
        c.snapped(k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Storage made with room takes a mesh of [`MESH_VERTICES_MIN`]
    /// vertices in place; one vertex more grows it.
    #[test]
    fn storage_with_room_fills_in_place() {
        let vp = Viewport::new(64, 48);
        let m = glam::Mat4::IDENTITY;
        let mut v = MeshVertices::with_room();
        assert_eq!(v.room(), MESH_VERTICES_MIN);
        let at = v.chunks.as_ptr();
        let positions = vec![Vec4::new(0.25, -0.5, 0.5, 1.0); MESH_VERTICES_MIN + 1];
        v.fill(&m, &positions[..MESH_VERTICES_MIN], &vp);
        assert_eq!(v.chunks.as_ptr(), at);
        v.fill(&m, &positions, &vp);
        assert!(v.room() > MESH_VERTICES_MIN);
        assert_eq!(v.snapped(MESH_VERTICES_MIN), v.snapped(0));
    }

    #[test]
    fn lane_transform_is_the_glam_product_bit_for_bit() {
        // A small LCG: values of mixed magnitude and sign, w = 0 included.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut r = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let u = (state >> 40) as f32 / (1u64 << 24) as f32;
            (u - 0.5) * 10f32.powi((state >> 33) as i32 % 7 - 3)
        };
        for _ in 0..200 {
            let m = glam::Mat4::from_cols_array(&std::array::from_fn(|_| r()));
            let p: [Vec4; 8] =
                std::array::from_fn(|k| Vec4::new(r(), r(), r(), if k == 3 { 0.0 } else { r() }));
            let lanes = transform_lanes(&m, |k| p[k]);
            let (lo, hi) = (
                glam::Vec3::new(r(), r(), r()),
                glam::Vec3::new(r(), r(), r()),
            );
            let mut cache = VertexCache::empty();
            cache.transform_box(&m, lo, hi);
            let corners = crate::item::aabb_corners(lo, hi);
            for k in 0..8 {
                let want = m * p[k];
                let got = Vec4::new(lanes[0][k], lanes[1][k], lanes[2][k], lanes[3][k]);
                assert_eq!(
                    got.to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits)
                );
                let want = m * corners[k];
                assert_eq!(
                    cache.at(k).to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits)
                );
            }
        }
    }

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
