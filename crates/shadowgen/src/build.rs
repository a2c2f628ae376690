//! One light's shadow volumes for a set of casters: silhouettes (cached),
//! method choice and volume construction into a caller-owned
//! [`raster::VolumeBuffer`] (DESIGN.md "One frame, per light", steps 5 and 7).

use crate::segments::{append_segments, ClampPlan, SegmentFrame, SegmentScratch};
use crate::volume::{append_volume, BuildPart, CasterGeometry, LocalLight};
use crate::{Error, MethodChoice, NearLightHull, Result, SilhouetteCache};
use raster::{VolumeBuffer, VolumeMethod};
use scene::{Camera, Light, ObjectId, Scene};
use std::time::Instant;

/// Options of [`build_volumes`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BuildOptions {
    /// How each caster's method is chosen.
    pub method: MethodChoice,
    /// Every triangle casts (back-facing ones flipped), as the reference's two-sided mode.
    pub two_sided: bool,
    /// Viewport `(width, height)` in pixels: when given, every range gets its
    /// scissor rectangle and depth bounds ([`crate::volume_bounds`], restricted
    /// to the scene bounds); when `None` they stay full (whole viewport, 1..0).
    pub viewport: Option<(u32, u32)>,
    /// Point and spot lights with a range extrude finitely where the caster
    /// allows it (`w = 1` far vertices at distance `D` from the light, always
    /// with a dark cap, zpass included; see the finite-extrusion section of
    /// `volume.rs`). Default `false`: every
    /// volume extrudes to infinity.
    pub finite_extrusion: bool,
}

/// Counters and timings of one [`build_volumes`] call.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeStats {
    /// Casters processed (one range each).
    pub casters: usize,
    /// Silhouettes taken from the cache.
    pub cache_hits: usize,
    /// Silhouettes recomputed.
    pub cache_misses: usize,
    /// Silhouette edges, counted with multiplicity.
    pub silhouette_edges: usize,
    /// Casting (light-cap) triangles over all casters.
    pub cap_source_triangles: usize,
    /// Triangles written to the volume buffer.
    pub volume_triangles: usize,
    /// Casters whose volume was extruded finitely ([`BuildOptions::finite_extrusion`]).
    pub finite_volumes: usize,
    /// Casters clamped into segments ([`build_clamped_volumes`]).
    pub clamped_casters: usize,
    /// Segments of the clamped casters (ranges).
    pub segments: usize,
    /// Triangles of the clamped casters' segments (within `volume_triangles`).
    pub segment_triangles: usize,
    /// Wall time of continuous clamping (the sweeps and the occupied
    /// intervals; with fragment receivers, their reading in the light pass
    /// too, which its own time also holds; set by the caller that plans
    /// it), ms.
    pub clamp_ms: f64,
    /// Overlapping pairs of clamping's sweeps (set by the caller).
    pub sap_pairs: usize,
    /// Endpoint swaps of clamping's sweeps (set by the caller).
    pub sap_swaps: usize,
    /// Ranges drawn with zpass (casters, or segments of clamped ones).
    pub zpass: usize,
    /// Ranges drawn with zfail.
    pub zfail: usize,
    /// Ranges drawn with zp+.
    pub zpplus: usize,
    /// Wall time of silhouette extraction (cache lookups and recomputation), ms.
    pub silhouette_ms: f64,
    /// Wall time of method choice and volume construction, ms.
    pub volume_ms: f64,
}

/// Builds the shadow volumes of `casters` for `light` seen by `camera` into
/// `out` (cleared first): one range per caster, in the order given, with the
/// method `options.method` yields. Silhouettes come from `cache` (updated),
/// which also holds the reusable construction scratch.
///
/// # Errors
/// [`Error::Light`] when the light fails [`Light::validate`];
/// [`Error::UnknownObject`] when a caster id is not in `scene`;
/// [`Error::BufferOverflow`] past `u32` indices.
pub fn build_volumes(
    out: &mut VolumeBuffer,
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    casters: &[ObjectId],
    options: BuildOptions,
    cache: &mut SilhouetteCache,
) -> Result<VolumeStats> {
    let request = VolumeRequest {
        scene,
        camera,
        light,
        casters,
        options,
    };
    build(
        out,
        &Request {
            request,
            clamp: None,
        },
        cache,
    )
}

/// [`build_volumes`] with continuous clamping [Steiner §4.4]: a caster that
/// `plan` clamps gets one range per occupied interval (segments `0..k`, each
/// a closed volume with its planes, its method chosen by the same rule on the
/// segment's own bounds; see `segments.rs`); the others are built as by
/// `build_volumes`. A finite extrusion never applies to a clamped caster:
/// its last segment ends at its last interval.
///
/// # Errors
/// As [`build_volumes`].
pub fn build_clamped_volumes(
    out: &mut VolumeBuffer,
    request: &VolumeRequest<'_>,
    cache: &mut SilhouetteCache,
    plan: &ClampPlan,
) -> Result<VolumeStats> {
    build(
        out,
        &Request {
            request: *request,
            clamp: Some(plan),
        },
        cache,
    )
}

fn build(
    out: &mut VolumeBuffer,
    request: &Request<'_>,
    cache: &mut SilhouetteCache,
) -> Result<VolumeStats> {
    let VolumeRequest {
        scene,
        light,
        casters,
        options,
        ..
    } = request.request;
    out.clear();
    light.validate()?;
    let objects = scene.objects().len();
    if let Some(bad) = casters.iter().find(|id| id.index() >= objects) {
        return Err(Error::UnknownObject {
            id: bad.slot(),
            objects,
        });
    }
    let mut stats = VolumeStats {
        casters: casters.len(),
        ..VolumeStats::default()
    };
    let t0 = Instant::now();
    let (h0, m0) = cache.hits_misses();
    cache.update(scene, light, options.two_sided, casters);
    let (h1, m1) = cache.hits_misses();
    stats.cache_hits = h1 - h0;
    stats.cache_misses = m1 - m0;
    stats.silhouette_ms = t0.elapsed().as_secs_f64() * 1e3;

    let t1 = Instant::now();
    let mut scratch = BuildScratch {
        volume: std::mem::take(&mut cache.scratch),
        segments: std::mem::take(&mut cache.segment_scratch),
        parts: std::mem::take(&mut cache.build_parts),
    };
    let result = append_all(out, request, cache, &mut scratch, &mut stats);
    (cache.scratch, cache.segment_scratch, cache.build_parts) =
        (scratch.volume, scratch.segments, scratch.parts);
    result?;
    stats.volume_ms = t1.elapsed().as_secs_f64() * 1e3;
    debug_assert_eq!(stats.volume_triangles, out.triangle_count());
    Ok(stats)
}

/// What [`build_volumes`] is asked for: the volumes of `casters` in `scene`
/// for `light`, seen by `camera`, built with `options`.
#[derive(Clone, Copy)]
pub struct VolumeRequest<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// The eye (method choice, scissor and depth bounds).
    pub camera: &'a Camera,
    /// The light.
    pub light: &'a Light,
    /// The casters, one range (or one per segment) each, in this order.
    pub casters: &'a [ObjectId],
    /// How to build.
    pub options: BuildOptions,
}

/// A request and, for continuous clamping, the casters to segment and where.
struct Request<'a> {
    request: VolumeRequest<'a>,
    clamp: Option<&'a ClampPlan>,
}

/// The volume construction of [`build_volumes`] (its silhouettes already in
/// `cache`): every caster's volume appended to `out`, then the ranges'
/// scissor and depth bounds when `options.viewport` asks for them.
fn append_all(
    out: &mut VolumeBuffer,
    request: &Request<'_>,
    cache: &SilhouetteCache,
    scratch: &mut BuildScratch,
    stats: &mut VolumeStats,
) -> Result<()> {
    let VolumeRequest {
        scene,
        camera,
        light,
        casters,
        options,
    } = request.request;
    let clamp = request.clamp;
    let hull = NearLightHull::new(camera, light);
    #[cfg(feature = "parallel")]
    if clamp.is_none() && casters.len() >= PARALLEL_CASTERS && rayon::current_num_threads() > 1 {
        let parts = &mut scratch.parts;
        parts.resize_with(rayon::current_num_threads() - 1, Default::default);
        let cx = Unclamped {
            request: request.request,
            cache,
            hull: &hull,
        };
        add_counts(
            stats,
            &split_build(&cx, (out, &mut scratch.volume), parts, casters)?,
        );
        merge_parts(out, parts)?;
        bound_all(out, request.request);
        return Ok(());
    }
    for &id in casters {
        let segments = clamp.and_then(|p| p.frame(id));
        let k = segments.map_or(1, |(_, i)| i.len());
        let caster = caster_geometry(out, scene, cache, light, id, k)?;
        let (object, sil) = (scene.object(id), caster.silhouette);
        // The method rule, on the volume's or segment's own bounds.
        let choose = |bounds: &scene::Aabb| choose_for(&hull, options.method, object, bounds);
        stats.silhouette_edges += sil.edge_count();
        stats.cap_source_triangles += sil.caps.len();
        if let Some((frame, intervals)) = segments {
            let seg_scratch = &mut scratch.segments;
            let before = out.ranges.len();
            // The rule on the segment's own bounds; but a segment lies in the
            // caster's shadow, so where the caster's rule allows zpass (the
            // near rectangle is not in its shadow) every segment may use it.
            // Slices take the caster's rule: a segment is a closed part of
            // the volume, counted as the volume is.
            let whole = choose(&object.world_bounds);
            let c = append_segments(
                out,
                seg_scratch,
                caster,
                frame,
                light,
                intervals,
                |k, near, far| match frame {
                    SegmentFrame::Axis(axis) if whole != VolumeMethod::ZPass => {
                        let near = (k > 0).then_some(near);
                        choose(&axis.segment_bounds(&object.world_bounds, near, far))
                    }
                    _ => whole,
                },
            );
            for r in &out.ranges[before..] {
                count_method(stats, r.method);
            }
            stats.clamped_casters += 1;
            stats.segments += c.segments;
            stats.segment_triangles += c.triangles;
            stats.volume_triangles += c.triangles;
            continue;
        }
        let method = choose(&object.world_bounds);
        append_unclamped(
            out,
            &mut scratch.volume,
            stats,
            (caster, method),
            request.request,
        );
    }
    bound_all(out, request.request);
    Ok(())
}

/// Caster `id` as [`append_volume`] reads it (its silhouette from `cache`),
/// once `out` is known to hold `k` more of its volumes (worst case per
/// volume: 2 vertices per mesh vertex, 3·(2·caps + 2·edges) indices)
/// within `u32` indices.
fn caster_geometry<'a>(
    out: &VolumeBuffer,
    scene: &'a Scene,
    cache: &'a SilhouetteCache,
    light: &Light,
    id: ObjectId,
    k: usize,
) -> Result<CasterGeometry<'a>> {
    let sil = cache.get(id, light).expect("update() cached every caster");
    let object = scene.object(id);
    let mesh = scene.object_mesh(id);
    let need_v = out.positions.len() + k * (2 * mesh.positions().len() + 1);
    let need_i = out.indices.len() + k * 6 * (sil.caps.len() + sil.edge_count());
    if need_v > u32::MAX as usize || need_i > u32::MAX as usize {
        return Err(Error::BufferOverflow);
    }
    Ok(CasterGeometry {
        object: id.slot(),
        positions: mesh.positions(),
        world_from_local: &object.world_from_local,
        silhouette: sil,
    })
}

/// One unclamped caster's volume appended to `out` with `method`.
fn append_unclamped(
    out: &mut VolumeBuffer,
    scratch: &mut crate::volume::VolumeScratch,
    stats: &mut VolumeStats,
    (caster, method): (CasterGeometry<'_>, VolumeMethod),
    request: VolumeRequest<'_>,
) {
    count_method(stats, method);
    let world_from_local = caster.world_from_local;
    let local = if request.options.finite_extrusion {
        LocalLight::finite(request.light, world_from_local)
    } else {
        LocalLight::new(request.light, world_from_local)
    };
    let c = append_volume(out, scratch, caster, &local, method);
    stats.volume_triangles += c.side_triangles + c.cap_triangles;
    stats.finite_volumes += usize::from(c.finite);
}

/// Casters from which [`append_all`] builds in parallel (each thread its
/// share into its own buffer, joined in order: the output is the
/// sequential one). city_16384's bird view has 16,385.
#[cfg(feature = "parallel")]
const PARALLEL_CASTERS: usize = 2048;

/// What every share of the parallel build reads.
#[cfg(feature = "parallel")]
struct Unclamped<'a> {
    request: VolumeRequest<'a>,
    cache: &'a SilhouetteCache,
    hull: &'a NearLightHull,
}

/// Builds `casters` in `parts.len() + 1` shares in parallel: the first into
/// `first` (the output), each other into its part (by halving:
/// `rayon::join` allocates nothing); the counters of them all.
#[cfg(feature = "parallel")]
fn split_build(
    cx: &Unclamped<'_>,
    first: (&mut VolumeBuffer, &mut crate::volume::VolumeScratch),
    parts: &mut [BuildPart],
    casters: &[ObjectId],
) -> Result<VolumeStats> {
    let shares = parts.len() + 1;
    let (mine, rest) = casters.split_at(casters.len() / shares);
    let (a, b) = rayon::join(
        || build_share(cx, first, mine),
        || build_parts(cx, parts, rest),
    );
    let (mut a, b) = (a?, b?);
    add_counts(&mut a, &b);
    Ok(a)
}

/// The shares of `parts`, `casters` split evenly between them; their
/// counters.
#[cfg(feature = "parallel")]
fn build_parts(
    cx: &Unclamped<'_>,
    parts: &mut [BuildPart],
    casters: &[ObjectId],
) -> Result<VolumeStats> {
    match parts {
        [] => Ok(VolumeStats::default()),
        [one] => {
            one.buffer.clear();
            build_share(cx, (&mut one.buffer, &mut one.scratch), casters)
        }
        _ => {
            let half = parts.len() / 2;
            let (pa, pb) = parts.split_at_mut(half);
            let (ca, cb) = casters.split_at(casters.len() * half / (pa.len() + pb.len()));
            let (a, b) = rayon::join(|| build_parts(cx, pa, ca), || build_parts(cx, pb, cb));
            let (mut a, b) = (a?, b?);
            add_counts(&mut a, &b);
            Ok(a)
        }
    }
}

/// The unclamped volumes of `casters`, in order, appended to `out`; their
/// counters.
#[cfg(feature = "parallel")]
fn build_share(
    cx: &Unclamped<'_>,
    (out, scratch): (&mut VolumeBuffer, &mut crate::volume::VolumeScratch),
    casters: &[ObjectId],
) -> Result<VolumeStats> {
    let VolumeRequest {
        scene,
        light,
        options,
        ..
    } = cx.request;
    let mut stats = VolumeStats::default();
    for &id in casters {
        let caster = caster_geometry(out, scene, cx.cache, light, id, 1)?;
        let (object, sil) = (scene.object(id), caster.silhouette);
        let method = choose_for(cx.hull, options.method, object, &object.world_bounds);
        stats.silhouette_edges += sil.edge_count();
        stats.cap_source_triangles += sil.caps.len();
        append_unclamped(out, scratch, &mut stats, (caster, method), cx.request);
    }
    Ok(stats)
}

/// Adds a share's construction counters to `stats`.
#[cfg(feature = "parallel")]
fn add_counts(stats: &mut VolumeStats, c: &VolumeStats) {
    stats.silhouette_edges += c.silhouette_edges;
    stats.cap_source_triangles += c.cap_source_triangles;
    stats.volume_triangles += c.volume_triangles;
    stats.finite_volumes += c.finite_volumes;
    stats.zpass += c.zpass;
    stats.zfail += c.zfail;
    stats.zpplus += c.zpplus;
}

/// Appends every part's buffer to `out` in order (indices and ranges moved
/// by what precedes them).
#[cfg(feature = "parallel")]
fn merge_parts(out: &mut VolumeBuffer, parts: &[BuildPart]) -> Result<()> {
    for p in parts {
        let (vo, io) = (out.positions.len(), out.indices.len());
        if vo + p.buffer.positions.len() > u32::MAX as usize
            || io + p.buffer.indices.len() > u32::MAX as usize
        {
            return Err(Error::BufferOverflow);
        }
        let (vo, io) = (vo as u32, io as u32);
        out.positions.extend_from_slice(&p.buffer.positions);
        out.indices.extend(p.buffer.indices.iter().map(|i| i + vo));
        out.ranges
            .extend(p.buffer.ranges.iter().map(|r| raster::VolumeRange {
                first_vertex: r.first_vertex + vo,
                first_index: r.first_index + io,
                light_cap: r.light_cap.start + io..r.light_cap.end + io,
                dark_cap: r.dark_cap.start + io..r.dark_cap.end + io,
                ..r.clone()
            }));
    }
    Ok(())
}

/// The method rule on `bounds` (a caster's, or one of its segments'):
/// the near-plane/light hull's choice, except that zpass leaves the light
/// cap out, right only while the eye sees the caster's own light-facing
/// surface wherever that cap lies. The eye sees through an invisible caster
/// (a shadow proxy): zfail, whose closed volume needs no such help.
fn choose_for(
    hull: &NearLightHull,
    choice: MethodChoice,
    object: &scene::Object,
    bounds: &scene::Aabb,
) -> VolumeMethod {
    let method = hull.choose(choice, bounds);
    if method == VolumeMethod::ZPass && choice == MethodChoice::Auto && !object.flags.visible {
        VolumeMethod::ZFail
    } else {
        method
    }
}

/// Every range's scissor and depth bounds, when the request's options ask
/// for them (in parallel).
fn bound_all(out: &mut VolumeBuffer, request: VolumeRequest<'_>) {
    let VolumeRequest {
        scene,
        camera,
        light,
        options,
        ..
    } = request;
    if let Some(viewport) = options.viewport {
        let scene_bounds = scene.bounds();
        let view = crate::BoundsView::new(camera);
        let bound = |r: &mut raster::VolumeRange| {
            let caster = &scene.objects()[r.object as usize].world_bounds;
            let b = view.volume_bounds(viewport, light, caster, &scene_bounds);
            r.scissor = b.scissor;
            r.depth_near = b.depth_near;
            r.depth_far = b.depth_far;
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            out.ranges.par_iter_mut().for_each(bound);
        }
        #[cfg(not(feature = "parallel"))]
        out.ranges.iter_mut().for_each(bound);
    }
}

fn count_method(stats: &mut VolumeStats, method: VolumeMethod) {
    match method {
        VolumeMethod::ZPass => stats.zpass += 1,
        VolumeMethod::ZFail => stats.zfail += 1,
        VolumeMethod::ZpPlus => stats.zpplus += 1,
    }
}

/// Construction scratch, kept in the [`SilhouetteCache`] between frames.
struct BuildScratch {
    volume: crate::volume::VolumeScratch,
    segments: SegmentScratch,
    /// The parallel build's other shares.
    parts: Vec<BuildPart>,
}

#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use glam::{DMat4, DVec3, Vec3};
    use scene::{SceneGraph, Transform};

    /// 60 × 60 boxes of varied heights under a point light and a sun: the
    /// build on two threads (in shares, joined) equals the one on one.
    #[test]
    fn the_parallel_build_is_the_sequential_one() {
        let mut g = SceneGraph::new();
        let m = g
            .add_mesh(scene::procedural::analytic::box_mesh("box", Vec3::ZERO, Vec3::ONE).unwrap());
        for i in 0..60 {
            for j in 0..60 {
                let h = 1.0 + ((i * 7 + j * 13) % 5) as f64;
                let t = DMat4::from_scale_rotation_translation(
                    DVec3::new(0.6, h, 0.6),
                    glam::DQuat::IDENTITY,
                    DVec3::new(f64::from(i) - 30.0, 0.0, f64::from(j) - 30.0),
                );
                g.add_instance(&format!("b{i}_{j}"), m, Transform::Matrix(t));
            }
        }
        let scene = Scene::new(g).unwrap();
        let camera = Camera::look_at(
            DVec3::new(0.0, 40.0, 45.0),
            DVec3::ZERO,
            DVec3::Y,
            1.0,
            1.0,
            0.1,
        )
        .unwrap();
        let casters: Vec<ObjectId> = (0..scene.objects().len() as u32)
            .map(ObjectId::from_slot)
            .collect();
        assert!(casters.len() >= PARALLEL_CASTERS);
        let lights = [
            Light::Point {
                position: DVec3::new(3.0, 12.0, -4.0),
                range: Some(40.0),
            },
            Light::Directional {
                direction: DVec3::new(-0.3, -1.0, 0.2).normalize(),
            },
        ];
        for light in lights {
            for finite_extrusion in [false, true] {
                let options = BuildOptions {
                    viewport: Some((320, 240)),
                    finite_extrusion,
                    ..BuildOptions::default()
                };
                let run = |threads: usize| {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    pool.install(|| {
                        let mut out = VolumeBuffer::new();
                        let mut cache = SilhouetteCache::new();
                        let req = (&scene, &camera, &light, &casters[..], options);
                        let st =
                            build_volumes(&mut out, req.0, req.1, req.2, req.3, req.4, &mut cache)
                                .unwrap();
                        out.check().unwrap();
                        (out, st)
                    })
                };
                let ((a, sa), (b, sb)) = (run(1), run(3));
                assert_eq!(a.positions, b.positions, "{light:?}");
                assert_eq!(a.indices, b.indices, "{light:?}");
                assert_eq!(a.ranges, b.ranges, "{light:?}");
                let counts = |s: VolumeStats| VolumeStats {
                    silhouette_ms: 0.0,
                    volume_ms: 0.0,
                    ..s
                };
                assert_eq!(counts(sa), counts(sb), "{light:?}");
            }
        }
    }
}
