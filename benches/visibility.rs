//! The whole frame with and without occlusion culling [Steiner ch. 5]: the
//! eye pass (PSR), the light pass (PSC), silhouettes, volumes and the stencil
//! through [`FrameRunner`], per culling mode (`none`, `exact`, `chc`, `chcpp`). Each
//! mode has one runner kept across the iterations, so its culling history,
//! silhouette caches and buffers are warm: a static camera in a running
//! application. Ids `scene/camera/frame_<culling>`.
//!
//! Scenes: the default city (`street`, `bird`: the first pose of each path) at
//! 800×600 with the default job's lights (a point light 1.5 scene heights above
//! the centre, `LightSpec::AboveScene(1.5)`, and the sun at 35° elevation) and
//! box-city `city_16384` `street` at 1280×1024 with its light (skipped with a
//! note when `../shared` is absent). Pipeline as the default job (`stencil: h`),
//! no reference.
//!
//! Before timing, each configuration prints its steady-state counters (the
//! second frame of a fresh runner) to stderr: PSR, per light PSC, volume
//! triangles, pixels processed, queries (eye + that light's) and waits, and the
//! eye, light-pass and stencil times. `cargo bench -p shadowcull-benches --bench visibility`.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use shadowcull::jobs::config::default_job;
use shadowcull::jobs::frame::{FrameRunner, LightFrame};
use shadowcull::pipeline::{CullingSpec, PipelineOptions};
use shadowcull::scene::{Camera, Light, Scene};
use std::path::Path;
use std::time::Duration;
use testkit::BenchScene;

/// The culling modes compared; one more is one more row.
const MODES: &[(&str, CullingSpec)] = &[
    ("none", CullingSpec::None),
    ("exact", CullingSpec::Exact),
    ("chc", CullingSpec::Chc),
    ("chcpp", CullingSpec::Chcpp),
];

fn options(culling: CullingSpec) -> PipelineOptions {
    PipelineOptions {
        culling,
        reference_every: 0,
        ..default_job().pipeline
    }
}

/// Per light: `f` of each light's result, as `[a, b]`.
fn per_light<T: std::fmt::Display>(out: &[LightFrame], f: impl Fn(&LightFrame) -> T) -> String {
    let v: Vec<String> = out.iter().map(|l| f(l).to_string()).collect();
    format!("[{}]", v.join(", "))
}

fn print_counters(id: &str, out: &[LightFrame]) {
    let s = &out[0].row.shadow;
    eprintln!(
        "{id}: psr {}, psc {}, volume_triangles {}, pixels_processed {}, queries {}, \
         waits {}, eye_ms {:.2}, light_ms {}, stencil_ms {}",
        s.psr,
        per_light(out, |l| l.row.shadow.psc),
        per_light(out, |l| l.row.shadow.volume_triangles),
        per_light(out, |l| l.row.shadow.stencil.pixels_processed),
        per_light(out, |l| l.row.shadow.queries),
        per_light(out, |l| l.row.shadow.waits),
        s.eye_ms,
        per_light(out, |l| format!("{:.2}", l.row.shadow.light_ms)),
        per_light(out, |l| format!("{:.2}", l.row.shadow.stencil_ms)),
    );
}

fn bench_view(
    c: &mut Criterion,
    group: &str,
    scene: &std::sync::Arc<Scene>,
    camera: &Camera,
    lights: &[Light],
    res: (u32, u32),
) {
    let mut g = c.benchmark_group(group);
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for &(name, culling) in MODES {
        let options = options(culling);
        let mut runner = FrameRunner::new(scene.clone());
        let mut frame = |f: u32| {
            runner
                .frame(f, camera, lights, res, &options, false)
                .expect("frame")
        };
        // A cold first frame, then the steady state whose counters we print.
        frame(0);
        print_counters(&format!("{group}/frame_{name}"), &frame(1));
        g.bench_function(format!("frame_{name}"), |b| b.iter(|| frame(2)));
    }
    g.finish();
}

fn bench_city(c: &mut Criterion) {
    let job = default_job();
    let city = BenchScene::default_city();
    let scene = &city.scene;
    let lights: Vec<Light> = job
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| {
            l.resolve(&city.loaded, &scene.bounds(), i, Path::new("<bench>"))
                .expect("light")
        })
        .collect();
    let res = job.resolution;
    for cam in ["street", "bird"] {
        let camera = city
            .path(cam)
            .at(0)
            .expect("pose")
            .camera(res.0 as f64 / res.1 as f64)
            .expect("camera");
        bench_view(c, &format!("city/{cam}"), scene, &camera, &lights, res);
    }
}

fn bench_box_city(c: &mut Criterion) {
    let Some(city) = BenchScene::box_city("city_16384") else {
        return;
    };
    let res = (1280, 1024);
    let camera = (city.look("street"))
        .camera(res.0 as f64 / res.1 as f64)
        .expect("camera");
    let light = city.first_light();
    bench_view(c, "city_16384/street", &city.scene, &camera, &[light], res);
}

criterion_group!(benches, bench_city, bench_box_city);
criterion_main!(benches);
