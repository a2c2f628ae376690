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
use std::collections::HashMap;

/// Relative clipping tolerance, per unit of the polyhedron's diameter.
pub const REL_EPS: f64 = 1e-9;

/// Clipping tolerance per unit of the largest absolute vertex coordinate.
pub const COORD_EPS: f64 = 1e-13;

/// One boundary polygon of a [`Polyhedron`].
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// The face's supporting plane, unit normal, inside = positive side.
    pub plane: Plane,
    /// Indices into [`Polyhedron::vertices`], in cyclic order around the face
    /// (orientation unspecified), at least 3.
    pub vertices: Vec<usize>,
}

/// A bounded convex polyhedron in world space (f64), possibly empty or flat.
///
/// Inside is the positive side of every plane (as [`scene::Plane`]). The
/// planes are those of the original box plus every plane that actually cut;
/// `vertices` are the corners of the clipped body (within [`Self::epsilon`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Polyhedron {
    planes: Vec<Plane>,
    vertices: Vec<DVec3>,
    faces: Vec<Face>,
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
        if b.is_empty() || !b.min.is_finite() || !b.max.is_finite() {
            return Polyhedron::default();
        }
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        let planes = vec![
            Plane::from_point_normal(lo, DVec3::X),
            Plane::from_point_normal(hi, DVec3::NEG_X),
            Plane::from_point_normal(lo, DVec3::Y),
            Plane::from_point_normal(hi, DVec3::NEG_Y),
            Plane::from_point_normal(lo, DVec3::Z),
            Plane::from_point_normal(hi, DVec3::NEG_Z),
        ];
        let vertices = b.corners().iter().map(|c| c.as_dvec3()).collect();
        let faces = BOX_FACES
            .iter()
            .zip(&planes)
            .map(|(f, pl)| Face {
                plane: *pl,
                vertices: f.to_vec(),
            })
            .collect();
        Polyhedron {
            planes,
            vertices,
            faces,
        }
    }

    /// The view frustum `V` (far end at infinity) clipped to the box `S`:
    /// `S` clipped by the frustum's five planes [Steiner §4.3.3]. Empty when
    /// they do not meet (or meet in zero area).
    pub fn from_frustum(frustum: &Frustum, bounds: &Aabb) -> Self {
        let mut p = Polyhedron::from_aabb(bounds);
        for pl in &frustum.planes {
            if p.is_empty() {
                break;
            }
            p = p.clip(pl);
        }
        p
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
    pub fn faces(&self) -> &[Face] {
        &self.faces
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
        self.faces
            .iter()
            .map(|f| {
                let p: Vec<DVec3> = f.vertices.iter().map(|&i| self.vertices[i]).collect();
                let mut area = DVec3::ZERO;
                for k in 1..p.len() - 1 {
                    area += (p[k] - p[0]).cross(p[k + 1] - p[0]);
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
        if self.is_empty() {
            return Polyhedron::default();
        }
        let pl = plane.normalized();
        if !pl.normal.is_finite() || !pl.d.is_finite() || pl.normal.length_squared() < 0.25 {
            return self.clone();
        }
        let eps = self.epsilon();
        let dist: Vec<f64> = self
            .vertices
            .iter()
            .map(|&v| {
                let s = pl.signed_distance(v);
                if s.abs() <= eps {
                    0.0
                } else {
                    s
                }
            })
            .collect();
        if dist.iter().all(|&s| s >= 0.0) {
            return self.clone();
        }
        if dist.iter().all(|&s| s < 0.0) {
            return Polyhedron::default();
        }
        let n0 = self.vertices.len();
        let mut verts = self.vertices.clone();
        let mut on_edge: HashMap<(usize, usize), usize> = HashMap::new();
        let mut faces = Vec::with_capacity(self.faces.len() + 1);
        for f in &self.faces {
            let n = f.vertices.len();
            let mut out = Vec::with_capacity(n + 1);
            for k in 0..n {
                let (a, b) = (f.vertices[k], f.vertices[(k + 1) % n]);
                let (da, db) = (dist[a], dist[b]);
                if da >= 0.0 {
                    out.push(a);
                }
                if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                    // Computed once per edge, from the canonical order, so
                    // both faces share the bit-identical vertex.
                    let (i, j) = (a.min(b), a.max(b));
                    let idx = *on_edge.entry((i, j)).or_insert_with(|| {
                        let (p, q) = (self.vertices[i], self.vertices[j]);
                        let t = dist[i] / (dist[i] - dist[j]);
                        verts.push(p + (q - p) * t);
                        verts.len() - 1
                    });
                    out.push(idx);
                }
            }
            if out.len() >= 3 {
                faces.push(Face {
                    plane: f.plane,
                    vertices: out,
                });
            }
        }
        // Cap: every kept vertex on the plane.
        let on_plane: Vec<usize> = (0..verts.len())
            .filter(|&i| i >= n0 || dist[i] == 0.0)
            .collect();
        if let Some(cap) = convex_polygon_in_plane(&verts, &on_plane, pl.normal) {
            faces.push(Face {
                plane: pl,
                vertices: cap,
            });
        }
        if faces.is_empty() {
            return Polyhedron::default();
        }
        // Compact: keep only referenced vertices.
        let mut remap = vec![usize::MAX; verts.len()];
        let mut vertices = Vec::new();
        for f in &mut faces {
            for i in &mut f.vertices {
                if remap[*i] == usize::MAX {
                    remap[*i] = vertices.len();
                    vertices.push(verts[*i]);
                }
                *i = remap[*i];
            }
        }
        let mut planes = self.planes.clone();
        planes.push(pl);
        Polyhedron {
            planes,
            vertices,
            faces,
        }
    }
}

/// The indices of `ids` that are corners of the convex hull of `verts[ids]`
/// projected into the plane with the given normal, in cyclic order; `None`
/// when the hull has zero area.
fn convex_polygon_in_plane(verts: &[DVec3], ids: &[usize], normal: DVec3) -> Option<Vec<usize>> {
    if ids.len() < 3 {
        return None;
    }
    let (u, v) = normal.any_orthonormal_pair();
    let mut pts: Vec<(DVec2, usize)> = ids
        .iter()
        .map(|&i| (DVec2::new(u.dot(verts[i]), v.dot(verts[i])), i))
        .collect();
    let hull = hull_2d(&mut pts);
    (hull.len() >= 3).then(|| hull.into_iter().map(|(_, i)| i).collect())
}

/// Andrew's monotone chain: the counter-clockwise hull corners (collinear
/// points dropped). Sorts `pts`.
pub(crate) fn hull_2d<T: Copy>(pts: &mut [(DVec2, T)]) -> Vec<(DVec2, T)> {
    pts.sort_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
    if pts.len() < 3 {
        return pts.to_vec();
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<(DVec2, T)> = Vec::with_capacity(2 * pts.len());
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
    hull
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
