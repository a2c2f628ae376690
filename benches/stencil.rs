//! The stencil stage per backend [Aila04 Table 1, ChanDurand04]: brute force
//! (BF), depth bounds (DB), the hierarchical stencil (H) with tiles 4, 8 and
//! 16, and the shadow-map hybrid (map 2048), on the default city (`street`,
//! `bird`) and box-city `city_16384` (`street`, `bird`), at 1280×1024 and
//! 2048×1536. Ids `res/scene/camera/backend`.
//!
//! Each measurement is one light's [`shadowcull::pipeline::shadow_mask`] on a
//! fixed eye pass with a warm silhouette cache: volume construction (the same
//! for every backend) plus the stencil stage (H: tile bounds, both stages,
//! resolve; hybrid: shadow map and classification too) plus mask assembly.
//! Settings as the goals: `Method::Auto`, wide counters, scissor off.
//! The counters (pixels processed, bandwidth, tiles) come from
//! `shadow_bench`, which prints them: `cargo bench -p shadowcull-benches --bench stencil`.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use shadowcull::pipeline::{
    eye_pass, shadow_mask, Backend, MeshCache, ShadowOptions, ShadowScratch,
};
use shadowcull::raster::{StencilBits, TileSize};
use shadowcull::scene::{Camera, Light, Scene};
use std::path::Path;
use testkit::BenchScene;

const RESOLUTIONS: [(u32, u32); 2] = [(1280, 1024), (2048, 1536)];

fn backends() -> Vec<(&'static str, Backend, bool)> {
    let h = |tile| Backend::Hierarchical {
        tile,
        full_shadow: true,
    };
    vec![
        ("bf", Backend::Brute, false),
        ("db", Backend::Brute, true),
        ("h_tile4", h(TileSize::T4), false),
        ("h_tile8", h(TileSize::T8), false),
        ("h_tile16", h(TileSize::T16), false),
        ("hybrid_2048", Backend::Hybrid { map_size: 2048 }, false),
    ]
}

/// `camera` gives the view's camera for an image size (its aspect ratio).
fn bench_view(
    c: &mut Criterion,
    group: &str,
    scene: &Scene,
    camera: &dyn Fn(u32, u32) -> Camera,
    light: Light,
) {
    let meshes = MeshCache::new(scene);
    for (w, h) in RESOLUTIONS {
        let camera = &camera(w, h);
        let eye = eye_pass(scene, &meshes, camera, w, h).expect("eye pass");
        let mut g = c.benchmark_group(format!("{w}x{h}/{group}"));
        g.sample_size(10);
        for (name, backend, depth_bounds) in backends() {
            let options = ShadowOptions {
                backend,
                bits: StencilBits::Wide,
                depth_bounds,
                ..Default::default()
            };
            let mut scratch = ShadowScratch::default();
            g.bench_function(name, |b| {
                b.iter(|| {
                    shadow_mask(scene, camera, &light, &eye, &options, &mut scratch)
                        .expect("shadow stage")
                })
            });
        }
        g.finish();
    }
}

fn bench_city(c: &mut Criterion) {
    let city = BenchScene::default_city();
    let scene = &city.scene;
    // The default job's first light: 1.5 scene heights above the centre.
    let light = shadowcull::jobs::config::LightSpec::AboveScene(1.5)
        .resolve(&city.loaded, &scene.bounds(), 0, Path::new("<bench>"))
        .expect("light");
    for cam in ["street", "bird"] {
        let pose = city.path(cam).at(0).expect("pose");
        let camera = |w: u32, h: u32| pose.camera(w as f64 / h as f64).expect("camera");
        bench_view(c, &format!("city/{cam}"), scene, &camera, light);
    }
}

fn bench_box_city(c: &mut Criterion) {
    let Some(city) = BenchScene::box_city("city_16384") else {
        return;
    };
    let light = city.first_light();
    for cam in ["street", "bird"] {
        let look = city.look(cam);
        let camera = |w: u32, h: u32| look.camera(w as f64 / h as f64).expect("camera");
        bench_view(c, &format!("city_16384/{cam}"), &city.scene, &camera, light);
    }
}

criterion_group!(benches, bench_city, bench_box_city);
criterion_main!(benches);
