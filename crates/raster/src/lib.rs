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
//! - [`setup_triangle`] / [`facing`]: the rasterizer's own setup (snapped post-clip
//!   polygon), for references and the stencil stage.
//!
//! - [`CullMode`]: draws may skip back faces ([`DepthTarget::set_cull`]), as a GPU
//!   does for closed occluders; queries never cull.
//!
//! Whole meshes (draws and box queries) whose projected rectangle lies under tiles
//! that are all strictly nearer than the mesh's nearest vertex are skipped before
//! setup. The per-mesh pipeline (vertex stage, bounds, setup, traversal) is
//! compiled three times — portable, AVX2 and AVX-512 — and chosen at runtime;
//! the results are bit-identical (`SHADOWCULL_RASTER_SCALAR=1` forces portable,
//! `SHADOWCULL_RASTER_AVX2=1` caps at AVX2).

mod backend;
mod clip;
mod coverage;
mod depth_target;
mod dispatch;
mod draw;
mod edge;
mod error;
mod hiz;
mod hstencil;
mod near_cap;
mod open_edges;
mod prefetch;
mod query;
mod receivers;
mod setup;
mod span;
mod stats;
mod stencil;
mod stencil_run;
mod tile_class;
mod traverse;
mod volume_buffer;

pub use backend::{
    BackendStats, DrawCommand, Gate, Latency, OcclusionBackend, QueryBuffers, QueryCommand,
    QueryId, ReadTarget, SimulatedBackend, SyncBackend, ThreadedBackend,
};
pub use clip::MAX_CLIPPED_VERTICES;
pub use coverage::{Coverage, DepthPick};
pub use depth_target::{DepthTarget, TileSize, BACKGROUND, NO_ID};
pub use draw::{aabb_corners, CullMode, DrawItem, AABB_TRIANGLES};
pub use error::{Error, Result};
pub use hstencil::{HierarchicalOptions, HierarchicalStencil, TileClass};
pub use query::{meets_apex_region, QueryMode, QueryOptions, APEX_EPS, VISIBLE};
pub use receivers::{ReceiverTarget, RECEIVER_EPS_PX, SEGMENT_SLACK_PX};
pub use setup::{facing, setup_triangle, Facing, Setup, SnappedVertex, SUBPIXEL};
pub use stats::RasterStats;
pub use stencil::{StencilBits, StencilStats, StencilTarget, StencilTests};
pub use volume_buffer::{VolumeBuffer, VolumeMethod, VolumeRange};

/// Largest width or height of a target, in pixels.
pub const MAX_TARGET_SIZE: u32 = 16384;

/// Guard band: clipped vertices project to within this many pixels outside the target.
/// With [`MAX_TARGET_SIZE`] every snapped coordinate stays below 2¹⁵ pixels, so edge
/// functions stay below 2⁵⁰ and are exact in i64 and f64.
pub const GUARD_BAND_PX: f64 = 8192.0;

/// ε_z, the relative depth-error bound: `|z_raster − z| ≤ DEPTH_ERROR · z` for the
/// depth `z` of the plane through the snapped post-clip vertices at a covered pixel
/// centre (standard coverage).
///
/// Justification: depth is evaluated as `Σ E_i·z_i / area` in f64 with exact integer
/// edge values `E_i ≥ 0` inside the triangle and vertex depths `z_i = z/w ≥ 0`, so no
/// term cancels and the f64 result is within 5·2⁻⁵³ relative; rounding to f32 adds
/// 2⁻²⁴. 2⁻²³ bounds the sum with room to spare. (It does not include the rounding of
/// `clip_from_local` or of clipping, which happen before the "own vertices".)
pub const DEPTH_ERROR: f64 = 1.0 / 8388608.0;
