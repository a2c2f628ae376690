//! Scene loaders. Every loader reads the whole file itself, bounds every size
//! by the real byte length, and reports bad input as an [`Error`] naming the
//! file and the element or line — never a panic. Entry points that take bytes
//! exist for fuzzing.
//!
//! The glTF and OBJ loaders sit behind the default cargo features `gltf` and
//! `obj`; the box-city loader is always built.

pub mod box_city;
#[cfg(feature = "gltf")]
pub mod gltf;
#[cfg(feature = "obj")]
pub mod obj;
#[cfg(feature = "obj")]
mod triangulate;

use crate::{CameraPath, Error, Light, LookAt, Result, SceneGraph};
use std::path::{Path, PathBuf};

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

/// A mesh (or a cluster of meshes) whose centre lies farther than this many
/// of its radii from its local origin is recentred by the loaders (see
/// [`recentre`]): its f32 vertices then gain at least four bits.
pub const RECENTRE_RATIO: f64 = 16.0;

/// The translation that recentres geometry with f64 bounds `[min, max]`, or
/// `None` when it stays as written.
///
/// Why: files in world coordinates (city.obj holds buildings a few metres
/// wide near (2.6e5, 9.9e6), where an f32 has a spacing of 1) would give
/// meshes whose f32 local vertices lose the geometry, and whose
/// `clip_from_local`, though composed in f64, is applied in f32 to vertices
/// of 1e7. The centre is the midpoint of the bounds; the loader stores
/// `f32(p − centre)`, formed from the file's values in f64, and puts the
/// translation into the node's transform (f64), so world positions are the
/// file's up to the f32 rounding of the *small* local coordinates. Geometry
/// whose centre lies within [`RECENTRE_RATIO`] radii (radius = largest
/// half-extent) of the origin is not moved.
pub fn recentre(min: glam::DVec3, max: glam::DVec3) -> Option<glam::DVec3> {
    if !(min.is_finite() && max.is_finite()) {
        return None;
    }
    let centre = (min + max) * 0.5;
    let radius = ((max - min) * 0.5).max_element();
    (centre.abs().max_element() > RECENTRE_RATIO * radius).then_some(centre)
}

/// Reads a whole file, naming it in the error.
pub(crate) fn read_file(path: &Path, referenced_from: Option<&Path>) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        referenced_from: referenced_from.map(Path::to_path_buf),
        source,
    })
}

/// Loads any supported file by its extension: `.gltf`/`.glb` (glTF 2.0),
/// `.obj` (or a directory of `.obj` files, in name order), `.txt` with a
/// `citysc 1` header (box city).
///
/// # Errors
/// The loader's error, or [`Error::Load`] for an unknown extension or a
/// format whose cargo feature (`gltf`, `obj`) is disabled.
pub fn load_path(path: &Path) -> Result<Loaded> {
    if path.is_dir() {
        #[cfg(feature = "obj")]
        return obj::load_obj_dir(path).map(Loaded::from_graph);
        #[cfg(not(feature = "obj"))]
        return Err(feature_disabled(path, "a directory of .obj files", "obj"));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        #[cfg(feature = "gltf")]
        "gltf" | "glb" => gltf::load_gltf(path).map(Loaded::from_graph),
        #[cfg(not(feature = "gltf"))]
        "gltf" | "glb" => Err(feature_disabled(path, "glTF", "gltf")),
        #[cfg(feature = "obj")]
        "obj" => obj::load_obj(path).map(Loaded::from_graph),
        #[cfg(not(feature = "obj"))]
        "obj" => Err(feature_disabled(path, "OBJ", "obj")),
        "txt" | "citysc" => box_city::load_box_city(path),
        _ => Err(Error::Load {
            file: PathBuf::from(path),
            element: "file name".into(),
            message: format!(
                "unknown scene format `.{ext}` (expected .gltf, .glb, .obj, a directory of .obj, or a box-city .txt)"
            ),
        }),
    }
}

/// The error for a format whose loader was compiled out.
#[cfg(not(all(feature = "gltf", feature = "obj")))]
fn feature_disabled(path: &Path, format: &str, feature: &str) -> Error {
    Error::Load {
        file: PathBuf::from(path),
        element: "file name".into(),
        message: format!(
            "{format} support is disabled: build shadowcull-scene with the `{feature}` feature"
        ),
    }
}

#[cfg(test)]
mod tests {
    /// `load_path` on a format whose feature is off names the feature.
    #[cfg(not(all(feature = "gltf", feature = "obj")))]
    fn assert_disabled(file: &str, feature: &str) {
        match super::load_path(std::path::Path::new(file)) {
            Err(crate::Error::Load { message, .. }) => {
                assert!(
                    message.contains(&format!("`{feature}` feature")),
                    "{message}"
                )
            }
            other => panic!("{file}: expected a disabled-feature error, got {other:?}"),
        }
    }

    #[cfg(not(feature = "gltf"))]
    #[test]
    fn gltf_without_its_feature_is_an_error_naming_it() {
        assert_disabled("missing.gltf", "gltf");
        assert_disabled("missing.GLB", "gltf");
    }

    #[cfg(not(feature = "obj"))]
    #[test]
    fn obj_without_its_feature_is_an_error_naming_it() {
        assert_disabled("missing.obj", "obj");
        assert_disabled(env!("CARGO_MANIFEST_DIR"), "obj");
    }
}
