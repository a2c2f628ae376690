//! Which cube face around a light holds a direction: the hybrid's own cube
//! maps and the light pass's cube faces read as maps share the rule.

use glam::DVec3;

/// The face (0..6 = +X, −X, +Y, −Y, +Z, −Z, the GL cube-map order) of the
/// dominant axis of `r`, the direction from the light to a point; ties go
/// to the earlier axis.
pub(super) fn dominant_face(r: DVec3) -> usize {
    let a = r.abs();
    if a.x >= a.y && a.x >= a.z {
        usize::from(r.x < 0.0)
    } else if a.y >= a.z {
        2 + usize::from(r.y < 0.0)
    } else {
        4 + usize::from(r.z < 0.0)
    }
}
