//! The scene crate's integration tests, mostly its loaders: one test binary
//! (`cargo test -p shadowcull-scene --test main`), one module per area.
//!
//! Tests that need the shared corpus (`../shared/data` relative to the
//! workspace root) skip with a printed note when it is absent.

mod box_city;
#[cfg(feature = "gltf")]
mod gltf;
#[cfg(feature = "obj")]
mod obj;
mod procedural;
