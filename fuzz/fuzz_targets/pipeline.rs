//! Differential fuzzing of the implementations that must agree, on small
//! scenes from the fuzzer's bytes (a ground quad and up to six boxes, any
//! light, any camera with near planes down to 10⁻⁴):
//! - the hierarchical stencil against brute force, value for value with the
//!   FS bit off, within the FS bit's stated differences with it on, on
//!   ordinary and on continuously clamped volumes
//!   (`testkit::check_hierarchical`, `check_hierarchical_clamped`);
//! - the pipeline's mask with conservative stop-and-wait (`exact`), CHC and
//!   CHC++ culling against the unculled mask: equal on every pixel.
//!
//! `cargo +nightly fuzz run pipeline fuzz/corpus/pipeline`
#![no_main]

use glam::{DMat4, DQuat, DVec3, Vec3};
use libfuzzer_sys::fuzz_target;
use shadowcull::pipeline::eye::{eye_pass, MeshCache};
use shadowcull::raster::TileSize;
use shadowcull::scene::{Camera, Light, Mesh, Scene, SceneGraph, Transform};
use shadowcull::shadowgen::MethodChoice;
use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};
use shadowcull_fuzz::Bytes;

const W: u32 = 40;
const H: u32 = 30;

fn unit_box() -> Mesh {
    let p: Vec<Vec3> = (0..8)
        .map(|c| Vec3::new((c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32))
        .collect();
    let tris = shadowcull::raster::AABB_TRIANGLES;
    Mesh::new("box", &p, &tris).expect("a unit box")
}

fn point(b: &mut Bytes, scale: f64) -> DVec3 {
    (DVec3::new(b.unit(), b.unit(), b.unit()) * 2.0 - 1.0) * scale
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let mut g = SceneGraph::new();
    let cube = g.add_mesh(unit_box());
    let ground = DMat4::from_scale_rotation_translation(
        DVec3::new(20.0, 0.01, 20.0),
        DQuat::IDENTITY,
        DVec3::new(-10.0, -0.01, -10.0),
    );
    g.add_instance("ground", cube, Transform::Matrix(ground));
    for k in 0..b.u8() % 7 {
        let size = DVec3::new(b.unit(), b.unit(), b.unit()) * 3.0 + 0.05;
        let at = point(&mut b, 6.0) + DVec3::Y * 6.0;
        let turn = DQuat::from_rotation_y(b.unit() * std::f64::consts::TAU);
        let m = DMat4::from_scale_rotation_translation(size, turn, at);
        g.add_instance(&format!("box{k}"), cube, Transform::Matrix(m));
    }
    let Ok(scene) = Scene::new(g) else {
        return;
    };
    let light = match b.u8() % 3 {
        0 => Light::Directional {
            direction: point(&mut b, 1.0) - DVec3::Y,
        },
        1 => Light::Point {
            position: point(&mut b, 12.0) + DVec3::Y * 8.0,
            range: None,
        },
        _ => Light::Spot {
            position: point(&mut b, 12.0) + DVec3::Y * 8.0,
            direction: point(&mut b, 1.0) - DVec3::Y,
            apex_angle: 0.2 + 2.5 * b.unit(),
            range: None,
        },
    };
    if light.validate().is_err() {
        return;
    }
    let near = 10f64.powf(-4.0 + 4.0 * b.unit());
    let eye = point(&mut b, 14.0) + DVec3::Y * 4.0;
    let target = point(&mut b, 4.0);
    let Ok(cam) = Camera::look_at(
        eye,
        target,
        DVec3::Y,
        1.0,
        f64::from(W) / f64::from(H),
        near,
    ) else {
        return;
    };
    let method = [
        MethodChoice::Auto,
        MethodChoice::ZFail,
        MethodChoice::ZpPlus,
    ][usize::from(b.u8() % 3)];
    let two_sided = b.u8() % 2 == 1;

    // H against BF.
    let meshes = MeshCache::new(&scene);
    let Ok(pass) = eye_pass(&scene, &meshes, &cam, W, H) else {
        return;
    };
    let tiles = [TileSize::T4, TileSize::T8, TileSize::T16];
    if let Err(e) = testkit::check_hierarchical(
        &scene,
        &cam,
        &light,
        &pass.target,
        method,
        two_sided,
        &tiles,
    ) {
        panic!("H against BF: {e}");
    }
    if let Err(e) = testkit::check_hierarchical_clamped(
        &scene,
        &cam,
        &light,
        &pass.target,
        method,
        two_sided,
        &tiles,
    ) {
        panic!("H against BF on segments: {e}");
    }

    // Culled masks against the unculled one.
    let scene = std::sync::Arc::new(scene);
    let mask = |culling| {
        let options = PipelineOptions {
            culling,
            stencil: StencilBackend::H,
            method,
            two_sided,
            light_resolution: 64,
            reference_every: 0,
            ..Default::default()
        };
        let mut p = Pipeline::new(scene.clone(), options).expect("valid options");
        p.add_light(light).expect("a valid light");
        let out = p.frame(&FrameInput::new(W, H, cam)).expect("a frame");
        let l = out.lights().next().expect("one light");
        l.mask().cloned().expect("a mask")
    };
    let plain = mask(CullingSpec::None);
    for culling in [CullingSpec::Exact, CullingSpec::Chc, CullingSpec::Chcpp] {
        assert!(
            mask(culling) == plain,
            "{culling:?} culling changed the mask"
        );
    }
});
