//! glTF 2.0 loader (in progress).
use crate::{Error, Result, SceneGraph};
use std::path::Path;

/// Loads a `.gltf` or `.glb` file.
///
/// # Errors
/// Not yet implemented.
pub fn load_gltf(path: &Path) -> Result<SceneGraph> {
    Err(Error::Load { file: path.into(), element: "file".into(), message: "glTF loading not built yet".into() })
}
