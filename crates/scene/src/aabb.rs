//! Axis-aligned bounding boxes in world or local space.

use glam::{DMat4, DVec3, Vec3};

/// An axis-aligned box, `min <= max` component-wise when non-empty.
///
/// f32, like everything handed to the rasterizer; boxes computed from f64 data
/// are rounded outward so they stay conservative.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box: `min = +inf`, `max = -inf`; the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// A box from two corners (taken component-wise min/max).
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Aabb {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box holding all `points` ([`Aabb::EMPTY`] for none).
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        let mut b = Aabb::EMPTY;
        for p in points {
            b.extend(p);
        }
        b
    }

    /// The smallest f32 box holding f64 `points`, rounded outward.
    pub fn from_dpoints(points: impl IntoIterator<Item = DVec3>) -> Self {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in points {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if lo.x > hi.x {
            return Aabb::EMPTY;
        }
        Aabb {
            min: round_down(lo),
            max: round_up(hi),
        }
    }

    /// True when the box holds no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Grows the box to hold `p`.
    pub fn extend(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The common part (may be empty).
    pub fn intersection(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.max(other.min),
            max: self.max.min(other.max),
        }
    }

    /// True when the closed boxes share a point.
    pub fn intersects(&self, other: &Aabb) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    /// True when the closed box holds `p`.
    pub fn contains(&self, p: Vec3) -> bool {
        self.min.cmple(p).all() && p.cmple(self.max).all()
    }

    /// Centre point, in f64 (exact for f32 corners).
    pub fn center(&self) -> DVec3 {
        (self.min.as_dvec3() + self.max.as_dvec3()) * 0.5
    }

    /// Edge lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// The eight corners, index bit 0 = x max, bit 1 = y max, bit 2 = z max.
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 != 0 { self.max.x } else { self.min.x },
                if i & 2 != 0 { self.max.y } else { self.min.y },
                if i & 4 != 0 { self.max.z } else { self.min.z },
            )
        })
    }

    /// The box of this box transformed by `m` (f64 affine), rounded outward.
    pub fn transformed(&self, m: &DMat4) -> Aabb {
        if self.is_empty() {
            return Aabb::EMPTY;
        }
        Aabb::from_dpoints(
            self.corners()
                .into_iter()
                .map(|c| m.transform_point3(c.as_dvec3())),
        )
    }
}

/// Largest f32 not above each component of `v`.
fn round_down(v: DVec3) -> Vec3 {
    let f = v.as_vec3();
    Vec3::new(
        step_down(f.x, v.x),
        step_down(f.y, v.y),
        step_down(f.z, v.z),
    )
}

/// Smallest f32 not below each component of `v`.
fn round_up(v: DVec3) -> Vec3 {
    let f = v.as_vec3();
    Vec3::new(step_up(f.x, v.x), step_up(f.y, v.y), step_up(f.z, v.z))
}

fn step_down(f: f32, exact: f64) -> f32 {
    if (f as f64) > exact {
        f.next_down()
    } else {
        f
    }
}

fn step_up(f: f32, exact: f64) -> f32 {
    if (f as f64) < exact {
        f.next_up()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outward_rounding_contains_exact_points() {
        let p = DVec3::new(1e6 + 0.1, -1e6 - 0.1, 0.3);
        let b = Aabb::from_dpoints([p]);
        assert!((b.min.x as f64) <= p.x && (b.max.x as f64) >= p.x);
        assert!((b.min.y as f64) <= p.y && (b.max.y as f64) >= p.y);
        assert!((b.min.z as f64) <= p.z && (b.max.z as f64) >= p.z);
        assert!(
            b.max.x > b.min.x,
            "1e6+0.1 is not an f32, so the box must widen"
        );
    }

    #[test]
    fn empty_is_union_identity() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(Aabb::EMPTY.union(&b), b);
        assert!(Aabb::EMPTY.is_empty());
        assert!(!b.intersects(&Aabb::new(Vec3::splat(1.5), Vec3::splat(2.0))));
        assert!(b.intersects(&Aabb::new(Vec3::splat(1.0), Vec3::splat(2.0))));
    }
}
