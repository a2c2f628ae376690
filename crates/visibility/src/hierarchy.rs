//! The object hierarchy the culling traversals walk: the scene's obvhs BVH
//! (one object per leaf), copied into a compact node array with parent links
//! [Steiner §2.5.1].
//!
//! Node indices are the BVH's own, so per-node traversal state kept by a view
//! stays valid when the scene refits the BVH after objects move (the topology
//! does not change); [`Hierarchy::refit`] copies the new bounds. A rebuilt
//! BVH gives a new hierarchy, and `ViewCuller::remap` carries each view's
//! state over to it through the objects of the leaves.

use glam::Vec3;
use scene::{ObjectId, Scene};

/// Index of a node of the BVH [`Hierarchy`] (not a scene-graph node,
/// [`scene::NodeId`]); the root is node 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BvhNodeId(pub u32);

/// No node (the root's parent, a leaf's children).
pub(crate) const NONE: u32 = u32::MAX;

/// One node: world bounds, children (inner) or object (leaf), parent.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub min: Vec3,
    pub max: Vec3,
    /// First child (the second is `first + 1`); [`NONE`] for a leaf.
    pub first: u32,
    /// The leaf's object; [`NONE`] for an inner node.
    pub object: u32,
    pub parent: u32,
}

impl Node {
    pub fn is_leaf(&self) -> bool {
        self.first == NONE
    }
}

/// The culling hierarchy over a scene's objects.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    pub(crate) nodes: Vec<Node>,
}

impl Hierarchy {
    /// The hierarchy of `scene`'s object BVH; empty for a scene without objects.
    pub fn from_scene(scene: &Scene) -> Self {
        let bvh = scene.object_bvh();
        if scene.objects().is_empty() || bvh.nodes.is_empty() {
            return Hierarchy::default();
        }
        let mut nodes: Vec<Node> = bvh
            .nodes
            .iter()
            .map(|n| {
                let leaf = n.prim_count > 0;
                Node {
                    min: n.aabb.min.into(),
                    max: n.aabb.max.into(),
                    first: if leaf { NONE } else { n.first_index },
                    object: if leaf {
                        bvh.primitive_indices[n.first_index as usize]
                    } else {
                        NONE
                    },
                    parent: NONE,
                }
            })
            .collect();
        for i in 0..nodes.len() {
            if !nodes[i].is_leaf() {
                let f = nodes[i].first as usize;
                nodes[f].parent = i as u32;
                nodes[f + 1].parent = i as u32;
            }
        }
        Hierarchy { nodes }
    }

    /// Copies the bounds of `scene`'s (refitted) BVH; the topology must be the
    /// one this hierarchy was built from.
    ///
    /// # Panics
    /// When the scene's BVH has another number of nodes.
    pub fn refit(&mut self, scene: &Scene) {
        let bvh = scene.object_bvh();
        assert_eq!(bvh.nodes.len(), self.nodes.len(), "BVH topology changed");
        for (n, b) in self.nodes.iter_mut().zip(&bvh.nodes) {
            n.min = b.aabb.min.into();
            n.max = b.aabb.max.into();
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True for a hierarchy without nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The object of a leaf node, `None` for an inner node.
    ///
    /// # Panics
    /// When `id` is out of range.
    pub fn object(&self, id: BvhNodeId) -> Option<ObjectId> {
        let n = &self.nodes[id.0 as usize];
        n.is_leaf().then_some(ObjectId::from_slot(n.object))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::procedural::city::{city, CityParams};

    /// Every object is in exactly one leaf, inside all its ancestors' bounds.
    #[test]
    fn leaves_hold_every_object_once_inside_their_ancestors() {
        let loaded = city(&CityParams {
            blocks_x: 3,
            blocks_z: 2,
            ..Default::default()
        })
        .unwrap();
        let scene = Scene::new(loaded.graph).unwrap();
        let h = Hierarchy::from_scene(&scene);
        let mut seen = vec![0u32; scene.objects().len()];
        for (i, n) in h.nodes.iter().enumerate() {
            if let Some(o) = h.object(BvhNodeId(i as u32)) {
                seen[o.index()] += 1;
                let b = scene.object(o).world_bounds;
                let mut p = i as u32;
                while p != NONE {
                    let a = &h.nodes[p as usize];
                    assert!(a.min.cmple(b.min).all() && a.max.cmpge(b.max).all());
                    p = a.parent;
                }
            } else {
                assert_eq!(h.nodes[n.first as usize].parent, i as u32);
            }
        }
        assert!(seen.iter().all(|&k| k == 1), "{seen:?}");
        assert_eq!(h.nodes[0].parent, NONE);
    }
}
