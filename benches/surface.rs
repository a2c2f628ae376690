//! The per-pixel consumers of the eye's visible surface, on the default
//! city (`street`, `bird`) with its first light at 800×600 and 1280×1024:
//! the receiver points the culling light passes mark
//! ([`shadowcull::pipeline::visible_points`], conservative and
//! point-sampled) and the mask assembly ([`shadowcull::mask::assemble`],
//! from a fixed raw stencil). Both walk every pixel of the eye target row
//! by row, by runs of one visible triangle. Ids `res/camera/consumer`:
//! `cargo bench -p shadowcull-benches --bench surface`.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items

use criterion::{criterion_group, criterion_main, Criterion};
use shadowcull::mask::{assemble, View};
use shadowcull::pipeline::{eye_pass, visible_points, MeshCache};
use shadowcull::visibility::Sampling;
use std::hint::black_box;
use std::path::Path;
use testkit::BenchScene;

fn bench_city(c: &mut Criterion) {
    let city = BenchScene::default_city();
    let scene = &city.scene;
    let meshes = MeshCache::new(scene);
    // The default job's first light: 1.5 scene heights above the centre.
    let light = shadowcull::jobs::config::LightSpec::AboveScene(1.5)
        .resolve(&city.loaded, &scene.bounds(), 0, Path::new("<bench>"))
        .expect("light");
    for (w, h) in [(800, 600), (1280, 1024)] {
        for cam in ["street", "bird"] {
            let pose = city.path(cam).at(0).expect("pose");
            let camera = pose.camera(w as f64 / h as f64).expect("camera");
            let eye = eye_pass(scene, &meshes, &camera, w, h).expect("eye pass");
            // A raw stencil with structure: every third pixel of a row run.
            let raw: Vec<bool> = (0..w as usize * h as usize).map(|i| i % 3 == 0).collect();
            let mut g = c.benchmark_group(format!("{w}x{h}/city/{cam}"));
            g.sample_size(30);
            for (name, sampling) in [
                ("points", Sampling::Conservative),
                ("points_point", Sampling::Point),
            ] {
                g.bench_function(name, |b| {
                    b.iter(|| black_box(visible_points(scene, &camera, &eye, sampling)))
                });
            }
            g.bench_function("assemble", |b| {
                b.iter(|| {
                    let view = View {
                        camera: &camera,
                        width: w,
                        height: h,
                    };
                    black_box(assemble(
                        scene,
                        view,
                        &light,
                        eye.surface(),
                        |i| raw[i],
                        false,
                    ))
                })
            });
            g.finish();
        }
    }
}

criterion_group!(benches, bench_city);
criterion_main!(benches);
