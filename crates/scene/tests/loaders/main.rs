//! Loader tests: one integration-test binary for the scene crate.
//!
//! Tests that need the shared corpus (`../shared/data` relative to the
//! workspace root) skip with a printed note when it is absent.

mod box_city;
#[cfg(feature = "gltf")]
mod gltf;
#[cfg(feature = "obj")]
mod obj;
mod procedural;

use std::path::PathBuf;

/// `../shared/data` relative to the workspace root, or `None` (with a note
/// printed) when it is absent, as in a user's clone.
pub fn shared_data() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if root.is_dir() {
        Some(root)
    } else {
        println!(
            "note: {} is absent; skipping a test that needs the shared corpus",
            root.display()
        );
        None
    }
}
