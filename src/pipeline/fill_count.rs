//! Fill accounting (`count_fill`): the brute-force pixels processed that one
//! light's volumes cost without and with continuous clamping — the fill
//! clamping exists to save [Steiner §4.4, eq. 4.3] — on any backend.
//!
//! The frame's own volumes are counted as drawn: by the stencil pass itself
//! when the backend is brute force, else by a brute-force pass into a scratch
//! stencil. The other variant (clamped when the frame is not, unclamped when
//! it is) is built beside them from the same casters, with its own volume
//! state, and counted the same way. Both counts use the frame's scissor and
//! depth-bounds tests, so they are what `bf` (or `db`) would process.

use super::shadow_options::{Backend, ClampOptions, ShadowInput, ShadowOptions};
use super::volume::{build_for, VolumeScratch};
use crate::Result;
use raster::{DepthTarget, StencilBits, StencilStats, StencilTarget, VolumeBuffer, VolumeRange};
use scene::ObjectId;

/// The counting's state kept per light between frames.
#[derive(Default)]
pub(crate) struct FillScratch {
    /// The variant the frame does not draw: its silhouettes, buffer and
    /// clamping state.
    other: VolumeScratch,
    /// The scratch stencil of the counting passes.
    target: Option<StencilTarget>,
}

/// One light's counts: brute-force pixels processed by its volumes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct FillCounts {
    pub(crate) unclamped: u64,
    pub(crate) clamped: u64,
}

/// What the frame drew for the light.
pub(crate) struct Drawn<'a> {
    /// Its volumes.
    pub(crate) buffer: &'a VolumeBuffer,
    /// Its stencil counters, when a stencil ran.
    pub(crate) stencil: Option<&'a StencilStats>,
}

/// The clamped variant's options, used when the frame draws unclamped volumes.
#[derive(Clone, Copy)]
pub(crate) struct ClampedVariant<'a> {
    /// Receivers and costs.
    pub(crate) options: ClampOptions,
    /// The receiver set, as in [`build_for`].
    pub(crate) receives: Option<&'a [bool]>,
    /// The fragment receivers, as in [`build_for`].
    pub(crate) fragments: Option<super::volume::Readings<'a>>,
}

/// Counts the brute-force fill of `drawn` and of the variant the frame did
/// not draw.
///
/// # Errors
/// As [`build_for`], and rasterizer errors.
pub(crate) fn count_fill(
    input: ShadowInput<'_>,
    eye: &DepthTarget,
    casters: &[ObjectId],
    options: &ShadowOptions,
    clamped: ClampedVariant<'_>,
    drawn: Drawn<'_>,
    scratch: &mut FillScratch,
) -> Result<FillCounts> {
    let viewport = (eye.width(), eye.height());
    let drawn_pixels = match (options.backend, drawn.stencil) {
        (Backend::Brute, Some(s)) => s.pixels_processed,
        _ => brute_pixels(input, eye, drawn.buffer, options, &mut scratch.target)?,
    };
    let other_options = ShadowOptions {
        clamping: match options.clamping {
            Some(_) => None,
            None => Some(clamped.options),
        },
        ..*options
    };
    build_for(
        input,
        casters,
        &other_options,
        viewport,
        clamped.receives,
        clamped.fragments,
        &mut scratch.other,
    )?;
    let other_pixels = brute_pixels(
        input,
        eye,
        &scratch.other.buffer,
        options,
        &mut scratch.target,
    )?;
    Ok(match options.clamping {
        Some(_) => FillCounts {
            unclamped: other_pixels,
            clamped: drawn_pixels,
        },
        None => FillCounts {
            unclamped: drawn_pixels,
            clamped: other_pixels,
        },
    })
}

/// The pixels a brute-force pass over `buffer` processes on `eye` under the
/// options' scissor and depth-bounds tests, drawn into `target` (kept).
fn brute_pixels(
    input: ShadowInput<'_>,
    eye: &DepthTarget,
    buffer: &VolumeBuffer,
    options: &ShadowOptions,
    target: &mut Option<StencilTarget>,
) -> Result<u64> {
    let (w, h) = (eye.width(), eye.height());
    let stencil = match target {
        Some(s) if (s.width(), s.height()) == (w, h) => {
            s.clear();
            s
        }
        _ => target.insert(StencilTarget::new(w, h, StencilBits::Eight)?),
    };
    let ranges: Vec<(glam::Mat4, &VolumeRange)> = buffer
        .ranges
        .iter()
        .map(|r| {
            let clip = scene::transform::clip_from_local(input.camera, &r.world_from_local);
            (clip, r)
        })
        .collect();
    let tests = raster::StencilTests {
        scissor: options.scissor,
        depth_bounds: options.depth_bounds,
    };
    let mut stats = StencilStats::default();
    stencil.draw_volumes(eye, &ranges, buffer, tests, &mut stats)?;
    Ok(stats.pixels_processed)
}
