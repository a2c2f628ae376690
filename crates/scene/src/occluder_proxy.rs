//! Automatic conservative occluders: a convex solid mesh's proxy is the
//! convex hull of a few of its own vertices.
//!
//! An occluder may hide only what its object hides, so a proxy must lie
//! inside the object's solid. The check: every chosen vertex lies behind
//! every face's plane. That puts their hull inside the intersection K of
//! the faces' inner half-spaces (convex), and K lies inside the solid of any
//! closed mesh: from a point outside, the nearest surface point is on a
//! face, or on a convex edge or vertex, whose plane (one of them) it is in
//! front of. For a convex solid K is the solid, so the check passes; for a
//! non-convex one it usually fails. The subset is spread over the mesh by
//! farthest-point sampling, so the proxy keeps most of the silhouette (a 32 × 16 UV sphere's
//! 16-vertex proxy covers about 80 % of its silhouette with 28 triangles
//! instead of 960). The proxy's triangles index the mesh's own vertices, so
//! a renderer draws them from the same vertex buffer, transformed alike: no
//! new rounding.
//!
//! Meshes that are not solid, that fail the check (non-convex ones), or too
//! small to gain keep their full mesh as occluder ([`occluder_proxy`] gives
//! `None`). Inscribed boxes for non-convex solids are left for later.

use crate::mesh::{Mesh, Solid};
use glam::DVec3;

/// Vertices a proxy is built from at most: its hull has at most
/// `2 · PROXY_VERTICES − 4` faces.
pub const PROXY_VERTICES: usize = 16;

/// Relative tolerance (of the bounds' diagonal) within which a chosen
/// vertex may lie in front of a face's plane: the f32 positions of one flat
/// face of a convex shape (a cylinder's side, as two triangles) round to
/// about 1e-7 off each other's planes. The proxy may reach that far out of
/// the solid, the rounding of the mesh's own positions.
const PLANE_TOLERANCE: f64 = 1e-6;

/// The proxy of `mesh`: triangles over its vertex indices, counter-clockwise
/// seen from outside, forming the convex hull of [`PROXY_VERTICES`] of its
/// vertices. `None` unless the mesh is solid (outward), those vertices lie
/// behind every face (within 1e-6 of the bounds' diagonal; see the module doc) and
/// the mesh has more triangles than the proxy.
pub fn occluder_proxy(mesh: &Mesh) -> Option<Vec<[u32; 3]>> {
    if mesh.solid() != Some(Solid::Outward) {
        return None;
    }
    let (positions, triangles) = (mesh.positions(), mesh.triangles());
    if triangles.len() <= 2 * PROXY_VERTICES {
        return None;
    }
    let b = mesh.bounds();
    let centre = b.center();
    // Centred, so that the tests keep their precision far from the origin.
    let p: Vec<DVec3> = positions.iter().map(|v| v.as_dvec3() - centre).collect();
    let diag = (b.max - b.min).as_dvec3().length();
    let chosen = farthest_points(&p, PROXY_VERTICES);
    let q: Vec<DVec3> = chosen.iter().map(|&i| p[i]).collect();
    if !behind_every_face(&p, triangles, &q, PLANE_TOLERANCE * diag) {
        return None;
    }
    let hull = hull_of(&q, diag)?;
    let proxy: Vec<[u32; 3]> = hull.iter().map(|t| t.map(|k| chosen[k] as u32)).collect();
    (proxy.len() < triangles.len()).then_some(proxy)
}

/// Relative tolerance (of the bounds' diagonal) of [`is_convex_solid`]:
/// tighter than a proxy's, since a convex draw covers the whole silhouette
/// of the vertices' hull.
const CONVEX_TOLERANCE: f64 = 1e-7;

/// Whether `mesh` bounds a convex solid: it is solid (outward) and every
/// vertex lies behind every face's plane (within 10⁻⁷ of the bounds'
/// diagonal). Checked for meshes of at most `2 · PROXY_VERTICES` triangles
/// (a box, a wedge; larger ones answer `false`, their proxies being the
/// convex solids the views draw).
pub fn is_convex_solid(mesh: &Mesh) -> bool {
    let (positions, triangles) = (mesh.positions(), mesh.triangles());
    if mesh.solid() != Some(Solid::Outward)
        || triangles.len() > 2 * PROXY_VERTICES
        || triangles.len() < 4
    {
        return false;
    }
    let b = mesh.bounds();
    let centre = b.center();
    let p: Vec<DVec3> = positions.iter().map(|v| v.as_dvec3() - centre).collect();
    let diag = (b.max - b.min).as_dvec3().length();
    diag > 0.0 && behind_every_face(&p, triangles, &p, CONVEX_TOLERANCE * diag)
}

/// Whether every point of `q` lies behind (within `tol`) every
/// non-degenerate face's outward plane.
fn behind_every_face(p: &[DVec3], triangles: &[[u32; 3]], q: &[DVec3], tol: f64) -> bool {
    triangles.iter().all(|t| {
        let [a, b, c] = t.map(|i| p[i as usize]);
        let n = (b - a).cross(c - a);
        let len = n.length();
        // Degenerate (or NaN) faces bound nothing.
        if len.is_nan() || len <= 0.0 {
            return true;
        }
        let n = n / len;
        q.iter().all(|v| n.dot(*v - a) <= tol)
    })
}

/// Up to `k` distinct vertices of `p` spread by farthest-point sampling:
/// first the one farthest from the centre, then each time the one farthest
/// from those chosen (ties: the lowest index, so the choice is
/// deterministic).
fn farthest_points(p: &[DVec3], k: usize) -> Vec<usize> {
    let mut chosen = Vec::with_capacity(k);
    let first = (0..p.len()).max_by(|&a, &b| {
        p[a].length_squared()
            .total_cmp(&p[b].length_squared())
            .then(b.cmp(&a))
    });
    let Some(first) = first else { return chosen };
    chosen.push(first);
    let mut dist: Vec<f64> = p.iter().map(|v| v.distance_squared(p[first])).collect();
    while chosen.len() < k {
        let (next, d) =
            dist.iter().enumerate().fold(
                (0, -1.0),
                |best, (i, &d)| if d > best.1 { (i, d) } else { best },
            );
        if d <= 0.0 {
            break;
        }
        chosen.push(next);
        for (i, v) in p.iter().enumerate() {
            dist[i] = dist[i].min(v.distance_squared(p[next]));
        }
    }
    chosen
}

/// The convex hull of a few points (brute force over triples, fine for
/// [`PROXY_VERTICES`]): every triple with all points on or behind its plane
/// is a face, oriented to face out; coplanar points give overlapping faces
/// on the same plane, harmless for an occluder. `None` when the points are
/// (nearly) coplanar.
fn hull_of(q: &[DVec3], scale: f64) -> Option<Vec<[usize; 3]>> {
    let n = q.len();
    let mut faces = Vec::new();
    let mut solid = false;
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let normal = (q[j] - q[i]).cross(q[k] - q[i]);
                let len = normal.length();
                if len.is_nan() || len <= 1e-12 * scale * scale {
                    continue;
                }
                let tol = 1e-9 * len * scale;
                let (mut front, mut back) = (false, false);
                for (m, v) in q.iter().enumerate() {
                    if m == i || m == j || m == k {
                        continue;
                    }
                    let s = normal.dot(*v - q[i]);
                    front |= s > tol;
                    back |= s < -tol;
                }
                match (front, back) {
                    (false, true) => faces.push([i, j, k]),
                    (true, false) => faces.push([i, k, j]),
                    (false, false) => {}
                    (true, true) => continue,
                }
                solid |= front || back;
            }
        }
    }
    (solid && faces.len() >= 4).then_some(faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use proptest::prelude::*;

    /// A UV sphere, counter-clockwise seen from outside.
    fn sphere(segments: u32, rings: u32) -> Mesh {
        let mut positions = vec![Vec3::Y];
        for r in 1..rings {
            let phi = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let theta = std::f32::consts::TAU * s as f32 / segments as f32;
                positions.push(Vec3::new(
                    phi.sin() * theta.cos(),
                    phi.cos(),
                    phi.sin() * theta.sin(),
                ));
            }
        }
        positions.push(Vec3::NEG_Y);
        let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
        let south = positions.len() as u32 - 1;
        let mut triangles = Vec::new();
        for s in 0..segments {
            triangles.push([0, ring(1, s + 1), ring(1, s)]);
            for r in 1..rings - 1 {
                let (a, b, c, d) = (
                    ring(r, s),
                    ring(r, s + 1),
                    ring(r + 1, s),
                    ring(r + 1, s + 1),
                );
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
            triangles.push([south, ring(rings - 1, s), ring(rings - 1, s + 1)]);
        }
        Mesh::new("sphere", &positions, &triangles).unwrap()
    }

    /// Every vertex of the proxy is the mesh's, and every point of it (its
    /// triangles' centroids and corners) lies behind every face of the mesh.
    fn assert_inside(mesh: &Mesh, proxy: &[[u32; 3]]) {
        let p = mesh.positions();
        let diag = (mesh.bounds().max - mesh.bounds().min).length() as f64;
        for t in proxy {
            let [a, b, c] = t.map(|i| p[i as usize].as_dvec3());
            for x in [a, b, c, (a + b + c) / 3.0] {
                for f in mesh.triangles() {
                    let [u, v, w] = f.map(|i| p[i as usize].as_dvec3());
                    let n = (v - u).cross(w - u);
                    if n.length() > 0.0 {
                        assert!(n.normalize().dot(x - u) <= 1e-6 * diag, "{x} outside");
                    }
                }
            }
        }
    }

    #[test]
    fn a_sphere_gets_a_small_proxy_inside_it() {
        let mesh = sphere(32, 16);
        let proxy = occluder_proxy(&mesh).expect("a convex solid");
        assert!(
            proxy.len() <= 2 * PROXY_VERTICES,
            "{} triangles",
            proxy.len()
        );
        assert_inside(&mesh, &proxy);
        // Faces out: the proxy's signed volume is positive and most of the sphere's.
        let p = mesh.positions();
        let volume: f64 = proxy
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| p[i as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        let ball = 4.0 / 3.0 * std::f64::consts::PI;
        assert!(volume > 0.5 * ball && volume < ball, "volume {volume}");
    }

    #[test]
    fn non_convex_open_and_small_meshes_keep_their_mesh() {
        // A sphere with one vertex pushed deep in: a dent whose faces'
        // planes cut off much of the sphere.
        let m = sphere(32, 16);
        let mut p = m.positions().to_vec();
        p[40] *= 0.2;
        let dented = Mesh::new("dented", &p, m.triangles()).unwrap();
        assert!(occluder_proxy(&dented).is_none());
        // Open: the south cap removed.
        let open = Mesh::new(
            "open",
            m.positions(),
            &m.triangles()[..m.triangles().len() - 32],
        )
        .unwrap();
        assert!(occluder_proxy(&open).is_none());
        // A coarse sphere has no more triangles than its proxy would.
        assert!(occluder_proxy(&sphere(4, 4)).is_none());
    }

    proptest! {
        /// The hull of random points, as a mesh, gets a proxy inside it.
        #[test]
        fn random_convex_meshes_get_proxies_inside(
            pts in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 40..80),
            offset in prop::array::uniform3(-1e4f32..1e4),
        ) {
            let o = Vec3::from(offset);
            let q: Vec<DVec3> = pts.iter().map(|a| Vec3::from(*a).as_dvec3()).collect();
            let Some(hull) = hull_of(&q, 2.0) else { return Ok(()) };
            let positions: Vec<Vec3> = pts.iter().map(|a| Vec3::from(*a) * 10.0 + o).collect();
            let triangles: Vec<[u32; 3]> = hull.iter().map(|t| t.map(|i| i as u32)).collect();
            let Ok(mesh) = Mesh::new("hull", &positions, &triangles) else { return Ok(()) };
            if mesh.solid() != Some(Solid::Outward) {
                // Overlapping coplanar faces (rare with random points).
                return Ok(());
            }
            if let Some(proxy) = occluder_proxy(&mesh) {
                prop_assert!(proxy.len() < mesh.triangles().len());
                assert_inside(&mesh, &proxy);
            }
        }
    }
}
