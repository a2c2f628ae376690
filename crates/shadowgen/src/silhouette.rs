//! Silhouette extraction with signed edge counters [AW §2.3–2.4, Steiner §4.2, A.2].
//!
//! Every casting (light-facing) triangle adds the direction in which it
//! traverses each of its edges to that edge's counter: `+1` along the edge's
//! stored direction, `−1` against it. An edge then yields `|counter|` side quads
//! oriented by the counter's sign. The counters are the boundary of the chain of
//! casting triangles, so the result is right for closed, open and non-manifold
//! meshes and for mixed winding with no per-case code.
//!
//! Facing is the one rule, [`scene::faces_light`], on the f64 world positions
//! of the one transform path ([`scene::Scene::world_triangle`]); mirrored
//! instances are counted in world winding.

use scene::{faces_light, Light, ObjectId, Scene};

/// A silhouette edge: directed `from → to` the way the casting triangles
/// traverse it (world winding), used `multiplicity` times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SilhouetteEdge {
    /// Start vertex (index into the mesh's welded positions).
    pub from: u32,
    /// End vertex.
    pub to: u32,
    /// `|counter|` of the edge, ≥ 1.
    pub multiplicity: u32,
}

/// The silhouette of one caster for one light.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Silhouette {
    /// Edges with a non-zero counter, in mesh edge order.
    pub edges: Vec<SilhouetteEdge>,
    /// The casting triangles (the light cap) as mesh vertex indices, ordered so
    /// that in world space they are counter-clockwise seen from the light.
    pub caps: Vec<[u32; 3]>,
}

impl Silhouette {
    /// Silhouette edges counted with multiplicity.
    pub fn edge_count(&self) -> usize {
        self.edges.iter().map(|e| e.multiplicity as usize).sum()
    }
}

/// Computes the silhouette of object `id` for `light` into `out` (cleared first).
///
/// One-sided (`two_sided = false`): the triangles that face the light cast.
/// Two-sided: every triangle casts, back-facing ones flipped before counting (a
/// triangle with the light exactly in its plane casts in neither mode).
///
/// # Panics
/// If `id` is not an object of `scene`.
pub fn silhouette(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    out: &mut Silhouette,
) {
    let mirrored = scene.object(id).mirrored;
    silhouette_with(scene, id, light, two_sided, mirrored, out, &mut Vec::new());
}

/// [`silhouette`] (into `out`, cleared first) with the per-edge counters in
/// `counters` (reused): with `out`'s lists reserved at their bounds (the
/// mesh's triangle and edge counts), a recomputed entry allocates nothing.
pub(crate) fn silhouette_with(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    mirrored: bool,
    out: &mut Silhouette,
    counters: &mut Vec<i32>,
) {
    out.edges.clear();
    out.caps.clear();
    let mesh = scene.object_mesh(id);
    out.caps.reserve(mesh.triangles().len());
    out.edges.reserve(mesh.edges().len());
    counters.clear();
    counters.resize(mesh.edges().len(), 0);
    count(scene, id, light, two_sided, mirrored, counters, out);
}

/// The counting of [`silhouette`], with `counters` zeroed, one per mesh edge.
fn count(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    mirrored: bool,
    counters: &mut [i32],
    out: &mut Silhouette,
) {
    let mesh = scene.object_mesh(id);
    for (t, (tri, refs)) in mesh
        .triangles()
        .iter()
        .zip(mesh.triangle_edges())
        .enumerate()
    {
        let world = scene.world_triangle(id, t);
        let sign = if faces_light(&world, light) {
            1
        } else if two_sided && faces_light(&[world[0], world[2], world[1]], light) {
            -1
        } else {
            continue;
        };
        // World winding: flipped for mirrored objects, and again for flipped
        // back faces in two-sided mode.
        let flip = (sign < 0) != mirrored;
        let s = if flip { -1 } else { 1 };
        for r in refs {
            counters[r.index()] += s * r.sign();
        }
        out.caps
            .push(if flip { [tri[0], tri[2], tri[1]] } else { *tri });
    }
    for (edge, &c) in mesh.edges().iter().zip(counters.iter()) {
        if c != 0 {
            let [a, b] = edge.v;
            let (from, to) = if c > 0 { (a, b) } else { (b, a) };
            out.edges.push(SilhouetteEdge {
                from,
                to,
                multiplicity: c.unsigned_abs(),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat4, DVec3, Vec3};
    use scene::{Mesh, SceneGraph, Transform};

    fn scene_of(mesh: Mesh, t: Transform) -> Scene {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(mesh);
        g.add_instance("o", m, t);
        Scene::new(g).unwrap()
    }

    fn point(p: DVec3) -> Light {
        Light::Point {
            position: p,
            range: None,
        }
    }

    #[test]
    fn open_quad_facing_the_light_gives_its_boundary() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let m = Mesh::new("quad", &p, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        let s = scene_of(m, Transform::default());
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId::from_slot(0),
            &point(DVec3::new(0.5, 0.5, 3.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 2);
        assert_eq!(out.edge_count(), 4);
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 1), (1, 2), (2, 3), (3, 0)]);
        // Seen from below: nothing casts one-sided, the reversed loop two-sided.
        let below = point(DVec3::new(0.5, 0.5, -3.0));
        silhouette(&s, ObjectId::from_slot(0), &below, false, &mut out);
        assert!(out.edges.is_empty() && out.caps.is_empty());
        silhouette(&s, ObjectId::from_slot(0), &below, true, &mut out);
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 3), (1, 0), (2, 1), (3, 2)]);
    }

    #[test]
    fn non_manifold_fin() {
        // Three triangles on edge (0,1), all facing +z... two do, one is vertical.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
        ];
        // t0 = (0,1,2) and t1 = (1,0,3)·reversed... t1 = (0,3,1) faces +z too;
        // t2 = (0,1,4) is the fin (normal −y).
        let m = Mesh::new("fin", &p, &[[0, 1, 2], [0, 3, 1], [0, 1, 4]]).unwrap();
        let s = scene_of(m, Transform::default());
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId::from_slot(0),
            &point(DVec3::new(0.3, 0.1, 5.0)),
            false,
            &mut out,
        );
        // t0 and t1 cast and cancel on (0,1); the fin faces the light too (light at y > 0?
        // no: the fin's normal is −y and the light has y = 0.1 > 0), so it does not.
        assert_eq!(out.caps.len(), 2);
        assert!(out
            .edges
            .iter()
            .all(|e| (e.from.min(e.to), e.from.max(e.to)) != (0, 1)));
        assert_eq!(out.edge_count(), 4);
        // Light on the fin's front side: (0,1) is traversed by t0 (+), t1 (−), t2 (+).
        silhouette(
            &s,
            ObjectId::from_slot(0),
            &point(DVec3::new(0.3, -0.1, 5.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 3);
        let e01 = out
            .edges
            .iter()
            .find(|e| (e.from.min(e.to), e.from.max(e.to)) == (0, 1))
            .unwrap();
        assert_eq!((e01.from, e01.to, e01.multiplicity), (0, 1, 1));
    }

    #[test]
    fn mirrored_instance_counts_in_world_winding() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let m = Mesh::new("quad", &p, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        let s = scene_of(
            m,
            Transform::Matrix(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0))),
        );
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId::from_slot(0),
            &point(DVec3::new(-0.5, 0.5, 3.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 2);
        // The cap triangles are CCW seen from the light in world space.
        let o = s.object(ObjectId::from_slot(0));
        for c in &out.caps {
            let w = c.map(|i| {
                scene::transform::world_point(
                    &o.world_from_local,
                    s.object_mesh(ObjectId::from_slot(0)).positions()[i as usize],
                )
            });
            assert!((w[1] - w[0]).cross(w[2] - w[0]).z > 0.0);
        }
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 3), (1, 0), (2, 1), (3, 2)]);
    }
}
