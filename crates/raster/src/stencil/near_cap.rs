//! zp+ near-plane initialization [EK "Zpass vs Zfail"; Steiner §3.2.1]: the
//! stencil count a zpass pass must start from at each pixel — the number of
//! volumes containing the pixel's point on the near plane — drawn as a fan of
//! triangles in the near plane.
//!
//! Construction (for one closed volume, wound counter-clockwise seen from
//! outside, see [`crate::VolumeBuffer`]):
//!
//! 1. Every volume triangle is clipped against the near plane `w − z ≥ 0`
//!    alone ([`crate::clip::near_segment`]). Where the plane cuts it, clipping
//!    creates one new edge, the segment `(a, b)` from where the triangle's
//!    boundary (in its winding order) leaves the kept side to where it comes
//!    back. The points come from the rasterizer's own clipper (same plane test,
//!    same canonical-order edge/plane intersection, and the near plane is the
//!    first plane it clips against), so they are bit-identical to the vertices
//!    of the near-clipped triangle the stencil pass rasterizes, and two
//!    triangles sharing an edge share the point on it: the segments of a
//!    closed volume form closed loops, the boundary of its near-plane
//!    cross-section. Endpoints may be points at infinity (`w = 0`, an
//!    extrusion parallel to the near plane).
//! 2. Each segment gives the fan triangle `(r, b, a)` with
//!    `r = (0, 0, 1, 1)`, the near-plane point at the viewport centre. Closing
//!    the clipped surface with the cross-section wound outward (its outward
//!    side faces the eye) traverses each segment against its triangle's
//!    winding, hence `(r, b, a)`: over the cross-section the fan's signed
//!    coverage (front-facing +1, back-facing −1) is its winding number, the
//!    number of volumes there; outside it is 0.
//! 3. Fan triangles are rasterized through the ordinary setup, clipped against
//!    the far and guard-band planes (not the near plane again, which would
//!    move their endpoints by rounding) — a far-away or `w = 0` endpoint is
//!    clipped exactly like the triangle it came from, and fan edges `(r, a)`
//!    shared by two fan triangles are clipped and snapped identically, so they
//!    cancel pixel for pixel. Each snapped fan sub-triangle counts +1 where it
//!    is front-facing (clockwise on screen, y down) and −1 where back-facing,
//!    judged from its snapped vertices, so the count at a pixel centre is the
//!    exact winding number of the snapped loops.
//! 4. Fan fragments lie at depth 1 (the near plane) and take the same strict
//!    zpass test as the volume's own triangles: they count where the near
//!    point is strictly in front of the stored surface. The volume triangles
//!    are counted with the zpass rule on the near-clipped surface.
//!
//! The result equals zfail pixel for pixel wherever the stored depth is below 1
//! (a surface at depth exactly 1 fails the fan's strict test): the clipped
//! surface and the fan form a closed surface whose snapped edges all match, so
//! their signed coverage cancels at every pixel centre, and each fragment is
//! counted by exactly one of the two rules (strictly nearer: zpass; else zfail).
//! It is defined for every light position and eye position, including the eye
//! inside volumes. Tested in `tests/stencil.rs` (`zp_plus_*`).

use crate::clip::near_segment;
use glam::DVec4;

/// The fan apex: the near-plane point at the viewport centre, in clip coordinates.
pub(crate) const APEX: DVec4 = DVec4::new(0.0, 0.0, 1.0, 1.0);

/// The near-cap fan triangle `(r, b, a)` of the volume triangle `tri` (f64 clip
/// coordinates, in its winding order), `None` when the near plane does not cut it.
/// Its vertices lie in the near plane; set it up with
/// [`crate::setup::setup_near_plane_into`] and count it by screen facing with the
/// zpass rule.
#[inline]
pub(crate) fn fan_triangle(tri: [DVec4; 3]) -> Option<[DVec4; 3]> {
    let (a, b) = near_segment(tri)?;
    Some([APEX, b, a])
}
