//! The light stage [Steiner §4.3]: per light, the light views fitted to the
//! intersection body B = conv(V ∪ l) ∩ S [Steiner §4.3.3], the eye's visible
//! surface points marked as receivers, and a CHC traversal per view that
//! finds the potential shadow casters (PSC) — [`visibility::LightPass`]. The
//! lights are independent (each owns its views' state) and run in parallel.

use crate::Result;
use scene::{Camera, Scene};
use std::time::Instant;
use visibility::{
    Hierarchy, LightPass, LightPassOptions, LightPassResult, MeshData, ReceiverPoints,
};

/// One light's light-pass state and its last result.
#[derive(Debug, Default)]
pub(crate) struct LightCulling {
    /// Per-view CHC state, targets and the last views.
    pub pass: LightPass,
    /// The last PSC (ascending) and traversal counters; its list is reused.
    pub result: LightPassResult,
    /// The last pass's wall time (ms).
    pub ms: f64,
}

/// Runs the light pass of every live light of `slots` concurrently for job
/// frame `frame`; each light's `culling.result` and `ms` are replaced.
///
/// # Errors
/// The first light's error.
#[allow(clippy::too_many_arguments)]
pub(crate) fn light_passes(
    slots: &mut [super::LightSlot],
    backends: Option<&visibility::BackendFactory>,
    hierarchy: &Hierarchy,
    scene: &Scene,
    meshes: &MeshData,
    camera: &Camera,
    receivers: &ReceiverPoints,
    options: &LightPassOptions,
    frame: u32,
) -> Result<()> {
    use rayon::prelude::*;
    slots
        .par_iter_mut()
        .filter_map(|slot| slot.state.as_mut())
        .map(|state| {
            let t = Instant::now();
            let (light, key) = (state.light, state.id.0);
            let c = &mut state.culling;
            c.pass.set_frame(frame);
            c.pass.run_into(
                hierarchy,
                scene,
                meshes,
                camera,
                &light,
                receivers,
                options,
                backends.map(|f| (f, key)),
                &mut c.result,
            )?;
            c.ms = t.elapsed().as_secs_f64() * 1e3;
            Ok(())
        })
        .collect::<std::result::Result<(), visibility::Error>>()?;
    Ok(())
}
