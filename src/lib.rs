//! # shadowcull
//!
//! CPU-side culling middleware for stencil shadow volumes in scenes with many
//! objects. This facade crate holds the batch-job configuration (RON), the
//! per-frame statistics, the exact ray-cast shadow reference every other
//! stage is measured against, the shadow pipeline (eye pass, volumes,
//! stencil, mask) and shadow-mask comparison and output.
//!
//! # Conventions
//! See `DESIGN.md` of the project: right-handed world, +y up, reversed Z with
//! an infinite far plane, pixel centres at +0.5, row 0 at the top; masks use
//! the four classes of [`mask::PixelClass`].
#![forbid(unsafe_code)]

pub mod compare;
pub mod config;
mod error;
pub mod frame;
pub mod hybrid;
pub mod mask;
pub mod pipeline;
pub mod reference;
pub mod run;
pub mod stats;

pub use error::{Error, Result};
pub use scene;
