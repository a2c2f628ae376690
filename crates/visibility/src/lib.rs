//! Visibility for shadowcull [Steiner §2.5.1, §4.3]: the view frustum as a
//! convex polyhedron, the light-frustum intersection body B = conv(V ∪ l) ∩ S
//! and the light views fitted to it (orthographic, perspective or cube faces)
//! [Steiner §4.3.3, Listing 4.1], and hierarchical occlusion culling over the
//! rasterizer's [`raster::OcclusionBackend`] — plain frustum culling, exact
//! stop-and-wait, and coherent hierarchical culling (CHC) [Bittner et al.
//! 2004; Steiner Listing 2.1] and CHC++ [Mattausch, Bittner, Wimmer 2008].
//!
//! Depends on `scene` and `raster` only.
//!
//! # Conventions
//! - Right-handed world, +y up, column vectors; matrices named `dst_from_src`.
//!   World geometry (frusta, the intersection body, light positions) is f64;
//!   node boxes are the scene BVH's f32 bounds, rounded outward.
//! - Light views' `clip_from_world` (see `light_view.rs`): perspective views
//!   and cube faces are reversed Z with an infinite far plane (depth 1 at the
//!   near plane, 0 at infinity); orthographic views of directional lights map
//!   B's nearest point to depth 1 and its farthest to 0. Every point of the
//!   intersection body lies in some view's frustum or apex region
//!   ([`LightView::covers`]).
//! - Occlusion queries have the backend's GEQUAL semantics: a box counts the
//!   samples at or in front of the depth drawn so far. [`Sampling::Conservative`]
//!   with threshold 0 never culls an object that has a visible pixel (eye) or
//!   can shadow a visible receiver (light); [`Sampling::Point`] and a
//!   threshold above 0 are aggressive.
//! - Coherence follows job frame numbers, not calls
//!   ([`ViewCuller::set_frame`], [`LightPass::set_frame`]): a node's history
//!   carries over only from the frame numbered just before, and CHC++'s
//!   revisit phases are a function of (seed, object, frame).
//! - Node ids are the scene BVH's ([`BvhNodeId`]); per-node state survives
//!   refits and is remapped across rebuilds (`ViewCuller::remap`).
#![forbid(unsafe_code)]

mod back_faces;
mod chcpp;
mod culler;
mod error;
mod footprint;
mod fragment_depths;
mod hierarchy;
mod intersection_body;
mod light_pass;
mod light_view;
mod polyhedron;
mod receivers;
mod slice_occupancy;
mod traverse;
mod view_setup;
mod view_split;

pub use back_faces::eye_cull;
pub use chcpp::ChcppOptions;
pub use culler::{CullResult, Objects, TraversalStats, ViewCuller};
pub use error::{Error, Result};
pub use fragment_depths::{AxisFn, DepthAxis, FragmentDepths, FragmentSource};
pub use hierarchy::{BvhNodeId, Hierarchy};
pub use intersection_body::{intersection_body, Face, Polyhedron};
pub use light_pass::{
    BackendFactory, LightPass, LightPassOptions, LightPassResult, PassInput, ViewRole,
};
pub use light_view::{fit_light_views, LightView, LightViewKind, DEFAULT_LIGHT_VIEW_RESOLUTION};
pub use receivers::{ReceiverPoints, ReceiverPolygons, RECEIVER_PUSH};
pub use slice_occupancy::{SliceRatio, MAX_SLICES};
pub use traverse::Culling;
pub use view_setup::{ConvexOccluders, MeshData, Sampling, ViewSetup};
