//! What the whole draws (`convex_draw.rs`, `closed_draw.rs`) share: their
//! buffers, kept in the target between draws, their margins and their
//! rounding.

use crate::depth_plane::DepthPlane;
use glam::DVec2;

/// Shrink of the hull, in pixels, before a pixel square must lie inside it:
/// covers the rounding of the projection and the snapping of vertices (to
/// 1/256 pixel) of a rasterizer drawing the same triangles at this
/// resolution or a finer one (the exact eye pass a coarse one stands for).
pub(crate) const HULL_MARGIN_PX: f64 = 1.0 / 256.0;

/// The part of a depth bound that covers snapping: how far a plane of
/// slopes `a`, `b` (per pixel) moves when its vertices move by
/// [`HULL_MARGIN_PX`].
#[inline(always)]
pub(crate) fn snap_slack(a: f64, b: f64) -> f64 {
    (a.abs() + b.abs()) * HULL_MARGIN_PX
}

/// Relative widening of the depth before rounding: the planes' evaluation
/// error (f64 fits of f32 projections, far below it) and the rounding to
/// f32 (2⁻²⁴ relative, to nearest).
const DEPTH_MARGIN: f64 = 1.0 / 2_097_152.0;

/// `z` widened by [`DEPTH_MARGIN`] and rounded to an f32 no nearer than
/// it: the widening exceeds the rounding's 2⁻²⁴. Depths too small for f32's
/// normal range (beyond 10⁻³⁰ of the near plane's 1) give 0: nothing.
#[inline(always)]
pub(crate) fn to_f32_below(z: f64) -> f32 {
    if z > 1e-30 {
        (z - DEPTH_MARGIN * z) as f32
    } else {
        0.0
    }
}

/// Buffers of convex draws, kept between draws (made with room for what
/// occluder proxies and boxes need, so that which target a light view gets
/// does not decide when they grow).
#[derive(Clone, Debug, Default)]
pub(crate) struct ConvexScratch {
    /// Projected vertices: pixel coordinates and depth.
    pub(crate) points: Vec<(f64, f64, f64)>,
    /// The hull, counter-clockwise in pixel coordinates (y down).
    pub(crate) hull: Vec<DVec2>,
    /// The projected points sorted, for the hull.
    pub(crate) sorted: Vec<DVec2>,
    /// Upper faces' depth planes.
    pub(crate) planes: Vec<DepthPlane>,
    /// Tiles written, to refresh: each once per draw (a tile's every pixel
    /// row writes to it, so without [`ConvexScratch::seen`] a large solid
    /// listed it up to eight times and outgrew the room).
    pub(crate) tiles: Vec<u32>,
    /// Per tile of the tile row being drawn, whether it is in `tiles` (bits).
    pub(crate) seen: Vec<u64>,
    /// Per upper face, `(a, base)` of the row being drawn.
    pub(crate) row: Vec<(f64, f64)>,
    /// The depths of one tile's part of a row.
    pub(crate) span: [f64; 16],
}

impl ConvexScratch {
    /// Room for a convex solid of up to 64 triangles on a target of
    /// `tiles` tiles (a proxy has at most 28; a box 12).
    pub(crate) fn with_room(tiles: usize) -> Self {
        const TRIANGLES: usize = 64;
        ConvexScratch {
            points: Vec::with_capacity(3 * TRIANGLES),
            hull: Vec::with_capacity(3 * TRIANGLES),
            sorted: Vec::with_capacity(3 * TRIANGLES),
            planes: Vec::with_capacity(TRIANGLES),
            tiles: Vec::with_capacity(tiles),
            seen: Vec::with_capacity(tiles.div_ceil(64)),
            row: Vec::with_capacity(TRIANGLES),
            span: [0.0; 16],
        }
    }
}

/// Buffers of closed draws, kept between draws.
#[derive(Clone, Debug, Default)]
pub(crate) struct ClosedScratch {
    /// Projected vertices by index (pixel coordinates, depth).
    pub(crate) points: Vec<(f64, f64, f64)>,
    /// Their clip points, for the faces' facing.
    pub(crate) clip: Vec<glam::DVec4>,
    /// Undirected edges `(low, high, front)` of every face, over welded
    /// vertices.
    pub(crate) edges: Vec<(u32, u32, bool)>,
    /// Per vertex, the first vertex at its position (faces of one closed
    /// mesh often repeat vertices: a box of quads with their own corners).
    pub(crate) weld: Vec<u32>,
    /// Vertices by position, to weld.
    pub(crate) order: Vec<([u32; 3], u32)>,
    /// Per pixel of the bounding rectangle: the farthest bound so far (+∞:
    /// no front face meets it), and whether a silhouette edge meets it.
    pub(crate) depth: Vec<f64>,
    pub(crate) edge: Vec<bool>,
    /// Tiles written, to refresh.
    pub(crate) touched: Vec<u32>,
}
