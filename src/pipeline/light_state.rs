//! A light's identity ([`LightId`]) and everything a pipeline keeps per
//! light from frame to frame ([`LightState`]): its culling state and
//! `auto` choices, caches, volume buffer, stencil targets and last result.

use super::auto;
use super::light::LightCulling;
use super::options::ClampingSpec;
use super::stencil::{ShadowFrame, ShadowScratch};
use crate::stats::ShadowStats;
use scene::{Light, LightId, ObjectId};
use shadowgen::VolumeStats;

/// One light's persistent state and last result.
#[derive(Debug)]
pub(super) struct LightState {
    pub(super) light: Light,
    pub(super) id: LightId,
    pub(super) culling: LightCulling,
    /// `culling: auto`'s choice state of the light pass.
    pub(super) auto: auto::AutoView,
    /// `stencil: auto`'s choice state of the stencil, one for frames whose
    /// light pass culls and one for frames that draw every caster: the two
    /// stencils' costs compare only over the same casters.
    pub(super) stencil_auto: [auto::AutoView; 2],
    /// `clamping: auto`'s choice states: clamping or not, and among
    /// clamped frames discrete or continuous.
    pub(super) clamp_auto: [auto::AutoView; 2],
    /// This frame's clamping.
    pub(super) clamping: ClampingSpec,
    /// Whether this frame runs the light pass (culls the casters).
    pub(super) culled: bool,
    /// This frame's bit in the receiver points' skip masks (0: it takes
    /// every point; `Pipeline::receiver_skips`).
    pub(super) skip_bit: u32,
    /// The last PSC as public ids (slot and generation), ascending.
    pub(super) psc: Vec<ObjectId>,
    /// This frame's casters (the PSC less non-casters), reused.
    pub(super) casters: Vec<ObjectId>,
    pub(super) scratch: ShadowScratch,
    pub(super) volume_stats: VolumeStats,
    pub(super) stats: ShadowStats,
    pub(super) shadow: Option<ShadowFrame>,
}

impl LightState {
    pub(super) fn new(light: Light, id: LightId) -> Self {
        LightState {
            light,
            id,
            culling: LightCulling::default(),
            auto: auto::AutoView::culling(),
            stencil_auto: [auto::AutoView::stencil(), auto::AutoView::stencil()],
            clamp_auto: [auto::AutoView::stencil(), auto::AutoView::stencil()],
            clamping: ClampingSpec::None,
            culled: false,
            skip_bit: 0,
            psc: Vec::new(),
            casters: Vec::new(),
            scratch: ShadowScratch::default(),
            volume_stats: VolumeStats::default(),
            stats: ShadowStats::default(),
            shadow: None,
        }
    }
}

/// A light slot: its generation and, while the light exists, its state.
#[derive(Debug, Default)]
pub(super) struct LightSlot {
    pub(super) generation: u32,
    pub(super) state: Option<LightState>,
}
