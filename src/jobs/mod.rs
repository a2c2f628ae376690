//! Batch jobs (feature `jobs`): the layer above the library that turns a RON
//! job file into frames run through [`Pipeline`](crate::Pipeline), checked
//! against the reference, and written out as statistics and images. A
//! renderer that links the library needs none of it; the `shadowcull` CLI,
//! the Python package's `run_job` and the benchmark examples are built on it.
//!
//! A batch job flows through its parts in this order:
//! - [`config`]: the job file, its schema, validation (every bad value named
//!   by file and field, or line and column) and resolution into a scene, a
//!   camera path and lights;
//! - [`run`]: its frames and lights through [`frame::FrameRunner`] (one
//!   frame through the pipeline, with the reference check where the job asks
//!   for it), `stats.csv`, `summary.json` and the images written as it goes,
//!   into an output directory it holds ([`out_dir`]);
//! - [`shard`] and [`merge`], when one machine is not enough: the frames cut
//!   into blocks that run apart (`run --shard I/N`, with warm-up frames that
//!   rebuild the coherent history), then put back together as the single
//!   run's directory;
//! - [`compare`]: the job's pipeline variants on the same frames, time and
//!   pixels against mismatch, as a table and the speed/accuracy plot;
//!   [`calibrate`] measures the clamping cost model's weights for a job.

pub mod calibrate;
pub mod compare;
pub mod config;
pub mod frame;
pub mod merge;
pub mod out_dir;
pub mod run;
pub mod shard;
mod trade_plot;
