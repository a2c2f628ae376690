//! Tests of the procedural scenes: the default city's size (Steiner ch. 5),
//! determinism, closed meshes, camera paths, and the analytic scenes.

use glam::{DVec3, Vec3};
use scene::procedural::{
    box_over_plane, city, city_bounds, city_height, stacked_occluders, CityParams,
};
use scene::{CameraPath, Light, ObjectId, Scene};
use std::time::Instant;

fn path<'a>(paths: &'a [(String, CameraPath)], name: &str) -> &'a CameraPath {
    &paths.iter().find(|(n, _)| n == name).expect("path").1
}

#[test]
fn procedural_default_city_matches_steiner_and_is_well_formed() {
    let params = CityParams::default();
    let t = Instant::now();
    let loaded = city(&params).unwrap();
    let generated = t.elapsed();
    let scene = Scene::new(loaded.graph.clone()).unwrap();
    let c = scene.counts();
    let b = scene.bounds();
    println!(
        "default city: {} objects, {} triangles, {} vertices, {} meshes; bounds {:?}..{:?}; \
         city_height {}; generated in {generated:?}, scene built in {:?}",
        c.objects,
        c.triangles,
        c.vertices,
        c.meshes,
        b.min,
        b.max,
        city_height(&params),
        t.elapsed()
    );
    assert!(
        (16_000..=18_000).contains(&c.objects),
        "{} objects",
        c.objects
    );
    assert!(
        (900_000..=1_100_000).contains(&c.triangles),
        "{} triangles",
        c.triangles
    );
    assert!(
        generated.as_secs_f64() < 8.0,
        "generation took {generated:?}"
    );

    // Only the 400 ground tiles are open (4 boundary edges each); everything
    // else is closed, manifold, consistently wound, without degenerate triangles.
    let tiles = (params.blocks_x * params.blocks_z) as usize;
    for m in loaded.graph.meshes() {
        let t = m.topology();
        assert_eq!(
            (
                t.non_manifold_edges,
                t.inconsistent_edges,
                t.degenerate_triangles
            ),
            (0, 0, 0),
            "{}",
            m.name()
        );
        let open = if m.name().starts_with("ground") { 4 } else { 0 };
        assert_eq!(t.boundary_edges, open, "{}", m.name());
    }
    assert_eq!(c.topology.boundary_edges, 4 * tiles);

    // Triangle counts vary (boxes, hip roofs, roof structures, towers, props).
    let mut kinds = std::collections::BTreeSet::new();
    for m in loaded.graph.meshes() {
        kinds.insert(m.triangles().len());
    }
    for n in [2, 12, 14, 28, 44, 316] {
        assert!(kinds.contains(&n), "no mesh with {n} triangles: {kinds:?}");
    }
    // Trees and lamps are instanced: two meshes shared by many objects.
    let tree_objects = scene
        .objects()
        .iter()
        .filter(|o| o.mesh.slot() == 0)
        .count();
    assert_eq!(tree_objects, (params.trees_per_block as usize) * tiles);

    // Bounds: inside city_bounds, spanning it in x and z, tallest object near city_height.
    let (lo, hi) = city_bounds(&params);
    assert_eq!(b.min, lo.as_vec3());
    assert_eq!((b.max.x, b.max.z), (hi.x as f32, hi.z as f32));
    assert!(
        f64::from(b.max.y) <= hi.y && f64::from(b.max.y) > 0.9 * hi.y,
        "max y {}",
        b.max.y
    );

    // Paths: 100 frames of valid cameras; the street camera stays inside the
    // city, above ground, in the street (clear of every object's bounds).
    for name in ["street", "bird"] {
        let start = loaded
            .cameras
            .iter()
            .find(|(n, _)| n == name)
            .expect("camera")
            .1;
        let p = path(&loaded.paths, name);
        assert_eq!(p.at(0), Some(start));
        for f in 0..100 {
            assert!(
                p.at(f).unwrap().camera(4.0 / 3.0).is_ok(),
                "{name} frame {f}"
            );
        }
    }
    let street = path(&loaded.paths, "street");
    assert!(matches!(street, CameraPath::Dolly { .. }));
    for f in 0..100 {
        let eye = street.at(f).unwrap().eye;
        assert!((eye.y - 1.7).abs() < 1e-12);
        assert!(
            f64::from(b.min.x) <= eye.x && eye.x <= f64::from(b.max.x),
            "frame {f}"
        );
        assert!(
            f64::from(b.min.z) <= eye.z && eye.z <= f64::from(b.max.z),
            "frame {f}"
        );
        let p = eye.as_vec3();
        let inside = scene
            .objects()
            .iter()
            .filter(|o| o.world_bounds.max.y > 0.0)
            .find(|o| o.world_bounds.contains(p));
        assert!(
            inside.is_none(),
            "frame {f}: street eye {eye} inside {:?}",
            inside.map(|o| o.node)
        );
    }
    if let Some(p1) = street.at(1) {
        assert_eq!(
            p1.eye - street.at(0).unwrap().eye,
            DVec3::new(0.0, 0.0, -1.0)
        );
    }
    let bird = path(&loaded.paths, "bird").at(0).unwrap();
    let down = (bird.target - bird.eye).normalize();
    let pitch = (-down.y).asin().to_degrees();
    assert!((pitch - 35.0).abs() < 1e-9, "bird looks down {pitch}°");
    assert_eq!(bird.target, DVec3::ZERO);
    assert!(loaded.lights.iter().all(|(_, l)| l.validate().is_ok()));
}

#[test]
fn procedural_city_is_deterministic_per_seed() {
    let small = CityParams {
        blocks_x: 4,
        blocks_z: 3,
        ..Default::default()
    };
    let fingerprint = |p: &CityParams| {
        let s = Scene::new(city(p).unwrap().graph).unwrap();
        let boxes: Vec<(Vec3, Vec3)> = s
            .objects()
            .iter()
            .map(|o| (o.world_bounds.min, o.world_bounds.max))
            .collect();
        let positions: Vec<Vec3> = s
            .graph()
            .meshes()
            .iter()
            .flat_map(|m| m.positions().to_vec())
            .collect();
        (s.counts(), boxes, positions)
    };
    let a = fingerprint(&small);
    assert_eq!(a, fingerprint(&small), "same seed, different city");
    let other = fingerprint(&CityParams {
        seed: 2,
        ..small.clone()
    });
    assert_ne!(a.1, other.1, "different seed, same city");
    assert!(
        Scene::new(city(&small).unwrap().graph)
            .unwrap()
            .object(ObjectId::from_slot(0))
            .world_bounds
            .min
            .y
            == 0.0
    );
}

#[test]
fn procedural_city_variants_generate() {
    for p in [
        CityParams {
            blocks_x: 1,
            blocks_z: 1,
            ..Default::default()
        },
        CityParams {
            blocks_x: 3,
            blocks_z: 2,
            lots_per_side: 1,
            trees_per_block: 0,
            lamps_per_block: 0,
            ..Default::default()
        },
        CityParams {
            blocks_x: 2,
            blocks_z: 2,
            tower_fraction: 1.0,
            roof_structure_fraction: 0.0,
            hip_roof_fraction: 0.0,
            ..Default::default()
        },
        CityParams {
            blocks_x: 2,
            blocks_z: 2,
            sidewalk: 0.0,
            building_density: 1.0,
            footprint_min: 1.0,
            footprint_max: 1.0,
            height_min: 1.0,
            height_max: 1.0,
            ..Default::default()
        },
    ] {
        let loaded = city(&p).unwrap();
        let scene = Scene::new(loaded.graph).unwrap();
        let (lo, hi) = city_bounds(&p);
        let b = scene.bounds();
        assert!(
            b.min.cmpge(lo.as_vec3()).all() && b.max.cmple(hi.as_vec3()).all(),
            "{p:?}"
        );
        for name in ["street", "bird"] {
            let path = path(&loaded.paths, name);
            assert!((0..100).all(|f| path.at(f).unwrap().camera(1.0).is_ok()));
        }
    }
}

#[test]
fn procedural_analytic_scenes() {
    let l = box_over_plane().unwrap();
    assert_eq!(
        l.lights[0].1,
        Light::Point {
            position: DVec3::new(0.0, 10.0, 0.0),
            range: None
        }
    );
    let s = Scene::new(l.graph).unwrap();
    assert_eq!(
        s.object(ObjectId::from_slot(0)).world_bounds.min,
        Vec3::new(-0.5, 1.0, -0.5)
    );
    assert_eq!(
        s.object(ObjectId::from_slot(0)).world_bounds.max,
        Vec3::new(0.5, 2.0, 0.5)
    );
    assert_eq!(s.counts().topology.boundary_edges, 4);
    let l = stacked_occluders(4).unwrap();
    assert!(l.cameras[0].1.camera(1.0).is_ok());
    let s = Scene::new(l.graph).unwrap();
    assert_eq!(s.object(ObjectId::from_slot(3)).world_bounds.max.y, 4.25);
}
