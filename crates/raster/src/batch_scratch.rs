//! The buffers of [`DepthTarget::draw_batch`]'s parallel path
//! (`draw.rs`), kept between batches so that a steady frame's batches
//! allocate nothing. A bundled backend lends a view's buffers to the target
//! while it holds it ([`crate::QueryBuffers`]), so they grow with that
//! view's batches.
//!
//! [`DepthTarget::draw_batch`]: crate::DepthTarget::draw_batch

use crate::hiz::Projected;
use crate::stats::RasterStats;

/// One band's output: its traversal counters, and per item set up there
/// its setup counters `(item, clipped, culled)`.
pub(crate) type BandOut = (RasterStats, Vec<(u32, u32, u32)>);

/// Buffers of a parallel batch.
#[derive(Clone, Debug, Default)]
#[cfg_attr(not(feature = "parallel"), allow(dead_code))]
pub(crate) struct BatchScratch {
    /// Per item: its screen bounds.
    pub projected: Vec<Projected>,
    /// Tile-row cuts of the bands.
    pub cuts: Vec<u32>,
    /// The band split's per-row work: differences and prefix sums.
    pub diff: Vec<i64>,
    pub prefix: Vec<u64>,
    /// Per band: its output (never shortened, so each keeps its buffer).
    pub bands: Vec<BandOut>,
    /// Per item: some band set it up.
    pub seen: Vec<bool>,
}
