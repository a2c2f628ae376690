//! Plain counters of the rasterizer, per pass (the caller resets them with
//! [`crate::DepthTarget::take_stats`]).

/// Counters of one pass of drawing and querying on a [`crate::DepthTarget`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct RasterStats {
    /// Triangles submitted (draws and queries).
    pub triangles_in: u64,
    /// Triangles cut by a clip plane (near, far or guard band).
    pub triangles_clipped: u64,
    /// Triangles rejected before traversal: edge-on, zero snapped area, outside a
    /// clip plane, or covering no pixel of the target.
    pub triangles_culled: u64,
    /// Meshes (draws or box queries) skipped whole: off screen, or hidden by
    /// hierarchical z under their screen rectangle ([`crate::DepthTarget::draw`]).
    pub meshes_rejected_hiz: u64,
    /// Tiles visited by traversal. A draw skips, without visiting, the tile rows
    /// under its mesh's screen rectangle that are wholly nearer than the mesh when
    /// it starts (the same rows for any thread count).
    pub tiles_touched: u64,
    /// Tiles missed by the triangle, decided at the tile corners.
    pub tiles_rejected_edges: u64,
    /// Tiles wholly covered by the triangle (no per-pixel edge tests).
    pub tiles_accepted_whole: u64,
    /// Tiles rejected by hierarchical z (no per-pixel work).
    pub tiles_rejected_hiz: u64,
    /// Query tiles counted whole by hierarchical z (no per-pixel work).
    pub tiles_query_accepted_whole: u64,
    /// Covered pixels whose depth was tested.
    pub pixels_tested: u64,
    /// Pixels whose depth (and id) was written.
    pub pixels_written: u64,
    /// Occlusion queries executed.
    pub queries: u64,
    /// Queries answered "visible" by the apex-region test without rasterizing.
    pub queries_apex: u64,
}

impl RasterStats {
    /// Adds `o` to `self`, counter by counter.
    pub fn add(&mut self, o: &RasterStats) {
        self.triangles_in += o.triangles_in;
        self.triangles_clipped += o.triangles_clipped;
        self.triangles_culled += o.triangles_culled;
        self.meshes_rejected_hiz += o.meshes_rejected_hiz;
        self.tiles_touched += o.tiles_touched;
        self.tiles_rejected_edges += o.tiles_rejected_edges;
        self.tiles_accepted_whole += o.tiles_accepted_whole;
        self.tiles_rejected_hiz += o.tiles_rejected_hiz;
        self.tiles_query_accepted_whole += o.tiles_query_accepted_whole;
        self.pixels_tested += o.pixels_tested;
        self.pixels_written += o.pixels_written;
        self.queries += o.queries;
        self.queries_apex += o.queries_apex;
    }
}
