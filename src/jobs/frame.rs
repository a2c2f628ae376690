//! One frame of a job through [`Pipeline`], for every light, with the
//! reference check where the job asks for it: the piece `shadowcull run`,
//! `shadowcull compare` and the benchmark examples share. It adds to the
//! pipeline only what a job needs — frame numbers, the statistics rows and
//! the reference check — and calls nothing but the pipeline's public API.
//!
//! On reference frames the ray-cast reference is fed the pipeline's own
//! primitive ids (DESIGN.md "Visible surface", [`Pipeline::reference_mask`]),
//! so the comparison measures the shadow stage alone.

use crate::mask::{compare, Mask};
use crate::pipeline::{FrameInput, HostDepth, LightId, Pipeline, PipelineOptions, ShadowFrame};
use crate::reference::ReferenceMask;
use crate::stats::{CheckStats, FrameRow, ReferenceStats, SceneStats};
use crate::Result;
use scene::{Camera, Light, Scene};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

/// Cache key of a reference mask: frame, light index, reference options.
type ReferenceKey = (u32, usize, (bool, u64));

/// A [`Pipeline`] driven frame by frame for a job, with reference masks
/// (optionally cached across variants).
#[derive(Debug)]
pub struct FrameRunner {
    pipeline: Option<Pipeline>,
    /// The pipeline's ids of the job's lights, in job order.
    lights: Vec<LightId>,
    scene: Arc<Scene>,
    /// Reference masks by (frame, light, reference options), when caching.
    references: Option<HashMap<ReferenceKey, ReferenceMask>>,
    /// Time spent building the reference's BVH (ms), 0 until it is built.
    pub bvh_ms: f64,
    /// Reset all coherent state at frames that are multiples of this.
    keyframe: Option<u32>,
    /// The next frame's host depth ([`FrameRunner::set_host_depth`]).
    host_depth: Option<HostDepth>,
}

/// One light's result within a frame.
#[derive(Debug)]
pub struct LightFrame {
    /// The statistics row (frame and light numbers, pipeline, reference, check).
    pub row: FrameRow,
    /// The stencil stage's output (mask and counters); `None` with
    /// `stencil: none`.
    pub shadow: Option<ShadowFrame>,
    /// The reference, on reference frames.
    pub reference: Option<ReferenceMask>,
}

impl LightFrame {
    /// The pipeline's mask.
    ///
    /// # Panics
    /// With `stencil: none` (no mask is computed).
    pub fn mask(&self) -> &Mask {
        &self
            .shadow
            .as_ref()
            .expect("the pipeline computed a mask")
            .mask
    }
}

impl FrameRunner {
    /// A runner over `scene` (shared: several runners may hold one scene).
    pub fn new(scene: impl Into<Arc<Scene>>) -> Self {
        FrameRunner {
            pipeline: None,
            lights: Vec::new(),
            scene: scene.into(),
            references: None,
            bvh_ms: 0.0,
            keyframe: None,
            host_depth: None,
        }
    }

    /// The scene the next frame sees: the pipeline's (with the edits staged
    /// since), or the runner's own before the first frame.
    pub fn scene(&self) -> &Scene {
        self.pipeline.as_ref().map_or(&self.scene, |p| p.scene())
    }

    /// Gives the next [`FrameRunner::frame`] the host's own depth of that
    /// frame ([`crate::FrameInput::host_depth`]; taken by it): for
    /// benches of a GPU host with a depth pre-pass.
    pub fn set_host_depth(&mut self, depth: Option<HostDepth>) {
        self.host_depth = depth;
    }

    /// The pipeline's ids of the lights of the last frame, in the order
    /// [`FrameRunner::frame`] was given them.
    pub fn light_ids(&self) -> &[LightId] {
        &self.lights
    }

    /// The pipeline the frames run through, `None` before the first frame:
    /// for scene edits between frames (they apply at the next frame).
    pub fn pipeline_mut(&mut self) -> Option<&mut Pipeline> {
        self.pipeline.as_mut()
    }

    /// Resets all coherent state ([`Pipeline::reset_history`]) before every
    /// frame whose number is a multiple of `keyframe` (`None`: only before
    /// frame 0, where every job's history starts).
    pub fn set_keyframe(&mut self, keyframe: Option<u32>) {
        self.keyframe = keyframe.filter(|&k| k > 0);
    }

    /// Keeps every reference mask computed, keyed by frame, light and reference
    /// options, and reuses it (for runs of several variants over the same frames;
    /// the eye pass is deterministic, so the reference is too).
    pub fn cache_references(&mut self, on: bool) {
        self.references = on.then(HashMap::new);
    }

    /// Runs job frame `frame` seen by `camera` at `width × height` for every
    /// light of `lights` with `options` (a change of options starts the
    /// pipeline's per-view state cold, [`Pipeline::set_options`]); computes
    /// the reference too when `reference`. The pipeline numbers the frame
    /// `frame` ([`Pipeline::set_frame_number`]), and forgets its history
    /// first at frame 0 and at keyframes ([`FrameRunner::set_keyframe`]).
    ///
    /// # Errors
    /// Pipeline errors (an invalid light or option names its field).
    pub fn frame(
        &mut self,
        frame: u32,
        camera: &Camera,
        lights: &[Light],
        (width, height): (u32, u32),
        options: &PipelineOptions,
        reference: bool,
    ) -> Result<Vec<LightFrame>> {
        let pipeline = match &mut self.pipeline {
            Some(p) => {
                p.set_options(*options)?;
                p
            }
            None => self
                .pipeline
                .insert(Pipeline::new(self.scene.clone(), *options)?),
        };
        // The job's lights, kept by job order (a change of count starts over).
        if self.lights.len() != lights.len() {
            for id in self.lights.drain(..) {
                pipeline.remove_light(id)?;
            }
            for l in lights {
                self.lights.push(pipeline.add_light(*l)?);
            }
        } else {
            for (&id, l) in self.lights.iter().zip(lights) {
                pipeline.set_light(id, *l)?;
            }
        }
        pipeline.set_frame_number(frame);
        if frame == 0 || self.keyframe.is_some_and(|k| frame.is_multiple_of(k)) {
            pipeline.reset_history();
        }
        let mut input = FrameInput::new(width, height, *camera);
        input.host_depth = self.host_depth.take();
        let out = pipeline.frame(&input)?;
        let frame_stats = *out.stats();
        let mut rows: Vec<LightFrame> = self
            .lights
            .iter()
            .filter_map(|&id| out.light(id))
            .enumerate()
            .map(|(li, l)| {
                let shadow = *l.stats();
                let frame_ms = shadow.eye_ms
                    + shadow.light_ms
                    + shadow.volumes.silhouette_ms
                    + shadow.volumes.volume_ms
                    + shadow.stencil_ms;
                LightFrame {
                    row: FrameRow {
                        frame,
                        light: li as u32,
                        scene: SceneStats {
                            update_ms: 0.0,
                            objects: frame_stats.objects,
                            triangles: frame_stats.triangles,
                        },
                        shadow,
                        frame_ms,
                        pipeline_frame_ms: frame_stats.frame_ms,
                        ..Default::default()
                    },
                    shadow: l.shadow().cloned(),
                    reference: None,
                }
            })
            .collect();
        if reference {
            let ro = options.reference_options();
            for (li, lf) in rows.iter_mut().enumerate() {
                let key = (frame, li, (ro.two_sided, ro.depth_error.to_bits()));
                let cached = self.references.as_mut().and_then(|c| c.remove(&key));
                let (r, reference_ms) = match cached {
                    Some(r) => (r, 0.0),
                    None => {
                        let t = Instant::now();
                        let r = pipeline.reference_mask(self.lights[li])?;
                        (r, t.elapsed().as_secs_f64() * 1e3)
                    }
                };
                lf.row.reference = reference_stats(&r, reference_ms);
                if let Some(shadow) = &lf.shadow {
                    lf.row.check = check_stats(&r, &shadow.mask);
                }
                if let Some(c) = self.references.as_mut() {
                    c.insert(key, r.clone());
                }
                lf.reference = Some(r);
            }
            self.bvh_ms = self.bvh_ms.max(pipeline.reference_bvh_ms());
        }
        Ok(rows)
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
        let scene = Arc::new(Scene::new(loaded.graph).unwrap());
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
        let mut reused = FrameRunner::new(scene.clone());
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
            let b = FrameRunner::new(scene.clone())
                .frame(frame as u32, &cam, &lights, res, &options, true)
                .unwrap();
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.mask(), y.mask(), "frame {frame}");
                let raw = |f: &LightFrame| f.shadow.as_ref().unwrap().raw_nonzero.clone();
                assert_eq!(raw(x), raw(y));
                assert_eq!(x.row.check, y.row.check);
                assert_eq!(x.row.shadow.stencil, y.row.shadow.stencil);
                assert!(
                    x.row.shadow.shadowed_pixels > 0,
                    "frame {frame}: shadows seen"
                );
            }
        }
    }
}
