//! Cameras: pose in f64, reversed-Z projection with an infinite far plane.

use crate::{Error, Frustum, Plane, Result};
use glam::{DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};

/// A pinhole camera.
///
/// Right-handed; the camera looks down its local −z with +y up. The projection
/// is reversed Z with an infinite far plane: depth = near / view distance, so
/// 1 at the near plane and 0 at infinity; clip w = view distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection in world space (f64: scenes may sit far from the origin).
    pub position: DVec3,
    /// Rotation from view space to world space (`world_from_view` without translation).
    pub orientation: DQuat,
    /// Vertical field of view in radians, in (0, π).
    pub fov_y: f64,
    /// Width / height of the viewport.
    pub aspect: f64,
    /// Distance of the near plane, > 0.
    pub near: f64,
    /// Off-centre shift of the projection in normalized device coordinates
    /// (x right, y up): the view axis lands at `shift` instead of the
    /// viewport centre. Zero for [`Camera::look_at`]; a host projection's
    /// off-centre or jitter terms ([`Camera::from_view_projection`]).
    pub shift: DVec2,
}

/// A camera placement independent of the viewport: where it stands and looks.
/// [`LookAt::camera`] turns it into a [`Camera`] once the aspect is known.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LookAt {
    /// Eye position.
    pub eye: DVec3,
    /// A point the camera looks at.
    pub target: DVec3,
    /// Approximate up direction.
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    /// Near-plane distance.
    pub near: f64,
}

impl LookAt {
    /// The camera for a viewport of the given aspect (width / height).
    ///
    /// # Errors
    /// [`Error::InvalidCamera`] naming the field when eye = target, up is
    /// parallel to the view direction, the fov is outside (0°, 180°), or near or
    /// aspect is not positive and finite.
    pub fn camera(&self, aspect: f64) -> Result<Camera> {
        Camera::look_at(
            self.eye,
            self.target,
            self.up,
            self.fov_y_deg.to_radians(),
            aspect,
            self.near,
        )
    }
}

fn cam_err(field: &'static str, message: &str) -> Error {
    Error::InvalidCamera {
        field,
        message: message.to_string(),
    }
}

impl Camera {
    /// A camera at `eye` looking at `target`.
    ///
    /// # Errors
    /// See [`LookAt::camera`].
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_y: f64,
        aspect: f64,
        near: f64,
    ) -> Result<Camera> {
        if !eye.is_finite() {
            return Err(cam_err("eye", "must be finite"));
        }
        if !target.is_finite() {
            return Err(cam_err("target", "must be finite"));
        }
        let forward = target - eye;
        if forward.length_squared() == 0.0 {
            return Err(cam_err("target", "must differ from the eye"));
        }
        if !forward.length_squared().is_finite() {
            return Err(cam_err(
                "eye",
                "is too far from the target (their distance overflows an f64): bring them nearer each other",
            ));
        }
        let f = forward.normalize();
        let side = f.cross(up);
        if !side.is_finite()
            || side.length() < 1e-12 * up.length().max(1e-300)
            || side.length() == 0.0
        {
            return Err(cam_err(
                "up",
                "must be finite and not parallel to the view direction",
            ));
        }
        let x = side.normalize();
        let y = x.cross(f);
        let rot = DMat3::from_cols(x, y, -f);
        let cam = Camera {
            position: eye,
            orientation: DQuat::from_mat3(&rot).normalize(),
            fov_y,
            aspect,
            near,
            shift: DVec2::ZERO,
        };
        cam.validate()?;
        Ok(cam)
    }

    /// Checks field of view, aspect and near.
    ///
    /// # Errors
    /// [`Error::InvalidCamera`] naming the bad field.
    pub fn validate(&self) -> Result<()> {
        if !self.position.is_finite() {
            return Err(cam_err("position", "must be finite"));
        }
        if !self.orientation.is_finite() || (self.orientation.length() - 1.0).abs() > 1e-6 {
            return Err(cam_err("orientation", "must be a unit quaternion"));
        }
        if !(self.fov_y > 0.0 && self.fov_y < std::f64::consts::PI) {
            return Err(cam_err("fov_y", "must lie strictly between 0° and 180°"));
        }
        if !(self.aspect > 0.0 && self.aspect.is_finite()) {
            return Err(cam_err("aspect", "must be positive and finite"));
        }
        if !(self.near > 0.0 && self.near.is_finite()) {
            return Err(cam_err("near", "must be positive and finite"));
        }
        if !self.shift.is_finite() {
            return Err(cam_err("shift", "must be finite"));
        }
        Ok(())
    }

    /// Unit view direction in world space.
    pub fn forward(&self) -> DVec3 {
        self.orientation * DVec3::NEG_Z
    }

    /// Rotation part of `view_from_world` (the translation is applied separately,
    /// eye-relative, by [`crate::transform::clip_from_local`]).
    pub fn view_rotation(&self) -> DMat4 {
        DMat4::from_quat(self.orientation.conjugate())
    }

    /// Reversed-Z projection with an infinite far plane (right-handed, view looks down −z):
    /// `clip = (x·f/aspect − shift.x·z, y·f − shift.y·z, near, −z_view)`, so
    /// depth = near / distance and a view-axis point lands at `shift` in NDC.
    pub fn projection(&self) -> DMat4 {
        let f = 1.0 / (0.5 * self.fov_y).tan();
        DMat4::from_cols(
            DVec4::new(f / self.aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, f, 0.0, 0.0),
            // `0 − shift`, not `−shift`: +0.0 (not −0.0) for a centred camera.
            DVec4::new(0.0 - self.shift.x, 0.0 - self.shift.y, 0.0, -1.0),
            DVec4::new(0.0, 0.0, self.near, 0.0),
        )
    }

    /// Projection times view rotation: maps eye-relative world points to clip space.
    pub fn clip_from_eye_relative(&self) -> DMat4 {
        self.projection() * self.view_rotation()
    }

    /// World-space unit direction of the ray through pixel centre `(px, py)`
    /// (pixel units, row 0 at the top) of a `width × height` viewport.
    pub fn ray_direction(&self, px: f64, py: f64, width: u32, height: u32) -> DVec3 {
        self.rays(width, height).direction(px, py)
    }

    /// [`Camera::ray_direction`] for many pixels of one viewport, with the
    /// per-viewport terms computed once (same results, bit for bit).
    pub fn rays(&self, width: u32, height: u32) -> Rays {
        Rays {
            orientation: self.orientation,
            tan_half_fov: (0.5 * self.fov_y).tan(),
            aspect: self.aspect,
            shift: self.shift,
            width: width as f64,
            height: height as f64,
        }
    }

    /// The view frustum (far end at infinity), planes with unit inside normals.
    pub fn frustum(&self) -> Frustum {
        self.frustum_part(DVec2::NEG_ONE, DVec2::ONE)
    }

    /// The frustum of the part of the view between NDC points `min` and
    /// `max` (each coordinate in `[-1, 1]`, +1 at the right and the top):
    /// [`Camera::frustum`] with its side planes through those bounds. For a
    /// traversal over one part of the view.
    pub fn frustum_part(&self, min: DVec2, max: DVec2) -> Frustum {
        let t = (0.5 * self.fov_y).tan();
        let (hx, hy) = (t * self.aspect, t);
        // NDC point (x, y) at view direction ((x − shift.x)·hx, (y − shift.y)·hy, −1).
        let (sx, sy) = (self.shift.x * hx, self.shift.y * hy);
        let (x0, x1, y0, y1) = (min.x * hx, max.x * hx, min.y * hy, max.y * hy);
        let view_dirs = [
            DVec3::new(x0 - sx, y0 - sy, -1.0),
            DVec3::new(x1 - sx, y0 - sy, -1.0),
            DVec3::new(x1 - sx, y1 - sy, -1.0),
            DVec3::new(x0 - sx, y1 - sy, -1.0),
        ];
        let dirs = view_dirs.map(|d| self.orientation * d);
        let near_corners = dirs.map(|d| self.position + d * self.near);
        let far_directions = dirs.map(|d| d.normalize());
        let e = self.position;
        // Side planes through the eye; CCW order seen from inside gives inside normals.
        let side = |a: DVec3, b: DVec3| Plane::from_point_normal(e, b.cross(a)).normalized();
        let fwd = self.forward();
        let planes = [
            side(dirs[3], dirs[0]), // left
            side(dirs[1], dirs[2]), // right
            side(dirs[0], dirs[1]), // bottom
            side(dirs[2], dirs[3]), // top
            Plane::from_point_normal(e + fwd * self.near, fwd),
        ];
        Frustum {
            planes,
            apex: e,
            near_corners,
            far_directions,
        }
    }
}

/// Eye-ray directions of one camera and viewport ([`Camera::rays`]).
#[derive(Clone, Copy, Debug)]
pub struct Rays {
    orientation: DQuat,
    tan_half_fov: f64,
    aspect: f64,
    shift: DVec2,
    width: f64,
    height: f64,
}

impl Rays {
    /// World-space unit direction through pixel position `(px, py)` (pixel
    /// units, row 0 at the top).
    #[inline]
    pub fn direction(&self, px: f64, py: f64) -> DVec3 {
        let ndc_x = 2.0 * px / self.width - 1.0 - self.shift.x;
        let ndc_y = 1.0 - 2.0 * py / self.height - self.shift.y;
        let t = self.tan_half_fov;
        let d = DVec3::new(ndc_x * t * self.aspect, ndc_y * t, -1.0);
        (self.orientation * d).normalize()
    }

    /// The world-space ray direction through `(px, py)`, not normalized,
    /// as `base + px · step` for the row `py`: `(base, step)`. Parallel to
    /// [`Rays::direction`]; for per-pixel loops that only need the ray's line
    /// (a ray–plane hit is independent of the direction's length).
    #[inline]
    pub fn row(&self, py: f64) -> (DVec3, DVec3) {
        let t = self.tan_half_fov;
        let ndc_y = 1.0 - 2.0 * py / self.height - self.shift.y;
        let base = DVec3::new((-1.0 - self.shift.x) * t * self.aspect, ndc_y * t, -1.0);
        let step = DVec3::new(2.0 * t * self.aspect / self.width, 0.0, 0.0);
        (self.orientation * base, self.orientation * step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A part of the view holds the points whose pixel lies in it, by a
    /// margin, and no point of a pixel beyond it; the whole view's part is
    /// the frustum.
    #[test]
    fn frustum_part_holds_the_rays_of_its_pixels() {
        let c = cam();
        let whole = c.frustum_part(DVec2::NEG_ONE, DVec2::ONE);
        assert_eq!(whole.planes, c.frustum().planes);
        let (w, h) = (64u32, 48u32);
        let rays = c.rays(w, h);
        // The left 24 columns and rows 10..30, in NDC.
        let (min, max) = (
            DVec2::new(-1.0, 1.0 - 60.0 / 48.0),
            DVec2::new(-0.25, 1.0 - 20.0 / 48.0),
        );
        let part = c.frustum_part(min, max);
        for py in 0..h {
            for px in 0..w {
                let p = c.position + rays.direction(f64::from(px) + 0.5, f64::from(py) + 0.5) * 7.0;
                let inside = part.planes.iter().all(|pl| pl.signed_distance(p) >= 0.0);
                assert_eq!(inside, px < 24 && (10..30).contains(&py), "({px}, {py})");
            }
        }
    }

    fn cam() -> Camera {
        Camera::look_at(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 2.0, -10.0),
            DVec3::Y,
            60f64.to_radians(),
            4.0 / 3.0,
            0.5,
        )
        .unwrap()
    }

    /// An eye so far away that the view distance overflows is blamed, not
    /// `up` (whose cross product only then turned non-finite).
    #[test]
    fn an_eye_at_1e300_names_the_eye() {
        let e = Camera::look_at(
            DVec3::new(1e300, 1e300, 0.0),
            DVec3::ZERO,
            DVec3::Y,
            1.0,
            1.0,
            0.1,
        )
        .unwrap_err();
        assert!(
            matches!(e, Error::InvalidCamera { field: "eye", .. }),
            "{e}"
        );
    }

    /// `Rays::row` spans the same rays as `Rays::direction`, pixel by pixel.
    #[test]
    fn ray_rows_are_parallel_to_directions() {
        let c = Camera::look_at(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(4.0, -1.0, -10.0),
            DVec3::Y,
            50f64.to_radians(),
            16.0 / 9.0,
            0.1,
        )
        .unwrap();
        let r = c.rays(64, 36);
        for y in 0..36 {
            let (base, step) = r.row(f64::from(y) + 0.5);
            for x in 0..64 {
                let d = r.direction(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let u = (base + step * (f64::from(x) + 0.5)).normalize();
                assert!((u - d).length() < 1e-14, "({x}, {y}): {u} vs {d}");
            }
        }
    }

    #[test]
    fn reversed_z_depth_is_one_at_near_zero_at_infinity() {
        let c = cam();
        let m = c.clip_from_eye_relative();
        let near = m * (c.forward() * c.near).extend(1.0);
        assert!((near.z / near.w - 1.0).abs() < 1e-12);
        let far = m * (c.forward() * 1e12).extend(1.0);
        assert!(far.z / far.w < 1e-12);
        let inf = m * c.forward().extend(0.0);
        assert_eq!(inf.z, 0.0);
        assert!(inf.w > 0.0);
    }

    #[test]
    fn frustum_contains_forward_points_only() {
        let f = cam().frustum();
        assert!(f.contains(DVec3::new(1.0, 2.0, -100.0)));
        assert!(!f.contains(DVec3::new(1.0, 2.0, 10.0)));
        assert!(
            !f.contains(DVec3::new(1.0, 2.0, 2.9)),
            "between eye and near plane"
        );
        assert!(!f.contains(DVec3::new(200.0, 2.0, -100.0)));
        for c in f.near_corners {
            for p in &f.planes {
                assert!(p.signed_distance(c) > -1e-9);
            }
        }
    }

    #[test]
    fn pixel_rays_hit_the_viewport_corners() {
        let c = cam();
        let d = c.ray_direction(0.0, 0.0, 800, 600); // top-left corner of the image
        let f = c.frustum();
        let expect = f.far_directions[3];
        assert!((d - expect).length() < 1e-12);
    }

    #[test]
    fn bad_cameras_name_their_field() {
        let e = Camera::look_at(DVec3::ZERO, DVec3::ZERO, DVec3::Y, 1.0, 1.0, 0.1);
        assert!(matches!(
            e,
            Err(Error::InvalidCamera {
                field: "target",
                ..
            })
        ));
        let e = Camera::look_at(DVec3::ZERO, DVec3::Y, DVec3::Y, 1.0, 1.0, 0.1);
        assert!(matches!(e, Err(Error::InvalidCamera { field: "up", .. })));
        let e = Camera::look_at(DVec3::ZERO, DVec3::X, DVec3::Y, 4.0, 1.0, 0.1);
        assert!(matches!(
            e,
            Err(Error::InvalidCamera { field: "fov_y", .. })
        ));
        let e = Camera::look_at(DVec3::ZERO, DVec3::X, DVec3::Y, 1.0, 1.0, 0.0);
        assert!(matches!(e, Err(Error::InvalidCamera { field: "near", .. })));
    }
}
