//! The rasterizer's numeric limits and its derived error bound: the largest
//! target, the guard band that keeps snapped coordinates exact in i64, and ε_z.

/// Largest width or height of a target, in pixels.
pub const MAX_TARGET_SIZE: u32 = 16384;

/// Guard band: clipped vertices project to within this many pixels outside the target.
/// With [`MAX_TARGET_SIZE`] every snapped coordinate stays below 2¹⁵ pixels, so edge
/// functions stay below 2⁵⁰ and are exact in i64 and f64.
pub const GUARD_BAND_PX: f64 = 8192.0;

/// ε_z, the relative depth-error bound: `|z_raster − z| ≤ DEPTH_ERROR · z` for the
/// depth `z` of the plane through the snapped post-clip vertices at a covered pixel
/// centre (standard coverage).
///
/// Justification: depth is evaluated as `Σ E_i·z_i / area` in f64 with exact integer
/// edge values `E_i ≥ 0` inside the triangle and vertex depths `z_i = z/w ≥ 0`, so no
/// term cancels and the f64 result is within 5·2⁻⁵³ relative; rounding to f32 adds
/// 2⁻²⁴. 2⁻²³ bounds the sum with room to spare. (It does not include the rounding of
/// `clip_from_local` or of clipping, which happen before the "own vertices".)
pub const DEPTH_ERROR: f64 = 1.0 / 8388608.0;
