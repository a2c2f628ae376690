//! The stencil shadow pipeline per stage and stencil variant: ids
//! `scene/camera/stage`. The BF and DB columns of [Aila04 Table 1] for our
//! scenes: `cargo bench -p shadowcull-benches --bench shadow`; the counters (volume triangles,
//! pixels processed) come from `shadow_bench`, which prints them.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use shadowcull::jobs::frame::FrameRunner;
use shadowcull::pipeline::{PipelineOptions, StencilBackend};
use shadowcull::scene::{Camera, Light, Scene};
use std::path::Path;
use testkit::BenchScene;

const RES: (u32, u32) = (1280, 1024);

fn variants() -> [(&'static str, PipelineOptions); 3] {
    let base = PipelineOptions {
        reference_every: 0,
        ..Default::default()
    };
    [
        ("bf", base),
        (
            "db",
            PipelineOptions {
                stencil: StencilBackend::Db,
                ..base
            },
        ),
        (
            "scissor_db",
            PipelineOptions {
                stencil: StencilBackend::Db,
                scissor: true,
                ..base
            },
        ),
    ]
}

fn bench_view(
    c: &mut Criterion,
    group: &str,
    scene: &std::sync::Arc<Scene>,
    camera: &Camera,
    light: Light,
) {
    let mut g = c.benchmark_group(group);
    g.sample_size(10);
    let mut runner = FrameRunner::new(scene.clone());
    for (name, options) in variants() {
        // Warm silhouette cache: a static scene's steady state.
        g.bench_function(format!("frame_{name}"), |b| {
            b.iter(|| {
                runner
                    .frame(0, camera, &[light], RES, &options, false)
                    .expect("frame")
            })
        });
    }
    g.bench_function("frame_bf_cold_silhouettes", |b| {
        b.iter(|| {
            let mut runner = FrameRunner::new(scene.clone());
            runner
                .frame(0, camera, &[light], RES, &variants()[0].1, false)
                .expect("frame")
        })
    });
    g.finish();
}

fn bench_city(c: &mut Criterion) {
    let city = BenchScene::default_city();
    let scene = &city.scene;
    // The default job's first light: 1.5 scene heights above the centre.
    let light = shadowcull::jobs::config::LightSpec::AboveScene(1.5)
        .resolve(&city.loaded, &scene.bounds(), 0, Path::new("<bench>"))
        .expect("light");
    for cam in ["street", "bird"] {
        let camera = city
            .path(cam)
            .at(0)
            .expect("pose")
            .camera(RES.0 as f64 / RES.1 as f64)
            .expect("camera");
        bench_view(c, &format!("city/{cam}"), scene, &camera, light);
    }
}

fn bench_box_city(c: &mut Criterion) {
    let Some(city) = BenchScene::box_city("city_16384") else {
        return;
    };
    let camera = (city.look("street"))
        .camera(RES.0 as f64 / RES.1 as f64)
        .expect("camera");
    let light = city.first_light();
    bench_view(c, "city_16384/street", &city.scene, &camera, light);
    // Every caster's scissor and depth bounds on the bird view (the GPU
    // host's preset computes them each frame).
    let bird = (city.look("bird"))
        .camera(RES.0 as f64 / RES.1 as f64)
        .expect("camera");
    let scene = &city.scene;
    let bounds = scene.bounds();
    let mut g = c.benchmark_group("city_16384/bird");
    g.sample_size(10);
    g.bench_function("volume_bounds_all", |b| {
        b.iter(|| {
            let mut visible = 0usize;
            for o in scene.objects() {
                let v = shadowcull::shadowgen::volume_bounds(
                    &bird,
                    RES,
                    &light,
                    &o.world_bounds,
                    &bounds,
                );
                visible += usize::from(v.scissor[0] < v.scissor[2]);
            }
            visible
        })
    });
    g.finish();
}

criterion_group!(benches, bench_city, bench_box_city);
criterion_main!(benches);
