//! Helpers shared by the facade's integration-test binaries.

use scene::{Mesh, Scene, SceneGraph, Transform};

/// A scene of one root node with `root`'s transform drawing every mesh once.
pub fn scene_of(meshes: Vec<Mesh>, root: Transform) -> Scene {
    let mut g = SceneGraph::new();
    let ids: Vec<_> = meshes.into_iter().map(|m| g.add_mesh(m)).collect();
    g.add_root(scene::Node {
        name: "root".into(),
        transform: root,
        meshes: ids,
        children: vec![],
    });
    Scene::new(g).unwrap()
}
