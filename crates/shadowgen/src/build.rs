//! One light's shadow volumes for a set of casters: silhouettes (cached),
//! method choice and volume construction into a caller-owned
//! [`raster::VolumeBuffer`] (DESIGN.md "One frame, per light", steps 5 and 7).

use crate::segments::{append_segments, ClampPlan, SegmentFrame, SegmentScratch};
use crate::volume::{append_volume, CasterGeometry, LocalLight};
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
    if let Some(bad) = casters.iter().find(|id| id.0 as usize >= objects) {
        return Err(Error::UnknownObject { id: bad.0, objects });
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
    };
    let result = append_all(out, request, cache, &mut scratch, &mut stats);
    (cache.scratch, cache.segment_scratch) = (scratch.volume, scratch.segments);
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
    for &id in casters {
        let sil = cache.get(id, light).expect("update() cached every caster");
        let object = scene.object(id);
        let mesh = scene.object_mesh(id);
        let segments = clamp.and_then(|p| p.frame(id));
        // Worst case per caster and segment: 2 vertices per mesh vertex,
        // 3·(2·caps + 2·edges) indices.
        let k = segments.map_or(1, |(_, i)| i.len());
        let need_v = out.positions.len() + k * (2 * mesh.positions().len() + 1);
        let need_i = out.indices.len() + k * 6 * (sil.caps.len() + sil.edge_count());
        if need_v > u32::MAX as usize || need_i > u32::MAX as usize {
            return Err(Error::BufferOverflow);
        }
        let caster = CasterGeometry {
            object: id.0,
            positions: mesh.positions(),
            world_from_local: &object.world_from_local,
            silhouette: sil,
        };
        // The method rule, on the volume's or segment's own bounds.
        let choose = |bounds: &scene::Aabb| {
            let method = hull.choose(options.method, bounds);
            // zpass leaves the light cap out: right only while the eye sees
            // the caster's own light-facing surface wherever that cap lies.
            // The eye sees through an invisible caster (a shadow proxy):
            // zfail, whose closed volume needs no such help.
            if method == VolumeMethod::ZPass
                && options.method == MethodChoice::Auto
                && !object.flags.visible
            {
                VolumeMethod::ZFail
            } else {
                method
            }
        };
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
        count_method(stats, method);
        let local = if options.finite_extrusion {
            LocalLight::finite(light, &object.world_from_local)
        } else {
            LocalLight::new(light, &object.world_from_local)
        };
        let c = append_volume(out, &mut scratch.volume, caster, &local, method);
        stats.volume_triangles += c.side_triangles + c.cap_triangles;
        stats.finite_volumes += usize::from(c.finite);
    }
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
    Ok(())
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
}
