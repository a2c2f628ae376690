//! The one facing rule (DESIGN.md "Facing").

use crate::Light;
use glam::DVec3;

/// True when the triangle `(a, b, c)` (world space, f64, counter-clockwise =
/// front) faces `light`: the light lies strictly on the positive side of the
/// triangle's plane, the side `(b − a) × (c − a)` points to. A light exactly in
/// the plane means *not* facing; a degenerate triangle faces nothing.
///
/// Silhouettes, caps, light-view occluders, the reference and the mask classes
/// all call this with the same world positions (from
/// [`crate::transform::world_point`], winding already flipped for mirrored
/// objects by [`crate::Scene::world_triangle`]).
pub fn faces_light(tri: &[DVec3; 3], light: &Light) -> bool {
    let [a, b, c] = *tri;
    let n = (b - a).cross(c - a);
    let s = match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => n.dot(position - a),
        Light::Directional { direction } => -n.dot(direction),
    };
    s > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_sign_and_in_plane() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Z * -1.0]; // normal +y
        let above = Light::Point {
            position: DVec3::new(0.2, 5.0, -0.2),
            range: None,
        };
        let below = Light::Point {
            position: DVec3::new(0.2, -5.0, -0.2),
            range: None,
        };
        let inplane = Light::Point {
            position: DVec3::new(7.0, 0.0, 3.0),
            range: None,
        };
        assert!(faces_light(&t, &above));
        assert!(!faces_light(&t, &below));
        assert!(!faces_light(&t, &inplane));
        let sun = Light::Directional {
            direction: DVec3::new(0.3, -1.0, 0.0),
        };
        assert!(faces_light(&t, &sun));
        let grazing = Light::Directional {
            direction: DVec3::X,
        };
        assert!(!faces_light(&t, &grazing));
    }
}
