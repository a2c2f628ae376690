//! The volume stage: one light's shadow volumes for its casters —
//! silhouettes by signed edge counters, cached while caster and light are
//! static [AW §2.4, Steiner §4.2], the per-caster zpass/zfail/zp+ choice
//! [EK, Steiner §3.2.1], w = 0 extrusion, and the scissor rectangles and depth
//! bounds the stencil tests use — into a caller-owned
//! [`raster::VolumeBuffer`] ([`shadowgen::build_volumes`]).

use super::shadow_options::{ShadowInput, ShadowOptions};
use crate::Result;
use raster::VolumeBuffer;
use scene::ObjectId;
use shadowgen::{build_volumes, BuildOptions, SilhouetteCache, VolumeStats};

/// Builds the volumes of `casters` for `light` into `out` (cleared first)
/// with the shadow stage's method and extrusion options; scissor rectangles
/// and depth bounds are computed only when a stencil test uses them (they cost
/// time), for a `viewport` of `(width, height)` pixels.
///
/// # Errors
/// An invalid light or caster id ([`crate::Error::Shadowgen`]).
pub(crate) fn build_for(
    input: ShadowInput<'_>,
    casters: &[ObjectId],
    options: &ShadowOptions,
    viewport: (u32, u32),
    out: &mut VolumeBuffer,
    cache: &mut SilhouetteCache,
) -> Result<VolumeStats> {
    let ShadowInput {
        scene,
        camera,
        light,
    } = input;
    let build = BuildOptions {
        method: options.method,
        two_sided: options.two_sided,
        viewport: (options.scissor || options.depth_bounds).then_some(viewport),
        finite_extrusion: options.finite_extrusion,
    };
    let stats = build_volumes(out, scene, camera, light, casters, build, cache)?;
    out.reserve_headroom();
    Ok(stats)
}
