//! What a stencil stores and counts: counter widths ([`StencilBits`]), the
//! per-volume tests ([`StencilTests`]), the counters of a pass
//! ([`StencilStats`]) with their modelled bytes, and the tiled counter storage
//! both passes share.

/// Width of the stencil counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum StencilBits {
    /// 8-bit counters with wrapping arithmetic, like a GPU stencil buffer
    /// (a count of 256 aliases to 0). Spelled `bits8` (or `eight`) in serde.
    #[default]
    #[cfg_attr(feature = "serde", serde(rename = "bits8", alias = "eight"))]
    Eight,
    /// `i32` counters (wrapping too, but far out of reach): shows where 8 bits
    /// alias. Spelled `wide` in serde.
    Wide,
}

/// Per-volume tests [`StencilTarget::draw_volume`](crate::StencilTarget::draw_volume) applies before a fragment's
/// stencil operation [EK "Exploit Bounds"]; both off by default.
///
/// They are meant for bounds that are conservative — every pixel they reject has
/// its visible surface point outside the volume, so the volume's count there is 0
/// (zfail, zp+, and zpass where zpass is legal) — and then leave the stencil
/// unchanged and only save work. Bounds that are too tight change the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StencilTests {
    /// Scissor test: only pixels inside [`VolumeRange::scissor`](crate::VolumeRange::scissor) (`[x0, y0, x1, y1)`,
    /// row 0 at the top, clamped to the target; [`VolumeRange::FULL_SCISSOR`](crate::VolumeRange::FULL_SCISSOR) is
    /// unbounded) are rasterized; every triangle's pixel loop is shrunk to it, and a
    /// volume with an empty (or inverted) rectangle is not set up at all.
    pub scissor: bool,
    /// Depth-bounds test: a pixel whose stored eye depth `d` lies outside
    /// `[depth_far, depth_near]` (reversed Z, bounds inclusive) is skipped.
    pub depth_bounds: bool,
}

/// Counters of [`StencilTarget::draw_volume`](crate::StencilTarget::draw_volume).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StencilStats {
    /// Per-pixel stencil operations: fragments covered by a volume triangle (or a
    /// zp+ near-cap fan triangle) on non-background pixels that pass the enabled
    /// [`StencilTests`] — inside the scissor, and inside the depth bounds. Each is
    /// depth-tested. Fragments the tests reject are not counted.
    pub pixels_processed: u64,
    /// Tiles the fill scans for written depth inside the depth window: per
    /// band of tile rows a volume triangle crosses, the tiles its span
    /// there reaches (inside the scissor). Where the depth-bounds test
    /// rejects whole tiles, a long volume triangle costs these, not
    /// fragments.
    #[cfg_attr(feature = "serde", serde(default))]
    pub tiles_scanned: u64,
    /// Fragments that changed a stencil value (incremented or decremented).
    pub stencil_updates: u64,
    /// Volume triangles submitted (before clipping and culling; zp+ near-cap fan
    /// triangles are not counted).
    pub triangles: u64,
    /// Pixels this call updated for the first time since the target's last
    /// [`StencilTarget::clear`](crate::StencilTarget::clear) (or its creation). Summed over the calls on one
    /// target since a clear, it is [`StencilTarget::touched_pixels`](crate::StencilTarget::touched_pixels): the number of
    /// distinct pixels whose counter was incremented or decremented at least once
    /// (even if it came back to its old value).
    pub pixels_touched: u64,
    /// Hierarchical stencil only: volume fragments rasterized per pixel inside
    /// boundary tiles (covered, non-background, inside the enabled tests) — the
    /// brute-force count restricted to the boundary tiles. For the hierarchical
    /// stencil `pixels_processed` is instead tile area × boundary tiles, summed
    /// over volumes, as [Aila04 Table 1] counts it.
    pub h_fragments: u64,
    /// Hierarchical stencil only: stage-1 visits of a (volume triangle piece, tile) pair.
    pub tile_tests: u64,
    /// Hierarchical stencil only: tiles a volume reached and classified lit,
    /// summed over volumes.
    pub tiles_lit: u64,
    /// Tiles a volume classified wholly inside it (whole-tile update), summed over volumes.
    pub tiles_shadow: u64,
    /// Tiles a volume classified as boundary (per-pixel work), summed over volumes.
    pub tiles_boundary: u64,
    /// Modeled memory traffic of per-pixel buffers in bytes (depth reads,
    /// stencil reads and writes, the mask resolve's stencil reads); the model is
    /// stated in `hstencil.rs`.
    pub pixel_bytes: u64,
    /// Modeled memory traffic of per-tile buffers in bytes (tile depth bounds,
    /// the PSV records, Smin/Smax/offset and FS bits); 0 for brute force.
    pub tile_bytes: u64,
}

impl StencilStats {
    /// Adds `other` to `self`.
    pub fn add(&mut self, other: &StencilStats) {
        self.pixels_processed += other.pixels_processed;
        self.tiles_scanned += other.tiles_scanned;
        self.stencil_updates += other.stencil_updates;
        self.triangles += other.triangles;
        self.pixels_touched += other.pixels_touched;
        self.h_fragments += other.h_fragments;
        self.tile_tests += other.tile_tests;
        self.tiles_lit += other.tiles_lit;
        self.tiles_shadow += other.tiles_shadow;
        self.tiles_boundary += other.tiles_boundary;
        self.pixel_bytes += other.pixel_bytes;
        self.tile_bytes += other.tile_bytes;
    }

    /// Total modeled bandwidth: per-pixel plus per-tile bytes.
    pub fn bandwidth_bytes(&self) -> u64 {
        self.pixel_bytes + self.tile_bytes
    }
}

#[derive(Clone, Debug)]
pub(crate) enum Counters {
    Eight(Vec<u8>),
    Wide(Vec<i32>),
}

/// Mutable counters of one band.
pub(crate) enum CountersMut<'a> {
    Eight(&'a mut [u8]),
    Wide(&'a mut [i32]),
}

/// A stencil counter: adds with wrap-around.
pub(crate) trait Counter: Copy + Default {
    fn wrapping(self, delta: Self) -> Self;
}

impl Counter for u8 {
    #[inline(always)]
    fn wrapping(self, delta: u8) -> u8 {
        self.wrapping_add(delta)
    }
}

impl Counter for i32 {
    #[inline(always)]
    fn wrapping(self, delta: i32) -> i32 {
        self.wrapping_add(delta)
    }
}

/// Bytes of one stencil counter: 1 for 8 bits, 4 for wide counters.
pub(crate) fn counter_bytes(bits: StencilBits) -> u64 {
    match bits {
        StencilBits::Eight => 1,
        StencilBits::Wide => 4,
    }
}

/// Modeled per-pixel traffic of a stencil pass (see `hstencil.rs`): every processed
/// fragment reads its 4-byte depth and its counter, every update writes the counter.
pub(crate) fn pass_bytes(bits: StencilBits, processed: u64, updates: u64) -> u64 {
    let s = counter_bytes(bits);
    (4 + s) * processed + s * updates
}

/// Index of pixel `(x, y)` in a `width`-wide buffer stored in 8×8 tiles, tile
/// rows of 8 pixels contiguous: a volume triangle is mostly a thin sliver, and
/// with row-major storage every pixel row it covers would be another cache line.
#[inline(always)]
pub(crate) fn tiled_index(width: u32, x: u32, y: u32) -> usize {
    let tiles_x = width.div_ceil(8) as usize;
    (((y >> 3) as usize * tiles_x + (x >> 3) as usize) << 6) + (((y & 7) << 3) + (x & 7)) as usize
}
