//! The stencil shadow pipeline per stage and stencil variant: ids
//! `scene/camera/stage`. The BF and DB columns of [Aila04 Table 1] for our
//! scenes: `cargo bench --bench shadow`; the counters (volume triangles,
//! pixels processed) come from `shadow_bench`, which prints them.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use scene::procedural::city::{city, CityParams};
use scene::{Camera, Light, Scene};
use shadowcull::frame::FrameRunner;
use shadowcull::pipeline::{PipelineOptions, StencilBackend};
use std::path::Path;

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
    let loaded = city(&CityParams::default()).expect("default city");
    let scene = std::sync::Arc::new(Scene::new(loaded.graph.clone()).expect("flatten"));
    // The default job's first light: 1.5 scene heights above the centre.
    let light = shadowcull::config::LightSpec::AboveScene(1.5)
        .resolve(&loaded, &scene.bounds(), 0, std::path::Path::new("<bench>"))
        .expect("light");
    for cam in ["street", "bird"] {
        let path = &loaded.paths.iter().find(|(n, _)| n == cam).expect(cam).1;
        let camera = path
            .at(0)
            .expect("pose")
            .camera(RES.0 as f64 / RES.1 as f64)
            .expect("camera");
        bench_view(c, &format!("city/{cam}"), &scene, &camera, light);
    }
}

fn bench_box_city(c: &mut Criterion) {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/bench/city_16384.txt");
    if !file.exists() {
        println!("note: {} is absent; skipping city_16384", file.display());
        return;
    }
    let loaded = scene::load::box_city::load_box_city(&file).expect("box city");
    let camera = loaded
        .cameras
        .iter()
        .find(|(n, _)| n == "street")
        .expect("street")
        .1
        .camera(RES.0 as f64 / RES.1 as f64)
        .expect("camera");
    let light = loaded.lights[0].1;
    let scene = std::sync::Arc::new(Scene::new(loaded.graph).expect("flatten"));
    bench_view(c, "city_16384/street", &scene, &camera, light);
}

criterion_group!(benches, bench_city, bench_box_city);
criterion_main!(benches);
