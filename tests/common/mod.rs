//! Helpers shared by the facade's integration-test binaries.

use glam::{DVec3, Vec3};
use scene::procedural::analytic;
use scene::procedural::city::{city, CityParams};
use scene::{Camera, CameraPath, Light, Mesh, Scene, SceneGraph, Transform};

/// A scene of one root node with `root`'s transform drawing every mesh once.
pub fn scene_of(meshes: Vec<Mesh>, root: Transform) -> Scene {
    let mut g = SceneGraph::new();
    let ids: Vec<_> = meshes.into_iter().map(|m| g.add_mesh(m)).collect();
    g.add_root(scene::Node {
        name: "root".into(),
        transform: root,
        meshes: ids,
        children: vec![],
    });
    Scene::new(g).unwrap()
}

/// The ground, a tower, a slab and an open awning: the stencil tests' scene.
#[allow(dead_code)] // not every test binary uses it
pub fn boxes_on_ground(root: Transform) -> Scene {
    scene_of(
        vec![
            analytic::horizontal_quad("ground", [-10.0, 10.0], [-10.0, 10.0], 0.0, true).unwrap(),
            analytic::box_mesh(
                "tower",
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 3.0, 1.0),
            )
            .unwrap(),
            analytic::box_mesh("slab", Vec3::new(2.0, 1.0, 2.0), Vec3::new(3.0, 1.5, 4.0)).unwrap(),
            analytic::horizontal_quad("awning", [-4.0, -2.0], [1.0, 3.0], 2.0, true).unwrap(),
        ],
        root,
    )
}

/// The view of [`boxes_on_ground`] from above and in front (4:3, fov_y 50°).
#[allow(dead_code)] // not every test binary uses it
pub fn overview_camera() -> Camera {
    Camera::look_at(
        DVec3::new(2.0, 9.0, 12.0),
        DVec3::ZERO,
        DVec3::Y,
        50f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap()
}

/// What [`check_hierarchical`] found for one view.
#[allow(dead_code)] // not every test binary uses it
#[derive(Debug, Default, Clone, Copy)]
pub struct HierarchyCheck {
    /// Pixels where the FS bit changed the wide-counter mask (each proven to
    /// have a volume with a negative count).
    pub fs_wide_differences: u64,
    /// Pixels where FS with 8-bit counters differs from 8-bit brute force (each
    /// proven: wide count a non-zero multiple of 256, or a negative volume count).
    pub fs_eight_differences: u64,
    /// Boundary tiles summed over the FS-off runs (to show the check saw work).
    pub boundary_tiles: u64,
    /// Brute-force fragments processed.
    pub brute_fragments: u64,
}

/// The hierarchical stencil against brute force on one view, with the same
/// volumes, eye depth and tests (scissor and depth bounds off):
///
/// - wide counters without the FS bit: equal values at every written pixel,
///   for every tile size in `tiles`; 8-bit counters without FS likewise;
/// - FS on (tile 8), wide: every pixel whose mask differs has some volume
///   whose own count there is negative;
/// - FS on, 8-bit against 8-bit brute force: every differing pixel has a wide
///   count that is a non-zero multiple of 256, or a negative volume count.
///
/// Returns the counts and the differing pixels (for the caller's reference check).
#[allow(dead_code)] // not every test binary uses it
pub fn check_hierarchical(
    scene: &Scene,
    cam: &Camera,
    light: &scene::Light,
    eye: &raster::DepthTarget,
    method: shadowgen::MethodChoice,
    two_sided: bool,
    tiles: &[raster::TileSize],
) -> Result<(HierarchyCheck, Vec<usize>), String> {
    use raster::{
        HierarchicalOptions, HierarchicalStencil, StencilBits, StencilStats, StencilTarget,
        StencilTests, TileSize, VolumeBuffer,
    };
    let (w, h) = (eye.width(), eye.height());
    let mut buf = VolumeBuffer::new();
    let casters: Vec<scene::ObjectId> = (0..scene.objects().len() as u32)
        .map(scene::ObjectId)
        .collect();
    let options = shadowgen::BuildOptions {
        method,
        two_sided,
        ..Default::default()
    };
    let mut cache = shadowgen::SilhouetteCache::default();
    shadowgen::build_volumes(&mut buf, scene, cam, light, &casters, options, &mut cache)
        .map_err(|e| e.to_string())?;
    let clip: Vec<glam::Mat4> = buf
        .ranges
        .iter()
        .map(|r| scene::transform::clip_from_local(cam, &r.world_from_local))
        .collect();
    let ranges: Vec<_> = clip.iter().copied().zip(&buf.ranges).collect();
    let tests = StencilTests::default();
    let brute = |bits| {
        let mut s = StencilTarget::new(w, h, bits).unwrap();
        let mut st = StencilStats::default();
        s.draw_volumes(eye, &ranges, &buf, tests, &mut st).unwrap();
        (s, st)
    };
    let hier = |tile, bits, full_shadow| {
        let o = HierarchicalOptions {
            tile,
            bits,
            full_shadow,
        };
        let mut s = HierarchicalStencil::new(w, h, o).unwrap();
        let mut st = StencilStats::default();
        s.draw_volumes(eye, &ranges, &buf, tests, &mut st).unwrap();
        (s, st)
    };
    let mask = |f: &dyn Fn(u32, u32) -> bool| -> Vec<bool> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| eye.depth_at(x, y).is_some() && f(x, y))
            .collect()
    };
    let mut out = HierarchyCheck::default();
    let (bw, bst) = brute(StencilBits::Wide);
    let (b8, _) = brute(StencilBits::Eight);
    out.brute_fragments = bst.pixels_processed;
    for &tile in tiles {
        for (bits, bf) in [(StencilBits::Wide, &bw), (StencilBits::Eight, &b8)] {
            let (hs, st) = hier(tile, bits, false);
            out.boundary_tiles += st.tiles_boundary;
            for y in 0..h {
                for x in 0..w {
                    if eye.depth_at(x, y).is_some() && hs.value(x, y) != bf.value(x, y) {
                        return Err(format!(
                            "{tile:?} {bits:?} FS off: pixel ({x}, {y}) hierarchical {} brute force {}",
                            hs.value(x, y),
                            bf.value(x, y)
                        ));
                    }
                }
            }
        }
    }
    // FS on: differences need a reason.
    let singles = std::cell::OnceCell::new();
    let negative = |x: u32, y: u32| {
        let singles: &Vec<StencilTarget> = singles.get_or_init(|| {
            ranges
                .iter()
                .map(|&(m, r)| {
                    let mut s = StencilTarget::new(w, h, StencilBits::Wide).unwrap();
                    s.draw_volume(eye, m, &buf, r, tests, &mut StencilStats::default())
                        .unwrap();
                    s
                })
                .collect()
        });
        singles.iter().any(|s| s.value(x, y) < 0)
    };
    let mut differing = Vec::new();
    let (hw, _) = hier(TileSize::T8, StencilBits::Wide, true);
    let (a, b) = (
        mask(&|x, y| hw.nonzero(x, y)),
        mask(&|x, y| bw.nonzero(x, y)),
    );
    for i in (0..a.len()).filter(|&i| a[i] != b[i]) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        if !(a[i] && negative(x, y)) {
            return Err(format!(
                "FS wide: pixel ({x}, {y}) differs without a negative volume count"
            ));
        }
        out.fs_wide_differences += 1;
        differing.push(i);
    }
    let (h8, _) = hier(TileSize::T8, StencilBits::Eight, true);
    let (a, b) = (
        mask(&|x, y| h8.nonzero(x, y)),
        mask(&|x, y| b8.nonzero(x, y)),
    );
    for i in (0..a.len()).filter(|&i| a[i] != b[i]) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let wide = bw.value(x, y);
        let wraps = wide != 0 && wide % 256 == 0;
        if !(a[i] && (wraps || negative(x, y))) {
            return Err(format!(
                "FS 8-bit: pixel ({x}, {y}) differs (wide count {wide}) without a reason"
            ));
        }
        out.fs_eight_differences += 1;
        if !differing.contains(&i) {
            differing.push(i);
        }
    }
    Ok((out, differing))
}

/// The culling tests' procedural city (6×6 blocks: the default 20×20 city's
/// unculled runs would take minutes in the test profile) and its `street`
/// camera path.
#[allow(dead_code)] // not every test binary uses it
pub fn street_city() -> (std::sync::Arc<Scene>, CameraPath) {
    city_with_street(6)
}

/// The procedural city of `blocks × blocks` blocks and its `street` camera path.
#[allow(dead_code)] // not every test binary uses it
pub fn city_with_street(blocks: u32) -> (std::sync::Arc<Scene>, CameraPath) {
    let loaded = city(&CityParams {
        blocks_x: blocks,
        blocks_z: blocks,
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
    (std::sync::Arc::new(Scene::new(loaded.graph).unwrap()), path)
}

/// The culling tests' lights for a city: a point light 1.5 scene heights
/// above its centre and a sun.
#[allow(dead_code)] // not every test binary uses it
pub fn city_lights(scene: &Scene) -> [Light; 2] {
    let b = scene.bounds();
    let c = b.center();
    [
        Light::Point {
            position: DVec3::new(c.x, f64::from(b.max.y) * 1.5, c.z),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(0.4, -0.8, 0.3),
        },
    ]
}
