//! The shadow-map hybrid [ChanDurand04] end to end: not exact, and where it
//! fails — thin casters whose shadow falls between shadow-map samples go
//! missing — measured against the ray-cast reference and against the exact
//! hierarchical stencil on the same eye pass.

use crate::common::{overview_camera, scene_of};
use glam::{DVec3, Vec3};
use scene::procedural::analytic;
use scene::{Light, Transform};
use shadowcull::mask::{compare, PixelClass};
use shadowcull::pipeline::{
    eye_pass, shadow_mask, Backend, MeshCache, ShadowOptions, ShadowScratch,
};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};

const W: u32 = 320;
const H: u32 = 240;

/// Ground, a tower, and a row of thin poles (2 cm wide, 3 m tall) under a
/// low sun: the poles' shadows are long lines a few pixels wide.
fn poles() -> scene::Scene {
    let mut meshes = vec![
        analytic::horizontal_quad("ground", [-10.0, 10.0], [-10.0, 10.0], 0.0, true).unwrap(),
        analytic::box_mesh(
            "tower",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 3.0, 1.0),
        )
        .unwrap(),
    ];
    for k in 0..5 {
        let x = 2.0 + k as f32 * 0.8;
        meshes.push(
            analytic::box_mesh(
                format!("pole{k}"),
                Vec3::new(x, 0.0, 2.0),
                Vec3::new(x + 0.02, 3.0, 2.02),
            )
            .unwrap(),
        );
    }
    scene_of(meshes, Transform::default())
}

#[test]
fn hybrid_misses_thin_shadows_at_low_map_resolution() {
    let scene = poles();
    let cam = overview_camera();
    let light = Light::Directional {
        direction: DVec3::new(-0.5, -0.6, -0.4),
    };
    let meshes = MeshCache::new(&scene);
    let eye = eye_pass(&scene, &meshes, &cam, W, H).unwrap();
    let bvh = TriangleBvh::new(&scene);
    let r = reference_mask(
        &bvh,
        &cam,
        &light,
        W,
        H,
        &ReferenceOptions::default(),
        Some(eye.surface()),
    );
    let run = |backend| {
        let opts = ShadowOptions {
            backend,
            ..Default::default()
        };
        shadow_mask(
            &scene,
            &cam,
            &light,
            &eye,
            &opts,
            &mut ShadowScratch::default(),
        )
        .unwrap()
    };
    // The exact backend has no mismatch off a shadow boundary.
    let exact = run(Backend::Hierarchical {
        tile: raster::TileSize::T8,
        full_shadow: true,
    });
    let c = compare(&r.mask, &r.ambiguous, &exact.mask);
    assert_eq!(c.mismatches - c.mismatches_on_boundary, 0);
    let brute = run(Backend::Brute);
    let mut missed = Vec::new();
    for map in [64, 256, 1024, 4096] {
        let f = run(Backend::Hybrid { map_size: map });
        let c = compare(&r.mask, &r.ambiguous, &f.mask);
        // Shadow in the reference, lit in the hybrid: a missing shadow.
        let lost = c
            .mismatch_pixels
            .iter()
            .filter(|&&(x, y, _)| {
                r.mask.get(x, y) == PixelClass::Shadow && f.mask.get(x, y) == PixelClass::Lit
            })
            .count();
        println!(
            "map {map}: {} mismatches of {} compared ({lost} lost shadow), {} silhouette pixels, volumes processed {} pixels",
            c.mismatches, c.compared, f.silhouette_pixels, f.stencil.pixels_processed
        );
        assert!(f.silhouette_pixels > 0);
        // Volumes run only at silhouette pixels: far less work than brute force.
        assert!(f.stencil.pixels_processed < brute.stencil.pixels_processed);
        missed.push((c.mismatches, lost));
    }
    // A coarse map loses the poles' shadows; a fine one finds (nearly) all.
    assert!(missed[0].1 > 20, "{missed:?}");
    assert!(missed[3].0 < missed[0].0, "{missed:?}");
}
