//! One frame of a job through the shadow pipeline, for every light, with the
//! reference check where the job asks for it: the piece `shadowcull run`,
//! `shadowcull compare` and the benchmark example share.
//!
//! Per frame: the eye pass once (depth and primitive ids), then per light the
//! shadow stage ([`crate::pipeline::shadow_mask`]); on reference frames the
//! ray-cast reference is fed the same primitive ids (DESIGN.md "Visible
//! surface"), so the comparison measures the shadow stage alone.

use crate::config::CullingSpec;
use crate::config::PipelineOptions;
use crate::mask::{compare, Mask};
use crate::pipeline::{
    eye_pass_culled, eye_pass_reusing, shadow_mask, shadow_mask_for, EyeCulling, EyePass,
    MeshCache, ShadowFrame, ShadowScratch,
};
use crate::reference::{reference_mask, ReferenceMask, TriangleBvh};
use crate::stats::{CheckStats, FrameStats, ReferenceStats, SceneStats, ShadowStats};
use crate::Result;
use scene::{Camera, Light, Scene};
use std::collections::HashMap;
use std::time::Instant;

/// Cache key of a reference mask: frame, light index, reference options.
type ReferenceKey = (u32, usize, (bool, u64));

/// State kept across the frames of one run: per-mesh vertex data, the
/// reference's BVH (built on first use) and per-light scratch (silhouette
/// caches, volume buffers).
#[derive(Debug)]
pub struct FrameRunner<'s> {
    scene: &'s Scene,
    meshes: MeshCache,
    bvh: Option<TriangleBvh>,
    scratch: Vec<ShadowScratch>,
    /// The last frame's eye pass, whose buffers the next one reuses.
    eye: Option<EyePass>,
    /// The culled eye pass's hierarchy and CHC state, built on first use.
    eye_culling: Option<EyeCulling>,
    /// The light pass's receivers (the eye's visible surface points), reused.
    receivers: visibility::ReceiverPoints,
    /// Reference masks by (frame, light, reference options), when caching.
    references: Option<HashMap<ReferenceKey, ReferenceMask>>,
    /// Time spent building the reference's BVH (ms), 0 until it is built.
    pub bvh_ms: f64,
}

/// One light's result within a frame.
#[derive(Debug)]
pub struct LightFrame {
    /// The statistics row (frame and light numbers, pipeline, reference, check).
    pub row: FrameStats,
    /// The shadow stage's output (mask and counters).
    pub shadow: ShadowFrame,
    /// The reference, on reference frames.
    pub reference: Option<ReferenceMask>,
}

impl<'s> FrameRunner<'s> {
    /// A runner over `scene`.
    pub fn new(scene: &'s Scene) -> Self {
        FrameRunner {
            scene,
            meshes: MeshCache::new(scene),
            bvh: None,
            scratch: Vec::new(),
            eye: None,
            eye_culling: None,
            receivers: Default::default(),
            references: None,
            bvh_ms: 0.0,
        }
    }

    /// Keeps every reference mask computed, keyed by frame, light and reference
    /// options, and reuses it (for runs of several variants over the same frames;
    /// the eye pass is deterministic, so the reference is too).
    pub fn cache_references(&mut self, on: bool) {
        self.references = on.then(HashMap::new);
    }

    /// Drops the shadow stage's per-light state (silhouette caches, volume
    /// buffers) so the next frame starts cold; the BVH and cached references stay.
    pub fn reset_caches(&mut self) {
        self.scratch.clear();
    }

    /// Runs frame `frame` seen by `camera` at `width × height` for every light
    /// of `lights` with `options`; computes the reference too when `reference`.
    ///
    /// # Errors
    /// Rasterizer and shadow-stage errors (an invalid light names its field).
    pub fn frame(
        &mut self,
        frame: u32,
        camera: &Camera,
        lights: &[Light],
        (width, height): (u32, u32),
        options: &PipelineOptions,
        reference: bool,
    ) -> Result<Vec<LightFrame>> {
        let t = Instant::now();
        let previous = self.eye.take();
        let (eye, cull) = if options.culling == CullingSpec::None {
            let eye = eye_pass_reusing(self.scene, &self.meshes, camera, width, height, previous)?;
            (eye, None)
        } else {
            let state = self
                .eye_culling
                .get_or_insert_with(|| EyeCulling::new(self.scene));
            let (eye, r) = eye_pass_culled(
                self.scene,
                state,
                camera,
                width,
                height,
                options.culling(),
                options.query_threshold,
                options.coverage.sampling(),
                previous,
            )?;
            (eye, Some(r))
        };
        // The light pass's receivers, the eye's visible surface points, are
        // part of the eye pass's work (`eye_ms`): computed once per frame.
        if let (Some(_), Some(_)) = (&cull, &self.eye_culling) {
            crate::pipeline::visible_points_into(self.scene, camera, &eye, &mut self.receivers);
        }
        let eye_ms = ms(t);
        let (psr, queries, waits) = match &cull {
            Some(r) => (r.stats.objects_rendered, r.stats.queries, r.stats.waits),
            None => (self.scene.objects().len() as u64, 0, 0),
        };
        if self.scratch.len() < lights.len() {
            self.scratch
                .resize_with(lights.len(), ShadowScratch::default);
        }
        let shadow_options = options.shadow_options();
        let counts = self.scene.counts();
        let mut out = Vec::with_capacity(lights.len());
        // The light passes (PSC) of all lights, concurrently: each light owns
        // its views' state. `light_ms` is each light's own elapsed time.
        let light_passes: Vec<(Option<visibility::LightPassResult>, f64)> =
            match (&cull, &self.eye_culling) {
                (Some(_), Some(state)) => {
                    use rayon::prelude::*;
                    let (h, meshes) = state.parts();
                    let lp = visibility::LightPassOptions {
                        culling: options.culling(),
                        sampling: options.coverage.sampling(),
                        resolution: options.light_resolution,
                        threshold: options.query_threshold,
                        two_sided: options.two_sided,
                    };
                    let (scene, receivers) = (self.scene, &self.receivers);
                    self.scratch[..lights.len()]
                        .par_iter_mut()
                        .zip(lights)
                        .map(|(sc, light)| {
                            let tl = Instant::now();
                            let r = sc
                                .light_pass
                                .run(h, scene, meshes, camera, light, receivers, &lp)?;
                            Ok((Some(r), ms(tl)))
                        })
                        .collect::<std::result::Result<_, visibility::Error>>()?
                }
                _ => lights.iter().map(|_| (None, 0.0)).collect(),
            };
        for ((li, light), (light_pass, light_ms)) in lights.iter().enumerate().zip(light_passes) {
            let shadow = match &light_pass {
                Some(lp) => shadow_mask_for(
                    self.scene,
                    camera,
                    light,
                    &eye,
                    &shadow_options,
                    &mut self.scratch[li],
                    &lp.psc,
                )?,
                None => shadow_mask(
                    self.scene,
                    camera,
                    light,
                    &eye,
                    &shadow_options,
                    &mut self.scratch[li],
                )?,
            };
            let (psc, lq, lw) = match &light_pass {
                Some(lp) => (lp.psc.len() as u64, lp.stats.queries, lp.stats.waits),
                None => (self.scene.objects().len() as u64, 0, 0),
            };
            let v = &shadow.volumes;
            let mut row = FrameStats {
                frame,
                light: li as u32,
                scene: SceneStats {
                    update_ms: 0.0,
                    objects: counts.objects as u64,
                    triangles: counts.drawn_triangles as u64,
                },
                shadow: ShadowStats {
                    eye_ms,
                    silhouette_ms: v.silhouette_ms,
                    volume_ms: v.volume_ms,
                    stencil_ms: shadow.stencil_ms,
                    volume_triangles: shadow.volume_triangles,
                    silhouette_edges: v.silhouette_edges as u64,
                    zpass_casters: v.zpass as u64,
                    zfail_casters: v.zfail as u64,
                    zpplus_casters: v.zpplus as u64,
                    pixels_processed: shadow.stencil.pixels_processed,
                    stencil_updates: shadow.stencil.stencil_updates,
                    pixels_touched: shadow.stencil.pixels_touched,
                    shadowed_pixels: shadow.mask.counts().shadow,
                    h_fragments: shadow.stencil.h_fragments,
                    tile_tests: shadow.stencil.tile_tests,
                    tiles_lit: shadow.stencil.tiles_lit,
                    tiles_shadow: shadow.stencil.tiles_shadow,
                    tiles_boundary: shadow.stencil.tiles_boundary,
                    pixel_bytes: shadow.stencil.pixel_bytes,
                    tile_bytes: shadow.stencil.tile_bytes,
                    bandwidth_bytes: shadow.stencil.bandwidth_bytes(),
                    silhouette_pixels: shadow.silhouette_pixels,
                    map_ms: shadow.map_ms,
                    psr,
                    psc,
                    queries: queries + lq,
                    waits: waits + lw,
                    light_ms,
                },
                ..Default::default()
            };
            row.frame_ms = eye_ms + light_ms + v.silhouette_ms + v.volume_ms + shadow.stencil_ms;
            let reference = if reference {
                let ro = options.reference_options();
                let key = (frame, li, (ro.two_sided, ro.depth_error.to_bits()));
                let cached = self.references.as_mut().and_then(|c| c.remove(&key));
                let (r, reference_ms) = match cached {
                    Some(r) => (r, 0.0),
                    None => {
                        let t = Instant::now();
                        let r = self.reference(camera, light, &eye, options);
                        (r, ms(t))
                    }
                };
                row.reference = reference_stats(&r, reference_ms);
                row.check = check_stats(&r, &shadow.mask);
                if let Some(c) = self.references.as_mut() {
                    c.insert(key, r.clone());
                }
                Some(r)
            } else {
                None
            };
            out.push(LightFrame {
                row,
                shadow,
                reference,
            });
        }
        self.eye = Some(eye);
        Ok(out)
    }

    fn reference(
        &mut self,
        camera: &Camera,
        light: &Light,
        eye: &EyePass,
        options: &PipelineOptions,
    ) -> ReferenceMask {
        let scene = self.scene;
        let bvh = self.bvh.get_or_insert_with(|| {
            let t = Instant::now();
            let b = TriangleBvh::new(scene);
            self.bvh_ms = ms(t);
            b
        });
        reference_mask(
            bvh,
            camera,
            light,
            eye.target.width(),
            eye.target.height(),
            &options.reference_options(),
            Some(eye.surface()),
        )
    }
}

fn reference_stats(r: &ReferenceMask, reference_ms: f64) -> ReferenceStats {
    let c = &r.counts;
    ReferenceStats {
        reference_ms,
        lit: c.classes.lit,
        shadow: c.classes.shadow,
        unlit: c.classes.unlit,
        background: c.classes.background,
        ambiguous: c.ambiguous,
    }
}

fn check_stats(r: &ReferenceMask, mask: &Mask) -> CheckStats {
    let c = compare(&r.mask, &r.ambiguous, mask);
    CheckStats {
        mismatch_pixels: c.mismatches,
        mismatch_off_boundary: c.mismatches - c.mismatches_on_boundary,
        ambiguous_pixels: c.ambiguous,
        compared_pixels: c.compared,
    }
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec3};
    use scene::procedural::analytic;

    /// A runner that reuses last frame's buffers gives every frame exactly what
    /// a fresh runner gives, also after a size change.
    #[test]
    fn reused_buffers_give_fresh_results() {
        let loaded = analytic::ground_with_boxes(
            10.0,
            &[
                (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0)),
                (Vec3::new(2.0, 0.5, 2.0), Vec3::new(3.0, 1.0, 4.0)),
            ],
        )
        .unwrap();
        let scene = Scene::new(loaded.graph).unwrap();
        let lights = [
            Light::Point {
                position: DVec3::new(-3.0, 8.0, 2.0),
                range: None,
            },
            Light::Directional {
                direction: DVec3::new(0.4, -1.0, 0.3),
            },
        ];
        let options = PipelineOptions::default();
        let views = [
            (DVec3::new(2.0, 9.0, 12.0), (96, 72)),
            (DVec3::new(-8.0, 3.0, 5.0), (96, 72)),
            (DVec3::new(4.0, 6.0, -9.0), (64, 80)),
        ];
        let mut reused = FrameRunner::new(&scene);
        for (frame, (eye, res)) in views.into_iter().enumerate() {
            let cam = Camera::look_at(
                eye,
                DVec3::ZERO,
                DVec3::Y,
                1.0,
                res.0 as f64 / res.1 as f64,
                0.05,
            )
            .unwrap();
            let a = reused
                .frame(frame as u32, &cam, &lights, res, &options, true)
                .unwrap();
            let b = FrameRunner::new(&scene)
                .frame(frame as u32, &cam, &lights, res, &options, true)
                .unwrap();
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.shadow.mask, y.shadow.mask, "frame {frame}");
                assert_eq!(x.shadow.raw_nonzero, y.shadow.raw_nonzero);
                assert_eq!(x.row.check, y.row.check);
                assert_eq!(x.row.shadow.pixels_processed, y.row.shadow.pixels_processed);
                assert!(
                    x.row.shadow.shadowed_pixels > 0,
                    "frame {frame}: shadows seen"
                );
            }
        }
    }
}
