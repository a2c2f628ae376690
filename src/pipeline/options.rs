//! The pipeline's options: what [`super::Pipeline`] computes and how. The
//! RON job's `pipeline` section deserializes straight into
//! [`PipelineOptions`]; [`PipelineOptions::shadow_options`],
//! [`PipelineOptions::culling`] and [`PipelineOptions::light_pass_options`]
//! are the one place they map onto the stages' own option types.

use raster::StencilBits;
use serde::{Deserialize, Serialize};
use shadowgen::MethodChoice;

pub use super::shadow_options::ClampReceiversSpec;

/// Stencil backend (`stencil: bf`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StencilBackend {
    /// Brute force: every volume fragment on a non-background pixel.
    #[default]
    Bf,
    /// Brute force with the per-volume depth-bounds test [EK "Computing Depth Bounds"].
    Db,
    /// Hierarchical shadow volumes \[Aila04\] (`tile`, `full_shadow`).
    H,
    /// Shadow map plus volumes at its silhouette pixels \[ChanDurand04\]: the
    /// light pass's light views as maps, or its own (`map_size`).
    Hybrid,
    /// No CPU stencil and no mask: PSR, PSC and the volumes only, for a host
    /// that draws the volumes on its GPU.
    None,
    /// Per light and per frame, `h` or `db` with scissor rectangles,
    /// whichever the cost model of [`AutoSpec::stencil`] finds cheaper from
    /// the counters of earlier frames (never from timers): see
    /// `src/pipeline/auto.rs` for the rule. The mask is the same either way.
    Auto,
}

/// Occlusion culling (`culling: chc`) of the eye pass (PSR) and of the light
/// views (PSC: shadow volumes only for potential casters) [Steiner §2.5.1, §4.3].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CullingSpec {
    /// Draw every object.
    None,
    /// View-frustum culling.
    Frustum,
    /// Stop-and-wait hierarchical occlusion culling.
    Exact,
    /// Coherent hierarchical culling.
    Chc,
    /// CHC++: batched queries, multiqueries, revisits (`chcpp`).
    Chcpp,
    /// Per view (the eye, each light) and per frame, CHC++ or no culling,
    /// whichever the cost model of [`AutoSpec`] finds cheaper from the
    /// counters of earlier frames (never from timers): see
    /// `src/pipeline/auto.rs` for the rule. The mask is the unculled one.
    /// The default: it is never far from the best fixed choice, and a
    /// scene of fewer than `auto.min_objects` objects never culls.
    #[default]
    Auto,
}

/// How culling samples pixels (`coverage: conservative`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CoverageSpec {
    /// Conservative queries, occluders and receivers: the mask equals the
    /// unculled one.
    #[default]
    Conservative,
    /// Pixel-centre sampling (aggressive; its mismatch is measured).
    Point,
}

impl CoverageSpec {
    /// The traversals' sampling.
    pub fn sampling(self) -> visibility::Sampling {
        match self {
            CoverageSpec::Conservative => visibility::Sampling::Conservative,
            CoverageSpec::Point => visibility::Sampling::Point,
        }
    }
}

/// What the light views draw as occluders (`occluders: proxy`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum OccludersSpec {
    /// Every object's own mesh (its light-facing triangles).
    #[default]
    Mesh,
    /// Each object's host-given occluder ([`crate::Pipeline::set_occluder`])
    /// where it has one; else each solid convex mesh's proxy
    /// ([`scene::occluder_proxy`]: the hull of 16 of its vertices, inside
    /// the solid, conservative); other meshes (open, non-convex, or with few
    /// triangles) their own. Not with the hybrid's point-sampled shadow
    /// maps, which keep the casters' surfaces.
    Proxy,
}

/// Shadow-volume clamping (`clamping: continuous`) [Steiner §4.4].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ClampingSpec {
    /// Volumes extrude to infinity (or to the finite-extrusion distance).
    #[default]
    None,
    /// Continuous clamping: each caster's volume is cut into segments over
    /// the depth intervals its receivers occupy in the light's view
    /// (sweep-and-prune, [`shadowgen::LightClamp`]). The mask is unchanged.
    Continuous,
    /// Discrete clamping [Steiner §4.4.2]: the view is cut into `slices`
    /// strips by planes through the eye that face the light
    /// ([`shadowgen::EyeSlices`]), and each caster's volume is drawn only
    /// in the strips where the light pass finds the eye's visible surface
    /// in its shadow (`visibility::SliceRatio`). The planes are edge-on for
    /// the eye, so the segments' caps cost no fill. With `coverage:
    /// conservative` the mask is unchanged; with `coverage: point` a
    /// receiver between the light view's samples may be missed
    /// (aggressive). A caster that the plane through the eye, the light
    /// and the strips' direction cuts (its rays run both ways through the
    /// strips), or that is not wholly in front of the eye, stays unclamped,
    /// as does every caster of a light the frame does not cull (no light
    /// pass).
    Discrete,
    /// Per light and per frame, none, continuous (with
    /// `clamping_receivers`) or discrete, whichever a cost model of earlier
    /// frames' counters finds cheaper (`auto.rs`, "Clamping"): never from
    /// timers, so results are deterministic. The mask is unchanged.
    Auto,
}

/// Default [`PipelineOptions::slices`]: "10 slices are usually sufficient"
/// at a 60° field of view [Steiner §4.4.2].
pub const DEFAULT_SLICES: u32 = 10;

/// CHC++ parameters (`chcpp: (batch: 50, revisit: 5, seed: 1)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ChcppSpec {
    /// Previously invisible nodes queried together.
    pub batch: u32,
    /// A visible leaf is re-queried every this many frames.
    pub revisit: u32,
    /// Seed of the revisit phases.
    pub seed: u64,
}

impl Default for ChcppSpec {
    fn default() -> Self {
        let o = visibility::ChcppOptions::default();
        ChcppSpec {
            batch: o.batch,
            revisit: o.revisit,
            seed: o.seed,
        }
    }
}

/// The cost model of `culling: auto` and `stencil: auto` (`auto: (probe: 8, ...)`): what one unit of
/// each counter costs, in nanoseconds on the machine kind the defaults were
/// fitted on (2-core AMD EPYC Zen 4, `docs/auto.md`), and when to look
/// again at the mode not chosen. Only the ratios matter to the rule.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutoSpec {
    /// Culled eye pass: per triangle submitted to the eye target (the
    /// traversal's draws and query boxes, one at a time).
    pub eye_triangle: f64,
    /// Culled eye pass: per 8×8 tile the rasterizer visits.
    pub eye_tile: f64,
    /// Culled eye pass: per pixel depth-tested.
    pub eye_pixel: f64,
    /// Culled eye pass: per hierarchy node visited.
    pub eye_node: f64,
    /// Unculled eye pass (one parallel batch of every object): per triangle.
    pub batch_triangle: f64,
    /// Unculled eye pass: per tile visited.
    pub batch_tile: f64,
    /// Unculled eye pass: per pixel depth-tested.
    pub batch_pixel: f64,
    /// Light pass: per triangle submitted to a light view.
    pub light_triangle: f64,
    /// Light pass: per tile visited.
    pub light_tile: f64,
    /// Light pass: per pixel depth-tested.
    pub light_pixel: f64,
    /// Light pass: per hierarchy node visited.
    pub light_node: f64,
    /// Per occlusion query a host backend answers (its raster work is not
    /// counted here).
    pub query: f64,
    /// Per eye pixel, for each culling light: the receiver points.
    pub receiver_pixel: f64,
    /// Per triangle of a caster whose volume is built (silhouette, volume).
    pub caster_triangle: f64,
    /// Per shadow-volume triangle drawn by the stencil.
    pub volume_triangle: f64,
    /// `clamping: auto`: per triangle of a clamped caster's segments, in
    /// place of `volume_triangle` (their caps are small or, between slices,
    /// edge-on; the hierarchical stencil's extra tile tests count apart).
    pub segment_triangle: f64,
    /// Per hierarchical-stencil tile test.
    pub stencil_tile: f64,
    /// Per hierarchical-stencil fragment (in boundary tiles).
    pub h_fragment: f64,
    /// Per brute-force stencil fragment (pixels processed; also `db`).
    pub bf_fragment: f64,
    /// Per tile the brute-force fill scans for written depth inside the
    /// depth window (`tiles_scanned`; also `db`): where the depth-bounds
    /// test rejects whole tiles, a long volume triangle costs these.
    pub fill_tile: f64,
    /// Frames before the mode not chosen is tried again; doubles (up to 8×)
    /// each time a try confirms the choice.
    pub probe: u32,
    /// A light's culled frame estimates its unculled cost; the estimate is
    /// trusted only when it differs from the culled cost by more than this
    /// factor, and the unculled mode is probed otherwise.
    pub margin: f64,
    /// Scenes with fewer objects never cull: there is too little to cull
    /// for a traversal to pay.
    pub min_objects: u32,
    /// The stencil stage's cost model of `stencil: auto`.
    pub stencil: StencilCosts,
}

/// The stencil stage's modeled cost (`stencil: auto`), per backend, in
/// nanoseconds on the calibration machine (`docs/auto.md`): a fixed cost
/// per eye pixel (clears, the tile bounds, the resolve and the mask), per
/// volume triangle submitted, and per unit of the backend's own work.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct StencilCosts {
    /// `h`: per eye pixel.
    pub h_pixel: f64,
    /// `h`: per volume triangle.
    pub h_triangle: f64,
    /// `h`: per tile test (a volume triangle piece against a tile).
    pub h_tile: f64,
    /// `h`: per fragment in a boundary tile.
    pub h_fragment: f64,
    /// `db` (with scissor rectangles): per eye pixel.
    pub db_pixel: f64,
    /// `db`: per volume triangle.
    pub db_triangle: f64,
    /// `db`: per fragment processed (inside the scissor and the depth bounds).
    pub db_fragment: f64,
}

impl Default for AutoSpec {
    /// Fitted (non-negative least squares) to the stage times of the city
    /// and city_16384 street and bird views, point light and sun, `h` and
    /// `bf` (`docs/auto.md`).
    fn default() -> Self {
        AutoSpec {
            eye_triangle: 74.0,
            eye_tile: 33.0,
            eye_pixel: 7.7,
            eye_node: 1690.0,
            batch_triangle: 21.7,
            batch_tile: 184.0,
            batch_pixel: 0.0,
            light_triangle: 206.0,
            light_tile: 2.6,
            light_pixel: 9.0,
            light_node: 1600.0,
            query: 2000.0,
            receiver_pixel: 10.0,
            caster_triangle: 253.0,
            volume_triangle: 424.0,
            segment_triangle: 190.0,
            stencil_tile: 55.0,
            h_fragment: 16.0,
            bf_fragment: 7.7,
            fill_tile: 15.0,
            probe: 8,
            margin: 2.0,
            min_objects: 16,
            stencil: StencilCosts::default(),
        }
    }
}

impl Default for StencilCosts {
    /// Fitted (non-negative least squares) to the stencil times of `h` and
    /// `db` with scissor on the city, city_16384 and city_4096 street and
    /// bird views, point light and sun (`docs/auto.md`).
    fn default() -> Self {
        StencilCosts {
            h_pixel: 10.3,
            h_triangle: 344.0,
            h_tile: 124.0,
            h_fragment: 4.7,
            db_pixel: 16.5,
            db_triangle: 363.0,
            db_fragment: 2.0,
        }
    }
}

/// Default [`PipelineOptions::clamp_vertex_cost`]: nanoseconds per volume
/// vertex of the CPU stencil (clip, setup and bin), an estimate for this
/// machine kind.
pub const DEFAULT_CLAMP_VERTEX_COST: f64 = 40.0;

/// Default [`PipelineOptions::clamp_pixel_cost`]: nanoseconds per brute-force
/// stencil pixel, an estimate for this machine kind.
pub const DEFAULT_CLAMP_PIXEL_COST: f64 = 1.0;

/// Pipeline options: how shadows are computed and how often the reference checks them.
///
/// [`PipelineOptions::default`] is the batch preset: a CPU mask (`stencil:
/// bf`) and, in batch jobs, the reference every frame. A renderer that draws
/// the volumes on its own GPU starts from [`PipelineOptions::gpu_host`]. In
/// RON and JSON, `preset: gpu_host` picks the starting point
/// ([`super::Preset`]) and every field named overrides it.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(from = "super::preset::PipelineSection")]
pub struct PipelineOptions {
    /// Volume method per caster (`auto`, `zpass`, `zfail`, `zpplus`).
    pub method: MethodChoice,
    /// Stencil backend.
    pub stencil: StencilBackend,
    /// Per-volume scissor rectangles.
    pub scissor: bool,
    /// Per-volume depth-bounds test for any backend (`stencil: db` is `bf` with it).
    pub depth_bounds: bool,
    /// Stencil counter width (`bits8` or `wide`).
    #[serde(alias = "stencil_bits")]
    pub counters: StencilBits,
    /// Tile size of the hierarchical stencil: 4, 8 or 16.
    pub tile: u32,
    /// The hierarchical stencil's full-shadow bit [Aila04 §4.3.2].
    pub full_shadow: bool,
    /// Shadow-map size of the hybrid (texels per side) when it renders its
    /// own maps: for a light without a light pass this frame (no culling,
    /// or a host's occlusion backends) or with conservative light views. A
    /// light pass's point-sampled light views (`coverage: point`) are the
    /// maps otherwise, at `light_resolution`.
    pub map_size: u32,
    /// The size the culling eye pass runs at, `(width, height)` in pixels:
    /// the largest size within it with the viewport's aspect, and never
    /// above the viewport (`None`, the default: the viewport's own). Below
    /// the viewport, the eye pass draws occluders inner-conservative at
    /// their farthest depth and the light passes mark receiver polygons
    /// (`docs/host.md`), so culling costs what this size costs, whatever
    /// the output resolution; a CPU stencil still runs on an exact eye pass
    /// at the viewport, drawn from the PSR, and masks are unchanged.
    pub culling_resolution: Option<(u32, u32)>,
    /// Occlusion culling of the eye pass (the objects it draws are the
    /// potentially shadowed receivers, PSR) and of the light pass (shadow
    /// volumes only for the potential shadow casters, PSC); `auto` by
    /// default.
    pub culling: CullingSpec,
    /// A node counts as visible above this many samples (0: conservative).
    pub query_threshold: u32,
    /// How culling samples pixels (`conservative` or the aggressive `point`).
    pub coverage: CoverageSpec,
    /// CHC++ parameters (with `culling: chcpp` or `auto`).
    pub chcpp: ChcppSpec,
    /// The cost model of `culling: auto`.
    pub auto: AutoSpec,
    /// Side of every light view (or cube face) of the light pass, in pixels.
    pub light_resolution: u32,
    /// Every triangle casts (back-facing ones flipped); the reference uses the same rule.
    pub two_sided: bool,
    /// What the light views draw as occluders (`mesh`, `proxy`).
    pub occluders: OccludersSpec,
    /// Lights with a range extrude their shadow volumes finitely (always closed).
    pub finite_extrusion: bool,
    /// Shadow-volume clamping (`none`, `continuous`, `discrete` or `auto`).
    pub clamping: ClampingSpec,
    /// Discrete clamping's number of slices (strips of the image), 1 to
    /// [`visibility::MAX_SLICES`].
    pub slices: u32,
    /// The receivers clamping fits volumes to (`all`, `psr` or `fragment`).
    pub clamping_receivers: ClampReceiversSpec,
    /// Clamping's cost per volume vertex, v in V = (2C + 2S)·v
    /// [Steiner eq. 4.2]: a gap between occupied intervals becomes a break
    /// between segments when V < R. Same unit as `clamp_pixel_cost`.
    pub clamp_vertex_cost: f64,
    /// Clamping's cost per stencil pixel, r in R = A·r [Steiner eq. 4.3].
    pub clamp_pixel_cost: f64,
    /// Counts, per light, the brute-force pixels processed by its volumes
    /// both without and with continuous clamping (`bf_fill_unclamped`,
    /// `bf_fill_clamped`; receivers and costs from the clamping fields) on
    /// any backend: the volumes the frame does not draw are built beside it
    /// and counted by a brute-force pass. A measurement, not a stage: its
    /// time is left out of every stage time and of the frame time.
    pub count_fill: bool,
    /// Worker threads of the pipeline's own rayon pool; 0 (the default) runs
    /// on rayon's global pool, or on the pool given to
    /// [`super::Pipeline::set_thread_pool`]. Results are identical for any count.
    pub threads: u32,
    /// Compute the reference mask every n-th frame (0 = never).
    pub reference_every: u32,
    /// The reference's options (depth-error bound; its `two_sided` must equal
    /// the pipeline's or be left out).
    pub reference: crate::reference::ReferenceOptions,
    /// The most memory a frame (or a batch job) may need, by the estimate of
    /// [`crate::memory`]: bytes, or `"8G"`. `None` (the default): three
    /// quarters of the machine's memory. A larger estimate is an
    /// [`crate::Error::Options`] on `max_memory` before anything is allocated.
    pub max_memory: Option<crate::byte_size::ByteSize>,
    /// Caps the rasterizer kernels' instruction set (`portable`, `avx2`,
    /// `avx512`; [`raster::InstructionSet`]). `None` (the default): the
    /// detected one. Every level gives the same results; the cap is for
    /// comparing builds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instruction_set: Option<raster::InstructionSet>,
}

impl Default for PipelineOptions {
    fn default() -> Self {
        PipelineOptions {
            method: MethodChoice::Auto,
            stencil: StencilBackend::Bf,
            scissor: false,
            depth_bounds: false,
            counters: StencilBits::Eight,
            tile: 8,
            full_shadow: true,
            map_size: 2048,
            culling_resolution: None,
            culling: CullingSpec::Auto,
            query_threshold: 0,
            coverage: CoverageSpec::Conservative,
            chcpp: ChcppSpec::default(),
            auto: AutoSpec::default(),
            light_resolution: 1024,
            two_sided: false,
            occluders: OccludersSpec::Mesh,
            finite_extrusion: false,
            clamping: ClampingSpec::None,
            slices: DEFAULT_SLICES,
            clamping_receivers: ClampReceiversSpec::All,
            clamp_vertex_cost: DEFAULT_CLAMP_VERTEX_COST,
            clamp_pixel_cost: DEFAULT_CLAMP_PIXEL_COST,
            count_fill: false,
            threads: 0,
            reference_every: 1,
            reference: Default::default(),
            max_memory: None,
            instruction_set: None,
        }
    }
}

impl PipelineOptions {
    /// The size of the culling eye pass for a `width × height` viewport
    /// ([`PipelineOptions::culling_resolution`]): the viewport's own, or the
    /// largest size within the culling resolution with its aspect.
    pub fn culling_size(&self, (width, height): (u32, u32)) -> (u32, u32) {
        let Some((cw, ch)) = self.culling_resolution else {
            return (width, height);
        };
        let (w, h) = (f64::from(width), f64::from(height));
        let s = (f64::from(cw) / w).min(f64::from(ch) / h);
        if s >= 1.0 {
            return (width, height);
        }
        let fit = |v: f64, most: u32| ((v * s).round() as u32).clamp(1, most);
        (fit(w, cw.min(width)), fit(h, ch.min(height)))
    }

    /// The culling traversal (`auto`'s culled mode is CHC++).
    pub fn culling(&self) -> visibility::Culling {
        match self.culling {
            CullingSpec::None => visibility::Culling::None,
            CullingSpec::Frustum => visibility::Culling::Frustum,
            CullingSpec::Exact => visibility::Culling::Exact,
            CullingSpec::Chc => visibility::Culling::Chc,
            CullingSpec::Chcpp | CullingSpec::Auto => {
                visibility::Culling::ChcPlusPlus(visibility::ChcppOptions {
                    batch: self.chcpp.batch,
                    revisit: self.chcpp.revisit,
                    seed: self.chcpp.seed,
                })
            }
        }
    }

    /// The shadow stage's options.
    pub fn shadow_options(&self) -> super::shadow_options::ShadowOptions {
        super::shadow_options::ShadowOptions {
            method: self.method,
            two_sided: self.two_sided,
            backend: match self.stencil {
                StencilBackend::Bf | StencilBackend::Db | StencilBackend::None => {
                    super::shadow_options::Backend::Brute
                }
                // `auto` starts each light with `h` (`db` per light and frame
                // by `auto::db_options`).
                StencilBackend::H | StencilBackend::Auto => {
                    super::shadow_options::Backend::Hierarchical {
                        tile: match self.tile {
                            4 => raster::TileSize::T4,
                            16 => raster::TileSize::T16,
                            _ => raster::TileSize::T8,
                        },
                        full_shadow: self.full_shadow,
                    }
                }
                StencilBackend::Hybrid => super::shadow_options::Backend::Hybrid {
                    map_size: self.map_size,
                },
            },
            bits: self.counters,
            scissor: self.scissor,
            depth_bounds: self.depth_bounds || self.stencil == StencilBackend::Db,
            finite_extrusion: self.finite_extrusion,
            clamping: self.clamping_options(self.clamping),
        }
    }

    /// The shadow stage's clamping for `clamping` (`auto`: none; each light
    /// sets its own).
    pub(crate) fn clamping_options(
        &self,
        clamping: ClampingSpec,
    ) -> Option<super::shadow_options::ClampOptions> {
        match clamping {
            ClampingSpec::None | ClampingSpec::Auto => None,
            ClampingSpec::Continuous => Some(self.clamp_options()),
            ClampingSpec::Discrete => Some(super::shadow_options::ClampOptions {
                slices: Some(self.slices),
                ..self.clamp_options()
            }),
        }
    }

    /// Continuous clamping's receivers and costs (used when `clamping` is
    /// `continuous`, and by `count_fill`).
    pub(crate) fn clamp_options(&self) -> super::shadow_options::ClampOptions {
        super::shadow_options::ClampOptions {
            receivers: self.clamping_receivers,
            vertex_cost: self.clamp_vertex_cost,
            pixel_cost: self.clamp_pixel_cost,
            slices: None,
        }
    }

    /// The reference's options, with the pipeline's two-sided rule.
    pub fn reference_options(&self) -> crate::reference::ReferenceOptions {
        crate::reference::ReferenceOptions {
            two_sided: self.two_sided,
            ..self.reference
        }
    }
}

/// A [`PipelineOptions`] field with a bad value: its name and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BadOption {
    /// The field, as the job spells it (`tile`, `chcpp`, `reference.two_sided`).
    pub field: &'static str,
    /// What is wrong, with the value.
    pub message: String,
}

impl PipelineOptions {
    /// Checks every field's range.
    ///
    /// # Errors
    /// The first bad field ([`BadOption`]).
    pub fn validate(&self) -> std::result::Result<(), BadOption> {
        let bad = |field, message| Err(BadOption { field, message });
        let p = self;
        if !(p.reference.depth_error >= 0.0 && p.reference.depth_error < 1e-2) {
            return bad("reference.depth_error", "must lie in [0, 0.01)".into());
        }
        if ![4, 8, 16].contains(&p.tile) {
            return bad("tile", format!("{} is not 4, 8 or 16", p.tile));
        }
        if let Some((w, h)) = p.culling_resolution {
            let most = raster::MAX_TARGET_SIZE;
            if !((1..=most).contains(&w) && (1..=most).contains(&h)) {
                return bad(
                    "culling_resolution",
                    format!("{w}×{h} must be between 1×1 and {most}×{most}"),
                );
            }
        }
        if p.chcpp.batch == 0 || p.chcpp.revisit == 0 {
            return bad(
                "chcpp",
                format!(
                    "batch ({}) and revisit ({}) must be at least 1",
                    p.chcpp.batch, p.chcpp.revisit
                ),
            );
        }
        if p.auto.probe == 0 {
            return bad("auto.probe", "must be at least 1".into());
        }
        if !(p.auto.margin >= 1.0 && p.auto.margin.is_finite()) {
            return bad(
                "auto.margin",
                format!("{} is not a finite number >= 1", p.auto.margin),
            );
        }
        let a = &p.auto;
        let t = &a.stencil;
        for (field, costs) in [
            (
                "auto",
                &[
                    a.eye_triangle,
                    a.eye_tile,
                    a.eye_pixel,
                    a.eye_node,
                    a.batch_triangle,
                    a.batch_tile,
                    a.batch_pixel,
                    a.light_triangle,
                    a.light_tile,
                    a.light_pixel,
                    a.light_node,
                    a.query,
                    a.receiver_pixel,
                    a.caster_triangle,
                    a.volume_triangle,
                    a.segment_triangle,
                    a.stencil_tile,
                    a.h_fragment,
                    a.bf_fragment,
                    a.fill_tile,
                ][..],
            ),
            (
                "auto.stencil",
                &[
                    t.h_pixel,
                    t.h_triangle,
                    t.h_tile,
                    t.h_fragment,
                    t.db_pixel,
                    t.db_triangle,
                    t.db_fragment,
                ][..],
            ),
        ] {
            if let Some(c) = costs.iter().find(|c| !(c.is_finite() && **c >= 0.0)) {
                return bad(field, format!("cost {c} is not a finite number >= 0"));
            }
        }
        if !(8..=raster::MAX_TARGET_SIZE).contains(&p.light_resolution) {
            return bad(
                "light_resolution",
                format!(
                    "{} is not in 8..={}",
                    p.light_resolution,
                    raster::MAX_TARGET_SIZE
                ),
            );
        }
        if !(16..=raster::MAX_TARGET_SIZE).contains(&p.map_size) {
            return bad(
                "map_size",
                format!("{} is not in 16..={}", p.map_size, raster::MAX_TARGET_SIZE),
            );
        }
        if !(1..=visibility::MAX_SLICES as u32).contains(&p.slices) {
            return bad(
                "slices",
                format!("{} is not in 1..={}", p.slices, visibility::MAX_SLICES),
            );
        }
        if p.threads > 1024 {
            return bad("threads", format!("{} is not in 0..=1024", p.threads));
        }
        if p.reference.two_sided && !p.two_sided {
            return bad(
                "reference.two_sided",
                "set two_sided instead: the pipeline and its reference use one rule".into(),
            );
        }
        Ok(())
    }

    /// The light pass's options (PSC).
    pub fn light_pass_options(&self) -> visibility::LightPassOptions {
        visibility::LightPassOptions {
            culling: self.culling(),
            sampling: self.coverage.sampling(),
            resolution: self.light_resolution,
            threshold: self.query_threshold,
            two_sided: self.two_sided,
            instruction_set: self.instruction_set.unwrap_or_default(),
            // The hybrid's shadow maps are the light views' depth when they
            // sample pixel centres. Conservative views draw each triangle
            // inner-conservative: texels along a caster's inner edges and
            // the thin strips of walls seen steeply lie wholly in no one
            // triangle and stay empty, holes in its shadow (city street,
            // point light: 6,475 pixels off the shadow boundaries against
            // 158 with point-sampled views).
            keep_depth: self.stencil == StencilBackend::Hybrid
                && self.coverage.sampling() == visibility::Sampling::Point,
            proxies: self.occluders == OccludersSpec::Proxy,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The culling size keeps the viewport's aspect within the culling
    /// resolution, never exceeds the viewport, and is the viewport's own
    /// without one.
    #[test]
    fn the_culling_size_fits_the_resolution_to_the_viewport() {
        let at = |r: Option<(u32, u32)>, v: (u32, u32)| {
            PipelineOptions {
                culling_resolution: r,
                ..PipelineOptions::default()
            }
            .culling_size(v)
        };
        assert_eq!(at(None, (800, 600)), (800, 600));
        assert_eq!(at(Some((200, 150)), (800, 600)), (200, 150));
        // The narrower side of the box decides: 4:3 in 16:9.
        assert_eq!(at(Some((1920, 1080)), (3840, 2160)), (1920, 1080));
        assert_eq!(at(Some((960, 540)), (1280, 1024)), (675, 540));
        assert_eq!(at(Some((320, 320)), (1280, 720)), (320, 180));
        // Never above the viewport, and at least a pixel.
        assert_eq!(at(Some((1920, 1080)), (800, 600)), (800, 600));
        assert_eq!(at(Some((1, 1)), (4000, 10)), (1, 1));
    }
}
