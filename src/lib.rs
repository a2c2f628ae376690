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
//! # The library
//! What a renderer links:
//! - [`pipeline`]: [`Pipeline`], its options, inputs and outputs, and the
//!   stages of a frame (eye pass, light passes, volumes, stencil);
//! - [`mod@reference`]: the exact ray-cast shadow reference every option is
//!   measured against;
//! - [`mask`]: the four-class masks and their comparison;
//! - [`stats`]: the per-frame statistics, also emitted as `tracing` events;
//! - [`hybrid`]: the shadow-map hybrid's classification;
//! - [`byte_size`]: byte counts as users write them (`512M`);
//! - and the crates it is built on, re-exported: [`scene`], [`raster`],
//!   [`visibility`], [`shadowgen`].
//!
//! # Batch jobs
//! With the `jobs` feature, [`jobs`] is the layer above the library: RON job
//! files run, sharded over machines, merged and compared (what the CLI
//! does). No library module uses it.
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
mod error;
pub mod hybrid;
pub mod mask;
pub mod pipeline;
pub mod reference;
pub mod stats;
mod surface;

#[cfg(feature = "jobs")]
pub mod jobs;

// The batch modules' paths before they moved under `jobs` (0.1), kept for
// one minor version.
#[cfg(feature = "jobs")]
#[doc(hidden)]
pub use jobs::{calibrate, compare, config, frame, merge, out_dir, run, shard};

pub use error::{Error, Result};
/// The glam and rayon this API uses (`DMat4`, `Vec3`, thread pools), so a
/// host names the same versions.
pub use glam;
pub use pipeline::gpu_check::GpuCheck;
pub use pipeline::memory;
pub use pipeline::{
    AutoSpec, ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec, FrameInput, FrameOutput,
    HostDepth, LightId, LightOutput, OccludersSpec, Pipeline, PipelineOptions, Preset,
    StencilBackend, StencilCosts, MAX_ASPECT_MISMATCH,
};
pub use raster;
pub use rayon;
pub use scene;
pub use shadowgen;
pub use stats::FrameStats;
pub use visibility;
