//! Visibility for shadowcull [Steiner §2.5.1, §4.3]: the view frustum and the
//! light-frustum intersection body [Steiner §4.3.3], and hierarchical occlusion
//! culling over the rasterizer's [`raster::OcclusionBackend`] — plain frustum
//! culling, exact stop-and-wait, and coherent hierarchical culling (CHC)
//! [Bittner et al. 2004; Steiner Listing 2.1].
//!
//! Depends on `scene` and `raster` only.

mod error;
mod hierarchy;
mod traverse;

pub use error::{Error, Result};
pub use hierarchy::{Hierarchy, NodeId};
pub use traverse::{CullResult, Culling, MeshData, TraversalStats, ViewCuller, ViewSetup};
