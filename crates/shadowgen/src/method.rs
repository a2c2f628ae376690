//! Per-caster choice of the stencil counting method [EK "Zpass vs Zfail (4)",
//! Steiner §3.2.1].
//!
//! zpass is wrong exactly where a volume covers part of the near rectangle R.
//! A point r of R lies in a caster's volume only if the segment from r to the
//! light meets the caster, so the volume meets R iff the caster meets the
//! near-plane/light pyramid P = conv(l, R) (for a directional light the
//! semi-infinite prism R + t·(−d), t ≥ 0, reaching toward the light; for a
//! light behind the near plane the same hull, which then lies on the camera
//! side). Testing the caster's own world box against P is therefore exact up to
//! the box's looseness. The test is an exact separating-axis test in f64 between
//! the (widened) box and P; touching counts as meeting.
//!
//! Widening: the box grows on every side by
//! `ZPASS_MARGIN · DEPTH_ERROR · (|c − e| + |size|/2 + near)` (c the box centre,
//! e the eye, `raster::DEPTH_ERROR` the rasterizer's relative depth-error
//! bound), which covers the f32 rounding of `clip_from_local`, of the volume
//! vertices and of near clipping at the box's distance from the eye; it scales
//! with the scene, so no absolute epsilon is involved.
//!
//! `Auto` picks zpass when P misses the widened box, else zfail; zp+ is only
//! used when asked for (choosing it automatically is left for later).

use glam::DVec3;
use raster::{VolumeMethod, DEPTH_ERROR};
use scene::{Aabb, Camera, Light};

/// How [`crate::build_volumes`] picks each caster's method.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum MethodChoice {
    /// zpass where [`zpass_is_safe`], else zfail.
    ///
    /// zfail rather than zp+ where zpass is not safe: both draw the same closed
    /// volume, and zp+ adds near-plane fan triangles from the viewport centre
    /// to every near-clipped edge — including the dark caps' edges at clip
    /// w = 0 for extrusions pointing behind the eye — whose fragments cancel
    /// but cost work. Measured on city_16384 `street` at 1280×1024 with every
    /// caster forced (`shadow_bench --method zfail|zpplus`): 123 M against 234 M
    /// pixels processed, 2.1 s against 3.4 s of brute-force stencil.
    #[default]
    Auto,
    /// zpass everywhere (wrong where a volume meets the near rectangle; for comparison).
    ZPass,
    /// zfail everywhere.
    ZFail,
    /// zp+ everywhere.
    ZpPlus,
}

/// Multiple of `raster::DEPTH_ERROR · distance` the caster box is widened by.
pub const ZPASS_MARGIN: f64 = 64.0;

/// The method `choice` gives a caster with world bounds `bounds`.
///
/// Builds the pyramid for one caster; [`build_volumes`](crate::build_volumes)
/// uses [`NearLightHull`] once per light instead.
pub fn choose_method(
    choice: MethodChoice,
    camera: &Camera,
    light: &Light,
    bounds: &Aabb,
) -> VolumeMethod {
    NearLightHull::new(camera, light).choose(choice, bounds)
}

/// True when the caster box `bounds` (world space), widened as the module
/// states, misses the near-plane/light pyramid, so zpass counts its volume
/// correctly. An empty box is always safe.
pub fn zpass_is_safe(camera: &Camera, light: &Light, bounds: &Aabb) -> bool {
    NearLightHull::new(camera, light).zpass_is_safe(bounds)
}

/// Most separating axes of a hull: 3 box axes, 15 pair crosses of the 6 hull
/// edge directions, 18 box-axis crosses.
const MAX_AXES: usize = 36;

/// The near-plane/light pyramid conv(l, R) (or prism toward a directional
/// light) of one camera and light, prepared for many box tests: the candidate
/// separating axes and the hull's extent along each.
///
/// Candidate axes: the box axes, the cross products of all pairs of hull edge
/// directions (they include its face normals) and box axis × hull edge
/// direction; a superset of the needed axes keeps the test exact.
#[derive(Clone, Copy, Debug)]
pub struct NearLightHull {
    eye: DVec3,
    near: f64,
    axes: [(DVec3, f64, f64); MAX_AXES],
    count: usize,
}

impl NearLightHull {
    /// The hull of `camera`'s near rectangle and `light`.
    pub fn new(camera: &Camera, light: &Light) -> Self {
        let near = camera.frustum().near_corners;
        let mut dirs = [DVec3::ZERO; 6];
        dirs[0] = near[1] - near[0];
        dirs[1] = near[3] - near[0];
        let (apex, ray, ndirs) = match *light {
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                for (d, r) in dirs[2..].iter_mut().zip(near) {
                    *d = position - r;
                }
                (Some(position), None, 6)
            }
            Light::Directional { direction } => {
                dirs[2] = -direction;
                (None, Some(-direction), 3)
            }
        };
        let dirs = &dirs[..ndirs];
        let mut hull = NearLightHull {
            eye: camera.position,
            near: camera.near,
            axes: [(DVec3::ZERO, 0.0, 0.0); MAX_AXES],
            count: 0,
        };
        let mut add = |n: DVec3| {
            if n == DVec3::ZERO || !n.is_finite() {
                return;
            }
            let mut pmin = f64::INFINITY;
            let mut pmax = f64::NEG_INFINITY;
            for p in near.iter().copied().chain(apex) {
                let s = n.dot(p);
                pmin = pmin.min(s);
                pmax = pmax.max(s);
            }
            if let Some(u) = ray {
                let s = n.dot(u);
                if s > 0.0 {
                    pmax = f64::INFINITY;
                } else if s < 0.0 {
                    pmin = f64::NEG_INFINITY;
                }
            }
            hull.axes[hull.count] = (n, pmin, pmax);
            hull.count += 1;
        };
        for e in [DVec3::X, DVec3::Y, DVec3::Z] {
            add(e);
        }
        for (i, &a) in dirs.iter().enumerate() {
            for &b in &dirs[i + 1..] {
                add(a.cross(b));
            }
            for e in [DVec3::X, DVec3::Y, DVec3::Z] {
                add(e.cross(a));
            }
        }
        hull
    }

    /// See [`zpass_is_safe`].
    pub fn zpass_is_safe(&self, bounds: &Aabb) -> bool {
        if bounds.is_empty() {
            return true;
        }
        let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        let centre = (lo + hi) * 0.5;
        let half = (hi - lo) * 0.5;
        let margin =
            ZPASS_MARGIN * DEPTH_ERROR * ((centre - self.eye).length() + half.length() + self.near);
        let half = half + DVec3::splat(margin);
        // Separated along some axis ⇔ disjoint (touching counts as meeting).
        self.axes[..self.count].iter().any(|&(n, pmin, pmax)| {
            let c = n.dot(centre);
            let r = n.abs().dot(half);
            pmax < c - r || c + r < pmin
        })
    }

    /// See [`choose_method`].
    pub fn choose(&self, choice: MethodChoice, bounds: &Aabb) -> VolumeMethod {
        match choice {
            MethodChoice::ZPass => VolumeMethod::ZPass,
            MethodChoice::ZFail => VolumeMethod::ZFail,
            MethodChoice::ZpPlus => VolumeMethod::ZpPlus,
            MethodChoice::Auto => {
                if self.zpass_is_safe(bounds) {
                    VolumeMethod::ZPass
                } else {
                    VolumeMethod::ZFail
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn cam() -> Camera {
        Camera::look_at(DVec3::ZERO, DVec3::NEG_Z, DVec3::Y, 1.0, 1.0, 0.5).unwrap()
    }

    fn point(p: DVec3) -> Light {
        Light::Point {
            position: p,
            range: None,
        }
    }

    fn bx(lo: [f32; 3], hi: [f32; 3]) -> Aabb {
        Aabb::new(Vec3::from(lo), Vec3::from(hi))
    }

    #[test]
    fn caster_far_from_the_pyramid_is_zpass() {
        let l = point(DVec3::new(0.0, 10.0, -5.0));
        // Beside the pyramid.
        assert!(zpass_is_safe(
            &cam(),
            &l,
            &bx([5.0, 0.0, -6.0], [6.0, 1.0, -5.0])
        ));
        // Behind the light (far side from the camera).
        assert!(zpass_is_safe(
            &cam(),
            &l,
            &bx([-1.0, 11.0, -6.0], [1.0, 12.0, -4.0])
        ));
        // Between the light and the near plane.
        assert!(!zpass_is_safe(
            &cam(),
            &l,
            &bx([-0.5, 4.0, -3.0], [0.5, 5.0, -2.0])
        ));
    }

    #[test]
    fn camera_inside_a_volume_is_not_zpass() {
        // A caster between the eye and a light above it: the eye is in its shadow.
        let l = point(DVec3::new(0.0, 10.0, 0.0));
        let b = bx([-1.0, 4.0, -1.0], [1.0, 5.0, 1.0]);
        assert!(!zpass_is_safe(&cam(), &l, &b));
        assert_eq!(
            choose_method(MethodChoice::Auto, &cam(), &l, &b),
            VolumeMethod::ZFail
        );
        assert_eq!(
            choose_method(MethodChoice::ZPass, &cam(), &l, &b),
            VolumeMethod::ZPass
        );
    }

    #[test]
    fn light_on_the_near_plane() {
        // Near plane z = −0.5; light in it, off to the side.
        let l = point(DVec3::new(3.0, 0.0, -0.5));
        // A box touching the flat "pyramid" (the hull lies in the near plane).
        assert!(!zpass_is_safe(
            &cam(),
            &l,
            &bx([1.0, -0.1, -0.6], [1.2, 0.1, -0.4])
        ));
        // Just in front of the plane, not meeting it.
        assert!(zpass_is_safe(
            &cam(),
            &l,
            &bx([1.0, -0.1, -0.7], [1.2, 0.1, -0.6])
        ));
        // Light at a near-rectangle corner.
        let c = cam().frustum().near_corners[2];
        let l = point(c);
        assert!(!zpass_is_safe(
            &cam(),
            &l,
            &bx([-0.01, -0.01, -0.51], [0.01, 0.01, -0.49])
        ));
        assert!(zpass_is_safe(
            &cam(),
            &l,
            &bx([-0.01, -0.01, -3.0], [0.01, 0.01, -2.0])
        ));
    }

    #[test]
    fn light_behind_the_near_plane() {
        // Light behind the camera: the pyramid lies on the camera side.
        let l = point(DVec3::new(0.0, 0.0, 10.0));
        assert!(!zpass_is_safe(
            &cam(),
            &l,
            &bx([-0.1, -0.1, 4.0], [0.1, 0.1, 5.0])
        ));
        assert!(zpass_is_safe(
            &cam(),
            &l,
            &bx([-0.1, -0.1, -5.0], [0.1, 0.1, -4.0])
        ));
    }

    #[test]
    fn directional_light_prism() {
        // Sun shining straight down: the prism rises above the near rectangle.
        let sun = Light::Directional {
            direction: DVec3::NEG_Y,
        };
        assert!(!zpass_is_safe(
            &cam(),
            &sun,
            &bx([-0.1, 100.0, -0.6], [0.1, 101.0, -0.4])
        ));
        assert!(zpass_is_safe(
            &cam(),
            &sun,
            &bx([-0.1, -101.0, -0.6], [0.1, -100.0, -0.4])
        ));
        assert!(zpass_is_safe(
            &cam(),
            &sun,
            &bx([-0.1, 100.0, -5.6], [0.1, 101.0, -5.4])
        ));
        // Grazing: a sun perpendicular to the view direction, travelling along +x.
        let side = Light::Directional {
            direction: DVec3::X,
        };
        assert!(!zpass_is_safe(
            &cam(),
            &side,
            &bx([-50.0, -0.1, -0.6], [-49.0, 0.1, -0.4])
        ));
        assert!(zpass_is_safe(
            &cam(),
            &side,
            &bx([49.0, -0.1, -0.6], [50.0, 0.1, -0.4])
        ));
    }
}
