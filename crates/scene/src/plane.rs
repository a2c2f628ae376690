//! Planes in f64 (plane fits and frustum planes need the precision).

use glam::DVec3;

/// The plane `normal · p + d = 0`; points with `normal · p + d > 0` are on its
/// positive ("inside") side. `normal` need not be unit length unless stated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Normal pointing to the inside.
    pub normal: DVec3,
    /// Offset: `-normal · p0` for a point `p0` on the plane.
    pub d: f64,
}

impl Plane {
    /// The plane through `point` with the given inside `normal`.
    pub fn from_point_normal(point: DVec3, normal: DVec3) -> Self {
        Plane {
            normal,
            d: -normal.dot(point),
        }
    }

    /// The plane through `a, b, c`; inside is where `(b − a) × (c − a)` points
    /// (counter-clockwise seen from the inside).
    pub fn from_points(a: DVec3, b: DVec3, c: DVec3) -> Self {
        Plane::from_point_normal(a, (b - a).cross(c - a))
    }

    /// Signed distance scaled by `|normal|` (the true distance when `normal` is unit).
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) + self.d
    }

    /// The same plane with a unit normal; unchanged if the normal is zero.
    pub fn normalized(&self) -> Self {
        let len = self.normal.length();
        if len > 0.0 {
            Plane {
                normal: self.normal / len,
                d: self.d / len,
            }
        } else {
            *self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ccw_points_face_their_normal() {
        let p = Plane::from_points(DVec3::ZERO, DVec3::X, DVec3::Y);
        assert!(p.signed_distance(DVec3::Z) > 0.0);
        assert!(p.signed_distance(-DVec3::Z) < 0.0);
        assert_eq!(
            p.normalized().signed_distance(DVec3::new(3.0, 4.0, 2.0)),
            2.0
        );
    }
}
