//! The light stage [Steiner §4.3]: per light, the light views fitted to the
//! intersection body B = conv(V ∪ l) ∩ S [Steiner §4.3.3], the eye's visible
//! surface points marked as receivers, and a CHC traversal per view that
//! finds the potential shadow casters (PSC) — [`visibility::LightPass`]. The
//! lights are independent (each owns its views' state): each light's pass
//! starts its share of the frame (`light_frame.rs`), and the shares run in
//! parallel.

use crate::Result;
use scene::Light;
use std::time::Instant;
use visibility::{
    FragmentSource, LightPass, LightPassOptions, LightPassResult, PassInput, SliceRatio,
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

/// What every light's pass of one frame reads.
pub(crate) struct LightPassInput<'a> {
    /// The objects, the eye and its visible surface.
    pub pass: PassInput<'a>,
    /// The host's occlusion backends, if it brings its own.
    pub backends: Option<&'a visibility::BackendFactory>,
    /// Light-pass options.
    pub options: &'a LightPassOptions,
    /// The job frame number.
    pub frame: u32,
    /// The viewport and the number of slices: a light reading
    /// [`Reading::Slices`] reads its casters' occupied slices of its own
    /// [`shadowgen::EyeSlices`].
    pub slices: ((u32, u32), u32),
}

// The bands are read as slices.
const _: () = assert!(shadowgen::BAND_SLICES as usize <= visibility::MAX_SLICES);

/// What one light's pass reads for clamping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reading {
    /// Nothing.
    None,
    /// Fragment intervals along each caster's axis (`pass.fragments`, the
    /// axes), and its bands: its occupied slices of the light's
    /// [`shadowgen::EyeSlices`] of [`shadowgen::BAND_SLICES`].
    Axes,
    /// Occupied slices of the light's [`shadowgen::EyeSlices`].
    Slices,
}

/// Runs one light's pass: `light`, its key for the host's backend factory
/// and its bit in the receiver points' skip masks, its culling state (whose
/// `result` and `ms` are replaced) and what it reads for clamping.
///
/// # Errors
/// The pass's error.
pub(crate) fn light_pass(
    light: Light,
    (key, skip): (scene::LightId, u32),
    c: &mut LightCulling,
    reading: Reading,
    input: &LightPassInput<'_>,
) -> Result<()> {
    let t = Instant::now();
    c.pass.set_frame(input.frame);
    let mut edges = [0.0; visibility::MAX_SLICES + 1];
    let mut pass = input.pass;
    pass.skip_receivers = skip;
    let (viewport, n) = input.slices;
    // Continuous clamping also reads each caster's bands: its occupied
    // slices at the finest count (`shadowgen`'s `bands.rs`).
    let (axes, count) = match reading {
        Reading::None => (None, None),
        Reading::Axes => (
            input.pass.fragments.and_then(|f| f.axes),
            Some(shadowgen::BAND_SLICES),
        ),
        Reading::Slices => (None, Some(n)),
    };
    let slices = count.and_then(|n| {
        shadowgen::EyeSlices::new(pass.camera, viewport, &light, n).map(|s| {
            let edges = &mut edges[..=n as usize];
            for (i, e) in edges.iter_mut().enumerate() {
                *e = s.edge(i as u32);
            }
            let (num, den) = s.world_ratio();
            let edges = &*edges;
            SliceRatio { num, den, edges }
        })
    });
    pass.fragments = (reading != Reading::None).then_some(FragmentSource { axes, slices });
    c.pass.run_into(
        &pass,
        &light,
        input.options,
        input.backends.map(|f| (f, key)),
        &mut c.result,
    )?;
    c.ms = t.elapsed().as_secs_f64() * 1e3;
    Ok(())
}
