//! The intersection body B = conv(V ∪ l) ∩ S [Steiner §4.3.3, Listing 4.1,
//! Fig. 4.12; after Wimmer et al.]: the region whose objects matter for the
//! light's visibility pass, with V the view frustum, l the light (a point, or a
//! direction at infinity) and S the scene bounds.
//!
//! What is built is conv(P ∪ l) ∩ S with P = V ∩ S: it holds every segment
//! from the light to a point of V ∩ S — where every visible receiver lies, so
//! every caster that can shadow one — and is contained in conv(V ∪ l) ∩ S
//! (often strictly: parts of V outside S add nothing).
//! It is an intersection of half-spaces, each containing conv(P ∪ l):
//!
//! * S's six planes;
//! * the planes of P that do not face the light (those of its faces, and any
//!   cutting plane a flat P keeps only in its plane list) — a plane that
//!   has the light on its inside (positive) side, `plane(l) ≥ −tol`; for a
//!   directional light travelling along `d`, `normal · d ≤ 0` (moving toward
//!   the light never leaves the half-space), or `≤ PARALLEL_EPS` = 1e-12 with
//!   the normal then made exactly perpendicular to `d`. (Keeping a plane with
//!   the light just on it matters for a flat P, whose cut edges are no face's
//!   edges; see below.) Faces facing the light are the
//!   ones the listing's `createConvexHullWithPoint` removes;
//! * the planes through each edge of P and the light point (directional: the
//!   plane through the edge parallel to `d`) that support P — P and l on one
//!   side (both orientations when P and l are flat in it); for a flat P
//!   (volume ≤ tol · diam²) also the planes through l and each vertex
//!   containing a face normal, which bound the flat hull sideways. These are the silhouette edges' fan (point) or extrusion (direction)
//!   planes of the listing; a non-silhouette edge whose plane also supports P
//!   adds a redundant but valid half-space.
//!
//! An edge plane counts as supporting when no vertex of P lies more than
//! `tol = REL_EPS · (diam P + |l − centroid P|) + COORD_EPS · max |coordinate|`
//! on its wrong side (`REL_EPS`, `COORD_EPS` as in the polyhedron module); for a
//! directional light its normal has the component along `d` removed, so the
//! extrusion stays inside to ~1e-16 per unit of length.
//! Each plane is then shifted outward by the largest violation of any vertex of P
//! (and l) so that every half-space contains them exactly in f64 evaluation:
//! rounding can only make B larger, never drop a point of conv(P ∪ l). A
//! degenerate plane (l on the edge's line, an edge parallel to `d`) is
//! skipped, which also only makes B larger. The light inside P needs no
//! special case: no edge plane through an interior point supports P, every
//! face is kept, and B = P. A light on a frustum plane is robust the same way:
//! whether the face is kept or not, the edge planes of that face reproduce it.

use crate::polyhedron::{ClipScratch, COORD_EPS, REL_EPS};
pub use crate::polyhedron::{Face, Polyhedron};
use glam::DVec3;
use scene::{Aabb, Frustum, Light, Plane};

/// |normal · d| below which a plane of P counts as parallel to a directional
/// light's travel direction `d` (unit vectors; ~1e4 f64 roundings).
const PARALLEL_EPS: f64 = 1e-12;

/// The light as the hull construction sees it.
#[derive(Clone, Copy)]
enum Source {
    /// A point light position.
    Point(DVec3),
    /// A unit direction the light travels.
    Direction(DVec3),
}

/// The intersection body B = conv(V ∪ l) ∩ S in world space (f64)
/// [Steiner §4.3.3, Listing 4.1], built as conv((V ∩ S) ∪ l) ∩ S (see the
/// module docs): B ⊆ S, and B holds every segment from the light to a point
/// of V ∩ S (for a directional light, every ray from such a point toward the
/// light, within S).
///
/// `frustum` is V (far end at infinity), `scene_bounds` is S. Point and spot
/// lights use their position (a spot's cone is not applied here: the light
/// views clip B by it, see [`crate::fit_light_views`]; ranges are not
/// applied); directional lights use their direction of travel. The light may
/// lie anywhere, inside V, on its planes or outside S.
///
/// Returns the empty polyhedron when V ∩ S is empty (or meets S in only an
/// edge or a vertex), when `light` fails [`Light::validate`] (e.g. a zero
/// direction), or when the frustum has non-finite planes — callers that must
/// tell these apart validate the light first.
pub fn intersection_body(frustum: &Frustum, light: &Light, scene_bounds: &Aabb) -> Polyhedron {
    let mut out = Polyhedron::default();
    intersection_body_into(
        frustum,
        light,
        scene_bounds,
        &mut out,
        &mut BodyScratch::default(),
    );
    out
}

/// Buffers [`intersection_body_into`] reuses from frame to frame.
#[derive(Debug, Default)]
pub(crate) struct BodyScratch {
    /// V ∩ S.
    p: Polyhedron,
    pub(crate) clip: ClipScratch,
    planes: Vec<Plane>,
    lines: Vec<(DVec3, DVec3)>,
    edges: Vec<(usize, usize)>,
    normals: Vec<DVec3>,
}

/// [`intersection_body`] into `out`, with buffers reused from `s`: no
/// allocation once they have grown.
pub(crate) fn intersection_body_into(
    frustum: &Frustum,
    light: &Light,
    scene_bounds: &Aabb,
    out: &mut Polyhedron,
    s: &mut BodyScratch,
) {
    out.clear();
    if light.validate().is_err()
        || frustum
            .planes
            .iter()
            .any(|p| !p.normal.is_finite() || !p.d.is_finite())
    {
        return;
    }
    s.p.set_frustum(frustum, scene_bounds, &mut s.clip);
    if s.p.is_empty() {
        return;
    }
    let source = match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => Source::Point(position),
        Light::Directional { direction } => Source::Direction(direction.normalize()),
    };
    let p = std::mem::take(&mut s.p);
    hull_planes(&p, source, s);
    s.p = p;
    out.set_aabb(scene_bounds);
    for pl in &s.planes {
        out.clip_with(pl, &mut s.clip);
        if out.is_empty() {
            break;
        }
    }
}

/// Half-spaces whose intersection is conv(P ∪ l) (each shifted to contain P
/// and l exactly; see the module docs), into `s.planes`.
fn hull_planes(p: &Polyhedron, source: Source, s: &mut BodyScratch) {
    let verts = p.vertices();
    let extra = match source {
        Source::Point(l) => Some(l),
        Source::Direction(_) => None,
    };
    // Support tolerance: rounding of plane evaluations over P and l.
    let c = p.centroid();
    let (far, coord) = match source {
        Source::Point(l) => ((l - c).length(), l.abs().max_element()),
        Source::Direction(_) => (0.0, 0.0),
    };
    let coord = verts
        .iter()
        .map(|v| v.abs().max_element())
        .fold(coord, f64::max);
    let tol = REL_EPS * (p.diameter() + far) + COORD_EPS * coord;

    let out = &mut s.planes;
    out.clear();
    // Planes of P not facing the light (every plane of P, not only those of
    // its faces: a flat or degenerate P keeps its cutting planes there).
    for pl in p.planes() {
        let kept = match source {
            // A light within `tol` of the plane keeps it (then shifted onto l).
            Source::Point(l) => (pl.signed_distance(l) >= -tol).then_some(*pl),
            Source::Direction(d) => {
                let nd = pl.normal.dot(d);
                if nd <= 0.0 {
                    Some(*pl)
                } else if nd <= PARALLEL_EPS {
                    // Parallel to d up to rounding: made exactly parallel.
                    Some(Plane {
                        normal: (pl.normal - d * nd).normalize(),
                        d: pl.d,
                    })
                } else {
                    None
                }
            }
        };
        if let Some(pl) = kept {
            out.push(enclose(pl, verts, extra));
        }
    }
    // Candidate planes through l (or parallel to d) and a line of P: every
    // edge, and — for a flat P, whose hull with l has silhouette *vertices*
    // rather than edges — every vertex with a face normal as second
    // direction. Each is kept (both orientations if P and l are flat in it)
    // when it supports P.
    let (lines, edges) = (&mut s.lines, &mut s.edges);
    lines.clear();
    edges.clear();
    edges.extend(p.faces().flat_map(|f| {
        let n = f.vertices.len();
        (0..n).map(move |k| {
            let (a, b) = (f.vertices[k], f.vertices[(k + 1) % n]);
            (a.min(b), a.max(b))
        })
    }));
    edges.sort_unstable();
    edges.dedup();
    lines.extend(edges.iter().map(|&(i, j)| (verts[i], verts[j] - verts[i])));
    if p.volume() <= tol * p.diameter() * p.diameter() {
        let normals = &mut s.normals;
        normals.clear();
        for f in p.faces() {
            let n = f.plane.normal;
            if !normals.iter().any(|m| m.cross(n).length() <= 1e-12) {
                normals.push(n);
            }
        }
        for &v in verts {
            lines.extend(normals.iter().map(|&n| (v, n)));
        }
    }
    for &(a, e) in lines.iter() {
        let normal = match source {
            Source::Point(l) => {
                let n = e.cross(l - a);
                if n.length().is_nan() || n.length() <= 1e-12 * e.length() * (l - a).length() {
                    continue; // l on the line
                }
                n.normalize()
            }
            Source::Direction(d) => {
                let n = e.cross(d);
                if n.length().is_nan() || n.length() <= 1e-12 * e.length() {
                    continue; // line parallel to d
                }
                // Remove the rounding component along d so the extrusion
                // stays inside to 1e-16 per unit length.
                let n = n.normalize();
                (n - d * n.dot(d)).normalize()
            }
        };
        let plane = Plane::from_point_normal(a, normal);
        let (lo, hi) = verts
            .iter()
            .map(|&v| plane.signed_distance(v))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(s), hi.max(s))
            });
        if lo >= -tol {
            out.push(enclose(plane, verts, extra));
        }
        if hi <= tol {
            let flipped = Plane {
                normal: -plane.normal,
                d: -plane.d,
            };
            out.push(enclose(flipped, verts, extra));
        }
    }
}

/// `plane` moved outward until every point of `pts` (and `extra`) is on its
/// positive side in f64 evaluation.
fn enclose(plane: Plane, pts: &[DVec3], extra: Option<DVec3>) -> Plane {
    let worst = pts
        .iter()
        .chain(extra.iter())
        .map(|&v| plane.signed_distance(v))
        .fold(0.0, f64::min);
    Plane {
        normal: plane.normal,
        d: plane.d - worst,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec3;
    use proptest::prelude::*;
    use scene::Camera;

    /// A random scene box S and camera: eye in ±100, looking at a random
    /// point of S (3 cases in 4) or in a random direction, fov 10°–170°,
    /// aspect 0.5–2, near 1e-4–1.
    pub(crate) fn setup() -> impl Strategy<Value = (Camera, Aabb)> {
        (
            scene_box(),
            prop::array::uniform3(-100.0..100.0f64),
            prop::array::uniform3(-1.0..1.0f64),
            0..4u8,
            10.0..170.0f64,
            0.5..2.0f64,
            -4.0..0.0f64,
        )
            .prop_filter_map("degenerate look", |(s, e, d, aim, fov, aspect, lg_near)| {
                let eye = DVec3::from(e);
                let dir = if aim == 0 {
                    DVec3::from(d)
                } else {
                    let t = DVec3::from(d) * 0.5 + 0.5;
                    s.min.as_dvec3() + s.size().as_dvec3() * t - eye
                };
                if dir.length() < 1e-3 {
                    return None;
                }
                let up = if dir.normalize().y.abs() > 0.9 {
                    DVec3::X
                } else {
                    DVec3::Y
                };
                let near = 10f64.powf(lg_near);
                Camera::look_at(eye, eye + dir, up, fov.to_radians(), aspect, near)
                    .ok()
                    .map(|c| (c, s))
            })
    }

    /// A random scene box: centre in ±100 (1 case in 5 moved 1e6 from the
    /// origin), sizes 0–120 per axis (1 case in 4 flat in y).
    pub(crate) fn scene_box() -> impl Strategy<Value = Aabb> {
        (
            prop::array::uniform3(-100.0..100.0f32),
            prop::array::uniform3(0.0..120.0f32),
            0..4u8,
            0..5u8,
        )
            .prop_map(|(c, s, flat, far)| {
                let mut c = Vec3::from(c);
                if far == 0 {
                    c += Vec3::new(1e6, -1e6, 1e6);
                }
                let mut s = Vec3::from(s);
                if flat == 0 {
                    s.y = 0.0;
                }
                Aabb::new(c - 0.5 * s, c + 0.5 * s)
            })
    }

    /// A random light for camera `cam` and box `s`, from one of the listed
    /// cases; `pick` chooses the case, `a, b, c` place it.
    pub(crate) fn light_for(cam: &Camera, s: &Aabb, pick: u8, a: f64, b: f64, c: DVec3) -> Light {
        let f = cam.frustum();
        let e = f.apex;
        let dir = |k: usize| f.far_directions[k % 4];
        let point = |position| Light::Point {
            position,
            range: None,
        };
        match pick % 13 {
            // Inside V.
            0 => {
                let d =
                    (dir(0) * a + dir(1) * b + dir(2) * (1.0 - a) + dir(3) * (1.0 - b)).normalize();
                point(e + d * ((cam.near * 1.01 + 50.0 * a * b) / d.dot(cam.forward())))
            }
            // On a frustum side plane (between two adjacent edges).
            1 => {
                let k = (b * 4.0) as usize;
                let d = dir(k) * a + dir(k + 1) * (1.0 - a);
                point(e + d * (cam.near + 30.0 * b))
            }
            // At the eye (on all four side planes).
            2 => point(e),
            // On the near plane.
            3 => point(
                f.near_corners[0]
                    + (f.near_corners[1] - f.near_corners[0]) * (3.0 * a - 1.0)
                    + (f.near_corners[3] - f.near_corners[0]) * (3.0 * b - 1.0),
            ),
            // Far away at 1e5.
            4 => point(s.center() + c.normalize_or(DVec3::X) * 1e5),
            // Inside S.
            5 => point(s.min.as_dvec3() + (s.max - s.min).as_dvec3() * DVec3::new(a, b, 0.5)),
            // Anywhere near (inside or outside S).
            6 => point(s.center() + c * 150.0),
            // Directional, random.
            7 => Light::Directional {
                direction: c.normalize_or(DVec3::Y),
            },
            // Directional along a side edge (parallel to two frustum planes).
            8 => Light::Directional {
                direction: dir((a * 4.0) as usize) * if b < 0.5 { 1.0 } else { -1.0 },
            },
            // Directional parallel to a frustum plane.
            9 => {
                let n = f.planes[(a * 5.0) as usize % 5].normal;
                let d = c - n * n.dot(c);
                Light::Directional {
                    direction: d.normalize_or(n.any_orthogonal_vector()),
                }
            }
            // Spot light anywhere near.
            10 => Light::Spot {
                position: s.center() + c * 120.0,
                direction: -c.normalize_or(DVec3::Y) + DVec3::new(a - 0.5, b - 0.5, 0.0),
                apex_angle: (20.0 + 150.0 * a).to_radians(),
                range: None,
            },
            // At a vertex of V ∩ S (on several of its planes at once).
            12 => {
                let p = Polyhedron::from_frustum(&f, s);
                let v = p.vertices();
                point(if v.is_empty() {
                    e
                } else {
                    v[(a * v.len() as f64) as usize % v.len()]
                })
            }
            // Directional along the view direction.
            _ => Light::Directional {
                direction: cam.forward() * if a < 0.5 { 1.0 } else { -1.0 },
            },
        }
    }

    /// Tolerance of the property checks: 1e-12 of (S's diameter + the light's
    /// distance from S's centre + S's distance from the origin).
    pub(crate) fn check_tol(s: &Aabb, light: &Light) -> f64 {
        let c = s.center();
        let far = light.position().map_or(0.0, |l| (l - c).length());
        1e-12 * (s.size().as_dvec3().length() + far + c.length() + 1.0)
    }

    /// A point in P: a random convex combination of its vertices.
    pub(crate) fn sample_in(p: &Polyhedron, weights: &[f64]) -> DVec3 {
        let v = p.vertices();
        let mut sum = 0.0;
        let mut acc = DVec3::ZERO;
        for (i, &x) in v.iter().enumerate() {
            let w = weights[i % weights.len()].powi(4) + 1e-12;
            acc += x * w;
            sum += w;
        }
        acc / sum
    }

    /// The facet planes of conv(P ∪ l) by brute force (oracle for the
    /// tightness check): every plane through three of P's vertices and l
    /// (directional: also through two vertices parallel to d, and only planes
    /// the extrusion stays inside) with all of them on its positive side up
    /// to `tol`. For a P and l that are flat together, only their common plane.
    fn hull_facets(p: &Polyhedron, light: &Light, tol: f64) -> Vec<Plane> {
        let mut pts = p.vertices().to_vec();
        let dir = match *light {
            Light::Directional { direction } => Some(direction.normalize()),
            _ => {
                pts.push(light.position().unwrap());
                None
            }
        };
        let mut normals = Vec::new();
        let n = pts.len();
        for i in 0..n {
            for j in i + 1..n {
                if let Some(d) = dir {
                    normals.push((pts[i], (pts[j] - pts[i]).cross(d)));
                }
                for k in j + 1..n {
                    normals.push((pts[i], (pts[j] - pts[i]).cross(pts[k] - pts[i])));
                }
            }
        }
        let mut out = Vec::new();
        for (a, nrm) in normals {
            if nrm.length().is_nan() || nrm.length() <= 0.0 {
                continue;
            }
            for sign in [1.0, -1.0] {
                let mut nn = nrm.normalize() * sign;
                if let Some(d) = dir {
                    if nn.dot(d) > 1e-9 {
                        continue;
                    }
                    nn -= d * nn.dot(d).max(0.0);
                }
                let pl = Plane::from_point_normal(a, nn);
                if pts.iter().all(|&v| pl.signed_distance(v) >= -tol) {
                    out.push(pl);
                }
            }
        }
        out
    }

    /// Tolerance factor of the tightness check, over [`check_tol`].
    const TIGHT_REL: f64 = 1e3;

    fn in_box(s: &Aabb, p: DVec3, tol: f64) -> bool {
        p.cmpge(s.min.as_dvec3() - tol).all() && p.cmple(s.max.as_dvec3() + tol).all()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn body_is_in_s_and_holds_every_light_ray(
            (cam, s) in setup(),
            pick in 0..13u8,
            a in 0.0..1.0f64,
            b in 0.0..1.0f64,
            c in prop::array::uniform3(-1.0..1.0f64),
            weights in prop::collection::vec(0.0..1.0f64, 1..12),
            ts in prop::collection::vec(0.0..1.0f64, 8),
        ) {
            let light = light_for(&cam, &s, pick, a, b, DVec3::from(c));
            prop_assume!(light.validate().is_ok());
            let frustum = cam.frustum();
            let body = intersection_body(&frustum, &light, &s);
            let p = Polyhedron::from_frustum(&frustum, &s);
            let tol = check_tol(&s, &light);
            prop_assert_eq!(body.is_empty(), p.is_empty());
            for v in body.vertices() {
                prop_assert!(in_box(&s, *v, tol), "vertex {v} outside S");
            }
            if p.is_empty() {
                return Ok(());
            }
            for v in p.vertices() {
                prop_assert!(body.contains(*v, tol), "P's vertex {v} outside B");
            }
            // Tightness: every vertex of B lies in conv(P ∪ l), up to
            // TIGHT_REL · tol (B's planes may be shifted outward by rounding,
            // and vertices of nearly parallel planes amplify it), plus the
            // tilt of planes built on P's near face: its corners are known to
            // a few ulps of the coordinates, over the face's size, which far
            // from it outgrows any fixed tolerance (a near plane 1.7·10⁻⁴
            // from an eye 100 from the origin).
            // Not for an S of zero area (a segment or a point): B's ends along
            // it are not derived there (B is conservative, not tight).
            let flat_axes = s.size().to_array().iter().filter(|&&x| x == 0.0).count();
            let facets = hull_facets(&p, &light, TIGHT_REL * tol);
            let scale = (p.vertices().iter().chain(&[cam.position]))
                .chain(light.position().as_ref())
                .map(|v| v.abs().max_element())
                .fold(1.0, f64::max);
            let near_half = cam.near * (cam.fov_y * 0.5).tan() * cam.aspect.min(1.0);
            let tilt = 64.0 * f64::EPSILON * scale / near_half;
            for v in body.vertices().iter().filter(|_| flat_axes < 2) {
                let slack = TIGHT_REL * tol + tilt * (*v - cam.position).length();
                let worst = facets.iter().map(|f| f.signed_distance(*v)).fold(0.0, f64::min);
                prop_assert!(worst >= -slack, "B's vertex {v} outside conv(P ∪ l) by {worst:e} (slack {slack:e})");
            }
            let diam = s.size().as_dvec3().length();
            for k in 0..weights.len().max(3) {
                let mut w = weights.clone();
                w.rotate_left(k % weights.len());
                let q = sample_in(&p, &w);
                for &t in &ts {
                    let x = match light {
                        Light::Directional { direction } => q - direction.normalize() * (t * diam),
                        _ => {
                            let l = light.position().unwrap();
                            l + (q - l) * t
                        }
                    };
                    if in_box(&s, x, 0.0) {
                        prop_assert!(body.contains(x, tol), "{x} (t = {t}) in S but not in B");
                    }
                }
            }
        }
    }

    fn camera_at_origin() -> Camera {
        Camera::look_at(
            DVec3::ZERO,
            DVec3::NEG_Z,
            DVec3::Y,
            60f64.to_radians(),
            1.0,
            0.1,
        )
        .unwrap()
    }

    #[test]
    fn light_inside_gives_v_cap_s() {
        let cam = camera_at_origin();
        let s = Aabb::new(Vec3::new(-10.0, -10.0, -20.0), Vec3::new(10.0, 10.0, 10.0));
        let p = Polyhedron::from_frustum(&cam.frustum(), &s);
        let light = Light::Point {
            position: DVec3::new(0.0, 0.0, -5.0),
            range: None,
        };
        let b = intersection_body(&cam.frustum(), &light, &s);
        assert!((b.volume() - p.volume()).abs() < 1e-9 * p.volume());
    }

    #[test]
    fn light_behind_the_eye_grows_the_body() {
        let cam = camera_at_origin();
        let s = Aabb::new(Vec3::new(-10.0, -10.0, -20.0), Vec3::new(10.0, 10.0, 10.0));
        let p = Polyhedron::from_frustum(&cam.frustum(), &s);
        let light = Light::Point {
            position: DVec3::new(0.0, 0.0, 5.0),
            range: None,
        };
        let b = intersection_body(&cam.frustum(), &light, &s);
        assert!(b.volume() > p.volume() * 1.01);
        assert!(b.contains(DVec3::new(0.0, 0.0, 4.9), 1e-9));
        assert!(!b.contains(DVec3::new(5.0, 0.0, 4.9), 1e-9));
        // A sun from straight above: the prism above P up to S's top.
        let sun = Light::Directional {
            direction: DVec3::NEG_Y,
        };
        let b = intersection_body(&cam.frustum(), &sun, &s);
        assert!(b.contains(DVec3::new(0.0, 9.9, -15.0), 1e-9));
        assert!(!b.contains(DVec3::new(0.0, 9.9, 5.0), 1e-9));
    }

    #[test]
    fn invalid_or_missing_inputs_give_empty() {
        let cam = camera_at_origin();
        let s = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let zero = Light::Directional {
            direction: DVec3::ZERO,
        };
        assert!(intersection_body(&cam.frustum(), &zero, &s).is_empty());
        let behind = Aabb::new(Vec3::new(-1.0, -1.0, 5.0), Vec3::new(1.0, 1.0, 6.0));
        let sun = Light::Directional {
            direction: DVec3::NEG_Y,
        };
        assert!(intersection_body(&cam.frustum(), &sun, &behind).is_empty());
        assert!(intersection_body(&cam.frustum(), &sun, &Aabb::EMPTY).is_empty());
    }
}
