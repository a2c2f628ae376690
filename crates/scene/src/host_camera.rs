//! Cameras from a host renderer's own view and projection matrices, and the
//! change of basis for hosts whose world is left-handed or z-up.
//!
//! A host hands its perspective projection as it draws with it: OpenGL's
//! `[−1, 1]` or Direct3D/Vulkan/Metal's `[0, 1]` clip depth, standard or
//! reversed, with a finite or an infinite far plane, off-centre or jittered.
//! x and y are taken from it exactly; depth is rebuilt as this crate's
//! reversed-Z infinite projection from the host's near plane (DESIGN.md
//! "Projection"), so method choice, rays and the light views do not depend on
//! the host's depth convention.

use crate::{Camera, Error, Result};
use glam::{DMat3, DMat4, DQuat, DVec2, DVec4, Mat4};

/// The clip-space depth range of a host's projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClipDepth {
    /// OpenGL: depth in `[−w, w]`.
    NegativeOneToOne,
    /// Direct3D, Vulkan, Metal, WebGPU: depth in `[0, w]`.
    ZeroToOne,
}

/// How a host's world axes relate to this crate's (right-handed, +y up).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HostBasis {
    /// The host's up axis is +z (Blender, Unreal, CAD) instead of +y.
    pub z_up: bool,
    /// The host's world and view are left-handed (Direct3D's, Unity's and
    /// Unreal's convention; the view then looks down +z).
    pub left_handed: bool,
}

/// Negates z: the map between a left-handed and a right-handed frame.
const FLIP_Z: DMat4 = DMat4::from_cols(DVec4::X, DVec4::Y, DVec4::NEG_Z, DVec4::W);

impl HostBasis {
    /// Maps host world coordinates to this crate's world: multiply a host
    /// object's world matrix by it (`world_from_local = world_from_host ·
    /// host_world_from_local`). A left-handed basis mirrors, which the scene
    /// turns into flipped winding, so the host's front faces stay front faces.
    pub fn world_from_host(&self) -> DMat4 {
        // z-up to y-up: host (x, y, z) is ours (x, z, −y).
        let up = if self.z_up {
            DMat4::from_cols(DVec4::X, DVec4::NEG_Z, DVec4::Y, DVec4::W)
        } else {
            DMat4::IDENTITY
        };
        let hand = if self.left_handed {
            FLIP_Z
        } else {
            DMat4::IDENTITY
        };
        // Up first, then the mirror of a horizontal axis (never the up axis).
        hand * up
    }

    /// The inverse of [`HostBasis::world_from_host`].
    pub fn host_from_world(&self) -> DMat4 {
        self.world_from_host().transpose()
    }

    /// A camera from the host's `view` (host world → host view) and
    /// `projection` (host view → clip) matrices: both converted into this
    /// crate's right-handed frame, then [`Camera::from_view_projection`].
    ///
    /// # Errors
    /// As [`Camera::from_view_projection`].
    pub fn camera(&self, view: DMat4, projection: DMat4, depth: ClipDepth) -> Result<Camera> {
        let (view, projection) = if self.left_handed {
            (FLIP_Z * view, projection * FLIP_Z)
        } else {
            (view, projection)
        };
        Camera::from_view_projection(view * self.host_from_world(), projection, depth)
    }
}

fn err(field: &'static str, message: impl Into<String>) -> Error {
    Error::InvalidCamera {
        field,
        message: message.into(),
    }
}

impl Camera {
    /// A camera from a host's right-handed `view` (world → view, looking down
    /// −z, rigid) and perspective `projection` (view → clip, column vectors)
    /// with clip depth `depth`. Off-centre and jittered projections keep
    /// their shift ([`Camera::shift`]); the near plane is read from the
    /// projection's depth rows, which may be standard or reversed, with a
    /// finite or an infinite far plane. Left-handed and z-up hosts convert with
    /// [`HostBasis::camera`].
    ///
    /// # Errors
    /// [`Error::InvalidCamera`] naming `view` when it is not finite or not a
    /// rotation plus translation, and `projection` when it is not finite, is
    /// orthographic or left-handed (its w row is not `(0, 0, −1, 0)`), has
    /// skew, flips y (`projection[1][1] ≤ 0`: pass a Vulkan projection
    /// unflipped), or has no positive near plane.
    pub fn from_view_projection(
        view: DMat4,
        projection: DMat4,
        depth: ClipDepth,
    ) -> Result<Camera> {
        if !view.is_finite() {
            return Err(err("view", "must be finite"));
        }
        if !projection.is_finite() {
            return Err(err("projection", "must be finite"));
        }
        let p = projection;
        let w_row = p.row(3);
        let scale = p.x_axis.x.abs().max(p.y_axis.y.abs()).max(1.0);
        let tol = 1e-9 * scale;
        if w_row.w.abs() > tol || (w_row.z + 1.0).abs() > 1e-9 {
            let kind = if w_row.w.abs() > tol {
                "orthographic projections are not supported (a perspective one has w row (0, 0, −1, 0))"
            } else if (w_row.z - 1.0).abs() <= 1e-9 {
                "is left-handed (w = +z): convert with HostBasis { left_handed: true, .. }"
            } else {
                "must be a perspective projection with w row (0, 0, −1, 0)"
            };
            return Err(err("projection", kind));
        }
        if w_row.x.abs() > tol || w_row.y.abs() > tol {
            return Err(err("projection", "must have w row (0, 0, −1, 0)"));
        }
        if p.y_axis.x.abs() > tol || p.x_axis.y.abs() > tol {
            return Err(err("projection", "has skew (x depends on y or y on x)"));
        }
        let (sx, sy) = (p.x_axis.x, p.y_axis.y);
        if !(sx > 0.0 && sy > 0.0) {
            return Err(err(
                "projection",
                "must map view +x to clip +x and view +y to clip +y (pass a y-flipped Vulkan projection unflipped)",
            ));
        }
        // Depth: clip z = a·z_view + b (w_view = 1), NDC depth −a + b / d at view
        // distance d; standard depth grows with d (b < 0), reversed falls (b > 0).
        let (a, b) = (p.z_axis.z, p.w_axis.z);
        let at_near = if b > 0.0 {
            1.0
        } else {
            match depth {
                ClipDepth::NegativeOneToOne => -1.0,
                ClipDepth::ZeroToOne => 0.0,
            }
        };
        let near = b / (at_near + a);
        if !(near > 0.0 && near.is_finite()) {
            return Err(err(
                "projection",
                format!("has no positive near plane (depth row a = {a}, b = {b}, {depth:?})"),
            ));
        }
        // The view: rotation rows orthonormal, right-handed.
        let r = DMat3::from_mat4(view);
        let gram = r * r.transpose();
        if !gram.abs_diff_eq(DMat3::IDENTITY, 1e-6) || r.determinant() <= 0.0 {
            return Err(err(
                "view",
                "must be a right-handed rotation plus translation (no scale, shear or mirror)",
            ));
        }
        if (view.row(3) - DVec4::W).abs().max_element() > 1e-12 {
            return Err(err("view", "must have bottom row (0, 0, 0, 1)"));
        }
        let world_from_view = view.inverse();
        let orientation = DQuat::from_mat3(&DMat3::from_mat4(world_from_view)).normalize();
        let cam = Camera {
            position: world_from_view.w_axis.truncate(),
            orientation,
            fov_y: 2.0 * (1.0 / sy).atan(),
            aspect: sy / sx,
            near,
            shift: DVec2::new(-p.z_axis.x, -p.z_axis.y),
        };
        cam.validate()?;
        Ok(cam)
    }

    /// [`Camera::from_view_projection`], checked against the near plane the
    /// host built `projection` with: a wrong [`ClipDepth`] cannot be seen in
    /// the matrix alone (an OpenGL matrix read as zero-to-one is a valid
    /// projection whose near plane is about half the host's; a Direct3D one
    /// read as OpenGL, about twice), so the near plane it implies under
    /// `depth` must equal `near` within 10⁻⁶ relative.
    ///
    /// # Errors
    /// As [`Camera::from_view_projection`]; [`Error::InvalidCamera`] naming
    /// `near` when it is not positive and finite, or when the projection's
    /// near plane under `depth` differs from it (naming both and the likely
    /// convention mix-up).
    pub fn from_view_projection_near(
        view: DMat4,
        projection: DMat4,
        depth: ClipDepth,
        near: f64,
    ) -> Result<Camera> {
        if !(near > 0.0 && near.is_finite()) {
            return Err(err(
                "near",
                format!("must be positive and finite, got {near}"),
            ));
        }
        let cam = Camera::from_view_projection(view, projection, depth)?;
        if ((cam.near - near) / near).abs() > 1e-6 {
            let other = match depth {
                ClipDepth::NegativeOneToOne => ClipDepth::ZeroToOne,
                ClipDepth::ZeroToOne => ClipDepth::NegativeOneToOne,
            };
            let hint = match Camera::from_view_projection(view, projection, other) {
                Ok(c) if ((c.near - near) / near).abs() <= 1e-6 => {
                    format!(": the projection is {other:?}, not {depth:?}")
                }
                _ => String::new(),
            };
            return Err(err(
                "near",
                format!(
                    "the projection's near plane under {depth:?} is {}, not the host's {near}{hint}",
                    cam.near
                ),
            ));
        }
        Ok(cam)
    }

    /// [`Camera::from_view_projection`] for `f32` matrices.
    ///
    /// # Errors
    /// As [`Camera::from_view_projection`].
    pub fn from_view_projection_f32(
        view: Mat4,
        projection: Mat4,
        depth: ClipDepth,
    ) -> Result<Camera> {
        Camera::from_view_projection(view.as_dmat4(), projection.as_dmat4(), depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec4Swizzles};

    // The usual host matrices, written out (column vectors).

    /// Right-handed view: looks down −z.
    fn look_at_rh(eye: DVec3, target: DVec3, up: DVec3) -> DMat4 {
        let f = (target - eye).normalize();
        let s = f.cross(up).normalize();
        let u = s.cross(f);
        DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
        )
    }

    /// Left-handed view: looks down +z.
    fn look_at_lh(eye: DVec3, target: DVec3, up: DVec3) -> DMat4 {
        let f = (target - eye).normalize();
        let s = up.cross(f).normalize();
        let u = f.cross(s);
        DMat4::from_cols(
            DVec4::new(s.x, u.x, f.x, 0.0),
            DVec4::new(s.y, u.y, f.y, 0.0),
            DVec4::new(s.z, u.z, f.z, 0.0),
            DVec4::new(-s.dot(eye), -u.dot(eye), -f.dot(eye), 1.0),
        )
    }

    /// Right-handed perspective with clip depth `depth(n, f) = (a, b)`.
    fn perspective(fov: f64, aspect: f64, (a, b): (f64, f64), w: f64) -> DMat4 {
        let h = 1.0 / (0.5 * fov).tan();
        DMat4::from_cols(
            DVec4::new(h / aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, h, 0.0, 0.0),
            DVec4::new(0.0, 0.0, a, w),
            DVec4::new(0.0, 0.0, b, 0.0),
        )
    }

    fn gl(fov: f64, aspect: f64, n: f64, f: f64) -> DMat4 {
        perspective(
            fov,
            aspect,
            (-(f + n) / (f - n), -2.0 * f * n / (f - n)),
            -1.0,
        )
    }

    fn d3d(fov: f64, aspect: f64, n: f64, f: f64) -> DMat4 {
        perspective(fov, aspect, (f / (n - f), n * f / (n - f)), -1.0)
    }

    fn d3d_lh(fov: f64, aspect: f64, n: f64, f: f64) -> DMat4 {
        perspective(fov, aspect, (f / (f - n), -n * f / (f - n)), 1.0)
    }

    /// A wrong clip-depth convention is caught when the host states its
    /// near plane; the right one passes.
    #[test]
    fn the_hosts_near_plane_catches_a_wrong_clip_depth() {
        let view = host_view();
        let (n, f) = (0.25, 300.0);
        let gl = gl(1.0, 1.5, n, f);
        let d3d = d3d(1.0, 1.5, n, f);
        let ok = |p, d| Camera::from_view_projection_near(view, p, d, n);
        assert!((ok(gl, ClipDepth::NegativeOneToOne).unwrap().near - n).abs() < 1e-12);
        assert!(ok(d3d, ClipDepth::ZeroToOne).is_ok());
        // Read the other way, each is a valid camera with another near plane.
        assert!(Camera::from_view_projection(view, gl, ClipDepth::ZeroToOne).is_ok());
        let e = ok(gl, ClipDepth::ZeroToOne).unwrap_err().to_string();
        assert!(
            e.contains("`near`") && e.contains("is NegativeOneToOne, not ZeroToOne"),
            "{e}"
        );
        let e = ok(d3d, ClipDepth::NegativeOneToOne)
            .unwrap_err()
            .to_string();
        assert!(e.contains("is ZeroToOne, not NegativeOneToOne"), "{e}");
        // A near plane that is simply not the matrix's.
        let e = Camera::from_view_projection_near(view, gl, ClipDepth::NegativeOneToOne, 0.3)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("not the host's 0.3") && !e.contains("not ZeroToOne"),
            "{e}"
        );
        for bad in [0.0, -1.0, f64::NAN] {
            assert!(
                Camera::from_view_projection_near(view, gl, ClipDepth::ZeroToOne, bad).is_err()
            );
        }
    }

    fn host_view() -> DMat4 {
        look_at_rh(
            DVec3::new(3.0, 2.0, 9.0),
            DVec3::new(-1.0, 0.5, 0.0),
            DVec3::Y,
        )
    }

    /// NDC x, y of a world point through a camera's own transform path.
    fn ndc_xy(cam: &Camera, p: DVec3) -> glam::DVec2 {
        let c = cam.clip_from_eye_relative() * (p - cam.position).extend(1.0);
        c.xy() / c.w
    }

    fn points() -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(-2.0, 1.5, -3.0),
            DVec3::new(4.0, -1.0, 2.0),
            DVec3::new(1.0, 3.0, -8.0),
        ]
    }

    /// Every depth convention gives the same camera as `look_at`: pose, field
    /// of view, aspect and near plane.
    #[test]
    fn host_projections_give_the_look_at_camera() {
        let (fov, aspect, near, far) = (0.9, 1.6, 0.25, 300.0);
        let want = Camera::look_at(
            DVec3::new(3.0, 2.0, 9.0),
            DVec3::new(-1.0, 0.5, 0.0),
            DVec3::Y,
            fov,
            aspect,
            near,
        )
        .unwrap();
        let cases = [
            (gl(fov, aspect, near, far), ClipDepth::NegativeOneToOne),
            (d3d(fov, aspect, near, far), ClipDepth::ZeroToOne),
            (
                perspective(fov, aspect, (-1.0, -near), -1.0),
                ClipDepth::ZeroToOne,
            ),
            (
                perspective(fov, aspect, (-1.0, -2.0 * near), -1.0),
                ClipDepth::NegativeOneToOne,
            ),
            (
                perspective(fov, aspect, (0.0, near), -1.0),
                ClipDepth::ZeroToOne,
            ),
            // Reversed and finite: the standard projection with depth 1 − z.
            (
                DMat4::from_cols(
                    DVec4::X,
                    DVec4::Y,
                    DVec4::new(0.0, 0.0, -1.0, 0.0),
                    DVec4::new(0.0, 0.0, 1.0, 1.0),
                ) * d3d(fov, aspect, near, far),
                ClipDepth::ZeroToOne,
            ),
        ];
        for (i, (p, depth)) in cases.into_iter().enumerate() {
            let cam = Camera::from_view_projection(host_view(), p, depth).unwrap();
            assert!((cam.position - want.position).length() < 1e-12, "{i}");
            assert!(cam.orientation.abs_diff_eq(want.orientation, 1e-12), "{i}");
            assert!((cam.fov_y - fov).abs() < 1e-12, "{i}");
            assert!((cam.aspect - aspect).abs() < 1e-12, "{i}");
            assert!((cam.near - near).abs() < 1e-9 * near, "{i}: {}", cam.near);
            assert_eq!(cam.shift, DVec2::ZERO);
            for q in points() {
                assert!((ndc_xy(&cam, q) - ndc_xy(&want, q)).length() < 1e-12);
            }
        }
    }

    /// An off-centre, jittered projection: x and y of every point land where
    /// the host's matrices put them, and the eye rays go through them.
    #[test]
    fn off_centre_and_jittered_projections_keep_x_and_y() {
        let (l, r, b, t, n, f) = (-0.3, 0.5, -0.2, 0.25, 0.4, 50.0);
        let mut p = DMat4::from_cols(
            DVec4::new(2.0 * n / (r - l), 0.0, 0.0, 0.0),
            DVec4::new(0.0, 2.0 * n / (t - b), 0.0, 0.0),
            DVec4::new(
                (r + l) / (r - l),
                (t + b) / (t - b),
                -(f + n) / (f - n),
                -1.0,
            ),
            DVec4::new(0.0, 0.0, -2.0 * f * n / (f - n), 0.0),
        );
        // TAA jitter of (0.3, −0.2) pixels at 640×360.
        p.z_axis.x += 2.0 * 0.3 / 640.0;
        p.z_axis.y -= 2.0 * -0.2 / 360.0;
        let v = host_view();
        let cam = Camera::from_view_projection(v, p, ClipDepth::NegativeOneToOne).unwrap();
        assert!((cam.near - n).abs() < 1e-12);
        for q in points() {
            let c = p * v * q.extend(1.0);
            let host = c.xy() / c.w;
            assert!((ndc_xy(&cam, q) - host).length() < 1e-12, "{q}");
            // The pixel ray through the host's NDC position passes through q.
            let (px, py) = ((host.x + 1.0) * 320.0, (1.0 - host.y) * 180.0);
            let d = cam.ray_direction(px, py, 640, 360);
            let to_q = (q - cam.position).normalize();
            assert!(d.dot(to_q) > 1.0 - 1e-12, "{q}");
        }
        // The frustum's side planes pass through the NDC corners.
        let fr = cam.frustum();
        for corner in fr.near_corners {
            let c = ndc_xy(&cam, corner);
            assert!(
                (c.x.abs() - 1.0).abs() < 1e-9 && (c.y.abs() - 1.0).abs() < 1e-9,
                "{c}"
            );
        }
        let f32_cam =
            Camera::from_view_projection_f32(v.as_mat4(), p.as_mat4(), ClipDepth::NegativeOneToOne)
                .unwrap();
        assert!((f32_cam.near - n).abs() < 1e-6 && (f32_cam.fov_y - cam.fov_y).abs() < 1e-6);
    }

    #[test]
    fn unsupported_matrices_name_their_field() {
        let v = host_view();
        let field = |r: Result<Camera>| match r {
            Err(Error::InvalidCamera { field, message }) => (field, message),
            other => panic!("{other:?}"),
        };
        let ortho = DMat4::from_cols(
            DVec4::X,
            DVec4::Y,
            DVec4::new(0.0, 0.0, -0.1, 0.0),
            DVec4::new(0.0, 0.0, -0.01, 1.0),
        );
        let (f, m) = field(Camera::from_view_projection(v, ortho, ClipDepth::ZeroToOne));
        assert!(f == "projection" && m.contains("orthographic"), "{m}");
        let lh = d3d_lh(1.0, 1.0, 0.1, 10.0);
        let (f, m) = field(Camera::from_view_projection(v, lh, ClipDepth::ZeroToOne));
        assert!(f == "projection" && m.contains("HostBasis"), "{m}");
        let mut flipped = d3d(1.0, 1.0, 0.1, 10.0);
        flipped.y_axis.y = -flipped.y_axis.y;
        assert_eq!(
            field(Camera::from_view_projection(
                v,
                flipped,
                ClipDepth::ZeroToOne
            ))
            .0,
            "projection"
        );
        let p = d3d(1.0, 1.0, 0.1, 10.0);
        let scaled = DMat4::from_scale(DVec3::splat(2.0)) * v;
        assert_eq!(
            field(Camera::from_view_projection(
                scaled,
                p,
                ClipDepth::ZeroToOne
            ))
            .0,
            "view"
        );
        let nan = DMat4::from_cols_array(&[f64::NAN; 16]);
        assert_eq!(
            field(Camera::from_view_projection(nan, p, ClipDepth::ZeroToOne)).0,
            "view"
        );
        assert_eq!(
            field(Camera::from_view_projection(v, nan, ClipDepth::ZeroToOne)).0,
            "projection"
        );
    }

    /// Left-handed and z-up hosts: the basis change round-trips, and a point
    /// lands at the same NDC x, y through the host's matrices and through
    /// the converted camera and point.
    #[test]
    fn left_handed_and_z_up_hosts_round_trip() {
        for (z_up, left_handed) in [(false, false), (true, false), (false, true), (true, true)] {
            let basis = HostBasis { z_up, left_handed };
            let m = basis.world_from_host();
            assert!((basis.host_from_world() * m).abs_diff_eq(DMat4::IDENTITY, 1e-15));
            assert_eq!(
                m.determinant() < 0.0,
                left_handed,
                "only handedness mirrors"
            );
            let up = if z_up { DVec3::Z } else { DVec3::Y };
            assert!(
                (m.transform_vector3(up) - DVec3::Y).length() < 1e-15,
                "host up is our +y"
            );
            let (eye, target) = (DVec3::new(4.0, -3.0, 2.5), DVec3::new(0.5, 1.0, 0.2));
            let (view, proj) = if left_handed {
                (look_at_lh(eye, target, up), d3d_lh(1.1, 1.5, 0.2, 80.0))
            } else {
                (look_at_rh(eye, target, up), d3d(1.1, 1.5, 0.2, 80.0))
            };
            let cam = basis.camera(view, proj, ClipDepth::ZeroToOne).unwrap();
            assert!((cam.position - m.transform_point3(eye)).length() < 1e-12);
            assert!((cam.near - 0.2).abs() < 1e-12);
            for q in [
                DVec3::new(1.0, 0.5, 0.0),
                DVec3::new(-0.5, 2.0, 1.0),
                DVec3::new(0.3, 0.2, -0.4),
            ] {
                let c = proj * view * q.extend(1.0);
                let ours = ndc_xy(&cam, m.transform_point3(q));
                assert!((ours - c.xy() / c.w).length() < 1e-12, "{basis:?} {q}");
            }
        }
    }
}
