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

/// A 20 m ground and a 2 × 3 × 2 m tower at its centre.
fn ground_and_tower() -> Vec<scene::Mesh> {
    vec![
        analytic::horizontal_quad("ground", [-10.0, 10.0], [-10.0, 10.0], 0.0, true).unwrap(),
        analytic::box_mesh(
            "tower",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 3.0, 1.0),
        )
        .unwrap(),
    ]
}

/// Ground, a tower, and a row of thin poles (2 cm wide, 3 m tall) under a
/// low sun: the poles' shadows are long lines a few pixels wide.
fn poles() -> scene::Scene {
    let mut meshes = ground_and_tower();
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

/// Ground, a tower and four blocks a metre or more across: no caster
/// thinner than a light-view texel.
fn blocks() -> scene::Scene {
    let mut meshes = ground_and_tower();
    for (k, (x, z)) in [(3.0, 1.0), (-4.0, 2.0), (1.5, -4.0), (-3.0, -3.5)]
        .into_iter()
        .enumerate()
    {
        meshes.push(
            analytic::box_mesh(
                format!("block{k}"),
                Vec3::new(x, 0.0, z),
                Vec3::new(x + 1.2, 1.0 + k as f32 * 0.5, z + 1.0),
            )
            .unwrap(),
        );
    }
    scene_of(meshes, Transform::default())
}

/// In a culled pipeline with point-sampled light views the hybrid's shadow
/// maps are the light pass's own light views (their depth after the
/// traversal), not maps of its own: with a 16² `map_size` its own maps
/// would leave most of the image to the volumes, the light views (256² or
/// 1024²) leave a thin band along the shadow boundaries, narrower in the
/// finer views. Off the reference's shadow boundaries the masks agree but
/// for a few pixels, in the first frame and in a steady one (where each
/// view keeps its target from frame to frame). Conservative light views
/// hold no shadow map (inner-conservative triangles leave holes): there the
/// hybrid renders its own maps, as without culling.
#[test]
fn hybrid_reads_the_light_views_of_the_light_pass() {
    use shadowcull::pipeline::{CoverageSpec, CullingSpec, Pipeline, PipelineOptions};
    use shadowcull::pipeline::{FrameInput, StencilBackend};
    let scene = std::sync::Arc::new(blocks());
    let cam = overview_camera();
    let lights = [
        Light::Point {
            position: DVec3::new(1.0, 7.0, 2.0),
            range: None,
        },
        // Inside the scene's bounds: cube faces.
        Light::Point {
            position: DVec3::new(0.5, 2.5, 2.5),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(-0.5, -0.7, -0.3),
        },
    ];
    for light in lights {
        // (silhouette pixels, mask) of one configuration, per frame.
        let run = |culling, coverage, light_resolution| {
            let options = PipelineOptions {
                stencil: StencilBackend::Hybrid,
                culling,
                coverage,
                light_resolution,
                map_size: 16,
                ..Default::default()
            };
            let mut p = Pipeline::new(scene.clone(), options).unwrap();
            let id = p.add_light(light).unwrap();
            let mut out = Vec::new();
            let mut views = 0;
            for _ in 0..2 {
                let f = p.frame(&FrameInput::new(W, H, cam)).unwrap();
                let l = f.light(id).unwrap();
                let shadow = l.shadow().unwrap();
                views = l.views().len();
                out.push((shadow.silhouette_pixels, shadow.mask.clone()));
            }
            let r = p.reference_mask(id).unwrap();
            let off: Vec<u64> = out
                .iter()
                .map(|(_, m)| {
                    let c = compare(&r.mask, &r.ambiguous, m);
                    assert!(c.compared > 30_000, "{c:?}");
                    c.mismatches - c.mismatches_on_boundary
                })
                .collect();
            (out[1].0, off, out[0].0, views)
        };
        let (own, ..) = run(CullingSpec::None, CoverageSpec::Conservative, 1024);
        let (conservative, ..) = run(CullingSpec::Chcpp, CoverageSpec::Conservative, 1024);
        assert_eq!(
            conservative, own,
            "conservative views: the hybrid's own maps"
        );
        let coarse = run(CullingSpec::Chcpp, CoverageSpec::Point, 256);
        let fine = run(CullingSpec::Chcpp, CoverageSpec::Point, 1024);
        println!(
            "{light:?}: silhouette own 16² maps {own}, {} views 256² {} \
             (off-boundary mismatches {:?}), 1024² {} ({:?})",
            coarse.3, coarse.0, coarse.1, fine.0, fine.1
        );
        for (sil, off, first, _) in [coarse.clone(), fine.clone()] {
            assert!(sil > 0 && sil == first, "{sil} {first}");
            assert!(sil * 4 < own, "{sil} vs own maps {own}");
            for o in off {
                assert!(o < 40, "{o} off-boundary mismatches");
            }
        }
        assert!(fine.0 < coarse.0, "{} {}", fine.0, coarse.0);
    }
}
