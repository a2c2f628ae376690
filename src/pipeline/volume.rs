//! The volume stage: one light's shadow volumes for its casters —
//! silhouettes by signed edge counters, cached while caster and light are
//! static [AW §2.4, Steiner §4.2], the per-caster zpass/zfail/zp+ choice
//! [EK, Steiner §3.2.1], w = 0 extrusion, continuous clamping into segments
//! when asked [Steiner §4.4], and the scissor rectangles and depth bounds the
//! stencil tests use — into a caller-owned [`raster::VolumeBuffer`]
//! ([`shadowgen::build_volumes`], [`shadowgen::build_clamped_volumes`]).

use super::shadow_options::{ClampOptions, ShadowInput, ShadowOptions};
use crate::Result;
use raster::VolumeBuffer;
use scene::{Aabb, Camera, ObjectId, Scene};
use shadowgen::{
    build_clamped_volumes, build_volumes, split_into_bands, BuildOptions, ClampInput, ClampPlan,
    EyeSlices, GapCost, GapModel, LightClamp, ReceiverDepths, SegmentAxis, SilhouetteCache,
    VolumeRequest, VolumeStats, BAND_SLICES,
};
use std::time::Instant;
use visibility::FragmentDepths;

/// The volume stage's state kept per light between frames.
#[derive(Default)]
pub(crate) struct VolumeScratch {
    /// Silhouettes while caster and light are static.
    pub(crate) cache: SilhouetteCache,
    /// The light's volumes of the last frame.
    pub(crate) buffer: VolumeBuffer,
    /// Continuous clamping's sweep state for this light, and its plan.
    pub(crate) clamp: LightClamp,
    pub(crate) plan: ClampPlan,
    /// The ranges while they are split into bands.
    pub(crate) bands: Vec<raster::VolumeRange>,
    /// Every object's receiver flag, when the frame gives none.
    pub(crate) receives: Vec<bool>,
}

/// What this frame's light pass read of the fragment receivers
/// ([`visibility::LightPassResult`]).
#[derive(Clone, Copy)]
pub(crate) struct Readings<'a> {
    /// Each caster's intervals along its axis (continuous clamping).
    pub axes: &'a FragmentDepths,
    /// Each caster's occupied eye slices: discrete clamping's, or the
    /// bands of [`BAND_SLICES`] under continuous clamping.
    pub slices: &'a FragmentDepths,
}

impl<'a> Readings<'a> {
    pub(crate) fn of(result: &'a visibility::LightPassResult) -> Self {
        Readings {
            axes: &result.fragments,
            slices: &result.slices,
        }
    }
}

/// Builds the volumes of `casters` for `light` into `scratch.buffer`
/// (cleared first) with the shadow stage's method, extrusion and clamping
/// options; scissor rectangles and depth bounds are computed only when a
/// stencil test or the hybrid uses them (they cost time), for a `viewport` of `(width,
/// height)` pixels. Clamping's receivers are `fragments` (the light pass's
/// fragment intervals) when given, else the objects `receives[id]`
/// (internal ids), `None`: every receiving object. With `fragments`, the
/// casters' ranges are also split into their bands (`shadowgen`'s
/// `bands.rs`): every range under continuous clamping, the unclamped ones
/// under discrete clamping (its segments already lie in their slices).
///
/// # Errors
/// An invalid light or caster id ([`crate::Error::Shadowgen`]).
pub(crate) fn build_for(
    input: ShadowInput<'_>,
    casters: &[ObjectId],
    options: &ShadowOptions,
    viewport: (u32, u32),
    receives: Option<&[bool]>,
    fragments: Option<Readings<'_>>,
    scratch: &mut VolumeScratch,
) -> Result<VolumeStats> {
    let ShadowInput {
        scene,
        camera,
        light,
    } = input;
    let build = BuildOptions {
        method: options.method,
        two_sided: options.two_sided,
        // The hybrid's volumes always run both tests.
        viewport: (options.scissor
            || options.depth_bounds
            || matches!(options.backend, super::Backend::Hybrid { .. }))
        .then_some(viewport),
        finite_extrusion: options.finite_extrusion,
    };
    let out = &mut scratch.buffer;
    let cache = &mut scratch.cache;
    let all = &mut scratch.receives;
    let stats = match &options.clamping {
        None => build_volumes(out, scene, camera, light, casters, build, cache)?,
        Some(clamp) => {
            let t = Instant::now();
            let receives = match receives {
                Some(r) => r,
                None => {
                    all.clear();
                    all.extend(scene.objects().iter().map(|o| o.flags.receives));
                    &all[..]
                }
            };
            let model = ScreenGaps {
                scene,
                camera,
                viewport,
                clamp,
            };
            let clamp_input = ClampInput {
                scene,
                light,
                casters,
                receives,
                cost: Some(&model),
            };
            // The light's pencil, with a light pass: discrete clamping's
            // slices, or the bands' (their runs need only its orientation).
            let discrete = clamp.slices.is_some();
            let count = clamp.slices.unwrap_or(BAND_SLICES);
            let pencil = fragments.and_then(|_| EyeSlices::new(camera, viewport, light, count));
            let cs = match (fragments, &pencil) {
                (Some(f), Some(s)) if discrete => scratch.clamp.plan_sliced(
                    &clamp_input,
                    s,
                    &Fragments(f.slices),
                    &mut scratch.plan,
                ),
                // Discrete clamping without a light pass (or with a
                // viewport or values no pencil fits): unclamped.
                _ if discrete => {
                    scratch.plan.clear();
                    Default::default()
                }
                (Some(f), _) => scratch.clamp.plan_from_depths(
                    &clamp_input,
                    &Fragments(f.axes),
                    &mut scratch.plan,
                ),
                (None, _) => scratch.clamp.plan(&clamp_input, &mut scratch.plan)?,
            };
            let clamp_ms = t.elapsed().as_secs_f64() * 1e3;
            let plan = &scratch.plan;
            let request = VolumeRequest {
                scene,
                camera,
                light,
                casters,
                options: build,
            };
            let mut stats = build_clamped_volumes(out, &request, cache, plan)?;
            let t = Instant::now();
            if let (Some(f), Some(pencil)) = (fragments, &pencil) {
                split_into_bands(
                    out,
                    0,
                    pencil,
                    |id| f.slices.get(id),
                    |r| !discrete || r.planes == [None, None],
                    &mut scratch.bands,
                );
            }
            stats.clamp_ms = clamp_ms + t.elapsed().as_secs_f64() * 1e3;
            stats.sap_pairs = cs.sap_pairs as usize;
            stats.sap_swaps = cs.sap_swaps as usize;
            stats
        }
    };
    scratch.buffer.reserve_headroom();
    Ok(stats)
}

/// The light pass's fragment intervals as clamping reads them.
struct Fragments<'a>(&'a FragmentDepths);

impl ReceiverDepths for Fragments<'_> {
    fn depths(&self, caster: ObjectId) -> Option<&[[f64; 2]]> {
        self.0.get(caster)
    }
}

/// The gap cost model on the eye's image: a caster's segments cost its
/// mesh's vertex count for both the cap and the silhouette (an upper bound
/// known before the silhouette), a gap its screen rectangle.
struct ScreenGaps<'a> {
    scene: &'a Scene,
    camera: &'a Camera,
    viewport: (u32, u32),
    clamp: &'a ClampOptions,
}

impl GapModel for ScreenGaps<'_> {
    fn cost(&self, caster: ObjectId) -> GapCost {
        let n = u32::try_from(self.scene.object_mesh(caster).positions().len()).unwrap_or(u32::MAX);
        GapCost {
            per_vertex: self.clamp.vertex_cost,
            per_pixel: self.clamp.pixel_cost,
            cap_vertices: n,
            silhouette_vertices: n,
        }
    }

    /// The pixels of the screen rectangle around the gap's bounds (the
    /// caster's corners projected onto both planes), the whole viewport when
    /// a corner lies behind the eye.
    fn area(&self, bounds: &Aabb, axis: &SegmentAxis, near: f64, far: f64) -> f64 {
        let b = axis.segment_bounds(bounds, Some(near), far);
        let (w, h) = (f64::from(self.viewport.0), f64::from(self.viewport.1));
        let clip = self.camera.clip_from_eye_relative();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for k in 0..8 {
            let pick = |bit: usize, a: f32, b: f32| f64::from(if k & bit != 0 { b } else { a });
            let p = glam::DVec3::new(
                pick(1, b.min.x, b.max.x),
                pick(2, b.min.y, b.max.y),
                pick(4, b.min.z, b.max.z),
            );
            let c = clip * (p - self.camera.position).extend(1.0);
            if c.w <= 0.0 || !c.w.is_finite() {
                return w * h;
            }
            for i in 0..2 {
                let ndc = (c[i] / c.w).clamp(-1.0, 1.0);
                lo[i] = lo[i].min(ndc);
                hi[i] = hi[i].max(ndc);
            }
        }
        0.25 * (hi[0] - lo[0]) * w * (hi[1] - lo[1]) * h
    }
}
