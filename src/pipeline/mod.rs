//! [`Pipeline`]: the whole per-frame flow of DESIGN.md behind one call.
//!
//! A host builds a [`Pipeline`] once from a [`Scene`] and [`PipelineOptions`],
//! then calls [`Pipeline::frame`] every frame with a [`FrameInput`] (viewport,
//! camera, lights) and reads the [`FrameOutput`]: the potentially shadowed
//! receivers (PSR), per light the potential shadow casters (PSC), the shadow
//! volumes to draw, the light views used, statistics and — when a CPU stencil
//! backend is chosen — the four-class shadow mask. The output borrows the
//! pipeline's buffers and stays valid until the next `frame` call.
//!
//! The stages, one module each, in the order data flows:
//! 1. `eye` — the eye pass: depth and primitive ids, culled by CHC/CHC++
//!    (PSR) or not, and the visible surface points [Steiner §2.5.1, §4.3];
//! 2. `light` — per light the light views and the light pass (PSC)
//!    [Steiner §4.3.1–4.3.3];
//! 3. `volume` — silhouettes, method choice and shadow volumes [AW, EK];
//! 4. `stencil` — the brute-force, hierarchical \[Aila04\] or hybrid
//!    \[ChanDurand04\] stencil and the mask.
//!
//! Stages 2–4 are one chain per light (`light_frame`), and the lights'
//! chains run side by side.

mod auto;
mod coarse_receivers;
mod edit;
pub mod eye;
mod fill_count;
pub(crate) mod gpu_check;
mod host_depth;
mod light;
mod light_frame;
mod light_state;
pub mod memory;
mod options;
mod preset;
mod shadow_options;
mod shadowable;
pub mod stencil;
mod volume;

use eye::visible_points_into;
pub use eye::{
    eye_pass, eye_pass_culled, eye_pass_reusing, visible_points, EyeCulling, EyePass, EyeTraversal,
    MeshCache,
};
pub use host_depth::HostDepth;
pub use options::{
    AutoSpec, BadOption, ChcppSpec, ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec,
    OccludersSpec, PipelineOptions, StencilBackend, StencilCosts, DEFAULT_CLAMP_PIXEL_COST,
    DEFAULT_CLAMP_VERTEX_COST,
};
pub use preset::Preset;
pub use shadow_options::{Backend, ClampOptions, ShadowOptions};
pub use stencil::{shadow_mask, shadow_mask_for, ShadowFrame, ShadowScratch, TileImage};

use crate::mask::Mask;
use crate::reference::{try_reference_mask, ReferenceMask, TriangleBvh};
use crate::stats::{FrameStats, ShadowStats};
use crate::{Error, Result};
use light_state::{LightSlot, LightState};
use raster::VolumeBuffer;
pub use scene::LightId;
use scene::{Camera, Light, ObjectId, Scene};
use shadowgen::VolumeStats;
use std::sync::Arc;
use std::time::Instant;
use visibility::{LightView, TraversalStats};

/// What one frame is computed for: the viewport, the camera and, from a GPU
/// host with a depth pre-pass, a coarse copy of this frame's depth. The
/// lights are the pipeline's own ([`Pipeline::add_light`]).
#[derive(Clone, Debug)]
pub struct FrameInput {
    /// Viewport width in pixels, `1..=`[`raster::MAX_TARGET_SIZE`].
    pub width: u32,
    /// Viewport height in pixels, `1..=`[`raster::MAX_TARGET_SIZE`].
    pub height: u32,
    /// The eye (reversed Z, infinite far plane; see [`Camera`], and
    /// [`Camera::from_view_projection`] for a host's own matrices).
    pub camera: Camera,
    /// The host's own depth of this frame at the culling size
    /// ([`HostDepth`]): when given and the eye culls, no CPU eye raster
    /// runs; the PSR and the light passes' receivers come from queries
    /// against it (see `host_depth.rs` for why that is exact, and
    /// `docs/host.md` for the latency it costs). `None`: the pipeline
    /// rasterizes its own eye pass.
    pub host_depth: Option<HostDepth>,
    /// The viewport's pixels are not square: its aspect (`width / height`)
    /// may differ from the camera's. Otherwise a frame whose viewport aspect
    /// differs from [`Camera::aspect`] by more than
    /// [`MAX_ASPECT_MISMATCH`] is refused: a projection made for another
    /// viewport (a window resized, a render target of another size) would
    /// give masks and scissors that are stretched, and no check could see it.
    pub anamorphic: bool,
}

/// The relative difference allowed between a viewport's aspect and its
/// camera's (1 %), unless [`FrameInput::anamorphic`] says the pixels are not
/// square: rounding a viewport to whole pixels stays well within it.
pub const MAX_ASPECT_MISMATCH: f64 = 0.01;

impl FrameInput {
    /// The input for a `width × height` viewport seen by `camera`.
    pub fn new(width: u32, height: u32, camera: Camera) -> Self {
        FrameInput {
            width,
            height,
            camera,
            host_depth: None,
            anamorphic: false,
        }
    }

    /// This input for a viewport of non-square pixels ([`FrameInput::anamorphic`]).
    pub fn anamorphic(self) -> Self {
        FrameInput {
            anamorphic: true,
            ..self
        }
    }

    /// This input with the host's depth of this frame ([`FrameInput::host_depth`]).
    pub fn with_host_depth(self, depth: HostDepth) -> Self {
        FrameInput {
            host_depth: Some(depth),
            ..self
        }
    }
}

/// The shadow-volume culling pipeline: owns the scene and everything a frame
/// needs — the object hierarchy, per-view CHC state of the eye and of every
/// light view, silhouette caches, render targets and volume buffers — and
/// reuses it from frame to frame.
///
/// ```
/// use glam::{DMat4, DVec3, UVec3, Vec3};
/// use shadowcull::scene::{Camera, Light, Mesh, ObjectId, Scene, SceneGraph, Transform};
/// use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};
/// // The host's arrays: a ground quad and a unit cube (corner i: x, y, z = bits 0, 1, 2 of i).
/// let quad = [[-9., 0., -9.], [-9., 0., 9.], [9., 0., 9.], [9., 0., -9.]].map(Vec3::from);
/// let corners: Vec<Vec3> = (0..8u32).map(|i| UVec3::new(i & 1, i >> 1 & 1, i >> 2 & 1).as_vec3()).collect();
/// let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
/// let tris: Vec<[u32; 3]> = faces.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
/// let mut graph = SceneGraph::new();
/// let ground = graph.add_mesh(Mesh::new("ground", &quad, &[[0, 1, 2], [0, 2, 3]])?);
/// let cube = graph.add_mesh(Mesh::new("cube", &corners, &tris)?);
/// graph.add_instance("ground", ground, Transform::Matrix(DMat4::IDENTITY));
/// graph.add_instance("cube", cube, Transform::translation(DVec3::new(0.0, 0.5, 0.0)));
/// // Culled PSR and PSC, volumes only: a GPU host draws them itself.
/// let options = PipelineOptions { culling: CullingSpec::Chcpp, stencil: StencilBackend::None, ..Default::default() };
/// let mut pipeline = Pipeline::new(Scene::new(graph)?, options)?;
/// let lamp = pipeline.add_light(Light::Point { position: DVec3::new(2.0, 8.0, 1.0), range: None })?;
/// let camera = Camera::look_at(DVec3::new(6.0, 5.0, 8.0), DVec3::ZERO, DVec3::Y, 1.0, 4.0 / 3.0, 0.1)?;
/// let out = pipeline.frame(&FrameInput::new(320, 240, camera))?;
/// assert_eq!(out.psr(), &[ObjectId::from_slot(0), ObjectId::from_slot(1)]);
/// let light = out.light(lamp).unwrap();
/// assert!(light.psc().contains(&ObjectId::from_slot(1)));
/// let volumes = light.volumes(); // one range per caster: draw its indices with its method
/// let cube_volume = volumes.ranges.iter().find(|r| r.object == 1).unwrap();
/// assert!(!volumes.indices[cube_volume.indices()].is_empty());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Pipeline {
    scene: Arc<Scene>,
    options: PipelineOptions,
    counts: scene::SceneCounts,
    meshes: MeshCache,
    /// Hierarchy, meshes and the eye view's CHC state, built on first culled frame.
    culling: Option<EyeCulling>,
    /// `culling: auto`'s choice state of the eye pass.
    auto_eye: auto::AutoView,
    /// The last frame's eye pass; `None` when nobody read one (no light
    /// culled, no CPU stencil, no fill count) until
    /// [`Pipeline::reference_mask`] rasterizes it.
    eye: Option<EyePass>,
    /// The last coarse culling pass (a culling resolution below the
    /// viewport's), kept for its buffers.
    coarse_eye: Option<EyePass>,
    /// The coarse pass's depths, row-major, for its receivers.
    coarse_rows: Vec<f32>,
    /// Per row segment of the coarse pass, its depth bounds.
    coarse_bounds: Vec<(f32, f32)>,
    /// The last frame's camera; `None` before the first frame and after a
    /// failed one.
    camera: Option<Camera>,
    /// The last frame's viewport.
    viewport: (u32, u32),
    /// The eye's visible points, in bands of rows.
    receivers: Vec<visibility::ReceiverPoints>,
    /// The receiver points' run buffers, one per band of rows.
    receiver_runs: Vec<eye::PointRuns>,
    /// Per skip bit, the light whose light pass may leave out the points of
    /// surfaces facing away from it (`receiver_skips`).
    skip_lights: Vec<scene::Light>,
    /// Every live visible object's slot id, ascending: the PSR without culling.
    all_visible: Vec<ObjectId>,
    /// Every live casting object's slot id, ascending: the casters without culling.
    all_casters: Vec<ObjectId>,
    /// The last PSR as public ids, ascending.
    psr: Vec<ObjectId>,
    lights: Vec<LightSlot>,
    /// Light states removed or replaced since the last frame, kept until the
    /// next one starts: the last frame's outputs (the C ABI's pointers into
    /// their volume buffers) stay valid across edits.
    retired: Vec<LightState>,
    /// No edit since the last successful frame: [`Pipeline::last_output`]
    /// still describes the scene and lights.
    output_current: bool,
    stats: FrameStats,
    /// Edits the scene does not stage (meshes added or removed, flags set)
    /// since the last frame: with its staged edits, what makes the next frame
    /// bring the derived data (mesh copies, hierarchy, reference BVH) up to date.
    edited: bool,
    bvh: Option<TriangleBvh>,
    bvh_ms: f64,
    /// The host's occlusion backends for the culling passes, if any.
    backends: Option<Arc<visibility::BackendFactory>>,
    /// The pool frames run in: the host's, or one of `options.threads`
    /// threads; `None` runs on rayon's global pool.
    pool: Option<Arc<rayon::ThreadPool>>,
    /// The pool came from [`Pipeline::set_thread_pool`] (kept across option changes).
    host_pool: bool,
    /// The job frame number of the next frame ([`Pipeline::set_frame_number`]).
    next_frame: u32,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("objects", &self.counts.objects)
            .field("options", &self.options)
            .field("lights", &self.live_lights().count())
            .finish_non_exhaustive()
    }
}

impl Pipeline {
    /// A pipeline over `scene` (owned, or shared with other pipelines through
    /// an [`Arc`]) with `options`. Scene-derived data (the rasterizer's mesh
    /// form, and with culling the object hierarchy) is built here or on the
    /// first culled frame.
    ///
    /// # Errors
    /// [`Error::Options`] naming the bad field of `options`.
    pub fn new(scene: impl Into<Arc<Scene>>, options: PipelineOptions) -> Result<Pipeline> {
        check_options(&options)?;
        let mut scene: Arc<Scene> = scene.into();
        if scene.has_staged_edits() {
            Arc::make_mut(&mut scene).commit_edits();
        }
        Ok(Pipeline {
            counts: scene.counts(),
            meshes: MeshCache::new(&scene),
            culling: None,
            auto_eye: auto::AutoView::culling(),
            eye: None,
            coarse_eye: None,
            coarse_rows: Vec::new(),
            coarse_bounds: Vec::new(),
            camera: None,
            viewport: (0, 0),
            receivers: Default::default(),
            receiver_runs: Default::default(),
            skip_lights: Vec::new(),
            all_visible: live_slots_of(&scene, |f| f.visible),
            all_casters: live_slots_of(&scene, |f| f.casts),
            psr: Vec::new(),
            lights: Vec::new(),
            retired: Vec::new(),
            output_current: false,
            stats: FrameStats::default(),
            edited: false,
            bvh: None,
            bvh_ms: 0.0,
            pool: own_pool(options.threads)?,
            host_pool: false,
            next_frame: 0,
            backends: None,
            options,
            scene,
        })
    }

    /// Runs every following frame (and [`Pipeline::reference_mask`]) in the
    /// host's rayon `pool` instead of rayon's global pool or the pipeline's own
    /// (`options.threads`); `None` returns to those. Results are identical
    /// for any pool size.
    pub fn set_thread_pool(&mut self, pool: Option<Arc<rayon::ThreadPool>>) -> Result<()> {
        self.host_pool = pool.is_some();
        self.pool = match pool {
            Some(p) => Some(p),
            None => own_pool(self.options.threads)?,
        };
        Ok(())
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The options in force.
    pub fn options(&self) -> &PipelineOptions {
        &self.options
    }

    /// Sends the culling passes' draws and queries — the eye pass and every
    /// light view — to backends made by `factory` (a host renderer's GPU
    /// queries) instead of the bundled rasterizer; `None` returns to it.
    /// The eye's visible surface is still rasterized here, from the objects
    /// the host's traversal rendered. See `docs/host.md` for what a host
    /// backend must honour.
    pub fn set_backend_factory(&mut self, factory: Option<Arc<visibility::BackendFactory>>) {
        self.backends = factory;
    }

    /// Replaces the options. When they differ from the current ones, every
    /// per-view and per-light state (culling history, silhouette caches,
    /// targets) starts cold, as in a new pipeline; scene-derived data is kept.
    ///
    /// # Errors
    /// [`Error::Options`] naming the bad field (the old options stay).
    pub fn set_options(&mut self, options: PipelineOptions) -> Result<()> {
        check_options(&options)?;
        if options != self.options {
            if !self.host_pool && options.threads != self.options.threads {
                self.pool = own_pool(options.threads)?;
            }
            self.options = options;
            if let Some(c) = &mut self.culling {
                c.reset();
            }
            self.auto_eye.reset();
            for s in self.lights.iter_mut().filter_map(|s| s.state.as_mut()) {
                let fresh = LightState::new(s.light, s.id);
                self.retired.push(std::mem::replace(s, fresh));
            }
            self.eye = None;
            self.camera = None;
            self.output_current = false;
        }
        Ok(())
    }

    /// Numbers the next frame `frame` (from 0); the frames after it count on.
    /// A new pipeline's first frame is 0. Coherent culling reads these
    /// numbers, not how many frames ran: a node's history carries only from
    /// the frame just before, and CHC++'s revisit phases are a function of
    /// the number ([`visibility::ViewCuller::set_frame`]). So a batch job
    /// split into blocks of frames numbers each block's frames as in the
    /// whole job, and a host that skips frames may say so.
    pub fn set_frame_number(&mut self, frame: u32) {
        self.next_frame = frame;
    }

    /// Forgets all coherent state — the eye's and every light view's culling
    /// history, the silhouette and casting-triangle caches — keeping the
    /// buffers and scene-derived data: the next frame runs as a new
    /// pipeline's would (at its own frame number). Call it at a camera cut,
    /// or at a batch job's keyframes so that every block between keyframes
    /// gives the same results however the job is split. Shadow masks never
    /// depend on history; query counts, PSR, PSC and the volumes drawn do.
    pub fn reset_history(&mut self) {
        if let Some(c) = &mut self.culling {
            c.reset();
        }
        self.auto_eye.reset();
        for s in self.lights.iter_mut().filter_map(|s| s.state.as_mut()) {
            s.culling.pass.reset_history();
            s.auto.reset();
            s.stencil_auto.iter_mut().for_each(auto::AutoView::reset);
            s.clamp_auto.iter_mut().for_each(auto::AutoView::reset);
            s.scratch.volume.cache.clear();
        }
    }

    /// Runs one frame: the scene edits since the last frame are applied
    /// (hierarchy refit or rebuilt, culling state remapped), then the eye
    /// pass, and for every light the light pass, the volumes and (unless
    /// `stencil` is [`StencilBackend::None`]) the stencil and mask. Its wall
    /// time, edits included, is [`FrameStats::frame_ms`].
    ///
    /// # Errors
    /// [`Error::Options`] for a viewport out of range; rasterizer errors.
    pub fn frame(&mut self, input: &FrameInput) -> Result<FrameOutput<'_>> {
        match self.pool.clone() {
            Some(pool) => pool.install(|| self.run_frame(input))?,
            None => self.run_frame(input)?,
        }
        Ok(FrameOutput { pipeline: self })
    }

    /// Runs `f` with this pipeline on a thread of the pool its frames run in
    /// (its own pool of `options.threads`, the host's from
    /// [`Pipeline::set_thread_pool`], or rayon's global one) and returns what
    /// `f` returns. Frames called inside run their parallel work without a
    /// hand-off from outside the pool: rayon's injector, which allocates a
    /// queue block now and then (about every 63 calls) when a frame is called
    /// from another thread, is not used. A host whose own job system is not
    /// this pool runs its steady frames this way to make no allocation at all
    /// (`docs/host.md`, "Allocations").
    pub fn install<R: Send>(&mut self, f: impl FnOnce(&mut Pipeline) -> R + Send) -> R {
        match self.pool.clone() {
            Some(pool) => pool.install(|| f(self)),
            None => rayon::scope(|_| f(self)),
        }
    }

    fn run_frame(&mut self, input: &FrameInput) -> Result<()> {
        let (w, h) = (input.width, input.height);
        if !(1..=raster::MAX_TARGET_SIZE).contains(&w)
            || !(1..=raster::MAX_TARGET_SIZE).contains(&h)
        {
            return Err(Error::Options {
                field: "viewport".into(),
                message: format!(
                    "{w}×{h} must be between 1×1 and {0}×{0}",
                    raster::MAX_TARGET_SIZE
                ),
            });
        }
        let viewport = f64::from(w) / f64::from(h);
        let camera_aspect = input.camera.aspect;
        // False for a NaN aspect too.
        let within = (viewport / camera_aspect - 1.0).abs() <= MAX_ASPECT_MISMATCH;
        if !input.anamorphic && !within {
            return Err(Error::Options {
                field: "viewport".into(),
                message: format!(
                    "{w}×{h} has aspect {viewport:.4}, the camera's projection {camera_aspect:.4} \
                     (more than 1% apart): a projection made for another viewport size? \
                     Set FrameInput::anamorphic for non-square pixels"
                ),
            });
        }
        let start = Instant::now();
        self.output_current = false;
        self.retired.clear();
        self.apply_edits();
        // Refuse a frame that cannot fit before its targets are allocated. A
        // frame computes no reference ([`Pipeline::reference_mask`] checks
        // its own share). The edits are applied by now: the last frame's
        // outputs no longer describe the scene, so they are dropped.
        if let Err(e) = self.check_memory(w, h, false) {
            self.eye = None;
            self.camera = None;
            return Err(e);
        }
        let frame = self.next_frame;
        self.next_frame = frame.saturating_add(1);
        let camera = &input.camera;
        let scene: &Scene = &self.scene;
        let o = self.options;
        // Which views cull this frame: every one, none, or (`auto`) each
        // as its cost model chooses.
        let auto = o.culling == CullingSpec::Auto;
        let may_cull = match o.culling {
            CullingSpec::None => false,
            CullingSpec::Auto => self.counts.objects >= o.auto.min_objects as usize,
            _ => true,
        };
        let mut lights_culled = false;
        for s in self.lights.iter_mut().filter_map(|s| s.state.as_mut()) {
            s.culled = may_cull && (!auto || s.auto.choose(&o.auto));
            lights_culled |= s.culled;
            s.skip_bit = 0;
            // `clamping: auto`: clamp or not, then discrete or continuous.
            s.clamping = match o.clamping {
                ClampingSpec::Auto if !s.clamp_auto[0].choose(&o.auto) => ClampingSpec::None,
                ClampingSpec::Auto if s.clamp_auto[1].choose(&o.auto) => ClampingSpec::Discrete,
                ClampingSpec::Auto => ClampingSpec::Continuous,
                fixed => fixed,
            };
        }

        // 1. Eye pass (PSR) and, for the light pass, the visible surface points.
        // No light culls this frame (`culling: none`, or `auto` choosing to
        // draw every caster), no CPU stencil and no fill count: nobody reads
        // an eye pass, so none runs (the PSR is every visible object) and
        // the eye's choice waits for a frame that reads one.
        // [`Pipeline::reference_mask`] rasterizes one when asked.
        let eye_read = lights_culled || o.stencil != StencilBackend::None || o.count_fill;
        // A culling resolution below the viewport's: the eye culls whenever
        // it is read (its coarse pass is what the resolution buys; `auto`
        // compares only passes at the viewport).
        let coarse_size = o.culling_size((w, h));
        // The host's depth of this frame, checked even when no view culls.
        if let Some(d) = &input.host_depth {
            d.check(&input.camera, (w, h), coarse_size)?;
            if self.backends.is_some() {
                return Err(Error::Options {
                    field: "host_depth".into(),
                    message: "not with a host backend factory (its queries would run on the \
                              host's own targets, not on this depth)"
                        .into(),
                });
            }
        }
        let host_depth = input.host_depth.as_ref();
        let culled = may_cull
            && eye_read
            && (!auto
                || coarse_size != (w, h)
                || host_depth.is_some()
                || self.auto_eye.choose(&o.auto));
        // `auto`'s lights model their unculled cost by every caster's triangles.
        let all_caster_triangles = if auto && may_cull {
            light_frame::triangles_of(scene, &self.all_casters)
        } else {
            0
        };
        if !eye_read {
            self.eye = None;
            self.psr.clear();
            self.psr
                .extend(self.all_visible.iter().map(|id| scene.id_of(id.slot())));
            let eye_ms = ms(start);
            let shared = light_frame::FrameShared {
                scene,
                camera,
                options: &o,
                viewport: (w, h),
                eye: None,
                eye_counts: light_frame::EyeCounts {
                    ms: eye_ms,
                    psr: self.psr.len() as u64,
                    queries: 0,
                    waits: 0,
                },
                pass: None,
                all_casters: &self.all_casters,
                receives: None,
                stored_points: false,
                auto_culling: auto && may_cull,
                all_caster_triangles,
                host: self.backends.is_some(),
            };
            let fill_ms = Self::run_lights_of(&mut self.lights, &shared)?;
            let camera = *camera;
            self.finish_frame(frame, start, (w, h), camera, eye_ms, fill_ms, (0, 0));
            return Ok(());
        }
        // Clamping to fragment receivers: the light passes read each
        // caster's intervals along its clamping axis, from the eye's surface
        // points and the stencil's (the stored depths). Their marks are
        // tighter and hold more points, so the PSC may differ from the other
        // receiver models': they are taken whenever the model is chosen, so
        // that `count_fill` and `clamping` change no PSC.
        // Discrete clamping reads occupied slices the same way; a sample's
        // slice is its pixel's, whatever its depth, so it needs no stored
        // points. What a light reads is per light (`clamping: auto`).
        let stored_points = (self.lights.iter())
            .filter_map(|s| s.state.as_ref())
            .any(|s| s.culled && light_frame::reading(s.clamping, &o) == light::Reading::Axes);
        // A culling resolution below the viewport's: the culled eye pass
        // runs coarse. Clamping's readings are the exact eye's points, so a
        // light reading them takes the points of an exact eye pass.
        // The host's depth stands in for a coarse pass at any size.
        let coarse = culled && (coarse_size != (w, h) || host_depth.is_some());
        let fine_points = (self.lights.iter())
            .filter_map(|s| s.state.as_ref())
            .any(|s| s.culled && light_frame::reading(s.clamping, &o) != light::Reading::None);
        let exact = !coarse || o.stencil != StencilBackend::None || o.count_fill || fine_points;
        let isa = o.instruction_set.unwrap_or_default();
        let mut previous = match exact {
            true => Some(EyePass::reusable(self.eye.take(), (w, h), isa)?),
            false => None,
        };
        if let Some(p) = &mut previous {
            p.target.take_stats();
        }
        let (eye, eye_queries, eye_waits) = if culled {
            let state = self.culling.get_or_insert_with(|| EyeCulling::new(scene));
            state.set_frame(frame);
            let size = if coarse { coarse_size } else { (w, h) };
            let traversal = EyeTraversal {
                culling: o.culling(),
                threshold: o.query_threshold,
                sampling: o.coverage.sampling(),
                coarse,
                host_occluders: o.occluders == OccludersSpec::Proxy,
            };
            let mut pass = match coarse {
                true => {
                    let mut p = EyePass::reusable_with(self.coarse_eye.take(), size, isa, false)?;
                    p.target.take_stats();
                    Some(p)
                }
                false => previous.take(),
            };
            let culled_pass = match (&self.backends, host_depth) {
                (_, Some(d)) => eye::cull_on_host_depth(
                    scene,
                    state,
                    camera,
                    traversal,
                    &d.depth,
                    pass.take().expect("made above"),
                )?,
                (None, None) => eye::eye_pass_culled_into(
                    scene,
                    &self.meshes,
                    state,
                    camera,
                    size,
                    traversal,
                    pass.take(),
                )?,
                (Some(f), None) => {
                    let mut backend = f(visibility::ViewRole::Eye {
                        width: size.0,
                        height: size.1,
                    });
                    eye::cull_with(scene, state, camera, &o, coarse, backend.as_mut())?;
                    let rendered = &state.result.rendered;
                    match coarse {
                        true => eye::coarse_pass_of(
                            scene,
                            &self.meshes,
                            camera,
                            pass.take().expect("made above"),
                            (rendered, o.coverage.sampling()),
                        )?,
                        false => eye::eye_pass_of(
                            scene,
                            &self.meshes,
                            camera,
                            (w, h),
                            pass.take(),
                            Some(rendered),
                        )?,
                    }
                }
            };
            let r = &state.result;
            self.psr.clear();
            self.psr.reserve(scene.objects().len());
            let visible = r
                .rendered
                .iter()
                .filter(|id| scene.object(**id).flags.visible);
            self.psr.extend(visible.map(|id| scene.id_of(id.slot())));
            self.psr.sort_unstable();
            // Coarse: the exact eye pass, when read, from the PSR (every
            // object owning an output pixel is in it: the same depth and ids).
            let eye = match coarse {
                true => {
                    self.coarse_eye = Some(culled_pass);
                    match exact {
                        true => Some(eye::eye_pass_of(
                            scene,
                            &self.meshes,
                            camera,
                            (w, h),
                            previous.take(),
                            Some(&r.rendered),
                        )?),
                        false => None,
                    }
                }
                false => Some(culled_pass),
            };
            (eye, r.stats.queries, r.stats.waits)
        } else {
            let eye = eye_pass_reusing(scene, &self.meshes, camera, w, h, previous)?;
            self.psr.clear();
            self.psr
                .extend(self.all_visible.iter().map(|id| scene.id_of(id.slot())));
            if lights_culled {
                // The light passes read the hierarchy.
                self.culling.get_or_insert_with(|| EyeCulling::new(scene));
            }
            (Some(eye), 0, 0)
        };
        // The culling lights mark the eye's visible surface points (or, from
        // a coarse pass, its receiver polygons), each leaving out those of
        // surfaces that face away from it.
        if lights_culled {
            receiver_skips(&mut self.lights, &o, &mut self.skip_lights);
            let skips = eye::SkipLights {
                lights: &self.skip_lights,
                two_sided: o.two_sided,
            };
            match (&eye, &self.coarse_eye, &self.culling) {
                (Some(eye), _, _) if !coarse || fine_points => visible_points_into(
                    scene,
                    camera,
                    eye,
                    o.coverage.sampling(),
                    stored_points,
                    skips,
                    (&mut self.receivers, &mut self.receiver_runs),
                ),
                (_, Some(pass), Some(state)) => coarse_receivers::coarse_receivers_into(
                    scene,
                    camera,
                    (&pass.target, &mut self.coarse_rows, &mut self.coarse_bounds),
                    &state.result.rendered,
                    skips,
                    &mut self.receivers,
                ),
                _ => unreachable!("a coarse frame keeps its pass and state"),
            }
        }
        let eye_ms = ms(start);
        if auto && may_cull && !coarse {
            let traversal = match (&self.culling, culled) {
                (Some(state), true) => state.result.stats,
                _ => TraversalStats::default(),
            };
            let raster = eye.as_ref().map(|e| e.target.stats()).unwrap_or_default();
            let host = self.backends.is_some();
            let halves = (self.culling.as_ref().and_then(|s| s.halves)).filter(|_| culled);
            let cost = match &halves {
                Some(halves) => auto::split_eye_cost(&o.auto, halves),
                None => auto::eye_cost(&o.auto, culled, &raster, &traversal, host),
            };
            self.auto_eye.observe(&o.auto, culled, cost, None);
            tracing::debug!(
                target: "shadowcull::auto",
                view = "eye",
                culled,
                cost,
                eye_ms,
                triangles = raster.triangles_in,
                tiles = raster.tiles_touched,
                pixels = raster.pixels_tested,
                nodes = traversal.nodes_visited,
                queries = traversal.queries,
                objects = traversal.objects_rendered,
                points = lights_culled,
            );
        }

        let axes = |l: &scene::Light, b: &scene::Aabb| {
            shadowgen::SegmentAxis::new(l, b).map(|a| visibility::DepthAxis {
                origin: a.origin,
                axis: a.axis,
            })
        };

        // 2.–4. Per light, side by side: the light pass (PSC) of a culling
        // light, then the volumes, the stencil and the mask.
        // Clamping's receivers under `psr`: the receiving objects the eye
        // pass drew (every receiving object without culling).
        let psr_model = (o.clamping != ClampingSpec::None || o.count_fill)
            && o.clamping_receivers == options::ClampReceiversSpec::Psr;
        let receives = match (&self.culling, culled && psr_model) {
            (Some(state), true) => {
                let mut r = vec![false; scene.objects().len()];
                for id in &state.result.rendered {
                    r[id.index()] = scene.object(*id).flags.receives;
                }
                Some(r)
            }
            _ => None,
        };
        let pass_options = o.light_pass_options();
        let pass = match (lights_culled, &self.culling) {
            (true, Some(state)) => {
                let (hierarchy, meshes) = state.parts();
                Some(light::LightPassInput {
                    pass: visibility::PassInput {
                        hierarchy,
                        scene,
                        meshes,
                        camera,
                        receivers: &self.receivers,
                        skip_receivers: 0,
                        fragments: Some(visibility::FragmentSource {
                            axes: Some(&axes),
                            slices: None,
                        }),
                    },
                    backends: self.backends.as_deref(),
                    options: &pass_options,
                    frame,
                    slices: ((w, h), o.slices),
                })
            }
            _ => None,
        };
        let psr = self.psr.len() as u64;
        let shared = light_frame::FrameShared {
            scene,
            camera,
            options: &o,
            viewport: (w, h),
            eye: eye.as_ref(),
            eye_counts: light_frame::EyeCounts {
                ms: eye_ms,
                psr,
                queries: eye_queries,
                waits: eye_waits,
            },
            pass,
            all_casters: &self.all_casters,
            receives: receives.as_deref(),
            stored_points,
            auto_culling: auto && may_cull,
            all_caster_triangles,
            host: self.backends.is_some(),
        };
        let fill_ms = Self::run_lights_of(&mut self.lights, &shared)?;
        self.eye = eye;
        let camera = *camera;
        self.finish_frame(
            frame,
            start,
            (w, h),
            camera,
            eye_ms,
            fill_ms,
            (eye_queries, eye_waits),
        );
        Ok(())
    }

    /// Every live light's share of the frame, side by side; returns the
    /// time spent counting fill (a measurement, not part of the frame).
    fn run_lights_of(
        lights: &mut [LightSlot],
        shared: &light_frame::FrameShared<'_>,
    ) -> Result<f64> {
        use rayon::prelude::*;
        lights
            .par_iter_mut()
            .filter_map(|slot| slot.state.as_mut())
            .map(|s| light_frame::run(s, shared))
            .try_reduce(|| 0.0, |a, b| Ok(a + b))
    }

    /// The frame's statistics, once every light has run.
    #[allow(clippy::too_many_arguments)]
    fn finish_frame(
        &mut self,
        frame: u32,
        start: Instant,
        viewport: (u32, u32),
        camera: Camera,
        eye_ms: f64,
        fill_ms: f64,
        (eye_queries, eye_waits): (u64, u64),
    ) {
        self.camera = Some(camera);
        self.output_current = true;
        self.viewport = viewport;
        self.stats = FrameStats {
            frame,
            // Fill accounting is a measurement, not part of the frame.
            frame_ms: ms(start) - fill_ms,
            eye_ms,
            objects: self.counts.objects as u64,
            triangles: self.counts.drawn_triangles as u64,
            psr: self.psr.len() as u64,
            eye_queries,
            eye_waits,
            lights: self.lights.iter().filter(|s| s.state.is_some()).count() as u32,
        };
    }

    /// The output of the last [`Pipeline::frame`] call, again: `None` before
    /// the first, after a failed one, and after any edit since (of the
    /// scene, a light or the options), which would make it describe a scene
    /// that no longer is. A [`FrameOutput`] borrows the pipeline, so none can
    /// be held across an edit; a host that reads a frame's results after
    /// editing for the next (a renderer drawing frame N while it prepares
    /// N + 1) copies what it keeps first. The C ABI's output pointers stay
    /// valid until the next frame call (removed lights' volume buffers are
    /// kept until then), and the Python frame dictionary is a copy.
    pub fn last_output(&self) -> Option<FrameOutput<'_>> {
        self.camera
            .as_ref()
            .filter(|_| self.output_is_current())
            .map(|_| FrameOutput { pipeline: self })
    }

    /// No edit (of the scene, a light or the options) since the last
    /// successful frame.
    fn output_is_current(&self) -> bool {
        self.output_current && !self.edited && !self.scene.has_staged_edits()
    }

    /// The exact ray-cast shadow mask [`crate::reference`] of light `light`
    /// on the last frame's visible surface, with the options' reference settings: the check every
    /// culling and stencil option is measured against. The triangle BVH is
    /// built on first use.
    ///
    /// # Errors
    /// [`Error::Options`] before the first frame, after scene edits not yet
    /// framed, or for an unknown light.
    pub fn reference_mask(&mut self, light: LightId) -> Result<ReferenceMask> {
        let Some(camera) = self.camera else {
            return Err(Error::Options {
                field: "reference_mask".into(),
                message: "no frame has run yet".into(),
            });
        };
        let (w, h) = self.viewport;
        self.check_memory(w, h, true)?;
        if !self.output_is_current() {
            return Err(Error::Options {
                field: "reference_mask".into(),
                message: "the scene, a light or the options were edited after the last frame: run a frame first".into(),
            });
        }
        self.exact_eye()?;
        let Some(eye) = &self.eye else {
            return Err(Error::Options {
                field: "reference_mask".into(),
                message: "no eye pass to cast from".into(),
            });
        };
        let light = self
            .light_state(light)
            .map_err(|e| match e {
                Error::Options { message, .. } => Error::Options {
                    field: "reference_mask".into(),
                    message,
                },
                e => e,
            })?
            .light;
        let scene = &self.scene;
        let bvh_ms = &mut self.bvh_ms;
        let options = self.options.reference_options();
        let pool = self.pool.clone();
        let bvh = &mut self.bvh;
        let run = move || {
            let bvh = bvh.get_or_insert_with(|| {
                let t = Instant::now();
                let b = TriangleBvh::new(scene);
                *bvh_ms = ms(t);
                b
            });
            try_reference_mask(
                bvh,
                &camera,
                &light,
                eye.target.width(),
                eye.target.height(),
                &options,
                Some(eye.surface()),
            )
        };
        in_pool(pool.as_ref(), run)
    }

    /// The last frame's eye pass at its viewport, rasterized now (every
    /// visible object, exact) when the frame ran none because nobody read
    /// one: the visible surface the reference and a GPU check take.
    ///
    /// # Errors
    /// [`Error::Options`] before the first frame; [`Error::Raster`] for a
    /// target larger than the rasterizer allows.
    pub fn exact_eye(&mut self) -> Result<&EyePass> {
        let Some(camera) = self.camera else {
            return Err(Error::Options {
                field: "exact_eye".into(),
                message: "no frame has run yet".into(),
            });
        };
        if self.eye.is_none() {
            let (w, h) = self.viewport;
            let scene: &Scene = &self.scene;
            let meshes = &self.meshes;
            let build = || eye_pass_reusing(scene, meshes, &camera, w, h, None);
            let eye = in_pool(self.pool.as_ref(), build)?;
            self.eye = Some(eye);
        }
        Ok(self.eye.as_ref().expect("built above"))
    }

    /// Checks the memory estimate of a `w × h` frame of the current scene
    /// and lights ([`memory`]) against the options' limit, with the
    /// reference's share when `reference`.
    fn check_memory(&self, w: u32, h: u32, reference: bool) -> Result<()> {
        let options = PipelineOptions {
            reference_every: u32::from(reference),
            ..self.options
        };
        let workload = memory::Workload {
            width: w,
            height: h,
            lights: self.live_lights().count() as u32,
            triangles: self.counts.triangles as u64,
            objects: self.counts.objects as u64,
            rows: 0,
        };
        memory::estimate(&options, &workload).check(memory::limit(&self.options))
    }

    /// Time spent building the reference's triangle BVH (ms), 0 until
    /// [`Pipeline::reference_mask`] first ran.
    pub fn reference_bvh_ms(&self) -> f64 {
        self.bvh_ms
    }
}

/// A frame's results, borrowed from the [`Pipeline`] until its next `frame`.
#[derive(Clone, Copy)]
pub struct FrameOutput<'a> {
    pipeline: &'a Pipeline,
}

impl std::fmt::Debug for FrameOutput<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameOutput")
            .field("psr", &self.psr().len())
            .field("lights", &self.light_count())
            .finish_non_exhaustive()
    }
}

impl<'a> FrameOutput<'a> {
    /// The potentially shadowed receivers: the objects the eye pass drew,
    /// ascending (every object without culling).
    pub fn psr(&self) -> &'a [ObjectId] {
        &self.pipeline.psr
    }

    /// Frame-level statistics.
    pub fn stats(&self) -> &'a FrameStats {
        &self.pipeline.stats
    }

    /// The number of lights of the frame.
    pub fn light_count(&self) -> usize {
        self.pipeline.live_lights().count()
    }

    /// The results of light `id` (`None` for an unknown or stale id).
    pub fn light(&self, id: LightId) -> Option<LightOutput<'a>> {
        self.pipeline
            .light_state(id)
            .ok()
            .map(|state| LightOutput { state })
    }

    /// Every light's results, in the order of their ids' slots.
    pub fn lights(self) -> impl Iterator<Item = LightOutput<'a>> + 'a {
        self.pipeline
            .live_lights()
            .map(|state| LightOutput { state })
    }

    /// The eye pass: reversed-Z depth and the visible `(object, triangle)`
    /// per pixel, row 0 at the top. `None` when the frame ran none because
    /// nobody read it (no view culled, `stencil: none`, no `count_fill`):
    /// [`Pipeline::exact_eye`] rasterizes it then.
    pub fn eye(&self) -> Option<&'a EyePass> {
        self.pipeline.eye.as_ref()
    }
}

/// One light's results in a [`FrameOutput`].
#[derive(Clone, Copy)]
pub struct LightOutput<'a> {
    state: &'a LightState,
}

impl std::fmt::Debug for LightOutput<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LightOutput")
            .field("light", &self.state.light)
            .field("psc", &self.psc().len())
            .field("volume_ranges", &self.volumes().ranges.len())
            .finish_non_exhaustive()
    }
}

impl<'a> LightOutput<'a> {
    /// The light's id.
    pub fn id(&self) -> LightId {
        self.state.id
    }

    /// The light.
    pub fn light(&self) -> &'a Light {
        &self.state.light
    }

    /// The potential shadow casters: the objects whose volumes were built,
    /// ascending (every object without culling).
    pub fn psc(&self) -> &'a [ObjectId] {
        &self.state.psc
    }

    /// The shadow volumes to draw: positions in each caster's local space
    /// (`w = 0` for points at infinity), indices, and one range per caster
    /// (object, segment, `world_from_local`, method, cap ranges, scissor,
    /// depth bounds). See `docs/host.md` for drawing them on a GPU.
    pub fn volumes(&self) -> &'a VolumeBuffer {
        &self.state.scratch.volume.buffer
    }

    /// The volume ranges with their casters as typed ids: each range of
    /// [`LightOutput::volumes`] with `ObjectId::from_bits(range.object)`
    /// (raster, which holds the ranges, knows no scene ids).
    pub fn ranges(
        &self,
    ) -> impl ExactSizeIterator<Item = (ObjectId, &'a raster::VolumeRange)> + 'a {
        let ranges = &self.state.scratch.volume.buffer.ranges;
        ranges.iter().map(|r| (ObjectId::from_bits(r.object), r))
    }

    /// The light views the light pass used (empty when the light did not
    /// cull this frame: without culling, or as `culling: auto` chose).
    pub fn views(&self) -> &'a [LightView] {
        if self.state.culled {
            self.state.culling.pass.views()
        } else {
            &[]
        }
    }

    /// This light's counters (the frame's eye figures repeated).
    pub fn stats(&self) -> &'a ShadowStats {
        &self.state.stats
    }

    /// Volume construction counters (silhouette cache hits and misses, methods).
    pub fn volume_stats(&self) -> &'a VolumeStats {
        &self.state.volume_stats
    }

    /// The four-class shadow mask; `None` with [`StencilBackend::None`].
    pub fn mask(&self) -> Option<&'a Mask> {
        self.state.shadow.as_ref().map(|s| &s.mask)
    }

    /// The stencil stage's full output (mask, raw stencil, tile image);
    /// `None` with [`StencilBackend::None`].
    pub fn shadow(&self) -> Option<&'a ShadowFrame> {
        self.state.shadow.as_ref()
    }
}

/// Gives each culling light a bit of the receiver points' skip masks
/// ([`visibility::ReceiverPoints::skip`]), and `lights` its light at that
/// bit: its light pass leaves out the points of surfaces that face away
/// from it. Their pixels are unlit whatever their stencil holds
/// ([`crate::mask::classify_runs`]), so the casters that shadow only them
/// need no volume; every caster that shadows a surface the light reaches
/// still shadows a point its pass takes, so the masks do not change. Not
/// for the hybrid, whose shadow maps are the light views' depth (its
/// approximate classification would change with them), and at most 32
/// lights (the rest take every point).
fn receiver_skips(slots: &mut [LightSlot], o: &PipelineOptions, lights: &mut Vec<scene::Light>) {
    lights.clear();
    if o.stencil == StencilBackend::Hybrid {
        return;
    }
    let culling = slots
        .iter_mut()
        .filter_map(|s| s.state.as_mut())
        .filter(|s| s.culled);
    for (k, s) in culling.take(u32::BITS as usize).enumerate() {
        s.skip_bit = 1 << k;
        lights.push(s.light);
    }
}

/// Runs `f` in `pool`, or on the caller's pool (rayon's global one) without.
pub(super) fn in_pool<R: Send>(
    pool: Option<&Arc<rayon::ThreadPool>>,
    f: impl FnOnce() -> R + Send,
) -> R {
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

/// A pool of `threads` workers, `None` for 0 (rayon's global pool).
fn own_pool(threads: u32) -> Result<Option<Arc<rayon::ThreadPool>>> {
    if threads == 0 {
        return Ok(None);
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads as usize)
        .thread_name(|i| format!("shadowcull-{i}"))
        .build()
        .map(|p| Some(Arc::new(p)))
        .map_err(|e| Error::Options {
            field: "threads".into(),
            message: e.to_string(),
        })
}

/// The slot ids of `scene`'s live objects whose flags pass `keep`, ascending,
/// into `out` (cleared first).
fn live_slots(scene: &Scene, keep: fn(&scene::ObjectFlags) -> bool, out: &mut Vec<ObjectId>) {
    out.clear();
    out.extend(
        scene
            .objects()
            .iter()
            .enumerate()
            .filter(|(_, o)| o.alive && keep(&o.flags))
            .map(|(i, _)| ObjectId::from_slot(i as u32)),
    );
}

fn live_slots_of(scene: &Scene, keep: fn(&scene::ObjectFlags) -> bool) -> Vec<ObjectId> {
    let mut out = Vec::new();
    live_slots(scene, keep, &mut out);
    out
}

fn check_options(options: &PipelineOptions) -> Result<()> {
    options.validate().map_err(|e| Error::Options {
        field: e.field.into(),
        message: e.message,
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
