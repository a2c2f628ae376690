//! Culling traversals on a procedural city along its street path: the depth
//! and primitive ids rendered with occlusion culling equal the unculled ones
//! bit for bit (threshold 0), and CHC issues fewer queries than stop-and-wait
//! over coherent frames.

use glam::DMat4;
use raster::{DepthTarget, Latency, OcclusionBackend, SimulatedBackend, SyncBackend, TileSize};
use scene::procedural::city::{city, CityParams};
use scene::{Camera, Scene};
use visibility::{CullResult, Culling, Hierarchy, MeshData, ViewCuller, ViewSetup};

const W: u32 = 160;
const H: u32 = 120;

fn target() -> DepthTarget {
    DepthTarget::new(W, H, TileSize::T8, true).unwrap()
}

/// One pixel's depth and primitive id.
type Pixel = (Option<f32>, Option<(u32, u32)>);

/// Depth and ids of a backend's target, row-major.
fn image(b: &mut dyn OcclusionBackend) -> Vec<Pixel> {
    let mut out = Vec::new();
    b.read_target(&mut |t: &DepthTarget| {
        for y in 0..H {
            for x in 0..W {
                out.push((t.depth_at(x, y), t.id_at(x, y)));
            }
        }
    });
    out
}

fn run(
    culler: &mut ViewCuller,
    h: &Hierarchy,
    scene: &Scene,
    meshes: &MeshData,
    cam: &Camera,
    culling: Culling,
    backend: &mut dyn OcclusionBackend,
) -> CullResult {
    let clip = |w: &DMat4| scene::transform::clip_from_local(cam, w);
    let view = ViewSetup::eye(cam, &clip, 0);
    culler
        .cull(h, scene, meshes, &view, culling, backend)
        .unwrap()
}

#[test]
fn culled_eye_pass_equals_unculled_and_chc_saves_queries() {
    let loaded = city(&CityParams {
        blocks_x: 6,
        blocks_z: 6,
        ..Default::default()
    })
    .unwrap();
    let path = loaded
        .paths
        .iter()
        .find(|(n, _)| n == "street")
        .unwrap()
        .1
        .clone();
    let scene = Scene::new(loaded.graph).unwrap();
    let h = Hierarchy::from_scene(&scene);
    let meshes = MeshData::from_scene(&scene);
    let mut cullers: Vec<ViewCuller> = (0..4).map(|_| ViewCuller::new()).collect();
    let mut backends: Vec<Box<dyn OcclusionBackend>> = vec![
        Box::new(SyncBackend::new(target())),
        Box::new(SyncBackend::new(target())),
        Box::new(SyncBackend::new(target())),
        Box::new(SimulatedBackend::new(target(), Latency::Commands(8))),
    ];
    let kinds = [Culling::None, Culling::Exact, Culling::Chc, Culling::Chc];
    let mut queries = [0u64; 4];
    let mut rendered = [0u64; 4];
    let frames = 30;
    for f in 0..frames {
        let cam = path
            .at(f)
            .unwrap()
            .camera(f64::from(W) / f64::from(H))
            .unwrap();
        let mut images = Vec::new();
        for k in 0..4 {
            let r = run(
                &mut cullers[k],
                &h,
                &scene,
                &meshes,
                &cam,
                kinds[k],
                backends[k].as_mut(),
            );
            queries[k] += r.stats.queries;
            rendered[k] += r.stats.objects_rendered;
            images.push(image(backends[k].as_mut()));
        }
        for k in 1..4 {
            let diff = images[0]
                .iter()
                .zip(&images[k])
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(diff, 0, "frame {f}: {:?} differs from no culling", kinds[k]);
        }
    }
    println!("queries none/exact/chc/chc-latency {queries:?}, rendered {rendered:?}");
    assert!(
        rendered[1] < rendered[0] / 2,
        "occlusion culling culls: {rendered:?}"
    );
    assert!(
        queries[2] < queries[1],
        "CHC issues fewer queries: {queries:?}"
    );
    // CHC renders a superset of the exact visible set.
    assert!(rendered[2] >= rendered[1]);
}

/// Frustum culling renders only objects whose boxes meet the view, and the
/// image is unchanged.
#[test]
fn frustum_culling_keeps_the_image() {
    let loaded = city(&CityParams {
        blocks_x: 4,
        blocks_z: 4,
        ..Default::default()
    })
    .unwrap();
    let pose = loaded
        .paths
        .iter()
        .find(|(n, _)| n == "bird")
        .unwrap()
        .1
        .at(0)
        .unwrap();
    let cam = pose.camera(f64::from(W) / f64::from(H)).unwrap();
    let scene = Scene::new(loaded.graph).unwrap();
    let h = Hierarchy::from_scene(&scene);
    let meshes = MeshData::from_scene(&scene);
    let mut a = SyncBackend::new(target());
    let mut b = SyncBackend::new(target());
    let none = run(
        &mut ViewCuller::new(),
        &h,
        &scene,
        &meshes,
        &cam,
        Culling::None,
        &mut a,
    );
    let fr = run(
        &mut ViewCuller::new(),
        &h,
        &scene,
        &meshes,
        &cam,
        Culling::Frustum,
        &mut b,
    );
    assert_eq!(none.rendered.len(), scene.objects().len());
    assert!(fr.rendered.len() <= none.rendered.len());
    assert_eq!(image(&mut a), image(&mut b));
}
