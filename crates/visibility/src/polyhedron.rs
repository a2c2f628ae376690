//! Convex polyhedra in f64, clipped plane by plane [Steiner §4.3.3, Listing 4.1:
//! `createSolidFrustum` and `clip`].
//!
//! The view frustum clipped to the scene bounds, the intersection body and the
//! light views' fitting all work on [`Polyhedron`]: a bounded convex body given
//! both as half-spaces (its planes) and as a boundary (vertices and cyclically
//! ordered face polygons). f64 throughout: DESIGN.md asks for f64 in the
//! intersection body, and lights 1e5 away from a unit-sized frustum need it.
//!
//! # Robustness
//! Clipping snaps a vertex onto the cutting plane when its distance is at most
//! [`Polyhedron::epsilon`] = `REL_EPS · diameter + COORD_EPS · max |coordinate|`
//! (1e-9 of the body's size plus 1e-13 of its distance from the origin, which
//! covers f64 rounding of plane evaluations at 1e6 from the origin with a wide
//! margin). Snapped vertices are kept, so a plane touching the body within ε
//! leaves it unchanged; a cut keeping only a face gives a flat polyhedron
//! (conservative), one keeping only an edge or a vertex gives the empty one.

use glam::{DVec2, DVec3};
use scene::{Aabb, Frustum, Plane};

/// Relative clipping tolerance, per unit of the polyhedron's diameter.
pub const REL_EPS: f64 = 1e-9;

/// Clipping tolerance per unit of the largest absolute vertex coordinate.
pub const COORD_EPS: f64 = 1e-13;

/// One boundary polygon of a [`Polyhedron`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face<'a> {
    /// The face's supporting plane, unit normal, inside = positive side.
    pub plane: Plane,
    /// Indices into [`Polyhedron::vertices`], in cyclic order around the face
    /// (orientation unspecified), at least 3.
    pub vertices: &'a [usize],
}

/// A face as stored: its plane and its run of [`Polyhedron::corners`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct FaceRun {
    plane: Plane,
    start: usize,
    end: usize,
}

/// A bounded convex polyhedron in world space (f64), possibly empty or flat.
///
/// Inside is the positive side of every plane (as [`scene::Plane`]). The
/// planes are those of the original box plus every plane that actually cut;
/// `vertices` are the corners of the clipped body (within [`Self::epsilon`]).
/// The faces' vertex lists are stored in one flat list, so clipping into a
/// reused polyhedron (`Polyhedron::clip_with`) allocates nothing once its
/// buffers have grown.
#[derive(Debug, Default, PartialEq)]
pub struct Polyhedron {
    planes: Vec<Plane>,
    vertices: Vec<DVec3>,
    faces: Vec<FaceRun>,
    /// Every face's vertex indices, face after face.
    corners: Vec<usize>,
}

impl Clone for Polyhedron {
    fn clone(&self) -> Self {
        let mut p = Polyhedron::default();
        p.clone_from(self);
        p
    }

    /// Copies into the existing buffers (no allocation once they are big enough).
    fn clone_from(&mut self, o: &Self) {
        self.planes.clone_from(&o.planes);
        self.vertices.clone_from(&o.vertices);
        self.faces.clone_from(&o.faces);
        self.corners.clone_from(&o.corners);
    }
}

/// A point projected into a plane, with its vertex index.
type Tagged = (DVec2, usize);

/// Buffers [`Polyhedron::clip_with`] reuses from call to call.
#[derive(Debug, Default)]
pub(crate) struct ClipScratch {
    dist: Vec<f64>,
    verts: Vec<DVec3>,
    /// Cut edges `(i, j)` (i < j) and their new vertex.
    on_edge: Vec<(usize, usize, usize)>,
    on_plane: Vec<usize>,
    hull_in: Vec<Tagged>,
    hull_out: Vec<Tagged>,
    remap: Vec<usize>,
    /// The clipped body, swapped with the input.
    out: Polyhedron,
}

/// Corner indices of each box face (bit 0 = x max, bit 1 = y max, bit 2 = z
/// max, as [`Aabb::corners`]), in cyclic order; same order as the planes.
const BOX_FACES: [[usize; 4]; 6] = [
    [0, 2, 6, 4],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 3, 7, 6],
    [0, 1, 3, 2],
    [4, 5, 7, 6],
];

impl Polyhedron {
    /// The box `b` (f32 corners widened exactly to f64); empty for an empty or
    /// non-finite box. A box of zero thickness gives a flat polyhedron.
    pub fn from_aabb(b: &Aabb) -> Self {
        let mut p = Polyhedron::default();
        p.set_aabb(b);
        p
    }

    /// Makes this polyhedron the box `b` ([`Polyhedron::from_aabb`]), in the
    /// existing buffers.
    pub(crate) fn set_aabb(&mut self, b: &Aabb) {
        self.clear();
        if b.is_empty() || !b.min.is_finite() || !b.max.is_finite() {
            return;
        }
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        self.planes.extend([
            Plane::from_point_normal(lo, DVec3::X),
            Plane::from_point_normal(hi, DVec3::NEG_X),
            Plane::from_point_normal(lo, DVec3::Y),
            Plane::from_point_normal(hi, DVec3::NEG_Y),
            Plane::from_point_normal(lo, DVec3::Z),
            Plane::from_point_normal(hi, DVec3::NEG_Z),
        ]);
        self.vertices
            .extend(b.corners().iter().map(|c| c.as_dvec3()));
        for (f, pl) in BOX_FACES.iter().zip(&self.planes) {
            let start = self.corners.len();
            self.corners.extend_from_slice(f);
            self.faces.push(FaceRun {
                plane: *pl,
                start,
                end: self.corners.len(),
            });
        }
    }

    /// Empties the polyhedron, keeping its buffers.
    pub(crate) fn clear(&mut self) {
        self.planes.clear();
        self.vertices.clear();
        self.faces.clear();
        self.corners.clear();
    }

    /// The view frustum `V` (far end at infinity) clipped to the box `S`:
    /// `S` clipped by the frustum's five planes [Steiner §4.3.3]. Empty when
    /// they do not meet (or meet in zero area).
    pub fn from_frustum(frustum: &Frustum, bounds: &Aabb) -> Self {
        let mut p = Polyhedron::default();
        p.set_frustum(frustum, bounds, &mut ClipScratch::default());
        p
    }

    /// Makes this polyhedron [`Polyhedron::from_frustum`]`(frustum, bounds)`,
    /// in the existing buffers.
    pub(crate) fn set_frustum(&mut self, frustum: &Frustum, bounds: &Aabb, s: &mut ClipScratch) {
        self.set_aabb(bounds);
        for pl in &frustum.planes {
            if self.is_empty() {
                break;
            }
            self.clip_with(pl, s);
        }
    }

    /// True when the polyhedron holds no point (or was clipped to zero area).
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// The corners (world space, f64).
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// The bounding planes, unit normals, inside = positive side. May hold
    /// redundant planes; empty for the empty polyhedron.
    pub fn planes(&self) -> &[Plane] {
        if self.is_empty() {
            &[]
        } else {
            &self.planes
        }
    }

    /// The boundary polygons.
    pub fn faces(&self) -> impl ExactSizeIterator<Item = Face<'_>> + '_ {
        self.faces.iter().map(|f| Face {
            plane: f.plane,
            vertices: &self.corners[f.start..f.end],
        })
    }

    /// Length of the diagonal of the vertices' bounding box (0 when empty).
    pub fn diameter(&self) -> f64 {
        let (lo, hi) = self.bounds();
        if self.is_empty() {
            0.0
        } else {
            (hi - lo).length()
        }
    }

    /// The clipping tolerance: `REL_EPS · diameter + COORD_EPS · max |coordinate|`.
    pub fn epsilon(&self) -> f64 {
        let m = self
            .vertices
            .iter()
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
        REL_EPS * self.diameter() + COORD_EPS * m
    }

    /// Component-wise min and max of the vertices (`+inf, -inf` when empty).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
    }

    /// The mean of the vertices (a point inside; `NaN` when empty).
    pub fn centroid(&self) -> DVec3 {
        self.vertices.iter().copied().sum::<DVec3>() / self.vertices.len() as f64
    }

    /// True when `p` lies on the positive side of every plane, up to `tolerance`
    /// (a distance in world units); false for the empty polyhedron.
    pub fn contains(&self, p: DVec3, tolerance: f64) -> bool {
        !self.is_empty()
            && self
                .planes
                .iter()
                .all(|pl| pl.signed_distance(p) >= -tolerance)
    }

    /// Volume (0 for flat or empty bodies), from the faces as pyramids over the centroid.
    pub fn volume(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let c = self.centroid();
        self.faces()
            .map(|f| {
                let p = |k: usize| self.vertices[f.vertices[k]];
                let mut area = DVec3::ZERO;
                for k in 1..f.vertices.len() - 1 {
                    area += (p(k) - p(0)).cross(p(k + 1) - p(0));
                }
                0.5 * area.length() * f.plane.signed_distance(c).abs() / 3.0
            })
            .sum()
    }

    /// The part on the positive side of `plane` [Steiner Listing 4.1 `clip`]:
    /// every face polygon is clipped, and the hole is closed with one cap face
    /// (the convex hull of the cut points in the plane).
    ///
    /// Vertices within [`Self::epsilon`] of the plane count as on it (kept, no
    /// new vertex). A plane that cuts nothing leaves the polyhedron unchanged
    /// (and is not recorded); one that leaves only an edge or a vertex gives
    /// the empty polyhedron (one leaving a face gives a flat one). A plane with a zero or non-finite normal or offset is
    /// ignored (the polyhedron is returned unchanged).
    pub fn clip(&self, plane: &Plane) -> Polyhedron {
        let mut p = self.clone();
        p.clip_with(plane, &mut ClipScratch::default());
        p
    }

    /// [`Polyhedron::clip`] in place, with buffers reused from `s`.
    pub(crate) fn clip_with(&mut self, plane: &Plane, s: &mut ClipScratch) {
        if self.is_empty() {
            return;
        }
        let pl = plane.normalized();
        if !pl.normal.is_finite() || !pl.d.is_finite() || pl.normal.length_squared() < 0.25 {
            return;
        }
        let eps = self.epsilon();
        s.dist.clear();
        s.dist.extend(self.vertices.iter().map(|&v| {
            let d = pl.signed_distance(v);
            if d.abs() <= eps {
                0.0
            } else {
                d
            }
        }));
        if s.dist.iter().all(|&d| d >= 0.0) {
            return;
        }
        if s.dist.iter().all(|&d| d < 0.0) {
            self.clear();
            return;
        }
        let n0 = self.vertices.len();
        let (dist, verts, out) = (&s.dist, &mut s.verts, &mut s.out);
        verts.clone_from(&self.vertices);
        s.on_edge.clear();
        out.clear();
        for f in &self.faces {
            let face = &self.corners[f.start..f.end];
            let n = face.len();
            let start = out.corners.len();
            for k in 0..n {
                let (a, b) = (face[k], face[(k + 1) % n]);
                let (da, db) = (dist[a], dist[b]);
                if da >= 0.0 {
                    out.corners.push(a);
                }
                if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                    // Computed once per edge, from the canonical order, so
                    // both faces share the bit-identical vertex.
                    let (i, j) = (a.min(b), a.max(b));
                    let idx = match s.on_edge.iter().find(|e| (e.0, e.1) == (i, j)) {
                        Some(e) => e.2,
                        None => {
                            let (p, q) = (self.vertices[i], self.vertices[j]);
                            let t = dist[i] / (dist[i] - dist[j]);
                            verts.push(p + (q - p) * t);
                            s.on_edge.push((i, j, verts.len() - 1));
                            verts.len() - 1
                        }
                    };
                    out.corners.push(idx);
                }
            }
            if out.corners.len() - start >= 3 {
                out.faces.push(FaceRun {
                    plane: f.plane,
                    start,
                    end: out.corners.len(),
                });
            } else {
                out.corners.truncate(start);
            }
        }
        // Cap: every kept vertex on the plane.
        s.on_plane.clear();
        s.on_plane
            .extend((0..verts.len()).filter(|&i| i >= n0 || dist[i] == 0.0));
        let start = out.corners.len();
        if convex_polygon_in_plane(
            verts,
            &s.on_plane,
            pl.normal,
            (&mut s.hull_in, &mut s.hull_out),
            &mut out.corners,
        ) {
            out.faces.push(FaceRun {
                plane: pl,
                start,
                end: out.corners.len(),
            });
        }
        if out.faces.is_empty() {
            self.clear();
            return;
        }
        // Compact: keep only referenced vertices.
        s.remap.clear();
        s.remap.resize(verts.len(), usize::MAX);
        for i in &mut out.corners {
            if s.remap[*i] == usize::MAX {
                s.remap[*i] = out.vertices.len();
                out.vertices.push(verts[*i]);
            }
            *i = s.remap[*i];
        }
        out.planes.clone_from(&self.planes);
        out.planes.push(pl);
        std::mem::swap(self, &mut s.out);
    }
}

/// Appends to `out` the indices of `ids` that are corners of the convex hull
/// of `verts[ids]` projected into the plane with the given normal, in cyclic
/// order; false (nothing appended) when the hull has zero area.
fn convex_polygon_in_plane(
    verts: &[DVec3],
    ids: &[usize],
    normal: DVec3,
    (pts, hull): (&mut Vec<Tagged>, &mut Vec<Tagged>),
    out: &mut Vec<usize>,
) -> bool {
    if ids.len() < 3 {
        return false;
    }
    let (u, v) = normal.any_orthonormal_pair();
    pts.clear();
    pts.extend(
        ids.iter()
            .map(|&i| (DVec2::new(u.dot(verts[i]), v.dot(verts[i])), i)),
    );
    hull_2d(pts, hull);
    if hull.len() < 3 {
        return false;
    }
    out.extend(hull.iter().map(|&(_, i)| i));
    true
}

/// Andrew's monotone chain: the counter-clockwise hull corners of `pts`
/// (collinear points dropped) into `hull`. Sorts `pts`.
pub(crate) fn hull_2d<T: Copy>(pts: &mut [(DVec2, T)], hull: &mut Vec<(DVec2, T)>) {
    pts.sort_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
    hull.clear();
    if pts.len() < 3 {
        hull.extend_from_slice(pts);
        return;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    for &p in pts.iter() {
        while hull.len() >= 2 && cross(hull[hull.len() - 2].0, hull[hull.len() - 1].0, p.0) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    let lower = hull.len() + 1;
    for &p in pts.iter().rev().skip(1) {
        while hull.len() >= lower
            && cross(hull[hull.len() - 2].0, hull[hull.len() - 1].0, p.0) <= 0.0
        {
            hull.pop();
        }
        hull.push(p);
    }
    hull.pop();
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn unit_box() -> Polyhedron {
        Polyhedron::from_aabb(&Aabb::new(Vec3::ZERO, Vec3::ONE))
    }

    #[test]
    fn box_volume_and_containment() {
        let b = unit_box();
        assert_eq!(b.vertices().len(), 8);
        assert!((b.volume() - 1.0).abs() < 1e-12);
        assert!(b.contains(DVec3::splat(0.5), 0.0));
        assert!(!b.contains(DVec3::splat(1.5), 0.0));
    }

    #[test]
    fn clip_halves_and_diagonal() {
        let b = unit_box();
        let half = b.clip(&Plane::from_point_normal(DVec3::splat(0.5), DVec3::X));
        assert!((half.volume() - 0.5).abs() < 1e-12);
        assert_eq!(half.vertices().len(), 8);
        // Cut off one corner: a tetrahedron of volume 1/6 removed, a triangle cap added.
        let corner = b.clip(&Plane::from_point_normal(DVec3::X, DVec3::ONE));
        assert!(
            (corner.volume() - 5.0 / 6.0).abs() < 1e-12,
            "{}",
            corner.volume()
        );
        assert_eq!(corner.vertices().len(), 7);
        assert_eq!(corner.faces().len(), 7);
        let tip = b.clip(&Plane::from_point_normal(
            DVec3::new(1.0, 0.0, 0.0),
            -DVec3::ONE,
        ));
        assert!((tip.volume() - 1.0 / 6.0).abs() < 1e-12);
        assert_eq!(tip.vertices().len(), 4);
    }

    #[test]
    fn touching_and_missing_planes() {
        let b = unit_box();
        // Through a face: unchanged.
        let same = b.clip(&Plane::from_point_normal(DVec3::ZERO, DVec3::X));
        assert_eq!(same, b);
        // Keeps only a face: a flat polyhedron (conservative), zero volume.
        let face = b.clip(&Plane::from_point_normal(DVec3::ZERO, DVec3::NEG_X));
        assert_eq!(face.vertices().len(), 4);
        assert_eq!(face.volume(), 0.0);
        // Through a corner only: empty.
        let none = b.clip(&Plane::from_point_normal(DVec3::ZERO, -DVec3::ONE));
        assert!(none.is_empty());
        // Zero normal: ignored.
        assert_eq!(
            b.clip(&Plane {
                normal: DVec3::ZERO,
                d: -1.0
            }),
            b
        );
        assert!(Polyhedron::from_aabb(&Aabb::EMPTY).is_empty());
    }

    #[test]
    fn flat_box_clips_without_panic() {
        let flat = Polyhedron::from_aabb(&Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)));
        assert_eq!(flat.volume(), 0.0);
        let cut = flat.clip(&Plane::from_point_normal(DVec3::splat(0.5), DVec3::X));
        assert!(!cut.is_empty());
        assert!(cut
            .vertices()
            .iter()
            .all(|v| v.x >= 0.5 - 1e-12 && v.y == 0.0));
    }

    #[test]
    fn far_from_origin_keeps_precision() {
        let c = Vec3::splat(1e6);
        let b = Polyhedron::from_aabb(&Aabb::new(c, c + Vec3::ONE));
        let half = b.clip(&Plane::from_point_normal(DVec3::splat(1e6 + 0.5), DVec3::Y));
        assert!((half.volume() - 0.5).abs() < 1e-6, "{}", half.volume());
    }

    #[test]
    fn frustum_in_box() {
        let cam = scene::Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            60f64.to_radians(),
            1.0,
            0.1,
        )
        .unwrap();
        let s = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let p = Polyhedron::from_frustum(&cam.frustum(), &s);
        assert!(!p.is_empty());
        let f = cam.frustum();
        for v in p.vertices() {
            assert!(f.planes.iter().all(|pl| pl.signed_distance(*v) >= -1e-9));
        }
        // Looking away: empty.
        let away = scene::Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::Y,
            60f64.to_radians(),
            1.0,
            0.1,
        )
        .unwrap();
        assert!(Polyhedron::from_frustum(&away.frustum(), &s).is_empty());
    }
}
