//! View frusta with the far end at infinity.

use crate::{Aabb, Plane};
use glam::DVec3;

/// A perspective view frustum with an infinite far plane, in world space (f64).
///
/// Inside is the positive side of every plane. The near rectangle's corners are
/// given in the order bottom-left, bottom-right, top-right, top-left (seen
/// from the eye); `far_directions` are the unit directions of the four side
/// edges (eye through each near corner), which run to infinity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Left, right, bottom, top, near; unit normals pointing inside.
    pub planes: [Plane; 5],
    /// The centre of projection.
    pub apex: DVec3,
    /// Near-plane rectangle corners: bottom-left, bottom-right, top-right, top-left.
    pub near_corners: [DVec3; 4],
    /// Unit directions of the side edges, same corner order.
    pub far_directions: [DVec3; 4],
}

impl Frustum {
    /// True when `p` lies inside or on every plane.
    pub fn contains(&self, p: DVec3) -> bool {
        self.planes.iter().all(|pl| pl.signed_distance(p) >= 0.0)
    }

    /// Conservative box test: false only when the box lies wholly outside
    /// one plane (may report true for some boxes that miss the frustum).
    pub fn may_intersect(&self, b: &Aabb) -> bool {
        if b.is_empty() {
            return false;
        }
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        self.planes.iter().all(|pl| {
            let n = pl.normal;
            let far = DVec3::new(
                if n.x >= 0.0 { hi.x } else { lo.x },
                if n.y >= 0.0 { hi.y } else { lo.y },
                if n.z >= 0.0 { hi.z } else { lo.z },
            );
            pl.signed_distance(far) >= 0.0
        })
    }
}
