//! The GPU host's exactness check: what a GPU drawing this frame's volumes
//! would show, against the reference and against every caster's volumes.
//!
//! A host with `stencil: none` draws [`super::LightOutput::volumes`] itself,
//! on its own exact depth buffer. [`Pipeline::check_gpu`] does the same on
//! the CPU, outside every timed stage: it takes the light's volumes as the
//! frame left them (the PSC's, clamped or not), runs the brute-force stencil
//! over exactly those on the exact eye depth at the output resolution
//! ([`Pipeline::exact_eye`]), and compares the mask it gives
//!
//! - with the ray-cast reference ([`crate::reference`]): mismatches off a
//!   shadow boundary are wrong pixels;
//! - with the mask of every casting object's unclamped volume: a pixel that
//!   differs is one culling or clamping changed, which conservative options
//!   never do.
//!
//! Both are 0 for every conservative option; a culling step that leaves out
//! a caster whose shadow is seen (an occluder that reaches outside its
//! object, say) makes them count the pixels it changed.

use super::shadow_options::{Backend, ShadowInput, ShadowOptions};
use super::stencil::{stencil_volumes, ShadowScratch};
use super::{volume, LightId, Pipeline};
use crate::mask::{compare, Mask};
use crate::Result;

/// What [`Pipeline::check_gpu`] found for one light.
#[derive(Clone, Debug)]
pub struct GpuCheck {
    /// The mask the frame's volumes give on the exact eye depth.
    pub mask: Mask,
    /// Its pixels that differ from the reference, a 4-neighbour of the same
    /// reference class away from any shadow boundary, ambiguous ones left out.
    pub mismatch_off_boundary: u64,
    /// Its pixels that differ from the reference (boundaries included).
    pub mismatch_pixels: u64,
    /// Pixels where it differs from the mask of every caster's unclamped
    /// volume (culled against unculled).
    pub culled_vs_unculled_differing_pixels: u64,
}

impl Pipeline {
    /// Checks light `light`'s volumes of the last frame as a GPU would draw
    /// them (see `gpu_check.rs`): the brute-force stencil over exactly those
    /// volumes on the exact eye depth, against the reference and against
    /// every caster's volumes. Costs an eye pass, the reference and two
    /// brute-force stencils: a check for tests and benches, not a frame
    /// stage.
    ///
    /// # Errors
    /// [`crate::Error::Options`] before the first frame, after scene edits
    /// not yet framed, or for an unknown light; rasterizer errors.
    pub fn check_gpu(&mut self, light: LightId) -> Result<GpuCheck> {
        let reference = self.reference_mask(light)?;
        let options = ShadowOptions {
            backend: Backend::Brute,
            clamping: None,
            ..self.options.shadow_options()
        };
        self.exact_eye()?;
        let state = self.light_state(light)?;
        let (Some(eye), Some(camera)) = (&self.eye, &self.camera) else {
            return Err(crate::Error::Options {
                field: "check_gpu".into(),
                message: "no frame has run yet".into(),
            });
        };
        let input = ShadowInput {
            scene: &self.scene,
            camera,
            light: &state.light,
        };
        let run = || -> Result<(Mask, Mask)> {
            // The frame's volumes, unchanged.
            let mut drawn = ShadowScratch::default();
            drawn.volume.buffer.clone_from(&state.scratch.volume.buffer);
            let stats = state.volume_stats;
            let culled = stencil_volumes(input, eye, &options, &mut drawn, stats, None, None)?;
            // Every casting object's volume.
            let mut all = ShadowScratch::default();
            let stats = volume::build_for(
                input,
                &self.all_casters,
                &options,
                self.viewport,
                None,
                None,
                &mut all.volume,
            )?;
            for r in &mut all.volume.buffer.ranges {
                r.object = self.scene.id_of(r.object as u32).to_bits();
            }
            let unculled = stencil_volumes(input, eye, &options, &mut all, stats, None, None)?;
            Ok((culled.mask, unculled.mask))
        };
        let (mask, unculled) = super::in_pool(self.pool.as_ref(), run)?;
        let c = compare(&reference.mask, &reference.ambiguous, &mask);
        let differing = (mask.pixels.iter().zip(&unculled.pixels))
            .filter(|(a, b)| a != b)
            .count() as u64;
        Ok(GpuCheck {
            mask,
            mismatch_off_boundary: c.mismatches - c.mismatches_on_boundary,
            mismatch_pixels: c.mismatches,
            culled_vs_unculled_differing_pixels: differing,
        })
    }
}
