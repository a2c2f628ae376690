//! Triangulation of one polygon face by constrained Delaunay triangulation
//! (CDT, [spade]) in the polygon's best-fit plane.
//!
//! Why: OBJ faces may be concave n-gons, and the fan most loaders (tobj
//! among them) use covers area outside a concave polygon — 13× the true area
//! for assimp's `concave_polygon.obj`. Shadow volumes built from such
//! triangles cast shadows that do not exist.
//!
//! How: the polygon is projected onto the plane through its centroid
//! perpendicular to its Newell normal (Newell's method; Tampieri, "Newell's
//! Method for Computing the Plane Equation of a Polygon", Graphics Gems III),
//! every corner is inserted into a CDT and every boundary edge added as a
//! constraint. The winding number of each CDT face is then found by walking
//! across edges from the outer face (winding 0), adding the number of
//! boundary edges crossed from right to left and subtracting those crossed
//! from left to right. Faces with a non-zero winding number are inside and
//! are kept, wound like the polygon (the Newell normal makes the projected
//! polygon counter-clockwise, so winding +1 faces keep spade's
//! counter-clockwise order and the triangles turn the way the face does).
//! Repeated corners and edges (a face that runs round the same quad many
//! times) are handled by counting edge multiplicities.
//!
//! A simple polygon with `n` distinct corners gives exactly `n − 2`
//! triangles whose areas add up to the polygon's area.
//!
//! Fallback: when CDT is impossible — the boundary crosses itself in the
//! plane, two different corners project to one point, or coordinates are out
//! of spade's range — the polygon is ear-clipped in the plane instead; a
//! polygon without a plane (zero Newell normal: collinear corners, or lobes
//! whose areas cancel) becomes a fan. A polygon whose corners are all
//! collinear is fanned too, without counting as a fallback: its zero-area
//! triangles are what the file says, and the mesh counts them as degenerate. [`Outcome::Fallback`] says which, so the
//! loader can warn.

use glam::{DVec2, DVec3, Vec3};
use spade::handles::{FixedFaceHandle, FixedVertexHandle, PossiblyOuterTag, OUTER_FACE};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};
use std::collections::HashMap;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Polygons with more corners than this are fanned rather than ear-clipped
/// when CDT fails (ear clipping here is cubic in the corner count).
const MAX_EAR_CLIP_CORNERS: usize = 512;

/// How a polygon was triangulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// Constrained Delaunay triangulation (or the polygon was a triangle).
    Cdt,
    /// All corners are collinear (or coincide): the polygon has no area and
    /// was fanned into zero-area triangles, which [`crate::Mesh::new`] drops
    /// and counts as degenerate.
    ZeroArea,
    /// CDT was impossible; see [`Fallback`] for why and what was done instead.
    Fallback(Fallback),
}

/// Why CDT was impossible for a polygon.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Fallback {
    /// The Newell normal is zero or not finite (collinear corners, or lobes
    /// whose signed areas cancel): the polygon was fanned.
    NoPlane,
    /// Boundary edges cross in the best-fit plane: ear-clipped.
    SelfIntersecting,
    /// Two corners at different 3D positions project to one point of the
    /// best-fit plane (a strongly non-planar polygon): ear-clipped.
    CoincidentCorners,
    /// spade rejected a coordinate or panicked: ear-clipped.
    Triangulator,
}

impl Fallback {
    /// A short description for load warnings.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            Fallback::NoPlane => "has no plane (collinear corners or cancelling lobes); fanned",
            Fallback::SelfIntersecting => "crosses itself in its best-fit plane; ear-clipped",
            Fallback::CoincidentCorners => {
                "has distinct corners that project to one point of its best-fit plane; ear-clipped"
            }
            Fallback::Triangulator => "could not be handled by the CDT; ear-clipped",
        }
    }
}

/// Triangulates the polygon with corners `points` (in order; the closing
/// edge from the last corner back to the first is implied) and appends the
/// triangles to `out` as indices into `points`, wound like the polygon.
///
/// Fewer than three corners give no triangles; three give `[0, 1, 2]`.
/// Never panics.
pub(crate) fn triangulate(points: &[Vec3], out: &mut Vec<[u32; 3]>) -> Outcome {
    let n = points.len();
    if n < 3 {
        return Outcome::Cdt;
    }
    if n == 3 {
        out.push([0, 1, 2]);
        return Outcome::Cdt;
    }
    let p: Vec<DVec3> = points.iter().map(|q| q.as_dvec3()).collect();
    let centroid = p.iter().copied().sum::<DVec3>() / n as f64;
    let normal = newell_normal(&p, centroid);
    if !normal.is_finite() || normal == DVec3::ZERO {
        fan(n, out);
        let collinear = (1..n - 1).all(|i| (p[i] - p[0]).cross(p[i + 1] - p[0]) == DVec3::ZERO);
        return if collinear {
            Outcome::ZeroArea
        } else {
            Outcome::Fallback(Fallback::NoPlane)
        };
    }
    let w = normal.normalize();
    let u = w.any_orthonormal_vector();
    let v = w.cross(u);
    let flat: Vec<DVec2> = p
        .iter()
        .map(|q| {
            let d = *q - centroid;
            DVec2::new(d.dot(u), d.dot(v))
        })
        .collect();
    let mut tris = Vec::with_capacity(n - 2);
    // spade documents panics only for `add_constraint`, which is not used;
    // catch_unwind is the last resort should one of its internal asserts fire.
    let result = catch_unwind(AssertUnwindSafe(|| cdt(&flat, points, &mut tris)));
    let reason = match result {
        Ok(Ok(())) => {
            out.extend(tris);
            return Outcome::Cdt;
        }
        Ok(Err(reason)) => reason,
        Err(_) => Fallback::Triangulator,
    };
    if n > MAX_EAR_CLIP_CORNERS {
        fan(n, out);
    } else {
        ear_clip(&flat, out);
    }
    Outcome::Fallback(reason)
}

/// Newell's normal: twice the polygon's vector area, computed relative to
/// `origin` for precision. Its direction makes the polygon counter-clockwise.
fn newell_normal(p: &[DVec3], origin: DVec3) -> DVec3 {
    let n = p.len();
    (0..n)
        .map(|i| (p[i] - origin).cross(p[(i + 1) % n] - origin))
        .sum()
}

fn fan(n: usize, out: &mut Vec<[u32; 3]>) {
    out.extend((1..n.saturating_sub(1)).map(|i| [0, i as u32, i as u32 + 1]));
}

/// The CDT of the projected polygon `flat` (corners `points` in 3D, used to
/// tell duplicate corners from distinct corners that project together).
fn cdt(flat: &[DVec2], points: &[Vec3], out: &mut Vec<[u32; 3]>) -> Result<(), Fallback> {
    let n = flat.len();
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
    // Spade vertex index -> first polygon corner at that position.
    let mut corner_of: Vec<u32> = Vec::with_capacity(n);
    let mut handles: Vec<FixedVertexHandle> = Vec::with_capacity(n);
    for (i, q) in flat.iter().enumerate() {
        let h = cdt
            .insert(spade::mitigate_underflow(Point2::new(q.x, q.y)))
            .map_err(|_| Fallback::Triangulator)?;
        let k = h.index();
        if k >= corner_of.len() {
            corner_of.resize(k + 1, u32::MAX);
        }
        match corner_of[k] {
            u32::MAX => corner_of[k] = i as u32,
            c if points[c as usize] != points[i] => return Err(Fallback::CoincidentCorners),
            _ => {}
        }
        handles.push(h);
    }
    // Multiplicity of each directed boundary edge between spade vertices.
    let mut multiplicity: HashMap<(usize, usize), i32> = HashMap::with_capacity(n);
    for i in 0..n {
        let (a, b) = (handles[i], handles[(i + 1) % n]);
        if a == b {
            continue;
        }
        let edges = cdt.try_add_constraint(a, b);
        if edges.is_empty() {
            return Err(Fallback::SelfIntersecting);
        }
        let dir = flat[(i + 1) % n] - flat[i];
        for e in edges {
            let e = cdt.directed_edge(e);
            let (from, to) = (e.from(), e.to());
            let step = to.position();
            let start = from.position();
            let along = (step.x - start.x) * dir.x + (step.y - start.y) * dir.y;
            let key = if along >= 0.0 {
                (from.fix().index(), to.fix().index())
            } else {
                (to.fix().index(), from.fix().index())
            };
            *multiplicity.entry(key).or_insert(0) += 1;
        }
    }
    let m = |a: usize, b: usize| multiplicity.get(&(a, b)).copied().unwrap_or(0);
    // Winding numbers by a walk over faces from the outer face. Every face
    // lies to the left of its own directed edges; crossing edge a→b from its
    // left to its right changes the winding by −m(a→b) + m(b→a).
    let mut winding: Vec<Option<i32>> = vec![None; cdt.num_all_faces()];
    let outer: FixedFaceHandle<PossiblyOuterTag> = OUTER_FACE;
    winding[outer.index()] = Some(0);
    let mut stack = vec![outer];
    let edge_budget = cdt.num_directed_edges() + 3;
    while let Some(f) = stack.pop() {
        let wf = winding[f.index()].unwrap_or(0);
        let Some(start) = cdt.face(f).adjacent_edge() else {
            continue;
        };
        let mut e = start;
        for _ in 0..edge_budget {
            let (a, b) = (e.from().fix().index(), e.to().fix().index());
            let neighbour = e.rev().face().fix();
            let slot = &mut winding[neighbour.index()];
            if slot.is_none() {
                *slot = Some(wf - m(a, b) + m(b, a));
                stack.push(neighbour);
            }
            e = e.next();
            if e == start {
                break;
            }
        }
    }
    for face in cdt.inner_faces() {
        let w = winding[face.fix().index()].unwrap_or(0);
        if w == 0 {
            continue;
        }
        let [a, b, c] = face.vertices().map(|v| corner_of[v.fix().index()]);
        out.push(if w > 0 { [a, b, c] } else { [a, c, b] });
    }
    Ok(())
}

/// Twice the signed area of a 2D polygon (positive when counter-clockwise).
fn signed_area2(p: &[DVec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n])).sum()
}

/// Ear clipping in the plane, for polygons CDT cannot take. Always emits
/// `n − 2` triangles in the polygon's own turning order; when no proper ear
/// exists (a self-intersecting polygon) it clips a convex corner anyway, or
/// the first corner.
fn ear_clip(flat: &[DVec2], out: &mut Vec<[u32; 3]>) {
    let sign = if signed_area2(flat) < 0.0 { -1.0 } else { 1.0 };
    let mut ring: Vec<usize> = (0..flat.len()).collect();
    while ring.len() > 3 {
        let k = ring.len();
        let corner = |i: usize| (ring[(i + k - 1) % k], ring[i], ring[(i + 1) % k]);
        let convex = |i: usize| {
            let (a, b, c) = corner(i);
            sign * (flat[b] - flat[a]).perp_dot(flat[c] - flat[b]) > 0.0
        };
        let is_ear = |i: usize| {
            let (a, b, c) = corner(i);
            convex(i)
                && ring.iter().all(|&j| {
                    j == a || j == b || j == c || !in_triangle(flat[j], flat[a], flat[b], flat[c])
                })
        };
        let pick = (0..k)
            .find(|&i| is_ear(i))
            .or_else(|| (0..k).find(|&i| convex(i)))
            .unwrap_or(0);
        let (a, b, c) = corner(pick);
        out.push([a as u32, b as u32, c as u32]);
        ring.remove(pick);
    }
    if let [a, b, c] = ring[..] {
        out.push([a as u32, b as u32, c as u32]);
    }
}

/// Whether `p` lies inside or on triangle `abc` (either orientation).
fn in_triangle(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> bool {
    let d1 = (b - a).perp_dot(p - a);
    let d2 = (c - b).perp_dot(p - b);
    let d3 = (a - c).perp_dot(p - c);
    let neg = d1 < 0.0 || d2 < 0.0 || d3 < 0.0;
    let pos = d1 > 0.0 || d2 > 0.0 || d3 > 0.0;
    !(neg && pos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn run(points: &[Vec3]) -> (Vec<[u32; 3]>, Outcome) {
        let mut out = Vec::new();
        let outcome = triangulate(points, &mut out);
        (out, outcome)
    }

    fn xy(points: &[(f32, f32)]) -> Vec<Vec3> {
        points.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect()
    }

    /// Twice the vector area of a triangle, in f64.
    fn tri_normal(p: &[Vec3], t: [u32; 3]) -> DVec3 {
        let [a, b, c] = t.map(|i| p[i as usize].as_dvec3());
        (b - a).cross(c - a)
    }

    fn polygon_normal(p: &[Vec3]) -> DVec3 {
        let d: Vec<DVec3> = p.iter().map(|q| q.as_dvec3()).collect();
        newell_normal(&d, DVec3::ZERO)
    }

    fn total_area(p: &[Vec3], tris: &[[u32; 3]]) -> f64 {
        tris.iter().map(|&t| tri_normal(p, t).length() / 2.0).sum()
    }

    #[test]
    fn l_shaped_hexagon_gives_four_triangles_of_its_exact_area() {
        // The L: a 2×2 square without its top-right unit square; area 3.
        let p = xy(&[
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Cdt);
        assert_eq!(tris.len(), 4);
        assert_eq!(total_area(&p, &tris), 3.0);
        for &t in &tris {
            assert!(tri_normal(&p, t).z > 0.0, "triangle {t:?} flipped");
        }
    }

    #[test]
    fn clockwise_polygon_keeps_clockwise_triangles() {
        let mut p = xy(&[
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]);
        p.reverse();
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Cdt);
        assert_eq!(tris.len(), 4);
        for &t in &tris {
            assert!(tri_normal(&p, t).z < 0.0, "triangle {t:?} flipped");
        }
    }

    #[test]
    fn quad_wound_many_times_gives_two_triangles() {
        // box_longline.obj: the face runs round one quad 118 times.
        let quad = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        let p: Vec<Vec3> = quad.iter().copied().cycle().take(4 * 118).collect();
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Cdt);
        assert_eq!(tris.len(), 2);
        assert_eq!(total_area(&p, &tris), 1.0);
    }

    #[test]
    fn collinear_corner_and_repeated_corner_are_kept_simple() {
        // A square with a corner on its bottom edge and the last corner repeated.
        let p = xy(&[
            (0.0, 0.0),
            (1.0, 0.0),
            (2.0, 0.0),
            (2.0, 2.0),
            (0.0, 2.0),
            (0.0, 2.0),
        ]);
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Cdt);
        assert_eq!(tris.len(), 3);
        assert_eq!(total_area(&p, &tris), 4.0);
        assert!(
            tris.iter().all(|t| !t.contains(&5)),
            "duplicate corner 5 maps to corner 4"
        );
    }

    #[test]
    fn bow_tie_falls_back_to_ear_clipping() {
        let p = xy(&[(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 3.0)]);
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Fallback(Fallback::SelfIntersecting));
        assert_eq!(tris.len(), 2);
    }

    #[test]
    fn collinear_polygon_is_fanned() {
        let p = xy(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]);
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::ZeroArea);
        assert_eq!(tris.len(), 2);
        // city.obj's flat roofs: two corners, each written twice.
        let p = xy(&[(5.0, 7.0), (5.0, 3.0), (5.0, 3.0), (5.0, 7.0)]);
        assert_eq!(run(&p).1, Outcome::ZeroArea);
    }

    #[test]
    fn cancelling_lobes_are_fanned_with_a_fallback() {
        // A symmetric bow-tie: its lobes' signed areas cancel.
        let p = xy(&[(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0)]);
        let (tris, outcome) = run(&p);
        assert_eq!(outcome, Outcome::Fallback(Fallback::NoPlane));
        assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn folded_polygon_with_coincident_projection_is_ear_clipped() {
        // Corners 1 and 2 differ only along the best-fit normal (z).
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1e-3),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let (tris, outcome) = run(&p);
        assert!(tris.len() <= 3);
        assert!(matches!(
            outcome,
            Outcome::Cdt | Outcome::Fallback(Fallback::CoincidentCorners)
        ));
    }

    #[test]
    fn tiny_polygons() {
        assert_eq!(run(&[]).0, Vec::<[u32; 3]>::new());
        assert_eq!(run(&xy(&[(0.0, 0.0), (1.0, 0.0)])).0.len(), 0);
        assert_eq!(
            run(&xy(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])).0,
            vec![[0, 1, 2]]
        );
    }

    /// A star-shaped (hence simple, often concave) polygon placed in a random
    /// plane of 3D, possibly wound clockwise.
    fn star_polygon() -> impl Strategy<Value = Vec<Vec3>> {
        (4usize..48)
            .prop_flat_map(|n| {
                (
                    prop::collection::vec((0.0f64..0.8, 0.15f64..1.0), n),
                    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
                    0.0f64..std::f64::consts::TAU,
                    (-10.0f64..10.0, -10.0f64..10.0, -10.0f64..10.0),
                    any::<bool>(),
                    0.01f64..100.0,
                )
            })
            .prop_map(|(corners, axis, angle, offset, reverse, scale)| {
                let n = corners.len();
                let axis = DVec3::new(axis.0, axis.1, axis.2 + 1.5).normalize();
                let rot = glam::DQuat::from_axis_angle(axis, angle);
                let offset = DVec3::new(offset.0, offset.1, offset.2);
                let mut p: Vec<Vec3> = corners
                    .iter()
                    .enumerate()
                    .map(|(i, &(jitter, r))| {
                        let a = (i as f64 + jitter) * std::f64::consts::TAU / n as f64;
                        let q = DVec3::new(a.cos() * r, a.sin() * r, 0.0) * scale;
                        (rot * q + offset).as_vec3()
                    })
                    .collect();
                if reverse {
                    p.reverse();
                }
                p
            })
    }

    proptest! {
        #[test]
        fn simple_polygon_laws(p in star_polygon()) {
            let (tris, outcome) = run(&p);
            prop_assert_eq!(outcome, Outcome::Cdt);
            prop_assert_eq!(tris.len(), p.len() - 2);
            let normal = polygon_normal(&p);
            let area = normal.length() / 2.0;
            let sum = total_area(&p, &tris);
            prop_assert!((sum - area).abs() <= 1e-5 * area, "area {} vs polygon {}", sum, area);
            for &t in &tris {
                prop_assert!(t.iter().all(|&i| (i as usize) < p.len()));
                prop_assert!(tri_normal(&p, t).dot(normal) > 0.0, "triangle {:?} flipped", t);
            }
        }

        #[test]
        fn arbitrary_polygons_never_panic(
            p in prop::collection::vec((-4i32..4, -4i32..4, -1i32..2), 0..24)
        ) {
            // Small integer grids make duplicates, collinear runs and crossings likely.
            let p: Vec<Vec3> = p.iter().map(|&(x, y, z)| Vec3::new(x as f32, y as f32, z as f32 * 0.25)).collect();
            let (tris, _) = run(&p);
            prop_assert!(tris.len() <= 2 * p.len());
            for t in &tris {
                prop_assert!(t.iter().all(|&i| (i as usize) < p.len()));
            }
        }
    }
}
