//! OBJ loader (in progress).
use crate::{Error, Result, SceneGraph};
use std::path::Path;

/// Loads an `.obj` file.
///
/// # Errors
/// Not yet implemented.
pub fn load_obj(path: &Path) -> Result<SceneGraph> {
    Err(Error::Load { file: path.into(), element: "file".into(), message: "OBJ loading not built yet".into() })
}

/// Loads every `.obj` file of a directory, in name order.
///
/// # Errors
/// Not yet implemented.
pub fn load_obj_dir(path: &Path) -> Result<SceneGraph> {
    load_obj(path)
}
