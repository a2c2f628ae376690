//! Box-city loader (in progress).
use super::Loaded;
use crate::{Error, Result};
use std::path::Path;

/// Loads a `citysc 1` box-city file.
///
/// # Errors
/// Not yet implemented.
pub fn load_box_city(path: &Path) -> Result<Loaded> {
    Err(Error::Load { file: path.into(), element: "file".into(), message: "box city not built yet".into() })
}
