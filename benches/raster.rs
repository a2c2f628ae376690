//! The tile rasterizer on the procedural city (default size): ids `city/stage`.
#![allow(missing_docs)] // criterion_group!/criterion_main! generate undocumented items
//!
//! `cargo bench -p shadowcull-benches --bench raster`. From the `street` and `bird` cameras at 800×600 and
//! 1920×1080: depth rasterization of all objects front to back, then one AABB query
//! per object against the result.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{DMat4, Mat4, Vec3, Vec4};
use shadowcull::raster::{Coverage, DepthTarget, DrawItem, QueryMode, QueryOptions, TileSize};
use testkit::BenchScene;

struct Frame {
    clip_from_world: Mat4,
    /// (clip_from_local, mesh index, object id), front to back.
    draws: Vec<(Mat4, usize, u32)>,
    /// World bounds, front to back.
    boxes: Vec<(Vec3, Vec3)>,
}

fn bench_city(c: &mut Criterion) {
    let city = BenchScene::default_city();
    let scene = &city.scene;
    let meshes: Vec<(Vec<Vec4>, Vec<[u32; 3]>)> = scene
        .graph()
        .meshes()
        .iter()
        .map(|m| {
            (
                m.positions().iter().map(|p| p.extend(1.0)).collect(),
                m.triangles().to_vec(),
            )
        })
        .collect();
    let mut g = c.benchmark_group("city");
    g.sample_size(10);
    for name in ["street", "bird"] {
        let look = city.look(name);
        for (w, h) in [(800u32, 600u32), (1920, 1080)] {
            let cam = look.camera(w as f64 / h as f64).expect("camera");
            let mut order: Vec<usize> = (0..scene.objects().len()).collect();
            let dist = |i: usize| {
                let b = scene.objects()[i].world_bounds;
                ((b.min + b.max).as_dvec3() * 0.5 - cam.position).length_squared()
            };
            order.sort_by(|&a, &b| dist(a).total_cmp(&dist(b)));
            let frame = Frame {
                clip_from_world: shadowcull::scene::transform::clip_from_local(
                    &cam,
                    &DMat4::IDENTITY,
                ),
                draws: order
                    .iter()
                    .map(|&i| {
                        let o = &scene.objects()[i];
                        (
                            shadowcull::scene::transform::clip_from_local(
                                &cam,
                                &o.world_from_local,
                            ),
                            o.mesh.index(),
                            i as u32,
                        )
                    })
                    .collect(),
                boxes: order
                    .iter()
                    .map(|&i| {
                        let b = scene.objects()[i].world_bounds;
                        (b.min, b.max)
                    })
                    .collect(),
            };
            let items: Vec<DrawItem> = frame
                .draws
                .iter()
                .map(|&(m, mesh, id)| DrawItem {
                    clip_from_local: m,
                    positions: &meshes[mesh].0,
                    triangles: &meshes[mesh].1,
                    object: id,
                    cull: shadowcull::raster::CullMode::None,
                })
                .collect();
            let mut target = DepthTarget::new(w, h, TileSize::T8, false).expect("target");
            g.bench_function(format!("raster_occluders_{name}_{w}x{h}"), |b| {
                b.iter(|| {
                    target.clear();
                    target.draw_batch(&items, Coverage::Standard).expect("draw");
                })
            });
            let opts = QueryOptions {
                coverage: Coverage::Standard,
                mode: QueryMode::Any,
            };
            let mut out = Vec::new();
            g.bench_function(format!("raster_queries_{name}_{w}x{h}"), |b| {
                b.iter(|| {
                    target
                        .query_aabbs(frame.clip_from_world, &frame.boxes, &opts, None, &mut out)
                        .expect("query")
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench_city);
criterion_main!(benches);
