//! The eye pass [Steiner §2.5.1]: every object (or, with culling, the
//! objects a CHC traversal finds visible: the potentially shadowed receivers,
//! PSR [Steiner §4.3]) rasterized into a depth and primitive-id target with
//! hierarchical z, and the visible surface points the light pass marks as
//! receivers.

use crate::mask::unlit_by_facing;
use crate::reference::PrimitiveId;
use crate::surface::{RayPlane, RunRows};
use crate::Result;
use glam::{DVec2, Vec4};
use raster::{Coverage, DepthTarget, DrawItem, TileSize};
use scene::{Camera, Light, ObjectId, Scene};

/// Per-mesh vertex data in the rasterizer's form (`w = 1`), built once per scene.
#[derive(Debug)]
pub struct MeshCache {
    positions: Vec<Vec<Vec4>>,
    /// The scene's mesh version each copy was made from.
    versions: Vec<u64>,
}

impl MeshCache {
    /// Converts every mesh of `scene`.
    pub fn new(scene: &Scene) -> Self {
        let mut cache = MeshCache {
            positions: Vec::new(),
            versions: Vec::new(),
        };
        cache.sync(scene);
        cache
    }

    /// Catches up with meshes added to `scene` since, and with meshes
    /// replaced (removed meshes keep their slot with no vertices).
    pub(crate) fn sync(&mut self, scene: &Scene) {
        let meshes = scene.graph().meshes();
        self.positions.truncate(meshes.len());
        self.versions.truncate(meshes.len());
        for (i, m) in meshes.iter().enumerate() {
            let version = scene.mesh_version(scene::MeshId::from_slot(i as u32));
            if self.versions.get(i) == Some(&version) {
                continue;
            }
            let p = m.positions().iter().map(|p| p.extend(1.0));
            if i < self.positions.len() {
                self.positions[i].clear();
                self.positions[i].extend(p);
                self.versions[i] = version;
            } else {
                self.positions.push(p.collect());
                self.versions.push(version);
            }
        }
    }
}

/// Draws the visible objects among `ids` into `target` (standard coverage,
/// skipping the faces [`visibility::eye_cull`] names, as the culled
/// traversal's draws do). One batch: bands of tile rows in parallel.
fn draw_objects(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    (target, scratch): (&mut DepthTarget, &mut EyeScratch),
    ids: impl Iterator<Item = ObjectId>,
) -> Result<()> {
    target.set_threads(rayon::current_num_threads());
    let items = eye_items(scene, meshes, camera, ids, visibility::eye_cull, scratch);
    let r = match items.is_empty() {
        true => Ok(()),
        false => target.draw_batch(&items, Coverage::Standard),
    };
    scratch.keep(items);
    Ok(r?)
}

/// The lists [`eye_items`] builds, kept from frame to frame so that the
/// eye passes that draw objects by list (without culling, the coarse pass,
/// the deferred non-occluders) allocate nothing once they have grown.
#[derive(Debug, Default)]
pub(crate) struct EyeScratch {
    /// (distance², position in the input, slot).
    order: Vec<(f64, usize, usize)>,
    /// An empty list whose allocation the next frame's draws reuse.
    items: Vec<DrawItem<'static>>,
}

impl EyeScratch {
    /// Takes back `items`' allocation.
    fn keep(&mut self, items: Vec<DrawItem<'_>>) {
        self.items = recycle(items);
    }
}

/// `v` emptied, as a list of another lifetime: the same allocation (the
/// standard library collects a mapped `into_iter` in place when the item
/// layouts agree, and they do: only the lifetime differs).
fn recycle<'b>(mut v: Vec<DrawItem<'_>>) -> Vec<DrawItem<'b>> {
    v.clear();
    v.into_iter()
        .map(|_| -> DrawItem<'b> { unreachable!("the list is empty") })
        .collect()
}

/// The draws of the visible objects among `ids`, each culling what `cull`
/// says, front to back by the distance from the eye to each object's bounds
/// centre, so hierarchical z rejects most hidden triangles; the depth and ids
/// do not depend on the order (nearest depth, then smallest id, wins).
fn eye_items<'a>(
    scene: &'a Scene,
    meshes: &'a MeshCache,
    camera: &Camera,
    ids: impl Iterator<Item = ObjectId>,
    cull: impl Fn(&Camera, &scene::Object, &scene::Mesh) -> raster::CullMode,
    scratch: &mut EyeScratch,
) -> Vec<DrawItem<'a>> {
    let objects = scene.objects();
    let order = &mut scratch.order;
    order.clear();
    order.extend(
        ids.map(|id| id.slot() as usize)
            .filter(|&i| objects[i].flags.visible)
            .enumerate()
            .map(|(k, i)| {
                let d = objects[i].world_bounds.center();
                (d.distance_squared(camera.position), k, i)
            }),
    );
    // A stable order, sorted in place (a stable sort's merge buffer would
    // allocate): equal distances keep the input order.
    order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mesh = |o: &scene::Object| &scene.graph().meshes()[o.mesh.index()];
    let mut items = recycle(std::mem::take(&mut scratch.items));
    items.extend(
        order
            .iter()
            .map(|&(_, _, i)| (i, &objects[i]))
            .map(|(i, o)| DrawItem {
                clip_from_local: scene::transform::clip_from_local(camera, &o.world_from_local),
                positions: &meshes.positions[o.mesh.index()],
                triangles: mesh(o).triangles(),
                object: i as u32,
                cull: cull(camera, o, mesh(o)),
            }),
    );
    items
}

/// The eye pass's result: depth with hierarchical z, and per pixel (row 0 at the
/// top) the visible primitive, in the rasterizer's tile-major target (read in
/// place: [`EyePass::primitive`], [`EyePass::surface`]).
#[derive(Debug)]
pub struct EyePass {
    /// Depth and primitive-id target.
    pub target: DepthTarget,
    /// The draw lists, kept for the next frame's pass.
    pub(crate) scratch: EyeScratch,
}

impl EyePass {
    /// `previous` when it is `width × height`, else an empty pass of that
    /// size, with the target's kernels capped at `isa`: what the eye passes
    /// reuse, so the cap holds from the first frame.
    ///
    /// # Errors
    /// [`crate::Error::Raster`] for a target larger than the rasterizer allows.
    pub(crate) fn reusable(
        previous: Option<EyePass>,
        (width, height): (u32, u32),
        isa: raster::InstructionSet,
    ) -> Result<EyePass> {
        Self::reusable_with(previous, (width, height), isa, true)
    }

    /// [`EyePass::reusable`], with a primitive-id target or (a coarse
    /// culling pass, whose ids nobody reads) without.
    pub(crate) fn reusable_with(
        previous: Option<EyePass>,
        (width, height): (u32, u32),
        isa: raster::InstructionSet,
        ids: bool,
    ) -> Result<EyePass> {
        let same = |t: &DepthTarget| (t.width(), t.height(), t.has_ids()) == (width, height, ids);
        let mut pass = match previous {
            Some(p) if same(&p.target) => p,
            _ => EyePass {
                target: DepthTarget::new(width, height, TileSize::T8, ids)?,
                scratch: EyeScratch::default(),
            },
        };
        pass.target.set_instruction_set(isa);
        Ok(pass)
    }

    /// The visible surface as the mask assembly and the reference take it:
    /// primitive ids and depth, read from the target in place.
    pub fn surface(&self) -> crate::reference::EyeSurface<'_> {
        crate::reference::EyeSurface::from_target(&self.target)
    }

    /// The visible `(object, triangle)` at pixel `(x, y)`, `None` for
    /// background.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the target.
    pub fn primitive(&self, x: u32, y: u32) -> Option<PrimitiveId> {
        self.surface().primitive(x, y)
    }

    /// Every pixel's visible primitive, row-major (row 0 at the top): a copy,
    /// for inspection.
    pub fn primitives(&self) -> Vec<Option<PrimitiveId>> {
        let (w, h) = (self.target.width(), self.target.height());
        let mut out = Vec::with_capacity(w as usize * h as usize);
        let surface = self.surface();
        for y in 0..h {
            surface.for_each_in_row(y, |_, p| out.push(p));
        }
        out
    }
}

/// Rasterizes every object (standard coverage, skipping the faces
/// [`visibility::eye_cull`] names) into a fresh `width × height` depth and
/// primitive-id target.
///
/// # Errors
/// [`crate::Error::Raster`] for a target larger than the rasterizer allows.
pub fn eye_pass(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    width: u32,
    height: u32,
) -> Result<EyePass> {
    eye_pass_reusing(scene, meshes, camera, width, height, None)
}

/// [`eye_pass`], reusing `previous`'s buffers when it has the same size (a
/// frame's fresh multi-megabyte buffers otherwise cost page faults every frame).
///
/// # Errors
/// As [`eye_pass`].
pub fn eye_pass_reusing(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    width: u32,
    height: u32,
    previous: Option<EyePass>,
) -> Result<EyePass> {
    eye_pass_of(scene, meshes, camera, (width, height), previous, None)
}

/// [`eye_pass_reusing`] drawing only `subset` when given (the objects a host
/// backend's culled traversal rendered: the same depth and ids, since the
/// culled objects have no visible pixel).
pub(crate) fn eye_pass_of(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    (width, height): (u32, u32),
    previous: Option<EyePass>,
    subset: Option<&[ObjectId]>,
) -> Result<EyePass> {
    let mut pass = match previous {
        Some(mut p) if (p.target.width(), p.target.height()) == (width, height) => {
            p.target.clear();
            p
        }
        p => EyePass {
            target: DepthTarget::new(width, height, TileSize::T8, true)?,
            scratch: p.map(|p| p.scratch).unwrap_or_default(),
        },
    };
    let to = (&mut pass.target, &mut pass.scratch);
    match subset {
        Some(ids) => draw_objects(scene, meshes, camera, to, ids.iter().copied())?,
        None => draw_objects(
            scene,
            meshes,
            camera,
            to,
            (0..scene.objects().len() as u32).map(ObjectId::from_slot),
        )?,
    }
    Ok(pass)
}

/// The coarse culling pass of the objects a host backend's coarse
/// traversal rendered (`subset`): their occluders drawn as
/// [`occluder_coverage`] says into `pass` (cleared first), the bound the
/// coarse receivers read.
pub(crate) fn coarse_pass_of(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    mut pass: EyePass,
    (subset, sampling): (&[ObjectId], visibility::Sampling),
) -> Result<EyePass> {
    pass.target.clear();
    pass.target.set_threads(rayon::current_num_threads());
    let occluders = subset
        .iter()
        .copied()
        .filter(|id| visibility::ViewSetup::eye_occluder(&scene.object(*id).flags));
    let items = eye_items(
        scene,
        meshes,
        camera,
        occluders,
        visibility::eye_cull,
        &mut pass.scratch,
    );
    let r = match items.is_empty() {
        true => Ok(()),
        false => pass
            .target
            .draw_batch(&items, occluder_coverage(true, sampling)),
    };
    pass.scratch.keep(items);
    r?;
    Ok(pass)
}

/// Per-run state of the culled eye pass (PSR, [Steiner §4.3]): the object
/// hierarchy, the meshes in the backend's form, and the eye view's
/// persistent CHC state.
///
/// The bundled backend's traversal runs as two, side by side: one over the
/// left tile columns of the view and one over the right, each with its own
/// CHC state and target that hides the other's columns (see
/// [`eye_pass_culled`]). A host's backend traverses the whole view with the
/// first state.
#[derive(Debug)]
pub struct EyeCulling {
    hierarchy: visibility::Hierarchy,
    meshes: visibility::MeshData,
    culler: visibility::ViewCuller,
    /// The last traversal's result (its lists reused): for the split
    /// traversal, the two parts' joined.
    pub(crate) result: visibility::CullResult,
    /// The bundled backend's query results, kept between frames.
    queries: raster::QueryBuffers,
    /// The right half's traversal.
    right: SecondHalf,
    /// The last split traversal's counters per half, left then right
    /// (`None` after a host's traversal): `culling: auto` models the
    /// culled eye by the slower half ([`super::auto::split_eye_cost`]).
    pub(crate) halves: Option<[(visibility::TraversalStats, raster::RasterStats); 2]>,
}

/// The right half of the split eye traversal: its CHC state, result,
/// query results and target, kept between frames.
#[derive(Debug, Default)]
struct SecondHalf {
    culler: visibility::ViewCuller,
    result: visibility::CullResult,
    queries: raster::QueryBuffers,
    target: Option<DepthTarget>,
}

impl EyeCulling {
    /// The state for `scene` (no history yet).
    pub fn new(scene: &Scene) -> Self {
        EyeCulling {
            hierarchy: visibility::Hierarchy::from_scene(scene),
            meshes: visibility::MeshData::from_scene(scene),
            culler: visibility::ViewCuller::new(),
            result: visibility::CullResult::default(),
            queries: raster::QueryBuffers::default(),
            right: SecondHalf::default(),
            halves: None,
        }
    }
}

impl EyeCulling {
    /// Forgets the eye view's CHC history (the hierarchy stays).
    pub(crate) fn reset(&mut self) {
        self.culler.reset();
        self.right.culler.reset();
    }

    /// Numbers the next traversal ([`visibility::ViewCuller::set_frame`]).
    pub(crate) fn set_frame(&mut self, frame: u32) {
        self.culler.set_frame(frame);
        self.right.culler.set_frame(frame);
    }

    /// Rebuilds the hierarchy and the meshes from `scene` (after its BVH was
    /// rebuilt or its meshes changed) and carries the eye view's CHC state
    /// over ([`visibility::ViewCuller::remap`]); returns the old hierarchy
    /// for the light views' remap.
    pub(crate) fn rebuild(&mut self, scene: &Scene) -> visibility::Hierarchy {
        let new = visibility::Hierarchy::from_scene(scene);
        let old = std::mem::replace(&mut self.hierarchy, new);
        self.culler.remap(&old, &self.hierarchy);
        self.right.culler.remap(&old, &self.hierarchy);
        old
    }

    /// Catches up with added and removed meshes.
    pub(crate) fn sync_meshes(&mut self, scene: &Scene) {
        self.meshes.sync(scene);
    }

    /// Copies the refit bounds of `scene`'s BVH (same topology).
    pub(crate) fn refit(&mut self, scene: &Scene) {
        self.hierarchy.refit(scene);
    }

    /// The object hierarchy.
    pub(crate) fn hierarchy(&self) -> &visibility::Hierarchy {
        &self.hierarchy
    }

    /// The hierarchy and meshes the eye and light passes share.
    pub(crate) fn parts(&self) -> (&visibility::Hierarchy, &visibility::MeshData) {
        (&self.hierarchy, &self.meshes)
    }
}

/// The eye's visible surface points (world, f64) that the light pass marks
/// as receivers: per eye row, the pixel-centre rays met with the visible
/// triangles' planes (as the mask assembly computes them), on receiving
/// objects only. A run of pixels on one triangle's plane (whose rays meet
/// it) lies on one line, in order; `sampling` decides how much of it is
/// kept:
/// - conservative: the run's first and last points, the last joined to the
///   first — the ends of the segment the light pass marks, which gives each
///   light pixel the depths of the part of the run there, so no point per
///   pixel is held;
/// - point-sampled (aggressive): every point, each its own mark.
///
/// A ray parallel to its plane gives the eye position, alone.
pub fn visible_points(
    scene: &Scene,
    camera: &Camera,
    eye: &EyePass,
    sampling: visibility::Sampling,
) -> visibility::ReceiverPoints {
    let mut bands = Vec::new();
    let skips = SkipLights {
        lights: &[],
        two_sided: false,
    };
    visible_points_into(
        scene,
        camera,
        eye,
        sampling,
        false,
        skips,
        (&mut bands, &mut Vec::new()),
    );
    let mut out = visibility::ReceiverPoints::default();
    for band in bands {
        out.points.extend(band.points);
        out.joined.extend(band.joined);
        out.skip.extend(band.skip);
    }
    out
}

/// The lights that may leave out receiver points
/// ([`visibility::ReceiverPoints::skip`]): light `k` (bit `k`) those of
/// every triangle its facing leaves unlit ([`crate::mask::unlit_by_facing`],
/// the mask's own rule, with `two_sided`).
#[derive(Clone, Copy)]
pub(crate) struct SkipLights<'a> {
    /// Per bit, its light.
    pub lights: &'a [Light],
    pub two_sided: bool,
}

/// The run buffers of [`visible_points_into`]: per visible triangle its
/// plane and skip mask.
pub(crate) type PointRuns = RunRows<Option<(RayPlane, u32)>>;

/// Rows per band of [`visible_points_into`]'s parallel work.
const BAND_ROWS: usize = 16;

/// [`visible_points`] in bands of [`BAND_ROWS`] rows, built in parallel
/// into `bands` (their buffers reused from frame to frame: no allocation
/// once they have grown): the parts the light pass takes.
///
/// With `stored`, each run's kept pixels also give, as a second line after
/// the run's, the points on their rays at the eye target's stored depth:
/// the surface as the stencil tests it, which at grazing angles lies off
/// the triangle's plane by more than the segments' margins (the ground
/// 350 m away at 1.7 m eye height: a metre along the ray). Fragment
/// receivers mark both, so that a segment holds the stencil's surface
/// point as well as the exact one.
pub(crate) fn visible_points_into(
    scene: &Scene,
    camera: &Camera,
    eye: &EyePass,
    sampling: visibility::Sampling,
    stored: bool,
    skips: SkipLights<'_>,
    (bands, runs): (&mut Vec<visibility::ReceiverPoints>, &mut Vec<PointRuns>),
) {
    use rayon::prelude::*;
    // Conservative: one piece per run (a stride no run reaches). Pieces of
    // 8 steps mark the same pixels at depths no tighter, and on
    // city_16384 street at 1280×1024 cost 176k segments against 27k.
    let stride = match sampling {
        visibility::Sampling::Conservative => usize::MAX,
        visibility::Sampling::Point => 1,
    };
    let (w, h) = (eye.target.width() as usize, eye.target.height() as usize);
    let rays = camera.rays(w as u32, h as u32);
    let e = camera.position;
    let surface = eye.surface();
    let clip = camera.clip_from_eye_relative();
    // The eye-relative point on ray `d` at stored depth `z`: `clip·(t·d, 1)`
    // has z/w = z where t = (b_z − z·b_w) / (z·a_w − a_z), a = clip·(d, 0),
    // b = clip·(0, 0, 0, 1).
    let at_depth = |d: glam::DVec3, z: f32| {
        let (a, b, z) = (clip * d.extend(0.0), clip.col(3), f64::from(z));
        let t = (b.z - z * b.w) / (z * a.w - a.z);
        (t.is_finite() && t > 0.0).then(|| e + d * t)
    };
    bands.resize_with(h.div_ceil(BAND_ROWS), Default::default);
    runs.resize_with(bands.len(), Default::default);
    // Per visible triangle: its plane and the lights that may leave its
    // points out, `None` for surfaces that cannot be shadowed (no
    // receivers).
    let plane_of = |prim: PrimitiveId| {
        if !scene.object(prim.0).flags.receives {
            return None;
        }
        let tri = scene.world_triangle(prim.0, prim.1 as usize);
        let mut skip = 0u32;
        for (k, light) in skips.lights.iter().enumerate() {
            if unlit_by_facing(&tri, e, light, skips.two_sided) {
                skip |= 1 << k;
            }
        }
        Some((RayPlane::new(&tri, e), skip))
    };
    bands
        .par_iter_mut()
        .zip(runs.par_iter_mut())
        .enumerate()
        .for_each(|(b, (band, runs))| {
            band.points.clear();
            band.joined.clear();
            band.skip.clear();
            let rows = (b * BAND_ROWS) as u32..((b + 1) * BAND_ROWS).min(h) as u32;
            // A run's stored-depth points, each with whether it is joined
            // to the one before.
            let mut stored_points: Vec<(glam::DVec3, bool)> = Vec::new();
            surface.for_each_run_in_rows(rows, runs, plane_of, |y, x0, x1, _, plane| {
                let Some((plane, skip)) = plane else { return };
                let (base, step) = rays.row(f64::from(y) + 0.5);
                let dir = |x: u32| base + step * (f64::from(x) + 0.5);
                let n = plane.normal;
                // The ray's dot product with the plane normal is affine in x.
                // Its computed value errs by under 1e-14 of `scale` (the sum
                // of the magnitudes it is made of, at any pixel of the run),
                // so with both ends of one sign and beyond 1e-9 · scale, no
                // pixel between them computes to 0 (a parallel ray). Tiny
                // scales (underflow) and runs of one or two pixels ask per
                // pixel instead.
                let never_parallel = x1 - x0 > 2 && {
                    let scale = n.abs().element_sum()
                        * (base.abs().element_sum()
                            + step.abs().element_sum() * (f64::from(x1) + 0.5));
                    let tol = 1e-9 * scale;
                    let (a, b) = (n.dot(dir(x0)), n.dot(dir(x1 - 1)));
                    tol >= f64::MIN_POSITIVE
                        && a.abs() > tol
                        && b.abs() > tol
                        && (a > 0.0) == (b > 0.0)
                };
                let parallel = |x: u32| plane.hit(dir(x)).is_none();
                // Whether the last point emitted has a stored-depth point.
                let mut chained = false;
                run_points(x0..x1, stride, never_parallel, parallel, |px, joined| {
                    let p = match px {
                        Some(x) => {
                            let d = dir(x);
                            if stored {
                                let q = surface.depth(x, y).and_then(|z| at_depth(d, z));
                                if let Some(q) = q {
                                    stored_points.push((q, joined && chained));
                                }
                                chained = q.is_some();
                            }
                            e + d * plane.hit(d).unwrap_or(0.0)
                        }
                        None => {
                            chained = false;
                            e
                        }
                    };
                    band.points.push(p);
                    band.joined.push(joined);
                    band.skip.push(skip);
                });
                for (q, joined) in stored_points.drain(..) {
                    band.points.push(q);
                    band.joined.push(joined);
                    band.skip.push(skip);
                }
            });
        });
}

/// The points one run of pixels `x0..x1` on one plane gives the light pass,
/// in order: `emit(Some(x), joined)` for pixel `x`'s point and
/// `emit(None, false)` for the lone point at the eye of a pixel whose ray is
/// parallel to the plane (`parallel(x)`), which ends the run: the pixels
/// after it start a new one. Each run between such pixels keeps its
/// [`piece_ends`]. `never_parallel` (the caller's proof that no pixel is)
/// skips asking `parallel`. Always inlined: as a call, the receiver points
/// of city street took 12–22 % longer (criterion, `surface` bench).
#[inline(always)]
fn run_points(
    run: std::ops::Range<u32>,
    stride: usize,
    never_parallel: bool,
    parallel: impl Fn(u32) -> bool,
    mut emit: impl FnMut(Option<u32>, bool),
) {
    let mut start = run.start;
    if !never_parallel {
        for x in run.clone() {
            if parallel(x) {
                piece_ends(start, x, stride).for_each(|(x, j)| emit(Some(x), j));
                emit(None, false);
                start = x + 1;
            }
        }
    }
    piece_ends(start, run.end, stride).for_each(|(x, j)| emit(Some(x), j));
}

/// The pixels of run `x0..x1` whose points are kept, each with whether it
/// is joined to the one before: the first (not joined), every `stride`-th
/// after it and the last — the ends of the pieces of `stride` steps the
/// light pass marks. Empty for an empty run.
fn piece_ends(x0: u32, x1: u32, stride: usize) -> impl Iterator<Item = (u32, bool)> {
    let stride = stride.max(1);
    let tail = x1
        .checked_sub(1)
        .filter(|&l| l >= x0 && !((l - x0) as usize).is_multiple_of(stride))
        .map(|l| (l, true));
    (x0..x1)
        .step_by(stride)
        .map(move |x| (x, x != x0))
        .chain(tail)
}

/// How the culled eye pass traverses: the algorithm, the query threshold
/// (0: conservative) and the sampling of queries and occluders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EyeTraversal {
    /// The traversal.
    pub culling: visibility::Culling,
    /// Query threshold (0: conservative).
    pub threshold: u32,
    /// Conservative or point-sampled.
    pub sampling: visibility::Sampling,
    /// A coarse pass, for culling only: conservative occluders are drawn
    /// inner-conservative at their farthest depth ([`occluder_coverage`]),
    /// and visible objects that may not occlude are not drawn at all, so
    /// the depth is a bound no visible sample of a pixel lies behind, not
    /// the visible surface.
    pub coarse: bool,
    /// A coarse pass draws objects' host-given occluders
    /// ([`scene::Object::occluder`], `occluders: proxy`) in place of their
    /// meshes.
    pub host_occluders: bool,
}

/// The coverage of the eye's occluder draws: standard at the output
/// resolution; for a `coarse` conservative pass inner-conservative at the
/// farthest depth: a coarse pixel is covered only where an occluder covers
/// it wholly, and no visible output sample in it is behind that depth.
pub fn occluder_coverage(coarse: bool, sampling: visibility::Sampling) -> raster::Coverage {
    match (coarse, sampling) {
        (true, visibility::Sampling::Conservative) => {
            raster::Coverage::Inner(raster::DepthPick::Farthest)
        }
        _ => raster::Coverage::Standard,
    }
}

/// The eye pass with occlusion culling: only the objects `culling` finds
/// visible (the potentially shadowed receivers, PSR) are drawn, one by one
/// through an occlusion backend, with the same transform path and coverage as
/// [`eye_pass`]. With a conservative traversal (threshold 0) the depth and
/// primitive ids equal [`eye_pass`]'s (point `sampling` is aggressive).
/// Returns the pass and the traversal's result (the PSR and its counters).
///
/// The traversal runs as two side by side: one over the left half of the
/// tile columns, one over the right, each with its own CHC state and
/// target, which hides the other half's columns from its draws and queries
/// ([`DepthTarget::set_hidden_part`]), and each culling to its half's
/// frustum ([`Camera::frustum_part`]). Every object visible at a pixel of a
/// half is drawn by that half's traversal, so the right target's tiles,
/// copied into the left's, give the same depth and ids. Columns, not rows:
/// a street view's horizon, where the far objects and most queries are,
/// runs across the middle rows, so halves of rows both queried it (on the
/// default job's street path over 48 frames, 751 queries a frame against
/// 590 for halves of columns and 551 unsplit). The PSR is the objects
/// either half drew; the counters are both halves' sums. The split does not
/// depend on the threads, so neither do the counters.
///
/// # Errors
/// As [`eye_pass`].
pub fn eye_pass_culled(
    scene: &Scene,
    meshes: &MeshCache,
    state: &mut EyeCulling,
    camera: &Camera,
    (width, height): (u32, u32),
    traversal: EyeTraversal,
    previous: Option<EyePass>,
) -> Result<(EyePass, visibility::CullResult)> {
    let eye = eye_pass_culled_into(
        scene,
        meshes,
        state,
        camera,
        (width, height),
        traversal,
        previous,
    )?;
    Ok((eye, state.result.clone()))
}

/// [`eye_pass_culled`] with the traversal's result left in `state.result`
/// (its lists, and the backend's, reused from frame to frame).
///
/// # Errors
/// As [`eye_pass`].
pub(crate) fn eye_pass_culled_into(
    scene: &Scene,
    meshes: &MeshCache,
    state: &mut EyeCulling,
    camera: &Camera,
    (width, height): (u32, u32),
    traversal: EyeTraversal,
    previous: Option<EyePass>,
) -> Result<EyePass> {
    let EyeTraversal {
        culling,
        threshold,
        sampling,
        coarse,
        host_occluders,
    } = traversal;
    let (mut left, mut scratch) = match previous {
        Some(p) if (p.target.width(), p.target.height()) == (width, height) => {
            (p.target, p.scratch)
        }
        p => (
            DepthTarget::new(width, height, TileSize::T8, true)?,
            p.map(|p| p.scratch).unwrap_or_default(),
        ),
    };
    let ids = left.has_ids();
    let mut right = match state.right.target.take() {
        Some(t) if (t.width(), t.height(), t.has_ids()) == (width, height, ids) => t,
        _ => DepthTarget::new(width, height, TileSize::T8, ids)?,
    };
    right.set_instruction_set(left.instruction_set());
    // Each half hides the other's tile columns, from the clear that starts
    // its traversal on (the tiles written before are cleared there).
    let ((tiles_x, tiles_y), mid) = (left.tile_counts(), left.tile_counts().0 / 2);
    left.set_hidden_part(mid..tiles_x, 0..tiles_y);
    right.set_hidden_part(0..mid, 0..tiles_y);
    // Each half culls to the frustum of its columns, widened by two pixels
    // into the other's: every pixel of its columns, whole, lies inside.
    let split = f64::from((mid * left.tile_pixels()).min(width));
    let ndc = |x: f64| (2.0 * x / f64::from(width) - 1.0).clamp(-1.0, 1.0);
    let halves = [
        (DVec2::NEG_ONE, DVec2::new(ndc(split + 2.0), 1.0)),
        (DVec2::new(ndc(split - 2.0), -1.0), DVec2::ONE),
    ];
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let objects = visibility::Objects::new(&state.hierarchy, scene, &state.meshes);
    let traverse = |culler: &mut visibility::ViewCuller,
                    (target, (min, max)): (DepthTarget, (DVec2, DVec2)),
                    queries: &mut raster::QueryBuffers,
                    result: &mut visibility::CullResult| {
        let mut backend = raster::SyncBackend::reusing(target, std::mem::take(queries));
        let mut view = visibility::ViewSetup::eye_sampled(camera, &clip, threshold, sampling);
        view.planes = camera.frustum_part(min, max).planes;
        view.draw_coverage = occluder_coverage(coarse, sampling);
        if coarse {
            view.convex = visibility::ConvexOccluders::Hulls;
            view.host_occluders = host_occluders;
        }
        let r = culler.cull_into(objects, &view, culling, &mut backend, result);
        let (target, q) = backend.into_parts();
        *queries = q;
        r.map(|()| target)
    };
    let EyeCulling {
        culler,
        result,
        queries,
        right: part,
        ..
    } = state;
    let (left, right) = rayon::join(
        || traverse(culler, (left, halves[0]), queries, result),
        || {
            let right = (right, halves[1]);
            traverse(&mut part.culler, right, &mut part.queries, &mut part.result)
        },
    );
    let (mut target, mut right) = (left?, right?);
    state.halves = Some([
        (result.stats, target.stats()),
        (part.result.stats, right.stats()),
    ]);
    target.set_hidden_part(0..0, 0..0);
    target.take_part_from(&mut right, mid..tiles_x, 0..tiles_y)?;
    part.target = Some(right);
    join_results(result, &part.result);
    if coarse {
        return Ok(EyePass { target, scratch });
    }
    // Visible objects that may not occlude were left out of the traversal's
    // draws: they join the visible surface now, hiding nothing they did not.
    let deferred = state.result.rendered.iter().copied().filter(|id| {
        let f = scene.object(*id).flags;
        f.visible && !f.occludes
    });
    draw_objects(scene, meshes, camera, (&mut target, &mut scratch), deferred)?;
    Ok(EyePass { target, scratch })
}

/// Joins the right half's traversal result into the left's: the objects
/// either part drew or found visible (ascending, each once), and the
/// counters of both (work: summed; `objects_visible`: the joined list's).
fn join_results(left: &mut visibility::CullResult, right: &visibility::CullResult) {
    for (list, more) in [
        (&mut left.rendered, &right.rendered),
        (&mut left.visible, &right.visible),
    ] {
        list.extend_from_slice(more);
        list.sort_unstable();
        list.dedup();
    }
    let (s, l) = (&mut left.stats, &right.stats);
    s.nodes_visited += l.nodes_visited;
    s.queries += l.queries;
    s.waits += l.waits;
    s.wait_ms += l.wait_ms;
    s.objects_rendered += l.objects_rendered;
    s.triangles_rendered += l.triangles_rendered;
    s.objects_visible = left.visible.len() as u64;
}

/// The culled eye traversal against the host's own depth of this frame
/// ([`super::HostDepth`], `depth` at `pass`'s size) loaded into `pass`'s
/// target: queries only, no draws (the host's depth holds every occluder),
/// one traversal over the whole view. The result is left in
/// `state.result`; the pass keeps the depth for the coarse receivers.
///
/// # Errors
/// Rasterizer errors (a depth of another size).
pub(crate) fn cull_on_host_depth(
    scene: &Scene,
    state: &mut EyeCulling,
    camera: &Camera,
    traversal: EyeTraversal,
    depth: &[f32],
    mut pass: EyePass,
) -> Result<EyePass> {
    pass.target.load_rows(depth)?;
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let mut view =
        visibility::ViewSetup::eye_sampled(camera, &clip, traversal.threshold, traversal.sampling);
    view.preloaded = true;
    let objects = visibility::Objects::new(&state.hierarchy, scene, &state.meshes);
    let queries = std::mem::take(&mut state.queries);
    let scratch = std::mem::take(&mut pass.scratch);
    let mut backend = raster::SyncBackend::reusing(pass.target, queries);
    state.halves = None;
    let r = state.culler.cull_into(
        objects,
        &view,
        traversal.culling,
        &mut backend,
        &mut state.result,
    );
    let (target, queries) = backend.into_parts();
    state.queries = queries;
    r?;
    Ok(EyePass { target, scratch })
}

/// The culled eye traversal through a host's `backend`: the same view and
/// culling as [`eye_pass_culled`], without the bundled target; the result is
/// left in `state.result`.
///
/// # Errors
/// Backend errors.
pub(crate) fn cull_with(
    scene: &Scene,
    state: &mut EyeCulling,
    camera: &Camera,
    options: &super::PipelineOptions,
    coarse: bool,
    backend: &mut dyn raster::OcclusionBackend,
) -> Result<()> {
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let mut view = visibility::ViewSetup::eye_sampled(
        camera,
        &clip,
        options.query_threshold,
        options.coverage.sampling(),
    );
    view.draw_coverage = occluder_coverage(coarse, options.coverage.sampling());
    if coarse {
        view.convex = visibility::ConvexOccluders::Hulls;
        view.host_occluders = options.occluders == super::OccludersSpec::Proxy;
    }
    let objects = visibility::Objects::new(&state.hierarchy, scene, &state.meshes);
    state.halves = None;
    Ok(state.culler.cull_into(
        objects,
        &view,
        options.culling(),
        backend,
        &mut state.result,
    )?)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The procedural city of 3 × 3 blocks and the first camera of its
    /// street path (4:3).
    pub(crate) fn small_street() -> (Scene, Camera) {
        use scene::procedural::city::{city, CityParams};
        let loaded = city(&CityParams {
            blocks_x: 3,
            blocks_z: 3,
            ..Default::default()
        })
        .unwrap();
        let camera = loaded.paths[0].1.at(0).unwrap().camera(4.0 / 3.0).unwrap();
        (Scene::new(loaded.graph).unwrap(), camera)
    }

    /// The culled eye pass of `camera` at 320×240 with `culling`
    /// (conservative, threshold 0), its result and its state.
    fn culled_at_320(
        scene: &Scene,
        camera: &Camera,
        culling: visibility::Culling,
    ) -> (EyePass, visibility::CullResult, EyeCulling) {
        let meshes = MeshCache::new(scene);
        let mut state = EyeCulling::new(scene);
        let traversal = EyeTraversal {
            culling,
            threshold: 0,
            sampling: visibility::Sampling::Conservative,
            coarse: false,
            host_occluders: false,
        };
        let size = (320, 240);
        let (eye, result) =
            eye_pass_culled(scene, &meshes, &mut state, camera, size, traversal, None).unwrap();
        (eye, result, state)
    }

    /// Down the procedural city's street, both eye paths skip the faces
    /// turned away of its solid buildings and give the same depth and ids;
    /// against every face drawn, that tests far fewer pixels and changes
    /// next to none (ties of rounding at silhouette edges).
    #[test]
    fn both_eye_paths_skip_the_hidden_faces_of_solid_objects() {
        let (scene, camera) = small_street();
        let solid = (scene.objects().iter())
            .filter(|o| scene.graph().meshes()[o.mesh.index()].solid().is_some())
            .count();
        assert!(2 * solid > scene.objects().len(), "{solid} solid objects");
        let meshes = MeshCache::new(&scene);
        let mut plain = eye_pass(&scene, &meshes, &camera, 320, 240).unwrap();
        let (culled, _, _) = culled_at_320(&scene, &camera, visibility::Culling::Exact);
        assert_eq!(plain.target.depth_rows(), culled.target.depth_rows());
        assert_eq!(plain.primitives(), culled.primitives());
        // Every face of every object, in the same order.
        let mut all = DepthTarget::new(320, 240, TileSize::T8, true).unwrap();
        let ids = (0..scene.objects().len()).map(|i| ObjectId::from_slot(i as u32));
        let mut scratch = EyeScratch::default();
        let none = |_: &Camera, _: &scene::Object, _: &scene::Mesh| raster::CullMode::None;
        let items = eye_items(&scene, &meshes, &camera, ids, none, &mut scratch);
        all.draw_batch(&items, Coverage::Standard).unwrap();
        let (s, s_all) = (plain.target.take_stats(), all.take_stats());
        assert!(
            s.triangles_culled > s_all.triangles_culled
                && 10 * s.pixels_tested < 9 * s_all.pixels_tested,
            "{s:?}\n{s_all:?}"
        );
        let (d, d_all) = (plain.target.depth_rows(), all.depth_rows());
        let changed = d.iter().zip(&d_all).filter(|(a, b)| a != b).count();
        assert!(changed * 200 < d.len(), "{changed} pixels changed");
    }

    /// The split traversal keeps each half's counters for `culling: auto`
    /// ([`super::super::auto::split_eye_cost`]): both halves worked, and
    /// together they are the joined traversal's counters and the target's
    /// (before the deferred draws of objects that do not occlude: none here).
    #[test]
    fn the_split_traversal_keeps_each_halfs_counters() {
        let (scene, camera) = small_street();
        let (eye, result, state) = culled_at_320(&scene, &camera, visibility::Culling::Chc);
        let [(lt, lr), (rt, rr)] = state.halves.expect("a split traversal's halves");
        assert!(
            lt.nodes_visited > 0 && rt.nodes_visited > 0,
            "{lt:?} {rt:?}"
        );
        assert!(
            lr.pixels_tested > 0 && rr.pixels_tested > 0,
            "{lr:?} {rr:?}"
        );
        let s = result.stats;
        assert_eq!(s.nodes_visited, lt.nodes_visited + rt.nodes_visited);
        assert_eq!(s.queries, lt.queries + rt.queries);
        let r = eye.target.stats();
        assert_eq!(r.triangles_in, lr.triangles_in + rr.triangles_in);
        assert_eq!(r.pixels_tested, lr.pixels_tested + rr.pixels_tested);
    }

    /// A run's points against the per-pixel rule they replace: each pixel's
    /// point is pushed in turn; a run keeps its first point (not joined),
    /// every `stride`-th after it and its last, each joined to the one
    /// before; a parallel pixel ends the run with a lone point at the eye.
    #[test]
    fn parallel_pixels_split_runs_as_the_per_pixel_rule_does() {
        fn per_pixel(n: u32, stride: u32, parallel: &[bool]) -> Vec<(Option<u32>, bool)> {
            let mut out = Vec::new();
            // (steps since the last kept point, the pending last point)
            let mut run: Option<(u32, Option<u32>)> = None;
            let end = |run: &mut Option<(u32, Option<u32>)>, out: &mut Vec<_>| {
                if let Some((_, Some(p))) = run.take() {
                    out.push((Some(p), true));
                }
            };
            for x in 0..n {
                if parallel[x as usize] {
                    end(&mut run, &mut out);
                    out.push((None, false));
                    continue;
                }
                run = match run {
                    None => {
                        out.push((Some(x), false));
                        Some((0, None))
                    }
                    Some((steps, _)) if steps + 1 == stride => {
                        out.push((Some(x), true));
                        Some((0, None))
                    }
                    Some((steps, _)) => Some((steps + 1, Some(x))),
                };
            }
            end(&mut run, &mut out);
            out
        }
        for stride in [1u32, 2, 3, 8] {
            for n in 0..14u32 {
                // Every set of parallel pixels of runs up to 9 pixels; masks
                // of longer runs by a fixed pattern.
                let masks: Vec<u32> = if n <= 9 {
                    (0..1 << n).collect()
                } else {
                    vec![0, 1, 1 << (n - 1), 0b1010_0100_1001 & ((1 << n) - 1)]
                };
                for m in masks {
                    let parallel: Vec<bool> = (0..n).map(|x| m >> x & 1 == 1).collect();
                    let mut got = Vec::new();
                    run_points(
                        0..n,
                        stride as usize,
                        false,
                        |x| parallel[x as usize],
                        |p, j| got.push((p, j)),
                    );
                    assert_eq!(got, per_pixel(n, stride, &parallel), "n {n} mask {m:b}");
                    if m == 0 {
                        let mut fast = Vec::new();
                        run_points(
                            0..n,
                            stride as usize,
                            true,
                            |_| true,
                            |p, j| fast.push((p, j)),
                        );
                        assert_eq!(fast, got);
                    }
                }
            }
        }
    }

    /// A run keeps its first point, every `stride`-th after it and its last,
    /// each joined to the one before: the ends of the pieces the light pass
    /// marks.
    #[test]
    fn runs_keep_their_piece_ends() {
        let t = true;
        let f = false;
        let ends = |x0, x1, stride| piece_ends(x0, x1, stride).collect::<Vec<_>>();
        assert_eq!(ends(0, 12, 8), [(0, f), (8, t), (11, t)]);
        assert_eq!(ends(15, 24, 8), [(15, f), (23, t)]);
        assert_eq!(ends(13, 14, 8), [(13, f)]);
        assert_eq!(ends(24, 26, 8), [(24, f), (25, t)]);
        assert!(ends(5, 5, 8).is_empty());
        // Stride 1 (point sampling) keeps every point.
        assert_eq!(ends(3, 6, 1), [(3, f), (4, t), (5, t)]);
        // Against the definition, on every short run.
        for stride in 1..10usize {
            for x0 in 0..12u32 {
                for x1 in x0..x0 + 30 {
                    let want: Vec<(u32, bool)> = (x0..x1)
                        .filter(|&x| ((x - x0) as usize).is_multiple_of(stride) || x + 1 == x1)
                        .map(|x| (x, x != x0))
                        .collect();
                    assert_eq!(ends(x0, x1, stride), want, "{x0}..{x1} by {stride}");
                }
            }
        }
    }
}
