//! The host's own depth ([`super::FrameInput::host_depth`]): a GPU host that runs a
//! depth pre-pass hands the pipeline a coarse copy of this frame's depth
//! buffer, and the eye's culling pass becomes queries against it — no CPU
//! eye raster runs. PSR and the light passes' receivers come from it as
//! from the pipeline's own coarse pass (`coarse_receivers.rs`).
//!
//! Why it is exact: each coarse pixel holds the farthest depth over the
//! output pixels whose centres lie in it. An object that owns an output
//! pixel is at that pixel's depth there, so its box's nearest depth is not
//! behind the coarse pixel's value, and its query (outer-conservative, at the
//! nearest depth, ties visible) passes: PSR holds it. A receiver point seen
//! at an output pixel is likewise not behind its coarse pixel's value, which
//! is all the coarse receivers assume. So the rules of a coarse pass hold
//! with the host's depth in place of the pipeline's occluders, as long as
//! the depth is of this frame: the same camera and the same scene. An
//! earlier frame's depth is not a bound on this frame's surfaces (what moved
//! in front of it would be culled): it is refused by its camera
//! ([`HostDepth::camera`]).
//!
//! What the host's depth may hold beyond the pipeline's scene: nothing that
//! should receive the pipeline's shadows. A surface only the host draws hides
//! what is behind it (as the GPU's own depth test will), but it is not a
//! receiver the light passes know of.

use crate::{Error, Result};
use scene::Camera;
use std::sync::Arc;

/// A host's coarse depth buffer of this frame ([`super::FrameInput::host_depth`]).
///
/// Reversed Z as the library's eye ([`Camera`]: `near / view distance`, 1
/// at the near plane, 0 at infinity). Coarse pixel `(x, y)` of a
/// `width × height` buffer covers the output pixels `(i, j)` of a `W × H`
/// viewport whose centres `(i + ½, j + ½)` lie in the square
/// `[x·W/width, (x+1)·W/width] × [y·H/height, (y+1)·H/height]`; it holds the
/// least depth (the farthest) over them, 0 where any of them shows nothing.
/// [`HostDepth::reduce`] makes one from an output-resolution buffer, as a
/// host's compute pass (a min-reduction) would.
#[derive(Clone, Debug)]
pub struct HostDepth {
    /// The camera the depth was rendered with: the frame's own
    /// ([`super::FrameInput::camera`]); a depth from another camera (an earlier
    /// frame's) is refused, since it bounds nothing of this frame.
    pub camera: Camera,
    /// Width in coarse pixels: the frame's culling size
    /// ([`crate::PipelineOptions::culling_size`] of the viewport).
    pub width: u32,
    /// Height in coarse pixels.
    pub height: u32,
    /// `width × height` depths, row-major, row 0 at the top, each in
    /// `0 ..= 1`.
    pub depth: Arc<[f32]>,
}

impl HostDepth {
    /// The coarse buffer of `width × height` of an output-resolution depth
    /// buffer `depth` (`output.0 × output.1` values, row-major, row 0 at the
    /// top, the same convention; 0 for nothing drawn) seen by `camera`: per
    /// coarse pixel the least value over the output pixels whose centres lie
    /// in it (a centre on a boundary counts for both sides).
    ///
    /// # Errors
    /// [`Error::Options`] naming `host_depth` when `depth` does not hold
    /// `output.0 × output.1` values, or a size is 0 or the coarse one
    /// exceeds the output.
    pub fn reduce(
        camera: Camera,
        output: (u32, u32),
        depth: &[f32],
        (width, height): (u32, u32),
    ) -> Result<HostDepth> {
        let (w, h) = output;
        if w == 0 || h == 0 || width == 0 || height == 0 || width > w || height > h {
            return Err(field_error(format!(
                "cannot reduce {w}×{h} to {width}×{height}"
            )));
        }
        if depth.len() != w as usize * h as usize {
            return Err(field_error(format!(
                "{} values for a {w}×{h} buffer",
                depth.len()
            )));
        }
        let mut out = vec![f32::INFINITY; width as usize * height as usize];
        // The coarse cells whose closed square holds the centre `i + ½` of
        // `n` output pixels mapped onto `m` cells.
        let cells = |i: u32, n: u32, m: u32| {
            let twice = u64::from(2 * i + 1) * u64::from(m);
            let n2 = 2 * u64::from(n);
            let c = (twice / n2) as u32;
            let on_edge = twice % n2 == 0 && c > 0;
            (if on_edge { c - 1 } else { c })..=c.min(m - 1)
        };
        for j in 0..h {
            for cy in cells(j, h, height) {
                let row = &mut out[(cy * width) as usize..((cy + 1) * width) as usize];
                let src = &depth[(j * w) as usize..((j + 1) * w) as usize];
                for (i, &d) in src.iter().enumerate() {
                    for cx in cells(i as u32, w, width) {
                        let v = &mut row[cx as usize];
                        *v = v.min(d.max(0.0));
                    }
                }
            }
        }
        Ok(HostDepth {
            camera,
            width,
            height,
            depth: out.into(),
        })
    }

    /// Checks this depth against the frame it comes with: the frame's
    /// `camera`, its culling size `size` (of the `viewport`), and every
    /// value in `0 ..= 1`.
    pub(crate) fn check(
        &self,
        camera: &Camera,
        viewport: (u32, u32),
        size: (u32, u32),
    ) -> Result<()> {
        if self.camera != *camera {
            return Err(field_error(
                "rendered from another camera than the frame's (an earlier frame's depth \
                 bounds nothing of this one: give this frame's pre-pass)"
                    .into(),
            ));
        }
        if (self.width, self.height) != size {
            return Err(field_error(format!(
                "{}×{} is not the frame's culling size {}×{} (culling_resolution within \
                 the {}×{} viewport)",
                self.width, self.height, size.0, size.1, viewport.0, viewport.1
            )));
        }
        if self.depth.len() != size.0 as usize * size.1 as usize {
            return Err(field_error(format!(
                "{} values for {}×{}",
                self.depth.len(),
                size.0,
                size.1
            )));
        }
        if let Some(k) = self.depth.iter().position(|d| !(0.0..=1.0).contains(d)) {
            let (x, y) = (k as u32 % size.0, k as u32 / size.0);
            return Err(field_error(format!(
                "pixel ({x}, {y}) holds {}, not a depth in 0..=1 (reversed Z: near / view \
                 distance)",
                self.depth[k]
            )));
        }
        Ok(())
    }
}

fn field_error(message: String) -> Error {
    Error::Options {
        field: "host_depth".into(),
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        scene::LookAt {
            eye: glam::DVec3::ZERO,
            target: glam::DVec3::NEG_Z,
            up: glam::DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
        }
        .camera(1.0)
        .unwrap()
    }

    /// Each coarse pixel is the least of the output pixels whose centres it
    /// holds, with centres on a boundary counted for both sides (3 → 2).
    #[test]
    fn a_reduction_takes_the_farthest_centre_of_each_cell() {
        let depth: Vec<f32> = (0..36).map(|k| 0.01 * (k + 1) as f32).collect();
        let d = HostDepth::reduce(camera(), (6, 6), &depth, (3, 3)).unwrap();
        // 2 × 2 output pixels a cell: its top-left one is its least.
        for (cy, cx) in (0..3).flat_map(|y| (0..3).map(move |x| (y, x))) {
            let least = depth[(2 * cy * 6 + 2 * cx) as usize];
            assert_eq!(d.depth[(cy * 3 + cx) as usize], least);
        }
        // 3 → 2: the middle pixel's centre (1.5 · 2/3 = 1) lies on the edge.
        let depth = [0.9, 0.2, 0.8, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9];
        let d = HostDepth::reduce(camera(), (3, 3), &depth, (2, 2)).unwrap();
        assert_eq!(&d.depth[..], &[0.2, 0.2, 0.9, 0.9]);
        assert!(HostDepth::reduce(camera(), (3, 3), &depth[1..], (2, 2)).is_err());
        assert!(HostDepth::reduce(camera(), (3, 3), &depth, (4, 2)).is_err());
    }

    /// The frame's camera, its culling size and depths in 0..=1, each
    /// refused by name.
    #[test]
    fn a_depth_must_be_of_the_frame() {
        let input = (camera(), (8, 8));
        let d = HostDepth::reduce(camera(), (8, 8), &[0.5; 64], (4, 4)).unwrap();
        d.check(&input.0, input.1, (4, 4)).unwrap();
        let e = d.check(&input.0, input.1, (2, 2)).unwrap_err().to_string();
        assert!(
            e.contains("host_depth") && e.contains("culling size"),
            "{e}"
        );
        let mut moved = d.clone();
        moved.camera.position.x += 1.0;
        let e = moved
            .check(&input.0, input.1, (4, 4))
            .unwrap_err()
            .to_string();
        assert!(e.contains("another camera"), "{e}");
        for bad in [f32::NAN, -0.5, 1.5] {
            let mut v = vec![0.5; 16];
            v[6] = bad;
            let d = HostDepth {
                depth: v.into(),
                ..d.clone()
            };
            let e = d.check(&input.0, input.1, (4, 4)).unwrap_err().to_string();
            assert!(e.contains("pixel (2, 1)"), "{e}");
        }
    }
}
