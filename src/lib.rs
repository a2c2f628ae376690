//! # shadowcull
//!
//! CPU-side culling middleware for stencil shadow volumes in scenes with many
//! objects. A host renderer builds a [`Pipeline`] from its [`scene::Scene`]
//! once and calls [`Pipeline::frame`] every frame: it gets the potentially
//! shadowed receivers (PSR), per light the potential shadow casters (PSC)
//! and the shadow volumes to draw, and — with a CPU stencil backend — the
//! exact shadow mask. See [`Pipeline`] for a complete example, and
//! `docs/host.md` of the repository for the host guide.
//!
//! Besides the pipeline the crate holds the exact ray-cast shadow reference
//! every option is measured against ([`mod@reference`]), the four-class masks
//! ([`mask`]), per-frame statistics ([`stats`]), and, with the `jobs`
//! feature, RON batch jobs ([`config`], [`run`], [`compare`]), split over
//! machines by [`shard`] and put back together by [`merge`].
//!
//! # Features
//! - `gltf`, `obj`: the scene loaders (passed to `shadowcull-scene`);
//! - `jobs`: RON jobs, `run` and `compare` (adds ron, serde_json, csv);
//! - `images`: PNG masks and the `compare` plot (adds png, plotters);
//! - `cli`: the `shadowcull` binary (adds clap, indicatif, anyhow,
//!   tracing-subscriber).
//!
//! All are on by default; a renderer that links the library alone uses
//! `default-features = false`.
//!
//! # Stability
//! The crate follows semantic versioning. Before 1.0 a minor version
//! (0.x → 0.x+1) may break the API; a patch version never does. Output
//! structs grow without breaking hosts: the statistics structs
//! ([`stats::FrameStats`], [`stats::ShadowStats`]) are `#[non_exhaustive]`,
//! and [`raster::VolumeRange`] only gains fields. The CSV columns, the JSON
//! keys of `summary.json` and of the examples, and the RON job schema
//! (`version: 1`) only gain entries within a major version.
//!
//! # Conventions
//! See `DESIGN.md` of the project: right-handed world, +y up, reversed Z with
//! an infinite far plane, pixel centres at +0.5, row 0 at the top; masks use
//! the four classes of [`mask::PixelClass`].
#![forbid(unsafe_code)]

pub mod byte_size;
#[cfg(feature = "jobs")]
pub mod calibrate;
#[cfg(feature = "jobs")]
pub mod compare;
#[cfg(feature = "jobs")]
pub mod config;
mod error;
#[cfg(feature = "jobs")]
pub mod frame;
pub mod hybrid;
pub mod mask;

#[cfg(feature = "jobs")]
pub mod merge;
#[cfg(feature = "jobs")]
pub mod out_dir;
pub mod pipeline;
pub mod reference;
#[cfg(feature = "jobs")]
pub mod run;
#[cfg(feature = "jobs")]
pub mod shard;
pub mod stats;
mod surface;
#[cfg(feature = "jobs")]
mod trade_plot;

pub use error::{Error, Result};
pub use pipeline::memory;
pub use pipeline::{
    AutoSpec, ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec, FrameInput, FrameOutput,
    LightId, LightOutput, Pipeline, PipelineOptions, StencilBackend, StencilCosts,
};
pub use raster;
pub use scene;
pub use shadowgen;
pub use stats::FrameStats;
pub use visibility;
