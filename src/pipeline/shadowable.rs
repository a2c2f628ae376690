//! The stencil's computation mask: the eye pixels whose class a light's
//! stencil decides. A pixel whose object receives no shadows is lit, and
//! one whose triangle faces away from the light (or shows the eye its other
//! side) or lies beyond the light's reach is unlit, whatever the stencil
//! holds there ([`crate::mask::classify_runs`] finds them before the
//! stencil runs). The brute-force and hierarchical stencils draw the
//! volumes on a copy of the eye depth in which those pixels are
//! background, so they cost no per-pixel work, and tiles holding only such
//! pixels cost no tile work. As the hybrid's computation mask restricts the
//! volumes to its silhouette pixels [ChanDurand04 §3], this restricts them
//! to the pixels that can be shadowed. The mask is unchanged: the stencil
//! skips only pixels whose stencil value the mask never reads.

use crate::Result;
use raster::DepthTarget;

/// One light's computation mask and masked depth, kept from frame to frame.
#[derive(Default)]
pub(crate) struct ShadowableScratch {
    /// Per pixel (row-major): the stencil decides its class.
    pub(crate) decides: Vec<bool>,
    /// The eye depth with every other pixel background.
    target: Option<DepthTarget>,
    /// Whether `target` holds this frame's masked depth; otherwise the eye
    /// target itself serves.
    masked: bool,
    /// Whether `decides` and the masked depth are this frame's.
    fresh: bool,
    /// Tests: draw on the whole eye depth.
    #[cfg(test)]
    pub(crate) keep_all: bool,
}

impl ShadowableScratch {
    /// Drops the last masked depth: [`ShadowableScratch::target`] is the
    /// eye target until the next [`ShadowableScratch::mask`].
    pub(crate) fn forget(&mut self) {
        (self.masked, self.fresh) = (false, false);
    }

    /// Whether [`ShadowableScratch::mask`] ran since the last
    /// [`ShadowableScratch::forget`].
    pub(crate) fn fresh(&self) -> bool {
        self.fresh
    }

    /// Makes the masked depth of `eye` from `decides`, when `left` (some
    /// visible pixel is left to its class; otherwise the eye target
    /// serves as it is).
    ///
    /// # Errors
    /// Rasterizer errors (a `decides` that does not fit the eye target).
    pub(crate) fn mask(&mut self, eye: &DepthTarget, left: bool) -> Result<()> {
        (self.masked, self.fresh) = (left, true);
        #[cfg(test)]
        if self.keep_all {
            self.masked = false;
        }
        if !self.masked {
            return Ok(());
        }
        let (w, h, tile) = (eye.width(), eye.height(), eye.tile_size());
        let target = match self.target.take() {
            Some(t) if (t.width(), t.height(), t.tile_size()) == (w, h, tile) => t,
            _ => DepthTarget::new(w, h, tile, false)?,
        };
        self.target
            .insert(target)
            .copy_kept_from(eye, &self.decides)?;
        Ok(())
    }

    /// The depth the stencil draws on: the masked copy of the last
    /// [`ShadowableScratch::mask`], or `eye` when it made none.
    pub(crate) fn target<'a>(&'a self, eye: &'a DepthTarget) -> &'a DepthTarget {
        match &self.target {
            Some(t) if self.masked => t,
            _ => eye,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::mask::is_unlit;
    use crate::pipeline::{
        eye_pass, shadow_mask, Backend, MeshCache, ShadowOptions, ShadowScratch,
    };
    use glam::DVec3;
    use raster::{StencilBits, StencilStats, TileSize};
    use scene::Light;

    /// On the city's street, under a point light and a sun, one- and
    /// two-sided: the stencil decides exactly the pixels of receivers its
    /// light reaches, the masked depth keeps exactly those, and the
    /// brute-force and hierarchical stencils drawn on it give the mask they
    /// give on the whole eye depth, for fewer fragments and tile tests.
    #[test]
    fn the_masked_stencil_gives_the_same_mask_for_less_work() {
        let (scene, camera) = crate::pipeline::eye::tests::small_street();
        let meshes = MeshCache::new(&scene);
        let (w, h) = (320, 240);
        let eye = eye_pass(&scene, &meshes, &camera, w, h).unwrap();
        let lights = [
            Light::Point {
                position: DVec3::new(20.0, 120.0, -30.0),
                range: None,
            },
            Light::Directional {
                direction: DVec3::new(-0.6, -0.5, -0.4),
            },
        ];
        let backends = [
            Backend::Brute,
            Backend::Hierarchical {
                tile: TileSize::T8,
                full_shadow: true,
            },
        ];
        let surface = eye.surface();
        for light in &lights {
            for two_sided in [false, true] {
                for backend in backends {
                    let options = ShadowOptions {
                        backend,
                        two_sided,
                        bits: StencilBits::Wide,
                        ..Default::default()
                    };
                    let run = |keep_all: bool| {
                        let mut scratch = ShadowScratch::default();
                        scratch.shadowable.keep_all = keep_all;
                        let f = shadow_mask(&scene, &camera, light, &eye, &options, &mut scratch)
                            .unwrap();
                        (f, scratch)
                    };
                    let (whole, _) = run(true);
                    let (masked, scratch) = run(false);
                    let what = format!("{light:?} two-sided {two_sided} {backend:?}");
                    assert_eq!(masked.mask, whole.mask, "{what}");
                    let work = |s: &StencilStats| s.pixels_processed + s.h_fragments;
                    let (m, a) = (&masked.stencil, &whole.stencil);
                    assert!(work(m) < work(a), "{what}: {m:?} against {a:?}");
                    assert!(m.tile_tests <= a.tile_tests, "{what}");
                    // The stencil's pixels, and the depth it drew on.
                    let sh = &scratch.shadowable;
                    let on = sh.target(&eye.target);
                    let mut dropped = 0;
                    for y in 0..h {
                        for x in 0..w {
                            let decides = surface.primitive(x, y).is_some_and(|(o, k)| {
                                let tri = scene.world_triangle(o, k as usize);
                                scene.object(o).flags.receives
                                    && !is_unlit(&tri, camera.position, light, tri[0], two_sided)
                            });
                            assert_eq!(sh.decides[(y * w + x) as usize], decides, "{what}");
                            let depth = eye.target.depth_at(x, y);
                            let want = if decides { depth } else { None };
                            assert_eq!(on.depth_at(x, y), want, "{what} ({x}, {y})");
                            dropped += usize::from(!decides && depth.is_some());
                        }
                    }
                    assert!(dropped > 1000, "{what}: {dropped} pixels dropped");
                }
            }
        }
    }
}
