//! Scenes, cameras and lights shared by the facade's integration tests (the
//! helpers other crates' tests use too live in `shadowcull-testkit`).

use glam::{DVec3, Vec3};
use scene::procedural::analytic;
use scene::{Camera, CameraPath, Light, Mesh, Scene, SceneGraph, Transform};

/// A scene of one root node with `root`'s transform drawing every mesh once.
pub fn scene_of(meshes: Vec<Mesh>, root: Transform) -> Scene {
    let mut g = SceneGraph::new();
    let ids: Vec<_> = meshes.into_iter().map(|m| g.add_mesh(m)).collect();
    g.add_root(scene::Node {
        name: "root".into(),
        transform: root,
        meshes: ids,
        children: vec![],
    });
    Scene::new(g).unwrap()
}

/// The ground, a tower, a slab and an open awning: the stencil tests' scene.
pub fn boxes_on_ground(root: Transform) -> Scene {
    scene_of(
        vec![
            analytic::horizontal_quad("ground", [-10.0, 10.0], [-10.0, 10.0], 0.0, true).unwrap(),
            analytic::box_mesh(
                "tower",
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 3.0, 1.0),
            )
            .unwrap(),
            analytic::box_mesh("slab", Vec3::new(2.0, 1.0, 2.0), Vec3::new(3.0, 1.5, 4.0)).unwrap(),
            analytic::horizontal_quad("awning", [-4.0, -2.0], [1.0, 3.0], 2.0, true).unwrap(),
        ],
        root,
    )
}

/// The view of [`boxes_on_ground`] from above and in front (4:3, fov_y 50°).
pub fn overview_camera() -> Camera {
    Camera::look_at(
        DVec3::new(2.0, 9.0, 12.0),
        DVec3::ZERO,
        DVec3::Y,
        50f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap()
}

/// The culling tests' procedural city (6×6 blocks: the default 20×20 city's
/// unculled runs would take minutes in the test profile) and its `street`
/// camera path.
pub fn street_city() -> (std::sync::Arc<Scene>, CameraPath) {
    testkit::street_city(6)
}

/// The culling tests' lights for a city: a point light 1.5 scene heights
/// above its centre and a sun.
pub fn city_lights(scene: &Scene) -> [Light; 2] {
    let b = scene.bounds();
    let c = b.center();
    [
        Light::Point {
            position: DVec3::new(c.x, f64::from(b.max.y) * 1.5, c.z),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(0.4, -0.8, 0.3),
        },
    ]
}
