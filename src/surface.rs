//! Where a pixel's eye ray meets its visible triangle's plane: the one
//! function the light pass's receiver points, the mask classes, the hybrid's
//! classification and the reference all use, so they agree on every pixel
//! (DESIGN.md "Visible surface").

use glam::DVec3;

/// A world triangle's plane seen from a ray origin (the eye), in
/// origin-relative form so that a scene far from the world origin keeps its
/// precision: the ray `origin + t·dir` meets the plane at
/// `t = offset / normal·dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RayPlane {
    /// The unnormalized plane normal `(b − a) × (c − a)`.
    pub normal: DVec3,
    /// `normal · (a − origin)`.
    offset: f64,
}

impl RayPlane {
    /// The plane of `tri` (world, f64) for rays from `origin`.
    pub fn new(tri: &[DVec3; 3], origin: DVec3) -> Self {
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        RayPlane {
            normal,
            offset: normal.dot(tri[0] - origin),
        }
    }

    /// The ray parameter at which `origin + t·dir` meets the plane, `None`
    /// when the ray is parallel to it (or the triangle is degenerate).
    pub fn hit(&self, dir: DVec3) -> Option<f64> {
        let den = self.normal.dot(dir);
        (den != 0.0).then(|| self.offset / den)
    }

    /// The point where the ray meets the plane; the origin itself when the
    /// ray is parallel (the mask assembly's and the light pass's rule).
    pub fn point_or_origin(&self, origin: DVec3, dir: DVec3) -> DVec3 {
        origin + dir * self.hit(dir).unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_the_plane_and_reports_parallel_rays() {
        let tri = [
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 1.0),
        ];
        let o = DVec3::new(0.3, 5.0, 0.2);
        let p = RayPlane::new(&tri, o);
        let d = DVec3::new(0.1, -2.0, 0.05);
        let t = p.hit(d).unwrap();
        assert!(((o + d * t).y - 1.0).abs() < 1e-12);
        assert_eq!(p.hit(DVec3::X), None);
        assert_eq!(p.point_or_origin(o, DVec3::X), o);
    }
}
