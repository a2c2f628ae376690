//! # Conventions
//!
//! - Clip space as produced by the scene crate's one transform path: right-handed
//!   world, column vectors, `clip = clip_from_local · p` in f32. Reversed Z with an
//!   infinite far plane: depth `z/w` is 1 at the near plane and 0 at infinity;
//!   points at infinity (`w = 0` in local space) are legal input.
//! - Clipping is homogeneous against the near plane (`z ≤ w`), the far plane
//!   (`z ≥ 0`) and guard-band planes [`GUARD_BAND_PX`] pixels outside the target
//!   (`w ≥ ε|x|`, `ε = 1 / (1 + 2·GUARD_BAND_PX/width)`, likewise y). Setup never
//!   divides by a clip w that can be 0.
//! - Screen: row 0 at the top, pixel centres at `+0.5`, vertices snapped to 1/256
//!   pixel, exact i64 edge functions, top-left fill rule: watertight.
//! - Facing: [`Facing::Front`] is counter-clockwise in NDC (y up), decided by the
//!   sign of `det[x y w]` of the clip-space vertices.
//! - Tiles of 8×8 pixels by default ([`TileSize`]: 4, 8, 16) with hierarchical z
//!   (zmin, zmax over written pixels; background pixels ignored).
//! - Depth tests named for reversed Z: draws write where GREATER (nearer wins; with
//!   the id target, equal depth and smaller `(object, triangle)` wins too), queries
//!   count GEQUAL samples.
//! - Depth error: an interpolated depth differs from the exact depth of the plane
//!   through the rasterizer's own snapped post-clip vertices by at most
//!   [`DEPTH_ERROR`] relative.
//! - Ids are plain `u32` pairs `(object, triangle)`; boxes are `(min, max)`.
//!
//! # What is here
//! - [`DepthTarget`]: depth (and optional primitive-id) target in tile-major layout
//!   with hierarchical z; [`DepthTarget::draw`] / [`DepthTarget::draw_batch`]
//!   (batches are binned into bands of tile rows of similar estimated work and
//!   rasterized in parallel with
//!   rayon on large targets — identical output), [`DepthTarget::query`] /
//!   [`DepthTarget::query_aabb`] / [`DepthTarget::query_aabbs`] (GEQUAL sample
//!   counts or any-samples, apex-region test, optional receiver restriction).
//! - [`Coverage`]: standard, outer- and inner-conservative with nearest/farthest depth.
//! - [`ReceiverTarget`]: receiver marking by points ([`RECEIVER_EPS_PX`]) or segments ([`SEGMENT_SLACK_PX`]).
//! - [`OcclusionBackend`]: the asynchronous seam, with [`SyncBackend`],
//!   [`SimulatedBackend`] ([`Latency::Commands`]) and [`ThreadedBackend`] (+ [`Gate`]).
//! - [`RasterStats`] / [`BackendStats`]: plain counters.
//! - `setup_triangle` / `facing` (feature `test-util`): the rasterizer's own
//!   setup (snapped post-clip polygon), for tests that check kernels against it.
//!
//! - [`CullMode`]: a draw may skip back (or front) faces ([`DrawItem::cull`],
//!   [`DrawCommand::cull`]), as a GPU does for closed occluders; queries never
//!   cull.
//!
//! Whole meshes (draws and box queries) whose projected rectangle lies under tiles
//! that are all strictly nearer than the mesh's nearest vertex are skipped before
//! setup. A mesh's vertices are transformed, clip-tested and snapped once each
//! (not once per triangle that uses them), with the values per-triangle setup
//! computes. The per-mesh pipeline (vertex stage, bounds, setup, traversal) is
//! compiled three times — portable, AVX2 and AVX-512 — and chosen at runtime
//! from the target's [`InstructionSet`] (the detected one unless capped with
//! [`DepthTarget::set_instruction_set`]); the results are bit-identical.

// Modules in layers, bottom-up: a module imports only from modules of its own
// layer or of layers above it, never in a cycle (`scripts/module_cycles.py
// --order` prints the exact order and CI checks it).
mod error;
mod isa;
mod limits;
mod stats;
// Geometry: clipping, snapped setup, edge functions, coverage rules.
mod clip;
mod coverage;
mod edge;
mod setup;
mod volume_buffer;
// Targets: the tile layout and hierarchical z, the depth and receiver targets.
mod band_extent;
mod batch_scratch;
mod closed_draw;
mod convex_draw;
mod depth_plane;
mod depth_target;
mod hiz;
mod layout;
mod polygon_marks;
mod prefetch;
mod receiver_target;
mod whole_draw;
// The tile walk, what is drawn, and the multiversioned per-mesh pipeline.
mod dispatch;
mod item;
mod query_options;
mod tile_walk;
// Draws and queries, and the asynchronous seam.
mod backend;
mod draw;
mod query;
// The stencil stage: brute force, then hierarchical.
mod stencil;

pub use backend::{
    trim_padding, BackendStats, DrawCommand, Gate, Latency, OcclusionBackend, QueryBuffers,
    QueryCommand, QueryId, ReadTarget, SimulatedBackend, SyncBackend, ThreadedBackend, Whole,
};
pub use band_extent::band_extent;
pub use coverage::{Coverage, DepthPick};
pub use depth_plane::DepthPlane;
pub use depth_target::{CullMode, DepthTarget, NO_ID};
pub use error::{Error, Result};
pub use isa::InstructionSet;
pub use item::{aabb_corners, DrawItem, AABB_TRIANGLES};
pub use layout::{TileSize, BACKGROUND};
pub use limits::{DEPTH_ERROR, GUARD_BAND_PX, MAX_TARGET_SIZE};
pub use polygon_marks::MAX_POLYGON_VERTICES;
pub use query_options::{meets_apex_region, QueryMode, QueryOptions, APEX_EPS, VISIBLE};
pub use receiver_target::{ReceiverTarget, TileMarks, RECEIVER_EPS_PX, SEGMENT_SLACK_PX};
pub use setup::Facing;
// The rasterizer's own setup, for tests that check the kernels against it.
#[cfg(feature = "test-util")]
pub use clip::MAX_CLIPPED_VERTICES;
#[cfg(feature = "test-util")]
pub use setup::{facing, setup_triangle, Setup, SnappedVertex, SUBPIXEL};
pub use stats::RasterStats;
pub use stencil::{
    HierarchicalOptions, HierarchicalStencil, StencilBits, StencilStats, StencilTarget,
    StencilTests, TileClass,
};
pub use volume_buffer::{VolumeBuffer, VolumeMethod, VolumeRange};
