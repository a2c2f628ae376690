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
///
/// The sign is computed from the triangle's lexicographically smallest
/// vertex, so it does not depend on which vertex a mesh lists first: a
/// triangle and its rotations get the same answer, and a triangle and its
/// reverse never both face the light, even where rounding decides (a light
/// nearly in the plane of a triangle whose coordinates differ by many orders
/// of magnitude). Otherwise a mesh holding one triangle twice, rotated,
/// could cast it once each way in two-sided mode, and its two volumes
/// cancel where the reference counts two blockers.
pub fn faces_light(tri: &[DVec3; 3], light: &Light) -> bool {
    let [a, b, c] = canonical(tri);
    let n = (b - a).cross(c - a);
    let s = match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => n.dot(position - a),
        Light::Directional { direction } => -n.dot(direction),
    };
    s > 0.0
}

/// `tri` rotated (an even permutation: the orientation is kept) to start
/// at its lexicographically smallest vertex.
fn canonical(tri: &[DVec3; 3]) -> [DVec3; 3] {
    let less = |p: DVec3, q: DVec3| p.to_array() < q.to_array();
    let [a, b, c] = *tri;
    if less(b, a) && !less(c, b) {
        [b, c, a]
    } else if less(c, a) && less(c, b) {
        [c, a, b]
    } else {
        [a, b, c]
    }
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

    /// Found by the `volumes` fuzz target: a vertex 10³⁸ times farther out
    /// than the others, a light nearly in the plane. Listed from its second
    /// vertex, the triangle used to face the light while listed from its
    /// first it did not, so a mesh holding both cast it once each way.
    #[test]
    fn rotations_agree_where_rounding_decides() {
        let t = [
            DVec3::new(-0.0003125, 0.0103125, 0.0),
            DVec3::new(-1.0800166385859862e-21, -0.0009375, -0.0015625),
            DVec3::new(-2.5646812848878285e36, -5.629624272932864e34, 0.01375),
        ];
        let l = Light::Point {
            position: DVec3::new(
                0.01317708094911116,
                -0.02354222934309911,
                -0.03934325169756619,
            ),
            range: None,
        };
        let f = faces_light(&t, &l);
        assert_eq!(faces_light(&[t[1], t[2], t[0]], &l), f);
        assert_eq!(faces_light(&[t[2], t[0], t[1]], &l), f);
        assert!(!(f && faces_light(&[t[0], t[2], t[1]], &l)));
    }

    proptest::proptest! {
        /// Any triangle (coordinates over 80 orders of magnitude) and light:
        /// its rotations agree, and it and its reverse never both face.
        #[test]
        fn rotations_agree_and_reverses_exclude(
            v in proptest::array::uniform3(proptest::array::uniform3(-1.0f64..1.0)),
            e in proptest::array::uniform3(-40i32..40),
            p in proptest::array::uniform3(-1.0f64..1.0),
            sun in proptest::bool::ANY,
        ) {
            let t = [0, 1, 2].map(|k| DVec3::from(v[k]) * 10f64.powi(e[k]));
            let l = if sun {
                Light::Directional { direction: DVec3::from(p) }
            } else {
                Light::Point { position: DVec3::from(p), range: None }
            };
            let f = faces_light(&t, &l);
            proptest::prop_assert_eq!(faces_light(&[t[1], t[2], t[0]], &l), f);
            proptest::prop_assert_eq!(faces_light(&[t[2], t[0], t[1]], &l), f);
            for r in [[t[0], t[2], t[1]], [t[2], t[1], t[0]], [t[1], t[0], t[2]]] {
                proptest::prop_assert!(!(f && faces_light(&r, &l)));
            }
        }
    }
}
