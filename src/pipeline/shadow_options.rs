//! The options of the volume and stencil stages ([`ShadowOptions`]): which
//! backend draws the volumes and which tests it runs. [`super::PipelineOptions::shadow_options`]
//! maps the job's options onto them.

use raster::{StencilBits, TileSize};
use scene::{Camera, Light, Scene};
use serde::{Deserialize, Serialize};
use shadowgen::MethodChoice;

/// Which stencil backend draws the volumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Brute force: every volume fragment ([`raster::StencilTarget`]).
    Brute,
    /// Hierarchical shadow volumes \[Aila04\] ([`raster::HierarchicalStencil`]).
    Hierarchical {
        /// Tile size of the classification.
        tile: TileSize,
        /// The full-shadow bit [Aila04 §4.3.2].
        full_shadow: bool,
    },
    /// A shadow map decides every pixel whose four nearest map comparisons
    /// agree; the volumes (brute force with scissor rectangles and depth bounds) run only at
    /// the others \[ChanDurand04\]. Not exact. The maps are the light pass's
    /// light views when the pipeline gives them, else its own.
    Hybrid {
        /// Its own maps' texels per side (per cube face for point lights).
        map_size: u32,
    },
}

/// Options of the shadow stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowOptions {
    /// Stencil backend.
    pub backend: Backend,
    /// Volume method per caster.
    pub method: MethodChoice,
    /// Every triangle casts (matches the reference's two-sided mode).
    pub two_sided: bool,
    /// 8-bit wrapping stencil or wide counters.
    pub bits: StencilBits,
    /// Per-volume scissor test ([`raster::VolumeRange::scissor`]).
    pub scissor: bool,
    /// Per-volume depth-bounds test (`stencil: db`).
    pub depth_bounds: bool,
    /// Point and spot lights with a range extrude their volumes finitely
    /// ([`shadowgen::BuildOptions::finite_extrusion`]).
    pub finite_extrusion: bool,
    /// Continuous or discrete clamping [Steiner §4.4]; `None`: off.
    pub clamping: Option<ClampOptions>,
}

/// Which objects count as receivers for clamping (`clamping_receivers: all`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ClampReceiversSpec {
    /// Every receiving object: the thesis's setting, independent of the view.
    #[default]
    All,
    /// The eye pass's potentially visible receivers (PSR): tighter, but
    /// view-dependent. Without culling every receiving object counts.
    Psr,
    /// Fragment receivers [Steiner Fig. 4.16]: the eye's visible surface as
    /// the light pass marks it, with the nearest and farthest depth per
    /// light pixel, read over each caster's light-view footprint
    /// (`visibility::FragmentDepths`). The tightest, recomputed every
    /// frame. The light pass then marks tighter depths (per light pixel,
    /// the part of a receiver segment over it) and also the eye's surface
    /// as the stencil tests it (the stored depths), so its PSC may differ
    /// from the other models' (conservative all the same). A light the
    /// frame does not cull (`culling: none`, or `auto` choosing none) has
    /// no light pass and clamps to every receiving object, as `all`.
    Fragment,
}

/// Options of continuous clamping in the shadow stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClampOptions {
    /// Which objects count as receivers.
    pub receivers: ClampReceiversSpec,
    /// v of the gap cost model ([`shadowgen::GapCost`]).
    pub vertex_cost: f64,
    /// r of the gap cost model.
    pub pixel_cost: f64,
    /// Discrete clamping's number of slices; `None`: continuous clamping.
    pub slices: Option<u32>,
}

impl Default for ShadowOptions {
    fn default() -> Self {
        ShadowOptions {
            backend: Backend::Brute,
            method: MethodChoice::Auto,
            two_sided: false,
            bits: StencilBits::Eight,
            scissor: false,
            depth_bounds: false,
            finite_extrusion: false,
            clamping: None,
        }
    }
}

/// What one light's volumes and stencil are computed for.
#[derive(Clone, Copy)]
pub(crate) struct ShadowInput<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// The eye.
    pub camera: &'a Camera,
    /// The light.
    pub light: &'a Light,
}
