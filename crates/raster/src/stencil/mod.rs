//! The stencil stage: shadow volumes counted on the eye depth buffer, brute
//! force ([`StencilTarget`], every fragment [Heidmann 1991; EK]) or
//! hierarchical ([`HierarchicalStencil`], whole tiles decided from their depth
//! bounds, per-pixel work only at boundary tiles [Aila04]).
//!
//! Files bottom-up: `counters` (storage and stats), `near_cap` and `pieces`
//! (volumes to set-up pieces), `span` and `run` (the per-row span walk and run
//! kernel), `tile_fill` (the same fill by 8×8 tiles), `fill` (pieces into a
//! band of counters, and the band runner),
//! `brute`, then `tile_class`, `open_edges` and `depth_ranges` (the
//! hierarchical pass's tile classification) and `hierarchical`.

mod brute;
mod counters;
mod depth_ranges;
mod fill;
mod hierarchical;
mod near_cap;
mod open_edges;
mod pieces;
mod run;
mod span;
mod tile_class;
mod tile_fill;

pub use brute::StencilTarget;
pub use counters::{StencilBits, StencilStats, StencilTests};
pub use hierarchical::{HierarchicalOptions, HierarchicalStencil, TileClass};
