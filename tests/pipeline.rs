//! `shadowcull::Pipeline` end to end, as a host drives it: one call per
//! frame, outputs read from the borrowed `FrameOutput`; masks checked
//! against the ray-cast reference and against the unculled pipeline.

use glam::DVec3;
use scene::{Camera, CameraPath, Light, ObjectFlags, ObjectId, Scene};
use shadowcull::mask::compare;
use shadowcull::{
    CullingSpec, Error, FrameInput, HostDepth, LightId, OccludersSpec, Pipeline, PipelineOptions,
    Result, StencilBackend,
};
use std::sync::Arc;

const W: u32 = 160;
const H: u32 = 120;

fn city() -> (Arc<Scene>, CameraPath) {
    testkit::street_city(3)
}

/// The city's point light and sun, and a spot light over the street the
/// camera looks down at its first frame.
fn lights(scene: &Scene, path: &CameraPath) -> Vec<Light> {
    let b = scene.bounds();
    let pose = path.at(0).unwrap();
    let ahead = pose.eye + (pose.target - pose.eye).normalize() * 15.0;
    let mut l = crate::common::city_lights(scene).to_vec();
    l.push(Light::Spot {
        position: DVec3::new(ahead.x + 3.0, f64::from(b.max.y) * 1.2, ahead.z - 2.0),
        direction: DVec3::new(-0.1, -1.0, 0.1),
        apex_angle: 100f64.to_radians(),
        range: None,
    });
    l
}

fn camera(path: &CameraPath, frame: u32) -> Camera {
    path.at(frame)
        .unwrap()
        .camera(f64::from(W) / f64::from(H))
        .unwrap()
}

/// A pipeline over `scene` with `options` and `lights` added (ids in order).
fn pipeline(
    scene: &Arc<Scene>,
    options: PipelineOptions,
    lights: &[Light],
) -> Result<(Pipeline, Vec<LightId>)> {
    let mut p = Pipeline::new(scene.clone(), options)?;
    let ids = lights
        .iter()
        .map(|l| p.add_light(*l))
        .collect::<Result<_>>()?;
    Ok((p, ids))
}

fn input(path: &CameraPath, frame: u32) -> FrameInput {
    FrameInput::new(W, H, camera(path, frame))
}

fn options(culling: CullingSpec, stencil: StencilBackend) -> PipelineOptions {
    PipelineOptions {
        culling,
        stencil,
        light_resolution: 256,
        ..Default::default()
    }
}

/// Conservative CHC++ in the pipeline changes no pixel of the unculled mask
/// (with a crowded light view culled as its quadrants, `view_split.rs`),
/// and both match the reference; PSR and PSC are subsets of the scene and the
/// volumes name exactly the PSC.
#[test]
fn culled_frames_equal_unculled_frames_and_the_reference() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let (mut culled, culled_ids) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &lights,
    )?;
    let (mut plain, _) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::H),
        &lights,
    )?;
    let n = scene.objects().len();
    let (mut culled_some, mut split) = (false, false);
    for frame in [0, 2, 4, 6] {
        let input = input(&path, frame);
        let masks: Vec<_> = {
            let out = culled.frame(&input)?;
            assert_eq!(out.light_count(), lights.len());
            assert!(out.psr().windows(2).all(|w| w[0] < w[1]), "PSR ascending");
            assert!(out.psr().len() <= n && !out.psr().is_empty());
            culled_some |= out.psr().len() < n;
            for l in out.lights() {
                let psc = l.psc();
                assert!(psc.windows(2).all(|w| w[0] < w[1]), "PSC ascending");
                let named: Vec<ObjectId> = l
                    .volumes()
                    .ranges
                    .iter()
                    .map(|r| ObjectId::from_bits(r.object))
                    .collect();
                assert_eq!(named, psc, "one volume range per caster, in PSC order");
                assert_eq!(l.stats().psc as usize, psc.len());
                assert!(!l.views().is_empty(), "culled lights report their views");
                // Fitted views at 256², a crowded one as four quadrants of 128².
                let quadrants = l.views().iter().filter(|v| v.resolution == 128).count();
                assert!(l.views().iter().all(|v| [256, 128].contains(&v.resolution)));
                assert_eq!(quadrants % 4, 0, "quadrants come in fours");
                split |= quadrants > 0;
            }
            let s = out.stats();
            assert!(s.frame_ms >= s.eye_ms && s.eye_ms > 0.0);
            assert_eq!(s.psr as usize, out.psr().len());
            out.lights().map(|l| l.mask().unwrap().clone()).collect()
        };
        let out = plain.frame(&input)?;
        assert_eq!(out.psr().len(), n);
        for (li, (m, l)) in masks.iter().zip(out.lights()).enumerate() {
            assert_eq!(l.psc().len(), n);
            assert!(l.views().is_empty());
            assert_eq!(
                m,
                l.mask().unwrap(),
                "frame {frame} light {li}: culled = unculled"
            );
        }
        for (li, m) in masks.iter().enumerate() {
            let r = culled.reference_mask(culled_ids[li])?;
            let c = compare(&r.mask, &r.ambiguous, m);
            assert!(c.compared > 500, "frame {frame} light {li}: {c:?}");
            assert_eq!(c.mismatches, 0, "frame {frame} light {li}: {c:?}");
        }
    }
    assert!(culled_some, "the street path culls objects");
    assert!(
        split,
        "a crowded light view (the sun's one) is culled as quadrants"
    );
    Ok(())
}

/// `stencil: none` (a GPU host): the same PSR, PSC and volumes as with the
/// CPU stencil, and no mask.
#[test]
fn volumes_only_pipeline_gives_the_same_volumes_and_no_mask() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let (mut gpu, _) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::None),
        &lights,
    )?;
    let (mut cpu, _) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &lights,
    )?;
    for frame in 0..3 {
        let input = input(&path, frame);
        let a = gpu.frame(&input)?;
        let b = cpu.frame(&input)?;
        assert_eq!(a.psr(), b.psr());
        for (x, y) in a.lights().zip(b.lights()) {
            assert!(x.mask().is_none() && x.shadow().is_none());
            assert!(y.mask().is_some());
            assert_eq!(x.psc(), y.psc());
            let (u, v) = (x.volumes(), y.volumes());
            assert_eq!(u.positions, v.positions);
            assert_eq!(u.indices, v.indices);
            assert_eq!(u.ranges, v.ranges);
            assert_eq!(x.stats().volume_triangles as usize, u.triangle_count());
            assert_eq!(x.stats().stencil.pixels_processed, 0);
        }
    }
    Ok(())
}

/// With no culling and no CPU stencil nobody reads an eye pass, so none
/// runs: the PSR is every visible object, the volumes are those of a
/// pipeline that ran one, and `exact_eye` and the reference rasterize it on
/// demand, equal to that pipeline's.
#[test]
fn no_culling_and_no_stencil_run_no_eye_pass() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let (mut bare, ids) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::None),
        &lights,
    )?;
    let (mut cpu, _) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::Bf),
        &lights,
    )?;
    let input = input(&path, 0);
    let a = bare.frame(&input)?;
    assert!(a.eye().is_none());
    let visible = scene.objects().iter().filter(|o| o.flags.visible).count();
    assert_eq!(a.psr().len(), visible);
    let a_lights: Vec<_> = a
        .lights()
        .map(|l| (l.psc().to_vec(), l.volumes().clone()))
        .collect();
    let b = cpu.frame(&input)?;
    assert_eq!(a_lights.len(), b.light_count());
    for ((psc, volumes), y) in a_lights.iter().zip(b.lights()) {
        assert_eq!(psc.as_slice(), y.psc());
        assert_eq!(volumes.indices, y.volumes().indices);
        assert_eq!(volumes.ranges, y.volumes().ranges);
    }
    let want = b
        .eye()
        .expect("a CPU stencil reads the eye")
        .target
        .depth_rows();
    assert_eq!(bare.exact_eye()?.target.depth_rows(), want);
    let (r, s) = (bare.reference_mask(ids[0])?, cpu.reference_mask(ids[0])?);
    assert_eq!((r.mask, r.primitive), (s.mask, s.primitive));
    // The next frame drops it again.
    assert!(bare.frame(&input)?.eye().is_none());
    Ok(())
}

/// `culling: auto` with no CPU stencil runs an eye pass only on the frames
/// where a light culls (it reads the eye's receivers); on the others the PSR
/// is every visible object, no eye target is kept, and the volumes still
/// give the exact mask.
#[test]
fn auto_runs_the_eye_pass_only_when_a_light_culls() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let mut o = options(CullingSpec::Auto, StencilBackend::None);
    o.auto.min_objects = 0;
    // A light pass priced far above its savings: auto culls only to
    // measure (cold, then warm) and on its probes.
    o.auto.light_node = 1e6;
    o.auto.light_triangle = 1e6;
    let (mut p, ids) = pipeline(&scene, o, &lights[..1])?;
    let visible = scene.objects().iter().filter(|o| o.flags.visible).count();
    let (mut with_eye, mut without) = (0, 0);
    for frame in 0..8 {
        let out = p.frame(&input(&path, frame))?;
        let culls = out.lights().any(|l| l.stats().light.nodes_visited > 0);
        assert_eq!(out.eye().is_some(), culls, "frame {frame}");
        if culls {
            with_eye += 1;
        } else {
            without += 1;
            assert_eq!(out.psr().len(), visible, "frame {frame}");
            let c = p.check_gpu(ids[0])?;
            assert_eq!(c.mismatch_off_boundary, 0, "frame {frame}");
            assert_eq!(c.culled_vs_unculled_differing_pixels, 0, "frame {frame}");
        }
    }
    assert!(
        with_eye > 0 && without > 0,
        "{with_eye} culled, {without} not"
    );
    Ok(())
}

/// `check_gpu` draws a `stencil: none` frame's volumes as a GPU host would:
/// conservative culling gives the reference's mask and every caster's, and
/// culling that drops casters whose shadows are seen (a query threshold far
/// above 0) makes it count the pixels they change.
#[test]
fn check_gpu_passes_conservative_culling_and_catches_dropped_casters() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let conservative = options(CullingSpec::Chcpp, StencilBackend::None);
    let dropping = PipelineOptions {
        query_threshold: 5_000,
        ..conservative
    };
    let mut dropped = 0;
    for (o, exact) in [(conservative, true), (dropping, false)] {
        let (mut p, ids) = pipeline(&scene, o, &lights)?;
        for frame in 0..2 {
            p.frame(&input(&path, frame))?;
            for &id in &ids {
                let c = p.check_gpu(id)?;
                assert_eq!((c.mask.width, c.mask.height), (W, H));
                if exact {
                    assert_eq!(c.mismatch_off_boundary, 0, "frame {frame}");
                    assert_eq!(c.culled_vs_unculled_differing_pixels, 0, "frame {frame}");
                } else {
                    dropped += c.culled_vs_unculled_differing_pixels;
                }
            }
        }
    }
    assert!(dropped > 0, "the check sees the dropped casters' shadows");
    Ok(())
}

/// The engine scene through the `gpu_host` preset with its edits (vehicles
/// moving, debris added and removed) and its three lights: every frame's
/// volumes draw the reference's mask and every caster's.
#[test]
fn the_engine_scene_under_the_gpu_host_preset_is_exact() -> Result<()> {
    let o = PipelineOptions {
        light_resolution: 256,
        ..PipelineOptions::gpu_host()
    };
    engine_frames(o, |p, ids, f| {
        for &id in ids {
            let c = p.check_gpu(id)?;
            assert_eq!(c.mismatch_off_boundary, 0, "frame {f}, light {id:?}");
            assert_eq!(
                c.culled_vs_unculled_differing_pixels, 0,
                "frame {f}, light {id:?}"
            );
        }
        Ok(())
    })
}

/// A culling resolution below the viewport (a coarse eye pass drawing
/// occluders inner-conservative at their farthest depth, and receiver
/// polygons): down the street with a point light, a sun and a spot, the
/// CPU stencil's masks (its eye exact at the viewport, drawn from the PSR)
/// equal the unculled ones and the reference, and the `gpu_host` volumes
/// draw the reference's mask and every caster's; the coarse pass still
/// culls casters.
#[test]
fn a_coarse_culling_resolution_keeps_masks_exact() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let mut views = CoarseViews::new(&scene, &lights, (W / 4, H / 4))?;
    assert_eq!(views.gpu.options().culling_size((W, H)), (W / 4, H / 4));
    let mut culled = 0;
    for frame in [0, 3, 6] {
        let input = input(&path, frame);
        culled += views.check(&input, &input, &format!("frame {frame}"))?;
    }
    assert!(culled >= 6, "{culled} of 9 light frames culled casters");
    Ok(())
}

/// The pipelines that check a culling size: a CPU stencil's (CHC++, culling
/// at `size`), the `gpu_host` preset's at `size`, and an unculled one.
struct CoarseViews {
    cpu: Pipeline,
    cpu_ids: Vec<LightId>,
    gpu: Pipeline,
    gpu_ids: Vec<LightId>,
    plain: Pipeline,
    objects: usize,
}

impl CoarseViews {
    fn new(scene: &Arc<Scene>, lights: &[Light], size: (u32, u32)) -> Result<Self> {
        let cpu = PipelineOptions {
            culling_resolution: Some(size),
            ..options(CullingSpec::Chcpp, StencilBackend::Bf)
        };
        let gpu = PipelineOptions {
            culling: CullingSpec::Chcpp,
            light_resolution: 256,
            culling_resolution: Some(size),
            ..PipelineOptions::gpu_host()
        };
        let (cpu, cpu_ids) = pipeline(scene, cpu, lights)?;
        let (gpu, gpu_ids) = pipeline(scene, gpu, lights)?;
        let plain = options(CullingSpec::None, StencilBackend::Bf);
        let (plain, _) = pipeline(scene, plain, lights)?;
        Ok(CoarseViews {
            cpu,
            cpu_ids,
            gpu,
            gpu_ids,
            plain,
            objects: scene.objects().len(),
        })
    }

    /// One frame of `input` (the unculled pipeline sees `own`, the same
    /// frame without a host's depth): the CPU stencil's masks equal the
    /// unculled ones and the reference, the GPU host runs no exact eye and
    /// its volumes pass the GPU check. Returns the lights that culled
    /// casters.
    fn check(&mut self, input: &FrameInput, own: &FrameInput, what: &str) -> Result<usize> {
        let (masks, culled): (Vec<_>, usize) = {
            let out = self.cpu.frame(input)?;
            assert!(
                out.eye().is_some(),
                "{what}: the CPU stencil's exact eye pass"
            );
            assert!(out.stats().eye_queries > 0, "{what}: the eye culls");
            let culled = out.lights().filter(|l| l.psc().len() < self.objects);
            let culled = culled.count();
            (
                out.lights().map(|l| l.mask().unwrap().clone()).collect(),
                culled,
            )
        };
        let out = self.plain.frame(own)?;
        for (li, (m, l)) in masks.iter().zip(out.lights()).enumerate() {
            assert_eq!(m, l.mask().unwrap(), "{what} light {li}");
        }
        for (li, m) in masks.iter().enumerate() {
            let r = self.cpu.reference_mask(self.cpu_ids[li])?;
            let c = compare(&r.mask, &r.ambiguous, m);
            assert!(c.compared > 500, "{what} light {li}: {c:?}");
            assert_eq!(c.mismatches, 0, "{what} light {li}: {c:?}");
        }
        assert!(
            self.gpu.frame(input)?.eye().is_none(),
            "{what}: no exact eye pass"
        );
        for &id in &self.gpu_ids {
            let c = self.gpu.check_gpu(id)?;
            assert_eq!(c.mismatch_off_boundary, 0, "{what}, light {id:?}");
            assert_eq!(c.culled_vs_unculled_differing_pixels, 0, "{what}, {id:?}");
        }
        Ok(culled)
    }
}

/// The exact eye depth of `input`'s frame (a pipeline with no culling and
/// a CPU stencil draws it), reduced to `size` as a host's pre-pass would.
fn host_depth_of(scene: &Arc<Scene>, input: &FrameInput, size: (u32, u32)) -> HostDepth {
    let o = options(CullingSpec::None, StencilBackend::Bf);
    let mut p = Pipeline::new(scene.clone(), o).unwrap();
    let out = p.frame(input).unwrap();
    let eye = &out.eye().expect("a CPU stencil's eye").target;
    let (w, h) = (input.width, input.height);
    let rows: Vec<f32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| eye.depth_at(x, y).unwrap_or(0.0))
        .collect();
    HostDepth::reduce(input.camera, (w, h), &rows, size).unwrap()
}

/// The host's own depth of each frame (`FrameInput::host_depth`): the eye
/// pass is queries against it alone, and the masks stay exact — a CPU
/// stencil's equal the unculled ones and the reference, the `gpu_host`
/// volumes pass the GPU check — at a coarse size and at the viewport's.
/// An earlier frame's depth, or one of another size, is refused.
#[test]
fn the_hosts_own_depth_keeps_masks_exact() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    for size in [(W / 4, H / 4), (W, H)] {
        let mut views = CoarseViews::new(&scene, &lights, size)?;
        let mut culled = 0;
        for frame in [0, 3, 6] {
            let own = input(&path, frame);
            let depth = host_depth_of(&scene, &own, size);
            let input = own.clone().with_host_depth(depth);
            culled += views.check(&input, &own, &format!("{size:?} frame {frame}"))?;
        }
        assert!(
            culled >= 6,
            "{size:?}: {culled} of 9 light frames culled casters"
        );
    }
    // Last frame's depth for this frame's camera, and a depth of another size.
    let (mut gpu, _) = pipeline(&scene, PipelineOptions::gpu_host(), &lights)?;
    let old = host_depth_of(&scene, &input(&path, 0), (W, H));
    let e = gpu
        .frame(&input(&path, 1).with_host_depth(old.clone()))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("host_depth") && e.contains("another camera"),
        "{e}"
    );
    let small = HostDepth::reduce(old.camera, (W, H), &old.depth, (W / 2, H / 2))?;
    let e = gpu
        .frame(&input(&path, 0).with_host_depth(small))
        .unwrap_err()
        .to_string();
    assert!(e.contains("culling size"), "{e}");
    gpu.frame(&input(&path, 0).with_host_depth(old))?;
    Ok(())
}

/// A wedge (a ramp rising along +x to a wall at x = 4), a small cube over
/// its slope, inside the wedge's bounds but outside its solid (an invisible
/// shadow caster), and a ground: the cube's shadow falls on the slope. The wedge's occluder is `occluder`.
fn wedge_pipeline(
    options: PipelineOptions,
    occluder: (glam::Vec3, glam::Vec3),
) -> Result<(Pipeline, LightId, ObjectId)> {
    use glam::{DMat4, Vec3};
    use scene::procedural::analytic::{box_mesh, ground_with_boxes};
    let ground = ground_with_boxes(20.0, &[]).unwrap();
    let mut p = Pipeline::new(Arc::new(Scene::new(ground.graph).unwrap()), options)?;
    let v = |x, y, z| Vec3::new(x, y, z);
    let positions = [
        v(0., 0., -1.),
        v(4., 0., -1.),
        v(4., 4., -1.),
        v(0., 0., 1.),
        v(4., 0., 1.),
        v(4., 4., 1.),
    ];
    let triangles = [
        [0, 1, 4],
        [0, 4, 3],
        [0, 2, 1],
        [3, 4, 5],
        [1, 2, 5],
        [1, 5, 4],
        [0, 3, 5],
        [0, 5, 2],
    ];
    let wedge = p.add_mesh(scene::Mesh::new("wedge", &positions, &triangles).unwrap());
    let cube = p.add_mesh(box_mesh("cube", v(0.3, 2.5, -0.4), v(1.3, 3.2, 0.4)).unwrap());
    let occluder = p.add_mesh(box_mesh("occluder", occluder.0, occluder.1).unwrap());
    let id = p.add_object(wedge, DMat4::IDENTITY, ObjectFlags::ALL)?;
    // An invisible shadow proxy: only its shadow is seen.
    let proxy = ObjectFlags {
        visible: false,
        receives: false,
        ..ObjectFlags::ALL
    };
    p.add_object(cube, DMat4::IDENTITY, proxy)?;
    p.set_occluder(id, Some(occluder))?;
    let sun = p.add_light(Light::Directional {
        direction: DVec3::new(0.15, -1.0, 0.05).normalize(),
    })?;
    Ok((p, sun, id))
}

fn wedge_view() -> FrameInput {
    let camera = scene::LookAt {
        eye: DVec3::new(-5.0, 7.0, 8.0),
        target: DVec3::new(1.5, 1.0, 0.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: 0.1,
    }
    .camera(f64::from(W) / f64::from(H))
    .unwrap();
    FrameInput::new(W, H, camera)
}

/// A host's own occluder (`Pipeline::set_occluder`) stands in for its
/// object's mesh under `occluders: proxy`: one inside the wedge keeps the
/// mask exact (culled = unculled = the reference, and the GPU check 0 and
/// 0), one that pokes out of it (its bounding box, which hides the cube
/// from the sun) makes culling drop the cube, and the GPU check counts the
/// pixels of its lost shadow. Bounds that reach outside the mesh's are
/// refused, naming the object.
#[test]
fn a_host_occluder_stands_in_for_its_mesh_and_the_gpu_check_catches_one_that_pokes_out(
) -> Result<()> {
    use glam::Vec3;
    let o = PipelineOptions {
        occluders: OccludersSpec::Proxy,
        ..options(CullingSpec::Chcpp, StencilBackend::Bf)
    };
    let inside = (Vec3::new(2.2, 0.1, -0.9), Vec3::new(3.9, 2.0, 0.9));
    let (mut p, sun, wedge) = wedge_pipeline(o, inside)?;
    let (mut plain, _, _) = wedge_pipeline(options(CullingSpec::None, StencilBackend::Bf), inside)?;
    let input = wedge_view();
    // CHC++ queries a visible object again after a few frames: by the
    // twelfth, every hidden one is culled.
    let settle = |p: &mut Pipeline| -> Result<Vec<usize>> {
        (0..12)
            .map(|_| Ok(p.frame(&input)?.lights().next().unwrap().psc().len()))
            .collect()
    };
    let psc = settle(&mut p)?;
    assert_eq!(
        psc.last(),
        Some(&3),
        "the wedge, the cube and the ground cast: {psc:?}"
    );
    let mask = p
        .last_output()
        .unwrap()
        .lights()
        .next()
        .unwrap()
        .mask()
        .unwrap()
        .clone();
    assert_eq!(
        &mask,
        plain
            .frame(&input)?
            .lights()
            .next()
            .unwrap()
            .mask()
            .unwrap()
    );
    let r = p.reference_mask(sun)?;
    let c = compare(&r.mask, &r.ambiguous, &mask);
    assert!(c.compared > 5_000, "{c:?}");
    assert_eq!(c.mismatches, 0, "{c:?}");
    let check = p.check_gpu(sun)?;
    assert_eq!(check.mismatch_off_boundary, 0);
    assert_eq!(check.culled_vs_unculled_differing_pixels, 0);
    // And for a GPU host whose coarse eye pass draws it too.
    let gpu = PipelineOptions {
        culling: CullingSpec::Chcpp,
        light_resolution: 256,
        culling_resolution: Some((W / 4, H / 4)),
        occluders: OccludersSpec::Proxy,
        ..PipelineOptions::gpu_host()
    };
    let (mut p, sun, _) = wedge_pipeline(gpu, inside)?;
    settle(&mut p)?;
    let check = p.check_gpu(sun)?;
    assert_eq!(check.mismatch_off_boundary, 0);
    assert_eq!(check.culled_vs_unculled_differing_pixels, 0);

    // The wedge's bounding box hides the cube from the sun.
    let bounds = (Vec3::new(0.0, 0.0, -1.0), Vec3::new(4.0, 4.0, 1.0));
    let (mut p, sun, _) = wedge_pipeline(o, bounds)?;
    let psc = settle(&mut p)?;
    assert_eq!(psc.last(), Some(&2), "the cube culled: {psc:?}");
    let check = p.check_gpu(sun)?;
    let (off, differing) = (
        check.mismatch_off_boundary,
        check.culled_vs_unculled_differing_pixels,
    );
    assert!(
        off > 20 && differing >= off,
        "{off} off the boundary, {differing} differing"
    );
    // The same occluder under `occluders: mesh` is not drawn.
    let (mut p, sun, _) = wedge_pipeline(
        PipelineOptions {
            occluders: OccludersSpec::Mesh,
            ..o
        },
        bounds,
    )?;
    assert_eq!(settle(&mut p)?.last(), Some(&3));
    assert_eq!(p.check_gpu(sun)?.culled_vs_unculled_differing_pixels, 0);

    // An occluder larger than its object's mesh is refused.
    let big = p.add_mesh(
        scene::procedural::analytic::box_mesh("big", Vec3::splat(-1.0), Vec3::splat(5.0)).unwrap(),
    );
    let e = p.set_occluder(wedge, Some(big)).unwrap_err().to_string();
    assert!(
        e.contains("occluder of object") && e.contains("reach outside"),
        "{e}"
    );
    Ok(())
}

/// The engine scene (objects moving, added and removed) under the
/// `gpu_host` preset with a coarse culling resolution: exact for the GPU.
#[test]
fn the_engine_scene_at_a_coarse_culling_resolution_is_exact() -> Result<()> {
    let o = PipelineOptions {
        light_resolution: 256,
        culling: CullingSpec::Chcpp,
        culling_resolution: Some((W / 3, H / 3)),
        ..PipelineOptions::gpu_host()
    };
    engine_frames(o, |p, ids, f| {
        for &id in ids {
            let c = p.check_gpu(id)?;
            assert_eq!(c.mismatch_off_boundary, 0, "frame {f}, light {id:?}");
            assert_eq!(c.culled_vs_unculled_differing_pixels, 0, "frame {f}");
        }
        Ok(())
    })
}

/// Frames 0, 13, 26 and 39 of the engine scene (its edits, lights and
/// camera path) through a pipeline with options `o`, `after` called after
/// each.
fn engine_frames(
    o: PipelineOptions,
    mut after: impl FnMut(&mut Pipeline, &[LightId], u32) -> Result<()>,
) -> Result<()> {
    use testkit::engine::EngineScene;
    let e = EngineScene::new(1);
    let scene = Arc::new(Scene::new(e.graph.clone()).unwrap());
    let (mut p, ids) = pipeline(&scene, o, &e.lights(0))?;
    let path = EngineScene::path();
    let mut added = std::collections::HashMap::new();
    for f in (0..40).step_by(13) {
        let edits = e.edits(f);
        for (i, m) in edits.moves {
            let id = p.scene().id_of(i as u32);
            p.set_transform(id, m)?;
        }
        for h in edits.removes {
            if let Some(id) = added.remove(&h) {
                p.remove_object(id)?;
            }
        }
        for (h, mesh, m) in edits.adds {
            added.insert(h, p.add_object(mesh, m, ObjectFlags::ALL)?);
        }
        for (&id, l) in ids.iter().zip(e.lights(f)) {
            p.set_light(id, l)?;
        }
        let cam = path
            .at(f)
            .unwrap()
            .camera(f64::from(W) / f64::from(H))
            .unwrap();
        p.frame(&FrameInput::new(W, H, cam))?;
        after(&mut p, &ids, f)?;
    }
    Ok(())
}

/// `occluders: proxy`: the light views draw the spheres' and pillars'
/// proxies (far fewer triangles) and the volumes stay exact for the GPU.
#[test]
fn occluder_proxies_draw_fewer_triangles_and_stay_exact() -> Result<()> {
    let run = |occluders| -> Result<Vec<u64>> {
        let o = PipelineOptions {
            light_resolution: 256,
            culling: CullingSpec::Chcpp,
            occluders,
            ..PipelineOptions::gpu_host()
        };
        let mut drawn = Vec::new();
        engine_frames(o, |p, ids, f| {
            let out = p.last_output().expect("a frame ran");
            drawn.extend(out.lights().map(|l| l.stats().light.triangles_rendered));
            for &id in ids {
                let c = p.check_gpu(id)?;
                assert_eq!(c.mismatch_off_boundary, 0, "frame {f}, light {id:?}");
                assert_eq!(c.culled_vs_unculled_differing_pixels, 0, "frame {f}");
            }
            Ok(())
        })?;
        Ok(drawn)
    };
    let (mesh, proxy) = (run(OccludersSpec::Mesh)?, run(OccludersSpec::Proxy)?);
    let (m, p): (u64, u64) = (mesh.iter().sum(), proxy.iter().sum());
    assert!(
        p * 2 < m,
        "{p} triangles drawn with proxies, {m} with meshes"
    );
    Ok(())
}

/// `reset_history` (a keyframe) makes the next frames equal a new pipeline's
/// started at the same frame number, counters included; frame numbers, not
/// calls, set CHC++'s revisit phases.
#[test]
fn reset_history_equals_a_fresh_pipeline_at_that_frame() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let o = options(CullingSpec::Chcpp, StencilBackend::H);
    let summary = |out: shadowcull::FrameOutput<'_>| {
        let lights: Vec<_> = out
            .lights()
            .map(|l| (l.psc().to_vec(), l.mask().cloned(), l.stats().queries))
            .collect();
        (
            out.stats().frame,
            out.psr().to_vec(),
            out.stats().eye_queries,
            lights,
        )
    };
    let (mut long, _) = pipeline(&scene, o, &lights)?;
    for frame in 0..4 {
        long.frame(&input(&path, frame))?;
    }
    long.reset_history();
    let (mut fresh, _) = pipeline(&scene, o, &lights)?;
    fresh.set_frame_number(4);
    let (mut at_zero, _) = pipeline(&scene, o, &lights)?;
    let mut phases_differ = false;
    for frame in 4..8 {
        let x = summary(long.frame(&input(&path, frame))?);
        let y = summary(fresh.frame(&input(&path, frame))?);
        assert_eq!(x.0, frame);
        assert_eq!(x, y, "frame {frame}");
        // Numbered from 0 instead: the same masks, other revisit queries.
        let z = summary(at_zero.frame(&input(&path, frame))?);
        for (a, b) in x.3.iter().zip(&z.3) {
            assert_eq!(a.1, b.1, "masks never depend on history");
        }
        phases_differ |= (x.2, x.3.iter().map(|l| l.2).collect::<Vec<_>>())
            != (z.2, z.3.iter().map(|l| l.2).collect::<Vec<_>>());
    }
    assert!(phases_differ, "revisit phases follow the frame number");
    Ok(())
}

/// Changing options starts the per-view state cold: the next frames equal a
/// new pipeline's with those options started at the same frame number,
/// counters included.
#[test]
fn set_options_equals_a_fresh_pipeline() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let a = options(CullingSpec::Chc, StencilBackend::Bf);
    let b = options(CullingSpec::Chcpp, StencilBackend::H);
    let (mut switched, _) = pipeline(&scene, a, &lights)?;
    let input = |frame| input(&path, frame);
    switched.frame(&input(0))?;
    switched.frame(&input(1))?;
    switched.set_options(b)?;
    assert_eq!(switched.options(), &b);
    let (mut fresh, _) = pipeline(&scene, b, &lights)?;
    fresh.set_frame_number(2);
    for frame in 2..5 {
        let x = switched.frame(&input(frame))?;
        let (psr, xs): (Vec<_>, Vec<_>) = (
            x.psr().to_vec(),
            x.lights()
                .map(|l| (l.psc().to_vec(), l.mask().cloned(), l.stats().queries))
                .collect(),
        );
        let y = fresh.frame(&input(frame))?;
        assert_eq!(psr, y.psr());
        let ys: Vec<_> = y
            .lights()
            .map(|l| (l.psc().to_vec(), l.mask().cloned(), l.stats().queries))
            .collect();
        assert_eq!(xs, ys, "frame {frame}");
    }
    // Back to no culling: no light pass runs, every object casts.
    let none = options(CullingSpec::None, StencilBackend::H);
    switched.set_options(none)?;
    let x = switched.frame(&input(5))?;
    let xs: Vec<_> = x
        .lights()
        .map(|l| {
            assert!(l.views().is_empty());
            assert_eq!((l.stats().queries, l.stats().light_ms), (0, 0.0));
            (l.psc().len(), l.mask().cloned())
        })
        .collect();
    let (mut fresh, _) = pipeline(&Arc::new(switched.scene().clone()), none, &lights)?;
    let y = fresh.frame(&input(5))?;
    let ys: Vec<_> = y
        .lights()
        .map(|l| (l.psc().len(), l.mask().cloned()))
        .collect();
    assert_eq!(xs, ys);
    Ok(())
}

/// Bad options, inputs, lights and ids are errors naming their field;
/// nothing panics and the pipeline keeps working afterwards.
#[test]
fn bad_options_and_inputs_name_their_field() -> Result<()> {
    let (scene, path) = city();
    let field = |r: Result<()>| match r {
        Err(Error::Options { field, .. }) => field,
        other => panic!("expected an options error, got {other:?}"),
    };
    let bad_tile = PipelineOptions {
        tile: 12,
        ..Default::default()
    };
    assert_eq!(
        field(Pipeline::new(scene.clone(), bad_tile).map(|_| ())),
        "tile"
    );
    let bad_res = PipelineOptions {
        light_resolution: 2,
        ..Default::default()
    };
    assert_eq!(
        field(Pipeline::new(scene.clone(), bad_res).map(|_| ())),
        "light_resolution"
    );
    let bad_culling_res = PipelineOptions {
        culling_resolution: Some((0, 240)),
        ..Default::default()
    };
    assert_eq!(
        field(Pipeline::new(scene.clone(), bad_culling_res).map(|_| ())),
        "culling_resolution"
    );
    let good = lights(&scene, &path);
    let (mut p, ids) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &good,
    )?;
    assert_eq!(
        field(p.reference_mask(ids[0]).map(|_| ())),
        "reference_mask"
    );
    assert_eq!(field(p.set_options(bad_tile)), "tile");
    let cam = camera(&path, 0);
    for (w, h) in [(0, 10), (10, 0), (raster::MAX_TARGET_SIZE + 1, 8)] {
        assert_eq!(
            field(p.frame(&FrameInput::new(w, h, cam)).map(|_| ())),
            "viewport"
        );
    }
    let broken = Light::Spot {
        position: DVec3::ZERO,
        direction: DVec3::ZERO,
        apex_angle: 1.0,
        range: None,
    };
    assert_eq!(field(p.add_light(broken).map(|_| ())), "light");
    assert_eq!(field(p.set_light(ids[1], broken)), "light");
    assert_eq!(
        p.frame(&FrameInput::new(W, H, cam))?.light_count(),
        good.len()
    );
    assert!(p.reference_mask(ids[0]).is_ok());
    // A removed light's id is stale everywhere; its slot comes back as a new id.
    p.remove_light(ids[1])?;
    assert_eq!(field(p.remove_light(ids[1])), "light");
    assert_eq!(field(p.set_light(ids[1], good[1])), "light");
    assert_eq!(
        field(p.reference_mask(ids[1]).map(|_| ())),
        "reference_mask"
    );
    let again = p.add_light(good[1])?;
    assert_ne!(again, ids[1]);
    assert!(p.light(ids[1]).is_err() && p.light(again)? == good[1]);
    // Unknown object and mesh ids are scene errors.
    let ghost = ObjectId::new(scene.objects().len() as u32 + 5, 0);
    assert!(matches!(p.remove_object(ghost), Err(Error::Scene(_))));
    assert!(matches!(
        p.set_transform(ObjectId::new(0, 3), glam::DMat4::IDENTITY),
        Err(Error::Scene(_))
    ));
    assert!(matches!(
        p.set_transform(
            ObjectId::from_slot(0),
            glam::DMat4::from_cols_array(&[f64::NAN; 16])
        ),
        Err(Error::Scene(_))
    ));
    // A projective matrix would give masks the reference disagrees with.
    let mut projective = glam::DMat4::IDENTITY;
    projective.x_axis.w = 0.05;
    let e = p
        .set_transform(ObjectId::from_slot(0), projective)
        .unwrap_err()
        .to_string();
    assert!(e.contains("object 0: transform is projective"), "{e}");
    assert!(matches!(
        p.add_object(
            scene::MeshId::from_slot(1 << 20),
            glam::DMat4::IDENTITY,
            ObjectFlags::ALL
        ),
        Err(Error::Scene(_))
    ));
    // No lights: an eye pass and PSR only.
    for id in p.light_ids().collect::<Vec<_>>() {
        p.remove_light(id)?;
    }
    let out = p.frame(&FrameInput::new(W, H, cam))?;
    assert_eq!(out.light_count(), 0);
    assert!(out.light(again).is_none() && !out.psr().is_empty());
    Ok(())
}

/// Per-light state follows the light's id: removing a light leaves the
/// others' state alone, adding one starts cold, and masks stay exact.
#[test]
fn lights_by_id_keep_results_exact() -> Result<()> {
    let (scene, path) = city();
    let all = lights(&scene, &path);
    let (mut p, ids) = pipeline(&scene, options(CullingSpec::Chcpp, StencilBackend::H), &all)?;
    let (mut unculled, plain_ids) =
        pipeline(&scene, options(CullingSpec::None, StencilBackend::H), &all)?;
    let masks = |p: &mut Pipeline, ids: &[LightId], frame| -> Result<Vec<_>> {
        let out = p.frame(&input(&path, frame))?;
        Ok(ids
            .iter()
            .map(|&id| out.light(id).map(|l| l.mask().unwrap().clone()))
            .collect())
    };
    assert_eq!(
        masks(&mut p, &ids, 0)?,
        masks(&mut unculled, &plain_ids, 0)?
    );
    // The sun goes; the others keep their state (cached silhouettes hit).
    p.remove_light(ids[1])?;
    unculled.remove_light(plain_ids[1])?;
    // The last output described a light that is gone: none until a frame.
    assert!(p.last_output().is_none(), "no output after an edit");
    assert!(
        p.reference_mask(ids[0]).is_err(),
        "no reference after an edit"
    );
    let a = masks(&mut p, &ids, 1)?;
    assert!(a[1].is_none());
    assert_eq!(a, masks(&mut unculled, &plain_ids, 1)?);
    let out = p.last_output().unwrap();
    let spot = out.light(ids[2]).unwrap();
    assert!(
        spot.volume_stats().cache_hits > 0,
        "kept state: {:?}",
        spot.volume_stats()
    );
    // A new sun in the freed slot starts cold, and is exact.
    let sun = p.add_light(all[1])?;
    let plain_sun = unculled.add_light(all[1])?;
    let b = masks(&mut p, &[ids[0], sun, ids[2]], 2)?;
    assert_eq!(
        b,
        masks(&mut unculled, &[plain_ids[0], plain_sun, plain_ids[2]], 2)?
    );
    assert_eq!(
        p.last_output()
            .unwrap()
            .light(sun)
            .unwrap()
            .volume_stats()
            .cache_hits,
        0,
        "a new light starts cold"
    );
    // Moving a light is a change of its parameters, not of its id.
    let moved = Light::Directional {
        direction: DVec3::new(-0.3, -1.0, 0.5),
    };
    assert!(p.last_output().is_some());
    p.set_light(sun, moved)?;
    unculled.set_light(plain_sun, moved)?;
    assert!(
        p.last_output().is_none(),
        "a moved light's last output is stale"
    );
    let c = masks(&mut p, &[ids[0], sun, ids[2]], 3)?;
    assert_eq!(
        c,
        masks(&mut unculled, &[plain_ids[0], plain_sun, plain_ids[2]], 3)?
    );
    assert_ne!(c[1], b[1], "the moved sun's shadows moved");
    // A failed edit changes nothing, and leaves the output readable.
    assert!(p.set_light(LightId::from_bits(u64::MAX), moved).is_err());
    assert!(p
        .remove_object(scene::ObjectId::from_bits(u64::MAX))
        .is_err());
    assert!(p.last_output().is_some(), "a failed edit keeps the output");
    Ok(())
}

/// The city with a culled and an unculled pipeline (the same lights) and a
/// tall slab mesh added to both; `ahead` is a street point in front of the
/// camera of frame 0, where the tests put the slab.
struct Slab {
    path: CameraPath,
    lights: Vec<Light>,
    culled: Pipeline,
    ids: Vec<LightId>,
    plain: Pipeline,
    mesh: scene::MeshId,
    ahead: DVec3,
}

fn slab_scene() -> Result<Slab> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let (mut culled, ids) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &lights,
    )?;
    let (mut plain, _) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::H),
        &lights,
    )?;
    let pose = path.at(0).unwrap();
    let ahead = pose.eye + (pose.target - pose.eye).normalize() * 12.0;
    let slab = scene::procedural::analytic::box_mesh(
        "slab",
        glam::Vec3::new(-0.5, 0.0, -2.0),
        glam::Vec3::new(0.5, 8.0, 2.0),
    )
    .unwrap();
    let mesh = culled.add_mesh(slab.clone());
    assert_eq!(plain.add_mesh(slab), mesh);
    Ok(Slab {
        path,
        lights,
        culled,
        ids,
        plain,
        mesh,
        ahead,
    })
}

/// A living scene: a moving caster's shadow follows it, static casters keep
/// their cached silhouettes, added and removed objects appear in and vanish
/// from PSR, PSC and the mask — culled = unculled = the reference throughout.
#[test]
fn scene_edits_keep_masks_exact() -> Result<()> {
    let Slab {
        path,
        lights,
        mut culled,
        ids,
        mut plain,
        mesh,
        ahead,
    } = slab_scene()?;
    let scene = culled.scene().clone();
    let at = |dx: f64| glam::DMat4::from_translation(DVec3::new(ahead.x + dx, 0.0, ahead.z));
    let check = |culled: &mut Pipeline, plain: &mut Pipeline, what: &str| -> Result<Vec<_>> {
        let c: Vec<_> = culled
            .frame(&input(&path, 0))?
            .lights()
            .map(|l| l.mask().unwrap().clone())
            .collect();
        let u: Vec<_> = plain
            .frame(&input(&path, 0))?
            .lights()
            .map(|l| l.mask().unwrap().clone())
            .collect();
        assert_eq!(c, u, "{what}: culled = unculled");
        for (k, m) in c.iter().enumerate() {
            let r = culled.reference_mask(ids[k])?;
            let cmp = compare(&r.mask, &r.ambiguous, m);
            assert_eq!(cmp.mismatches, 0, "{what}, light {k}: {cmp:?}");
        }
        Ok(c)
    };
    let before = check(&mut culled, &mut plain, "no slab")?;
    let n = scene.objects().len();
    let id = culled.add_object(mesh, at(0.0), ObjectFlags::ALL)?;
    assert_eq!(plain.add_object(mesh, at(0.0), ObjectFlags::ALL)?, id);
    assert_eq!(id, ObjectId::new(n as u32, 0), "a new slot");
    let with = check(&mut culled, &mut plain, "slab added")?;
    assert_ne!(with, before, "the slab casts");
    {
        let out = culled.last_output().unwrap();
        assert!(out.psr().contains(&id), "the slab is visible");
        assert!(
            out.lights().any(|l| l.psc().contains(&id)),
            "the slab casts"
        );
        assert!(out.lights().any(|l| l.ranges().any(|(o, _)| o == id)));
    }
    // Move it: its shadow follows; every other caster keeps its silhouette.
    culled.set_transform(id, at(3.0))?;
    plain.set_transform(id, at(3.0))?;
    let moved = check(&mut culled, &mut plain, "slab moved")?;
    assert_ne!(moved, with, "the shadow follows the slab");
    {
        let out = plain.last_output().unwrap();
        for l in out.lights() {
            let v = l.volume_stats();
            assert_eq!(v.cache_misses, 1, "only the slab recomputed: {v:?}");
            assert_eq!(v.cache_hits, n, "static casters cached: {v:?}");
        }
    }
    // A LOD change: a thinner, lower slab in its place keeps its id; its
    // shadow changes, only it is recomputed, and a pipeline that added the
    // thin slab directly gives the same masks.
    let thin = scene::procedural::analytic::box_mesh(
        "thin slab",
        glam::Vec3::new(-0.2, 0.0, -2.0),
        glam::Vec3::new(0.2, 5.0, 2.0),
    )
    .unwrap();
    let lod = culled.add_mesh(thin.clone());
    assert_eq!(plain.add_mesh(thin.clone()), lod);
    culled.set_mesh(id, lod)?;
    plain.set_mesh(id, lod)?;
    let swapped = check(&mut culled, &mut plain, "slab LOD")?;
    assert_ne!(swapped, moved, "the thinner slab casts another shadow");
    {
        let out = plain.last_output().unwrap();
        assert!(out.psr().contains(&id), "the id stays");
        for l in out.lights() {
            let v = l.volume_stats();
            assert_eq!(
                v.cache_misses, 1,
                "only the swapped object recomputed: {v:?}"
            );
        }
    }
    let (mut direct, _) = pipeline(
        &Arc::new(scene.clone()),
        options(CullingSpec::None, StencilBackend::H),
        &lights,
    )?;
    let m = direct.add_mesh(thin);
    direct.add_object(m, at(3.0), ObjectFlags::ALL)?;
    let d: Vec<_> = direct
        .frame(&input(&path, 0))?
        .lights()
        .map(|l| l.mask().unwrap().clone())
        .collect();
    assert_eq!(d, swapped, "set_mesh = adding the object with that mesh");
    assert!(culled
        .set_mesh(id, scene::MeshId::from_bits(u64::MAX))
        .is_err());
    culled.set_mesh(id, mesh)?;
    plain.set_mesh(id, mesh)?;
    assert_eq!(check(&mut culled, &mut plain, "slab back")?, moved);
    // Remove it: the masks are those without it, its id is stale.
    culled.remove_object(id)?;
    plain.remove_object(id)?;
    let gone = check(&mut culled, &mut plain, "slab removed")?;
    assert_eq!(gone, before);
    let out = culled.last_output().unwrap();
    assert!(!out.psr().contains(&id));
    assert!(out.lights().all(|l| !l.psc().contains(&id)));
    assert!(culled.set_transform(id, at(0.0)).is_err(), "stale id");
    // Its slot comes back with the next generation; the mesh stays in use.
    let again = culled.add_object(mesh, at(-2.0), ObjectFlags::ALL)?;
    plain.add_object(mesh, at(-2.0), ObjectFlags::ALL)?;
    assert_eq!((again.slot(), again.generation()), (id.slot(), 1));
    let back = check(&mut culled, &mut plain, "slab re-added")?;
    assert_ne!(back, before);
    assert!(culled.last_output().unwrap().psr().contains(&again));
    // Deform the slab (twice as tall): its shadow changes, nothing else recomputes.
    let tall = scene::procedural::analytic::box_corners(
        glam::Vec3::new(-0.5, 0.0, -2.0),
        glam::Vec3::new(0.5, 16.0, 2.0),
    );
    let tris = scene::procedural::analytic::box_triangles();
    // The culled pipeline takes it as a host's vertex buffer (f64, strided,
    // u16 indices), the plain one as positions.
    let bytes: Vec<u8> = (tall.iter())
        .flat_map(|p| p.to_array().map(f64::from))
        .flat_map(f64::to_ne_bytes)
        .collect();
    let indices: Vec<u16> = tris.iter().flatten().map(|&i| i as u16).collect();
    culled.update_mesh_strided(
        mesh,
        scene::StridedPositions {
            bytes: &bytes,
            offset: 0,
            stride: 24,
            count: tall.len(),
            format: scene::PositionFormat::F64x3,
        },
        scene::Indices::U16(&indices),
    )?;
    plain.update_mesh_positions(mesh, &tall, &tris)?;
    let deformed = check(&mut culled, &mut plain, "slab deformed")?;
    assert_ne!(deformed, back, "the taller slab casts a longer shadow");
    for l in plain.last_output().unwrap().lights() {
        assert_eq!(l.volume_stats().cache_misses, 1, "only the slab recomputed");
    }
    let flat = [[0, 1, 2]];
    assert!(
        culled.update_mesh_positions(mesh, &tall, &flat).is_err(),
        "a topology change is refused"
    );
    assert!(culled.remove_mesh(mesh).is_err(), "the mesh is instanced");
    for p in [&mut culled, &mut plain] {
        p.remove_object(again)?;
        p.remove_mesh(mesh)?;
        assert!(
            p.add_object(mesh, at(0.0), ObjectFlags::ALL).is_err(),
            "the mesh is gone"
        );
    }
    // The next mesh takes the freed slot at the next generation: the old id
    // stays dead, and every copy of the slot's mesh (the culler's, the
    // reference's) takes the new shape.
    let wide = scene::procedural::analytic::box_mesh(
        "wide",
        shadowcull::glam::Vec3::new(-3.0, 0.0, -0.5),
        shadowcull::glam::Vec3::new(3.0, 5.0, 0.5),
    )?;
    let reused = culled.add_mesh(wide.clone());
    assert_eq!(plain.add_mesh(wide), reused);
    assert_eq!(
        (reused.slot(), reused.generation()),
        (mesh.slot(), mesh.generation() + 1)
    );
    assert!(culled.remove_mesh(mesh).is_err(), "the old id stays dead");
    let wall = culled.add_object(reused, at(0.0), ObjectFlags::ALL)?;
    plain.add_object(reused, at(0.0), ObjectFlags::ALL)?;
    let walled = check(&mut culled, &mut plain, "a new mesh in the freed slot")?;
    assert_ne!(walled, before, "the wall casts");
    assert_ne!(walled, with, "the wall is not the slab");
    let out = culled.last_output().unwrap();
    assert!(out.lights().any(|l| l.ranges().any(|(o, _)| o == wall)));
    Ok(())
}

/// A pipeline can move to another thread, and its results do not depend on
/// the pool it runs in: its own (`threads`), the host's, or rayon's global one.
#[test]
fn results_are_identical_for_any_thread_count() -> Result<()> {
    fn assert_send<T: Send>() {}
    assert_send::<Pipeline>();
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let run = |threads: u32, host_pool: Option<usize>| -> Result<(Vec<_>, _)> {
        let (mut p, ids) = pipeline(
            &scene,
            PipelineOptions {
                threads,
                ..options(CullingSpec::Chcpp, StencilBackend::H)
            },
            &lights,
        )?;
        if let Some(n) = host_pool {
            let pool = shadowcull::rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap();
            p.set_thread_pool(Some(Arc::new(pool)))?;
        }
        let mut frames = Vec::new();
        for frame in 0..3 {
            let out = p.frame(&input(&path, frame))?;
            let lights: Vec<_> = out
                .lights()
                .map(|l| (l.psc().to_vec(), l.volumes().clone(), l.mask().cloned()))
                .collect();
            frames.push((out.psr().to_vec(), lights));
        }
        let reference = p.reference_mask(ids[0])?.mask;
        Ok((frames, reference))
    };
    let one = run(1, None)?;
    assert_eq!(one, run(0, None)?, "own pool of 1 = global pool");
    assert_eq!(one, run(0, Some(3))?, "own pool of 1 = host pool of 3");
    assert_eq!(one, run(2, None)?, "own pool of 1 = own pool of 2");
    Ok(())
}

/// A host's own matrices: an off-centre, jittered OpenGL projection with a
/// finite far plane. Culled masks equal unculled ones and the reference.
#[test]
fn host_matrices_give_exact_masks() -> Result<()> {
    use glam::{DMat4, DVec4};
    use scene::ClipDepth;
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let pose = path.at(1).unwrap();
    let f = (pose.target - pose.eye).normalize();
    let s = f.cross(DVec3::Y).normalize();
    let u = s.cross(f);
    let e = pose.eye;
    let view = DMat4::from_cols(
        DVec4::new(s.x, u.x, -f.x, 0.0),
        DVec4::new(s.y, u.y, -f.y, 0.0),
        DVec4::new(s.z, u.z, -f.z, 0.0),
        DVec4::new(-s.dot(e), -u.dot(e), f.dot(e), 1.0),
    );
    let (mut culled, culled_ids) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &lights,
    )?;
    let (mut plain, _) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::H),
        &lights,
    )?;
    for (k, jitter) in [(0.0, 0.0), (0.37, -0.21), (-0.5, 0.5)]
        .into_iter()
        .enumerate()
    {
        // Off-centre frustum l, r, b, t at the near plane n, far plane 400,
        // of the viewport's aspect.
        let (b, t, n, far) = (-0.06, 0.1, 0.1, 400.0);
        let (l, r) = (-0.09, -0.09 + (t - b) * f64::from(W) / f64::from(H));
        let projection = DMat4::from_cols(
            DVec4::new(2.0 * n / (r - l), 0.0, 0.0, 0.0),
            DVec4::new(0.0, 2.0 * n / (t - b), 0.0, 0.0),
            DVec4::new(
                (r + l) / (r - l) + 2.0 * jitter.0 / f64::from(W),
                (t + b) / (t - b) + 2.0 * jitter.1 / f64::from(H),
                -(far + n) / (far - n),
                -1.0,
            ),
            DVec4::new(0.0, 0.0, -2.0 * far * n / (far - n), 0.0),
        );
        let camera = Camera::from_view_projection(view, projection, ClipDepth::NegativeOneToOne)
            .expect("a perspective host camera");
        assert!(camera.shift.length() > 0.1, "off-centre");
        let input = FrameInput::new(W, H, camera);
        let masks: Vec<_> = culled
            .frame(&input)?
            .lights()
            .map(|l| l.mask().unwrap().clone())
            .collect();
        let out = plain.frame(&input)?;
        for (li, (m, p)) in masks.iter().zip(out.lights()).enumerate() {
            assert_eq!(
                m,
                p.mask().unwrap(),
                "view {k} light {li}: culled = unculled"
            );
            let r = culled.reference_mask(culled_ids[li])?;
            let c = compare(&r.mask, &r.ambiguous, m);
            assert!(c.compared > 500, "view {k} light {li}: {c:?}");
            assert_eq!(c.mismatches, 0, "view {k} light {li}: {c:?}");
        }
    }
    Ok(())
}

/// The host seam: a backend factory whose backends forward every call to
/// the bundled rasterizer, as a GPU host's would to its queries. The eye's
/// depth, PSC, volumes, masks and the light views' query counts equal the
/// built-in path's, and the factory is asked for the eye and every light
/// view. The host traverses the eye's view as one, the built-in path as two
/// halves side by side (`eye_pass_culled`): both PSRs hold every object the
/// eye's depth shows. Under a query threshold the host counts every sample
/// (as a GPU's `SAMPLES_PASSED`), the built-in path only up to the
/// threshold + 1: no decision differs.
#[test]
fn host_backends_give_identical_results() -> Result<()> {
    use raster::{
        BackendStats, DepthTarget, DrawCommand, OcclusionBackend, QueryCommand, QueryId, QueryMode,
        ReceiverTarget, SyncBackend, TileSize,
    };
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::sync::Mutex;
    use visibility::ViewRole;

    /// Forwards to a bundled backend of the role's size, counting its calls.
    struct Forward(SyncBackend, Arc<AtomicU32>);
    impl OcclusionBackend for Forward {
        fn clear(&mut self) {
            self.0.clear()
        }
        fn set_receivers(&mut self, r: Option<Arc<ReceiverTarget>>) -> raster::Result<()> {
            self.0.set_receivers(r)
        }
        fn draw(&mut self, cmd: DrawCommand) -> raster::Result<()> {
            self.1.fetch_add(1, Ordering::Relaxed);
            self.0.draw(cmd)
        }
        fn issue_query(&mut self, mut q: QueryCommand) -> raster::Result<QueryId> {
            self.1.fetch_add(1, Ordering::Relaxed);
            let (QueryCommand::Aabb { options, .. }
            | QueryCommand::Aabbs { options, .. }
            | QueryCommand::Mesh { options, .. }) = &mut q;
            if let QueryMode::CountUpTo(_) = options.mode {
                options.mode = QueryMode::Count;
            }
            self.0.issue_query(q)
        }
        fn poll(&mut self, id: QueryId) -> Option<u32> {
            self.0.poll(id)
        }
        fn wait(&mut self, id: QueryId) -> u32 {
            self.0.wait(id)
        }
        fn finish(&mut self) {
            self.0.finish()
        }
        fn stats(&self) -> BackendStats {
            self.0.stats()
        }
    }

    let (scene, path) = city();
    let lights = lights(&scene, &path);
    for threshold in [0, 8] {
        let o = PipelineOptions {
            query_threshold: threshold,
            ..options(CullingSpec::Chcpp, StencilBackend::H)
        };
        let (mut builtin, ids) = pipeline(&scene, o, &lights)?;
        let (mut hosted, hosted_ids) = pipeline(&scene, o, &lights)?;
        let calls = Arc::new(AtomicU32::new(0));
        let roles = Arc::new(Mutex::new(Vec::new()));
        let (c, r) = (calls.clone(), roles.clone());
        hosted.set_backend_factory(Some(Arc::new(move |role: ViewRole| {
            r.lock().unwrap().push(role);
            let (w, h, ids) = match role {
                ViewRole::Eye { width, height } => (width, height, true),
                ViewRole::LightView { size, .. } => (size, size, false),
            };
            let target = DepthTarget::new(w, h, TileSize::T8, ids).unwrap();
            Box::new(Forward(SyncBackend::new(target), c.clone()))
                as Box<dyn OcclusionBackend + Send>
        })));
        for frame in 0..4 {
            roles.lock().unwrap().clear();
            let take = |p: &mut Pipeline, ids: &[LightId]| -> Result<_> {
                let out = p.frame(&input(&path, frame))?;
                let lights: Vec<_> = ids
                    .iter()
                    .map(|&id| {
                        let l = out.light(id).unwrap();
                        let s = l.stats();
                        (
                            l.psc().to_vec(),
                            l.volumes().clone(),
                            l.mask().cloned(),
                            (s.light.queries, s.light.waits),
                        )
                    })
                    .collect();
                // The objects the eye's depth shows.
                let eye = out.eye().expect("a culled frame has an eye pass");
                let (w, h) = (eye.target.width(), eye.target.height());
                let mut shown: Vec<_> = (0..h)
                    .flat_map(|y| (0..w).filter_map(move |x| eye.primitive(x, y)))
                    .map(|p| scene.id_of(p.0.slot()))
                    .collect();
                shown.sort_unstable();
                shown.dedup();
                let psr = out.psr().to_vec();
                let missing: Vec<_> = shown
                    .iter()
                    .filter(|id| psr.binary_search(id).is_err())
                    .collect();
                assert!(missing.is_empty(), "shown but not in the PSR: {missing:?}");
                Ok((lights, eye.target.depth_rows()))
            };
            let a = take(&mut builtin, &ids)?;
            let b = take(&mut hosted, &hosted_ids)?;
            assert_eq!(a, b, "threshold {threshold} frame {frame}");
            let roles = roles.lock().unwrap();
            assert_eq!(
                roles
                    .iter()
                    .filter(|r| matches!(r, ViewRole::Eye { .. }))
                    .count(),
                1
            );
            let views: usize = hosted
                .last_output()
                .unwrap()
                .lights()
                .map(|l| l.views().len())
                .sum();
            assert!(roles.len() <= 1 + views && roles.len() > 1, "{roles:?}");
        }
        assert!(calls.load(Ordering::Relaxed) > 100, "the host answered");
    }
    Ok(())
}

/// Object flags, against the reference (which honours them too): an
/// invisible shadow proxy casts but has no pixels, a non-caster has pixels
/// and no shadow, a non-receiver shows no shadow on itself, a non-occluder
/// hides nothing from the culling queries — culled = unculled throughout.
#[test]
fn object_flags_keep_masks_exact() -> Result<()> {
    let Slab {
        path,
        lights: all,
        mut culled,
        ids,
        mut plain,
        mesh,
        ahead,
    } = slab_scene()?;
    let at = glam::DMat4::from_translation(DVec3::new(ahead.x, 0.0, ahead.z));
    let id = culled.add_object(mesh, at, ObjectFlags::ALL)?;
    plain.add_object(mesh, at, ObjectFlags::ALL)?;
    type Frame = (
        Vec<ObjectId>,
        Vec<Vec<ObjectId>>,
        Vec<scene::ObjectId>,
        Vec<shadowcull::mask::Mask>,
    );
    let mut run = |flags: ObjectFlags, what: &str| -> Result<Frame> {
        culled.set_flags(id, flags)?;
        plain.set_flags(id, flags)?;
        let out = culled.frame(&input(&path, 0))?;
        let psr = out.psr().to_vec();
        let psc: Vec<_> = out.lights().map(|l| l.psc().to_vec()).collect();
        let named: Vec<_> = out
            .lights()
            .flat_map(|l| {
                l.volumes()
                    .ranges
                    .iter()
                    .map(|r| ObjectId::from_bits(r.object))
            })
            .collect();
        let masks: Vec<_> = out.lights().map(|l| l.mask().unwrap().clone()).collect();
        let eye_ids = out.eye().expect("an eye pass").primitives();
        let unculled: Vec<_> = plain
            .frame(&input(&path, 0))?
            .lights()
            .map(|l| l.mask().unwrap().clone())
            .collect();
        assert_eq!(masks, unculled, "{what}: culled = unculled");
        for (k, m) in masks.iter().enumerate() {
            let r = culled.reference_mask(ids[k])?;
            let c = compare(&r.mask, &r.ambiguous, m);
            assert_eq!(c.mismatches, 0, "{what}, light {k}: {c:?}");
        }
        let seen = eye_ids.iter().flatten().any(|(o, _)| *o == id);
        assert_eq!(seen, flags.visible, "{what}: pixels");
        Ok((psr, psc, named, masks))
    };
    let base = run(ObjectFlags::ALL, "all")?;
    assert!(base.0.contains(&id) && base.1.iter().any(|p| p.contains(&id)));
    let proxy = run(
        ObjectFlags {
            visible: false,
            ..ObjectFlags::ALL
        },
        "invisible proxy",
    )?;
    assert!(!proxy.0.contains(&id), "an invisible object is no receiver");
    assert!(proxy.2.contains(&id), "an invisible proxy still casts");
    let no_cast = run(
        ObjectFlags {
            casts: false,
            ..ObjectFlags::ALL
        },
        "no cast",
    )?;
    assert!(no_cast.0.contains(&id));
    assert!(no_cast.1.iter().all(|p| !p.contains(&id)) && !no_cast.2.contains(&id));
    assert_ne!(no_cast.3, base.3, "its shadow is gone");
    let no_receive = run(
        ObjectFlags {
            receives: false,
            ..ObjectFlags::ALL
        },
        "no receive",
    )?;
    assert!(no_receive.2.contains(&id));
    let no_occlude = run(
        ObjectFlags {
            occludes: false,
            ..ObjectFlags::ALL
        },
        "no occlude",
    )?;
    assert_eq!(no_occlude.3, base.3, "occluding is a hint: the masks stay");
    // Without temporal coherence (stop-and-wait), what the slab hid is found.
    let psr = |flags: ObjectFlags| -> Result<Vec<ObjectId>> {
        let (mut p, _) = pipeline(
            &Arc::new(culled.scene().clone()),
            options(CullingSpec::Exact, StencilBackend::None),
            &all,
        )?;
        p.set_flags(id, flags)?;
        Ok(p.frame(&input(&path, 0))?.psr().to_vec())
    };
    let (hiding, open) = (
        psr(ObjectFlags::ALL)?,
        psr(ObjectFlags {
            occludes: false,
            ..ObjectFlags::ALL
        })?,
    );
    assert!(hiding.iter().all(|o| open.contains(o)), "PSR only grows");
    assert!(open.len() > hiding.len(), "the slab hid something");
    Ok(())
}

/// `count_fill` counts, on every backend and with clamping (continuous or
/// discrete) on or off, the
/// pixels the brute-force frames of both variants process themselves, and
/// changes no mask; without it an `h` frame counts nothing, and a `bf`
/// frame counts its own variant.
#[test]
fn count_fill_counts_what_brute_force_processes() -> Result<()> {
    use shadowcull::pipeline::{ClampReceiversSpec, ClampingSpec};
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    for (receivers, cont) in [
        (ClampReceiversSpec::All, ClampingSpec::Continuous),
        (ClampReceiversSpec::Psr, ClampingSpec::Continuous),
        (ClampReceiversSpec::Fragment, ClampingSpec::Continuous),
        (ClampReceiversSpec::All, ClampingSpec::Discrete),
    ] {
        let with = |stencil, clamping, count_fill| PipelineOptions {
            clamping,
            clamping_receivers: receivers,
            count_fill,
            ..options(CullingSpec::Chcpp, stencil)
        };
        let none = ClampingSpec::None;
        // Per pipeline, per frame and light: (mask, unclamped, clamped, pixels).
        type Fills = Vec<(Option<shadowcull::mask::Mask>, u64, u64, u64)>;
        let run = |o: PipelineOptions| -> Result<Vec<Fills>> {
            let (mut p, _) = pipeline(&scene, o, &lights)?;
            [0, 3]
                .iter()
                .map(|&f| {
                    let out = p.frame(&input(&path, f))?;
                    Ok(out
                        .lights()
                        .map(|l| {
                            let s = l.stats();
                            (
                                l.mask().cloned(),
                                s.bf_fill_unclamped,
                                s.bf_fill_clamped,
                                s.stencil.pixels_processed,
                            )
                        })
                        .collect())
                })
                .collect()
        };
        let bf = run(with(StencilBackend::Bf, none, false))?;
        let bf_clamped = run(with(StencilBackend::Bf, cont, false))?;
        for (a, b) in bf.iter().flatten().zip(bf_clamped.iter().flatten()) {
            assert_eq!((a.1, a.2), (a.3, 0), "bf counts its own variant");
            assert_eq!((b.1, b.2), (0, b.3), "bf counts its own variant");
            assert!(a.3 > 0 && b.3 > 0);
        }
        let counted = [
            (StencilBackend::Bf, none),
            (StencilBackend::Bf, cont),
            (StencilBackend::Db, cont),
            (StencilBackend::H, none),
            (StencilBackend::H, cont),
            (StencilBackend::None, cont),
        ];
        for (stencil, clamping) in counted {
            // An unclamped frame's other variant is continuous clamping's.
            if cont == ClampingSpec::Discrete && clamping == none {
                continue;
            }
            let uncounted = run(with(stencil, clamping, false))?;
            let got = run(with(stencil, clamping, true))?;
            let (plain, clamped) = if stencil == StencilBackend::Db {
                // `db` counts under its depth-bounds test: its own frames.
                (
                    run(with(StencilBackend::Db, none, false))?,
                    run(with(StencilBackend::Db, cont, false))?,
                )
            } else {
                (bf.clone(), bf_clamped.clone())
            };
            let rows = got.iter().flatten().zip(uncounted.iter().flatten());
            for (k, ((g, u), (p, c))) in rows
                .zip(plain.iter().flatten().zip(clamped.iter().flatten()))
                .enumerate()
            {
                let at = format!("{stencil:?} {clamping:?} {receivers:?} row {k}");
                assert_eq!(g.0, u.0, "{at}: count_fill changes no mask");
                if cont == ClampingSpec::Discrete {
                    // Discrete clamping's light pass marks the tighter
                    // fragment receivers: its PSC is not the unclamped
                    // frame's, so only its own fill is comparable.
                    assert_eq!(g.2, c.3, "{at}");
                    assert!(g.1 >= g.2, "{at}: {} unclamped, {} clamped", g.1, g.2);
                    continue;
                }
                assert_eq!((g.1, g.2), (p.3, c.3), "{at}");
            }
        }
        let h = run(with(StencilBackend::H, cont, false))?;
        assert!(h.iter().flatten().all(|r| (r.1, r.2) == (0, 0)));
    }
    Ok(())
}

/// `culling: auto` chooses per view and per frame from counters, so its
/// masks are the unculled ones, the same run twice gives the same counters,
/// `reset_history` starts the choice over, and a scene with fewer than
/// `min_objects` objects never culls. Costs are set so that both modes run:
/// the light pass is priced out (each light culls its first two frames and
/// then its probes), and the eye probes the unculled mode at its third
/// frame.
/// `stencil: auto` runs `h` first, then measures `db`, and keeps the
/// cheaper by its cost model: the constants decide which, the masks never
/// change, and two runs choose alike.
#[test]
fn auto_stencil_chooses_per_light_and_keeps_masks() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let (mut plain, _) = pipeline(
        &scene,
        options(CullingSpec::Chcpp, StencilBackend::H),
        &lights,
    )?;
    let mut o = options(CullingSpec::Chcpp, StencilBackend::Auto);
    o.auto.probe = 2;
    // Per frame and light: whether the stencil ran `h` (it has a tile image).
    let mut run = |o: PipelineOptions, frames: u32| -> Result<Vec<Vec<bool>>> {
        let (mut a, _) = pipeline(&scene, o, &lights)?;
        let (mut b, _) = pipeline(&scene, o, &lights)?;
        let mut modes = Vec::new();
        for frame in 0..frames {
            let input = input(&path, frame % 8);
            let x: Vec<_> = a
                .frame(&input)?
                .lights()
                .map(|l| (l.shadow().unwrap().tiles.is_some(), l.stats().stencil))
                .collect();
            let y: Vec<_> = b
                .frame(&input)?
                .lights()
                .map(|l| (l.shadow().unwrap().tiles.is_some(), l.stats().stencil))
                .collect();
            assert_eq!(x, y, "frame {frame}: the same choices and counters");
            let out = plain.frame(&input)?;
            for (li, (l, p)) in a
                .last_output()
                .unwrap()
                .lights()
                .zip(out.lights())
                .enumerate()
            {
                assert_eq!(l.mask(), p.mask(), "frame {frame} light {li}");
            }
            modes.push(x.iter().map(|m| m.0).collect());
        }
        Ok(modes)
    };
    let per_light =
        |modes: &[Vec<bool>], li: usize| -> Vec<bool> { modes.iter().map(|m| m[li]).collect() };
    // `h` priced out. Probe period 2: `h` (the start), the probe of `db`
    // reverses the choice (period 2), `h` probed at 2 confirms `db`
    // (period 4), at 6 again (period 8).
    let (t, f) = (true, false);
    let mut dear_h = o;
    dear_h.auto.stencil.h_pixel = 1e6;
    let modes = run(dear_h, 12)?;
    for li in 0..lights.len() {
        let l = per_light(&modes, li);
        assert_eq!(l, [t, f, t, f, f, f, t, f, f, f, f, f], "light {li}");
    }
    // `db` priced out: the start's probe of `db` confirms `h` (period 4),
    // `db` probed at 5 (period 8).
    let mut dear_db = o;
    dear_db.auto.stencil.db_pixel = 1e6;
    let modes = run(dear_db, 12)?;
    for li in 0..lights.len() {
        let l = per_light(&modes, li);
        assert_eq!(l, [t, f, t, t, t, f, t, t, t, t, t, t], "light {li}");
    }
    // The fitted constants choose per light; whatever they choose, the
    // masks are `h`'s (checked in `run`).
    let modes = run(o, 6)?;
    for li in 0..lights.len() {
        let l = per_light(&modes, li);
        assert_eq!(l[..2], [t, f], "light {li}: {l:?}");
    }
    Ok(())
}

/// `clamping: auto` chooses per light and frame between none, continuous
/// and discrete clamping from its cost model: two runs choose alike with
/// the same counters, the masks stay the unclamped pipeline's (but for at
/// most 0.01% of the image: a segment's new vertices snap on their own,
/// checked against the reference in `culling_matrix`), the first frame
/// clamps by slices and the second probes the unclamped mode, and the
/// constants decide: with segment triangles priced out the lights stop
/// clamping, with brute-force fragments priced out they keep clamping.
#[test]
fn auto_clamping_chooses_per_light_and_keeps_masks() -> Result<()> {
    use shadowcull::pipeline::{ClampReceiversSpec, ClampingSpec};
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let base = options(CullingSpec::Chcpp, StencilBackend::Bf);
    let (mut plain, _) = pipeline(&scene, base, &lights)?;
    let o = PipelineOptions {
        clamping: ClampingSpec::Auto,
        clamping_receivers: ClampReceiversSpec::Fragment,
        auto: shadowcull::pipeline::AutoSpec {
            probe: 2,
            ..base.auto
        },
        ..base
    };
    // Per frame and light, the clamping that ran: none (no segment),
    // discrete (a segment plane through the eye) or continuous.
    let mut run = |o: PipelineOptions, frames: u32| -> Result<Vec<Vec<ClampingSpec>>> {
        let (mut a, _) = pipeline(&scene, o, &lights)?;
        let (mut b, _) = pipeline(&scene, o, &lights)?;
        let mut modes = Vec::new();
        for frame in 0..frames {
            let input = input(&path, frame % 8);
            let eye = input.camera.position;
            let mode = |l: &shadowcull::pipeline::LightOutput<'_>| {
                let planes = l.volumes().ranges.iter().flat_map(|r| r.planes).flatten();
                let mut kind = ClampingSpec::None;
                for [x, y, z, d] in planes {
                    let at_eye = (x * eye.x + y * eye.y + z * eye.z + d).abs();
                    kind = if at_eye < 1e-6 * (1.0 + eye.length()) {
                        ClampingSpec::Discrete
                    } else {
                        ClampingSpec::Continuous
                    };
                }
                (
                    kind,
                    l.stats().volumes.segments,
                    l.stats().stencil.pixels_processed,
                )
            };
            let x: Vec<_> = a.frame(&input)?.lights().map(|l| mode(&l)).collect();
            let y: Vec<_> = b.frame(&input)?.lights().map(|l| mode(&l)).collect();
            assert_eq!(x, y, "frame {frame}: the same choices and counters");
            let out = plain.frame(&input)?;
            let clamped = a.last_output().unwrap();
            for (li, (l, p)) in clamped.lights().zip(out.lights()).enumerate() {
                let (l, p) = (&l.mask().unwrap().pixels, &p.mask().unwrap().pixels);
                let differ = l.iter().zip(p).filter(|(a, b)| a != b).count() as u32;
                assert!(
                    differ <= W * H / 10_000,
                    "frame {frame} light {li}: {differ} pixels"
                );
            }
            modes.push(x.iter().map(|m| m.0).collect());
        }
        Ok(modes)
    };
    let count = |modes: &[Vec<ClampingSpec>], li: usize, m: ClampingSpec| {
        modes.iter().filter(|f| f[li] == m).count()
    };
    let (none, discrete) = (ClampingSpec::None, ClampingSpec::Discrete);
    let mut dear_volumes = o;
    dear_volumes.auto.segment_triangle = 1e6;
    let modes = run(dear_volumes, 12)?;
    for li in 0..lights.len() {
        assert_eq!([modes[0][li], modes[1][li]], [discrete, none], "light {li}");
        assert!(count(&modes, li, none) >= 8, "light {li}: {modes:?}");
    }
    let mut dear_fill = o;
    dear_fill.auto.bf_fragment = 1e6;
    let modes = run(dear_fill, 12)?;
    for li in 0..lights.len() {
        assert_eq!([modes[0][li], modes[1][li]], [discrete, none], "light {li}");
        assert!(count(&modes, li, none) <= 3, "light {li}: {modes:?}");
    }
    Ok(())
}

#[test]
fn auto_culling_chooses_per_view_and_keeps_masks() -> Result<()> {
    let (scene, path) = city();
    let lights = lights(&scene, &path);
    let mut o = options(CullingSpec::Auto, StencilBackend::H);
    o.auto.probe = 2;
    o.auto.light_node = 1e9;
    let (mut a, _) = pipeline(&scene, o, &lights)?;
    let (mut b, _) = pipeline(&scene, o, &lights)?;
    let (mut plain, _) = pipeline(
        &scene,
        options(CullingSpec::None, StencilBackend::H),
        &lights,
    )?;
    let n = scene.objects().len();
    // Per frame: whether the eye culled, and each light.
    type Modes = (bool, Vec<bool>);
    let summary = |out: shadowcull::FrameOutput<'_>| {
        let lights: Vec<_> = out
            .lights()
            .map(|l| {
                let culled = !l.views().is_empty();
                assert_eq!(culled, l.stats().light.nodes_visited > 0);
                if !culled {
                    assert_eq!(l.psc().len(), n, "an unculled light casts every object");
                }
                (
                    culled,
                    l.psc().to_vec(),
                    l.stats().queries,
                    l.mask().cloned(),
                )
            })
            .collect::<Vec<_>>();
        let s = out.stats();
        let eye_culled = s.eye_queries > 0;
        assert_eq!(eye_culled, (s.psr as usize) < n || s.eye_queries > 0);
        (eye_culled, out.psr().to_vec(), lights)
    };
    let mut modes: Vec<Modes> = Vec::new();
    for frame in 0..14 {
        let input = input(&path, frame % 8);
        let x = summary(a.frame(&input)?);
        let y = summary(b.frame(&input)?);
        assert_eq!(x, y, "frame {frame}: the same choices and counters");
        let out = plain.frame(&input)?;
        for (li, (l, p)) in x.2.iter().zip(out.lights()).enumerate() {
            assert_eq!(l.3.as_ref(), p.mask(), "frame {frame} light {li}");
        }
        modes.push((x.0, x.2.iter().map(|l| l.0).collect()));
    }
    // The eye: culled cold and warm, then the unculled probe.
    assert_eq!(
        modes[..3].iter().map(|m| m.0).collect::<Vec<_>>(),
        [true, true, false]
    );
    // The lights: culled twice, then unculled, then probes of two frames.
    for li in 0..lights.len() {
        let l: Vec<bool> = modes.iter().map(|m| m.1[li]).collect();
        assert_eq!(l[..3], [true, true, false], "light {li}: {l:?}");
        assert!(l[3..].contains(&true), "light {li} probes culling: {l:?}");
        assert!(l.iter().filter(|c| **c).count() < 10, "light {li}: {l:?}");
    }
    // A reset starts over: the next frame culls every view.
    a.reset_history();
    let x = summary(a.frame(&input(&path, 0))?);
    assert!(x.0 && x.2.iter().all(|l| l.0));
    // Too few objects: nothing culls.
    o.auto.min_objects = n as u32 + 1;
    let (mut small, _) = pipeline(&scene, o, &lights)?;
    for frame in 0..3 {
        let x = summary(small.frame(&input(&path, frame))?);
        assert!(!x.0 && x.2.iter().all(|l| !l.0 && l.2 == 0));
    }
    Ok(())
}

/// `Merged(City(..))` bakes the city into one object: the same triangles
/// and bounds, one object, so `culling: auto` never culls (too few objects)
/// and every mask, whichever stencil `stencil: auto` runs, matches the
/// reference.
#[test]
fn a_merged_city_is_one_object_with_exact_masks_under_auto() -> Result<()> {
    use shadowcull::jobs::config::{load_scene, SceneSpec};
    let city = SceneSpec::City(scene::procedural::city::CityParams {
        seed: 3,
        blocks_x: 2,
        blocks_z: 2,
        ..Default::default()
    });
    let base = std::path::Path::new(".");
    let plain = Scene::new(load_scene(&city, base)?.graph)?;
    let loaded = load_scene(&SceneSpec::Merged(Box::new(city)), base)?;
    let (_, path) = loaded
        .paths
        .iter()
        .find(|(name, _)| name == "street")
        .cloned()
        .expect("the city's street path");
    let merged = Arc::new(Scene::new(loaded.graph)?);
    assert_eq!(merged.objects().len(), 1);
    assert!(plain.objects().len() > 16);
    assert_eq!(merged.counts().triangles, plain.counts().triangles);
    assert_eq!(merged.bounds(), plain.bounds());
    let lights = crate::common::city_lights(&merged).to_vec();
    let o = PipelineOptions {
        culling: CullingSpec::Auto,
        stencil: StencilBackend::Auto,
        light_resolution: 256,
        ..Default::default()
    };
    let (mut p, ids) = pipeline(&merged, o, &lights)?;
    for frame in 0..4 {
        let out = p.frame(&input(&path, frame * 2))?;
        assert_eq!(out.stats().eye_queries, 0, "frame {frame}: nothing culls");
        let masks: Vec<_> = out.lights().map(|l| l.mask().unwrap().clone()).collect();
        for (k, m) in masks.iter().enumerate() {
            let r = p.reference_mask(ids[k])?;
            let cmp = compare(&r.mask, &r.ambiguous, m);
            assert_eq!(cmp.mismatches, 0, "frame {frame} light {k}: {cmp:?}");
        }
    }
    Ok(())
}
