//! Recentring of geometry far from its local origin, shared by the loaders.

/// A mesh (or a cluster of meshes) whose centre lies farther than this many
/// of its radii from its local origin is recentred by the loaders (see
/// [`recentre`]): its f32 vertices then gain at least four bits.
pub const RECENTRE_RATIO: f64 = 16.0;

/// The translation that recentres geometry with f64 bounds `[min, max]`, or
/// `None` when it stays as written.
///
/// Why: files in world coordinates (city.obj holds buildings a few metres
/// wide near (2.6e5, 9.9e6), where an f32 has a spacing of 1) would give
/// meshes whose f32 local vertices lose the geometry, and whose
/// `clip_from_local`, though composed in f64, is applied in f32 to vertices
/// of 1e7. The centre is the midpoint of the bounds; the loader stores
/// `f32(p − centre)`, formed from the file's values in f64, and puts the
/// translation into the node's transform (f64), so world positions are the
/// file's up to the f32 rounding of the *small* local coordinates. Geometry
/// whose centre lies within [`RECENTRE_RATIO`] radii (radius = largest
/// half-extent) of the origin is not moved.
pub fn recentre(min: glam::DVec3, max: glam::DVec3) -> Option<glam::DVec3> {
    if !(min.is_finite() && max.is_finite()) {
        return None;
    }
    let centre = (min + max) * 0.5;
    let radius = ((max - min) * 0.5).max_element();
    (centre.abs().max_element() > RECENTRE_RATIO * radius).then_some(centre)
}
