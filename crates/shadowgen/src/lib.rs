//! # shadowcull-shadowgen
//!
//! Silhouettes, shadow-volume construction and per-caster method choice:
//! fills the [`raster::VolumeBuffer`] the stencil stage (or a GPU host) draws.
//!
//! # Conventions
//! - Right-handed world, column vectors; transforms named `dst_from_src`.
//! - Facing is the one rule [`scene::faces_light`] on f64 world positions from
//!   [`scene::Scene::world_triangle`]; a light in a triangle's plane does not face it.
//! - Volume positions stay in each caster's local space (the eye pass's own f32
//!   vertices, `w = 1`); extruded vertices are points at infinity, `w = 0`,
//!   or, with [`BuildOptions::finite_extrusion`] and a ranged light, finite
//!   points (`w = 1`) at a distance that covers the range.
//!   Clip space is reversed Z with an infinite far plane, reached through the
//!   one transform path `scene::transform::clip_from_local`.
//! - Winding: volume triangles are counter-clockwise seen from outside the
//!   volume in world space (\[EK\]), mirrored instances included; light caps keep
//!   the light-facing winding, dark caps are reversed.
//!
//! # What is here
//! - [`silhouette()`] and [`SilhouetteCache`]: signed edge counters [AW §2.4].
//! - `volume.rs`: sides, light and dark caps, `w = 0` extrusion [EK, Steiner §4.1],
//!   or finite extrusion for ranged lights.
//! - [`MethodChoice`], [`zpass_is_safe`]: near-plane/light pyramid test \[EK\].
//! - [`volume_bounds`], [`BoundsView`]: per-volume scissor and depth bounds
//!   [EK "Exploit Bounds"], from the swept box's vertices (`swept_vertices.rs`).
//! - [`SweepPrune`]: overlapping light-space boxes, kept across frames
//!   [Steiner §4.4.1], with [`sweep_pairs`] as its from-scratch baseline.
//! - [`LightClamp`]: continuous clamping for one light: sweep-and-prune on
//!   fixed image planes, then each caster's occupied intervals as a
//!   [`ClampPlan`] [Steiner §4.4.1].
//! - [`occupied_intervals`], [`GapCost`]: the depth intervals a caster's
//!   volume must cover [Steiner §4.4.1, Listing 4.2].
//! - [`ClampPlan`], [`SegmentAxis`], `segments.rs`: a caster's volume cut to
//!   its occupied intervals, one closed segment each [Steiner §4.4.3].
//! - [`EyeSlices`], [`LightClamp::plan_sliced`]: discrete clamping's
//!   slicing planes through the eye and each caster's occupied slices
//!   [Steiner §4.4.2].
//! - [`split_into_bands`]: each caster's ranges drawn only in the eye
//!   slices its receivers occupy (`bands.rs`).
//! - [`build_volumes`]: all of the above for one light, with [`VolumeStats`].
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod bands;
mod bounds;
mod build;
mod clamp;
mod clamp_intervals;
mod error;
mod method;
mod segments;
mod silhouette;
mod silhouette_cache;
mod slicing;
mod sweep_prune;
mod swept_vertices;
mod volume;

pub use bands::{split_into_bands, BAND_SLICES};
pub use bounds::{volume_bounds, BoundsView, VolumeBounds, BOUNDS_MARGIN};
pub use build::{build_clamped_volumes, build_volumes, BuildOptions, VolumeRequest, VolumeStats};
pub use clamp::{ClampInput, ClampStats, GapModel, LightClamp, ReceiverDepths};
pub use clamp_intervals::{occupied_intervals, GapArea, GapCost};
pub use error::{Error, Result};
pub use method::{choose_method, zpass_is_safe, MethodChoice, NearLightHull, ZPASS_MARGIN};
pub use segments::{ClampPlan, SegmentAxis, SEGMENT_MARGIN};
pub use silhouette::{silhouette, Silhouette, SilhouetteEdge};
pub use silhouette_cache::SilhouetteCache;
pub use slicing::EyeSlices;
pub use sweep_prune::{
    sweep_pairs, ImageRect, SapStats, SweepPrune, DEFAULT_SWAPS_PER_BOX, MAX_BOX_ID,
};
