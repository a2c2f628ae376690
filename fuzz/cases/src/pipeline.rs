//! Differential fuzzing of the implementations that must agree, on small
//! scenes from the fuzzer's bytes (a ground quad and up to six boxes, any
//! light, any camera with near planes down to 10⁻⁴):
//! - the hierarchical stencil against brute force, value for value with the
//!   FS bit off, within the FS bit's stated differences with it on, on
//!   ordinary and on continuously clamped volumes
//!   (`testkit::check_hierarchical`, `check_hierarchical_clamped`);
//! - the pipeline's mask with conservative stop-and-wait (`exact`), CHC and
//!   CHC++ culling against the unculled mask: equal on every pixel.

use crate::{box_scene, point, Bytes};
use glam::DVec3;
use shadowcull::pipeline::eye::{eye_pass, MeshCache};
use shadowcull::raster::TileSize;
use shadowcull::scene::Camera;
use shadowcull::shadowgen::MethodChoice;
use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};

const W: u32 = 40;
const H: u32 = 30;

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let mut b = Bytes(data);
    let Some((scene, light)) = box_scene(&mut b) else {
        return;
    };
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
}
