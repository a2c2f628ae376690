//! The ray-cast reference on named scenes: ids `scene/stage`.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items
//!
//! `cargo bench -p shadowcull-benches --bench reference`. Full resolution belongs here, not in tests.

use criterion::{criterion_group, criterion_main, Criterion};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};
use shadowcull::scene::Light;
use testkit::BenchScene;

fn bench_city(c: &mut Criterion) {
    let city = BenchScene::default_city();
    let scene = &city.scene;
    let street = city.path("street");
    let mut g = c.benchmark_group("city");
    g.sample_size(10);
    g.bench_function("triangle_bvh", |b| b.iter(|| TriangleBvh::new(scene)));
    let bvh = TriangleBvh::new(scene);
    let cam = street.at(0).unwrap().camera(800.0 / 600.0).unwrap();
    let b = scene.bounds();
    let c0 = b.center();
    let point = Light::Point {
        position: glam::DVec3::new(c0.x, b.min.y as f64 + 1.5 * b.size().y as f64, c0.z),
        range: None,
    };
    g.bench_function("reference_800x600_point", |bn| {
        bn.iter(|| {
            reference_mask(
                &bvh,
                &cam,
                &point,
                800,
                600,
                &ReferenceOptions::default(),
                None,
            )
        })
    });
    g.finish();
}

fn bench_box_city(c: &mut Criterion) {
    let Some(city) = BenchScene::box_city("city_4096") else {
        return;
    };
    let cam = city.look("bird").camera(800.0 / 600.0).unwrap();
    let light = city.first_light();
    let bvh = TriangleBvh::new(&city.scene);
    let mut g = c.benchmark_group("box_city_4096");
    g.sample_size(10);
    g.bench_function("reference_800x600_bird", |bn| {
        bn.iter(|| {
            reference_mask(
                &bvh,
                &cam,
                &light,
                800,
                600,
                &ReferenceOptions::default(),
                None,
            )
        })
    });
    g.finish();
}

criterion_group!(benches, bench_city, bench_box_city);
criterion_main!(benches);
