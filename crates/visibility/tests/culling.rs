//! Culling traversals on a procedural city along its street path: the depth
//! and primitive ids rendered with occlusion culling equal the unculled ones
//! bit for bit (threshold 0), CHC issues fewer queries than stop-and-wait
//! over coherent frames, and CHC++ fewer than CHC, with fewer waits under a
//! simulated query latency.

use glam::DMat4;
use raster::{
    DepthTarget, Latency, OcclusionBackend, ReadTarget, SimulatedBackend, SyncBackend, TileSize,
};
use scene::{Camera, Scene};
use visibility::{
    ChcppOptions, CullResult, Culling, Hierarchy, MeshData, Objects, ViewCuller, ViewSetup,
};

const W: u32 = 160;
const H: u32 = 120;

fn target() -> DepthTarget {
    DepthTarget::new(W, H, TileSize::T8, true).unwrap()
}

/// One pixel's depth and primitive id.
type Pixel = (Option<f32>, Option<(u32, u32)>);

/// A bundled backend: queries, and a target to read back.
trait Backend: OcclusionBackend + ReadTarget {}
impl<T: OcclusionBackend + ReadTarget> Backend for T {}

/// Depth and ids of a backend's target, row-major.
fn image(b: &mut dyn ReadTarget) -> Vec<Pixel> {
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
        .cull(Objects::new(h, scene, meshes), &view, culling, backend)
        .unwrap()
}

#[test]
fn culled_eye_pass_equals_unculled_and_chc_saves_queries() {
    let (scene, path) = testkit::street_city(6);
    let h = Hierarchy::from_scene(&scene);
    let meshes = MeshData::from_scene(&scene);
    // Query results arrive K commands after their query in the latency runs.
    const K: u32 = 8;
    let chcpp = Culling::ChcPlusPlus(ChcppOptions::default());
    // (traversal, simulated latency)
    let kinds = [
        (Culling::None, None),
        (Culling::Exact, None),
        (Culling::Chc, None),
        (Culling::Chc, Some(K)),
        (chcpp, None),
        (chcpp, Some(K)),
        (Culling::Exact, Some(K)),
    ];
    const N: usize = 7;
    let mut cullers: Vec<ViewCuller> = (0..N).map(|_| ViewCuller::new()).collect();
    let mut backends: Vec<Box<dyn Backend>> = kinds
        .iter()
        .map(|&(_, lat)| -> Box<dyn Backend> {
            match lat {
                None => Box::new(SyncBackend::new(target())),
                Some(k) => Box::new(SimulatedBackend::new(target(), Latency::Commands(k))),
            }
        })
        .collect();
    let frames = 30;
    let mut queries = [0u64; N];
    let mut waits = [0u64; N];
    let mut rendered = [0u64; N];
    let mut per_frame: Vec<Vec<u64>> = vec![Vec::new(); N];
    for f in 0..frames {
        let cam = path
            .at(f)
            .unwrap()
            .camera(f64::from(W) / f64::from(H))
            .unwrap();
        let mut images = Vec::new();
        for k in 0..N {
            let r = run(
                &mut cullers[k],
                &h,
                &scene,
                &meshes,
                &cam,
                kinds[k].0,
                backends[k].as_mut(),
            );
            queries[k] += r.stats.queries;
            waits[k] += r.stats.waits;
            rendered[k] += r.stats.objects_rendered;
            per_frame[k].push(r.stats.queries);
            images.push(image(backends[k].as_mut()));
        }
        for k in 1..N {
            let diff = images[0]
                .iter()
                .zip(&images[k])
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(diff, 0, "frame {f}: {:?} differs from no culling", kinds[k]);
        }
    }
    let medians: Vec<u64> = (per_frame.iter())
        .map(|v| testkit::median(v).unwrap())
        .collect();
    println!(
        "{:?}\nqueries {queries:?}\nmedian queries per frame {medians:?}\n\
         waits {waits:?}\nrendered {rendered:?}",
        kinds.map(|k| k.0)
    );
    assert!(
        rendered[1] < rendered[0] / 2,
        "occlusion culling culls: {rendered:?}"
    );
    assert!(
        queries[2] < queries[1] && medians[2] < medians[1],
        "CHC issues fewer queries than stop-and-wait: {queries:?} {medians:?}"
    );
    assert!(
        queries[4] < queries[2] && medians[4] < medians[2],
        "CHC++ issues fewer queries than CHC: {queries:?} {medians:?}"
    );
    // Under latency K, stop-and-wait waits for every query; CHC and CHC++
    // only when they run out of work (CHC++'s batch of previously invisible
    // nodes goes out when the traversal ends, so its count is about CHC's);
    // without latency neither ever waits.
    assert_eq!(waits[6], queries[6]);
    assert!(
        waits[3] * 20 < waits[6] && waits[5] * 20 < waits[6],
        "waits under latency {K}: {waits:?}"
    );
    assert_eq!(waits[4], 0, "{waits:?}");
    // The coherent traversals render supersets of the exact visible set.
    assert!(rendered[2] >= rendered[1] && rendered[4] >= rendered[1]);
}

/// Frustum culling renders only objects whose boxes meet the view, and the
/// image is unchanged.
#[test]
fn frustum_culling_keeps_the_image() {
    let city = testkit::BenchScene::city_blocks(4);
    let pose = city.path("bird").at(0).unwrap();
    let cam = pose.camera(f64::from(W) / f64::from(H)).unwrap();
    let scene = city.scene.clone();
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
