//! The one transform path (DESIGN.md "Conventions"): every stage that turns an
//! object's local vertices into clip space uses [`clip_from_local`], so a light
//! cap has bit-identical depth to the surface it caps, and scenes far from the
//! origin keep their precision.

use crate::Camera;
use glam::{DMat4, DVec3, Mat4, Vec3};

/// `clip_from_local` for one object and one camera.
///
/// Composed in f64 in eye-relative form, `P · R · (world_from_local · p − eye)`,
/// and rounded to an f32 matrix once: the translation `world_from_local.w − eye`
/// is formed before any rounding, so an object 1e6 from the origin near the eye
/// keeps full f32 precision in clip space.
pub fn clip_from_local(camera: &Camera, world_from_local: &DMat4) -> Mat4 {
    let mut eye_from_local = *world_from_local;
    eye_from_local.w_axis -= camera.position.extend(0.0);
    (camera.clip_from_eye_relative() * eye_from_local).as_mat4()
}

/// A local vertex in world space, in f64 (the reference and the facing rule use this).
pub fn world_point(world_from_local: &DMat4, p: Vec3) -> DVec3 {
    world_from_local.transform_point3(p.as_dvec3())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_from_origin_keeps_precision() {
        let eye = DVec3::new(1e6, 2.0, 1e6);
        let cam = Camera::look_at(
            eye,
            eye + DVec3::new(0.0, 0.0, -1.0),
            DVec3::Y,
            1.0,
            1.0,
            0.01,
        )
        .unwrap();
        let world = DMat4::from_translation(DVec3::new(1e6, 2.0, 1e6 - 1.0));
        let m = clip_from_local(&cam, &world);
        // A 1 mm offset in x must survive: at 1e6 an f32 world coordinate could not hold it.
        let a = m * glam::Vec4::new(0.0, 0.0, 0.0, 1.0);
        let b = m * glam::Vec4::new(0.001, 0.0, 0.0, 1.0);
        let dx = b.x / b.w - a.x / a.w;
        let f = 1.0 / 0.5f64.tan();
        assert!(((dx as f64) - 0.001 * f).abs() < 1e-6, "dx = {dx}");
    }
}
