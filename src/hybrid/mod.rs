//! The shadow-map half of the hybrid shadow algorithm [ChanDurand04 abstract]: a
//! shadow map rendered from the light classifies every eye pixel as surely
//! lit, surely shadowed, or a *shadow-silhouette* pixel where the map cannot
//! decide. Shadow volumes then only need to be rasterized at the silhouette
//! pixels: [`raster::DepthTarget::keep_only`] with
//! [`ShadowMapClass::silhouette`] turns the eye depth target into the
//! computation mask of [ChanDurand04 computation mask], so the stencil passes skip every
//! other pixel and every tile without one.
//!
//! # Maps
//! In a pipeline that runs a light pass with point-sampled light views, the
//! maps are the light pass's own light views ([`classify_with_views`],
//! `view_maps.rs`): fitted to the
//! intersection body, and holding after the traversal the casting
//! triangles of every caster that can shadow a visible receiver. Nothing is
//! drawn for the hybrid then. Without a light pass ([`classify`]) it draws
//! its own maps, as follows.
//!
//! Its own maps are drawn with the project's own rasterizer ([`DepthTarget`],
//! reversed Z, nearer = greater, [`raster::BACKGROUND`] where nothing was
//! drawn), `map_size × map_size` texels each:
//! - **directional** light: one orthographic map over the scene bounds
//!   (near and far planes just outside the bounds, so nothing is clipped);
//! - **spot** light with an apex angle up to 120°: one perspective map over
//!   the cone; wider spots, and **point** lights: a cube of six perspective
//!   faces around the light.
//!
//! Every map is widened by [`MARGIN_TEXELS`] texels on each side, so the 2×2
//! texel footprint of every point the map is meant to cover lies inside it.
//! Perspective maps have an infinite far plane and a near plane at half the
//! distance from the light to the nearest object bounds (at least 2⁻²⁰ of the
//! scene extent when the light is inside an object's bounds): parts of casters
//! nearer to the light than that are clipped and simply do not cast in the
//! map (their pixels can only end up as silhouette or misclassified — the
//! usual shadow-map limitation).
//!
//! Light clip matrices are built in f64 relative to the light position (the
//! scene-bounds centre for directional lights), composed per object with
//! `world_from_local` in f64 and rounded to f32 once, as the eye path does
//! (DESIGN.md "One transform path").
//!
//! Only casters go into the maps: per object and light the triangles that
//! face the light under the shared facing rule ([`scene::faces_light`]), all
//! triangles with `two_sided` — exactly the triangles the reference lets
//! block a shadow ray and the volumes are built from.
//!
//! # Classification
//! Per non-background eye pixel the surface point is reconstructed from the
//! eye depth (f64) and projected into the map (for the cube: the face of the
//! dominant axis of `p − l`); the four nearest texel centres (the bilinear
//! footprint) are each compared with the surface: shadowed when the map holds a surface
//! nearer to the light than the receiver by more than the bias. All four
//! agree → that answer; otherwise the pixel is a silhouette pixel.
//!
//! The receiver depth at each texel is that of the visible triangle's *plane*
//! along the texel's light ray ("receiver-plane depth"), not the point's own
//! depth: a lit plane then matches its own map samples at all four texels up
//! to rasterization error, whatever its slope, so no slope-dependent bias
//! has to hide self-shadowing ("shadow acne"), and a texel misses a real
//! caster only when the caster is within the bias of the receiver.
//!
//! # Bias
//! `bias = DEPTH_BIAS_REL · scale + SLOPE_BIAS_TEXELS · slope`, with `scale`
//! the receiver's light-space distance (perspective) or the map's depth range
//! (orthographic), and `slope` the largest change of the receiver plane's
//! depth between horizontally or vertically adjacent texels of the footprint.
//! The first term covers the f32 rounding of the clip matrix and of the
//! stored depth and the rasterizer's `ε_z` (2⁻²³), the second the vertex
//! snapping (1/256 texel moves a plane sideways by up to 1/512 texel).
//! Measured on the unit tests' scene (200×150, 256² maps): without bias 3–80 %
//! of the lit pixels self-shadow; with only one of the two terms 0.4–1.7 %
//! still do; with both, none do, and still none with each term 8× smaller.
//!
//! A receiver seen from the light at a grazing angle is undersampled: its
//! four texel rays meet its plane far from the point (beyond the caster's own
//! edge, say, where the roof above a wall answers "shadowed"). Where any of
//! them lands more than `GRAZING_TEXELS` texel footprints from the point,
//! the pixel is left to the volumes.
//!
//! Where a receiver meets another surface in a concave corner (a wall
//! standing on the ground), the texels next to the corner show the other
//! surface nearer than the receiver's plane: a band about one texel wide
//! along such corners is classified silhouette even where the reference sees
//! no shadow edge (left to the volumes, so harmless, but counted).
//!
//! # Pixels decided without a map
//! Background pixels are neither shadowed nor silhouette. Pixels the mask
//! classes make unlit whatever the stencil says ([`crate::mask::is_unlit`]:
//! back-facing surface, eye and light on opposite sides, outside the light's
//! cone or range) are also neither: no volume needs to be rasterized there.
//! Points outside every map (nearer to the light than the near plane) or at
//! infinite depth are silhouette pixels.

mod bias;
mod cube_face;
mod view_maps;

use bias::GRAZING_TEXELS;
pub use bias::{DEPTH_BIAS_REL, SLOPE_BIAS_TEXELS};

use crate::mask::is_unlit;
use crate::reference::EyeSurface;
use crate::surface::RayPlane;
use crate::Result;
use glam::{DMat3, DMat4, DVec3, DVec4, Vec4};
use raster::{Coverage, DepthTarget, DrawItem, RasterStats, TileSize};
use rayon::prelude::*;
use scene::{faces_light, Camera, Light, ObjectId, Scene};

/// Texels added on each side of every map, so the 2×2 footprint of every point
/// a map is meant to cover (the cone, the cube face, the scene bounds) lies
/// inside it.
pub const MARGIN_TEXELS: f64 = 2.0;

/// Smallest map side used (smaller requests are raised to it).
pub const MIN_MAP_SIZE: u32 = 8;

/// Widest spot cone (full apex angle) drawn into one perspective map; wider
/// spots use the six-face cube of point lights.
pub const MAX_SPOT_MAP_APEX_DEG: f64 = 120.0;

/// The shadow-map classification of one view and one light [ChanDurand04 abstract].
#[derive(Clone, Debug)]
pub struct ShadowMapClass {
    /// Per eye pixel (row-major, row 0 top): the shadow map says shadowed
    /// (meaningful where `!silhouette`).
    pub shadowed: Vec<bool>,
    /// Per eye pixel: the four nearest shadow-map comparisons disagree (or the
    /// pixel is outside every map): shadow volumes decide here.
    pub silhouette: Vec<bool>,
    /// Number of `true` entries of [`ShadowMapClass::silhouette`].
    pub silhouette_pixels: u64,
    /// Texels rasterized into: number of maps × `map_size²`.
    pub map_texels: u64,
    /// Number of maps drawn (1, or 6 for a cube; 0 for an empty scene).
    pub maps: u32,
    /// The maps' raster counters, summed.
    pub map_stats: RasterStats,
    /// Wall time of rendering the map(s) and classifying (ms).
    pub map_ms: f64,
}

/// A light view's projection (light view space looks down −z).
#[derive(Clone, Copy, Debug)]
enum Proj {
    /// Reversed Z, infinite far plane: depth = `near / d`, `d` the view distance;
    /// `f = 1 / tan(half field of view)`, square.
    Persp { f: f64, near: f64 },
    /// Depth = `(far − d) / (far − near)`; x, y centred on `(cx, cy)`, half
    /// extents `(hx, hy)`.
    Ortho {
        cx: f64,
        cy: f64,
        hx: f64,
        hy: f64,
        near: f64,
        far: f64,
    },
}

impl Proj {
    fn clip_from_view(&self) -> DMat4 {
        match *self {
            Proj::Persp { f, near } => DMat4::from_cols(
                DVec4::new(f, 0.0, 0.0, 0.0),
                DVec4::new(0.0, f, 0.0, 0.0),
                DVec4::new(0.0, 0.0, 0.0, -1.0),
                DVec4::new(0.0, 0.0, near, 0.0),
            ),
            Proj::Ortho {
                cx,
                cy,
                hx,
                hy,
                near,
                far,
            } => {
                let r = far - near;
                DMat4::from_cols(
                    DVec4::new(1.0 / hx, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, 1.0 / hy, 0.0, 0.0),
                    DVec4::new(0.0, 0.0, 1.0 / r, 0.0),
                    DVec4::new(-cx / hx, -cy / hy, far / r, 1.0),
                )
            }
        }
    }
}

/// One shadow map: a light view and its depth target.
struct MapView {
    /// Origin of the light-relative frame (light position, or the scene-bounds
    /// centre for directional lights).
    origin: DVec3,
    view_from_world: DMat3,
    proj: Proj,
    target: DepthTarget,
}

impl MapView {
    fn new(origin: DVec3, forward: DVec3, proj: Proj, size: u32) -> Result<Self> {
        let mut target = DepthTarget::new(size, size, TileSize::T8, false)?;
        target.set_threads(rayon::current_num_threads());
        Ok(MapView {
            origin,
            view_from_world: view_from_world(forward),
            proj,
            target,
        })
    }

    /// `clip_from_local` of an object, composed in f64 light-relative and
    /// rounded once.
    fn clip_from_local(&self, world_from_local: &DMat4) -> glam::Mat4 {
        let mut rel = *world_from_local;
        rel.w_axis -= self.origin.extend(0.0);
        (self.proj.clip_from_view() * DMat4::from_mat3(self.view_from_world) * rel).as_mat4()
    }

    /// Light view space of a world point.
    fn view(&self, p: DVec3) -> DVec3 {
        self.view_from_world * (p - self.origin)
    }

    /// Texel coordinates (pixel units, row 0 at the top) of a view-space point,
    /// `None` outside the view volume.
    fn texel_coords(&self, v: DVec3) -> Option<(f64, f64)> {
        let d = -v.z;
        let (nx, ny) = match self.proj {
            Proj::Persp { f, near } => {
                // (NaN fails too.)
                if d.is_nan() || d < near {
                    return None;
                }
                (v.x * f / d, v.y * f / d)
            }
            Proj::Ortho {
                cx,
                cy,
                hx,
                hy,
                near,
                far,
            } => {
                if !(d >= near && d <= far) {
                    return None;
                }
                ((v.x - cx) / hx, (v.y - cy) / hy)
            }
        };
        let n = f64::from(self.target.width());
        Some(((nx + 1.0) * 0.5 * n, (1.0 - ny) * 0.5 * n))
    }

    /// The light ray through texel centre `(i, j)`: view-space origin and
    /// direction, scaled so the ray parameter is the view distance `d`.
    fn texel_ray(&self, i: u32, j: u32) -> (DVec3, DVec3) {
        let n = f64::from(self.target.width());
        let nx = 2.0 * (f64::from(i) + 0.5) / n - 1.0;
        let ny = 1.0 - 2.0 * (f64::from(j) + 0.5) / n;
        match self.proj {
            Proj::Persp { f, .. } => (DVec3::ZERO, DVec3::new(nx / f, ny / f, -1.0)),
            Proj::Ortho { cx, cy, hx, hy, .. } => {
                (DVec3::new(cx + nx * hx, cy + ny * hy, 0.0), DVec3::NEG_Z)
            }
        }
    }

    /// View distance of the map's surface at texel `(i, j)`; `None` where the
    /// map holds nothing (or a surface at infinity).
    fn map_distance(&self, i: u32, j: u32) -> Option<f64> {
        let z = f64::from(self.target.depth_at(i, j)?);
        match self.proj {
            Proj::Persp { near, .. } => (z > 0.0).then(|| near / z),
            Proj::Ortho { near, far, .. } => Some(far - z * (far - near)),
        }
    }

    /// Side of one texel's footprint, in world units, on a surface facing the
    /// light at view distance `d`.
    fn texel_size(&self, d: f64) -> f64 {
        let n = f64::from(self.target.width());
        match self.proj {
            Proj::Persp { f, .. } => 2.0 * d.abs() / (f * n),
            Proj::Ortho { hx, hy, .. } => 2.0 * hx.max(hy) / n,
        }
    }

    /// Scale of the depth-relative bias at view distance `d`.
    fn bias_scale(&self, d: f64) -> f64 {
        match self.proj {
            Proj::Persp { .. } => d.abs(),
            Proj::Ortho { near, far, .. } => far - near,
        }
    }
}

/// Rotation from world to a light view looking along `forward` (view −z).
fn view_from_world(forward: DVec3) -> DMat3 {
    let f = forward.normalize();
    let up = if f.y.abs() < 0.9 { DVec3::Y } else { DVec3::Z };
    let x = f.cross(up).normalize();
    let y = x.cross(f);
    DMat3::from_cols(x, y, -f).transpose()
}

/// Distance from `p` to the box (0 inside).
fn box_distance(b: &scene::Aabb, p: DVec3) -> f64 {
    let lo = b.min.as_dvec3();
    let hi = b.max.as_dvec3();
    (lo - p).max(p - hi).max(DVec3::ZERO).length()
}

/// Perspective near plane for a light at `l` (see the module docs).
fn perspective_near(scene: &Scene, l: DVec3) -> f64 {
    let extent = f64::from(scene.bounds().size().max_element()).max(1e-30);
    let nearest = scene
        .objects()
        .iter()
        .map(|o| box_distance(&o.world_bounds, l))
        .fold(f64::INFINITY, f64::min);
    (0.5 * nearest).max(extent / (1u64 << 20) as f64)
}

/// The six cube faces around `l`, each 90° widened by the margin.
fn cube_views(scene: &Scene, l: DVec3, size: u32) -> Result<Vec<MapView>> {
    let n = f64::from(size);
    let t = n / (n - 2.0 * MARGIN_TEXELS);
    let near = perspective_near(scene, l);
    [
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ]
    .into_iter()
    .map(|d| MapView::new(l, d, Proj::Persp { f: 1.0 / t, near }, size))
    .collect()
}

/// The light views of `light` (see the module docs).
fn light_views(scene: &Scene, light: &Light, size: u32) -> Result<Vec<MapView>> {
    let n = f64::from(size);
    let widen = n / (n - 2.0 * MARGIN_TEXELS);
    match *light {
        Light::Point { position, .. } => cube_views(scene, position, size),
        Light::Spot {
            position,
            direction,
            apex_angle,
            ..
        } => {
            if apex_angle > MAX_SPOT_MAP_APEX_DEG.to_radians() {
                return cube_views(scene, position, size);
            }
            let t = (0.5 * apex_angle).tan() * widen;
            let near = perspective_near(scene, position);
            Ok(vec![MapView::new(
                position,
                direction,
                Proj::Persp { f: 1.0 / t, near },
                size,
            )?])
        }
        Light::Directional { direction } => {
            let b = scene.bounds();
            let origin = b.center();
            // Rotation first (the projection depends on the extents it gives).
            let rot = view_from_world(direction);
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for c in b.corners() {
                let v = rot * (c.as_dvec3() - origin);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            let extent = (hi - lo).max_element().max(1e-30);
            let pad = extent * (1.0 / 1024.0);
            let hx = (0.5 * (hi.x - lo.x) * widen).max(pad);
            let hy = (0.5 * (hi.y - lo.y) * widen).max(pad);
            // View distance d = −z: near = smallest, far = largest, padded.
            let proj = Proj::Ortho {
                cx: 0.5 * (lo.x + hi.x),
                cy: 0.5 * (lo.y + hi.y),
                hx,
                hy,
                near: -hi.z - pad,
                far: -lo.z + pad,
            };
            Ok(vec![MapView::new(origin, direction, proj, size)?])
        }
    }
}

/// Classifies every eye pixel with shadow maps of `light` [ChanDurand04 abstract]:
/// surely shadowed, surely lit, or silhouette (shadow volumes decide). See the
/// module docs for the maps, the comparison and its bias.
///
/// The light-facing triangles of every object are gathered from the scene per
/// call (the casters differ per light).
///
/// # Errors
/// [`crate::Error::Scene`] for an invalid light; [`crate::Error::Raster`] for a
/// `map_size` of 0 or above [`raster::MAX_TARGET_SIZE`], or an eye pass whose
/// buffers do not match its target.
pub fn classify(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: EyeSurface<'_>,
    (w, h): (u32, u32),
    map_size: u32,
    two_sided: bool,
) -> Result<ShadowMapClass> {
    let start = std::time::Instant::now();
    check_input(light, &eye, (w, h))?;
    let n = w as usize * h as usize;
    // Tiny maps cannot hold the margin; 0 stays 0 for the rasterizer to reject.
    let map_size = if map_size == 0 {
        0
    } else {
        map_size.max(MIN_MAP_SIZE)
    };
    if scene.objects().is_empty() {
        // Nothing to draw or to classify (every eye pixel is background).
        DepthTarget::new(map_size, map_size, TileSize::T8, false)?;
        return Ok(ShadowMapClass {
            shadowed: vec![false; n],
            silhouette: vec![false; n],
            silhouette_pixels: 0,
            map_texels: 0,
            maps: 0,
            map_stats: RasterStats::default(),
            map_ms: start.elapsed().as_secs_f64() * 1e3,
        });
    }
    let mut views = light_views(scene, light, map_size)?;

    // Casters: per object the triangles that face the light (all when two-sided).
    let positions: Vec<Vec<Vec4>> = scene
        .graph()
        .meshes()
        .iter()
        .map(|m| m.positions().iter().map(|p| p.extend(1.0)).collect())
        .collect();
    let casters: Vec<Vec<[u32; 3]>> = (0..scene.objects().len())
        .into_par_iter()
        .map(|i| {
            let id = ObjectId::from_slot(i as u32);
            let tris = scene.object_mesh(id).triangles();
            if !scene.objects()[i].flags.casts {
                return Vec::new();
            }
            if two_sided {
                return tris.to_vec();
            }
            (0..tris.len())
                .filter(|&t| faces_light(&scene.world_triangle(id, t), light))
                .map(|t| tris[t])
                .collect()
        })
        .collect();
    // Near to far from the light (hierarchical z rejects more); the map does not
    // depend on the order.
    let from = light.position().unwrap_or_else(|| {
        let extent = f64::from(scene.bounds().size().max_element());
        scene.bounds().center() + light.toward_light(DVec3::ZERO).normalize() * (4.0 * extent)
    });
    let mut order: Vec<(f64, usize)> = scene
        .objects()
        .iter()
        .enumerate()
        .filter(|(i, _)| !casters[*i].is_empty())
        .map(|(i, o)| (o.world_bounds.center().distance_squared(from), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let objects = scene.objects();
    let stats: Vec<RasterStats> = views
        .par_iter_mut()
        .map(|v| -> Result<RasterStats> {
            let items: Vec<DrawItem> = order
                .iter()
                .map(|&(_, i)| DrawItem {
                    clip_from_local: v.clip_from_local(&objects[i].world_from_local),
                    positions: &positions[objects[i].mesh.index()],
                    triangles: &casters[i],
                    object: i as u32,
                    cull: raster::CullMode::None,
                })
                .collect();
            v.target.draw_batch(&items, Coverage::Standard)?;
            Ok(v.target.take_stats())
        })
        .collect::<Result<_>>()?;
    let mut map_stats = RasterStats::default();
    for s in &stats {
        map_stats.add(s);
    }

    let (shadowed, silhouette, silhouette_pixels) =
        classify_pixels(scene, camera, light, eye, (w, h), two_sided, |p, a, nrm| {
            classify_point(&views, light, p, a, nrm)
        });
    Ok(ShadowMapClass {
        shadowed,
        silhouette,
        silhouette_pixels,
        map_texels: views.len() as u64 * u64::from(map_size) * u64::from(map_size),
        maps: views.len() as u32,
        map_stats,
        map_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

/// Refuses an invalid light, and an eye pass without depth or of another size.
fn check_input(light: &Light, eye: &EyeSurface<'_>, (w, h): (u32, u32)) -> Result<()> {
    light.validate()?;
    if !eye.has_depth() || !eye.fits(w, h) {
        return Err(raster::Error::MaskLength {
            expected: w as usize * h as usize,
            got: if eye.has_depth() { eye.len() } else { 0 },
            width: w,
            height: h,
        }
        .into());
    }
    Ok(())
}

/// [`classify`] with the light pass's own light views as the maps
/// (`view_maps.rs`): `views` are the views of this frame's light pass with
/// their kept depth ([`visibility::LightPass::view_depths`]), already
/// fitted to the intersection body and holding the casting triangles the
/// traversal drew, so no map is rendered here. `map_ms` is the
/// classification alone; `map_stats` stay zero (the light pass counts the
/// draws).
///
/// # Errors
/// As [`classify`]; also [`crate::Error::Raster`] for a view whose target
/// is not `resolution²`.
pub fn classify_with_views(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: EyeSurface<'_>,
    (w, h): (u32, u32),
    views: &[(&visibility::LightView, &DepthTarget)],
    two_sided: bool,
) -> Result<ShadowMapClass> {
    let start = std::time::Instant::now();
    check_input(light, &eye, (w, h))?;
    let maps = view_maps::ViewMaps::new(views, light)?;
    let (shadowed, silhouette, silhouette_pixels) =
        classify_pixels(scene, camera, light, eye, (w, h), two_sided, |p, a, nrm| {
            maps.classify(p, a, nrm)
        });
    Ok(ShadowMapClass {
        shadowed,
        silhouette,
        silhouette_pixels,
        map_texels: views
            .iter()
            .map(|(v, _)| u64::from(v.resolution).pow(2))
            .sum(),
        maps: views.len() as u32,
        map_stats: RasterStats::default(),
        map_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

/// Per eye pixel of `eye`: `(shadowed, silhouette)` from `point(p, a, nrm)`
/// (the map's answer for surface point `p` on the plane through `a` with
/// normal `nrm`, `None` for silhouette), and the number of silhouette
/// pixels. Background and unlit pixels are neither; a pixel at infinite
/// depth is silhouette.
fn classify_pixels(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: EyeSurface<'_>,
    (w, h): (u32, u32),
    two_sided: bool,
    point: impl Fn(DVec3, DVec3, DVec3) -> Option<bool> + Sync,
) -> (Vec<bool>, Vec<bool>, u64) {
    let n = w as usize * h as usize;
    let rays = camera.rays(w, h);
    let forward = camera.forward();
    let e = camera.position;
    let mut shadowed = vec![false; n];
    let mut silhouette = vec![false; n];
    shadowed
        .par_chunks_mut(w as usize)
        .zip(silhouette.par_chunks_mut(w as usize))
        .enumerate()
        .for_each(|(y, (sh_row, si_row))| {
            // The triangle and its plane once per run of one primitive.
            eye.for_each_run_in_row(y as u32, |x0, x1, id| {
                let Some((obj, t)) = id else {
                    return;
                };
                let tri = scene.world_triangle(obj, t as usize);
                let plane = RayPlane::new(&tri, e);
                let nrm = plane.normal;
                for x in x0 as usize..x1 as usize {
                    let dir = rays.direction(x as f64 + 0.5, y as f64 + 0.5);
                    // The unlit decision exactly as the mask assembly makes it.
                    if is_unlit(&tri, e, light, plane.point_or_origin(e, dir), two_sided) {
                        continue;
                    }
                    let z = f64::from(eye.depth(x as u32, y as u32).unwrap_or(raster::BACKGROUND));
                    if z.is_nan() || z <= 0.0 {
                        si_row[x] = true;
                        continue;
                    }
                    let p = e + dir * ((camera.near / z) / dir.dot(forward));
                    match point(p, tri[0], nrm) {
                        Some(s) => sh_row[x] = s,
                        None => si_row[x] = true,
                    }
                }
            });
        });
    let silhouette_pixels = silhouette.iter().filter(|&&s| s).count() as u64;
    (shadowed, silhouette, silhouette_pixels)
}

/// The map's answer for surface point `p` on the plane through `a` with normal
/// `nrm` (world space): `Some(shadowed)` when the four texels agree, `None`
/// for a silhouette point (disagreement, or outside every map).
fn classify_point(
    views: &[MapView],
    light: &Light,
    p: DVec3,
    a: DVec3,
    nrm: DVec3,
) -> Option<bool> {
    let view = if views.len() == 6 {
        let l = light.position().unwrap_or(DVec3::ZERO);
        &views[cube_face::dominant_face(p - l)]
    } else {
        &views[0]
    };
    let pv = view.view(p);
    let (u, v) = view.texel_coords(pv)?;
    let size = view.target.width();
    let (i0, j0) = ((u - 0.5).floor(), (v - 0.5).floor());
    if !(i0 >= 0.0 && j0 >= 0.0 && i0 + 1.0 < f64::from(size) && j0 + 1.0 < f64::from(size)) {
        return None;
    }
    let (i0, j0) = (i0 as u32, j0 as u32);
    // The receiver plane in view space.
    let nv = view.view_from_world * nrm;
    let av = view.view(a);
    let d_point = -pv.z;
    let mut d_plane = [0.0f64; 4];
    // Where the footprint's rays meet the receiver plane farther from the
    // point than this, the plane is seen at a grazing angle and the four
    // samples describe other parts of it (or the caster's own top beyond its
    // edge): the map cannot decide, the volumes must.
    let reach = GRAZING_TEXELS * view.texel_size(d_point);
    for (k, d) in d_plane.iter_mut().enumerate() {
        let (o, dir) = view.texel_ray(i0 + (k as u32 & 1), j0 + (k as u32 >> 1));
        let den = nv.dot(dir);
        let t = nv.dot(av - o) / den;
        // Plane parallel to the ray, or behind its origin: fall back to the
        // point's own depth.
        let ahead = t > 0.0 || matches!(view.proj, Proj::Ortho { .. });
        if !(den != 0.0 && t.is_finite() && ahead) || (o + dir * t - pv).length() > reach {
            return None;
        }
        *d = t;
    }
    let slope = [(0, 1), (2, 3), (0, 2), (1, 3)]
        .iter()
        .map(|&(a, b)| (d_plane[a] - d_plane[b]).abs())
        .fold(0.0f64, f64::max);
    let mut answer = None;
    for (k, &dp) in d_plane.iter().enumerate() {
        let bias = DEPTH_BIAS_REL * view.bias_scale(dp) + SLOPE_BIAS_TEXELS * slope;
        let s = view
            .map_distance(i0 + (k as u32 & 1), j0 + (k as u32 >> 1))
            .is_some_and(|dm| dm < dp - bias);
        match answer {
            None => answer = Some(s),
            Some(prev) if prev != s => return None,
            _ => {}
        }
    }
    answer
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask::PixelClass;
    use crate::pipeline::{eye_pass, MeshCache};
    use crate::reference::{reference_mask, ReferenceMask, ReferenceOptions, TriangleBvh};
    use glam::Vec3;
    use scene::procedural::analytic;
    use scene::{Mesh, SceneGraph, Transform};

    const W: u32 = 200;
    const H: u32 = 150;

    /// The stencil tests' ground, tower, slab and open awning
    /// (`tests/common::boxes_on_ground`).
    fn boxes_on_ground() -> Scene {
        let meshes: Vec<Mesh> = vec![
            analytic::horizontal_quad("ground", [-10.0, 10.0], [-10.0, 10.0], 0.0, true).unwrap(),
            analytic::box_mesh(
                "tower",
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 3.0, 1.0),
            )
            .unwrap(),
            analytic::box_mesh("slab", Vec3::new(2.0, 1.0, 2.0), Vec3::new(3.0, 1.5, 4.0)).unwrap(),
            analytic::horizontal_quad("awning", [-4.0, -2.0], [1.0, 3.0], 2.0, true).unwrap(),
        ];
        let mut g = SceneGraph::new();
        let ids: Vec<_> = meshes.into_iter().map(|m| g.add_mesh(m)).collect();
        g.add_root(scene::Node {
            name: "root".into(),
            transform: Transform::default(),
            meshes: ids,
            children: vec![],
        });
        Scene::new(g).unwrap()
    }

    fn overview_camera() -> Camera {
        Camera::look_at(
            DVec3::new(2.0, 9.0, 12.0),
            DVec3::ZERO,
            DVec3::Y,
            50f64.to_radians(),
            4.0 / 3.0,
            0.05,
        )
        .unwrap()
    }

    fn lights() -> [(&'static str, Light); 3] {
        [
            (
                "directional",
                Light::Directional {
                    direction: DVec3::new(1.0, -0.9, -0.6),
                },
            ),
            (
                "spot",
                Light::Spot {
                    position: DVec3::new(-4.0, 8.0, 3.0),
                    direction: DVec3::new(4.0, -8.0, -3.0),
                    apex_angle: 100f64.to_radians(),
                    range: None,
                },
            ),
            (
                "point",
                Light::Point {
                    position: DVec3::new(-4.0, 8.0, 3.0),
                    range: None,
                },
            ),
        ]
    }

    /// Measured agreement of a classification with the reference.
    #[derive(Debug)]
    struct Measure {
        /// Reference lit/shadow, unambiguous pixels.
        compared: u64,
        /// Of those, non-silhouette pixels whose map answer differs from the reference.
        wrong: u64,
        /// Non-silhouette pixels the reference calls lit but the map shadowed.
        false_shadow: u64,
        silhouette: u64,
        /// Silhouette pixels with both a reference lit and a reference shadow
        /// pixel within `NEAR_PX` (Chebyshev), or on a receiver the light grazes.
        silhouette_near_boundary: u64,
        map_ms: f64,
    }

    const NEAR_PX: i64 = 3;

    fn measure(
        scene: &Scene,
        bvh: &TriangleBvh,
        light: &Light,
        map_size: u32,
        two_sided: bool,
    ) -> (Measure, ShadowMapClass, ReferenceMask) {
        let cam = overview_camera();
        let meshes = MeshCache::new(scene);
        let eye = eye_pass(scene, &meshes, &cam, W, H).unwrap();
        let class = classify(
            scene,
            &cam,
            light,
            eye.surface(),
            (W, H),
            map_size,
            two_sided,
        )
        .unwrap();
        let opts = ReferenceOptions {
            two_sided,
            ..ReferenceOptions::default()
        };
        let r = reference_mask(bvh, &cam, light, W, H, &opts, Some(eye.surface()));
        let mut m = Measure {
            compared: 0,
            wrong: 0,
            false_shadow: 0,
            silhouette: class.silhouette_pixels,
            silhouette_near_boundary: 0,
            map_ms: class.map_ms,
        };
        for i in 0..(W * H) as usize {
            let c = r.mask.pixels[i];
            if !c.is_compared() || r.ambiguous[i] {
                continue;
            }
            m.compared += 1;
            if !class.silhouette[i] && class.shadowed[i] != (c == PixelClass::Shadow) {
                m.wrong += 1;
                m.false_shadow += u64::from(class.shadowed[i]);
            }
        }
        for y in 0..H as i64 {
            for x in 0..W as i64 {
                if !class.silhouette[(y * W as i64 + x) as usize] {
                    continue;
                }
                let (mut lit, mut shadow) = (false, false);
                for yy in (y - NEAR_PX).max(0)..=(y + NEAR_PX).min(H as i64 - 1) {
                    for xx in (x - NEAR_PX).max(0)..=(x + NEAR_PX).min(W as i64 - 1) {
                        match r.mask.get(xx as u32, yy as u32) {
                            PixelClass::Lit => lit = true,
                            PixelClass::Shadow => shadow = true,
                            _ => {}
                        }
                    }
                }
                // Or a receiver the light grazes (more than 60° from its
                // normal), which the map leaves to the volumes on purpose.
                let grazing = eye.primitive(x as u32, y as u32).is_some_and(|(o, t)| {
                    let tri = scene.world_triangle(o, t as usize);
                    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                    let to_light = light.toward_light(tri[0]).normalize();
                    n.dot(to_light).abs() < 0.5
                });
                m.silhouette_near_boundary += u64::from((lit && shadow) || grazing);
            }
        }
        (m, class, r)
    }

    fn check_light(name: &str, light: &Light, two_sided: bool) {
        let scene = boxes_on_ground();
        let bvh = TriangleBvh::new(&scene);
        let mut sil = Vec::new();
        for map_size in [256, 1024] {
            let (m, class, r) = measure(&scene, &bvh, light, map_size, two_sided);
            let shadow = r.counts.classes.shadow;
            println!(
                "{name} two_sided={two_sided} map {map_size}² ×{}: compared {} (shadow {shadow}), \
                 wrong non-silhouette {} ({:.4}%, false shadow {}), silhouette {} ({:.2}% of image), \
                 near boundary {:.1}%, {:.1} ms",
                class.maps,
                m.compared,
                m.wrong,
                100.0 * m.wrong as f64 / m.compared as f64,
                m.false_shadow,
                m.silhouette,
                100.0 * m.silhouette as f64 / f64::from(W * H),
                100.0 * m.silhouette_near_boundary as f64 / m.silhouette.max(1) as f64,
                m.map_ms,
            );
            assert!(shadow > 1000, "{name}: the scene must show shadows");
            assert!(m.compared > 15000);
            // (a) non-silhouette pixels agree with the reference but for a small fraction.
            assert!(
                (m.wrong as f64) < 0.002 * m.compared as f64,
                "{name} {map_size}: {m:?}"
            );
            // (b) silhouette pixels are few and lie near the reference's shadow boundary.
            assert!(
                (m.silhouette as f64) < 0.08 * f64::from(W * H),
                "{name} {map_size}: {m:?}"
            );
            assert!(
                m.silhouette_near_boundary as f64 >= 0.8 * m.silhouette as f64,
                "{name} {map_size}: {m:?}"
            );
            assert_eq!(
                class.map_texels,
                u64::from(class.maps) * (map_size as u64).pow(2)
            );
            sil.push(m.silhouette);
        }
        // (c) a finer map leaves fewer silhouette pixels.
        assert!(sil[1] < sil[0], "{name}: {sil:?}");
    }

    #[test]
    fn hybrid_directional_agrees_with_reference() {
        let (name, light) = lights()[0];
        check_light(name, &light, false);
    }

    #[test]
    fn hybrid_spot_agrees_with_reference() {
        let (name, light) = lights()[1];
        check_light(name, &light, false);
    }

    #[test]
    fn hybrid_point_agrees_with_reference() {
        let (name, light) = lights()[2];
        check_light(name, &light, false);
    }

    #[test]
    fn hybrid_two_sided_point_agrees_with_reference() {
        let (name, light) = lights()[2];
        check_light(name, &light, true);
    }

    /// The eye target read in place and its row-major copies are one
    /// surface: the same ids and depth at every pixel, the same classes.
    #[test]
    fn target_surface_reads_like_its_rows() {
        let scene = boxes_on_ground();
        let cam = overview_camera();
        let meshes = MeshCache::new(&scene);
        let eye = eye_pass(&scene, &meshes, &cam, W, H).unwrap();
        let ids = eye.primitives();
        let depth = eye.target.depth_rows();
        let rows = EyeSurface::from_rows(W, &ids, Some(&depth));
        let target = eye.surface();
        assert!(rows.fits(W, H) && target.fits(W, H) && !target.fits(W + 1, H));
        let mut seen = 0;
        for y in 0..H {
            for x in 0..W {
                assert_eq!(target.primitive(x, y), rows.primitive(x, y), "({x}, {y})");
                assert_eq!(target.depth(x, y), rows.depth(x, y), "({x}, {y})");
                seen += usize::from(rows.primitive(x, y).is_some());
            }
        }
        assert!(seen > 0 && seen < (W * H) as usize, "{seen}");
        let (_, light) = lights()[0];
        let a = classify(&scene, &cam, &light, target, (W, H), 64, false).unwrap();
        let b = classify(&scene, &cam, &light, rows, (W, H), 64, false).unwrap();
        assert_eq!((a.shadowed, a.silhouette), (b.shadowed, b.silhouette));
    }

    #[test]
    fn hybrid_background_and_bad_input() {
        let scene = boxes_on_ground();
        let cam = overview_camera();
        let meshes = MeshCache::new(&scene);
        let eye = eye_pass(&scene, &meshes, &cam, W, H).unwrap();
        let (_, light) = lights()[2];
        let class = classify(&scene, &cam, &light, eye.surface(), (W, H), 64, false).unwrap();
        for i in 0..(W * H) as usize {
            if eye.primitive(i as u32 % W, i as u32 / W).is_none() {
                assert!(!class.shadowed[i] && !class.silhouette[i]);
            }
        }
        assert_eq!(class.maps, 6);
        let wide = Light::Spot {
            position: DVec3::new(-4.0, 8.0, 3.0),
            direction: DVec3::NEG_Y,
            apex_angle: 150f64.to_radians(),
            range: Some(30.0),
        };
        let class = classify(&scene, &cam, &wide, eye.surface(), (W, H), 64, false).unwrap();
        assert_eq!((class.maps, class.map_texels), (6, 6 * 64 * 64));
        assert!(matches!(
            classify(&scene, &cam, &light, eye.surface(), (W, H), 0, false),
            Err(crate::Error::Raster(raster::Error::InvalidSize { .. }))
        ));
        let bad = Light::Directional {
            direction: DVec3::ZERO,
        };
        assert!(matches!(
            classify(&scene, &cam, &bad, eye.surface(), (W, H), 64, false),
            Err(crate::Error::Scene(_))
        ));
    }

    #[test]
    fn hybrid_mask_restricts_the_eye_target_to_silhouette_pixels() {
        let scene = boxes_on_ground();
        let cam = overview_camera();
        let meshes = MeshCache::new(&scene);
        let mut eye = eye_pass(&scene, &meshes, &cam, W, H).unwrap();
        let (_, light) = lights()[0];
        let class = classify(&scene, &cam, &light, eye.surface(), (W, H), 512, false).unwrap();
        eye.target.keep_only(&class.silhouette).unwrap();
        let (tx, ty) = eye.target.tile_counts();
        let mut live = 0;
        for y in 0..ty {
            for x in 0..tx {
                live += u32::from(eye.target.tile_bounds(x, y).is_some());
            }
        }
        let written = (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .filter(|&(x, y)| eye.target.depth_at(x, y).is_some())
            .count() as u64;
        println!(
            "computation mask: {written} pixels, {live} of {} tiles keep depth",
            tx * ty
        );
        assert_eq!(written, class.silhouette_pixels);
        assert!(live < tx * ty / 2);
    }
}
