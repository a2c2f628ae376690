//! The eye pass [Steiner §2.5.1]: every object (or, with culling, the
//! objects a CHC traversal finds visible: the potentially shadowed receivers,
//! PSR [Steiner §4.3]) rasterized into a depth and primitive-id target with
//! hierarchical z, and the visible surface points the light pass marks as
//! receivers.

use crate::reference::PrimitiveId;
use crate::surface::RayPlane;
use crate::Result;
use glam::Vec4;
use raster::{Coverage, DepthTarget, DrawItem, TileSize};
use scene::{Camera, ObjectId, Scene};

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
            let version = scene.mesh_version(scene::MeshId(i as u32));
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

/// Draws the visible objects among `ids` into `target` (both faces,
/// standard coverage), front to back by the distance from the eye to each
/// object's bounds centre, so hierarchical z rejects most hidden triangles;
/// the depth and ids do not depend on the order (nearest depth, then smallest
/// id, wins). One batch: bands of tile rows in parallel.
fn draw_objects(
    scene: &Scene,
    meshes: &MeshCache,
    camera: &Camera,
    target: &mut DepthTarget,
    ids: impl Iterator<Item = ObjectId>,
) -> Result<()> {
    target.set_threads(rayon::current_num_threads());
    let objects = scene.objects();
    let mut order: Vec<(f64, usize)> = ids
        .map(|id| id.slot() as usize)
        .filter(|&i| objects[i].flags.visible)
        .map(|i| {
            let d = objects[i].world_bounds.center();
            (d.distance_squared(camera.position), i)
        })
        .collect();
    if order.is_empty() {
        return Ok(());
    }
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let items: Vec<DrawItem> = order
        .iter()
        .map(|&(_, i)| (i, &objects[i]))
        .map(|(i, o)| DrawItem {
            clip_from_local: scene::transform::clip_from_local(camera, &o.world_from_local),
            positions: &meshes.positions[o.mesh.0 as usize],
            triangles: scene.graph().meshes()[o.mesh.0 as usize].triangles(),
            object: i as u32,
        })
        .collect();
    target.draw_batch(&items, Coverage::Standard)?;
    Ok(())
}

/// The eye pass's result: depth with hierarchical z, and per pixel (row 0 at the
/// top) the visible primitive.
#[derive(Debug)]
pub struct EyePass {
    /// Depth and primitive-id target.
    pub target: DepthTarget,
    /// Per pixel the visible `(object, triangle)`, `None` for background.
    pub primitive: Vec<Option<PrimitiveId>>,
    /// Per pixel (row 0 at the top) the rasterized depth, reversed Z
    /// ([`raster::BACKGROUND`] where nothing was drawn).
    pub depth: Vec<f32>,
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
        let mut pass = match previous {
            Some(p) if (p.target.width(), p.target.height()) == (width, height) => p,
            _ => EyePass {
                target: DepthTarget::new(width, height, TileSize::T8, true)?,
                primitive: Vec::new(),
                depth: Vec::new(),
            },
        };
        pass.target.set_instruction_set(isa);
        Ok(pass)
    }

    /// The visible surface as the reference takes it: primitive ids and depth.
    pub fn surface(&self) -> crate::reference::EyeSurface<'_> {
        crate::reference::EyeSurface {
            primitive: &self.primitive,
            depth: Some(&self.depth),
        }
    }
}

/// Rasterizes every object (both faces, standard coverage) into a fresh
/// `width × height` depth and primitive-id target.
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
    let (mut target, primitive, depth) = match previous {
        Some(p) if (p.target.width(), p.target.height()) == (width, height) => {
            let mut t = p.target;
            t.clear();
            (t, p.primitive, p.depth)
        }
        _ => (
            DepthTarget::new(width, height, TileSize::T8, true)?,
            Vec::new(),
            Vec::new(),
        ),
    };
    match subset {
        Some(ids) => draw_objects(scene, meshes, camera, &mut target, ids.iter().copied())?,
        None => draw_objects(
            scene,
            meshes,
            camera,
            &mut target,
            (0..scene.objects().len() as u32).map(ObjectId),
        )?,
    }
    Ok(EyePass::from_target(target, primitive, depth))
}

impl EyePass {
    /// The eye pass of a rendered `target`, filling (and reusing) the
    /// row-major id and depth vectors.
    fn from_target(
        target: DepthTarget,
        mut primitive: Vec<Option<PrimitiveId>>,
        mut depth: Vec<f32>,
    ) -> EyePass {
        use rayon::prelude::*;
        let (width, height) = (target.width() as usize, target.height() as usize);
        primitive.resize(width * height, None);
        depth.resize(width * height, raster::BACKGROUND);
        primitive
            .par_chunks_mut(width)
            .zip(depth.par_chunks_mut(width))
            .enumerate()
            .for_each(|(y, (prims, depths))| {
                target.for_each_in_row(y as u32, |x, d, id| {
                    prims[x as usize] = id.map(|(o, t)| (ObjectId(o), t));
                    depths[x as usize] = d;
                });
            });
        EyePass {
            target,
            primitive,
            depth,
        }
    }
}

/// Per-run state of the culled eye pass (PSR, [Steiner §4.3]): the object
/// hierarchy, the meshes in the backend's form, and the eye view's
/// persistent CHC state.
#[derive(Debug)]
pub struct EyeCulling {
    hierarchy: visibility::Hierarchy,
    meshes: visibility::MeshData,
    culler: visibility::ViewCuller,
    /// The last traversal's result (its lists reused).
    pub(crate) result: visibility::CullResult,
    /// The bundled backend's query results, kept between frames.
    queries: raster::QueryBuffers,
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
        }
    }
}

impl EyeCulling {
    /// Forgets the eye view's CHC history (the hierarchy stays).
    pub(crate) fn reset(&mut self) {
        self.culler.reset();
    }

    /// Numbers the next traversal ([`visibility::ViewCuller::set_frame`]).
    pub(crate) fn set_frame(&mut self, frame: u32) {
        self.culler.set_frame(frame);
    }

    /// Rebuilds the hierarchy and the meshes from `scene` (after its BVH was
    /// rebuilt or its meshes changed) and carries the eye view's CHC state
    /// over ([`visibility::ViewCuller::remap`]); returns the old hierarchy
    /// for the light views' remap.
    pub(crate) fn rebuild(&mut self, scene: &Scene) -> visibility::Hierarchy {
        let new = visibility::Hierarchy::from_scene(scene);
        let old = std::mem::replace(&mut self.hierarchy, new);
        self.culler.remap(&old, &self.hierarchy);
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

/// The eye's visible surface points (world, f64), row-major, one per pixel:
/// the pixel-centre ray met with the visible triangle's plane (as the mask
/// assembly computes them), NaN on background pixels — the fragment-level
/// receivers of the light pass, which skips the NaN points. A point is
/// joined to its left neighbour when both lie on the same triangle's plane
/// (and the rays meet it): the points of a run lie on one line, in order.
pub fn visible_points(scene: &Scene, camera: &Camera, eye: &EyePass) -> visibility::ReceiverPoints {
    let mut out = visibility::ReceiverPoints::default();
    visible_points_into(scene, camera, eye, &mut out);
    out
}

/// [`visible_points`] into `out` (reused from frame to frame: no allocation).
pub fn visible_points_into(
    scene: &Scene,
    camera: &Camera,
    eye: &EyePass,
    out: &mut visibility::ReceiverPoints,
) {
    use rayon::prelude::*;
    let (w, h) = (eye.target.width(), eye.target.height());
    let rays = camera.rays(w, h);
    let e = camera.position;
    let n = (w * h) as usize;
    out.points.resize(n, glam::DVec3::NAN);
    out.joined.resize(n, false);
    out.points
        .par_chunks_mut(w as usize)
        .zip(out.joined.par_chunks_mut(w as usize))
        .zip(eye.primitive.par_chunks(w as usize))
        .enumerate()
        .for_each(|(y, ((row, joined), prims))| {
            // The plane of the row's last triangle: runs of pixels share one.
            let mut last: Option<((ObjectId, u32), Option<RayPlane>)> = None;
            let mut prev: Option<(ObjectId, u32)> = None;
            let (base, step) = rays.row(y as f64 + 0.5);
            for (x, ((p, j), prim)) in row.iter_mut().zip(joined.iter_mut()).zip(prims).enumerate()
            {
                let plane = match *prim {
                    None => None,
                    Some(prim) => match last {
                        Some((q, plane)) if q == prim => plane,
                        _ => {
                            // Surfaces that cannot be shadowed are no receivers.
                            let plane = scene.object(prim.0).flags.receives.then(|| {
                                RayPlane::new(&scene.world_triangle(prim.0, prim.1 as usize), e)
                            });
                            last = Some((prim, plane));
                            plane
                        }
                    },
                };
                let (Some(prim), Some(plane)) = (*prim, plane) else {
                    *p = glam::DVec3::NAN;
                    *j = false;
                    prev = None;
                    continue;
                };
                let dir = base + step * (x as f64 + 0.5);
                let t_hit = plane.hit(dir);
                let hit = t_hit.is_some();
                *p = e + dir * t_hit.unwrap_or(0.0);
                *j = hit && prev == Some(prim);
                prev = hit.then_some(prim);
            }
        });
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
}

/// The eye pass with occlusion culling: only the objects `culling` finds
/// visible (the potentially shadowed receivers, PSR) are drawn, one by one
/// through an occlusion backend, with the same transform path and coverage as
/// [`eye_pass`]. With a conservative traversal (threshold 0) the depth and
/// primitive ids equal [`eye_pass`]'s (point `sampling` is aggressive). Returns the pass and the traversal's
/// result (the PSR and its counters).
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
    } = traversal;
    let (target, primitive, depth) = match previous {
        Some(p) if (p.target.width(), p.target.height()) == (width, height) => {
            (p.target, p.primitive, p.depth)
        }
        _ => (
            DepthTarget::new(width, height, TileSize::T8, true)?,
            Vec::new(),
            Vec::new(),
        ),
    };
    let queries = std::mem::take(&mut state.queries);
    let mut backend = raster::SyncBackend::reusing(target, queries);
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let view = visibility::ViewSetup::eye_sampled(camera, &clip, threshold, sampling);
    let objects = visibility::Objects::new(&state.hierarchy, scene, &state.meshes);
    state
        .culler
        .cull_into(objects, &view, culling, &mut backend, &mut state.result)?;
    let (mut target, queries) = backend.into_parts();
    state.queries = queries;
    // Visible objects that may not occlude were left out of the traversal's
    // draws: they join the visible surface now, hiding nothing they did not.
    let deferred = state.result.rendered.iter().copied().filter(|id| {
        let f = scene.object(*id).flags;
        f.visible && !f.occludes
    });
    draw_objects(scene, meshes, camera, &mut target, deferred)?;
    Ok(EyePass::from_target(target, primitive, depth))
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
    backend: &mut dyn raster::OcclusionBackend,
) -> Result<()> {
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let view = visibility::ViewSetup::eye_sampled(
        camera,
        &clip,
        options.query_threshold,
        options.coverage.sampling(),
    );
    let objects = visibility::Objects::new(&state.hierarchy, scene, &state.meshes);
    Ok(state.culler.cull_into(
        objects,
        &view,
        options.culling(),
        backend,
        &mut state.result,
    )?)
}
