//! Visibility for shadowcull [Steiner §2.5.1, §4.3]: the view frustum as a
//! convex polyhedron, the light-frustum intersection body B = conv(V ∪ l) ∩ S
//! and the light views fitted to it (orthographic, perspective or cube faces)
//! [Steiner §4.3.3, Listing 4.1], and hierarchical occlusion culling over the
//! rasterizer's [`raster::OcclusionBackend`] — plain frustum culling, exact
//! stop-and-wait, and coherent hierarchical culling (CHC) [Bittner et al.
//! 2004; Steiner Listing 2.1] and CHC++ [Mattausch, Bittner, Wimmer 2008].
//!
//! Depends on `scene` and `raster` only.

mod chcpp;
mod error;
mod hierarchy;
mod intersection_body;
mod light_pass;
mod light_view;
mod polyhedron;
mod receivers;
mod traverse;

pub use chcpp::ChcppOptions;
pub use error::{Error, Result};
pub use hierarchy::{Hierarchy, NodeId};
pub use intersection_body::{intersection_body, Face, Polyhedron};
pub use light_pass::{BackendFactory, LightPass, LightPassOptions, LightPassResult, ViewRole};
pub use light_view::{
    fit_light_views, wasted_area, LightView, LightViewKind, DEFAULT_LIGHT_VIEW_RESOLUTION,
};
pub use receivers::{ReceiverPoints, PIECE_STEPS, RECEIVER_PUSH};
pub use traverse::{
    CullResult, Culling, MeshData, Sampling, TraversalStats, ViewCuller, ViewSetup,
};
