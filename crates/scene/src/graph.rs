//! The scene graph as loaded or built in code: nodes with local transforms
//! and children, meshes shared between instances.

use crate::{Error, Mesh, MeshId, Result};
use glam::{DMat4, DQuat, DVec3};

/// Index of a node in a [`SceneGraph`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub struct NodeId(pub u32);

/// A node's transform relative to its parent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transform {
    /// Translation · rotation · scale (glTF's TRS order).
    Trs {
        /// Translation.
        translation: DVec3,
        /// Rotation (unit quaternion).
        rotation: DQuat,
        /// Non-uniform scale; a negative product mirrors.
        scale: DVec3,
    },
    /// A general affine matrix (column vectors).
    Matrix(DMat4),
}

impl Default for Transform {
    fn default() -> Self {
        Transform::Matrix(DMat4::IDENTITY)
    }
}

impl Transform {
    /// A pure translation.
    pub fn translation(t: DVec3) -> Self {
        Transform::Matrix(DMat4::from_translation(t))
    }

    /// The transform as a matrix.
    pub fn matrix(&self) -> DMat4 {
        match *self {
            Transform::Trs {
                translation,
                rotation,
                scale,
            } => DMat4::from_scale_rotation_translation(scale, rotation, translation),
            Transform::Matrix(m) => m,
        }
    }
}

/// A node of the graph.
#[derive(Clone, Debug, Default)]
pub struct Node {
    /// Name from the file (may be empty).
    pub name: String,
    /// Transform relative to the parent.
    pub transform: Transform,
    /// Meshes drawn at this node; each (node, mesh) pair becomes one object.
    pub meshes: Vec<MeshId>,
    /// Child nodes.
    pub children: Vec<NodeId>,
}

/// A scene graph: meshes, nodes, root nodes, and the warnings gathered while loading.
///
/// Nodes may be shared by several parents (instancing of whole subtrees); a
/// cycle is an error when the graph is flattened by [`crate::Scene::new`].
#[derive(Clone, Debug, Default)]
pub struct SceneGraph {
    meshes: Vec<Mesh>,
    nodes: Vec<Node>,
    roots: Vec<NodeId>,
    warnings: Vec<String>,
}

impl SceneGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a mesh; instances refer to it by the returned id.
    pub fn add_mesh(&mut self, mesh: Mesh) -> MeshId {
        self.meshes.push(mesh);
        MeshId::from_slot(self.meshes.len() as u32 - 1)
    }

    /// Replaces mesh `id` (the scene's mesh removal).
    pub(crate) fn replace_mesh(&mut self, id: MeshId, mesh: Mesh) {
        self.meshes[id.index()] = mesh;
    }

    /// Adds a node that is not yet attached to anything.
    pub fn add_node(&mut self, node: Node) -> NodeId {
        self.nodes.push(node);
        NodeId(self.nodes.len() as u32 - 1)
    }

    /// Adds a node and makes it a root.
    pub fn add_root(&mut self, node: Node) -> NodeId {
        let id = self.add_node(node);
        self.roots.push(id);
        id
    }

    /// Makes an existing node a root.
    pub fn push_root(&mut self, id: NodeId) {
        self.roots.push(id);
    }

    /// Convenience: one root node holding one mesh with a transform.
    pub fn add_instance(&mut self, name: &str, mesh: MeshId, transform: Transform) -> NodeId {
        self.add_root(Node {
            name: name.to_string(),
            transform,
            meshes: vec![mesh],
            children: Vec::new(),
        })
    }

    /// Records a load warning (something skipped or repaired).
    pub fn warn(&mut self, message: impl Into<String>) {
        self.warnings.push(message.into());
    }

    /// Appends all of `other` (its roots become roots here). Used to combine scenes.
    pub fn merge(&mut self, other: SceneGraph) {
        let mesh_base = self.meshes.len() as u32;
        let node_base = self.nodes.len() as u32;
        self.meshes.extend(other.meshes);
        self.nodes.extend(other.nodes.into_iter().map(|mut n| {
            for m in &mut n.meshes {
                *m = MeshId::from_slot(m.slot() + mesh_base);
            }
            for c in &mut n.children {
                c.0 += node_base;
            }
            n
        }));
        self.roots
            .extend(other.roots.into_iter().map(|r| NodeId(r.0 + node_base)));
        self.warnings.extend(other.warnings);
    }

    /// The meshes.
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Mutable access to a node (e.g. to set its transform before flattening).
    ///
    /// # Errors
    /// [`Error::Graph`] when `id` is out of range.
    pub fn node_mut(&mut self, id: NodeId) -> Result<&mut Node> {
        self.nodes.get_mut(id.0 as usize).ok_or(Error::Graph {
            node: id.0,
            message: "no such node".into(),
        })
    }

    /// The root nodes.
    pub fn roots(&self) -> &[NodeId] {
        &self.roots
    }

    /// Warnings gathered while loading.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }
}
