//! One frame of the exact stencil-shadow pipeline, without culling yet: the
//! eye pass rasterizes every object into a depth and primitive-id target, the
//! shadow volumes of every object are built [shadowgen], each is drawn into a
//! brute-force stencil on the eye depth buffer [raster], and the raw stencil
//! plus the primitive ids become the four-class mask ([`crate::mask::assemble`]).

use crate::mask::{assemble, Mask};
use crate::reference::PrimitiveId;
use crate::Result;
use glam::Vec4;
use raster::{
    Coverage, DepthTarget, DrawItem, HierarchicalOptions, HierarchicalStencil, StencilBits,
    StencilStats, StencilTarget, TileClass, TileSize, VolumeBuffer,
};
use scene::{Camera, Light, ObjectId, Scene};
use shadowgen::{build_volumes, BuildOptions, MethodChoice, SilhouetteCache, VolumeStats};

/// Per-mesh vertex data in the rasterizer's form (`w = 1`), built once per scene.
#[derive(Debug)]
pub struct MeshCache {
    positions: Vec<Vec<Vec4>>,
}

impl MeshCache {
    /// Converts every mesh of `scene`.
    pub fn new(scene: &Scene) -> Self {
        MeshCache {
            positions: scene
                .graph()
                .meshes()
                .iter()
                .map(|m| m.positions().iter().map(|p| p.extend(1.0)).collect())
                .collect(),
        }
    }
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
    target.set_threads(rayon::current_num_threads());
    // Front to back (by the distance from the eye to each object's bounds centre), so
    // hierarchical z rejects most hidden triangles; the depth and ids do not
    // depend on the order (nearest depth, then smallest id, wins).
    let mut order: Vec<(f64, usize)> = scene
        .objects()
        .iter()
        .enumerate()
        .map(|(i, o)| (o.world_bounds.center().distance_squared(camera.position), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let objects = scene.objects();
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
    // One batch: bands of tile rows in parallel; equal to drawing one by one.
    target.draw_batch(&items, Coverage::Standard)?;
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
}

impl EyeCulling {
    /// The state for `scene` (no history yet).
    pub fn new(scene: &Scene) -> Self {
        EyeCulling {
            hierarchy: visibility::Hierarchy::from_scene(scene),
            meshes: visibility::MeshData::from_scene(scene),
            culler: visibility::ViewCuller::new(),
        }
    }
}

impl EyeCulling {
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
            let mut last: Option<((ObjectId, u32), glam::DVec3, f64)> = None;
            let mut prev: Option<(ObjectId, u32)> = None;
            let (base, step) = rays.row(y as f64 + 0.5);
            for (x, ((p, j), prim)) in row.iter_mut().zip(joined.iter_mut()).zip(prims).enumerate()
            {
                let Some(prim) = *prim else {
                    *p = glam::DVec3::NAN;
                    *j = false;
                    prev = None;
                    continue;
                };
                let (n, d) = match last {
                    Some((q, n, d)) if q == prim => (n, d),
                    _ => {
                        let tri = scene.world_triangle(prim.0, prim.1 as usize);
                        let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                        let d = n.dot(tri[0] - e);
                        last = Some((prim, n, d));
                        (n, d)
                    }
                };
                let dir = base + step * (x as f64 + 0.5);
                let den = n.dot(dir);
                let hit = den != 0.0;
                let t_hit = if hit { d / den } else { 0.0 };
                *p = e + dir * t_hit;
                *j = hit && prev == Some(prim);
                prev = hit.then_some(prim);
            }
        });
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
#[allow(clippy::too_many_arguments)]
pub fn eye_pass_culled(
    scene: &Scene,
    state: &mut EyeCulling,
    camera: &Camera,
    width: u32,
    height: u32,
    culling: visibility::Culling,
    threshold: u32,
    sampling: visibility::Sampling,
    previous: Option<EyePass>,
) -> Result<(EyePass, visibility::CullResult)> {
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
    let mut backend = raster::SyncBackend::new(target);
    let clip = |w: &glam::DMat4| scene::transform::clip_from_local(camera, w);
    let view = visibility::ViewSetup::eye_sampled(camera, &clip, threshold, sampling);
    let result = state.culler.cull(
        &state.hierarchy,
        scene,
        &state.meshes,
        &view,
        culling,
        &mut backend,
    )?;
    Ok((
        EyePass::from_target(backend.into_target(), primitive, depth),
        result,
    ))
}

/// Which stencil backend draws the volumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Brute force: every volume fragment ([`StencilTarget`]).
    Brute,
    /// Hierarchical shadow volumes \[Aila04\] ([`HierarchicalStencil`]).
    Hierarchical {
        /// Tile size of the classification.
        tile: TileSize,
        /// The full-shadow bit [Aila04 §4.3.2].
        full_shadow: bool,
    },
    /// A shadow map decides every pixel whose four nearest map comparisons
    /// agree; the volumes (hierarchical stencil, 8×8 tiles, FS on) run only at
    /// the others \[ChanDurand04\]. Not exact.
    Hybrid {
        /// Shadow-map texels per side (per cube face for point lights).
        map_size: u32,
    },
}

/// The tile classification of a hierarchical frame ([Aila04 Fig. 1]).
#[derive(Clone, Debug, PartialEq)]
pub struct TileImage {
    /// Tile side in pixels.
    pub tile: u32,
    /// Tiles across and down.
    pub tiles_x: u32,
    /// Tiles down.
    pub tiles_y: u32,
    /// Row-major classes.
    pub classes: Vec<TileClass>,
}

impl TileImage {
    /// RGB pixels of a `width × height` image: every pixel takes its tile's
    /// colour — lit white, shadow dark blue, boundary orange, background black.
    pub fn rgb(&self, width: u32, height: u32) -> Vec<u8> {
        let mut out = Vec::with_capacity((width * height * 3) as usize);
        for y in 0..height {
            for x in 0..width {
                let c = self.classes[((y / self.tile) * self.tiles_x + x / self.tile) as usize];
                out.extend_from_slice(match c {
                    TileClass::Background => &[0, 0, 0],
                    TileClass::Lit => &[235, 235, 235],
                    TileClass::Shadow => &[40, 60, 140],
                    TileClass::Boundary => &[245, 150, 40],
                });
            }
        }
        out
    }
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
        }
    }
}

/// The shadow stage's output for one light.
#[derive(Debug)]
pub struct ShadowFrame {
    /// The four-class mask.
    pub mask: Mask,
    /// Volume construction counters.
    pub volumes: VolumeStats,
    /// Volume triangles drawn.
    pub volume_triangles: u64,
    /// Stencil counters.
    pub stencil: StencilStats,
    /// Per pixel (row-major, row 0 at the top): the raw stencil is non-zero,
    /// whatever the surface's facing.
    pub raw_nonzero: Vec<bool>,
    /// Wall time of the stencil stage: clearing, every volume drawn (for the
    /// hierarchical backend its tile bounds, both stages), the resolve, mask
    /// assembly (ms).
    pub stencil_ms: f64,
    /// The hierarchical backend's tile classification.
    pub tiles: Option<TileImage>,
    /// Hybrid: pixels left to the volumes (the shadow map's silhouette pixels).
    pub silhouette_pixels: u64,
    /// Hybrid: shadow-map rendering and classification (ms), inside `stencil_ms`.
    pub map_ms: f64,
}

/// Scratch kept across frames: the silhouette cache and the volume buffer.
#[derive(Default)]
pub struct ShadowScratch {
    cache: SilhouetteCache,
    volumes: VolumeBuffer,
    stencil: Option<StencilTarget>,
    hierarchical: Option<HierarchicalStencil>,
    /// The light pass's per-view culling state (PSC).
    pub(crate) light_pass: visibility::LightPass,
}

impl std::fmt::Debug for ShadowScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShadowScratch")
            .field("volume_ranges", &self.volumes.ranges.len())
            .finish_non_exhaustive()
    }
}

/// Builds every object's shadow volume for `light`, stencils them on the eye
/// depth buffer and assembles the mask.
///
/// # Errors
/// Invalid light ([`crate::Error::Shadowgen`]) or rasterizer errors.
pub fn shadow_mask(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: &EyePass,
    options: &ShadowOptions,
    scratch: &mut ShadowScratch,
) -> Result<ShadowFrame> {
    let casters: Vec<ObjectId> = (0..scene.objects().len() as u32).map(ObjectId).collect();
    shadow_mask_for(scene, camera, light, eye, options, scratch, &casters)
}

/// [`shadow_mask`] with shadow volumes for `casters` only (the potential
/// shadow casters of the light pass).
///
/// # Errors
/// As [`shadow_mask`]; also a caster id outside the scene.
pub fn shadow_mask_for(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: &EyePass,
    options: &ShadowOptions,
    scratch: &mut ShadowScratch,
    casters: &[ObjectId],
) -> Result<ShadowFrame> {
    let (w, h) = (eye.target.width(), eye.target.height());
    let build = BuildOptions {
        method: options.method,
        two_sided: options.two_sided,
        // Scissor rectangles and depth bounds cost time; only computed when used.
        viewport: (options.scissor || options.depth_bounds).then_some((w, h)),
        finite_extrusion: options.finite_extrusion,
    };
    let volumes = build_volumes(
        &mut scratch.volumes,
        scene,
        camera,
        light,
        casters,
        build,
        &mut scratch.cache,
    )?;
    let t = std::time::Instant::now();
    let mut stats = StencilStats::default();
    let tests = raster::StencilTests {
        scissor: options.scissor,
        depth_bounds: options.depth_bounds,
    };
    let clip: Vec<glam::Mat4> = scratch
        .volumes
        .ranges
        .iter()
        .map(|r| scene::transform::clip_from_local(camera, &r.world_from_local))
        .collect();
    let ranges: Vec<_> = clip.iter().copied().zip(&scratch.volumes.ranges).collect();
    let mut raw_nonzero = Vec::new();
    let mut tiles = None;
    let (mut silhouette_pixels, mut map_ms) = (0, 0.0);
    match options.backend {
        Backend::Brute => {
            let mut stencil = match scratch.stencil.take() {
                Some(mut s) if (s.width(), s.height(), s.bits()) == (w, h, options.bits) => {
                    s.clear();
                    s
                }
                _ => StencilTarget::new(w, h, options.bits)?,
            };
            stencil.draw_volumes(&eye.target, &ranges, &scratch.volumes, tests, &mut stats)?;
            stencil.resolve(&eye.target, &mut raw_nonzero, &mut stats)?;
            scratch.stencil = Some(stencil);
        }
        Backend::Hierarchical { tile, full_shadow } => {
            let want = HierarchicalOptions {
                tile,
                bits: options.bits,
                full_shadow,
            };
            let mut stencil = match scratch.hierarchical.take() {
                Some(mut s) if (s.width(), s.height(), s.options()) == (w, h, want) => {
                    s.clear();
                    s
                }
                _ => HierarchicalStencil::new(w, h, want)?,
            };
            stencil.draw_volumes(&eye.target, &ranges, &scratch.volumes, tests, &mut stats)?;
            stencil.resolve(&eye.target, &mut raw_nonzero, &mut stats)?;
            let (tiles_x, tiles_y) = stencil.tile_counts();
            tiles = Some(TileImage {
                tile: tile.pixels(),
                tiles_x,
                tiles_y,
                classes: stencil.tile_classes(),
            });
            scratch.hierarchical = Some(stencil);
        }
        Backend::Hybrid { map_size } => {
            let class =
                crate::hybrid::classify(scene, camera, light, eye, map_size, options.two_sided)?;
            // The computation mask: volumes see only the silhouette pixels' depth.
            // The hierarchical stencil then skips every tile without one, as a
            // GPU's hierarchical z rejects them [ChanDurand04].
            let mut masked = eye.target.clone();
            masked.keep_only(&class.silhouette)?;
            let want = HierarchicalOptions {
                tile: TileSize::T8,
                bits: options.bits,
                full_shadow: true,
            };
            let mut stencil = match scratch.hierarchical.take() {
                Some(mut s) if (s.width(), s.height(), s.options()) == (w, h, want) => {
                    s.clear();
                    s
                }
                _ => HierarchicalStencil::new(w, h, want)?,
            };
            stencil.draw_volumes(&masked, &ranges, &scratch.volumes, tests, &mut stats)?;
            stencil.resolve(&masked, &mut raw_nonzero, &mut stats)?;
            for (i, r) in raw_nonzero.iter_mut().enumerate() {
                if !class.silhouette[i] {
                    *r = class.shadowed[i];
                }
            }
            scratch.hierarchical = Some(stencil);
            silhouette_pixels = class.silhouette_pixels;
            map_ms = class.map_ms;
        }
    }
    let volume_triangles = stats.triangles;
    let shadowed = |i: usize| raw_nonzero[i];
    let mask = assemble(
        scene,
        camera,
        light,
        w,
        h,
        &eye.primitive,
        shadowed,
        options.two_sided,
    );
    Ok(ShadowFrame {
        mask,
        volumes,
        volume_triangles,
        stencil: stats,
        raw_nonzero,
        stencil_ms: t.elapsed().as_secs_f64() * 1e3,
        tiles,
        silhouette_pixels,
        map_ms,
    })
}
