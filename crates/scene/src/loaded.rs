//! What loading or generating a scene gives: the graph plus the named
//! cameras, camera paths and lights of its source. The loaders (`load`) and
//! the generators (`procedural`) both return it.

use crate::{CameraPath, Light, LookAt, SceneGraph};

/// What a loader returns: the graph plus the named cameras, camera paths and
/// lights the source defines (empty for plain meshes).
#[derive(Clone, Debug, Default)]
pub struct Loaded {
    /// Geometry and hierarchy (with load warnings).
    pub graph: SceneGraph,
    /// Named camera poses.
    pub cameras: Vec<(String, LookAt)>,
    /// Named camera paths.
    pub paths: Vec<(String, CameraPath)>,
    /// Named lights.
    pub lights: Vec<(String, Light)>,
}

impl Loaded {
    /// A source with geometry only.
    pub fn from_graph(graph: SceneGraph) -> Self {
        Loaded {
            graph,
            ..Default::default()
        }
    }

    /// Appends another source (geometry, cameras, paths, lights).
    pub fn merge(&mut self, other: Loaded) {
        self.graph.merge(other.graph);
        self.cameras.extend(other.cameras);
        self.paths.extend(other.paths);
        self.lights.extend(other.lights);
    }
}
