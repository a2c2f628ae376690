//! The light stage [Steiner §4.3]: per light, the light views fitted to the
//! intersection body B = conv(V ∪ l) ∩ S [Steiner §4.3.3], the eye's visible
//! surface points marked as receivers, and a CHC traversal per view that
//! finds the potential shadow casters (PSC) — [`visibility::LightPass`]. The
//! lights are independent (each owns its views' state) and run in parallel.

use crate::Result;
use scene::{Camera, Light, ObjectId, Scene};
use std::time::Instant;
use visibility::{
    Hierarchy, LightPass, LightPassOptions, MeshData, ReceiverPoints, TraversalStats,
};

/// One light's light-pass state and its last result.
#[derive(Debug, Default)]
pub(crate) struct LightCulling {
    /// Per-view CHC state, targets and the last views.
    pub pass: LightPass,
    /// The last PSC, ascending.
    pub psc: Vec<ObjectId>,
    /// The last pass's traversal counters.
    pub stats: TraversalStats,
    /// The last pass's wall time (ms).
    pub ms: f64,
}

/// Runs the light pass of every light, `states[i]` for `lights[i]`,
/// concurrently; each state's `psc`, `stats` and `ms` are replaced.
///
/// # Errors
/// The first light's error (an invalid light names its field).
#[allow(clippy::too_many_arguments)]
pub(crate) fn light_passes<'s>(
    states: impl rayon::iter::IndexedParallelIterator<Item = &'s mut LightCulling>,
    lights: &[Light],
    hierarchy: &Hierarchy,
    scene: &Scene,
    meshes: &MeshData,
    camera: &Camera,
    receivers: &ReceiverPoints,
    options: &LightPassOptions,
) -> Result<()> {
    use rayon::prelude::*;
    states
        .zip(lights)
        .map(|(state, light)| {
            let t = Instant::now();
            let r = state
                .pass
                .run(hierarchy, scene, meshes, camera, light, receivers, options)?;
            state.psc = r.psc;
            state.stats = r.stats;
            state.ms = t.elapsed().as_secs_f64() * 1e3;
            Ok(())
        })
        .collect::<std::result::Result<(), visibility::Error>>()?;
    Ok(())
}
