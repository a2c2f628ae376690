//! The flattened scene: objects = (node, mesh) pairs with world transforms,
//! world bounds and an object BVH (obvhs) that is refit, not rebuilt, when
//! objects move.

use crate::{Aabb, Error, Mesh, MeshId, NodeId, Result, SceneGraph, Topology, Transform};
use glam::{DMat4, DVec3, Vec3A};
use obvhs::bvh2::Bvh2;

/// Deepest node nesting accepted when flattening (deeper is an error, not a stack overflow).
pub const MAX_NODE_DEPTH: usize = 4096;

/// Most objects a scene may flatten into (guards against exponential instancing).
pub const MAX_OBJECTS: usize = 1 << 24;

/// Identifies a scene object; every output names objects by it.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct ObjectId(pub u32);

impl From<ObjectId> for u32 {
    fn from(id: ObjectId) -> u32 {
        id.0
    }
}

/// One drawable instance: a mesh at a node.
#[derive(Clone, Debug)]
pub struct Object {
    /// The node that places it.
    pub node: NodeId,
    /// The mesh it draws.
    pub mesh: MeshId,
    /// Accumulated transform of the node path (f64).
    pub world_from_local: DMat4,
    /// True when `world_from_local` has a negative determinant; triangles are
    /// then reported with flipped winding so world-space facing stays right.
    pub mirrored: bool,
    /// World-space bounds (outward-rounded f32).
    pub world_bounds: Aabb,
}

/// A scene ready for culling: the graph, its objects, bounds and object BVH.
#[derive(Clone)]
pub struct Scene {
    graph: SceneGraph,
    objects: Vec<Object>,
    bounds: Aabb,
    bvh: Bvh2,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("objects", &self.objects.len())
            .field("meshes", &self.graph.meshes().len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

/// Counts over a whole scene, as `shadowcull inspect` prints them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SceneCounts {
    /// Objects (instances).
    pub objects: usize,
    /// Distinct meshes.
    pub meshes: usize,
    /// Triangles as loaded, summed over all instances: the file's own count,
    /// including the degenerate triangles that meshes drop.
    pub triangles: usize,
    /// Triangles kept and drawn (degenerate ones dropped), summed over all instances.
    pub drawn_triangles: usize,
    /// Welded vertices summed over all instances.
    pub vertices: usize,
    /// Topology counts summed over distinct meshes.
    pub topology: Topology,
}

impl Scene {
    /// Flattens `graph` into objects and builds the object BVH.
    ///
    /// # Errors
    /// [`Error::Graph`] on a node cycle, a dangling node or mesh index, a
    /// non-finite transform, nesting deeper than [`MAX_NODE_DEPTH`], or more
    /// than [`MAX_OBJECTS`] objects.
    pub fn new(graph: SceneGraph) -> Result<Scene> {
        let objects = flatten(&graph)?;
        let mut scene = Scene {
            graph,
            objects,
            bounds: Aabb::EMPTY,
            bvh: Bvh2::default(),
        };
        scene.bounds = scene.compute_bounds();
        scene.bvh = scene.build_bvh();
        Ok(scene)
    }

    fn compute_bounds(&self) -> Aabb {
        self.objects
            .iter()
            .fold(Aabb::EMPTY, |b, o| b.union(&o.world_bounds))
    }

    fn build_bvh(&self) -> Bvh2 {
        if self.objects.is_empty() {
            return Bvh2::default();
        }
        let boxes: Vec<obvhs::aabb::Aabb> = self
            .objects
            .iter()
            .map(|o| to_obvhs(&o.world_bounds))
            .collect();
        let mut params = obvhs::BvhBuildParams::medium_build();
        // One object per leaf: visibility traverses objects, and refit needs it.
        params.max_prims_per_leaf = 1;
        let mut bvh = obvhs::bvh2::builder::build_bvh2(&boxes, params, &mut Default::default());
        bvh.init_primitives_to_nodes_if_uninit();
        bvh
    }

    /// The graph the scene was built from.
    pub fn graph(&self) -> &SceneGraph {
        &self.graph
    }

    /// All objects, indexed by [`ObjectId`].
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// One object.
    ///
    /// # Panics
    /// If `id` is out of range (ids come from this scene).
    pub fn object(&self, id: ObjectId) -> &Object {
        &self.objects[id.0 as usize]
    }

    /// The mesh an object draws.
    pub fn object_mesh(&self, id: ObjectId) -> &Mesh {
        &self.graph.meshes()[self.object(id).mesh.0 as usize]
    }

    /// World bounds of all objects (the scene bounds S of [Steiner §4.3.3]).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The object BVH: leaf primitive `i` is `ObjectId(bvh.primitive_indices[i])`.
    pub fn object_bvh(&self) -> &Bvh2 {
        &self.bvh
    }

    /// Load warnings of the graph.
    pub fn warnings(&self) -> &[String] {
        self.graph.warnings()
    }

    /// Triangle `t` of object `id` in world space (f64, from the one transform
    /// path), counter-clockwise = front even for mirrored objects.
    pub fn world_triangle(&self, id: ObjectId, t: usize) -> [DVec3; 3] {
        let o = self.object(id);
        let mesh = &self.graph.meshes()[o.mesh.0 as usize];
        let [a, b, c] = mesh
            .triangle(t)
            .map(|p| crate::transform::world_point(&o.world_from_local, p));
        if o.mirrored {
            [a, c, b]
        } else {
            [a, b, c]
        }
    }

    /// Counts over the scene.
    pub fn counts(&self) -> SceneCounts {
        let mut c = SceneCounts {
            objects: self.objects.len(),
            meshes: self.graph.meshes().len(),
            ..Default::default()
        };
        for o in &self.objects {
            let m = &self.graph.meshes()[o.mesh.0 as usize];
            c.triangles += m.triangles().len() + m.topology().degenerate_triangles;
            c.drawn_triangles += m.triangles().len();
            c.vertices += m.positions().len();
        }
        for m in self.graph.meshes() {
            let t = m.topology();
            c.topology.boundary_edges += t.boundary_edges;
            c.topology.non_manifold_edges += t.non_manifold_edges;
            c.topology.inconsistent_edges += t.inconsistent_edges;
            c.topology.degenerate_triangles += t.degenerate_triangles;
        }
        c
    }

    /// Sets a node's local transform and updates every affected object's world
    /// transform and bounds; the BVH is refit, not rebuilt.
    ///
    /// # Errors
    /// [`Error::Graph`] when the node does not exist or the transform is not finite.
    pub fn set_node_transform(&mut self, node: NodeId, transform: Transform) -> Result<()> {
        check_transform(node, &transform)?;
        self.graph.node_mut(node)?.transform = transform;
        let objects = flatten(&self.graph)?;
        debug_assert_eq!(objects.len(), self.objects.len());
        self.objects = objects;
        self.refit();
        Ok(())
    }

    /// Sets one object's world transform directly (for hosts that animate
    /// objects themselves) and refits the BVH.
    ///
    /// # Errors
    /// [`Error::Graph`] naming the object's node when the matrix is not finite.
    pub fn set_object_transform(&mut self, id: ObjectId, world_from_local: DMat4) -> Result<()> {
        let o = self.objects.get(id.0 as usize).ok_or(Error::Graph {
            node: u32::MAX,
            message: format!("no object {}", id.0),
        })?;
        check_transform(o.node, &Transform::Matrix(world_from_local))?;
        let mesh_bounds = self.graph.meshes()[o.mesh.0 as usize].bounds();
        let o = &mut self.objects[id.0 as usize];
        o.world_from_local = world_from_local;
        o.mirrored = world_from_local.determinant() < 0.0;
        o.world_bounds = mesh_bounds.transformed(&world_from_local);
        self.refit();
        Ok(())
    }

    fn refit(&mut self) {
        self.bounds = self.compute_bounds();
        if self.objects.is_empty() {
            return;
        }
        for (prim, o) in self.objects.iter().enumerate() {
            let node = self.bvh.primitives_to_nodes[prim] as usize;
            self.bvh.nodes[node].set_aabb(to_obvhs(&o.world_bounds));
        }
        self.bvh.refit_all();
    }
}

fn to_obvhs(b: &Aabb) -> obvhs::aabb::Aabb {
    obvhs::aabb::Aabb::new(Vec3A::from(b.min), Vec3A::from(b.max))
}

fn check_transform(node: NodeId, t: &Transform) -> Result<()> {
    let finite = match t {
        Transform::Trs {
            translation,
            rotation,
            scale,
        } => translation.is_finite() && rotation.is_finite() && scale.is_finite(),
        Transform::Matrix(m) => m.is_finite(),
    };
    if finite {
        Ok(())
    } else {
        Err(Error::Graph {
            node: node.0,
            message: "transform is not finite".into(),
        })
    }
}

/// Walks the graph with an explicit stack (no recursion), detecting cycles and
/// limiting depth, and emits one object per (node, mesh) in depth-first order.
fn flatten(graph: &SceneGraph) -> Result<Vec<Object>> {
    let nodes = graph.nodes();
    let n_meshes = graph.meshes().len();
    let mut on_path = vec![false; nodes.len()];
    let mut path: Vec<NodeId> = Vec::new();
    let mut objects = Vec::new();
    // (node, depth, parent's world transform)
    let mut stack: Vec<(NodeId, usize, DMat4)> = graph
        .roots()
        .iter()
        .rev()
        .map(|&r| (r, 0, DMat4::IDENTITY))
        .collect();
    while let Some((id, depth, parent)) = stack.pop() {
        while path.len() > depth {
            let left = path.pop().expect("path is longer than depth");
            on_path[left.0 as usize] = false;
        }
        let node = nodes.get(id.0 as usize).ok_or(Error::Graph {
            node: id.0,
            message: format!("referenced, but the graph has only {} nodes", nodes.len()),
        })?;
        if on_path[id.0 as usize] {
            return Err(Error::Graph {
                node: id.0,
                message: "node cycle: the node is its own ancestor".into(),
            });
        }
        if depth >= MAX_NODE_DEPTH {
            return Err(Error::Graph {
                node: id.0,
                message: format!("nodes nested deeper than {MAX_NODE_DEPTH} levels"),
            });
        }
        check_transform(id, &node.transform)?;
        on_path[id.0 as usize] = true;
        path.push(id);
        let world = parent * node.transform.matrix();
        for &m in &node.meshes {
            let mesh = graph.meshes().get(m.0 as usize).ok_or(Error::Graph {
                node: id.0,
                message: format!("mesh {} referenced, but there are only {n_meshes}", m.0),
            })?;
            if objects.len() >= MAX_OBJECTS {
                return Err(Error::Graph {
                    node: id.0,
                    message: format!("more than {MAX_OBJECTS} objects"),
                });
            }
            objects.push(Object {
                node: id,
                mesh: m,
                world_from_local: world,
                mirrored: world.determinant() < 0.0,
                world_bounds: mesh.bounds().transformed(&world),
            });
        }
        for &c in node.children.iter().rev() {
            stack.push((c, depth + 1, world));
        }
    }
    Ok(objects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{faces_light, Light, Node};
    use glam::Vec3;

    fn tri_mesh() -> Mesh {
        Mesh::new("tri", &[Vec3::ZERO, Vec3::X, Vec3::NEG_Z], &[[0, 1, 2]]).unwrap()
    }

    #[test]
    fn instancing_and_hierarchy_accumulate() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh());
        let child = g.add_node(Node {
            name: "c".into(),
            transform: Transform::translation(DVec3::new(0.0, 1.0, 0.0)),
            meshes: vec![m],
            children: vec![],
        });
        g.add_root(Node {
            name: "p".into(),
            transform: Transform::translation(DVec3::new(10.0, 0.0, 0.0)),
            meshes: vec![m],
            children: vec![child],
        });
        let s = Scene::new(g).unwrap();
        assert_eq!(s.objects().len(), 2);
        assert_eq!(s.counts().triangles, 2);
        assert_eq!(s.counts().meshes, 1);
        assert_eq!(
            s.object(ObjectId(1)).world_bounds.min,
            Vec3::new(10.0, 1.0, -1.0)
        );
        assert_eq!(s.bounds().max, Vec3::new(11.0, 1.0, 0.0));
    }

    #[test]
    fn cycles_are_errors_not_hangs() {
        let mut g = SceneGraph::new();
        let a = g.add_root(Node::default());
        let b = g.add_node(Node {
            children: vec![a],
            ..Node::default()
        });
        g.node_mut(a).unwrap().children.push(b);
        let e = Scene::new(g).unwrap_err();
        assert!(e.to_string().contains("cycle"), "{e}");
    }

    #[test]
    fn deep_chains_are_errors_not_overflows() {
        let mut g = SceneGraph::new();
        let mut prev = g.add_root(Node::default());
        for _ in 0..200_000 {
            let n = g.add_node(Node::default());
            g.node_mut(prev).unwrap().children.push(n);
            prev = n;
        }
        assert!(Scene::new(g).is_err());
    }

    #[test]
    fn mirrored_instances_keep_world_facing() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh()); // CCW seen from +y
        g.add_instance(
            "mirror",
            m,
            Transform::Matrix(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0))),
        );
        let s = Scene::new(g).unwrap();
        assert!(s.object(ObjectId(0)).mirrored);
        let above = Light::Point {
            position: DVec3::new(-0.2, 3.0, -0.2),
            range: None,
        };
        // The mirror image of an upward-facing triangle still faces up.
        assert!(faces_light(&s.world_triangle(ObjectId(0), 0), &above));
    }

    #[test]
    fn moving_objects_refits_bounds_and_bvh() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh());
        let n0 = g.add_instance("a", m, Transform::default());
        g.add_instance("b", m, Transform::translation(DVec3::new(5.0, 0.0, 0.0)));
        let mut s = Scene::new(g).unwrap();
        s.set_node_transform(n0, Transform::translation(DVec3::new(0.0, 100.0, 0.0)))
            .unwrap();
        assert_eq!(s.bounds().max.y, 100.0);
        let root = s.object_bvh().nodes[0];
        assert_eq!(root.aabb().max.y, 100.0);
        s.set_object_transform(
            ObjectId(1),
            DMat4::from_translation(DVec3::new(0.0, -7.0, 0.0)),
        )
        .unwrap();
        assert_eq!(s.object_bvh().nodes[0].aabb().min.y, -7.0);
        assert!(s
            .set_node_transform(n0, Transform::translation(DVec3::NAN))
            .is_err());
    }
}
