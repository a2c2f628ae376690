//! Back-face culling in the eye pass: which faces an eye draw of an object
//! may skip without changing what the eye sees.
//!
//! Seen from a point outside a closed mesh whose pieces all enclose volume of
//! one sign ([`scene::Mesh::solid`]), the first surface each eye ray meets
//! faces it, so the faces turned away can be skipped — the same depth and
//! ids, bar ties of rounding at silhouette edges, for a fraction of the
//! rasterization (every mesh of a city of buildings is solid). The eye's
//! centre of projection is outside the mesh when the object's bounds lie
//! wholly beyond the near plane, which also keeps the near plane from
//! cutting the mesh open. A mirroring transform (negative determinant) turns
//! the faces: its outside then faces away on screen ([`CullMode::Front`]).
//!
//! Both eye paths use it — the culled traversal's occluder draws and the
//! unculled draw of every object — so culled and unculled frames stay
//! identical; light views never cull (their occluder depth is their
//! farthest, inner-conservative one).

use raster::CullMode;
use scene::{Camera, Mesh, Object, Solid};

/// Relative margin of the near-plane test, of the distances involved: far
/// above the rounding of the f32 clip transform (about `1e-7` of them), so a
/// mesh that passes is never cut by the rasterizer's near plane.
const NEAR_MARGIN: f64 = 1e-5;

/// The faces the eye of `camera` may skip when it draws `object` (whose mesh
/// is `mesh`): back faces (front faces when mirrored or inside out) of a
/// solid mesh wholly beyond the near plane; none otherwise.
pub fn eye_cull(camera: &Camera, object: &Object, mesh: &Mesh) -> CullMode {
    let Some(solid) = mesh.solid() else {
        return CullMode::None;
    };
    let b = object.world_bounds;
    let (centre, half) = (
        b.center() - camera.position,
        0.5 * (b.max - b.min).as_dvec3(),
    );
    let forward = camera.forward();
    let nearest = centre.dot(forward) - half.dot(forward.abs());
    let margin = NEAR_MARGIN * (camera.near + centre.length() + half.length());
    // (Empty bounds give NaN, which culls nothing.)
    if nearest.is_nan() || nearest <= camera.near + margin {
        return CullMode::None;
    }
    let det = object.world_from_local.determinant();
    if !det.is_finite() || det == 0.0 {
        return CullMode::None;
    }
    if (solid == Solid::Outward) == (det > 0.0) {
        CullMode::Back
    } else {
        CullMode::Front
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat4, DQuat, DVec3, Vec3};
    use scene::procedural::analytic::box_mesh;
    use scene::{Aabb, LookAt, MeshId, NodeId, ObjectFlags};

    /// A unit box placed by `m`, its bounds the transformed corners'.
    fn object(m: DMat4) -> Object {
        let corners = (0..8).map(|k| {
            let c = DVec3::new((k & 1) as f64, (k >> 1 & 1) as f64, (k >> 2) as f64);
            m.transform_point3(c).as_vec3()
        });
        Object {
            node: NodeId(0),
            mesh: MeshId::from_slot(0),
            world_from_local: m,
            mirrored: m.determinant() < 0.0,
            world_bounds: Aabb::from_points(corners),
            alive: true,
            flags: ObjectFlags::ALL,
            occluder: None,
        }
    }

    /// The rule's cases: a solid box ahead is back-culled, mirrored or
    /// inside out front-culled; a box the near plane cuts, one around or
    /// behind the eye, a flattened one and an open mesh are drawn whole.
    #[test]
    fn solid_objects_ahead_skip_the_faces_turned_away() {
        let camera = LookAt {
            eye: DVec3::new(0.0, 0.0, 10.0),
            target: DVec3::ZERO,
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.5,
        }
        .camera(1.0)
        .unwrap();
        let cube = box_mesh("box", Vec3::ZERO, Vec3::ONE).unwrap();
        let t = DMat4::from_translation;
        let s = DMat4::from_scale;
        let cull = |m: DMat4, mesh: &Mesh| eye_cull(&camera, &object(m), mesh);
        assert_eq!(cull(DMat4::IDENTITY, &cube), CullMode::Back);
        let turned = DMat4::from_quat(DQuat::from_rotation_y(0.7));
        assert_eq!(cull(t(DVec3::X) * turned, &cube), CullMode::Back);
        let mirror = s(DVec3::new(-1.0, 1.0, 1.0));
        assert_eq!(cull(mirror, &cube), CullMode::Front);
        let (p, tris): (Vec<Vec3>, Vec<[u32; 3]>) = (
            cube.positions().to_vec(),
            cube.triangles()
                .iter()
                .map(|&[a, b, c]| [a, c, b])
                .collect(),
        );
        let inside_out = Mesh::new("inside out", &p, &tris).unwrap();
        assert_eq!(cull(DMat4::IDENTITY, &inside_out), CullMode::Front);
        assert_eq!(cull(mirror, &inside_out), CullMode::Back);
        // Its near face 0.5 behind the near plane, then cut by it, then
        // around the eye, then behind it.
        assert_eq!(cull(t(DVec3::new(0.0, 0.0, 8.0)), &cube), CullMode::Back);
        assert_eq!(cull(t(DVec3::new(0.0, 0.0, 8.99)), &cube), CullMode::None);
        assert_eq!(cull(t(DVec3::new(-0.5, -0.5, 9.5)), &cube), CullMode::None);
        assert_eq!(cull(t(DVec3::new(0.0, 0.0, 12.0)), &cube), CullMode::None);
        // Off to the side but level with the eye: the near plane's extension
        // cuts it.
        assert_eq!(cull(t(DVec3::new(30.0, 0.0, 9.2)), &cube), CullMode::None);
        assert_eq!(cull(s(DVec3::new(1.0, 0.0, 1.0)), &cube), CullMode::None);
        let open = Mesh::new("open", &p, &cube.triangles()[2..]).unwrap();
        assert_eq!(cull(DMat4::IDENTITY, &open), CullMode::None);
    }
}
