//! The light pass: shadow-caster culling (PSC) [Steiner §4.3.1–4.3.3; Bittner,
//! Mattausch, Silvennoinen, Wimmer 2011, "Shadow caster culling for efficient
//! shadow mapping"].
//!
//! Per light, the views fitted to the intersection body B ([`fit_light_views`])
//! each get a depth target and a receiver target. The eye's visible surface
//! points (the fragment-level receivers) mark, per light pixel, the farthest
//! receiver depth. A culling traversal then runs in each view with:
//!
//! - occluders: only the triangles that cast under the shared facing rule
//!   (light-facing ones; every triangle when two-sided), drawn
//!   inner-conservative at the farthest depth over pixel ∩ triangle, so an
//!   occluder covers a light pixel only where it covers all of it;
//! - queries: node boxes, outer-conservative at the nearest depth, counting a
//!   sample only over a marked pixel and at or in front of its receiver depth
//!   (the raster crate's receiver restriction) — a box that passes nowhere
//!   holds no caster that can shadow a visible receiver point, nor one wholly
//!   hidden behind other casters from the light.
//!
//! PSC is the union over the light's views of the objects found visible.
//!
//! With [`PassInput::fragments`] (fragment receivers for clamping) each
//! view's receiver target also keeps the nearest receiver depth per pixel,
//! and after its traversal the view reads the depth intervals of the casters
//! it found along their clamping axes (`fragment_depths.rs`); the pass
//! gathers them per caster ([`LightPassResult::fragments`]).
//!
//! With [`Sampling::Point`] (aggressive) receivers mark only the pixels
//! holding their projection, unpushed, and occluders and queries sample
//! pixel centres.
//!
//! Conservative receivers: each point is pushed away from the light by
//! [`RECEIVER_PUSH`](crate::RECEIVER_PUSH) of its distance (directional: of the scene diameter)
//! before marking, beyond the f32 rounding of its light-space depth, and marks
//! every pixel within [`raster::RECEIVER_EPS_PX`] of its projection — through
//! the segments of `receivers.rs`, which mark a superset.

use crate::culler::{CullResult, Objects, TraversalStats, ViewCuller};
use crate::fragment_depths::{FragmentDepths, FragmentSource, ViewFragments, ViewIntervals};
use crate::hierarchy::Hierarchy;
use crate::intersection_body::{intersection_body_into, BodyScratch, Polyhedron};
use crate::light_view::{fit_light_views_into, FitScratch, LightView};
use crate::receivers::{Marks, Prepared, ReceiverPoints};
use crate::traverse::Culling;
use crate::view_setup::{drawn_mesh, ConvexOccluders, MeshData, Sampling, ViewSetup};
use crate::view_split::cull_views_into;
use crate::Result;
use glam::{DMat4, DVec3, DVec4};
use raster::{
    Coverage, DepthPick, DepthTarget, OcclusionBackend, QueryBuffers, QueryMode, QueryOptions,
    ReceiverTarget, SyncBackend, TileSize,
};
#[cfg(feature = "parallel")]
use rayon::prelude::*;
use scene::{faces_light, Camera, Light, LightId, ObjectId, Plane, Scene};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

/// Which view a host's occlusion backend serves ([`BackendFactory`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewRole {
    /// The eye pass: a `width × height` view; occluders with standard
    /// coverage; queries as the eye's [`ViewSetup`] says.
    Eye {
        /// Viewport width in pixels.
        width: u32,
        /// Viewport height in pixels.
        height: u32,
    },
    /// View `view` of light `light`'s pass: a `size × size` view; with
    /// conservative sampling, occluders inner-conservative at farthest depth
    /// and queries outer-conservative at nearest depth; queries restricted to
    /// the receiver target set by [`OcclusionBackend::set_receivers`].
    LightView {
        /// The light (the pipeline's id of it).
        light: LightId,
        /// The view's index among the light's views.
        view: u32,
        /// Side of the view in pixels.
        size: u32,
    },
}

/// Makes the occlusion backend of one view for one frame: the seam through
/// which a host renderer answers the passes' draws and queries with its own
/// (GPU) queries. Called from the pipeline's pool threads, one call per view
/// and frame; each backend is used by one thread and dropped after its view.
pub type BackendFactory = dyn Fn(ViewRole) -> Box<dyn OcclusionBackend + Send> + Send + Sync;

/// Options of a light pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightPassOptions {
    /// The traversal in every light view.
    pub culling: Culling,
    /// Side of every light view or cube face, in pixels.
    pub resolution: u32,
    /// Query threshold (0: conservative).
    pub threshold: u32,
    /// Every triangle casts (the reference's two-sided mode).
    pub two_sided: bool,
    /// Conservative (exact mask) or point-sampled (aggressive) light views.
    pub sampling: Sampling,
    /// The light views' rasterizer level ([`DepthTarget::set_instruction_set`]).
    pub instruction_set: raster::InstructionSet,
    /// Draw each solid convex mesh's occluder proxy
    /// ([`scene::occluder_proxy`]) in place of its mesh: far fewer
    /// triangles, inside the solid, so culling stays conservative. Not with
    /// [`LightPassOptions::keep_depth`], whose depths are shadow maps of the
    /// casters' own surfaces.
    pub proxies: bool,
    /// Keep every view's depth target after the pass ([`LightPass::view_depths`]):
    /// the casters the traversal drew, at the light's depth, as shadow maps
    /// (the hybrid stencil's \[ChanDurand04\]). Costs one target per view
    /// instead of one per thread.
    pub keep_depth: bool,
}

/// What every light's pass of one frame reads: the objects, the eye and the
/// eye's visible surface.
#[derive(Clone, Copy)]
pub struct PassInput<'a> {
    /// The object hierarchy.
    pub hierarchy: &'a Hierarchy,
    /// The scene.
    pub scene: &'a Scene,
    /// Meshes in the backends' form.
    pub meshes: &'a MeshData,
    /// The eye.
    pub camera: &'a Camera,
    /// The eye's visible surface points, in parts (any split that keeps
    /// each joined point in the part of the point it is joined to).
    pub receivers: &'a [ReceiverPoints],
    /// The light's bits in [`ReceiverPoints::skip`]: the points whose mask
    /// shares one are left out (0: none is).
    pub skip_receivers: u32,
    /// Fragment receivers for clamping: along each caster's clamping axis
    /// and in the eye slices, the pass also finds each caster's fragment
    /// intervals ([`LightPassResult::fragments`], [`LightPassResult::slices`]);
    /// `None` skips them.
    pub fragments: Option<FragmentSource<'a>>,
}

/// What a light pass found.
#[derive(Clone, Debug, Default)]
pub struct LightPassResult {
    /// Potential shadow casters: objects that can shadow a visible receiver.
    pub psc: Vec<ObjectId>,
    /// Light views used.
    pub views: usize,
    /// Counters summed over the views.
    pub stats: TraversalStats,
    /// The bundled rasterizer's counters summed over the views (zero for
    /// views a host backend ran): what `culling: auto` weighs.
    pub raster: raster::RasterStats,
    /// Per caster of the PSC, its fragment intervals along its axis when
    /// [`PassInput::fragments`] reads the axes (else empty).
    pub fragments: FragmentDepths,
    /// Per caster of the PSC, its occupied eye slices when
    /// [`PassInput::fragments`] reads the slices (else empty).
    pub slices: FragmentDepths,
    /// Wall time spent on the fragment intervals, summed over the views (ms).
    pub fragment_ms: f64,
}

/// One light view's persistent state: its culler, its query buffers and
/// its last result, reused from frame to frame (cleared, not reallocated).
#[derive(Debug, Default)]
struct ViewSlot {
    culler: ViewCuller,
    /// The bundled backend's query results, kept between frames.
    queries: QueryBuffers,
    /// The last traversal's result (its lists reused).
    result: CullResult,
    /// The bundled rasterizer's counters of the last traversal.
    raster: raster::RasterStats,
    /// The fragment intervals of the last traversal's casters, and the
    /// per-pixel ranges they are merged from.
    fragments: ViewIntervals,
    ranges: Vec<[f64; 2]>,
    fragment_ms: f64,
    /// With [`LightPassOptions::keep_depth`], the last traversal's depth
    /// target (`depth_valid`: drawn by the bundled rasterizer this run).
    depth: Option<DepthTarget>,
    depth_valid: bool,
}

/// A depth target and a receiver target (one light view's worth, 8 bytes
/// per texel), shared by the views one group claims: the views run in as
/// many groups as the pool has threads, each group running the views it
/// claims one after another, so a light holds one set per thread instead of
/// one per view (a point light's
/// six 1024² cube faces: two sets, 16 MiB, instead of six, 48 MiB). Nothing
/// a view computes depends on which set it used: each view clears both.
///
/// A set holds a pair of targets for whole views and, once a crowded view
/// was culled as quadrants (`view_split.rs`), a pair of a quarter the size.
#[derive(Debug, Default)]
struct TargetSet {
    whole: TargetPair,
    quadrant: TargetPair,
}

impl TargetSet {
    /// Holds the pairs the `views` of whole side `full` (and their
    /// quadrants) will take ([`TargetPair::prepare`]).
    fn prepare(&mut self, views: &[LightView], full: u32) -> Result<()> {
        for (pair, side) in [(&mut self.whole, full), (&mut self.quadrant, full / 2)] {
            if views.iter().any(|v| v.resolution == side) {
                pair.prepare((side, side))?;
            }
        }
        Ok(())
    }

    /// The pair `view` takes.
    fn pair(&mut self, view: &LightView, full: u32) -> &mut TargetPair {
        if view.resolution == full {
            &mut self.whole
        } else {
            &mut self.quadrant
        }
    }
}

/// One view's depth target and receiver target.
#[derive(Debug, Default)]
struct TargetPair {
    target: Option<DepthTarget>,
    marks: Option<Arc<ReceiverTarget>>,
}

impl TargetPair {
    /// The set's targets for a `size` view: its own, unless the size
    /// changed or a host backend kept a reference to the receivers; new
    /// ones otherwise.
    fn take(&mut self, size: (u32, u32)) -> Result<(DepthTarget, Arc<ReceiverTarget>)> {
        let target = match self.target.take() {
            Some(t) if (t.width(), t.height()) == size => t,
            _ => DepthTarget::new(size.0, size.1, TileSize::T8, false)?,
        };
        let marks = match self.marks.take() {
            Some(r)
                if r.size() == size && Arc::strong_count(&r) == 1 && Arc::weak_count(&r) == 0 =>
            {
                r
            }
            _ => Arc::new(ReceiverTarget::for_target(&target)),
        };
        Ok((target, marks))
    }

    /// Holds targets for a `size` view, before the views are claimed: a
    /// group that claims its first view in a later frame (the other
    /// groups claimed them all until then) would otherwise allocate its
    /// set in that frame.
    fn prepare(&mut self, size: (u32, u32)) -> Result<()> {
        let (target, marks) = self.take(size)?;
        (self.target, self.marks) = (Some(target), Some(marks));
        Ok(())
    }
}

/// One light's persistent light-pass state: a slot per light view, the
/// receiver buffers (reused, not reallocated, from frame to frame) and the
/// casting triangles of the objects drawn as occluders.
#[derive(Debug, Default)]
pub struct LightPass {
    /// Per view; a lock only so that whichever group claims a view can run
    /// it (each view is claimed once per frame: never contended).
    slots: Vec<Mutex<ViewSlot>>,
    sets: Vec<TargetSet>,
    /// A second receiver target, for the view whose many segments are
    /// marked on two threads ([`Marks::mark`]); one per light.
    spare: Mutex<Option<ReceiverTarget>>,
    receivers: Prepared,
    /// The views fitted this run (`whole`), and the views culled (`views`:
    /// the fitted ones, a crowded one as its quadrants; a slot each).
    whole: Vec<LightView>,
    views: Vec<LightView>,
    casting: CastingCache,
    /// The intersection body, the views just fitted, and the buffers of
    /// their construction: kept so a steady frame allocates nothing.
    body: Polyhedron,
    fitted: Vec<LightView>,
    body_scratch: BodyScratch,
    fit_scratch: FitScratch,
    /// Per object: already in the PSC being collected.
    in_psc: Vec<bool>,
    /// The job frame number of the next run, shared by every view's culler.
    frame: u32,
}

/// Per object, the triangles it casts with (light-facing, or all when
/// two-sided), found on first use and kept while the object (transform,
/// mesh and its version) and the light stay as they were: a static scene
/// finds them once, not every frame. When the light moves, each entry's
/// allocation is kept as its slot's spare and refilled in place on the
/// object's next use: a moving light allocates nothing either.
#[derive(Debug, Default)]
struct CastingCache {
    /// The light's homogeneous position bits, the two-sided rule and
    /// whether proxies stand in for meshes.
    key: Option<([u64; 4], bool, bool)>,
    /// Per object.
    entries: Vec<CastingEntry>,
    /// A moved object's casting triangles, found by the update to compare
    /// with its old list: an unchanged set keeps its list (no allocation).
    found: Vec<[u32; 3]>,
}

/// One object's slot of the cache (boxed: an empty slot costs 24 bytes, not
/// 180).
#[derive(Debug, Default)]
struct CastingEntry {
    /// The current casting triangles, found on first use.
    current: OnceLock<Box<Casting>>,
    /// An outdated entry whose allocations the next finding reuses.
    spare: Mutex<Option<Box<Casting>>>,
}

impl CastingEntry {
    /// Moves the current entry (if any) to the spare.
    fn retire(&mut self) {
        if let Some(c) = self.current.take() {
            *self.spare.get_mut().unwrap_or_else(PoisonError::into_inner) = Some(c);
        }
    }
}

/// The items of `found` as a casting list, written into `list` in place when
/// it is unshared and `all` long (the most `found` can yield: a list of the
/// same mesh), else into a new list; padded as [`refill`] pads.
fn fill(list: &mut Arc<[[u32; 3]]>, found: impl Iterator<Item = [u32; 3]>, all: usize) {
    match Arc::get_mut(list).filter(|l| l.len() == all) {
        Some(l) => {
            let mut n = 0;
            for (slot, t) in l.iter_mut().zip(found) {
                *slot = t;
                n += 1;
            }
            let pad = [l.first().filter(|_| n > 0).map_or(0, |t| t[0]); 3];
            l[n..].fill(pad);
        }
        None => {
            let found: Vec<[u32; 3]> = found.collect();
            let pad = [found.first().map_or(0, |t| t[0]); 3];
            *list = found
                .iter()
                .copied()
                .chain(std::iter::repeat(pad))
                .take(all.max(found.len()))
                .collect();
        }
    }
}

/// `found` as a casting list: written into `list` when it is unshared and at
/// least as long, else into a new list of `all` (the mesh's triangle count)
/// entries, so that a moving object's later sets fit in place. The tail is
/// padded with a degenerate triangle, which every draw rejects.
fn refill(list: &mut Arc<[[u32; 3]]>, found: &[[u32; 3]], all: usize) {
    let pad = [found.first().map_or(0, |t| t[0]); 3];
    match Arc::get_mut(list).filter(|l| l.len() >= found.len()) {
        Some(l) => {
            l[..found.len()].copy_from_slice(found);
            l[found.len()..].fill(pad);
        }
        None => {
            *list = found
                .iter()
                .copied()
                .chain(std::iter::repeat(pad))
                .take(all.max(found.len()))
                .collect();
        }
    }
}

/// The triangles of object `id` facing `light` (the shared facing rule):
/// of `mesh` (the one it draws as an occluder, [`drawn_mesh`]), or of
/// `proxy` (triangles over that mesh's vertices) when given.
fn facing_triangles<'a>(
    scene: &'a Scene,
    light: &'a Light,
    id: ObjectId,
    mesh: scene::MeshId,
    proxy: Option<&'a [[u32; 3]]>,
) -> impl Iterator<Item = [u32; 3]> + 'a {
    let o = scene.object(id);
    let positions = scene.graph().meshes()[mesh.index()].positions();
    let (m, mirrored) = (o.world_from_local, o.mirrored);
    // Counter-clockwise is front even for mirrored objects (as
    // `Scene::world_triangle`).
    let world = move |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| scene::transform::world_point(&m, positions[i as usize]));
        match mirrored {
            true => [a, c, b],
            false => [a, b, c],
        }
    };
    let triangles = proxy.unwrap_or(scene.graph().meshes()[mesh.index()].triangles());
    triangles
        .iter()
        .filter(move |t| faces_light(&world(t), light))
        .copied()
}

/// One object's casting triangles and what they were found for.
#[derive(Debug)]
struct Casting {
    world_from_local: DMat4,
    mesh: scene::MeshId,
    version: u64,
    triangles: Arc<[[u32; 3]]>,
}

impl CastingCache {
    /// Drops every entry that no longer matches `scene` and `light`.
    fn update(
        &mut self,
        scene: &Scene,
        meshes: &MeshData,
        light: &Light,
        (two_sided, proxies): (bool, bool),
    ) {
        let key = (
            light.homogeneous().to_array().map(|v| (v + 0.0).to_bits()),
            two_sided,
            proxies,
        );
        if self.key != Some(key) {
            self.entries.iter_mut().for_each(CastingEntry::retire);
            self.key = Some(key);
        }
        let n = scene.objects().len();
        self.entries.truncate(n);
        self.entries.resize_with(n, CastingEntry::default);
        for (k, (entry, o)) in self.entries.iter_mut().zip(scene.objects()).enumerate() {
            let Some(c) = entry.current.get() else {
                continue;
            };
            let drawn = drawn_mesh(o, proxies);
            if c.mesh != drawn || c.version != scene.mesh_version(drawn) {
                entry.retire();
            } else if c.world_from_local.to_cols_array().map(f64::to_bits)
                != o.world_from_local.to_cols_array().map(f64::to_bits)
            {
                // Moved: its casting set is found again, into its old list
                // when that is unshared and long enough (no allocation).
                let e = &mut entry.current;
                let mut c = e.take().expect("checked");
                if !two_sided {
                    let id = ObjectId::from_slot(k as u32);
                    let proxy = meshes.proxy_of(drawn).filter(|_| proxies);
                    let all = proxy.map_or(meshes.triangles[drawn.index()].len(), |p| p.len());
                    self.found.clear();
                    self.found.reserve(all);
                    self.found.extend(facing_triangles(
                        scene,
                        light,
                        id,
                        drawn,
                        proxy.map(|p| &p[..]),
                    ));
                    if c.triangles[..] != self.found[..] {
                        refill(&mut c.triangles, &self.found, all);
                    }
                }
                c.world_from_local = o.world_from_local;
                let _ = e.set(c);
            }
        }
    }

    /// The casting triangles of `id` (found now when missing).
    fn get(
        &self,
        scene: &Scene,
        meshes: &MeshData,
        light: &Light,
        (two_sided, proxies): (bool, bool),
        id: ObjectId,
    ) -> Arc<[[u32; 3]]> {
        let entry = &self.entries[id.index()];
        entry
            .current
            .get_or_init(|| {
                let o = scene.object(id);
                let drawn = drawn_mesh(o, proxies);
                let proxy = meshes.proxy_of(drawn).filter(|_| proxies);
                let spare = entry
                    .spare
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .take();
                let mut c = spare.unwrap_or_else(|| {
                    Box::new(Casting {
                        world_from_local: o.world_from_local,
                        mesh: drawn,
                        version: 0,
                        triangles: Arc::new([]),
                    })
                });
                match (two_sided, proxy) {
                    (true, Some(p)) => c.triangles = p.clone(),
                    (true, None) => c.triangles = meshes.triangles_of(drawn),
                    (false, p) => {
                        let all = p.map_or(meshes.triangles[drawn.index()].len(), |p| p.len());
                        let found = facing_triangles(scene, light, id, drawn, p.map(|p| &p[..]));
                        fill(&mut c.triangles, found, all);
                    }
                }
                c.world_from_local = o.world_from_local;
                c.mesh = drawn;
                c.version = scene.mesh_version(drawn);
                c
            })
            .triangles
            .clone()
    }
}

/// The view's culling planes (inside positive) from its clip matrix: the
/// sides `|x| ≤ w`, `|y| ≤ w` and the far side `z ≥ 0` — not the near plane:
/// a caster between the light and the near plane still casts (its box meets
/// the apex region and its query says visible).
fn clip_planes(m: &DMat4) -> [Plane; 5] {
    let r = [m.row(0), m.row(1), m.row(2), m.row(3)];
    let plane = |v: DVec4| Plane {
        normal: v.truncate(),
        d: v.w,
    };
    [
        plane(r[3] + r[0]),
        plane(r[3] - r[0]),
        plane(r[3] + r[1]),
        plane(r[3] - r[1]),
        plane(r[2]),
    ]
}

impl LightPass {
    /// A light pass with no history.
    pub fn new() -> Self {
        LightPass::default()
    }

    /// The light views of the last [`LightPass::run`] (empty before the
    /// first): fitted to the intersection body, each with its world → clip
    /// matrix, kind and resolution; a view that held the light's receivers
    /// all but alone is there as its four quadrants (half the resolution,
    /// the same pixel grid), as it was culled, on the threads in parallel.
    pub fn views(&self) -> &[LightView] {
        &self.views
    }

    /// Per view of the last run, its depth target when the run kept it
    /// ([`LightPassOptions::keep_depth`]) and the bundled rasterizer drew it:
    /// the casting triangles of the objects the traversal found visible (with
    /// conservative sampling inner-conservative at the farthest depth over
    /// each pixel, else sampled at pixel centres), in the rows that hold
    /// receivers; elsewhere the background. `None` for a view a host backend
    /// ran, a view without receivers (nothing drawn), or when not kept.
    pub fn view_depths(&mut self) -> impl Iterator<Item = (&LightView, Option<&DepthTarget>)> {
        let n = self.views.len();
        self.views.iter().zip(self.slots[..n].iter_mut().map(|s| {
            let s = slot_mut(s);
            s.depth.as_ref().filter(|_| s.depth_valid)
        }))
    }

    /// Makes the next run job frame `frame`; later runs count on from it.
    /// Every view's culler takes this number ([`ViewCuller::set_frame`]), so
    /// a view that found no receivers for a while, or was re-fitted, stays
    /// in step with the job's frames.
    pub fn set_frame(&mut self, frame: u32) {
        self.frame = frame;
    }

    /// Forgets every view's culling history and the casting-triangle cache,
    /// keeping the buffers: the next run is a cold start (a keyframe).
    pub fn reset_history(&mut self) {
        for s in &mut self.slots {
            slot_mut(s).culler.reset();
        }
        self.casting.entries.clear();
        self.casting.key = None;
    }

    /// Carries every light view's state over to a rebuilt hierarchy
    /// ([`ViewCuller::remap`]).
    pub fn remap(&mut self, old: &Hierarchy, new: &Hierarchy) {
        for s in &mut self.slots {
            slot_mut(s).culler.remap(old, new);
        }
    }

    /// Finds the potential shadow casters of `light` for the receivers of
    /// `input` (the eye's visible surface points).
    ///
    /// # Errors
    /// Backend errors.
    pub fn run(
        &mut self,
        input: &PassInput<'_>,
        light: &Light,
        options: &LightPassOptions,
    ) -> Result<LightPassResult> {
        self.run_with(input, light, options, None)
    }

    /// [`LightPass::run`] with the views' draws and queries going to
    /// backends from `backends` (a factory and the light's key for
    /// [`ViewRole::LightView`]) instead of the bundled rasterizer.
    ///
    /// # Errors
    /// Backend errors.
    pub fn run_with(
        &mut self,
        input: &PassInput<'_>,
        light: &Light,
        options: &LightPassOptions,
        backends: Option<(&BackendFactory, LightId)>,
    ) -> Result<LightPassResult> {
        let mut out = LightPassResult::default();
        self.run_into(input, light, options, backends, &mut out)?;
        Ok(out)
    }

    /// [`LightPass::run_with`] into `out`, whose PSC list is reused: a steady
    /// frame (same views, no new object) allocates nothing.
    ///
    /// # Errors
    /// Backend errors.
    pub fn run_into(
        &mut self,
        input: &PassInput<'_>,
        light: &Light,
        options: &LightPassOptions,
        backends: Option<(&BackendFactory, LightId)>,
        out: &mut LightPassResult,
    ) -> Result<()> {
        let PassInput {
            hierarchy: h,
            scene,
            meshes,
            camera,
            receivers,
            skip_receivers,
            fragments: fragment_source,
        } = *input;
        let bounds = scene.bounds();
        intersection_body_into(
            &camera.frustum(),
            light,
            &bounds,
            &mut self.body,
            &mut self.body_scratch,
        );
        fit_light_views_into(
            &self.body,
            light,
            options.resolution.max(1),
            &mut self.fitted,
            &mut self.fit_scratch,
            &mut self.body_scratch.clip,
        );
        std::mem::swap(&mut self.whole, &mut self.fitted);
        let diameter = f64::from(bounds.size().length());
        let origin = light.position().unwrap_or_else(|| bounds.center());
        self.receivers.prepare(
            receivers,
            skip_receivers,
            light,
            origin,
            diameter,
            options.sampling,
            &self.whole,
        );
        // The views culled: the crowded one as its quadrants
        // (`view_split.rs`), unless their depth is kept as the hybrid's maps
        // (read as whole views) or fragment intervals are read (a caster's
        // intervals come from the views it was found in: in a quadrant it
        // was not found in, its receivers would go unread).
        let prepared = &self.receivers;
        let previous = std::mem::take(&mut self.views);
        let mut culled = std::mem::take(&mut self.fitted);
        if !options.keep_depth && fragment_source.is_none() {
            cull_views_into(&self.whole, |v| prepared.count_for(v), &mut culled);
        } else {
            culled.clone_from(&self.whole);
        }
        // A new set of views starts its culling history cold, but keeps the
        // target sets (their buffers are reused, not reallocated).
        let same = |a: &LightView, b: &LightView| (a.kind, a.resolution) == (b.kind, b.resolution);
        if previous.len() != culled.len() || !previous.iter().zip(&culled).all(|(a, b)| same(a, b))
        {
            for s in &mut self.slots {
                slot_mut(s).culler.reset();
            }
        }
        (self.views, self.fitted) = (culled, previous);
        let views = &self.views;
        if self.slots.len() < views.len() {
            self.slots.resize_with(views.len(), Mutex::default);
        }
        // The casting triangles of every object drawn as an occluder: kept
        // across frames, shared by the views.
        let rules = (options.two_sided, options.proxies && !options.keep_depth);
        self.casting.update(scene, meshes, light, rules);
        let cache = &self.casting;
        let casting =
            |id: ObjectId| -> Arc<[[u32; 3]]> { cache.get(scene, meshes, light, rules, id) };
        let shared = ViewsInput {
            spare: &self.spare,
            objects: Objects::new(h, scene, meshes),
            light,
            origin,
            diameter,
            casting: &casting,
            options,
            fragments: fragment_source.map(|source| ViewFragments {
                scene,
                light,
                source,
                diameter,
            }),
        };
        let frame = self.frame;
        self.frame = frame.saturating_add(1);
        for s in &mut self.slots {
            slot_mut(s).culler.set_frame(frame);
        }
        // The views are independent: each has its own culler. They run in
        // `groups` tasks (one per thread of the pool), each with its own
        // target set, each claiming the next unclaimed view until none is
        // left: balanced like a parallel loop over the views, but never
        // more target sets than groups, however rayon nests its tasks.
        #[cfg(feature = "parallel")]
        let threads = rayon::current_num_threads();
        #[cfg(not(feature = "parallel"))]
        let threads = 1;
        let groups = threads.clamp(1, views.len().max(1));
        if self.sets.len() < groups {
            self.sets.resize_with(groups, TargetSet::default);
        }
        // Every fitted view of a light has one side; quadrants half of it.
        let full = self.whole.first().map_or(0, |v| v.resolution);
        for set in &mut self.sets[..groups] {
            set.prepare(views, full)?;
        }
        let next = AtomicUsize::new(0);
        let slots = &self.slots;
        let group = |set: &mut TargetSet| -> Result<()> {
            loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(view) = views.get(k) else {
                    return Ok(());
                };
                let receivers = prepared.for_view(view);
                let backend = backends.map(|(f, light)| {
                    f(ViewRole::LightView {
                        light,
                        view: k as u32,
                        size: view.resolution,
                    })
                });
                let mut slot = slots[k].lock().unwrap_or_else(PoisonError::into_inner);
                slot.run(set.pair(view, full), &shared, view, receivers, backend)?;
            }
        };
        #[cfg(feature = "parallel")]
        self.sets[..groups].par_iter_mut().try_for_each(group)?;
        #[cfg(not(feature = "parallel"))]
        self.sets[..groups].iter_mut().try_for_each(group)?;
        out.psc.clear();
        out.psc.reserve(scene.objects().len());
        out.views = views.len();
        out.stats = TraversalStats::default();
        out.raster = raster::RasterStats::default();
        self.in_psc.clear();
        self.in_psc.resize(scene.objects().len(), false);
        out.fragments.clear();
        out.slices.clear();
        out.fragment_ms = 0.0;
        for slot in &mut self.slots[..views.len()] {
            let slot = slot_mut(slot);
            let r = &slot.result;
            add_stats(&mut out.stats, &r.stats);
            out.raster.add(&slot.raster);
            if fragment_source.is_some() {
                out.fragments.pixels += slot.fragments.pixels[0];
                out.slices.pixels += slot.fragments.pixels[1];
                out.fragment_ms += slot.fragment_ms;
            }
            for id in &r.visible {
                if !self.in_psc[id.index()] {
                    self.in_psc[id.index()] = true;
                    out.psc.push(*id);
                }
            }
        }
        out.psc.sort_unstable();
        if fragment_source.is_some() {
            let t = std::time::Instant::now();
            let slots = &mut self.slots[..views.len()];
            let lists: Vec<&ViewIntervals> =
                slots.iter_mut().map(|s| &slot_mut(s).fragments).collect();
            out.fragments.gather(lists.iter().map(|l| &l.axes[..]));
            out.slices.gather(lists.iter().map(|l| &l.slices[..]));
            out.fragment_ms += t.elapsed().as_secs_f64() * 1e3;
        }
        Ok(())
    }
}

/// What every light view of one light's pass shares.
struct ViewsInput<'a> {
    objects: Objects<'a>,
    light: &'a Light,
    /// Where the views' cones start: the light's position, or for a
    /// directional light the scene's centre.
    origin: DVec3,
    /// The diameter of the scene's bounds.
    diameter: f64,
    /// The casting triangles of an object drawn as an occluder.
    casting: &'a (dyn Fn(ObjectId) -> Arc<[[u32; 3]]> + Sync),
    options: &'a LightPassOptions,
    /// Fragment receivers: what each view reads its casters' intervals with.
    fragments: Option<ViewFragments<'a>>,
    /// The light's spare receiver target (whichever view gets it first).
    spare: &'a Mutex<Option<ReceiverTarget>>,
}

impl ViewSlot {
    /// Culls one light view: marks its `receivers`, then finds the casters
    /// in front of them, in `host` when given, else in the slot's own target.
    fn run(
        &mut self,
        set: &mut TargetPair,
        input: &ViewsInput<'_>,
        view: &LightView,
        receivers: Marks<'_>,
        host: Option<Box<dyn OcclusionBackend + Send>>,
    ) -> Result<()> {
        let ViewsInput {
            objects,
            light,
            origin,
            diameter,
            casting,
            options,
            ref fragments,
            spare,
        } = *input;
        let m = view.clip_from_world;
        self.depth_valid = false;
        self.fragments.clear();
        self.fragment_ms = 0.0;
        let clip_from_origin = (m * DMat4::from_translation(origin)).as_mat4();
        let size = (view.resolution, view.resolution);
        let (mut target, mut marks) = set.take(size)?;
        target.set_instruction_set(options.instruction_set);
        let Some(marks_mut) = Arc::get_mut(&mut marks) else {
            unreachable!("a fresh or unshared receiver target")
        };
        marks_mut.set_track_nearest(fragments.is_some());
        marks_mut.clear();
        let (eps, draw_coverage) = match options.sampling {
            Sampling::Conservative => (
                raster::RECEIVER_EPS_PX,
                Coverage::Inner(DepthPick::Farthest),
            ),
            Sampling::Point => (0.0, Coverage::Standard),
        };
        // (A view that finds the spare taken marks on its own thread.)
        let mut spare = spare.try_lock().ok();
        receivers.mark(marks_mut, clip_from_origin, eps, spare.as_deref_mut());
        drop(spare);
        // A view without receivers finds no caster: a caster's shadow on a
        // receiver point r crosses the segment from r to the light, which
        // lies in the view holding r (views are cones from the light, fitted
        // to B, which holds the segment) — r's own view finds it.
        let Some(rows) = marks_mut.marked_rows() else {
            set.target = Some(target);
            set.marks = Some(marks);
            self.result.clear();
            self.raster = raster::RasterStats::default();
            return Ok(());
        };
        let mut target = Some(target);
        let mut host = host;
        let mut bundled = None;
        let backend: &mut dyn OcclusionBackend = match &mut host {
            Some(b) => b.as_mut(),
            None => {
                // Depth matters only where queries can pass: the receivers'
                // rows, and in them their tiles (all of the rows when the
                // depth is kept as the hybrid's maps: it reads around each
                // receiver point).
                let mut t = target.take().expect("the view's target");
                t.set_draw_rows(Some(rows));
                t.set_draw_tiles((!options.keep_depth).then_some(&*marks))?;
                let queries = std::mem::take(&mut self.queries);
                bundled.insert(SyncBackend::reusing(t, queries))
            }
        };
        backend.set_receivers(Some(marks.clone()))?;
        let clip = |w: &DMat4| (m * *w).as_mat4();
        let apex = match light.position() {
            Some(l) => l,
            // Far toward the light: distances then order nodes along it.
            None => origin + light.toward_light(origin).normalize_or_zero() * (2.0 * diameter),
        };
        let setup = ViewSetup {
            clip_from_local: &clip,
            origin,
            clip_from_origin,
            planes: clip_planes(&m),
            apex,
            draw_coverage,
            query: QueryOptions {
                coverage: options.sampling.query_coverage(),
                // A view asks whether more than `threshold` samples pass: the
                // count stops there (at the first sample for 0).
                mode: QueryMode::more_than(options.threshold),
            },
            threshold: options.threshold,
            triangles: Some(casting),
            occluder: ViewSetup::light_occluder,
            back_faces: None,
            // (Not for kept depths: the hybrid's shadow maps are the
            // casters' own triangles.)
            convex: match options.keep_depth {
                false => ConvexOccluders::Own {
                    proxies: options.proxies,
                },
                true => ConvexOccluders::Off,
            },
            host_occluders: options.proxies && !options.keep_depth,
            preloaded: false,
        };
        let r = self
            .culler
            .cull_into(objects, &setup, options.culling, backend, &mut self.result);
        backend.set_receivers(None)?;
        if let (Some(f), true) = (fragments, r.is_ok()) {
            let t = std::time::Instant::now();
            f.read(
                view,
                &marks,
                &self.result.visible,
                &mut self.fragments,
                &mut self.ranges,
            );
            self.fragment_ms = t.elapsed().as_secs_f64() * 1e3;
        }
        set.target = match (bundled, target) {
            (Some(b), _) => {
                let (mut t, queries) = b.into_parts();
                self.queries = queries;
                self.raster = t.take_stats();
                if options.keep_depth && r.is_ok() {
                    // The set takes the target this view kept last time
                    // (same size after the first frame: no allocation).
                    self.depth_valid = true;
                    self.depth.replace(t)
                } else {
                    Some(t)
                }
            }
            (None, t) => {
                self.raster = raster::RasterStats::default();
                t
            }
        };
        set.marks = Some(marks);
        r
    }
}

/// A view's slot, with exclusive access (a poisoned lock only means a view
/// panicked; its state is still a valid culler).
fn slot_mut(s: &mut Mutex<ViewSlot>) -> &mut ViewSlot {
    s.get_mut().unwrap_or_else(PoisonError::into_inner)
}

fn add_stats(a: &mut TraversalStats, b: &TraversalStats) {
    a.nodes_visited += b.nodes_visited;
    a.queries += b.queries;
    a.waits += b.waits;
    a.wait_ms += b.wait_ms;
    a.objects_rendered += b.objects_rendered;
    a.triangles_rendered += b.triangles_rendered;
    a.objects_visible += b.objects_visible;
}
