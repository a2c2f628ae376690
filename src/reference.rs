//! The exact shadow reference: per pixel, the visible surface point and a
//! shadow ray to the light, through an obvhs BVH over every scene triangle.
//!
//! Every culling, clamping and stencil variant is measured against this.
//!
//! # Precision
//! The BVH is built in f32 coordinates relative to the centre of the scene
//! bounds (converted from the f64 world positions of the one transform path,
//! boxes rounded outward and padded by 2⁻¹⁶ of the scene extent so f32 ray
//! traversal never misses a triangle it should test); every ray–triangle test
//! is done in f64 on centre-relative positions formed from the f64 world
//! positions, so a scene 1e6 from the origin behaves as one at the origin.
//! Facing and the unlit rule use the world positions themselves, exactly as
//! the volume code does.
//!
//! # Which triangles block
//! A triangle blocks a shadow ray only if it faces the light under the shared
//! facing rule ([`scene::faces_light`]) — exactly the triangles shadow volumes
//! are built from. With [`ReferenceOptions::two_sided`] every triangle blocks.
//!
//! # Epsilon rule (self-shadow and ambiguity)
//! Let `d` be the view depth of the surface point `p` (distance along the
//! camera's forward axis) and `δ = max(4·ε_z·d, 2⁻²⁰·d)`, ε_z the
//! rasterizer's relative depth-error bound ([`ReferenceOptions::depth_error`]).
//! - The shadow ray from a point `q` ignores the surface's own triangle and
//!   every hit nearer than `δ` (self-shadow), and — when `q` lies behind the
//!   surface's plane — every hit before the ray has crossed that plane plus `δ`
//!   (what lies behind the visible surface cannot shadow it). The ambiguity
//!   probes below classify as if the surface were at the probe point: only
//!   its own triangle and hits nearer than `δ` are ignored there.
//! - A pixel is *ambiguous* when one of these holds (ambiguous pixels are
//!   excluded from comparisons and counted):
//!   - along the eye ray, the class at `p ± w·e` differs from `p`'s (e the unit eye-ray direction), with the
//!     window `w = δ`, widened to twice the distance between `p` and the
//!     rasterized surface when the eye buffer's depth is given: coplanar
//!     casters, grazing light, a light in a face's plane, points on a shadow
//!     edge within the depth error;
//!   - across the screen, the class differs at the points of the surface's
//!     plane seen through the pixel centre moved by ±[`SNAP_PROBE_PX`] in x or y: the rasterizer
//!     snaps every vertex to 1/256 pixel, moving each projected edge and each
//!     interpolated plane by up to half of that sideways (an error ε_z does not
//!     cover: on a grazing surface it is many δ along the ray);
//!   - the eye ray crosses a plane through an edge of the
//!     visible triangle along the light direction within `w` of `p` — a
//!     terminator under grazing light, where the surface and a side of its own
//!     shadow volume nearly coincide and the rasterizer's order of the two
//!     decides the count (the reference never lets a triangle shadow itself,
//!     so its class cannot show this).
//!
//! Both δ terms scale with depth, so the rule is the same at scene scales
//! 1e-3 and 1e3 and at coordinates of 1e5 and 1e6.

use crate::mask::{is_unlit, ClassCounts, Mask, PixelClass};
use crate::{Error, Result};
use glam::{DVec3, Vec3A};
use obvhs::{bvh2::Bvh2, ray::Ray};
use rayon::prelude::*;
use scene::{faces_light, Camera, Light, ObjectId, Scene};

/// Screen-space reach of the sideways ambiguity probes, pixels: twice the
/// rasterizer's largest vertex-snapping displacement (half of its 1/256-pixel grid).
pub const SNAP_PROBE_PX: f64 = 1.0 / 256.0;

/// Default relative depth-error bound ε_z (a few f32 ulps) until a
/// rasterizer states its own; δ is then `2⁻²⁰·d`.
pub const DEFAULT_DEPTH_ERROR: f64 = 1.0 / (1u64 << 22) as f64;

/// Options of the reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReferenceOptions {
    /// Every triangle casts (both sides), not only light-facing ones.
    pub two_sided: bool,
    /// The rasterizer's relative depth-error bound ε_z.
    pub depth_error: f64,
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        ReferenceOptions {
            two_sided: false,
            depth_error: DEFAULT_DEPTH_ERROR,
        }
    }
}

pub use crate::surface::{EyeSurface, PrimitiveId};

/// Most triangles per cluster of the reference BVH's build.
const CLUSTER: usize = 4;

/// How far a cluster's box may outgrow its triangles' boxes: at most this
/// many times their summed half-areas ([`push_clusters`]). A building's
/// opposite faces (the city's boxes) stay one cluster; triangles from
/// opposite ends of a mesh do not.
const CLUSTER_SPREAD: f32 = 4.0;

/// All scene triangles in a BVH, for ray casting.
pub struct TriangleBvh {
    bvh: Bvh2,
    /// World-space f64 vertices (from [`Scene::world_triangle`]), indexed by primitive.
    tris: Vec<[DVec3; 3]>,
    ids: Vec<PrimitiveId>,
    /// Per object the index of its first triangle, then the triangle count.
    firsts: Vec<u32>,
    /// Per primitive, its object's flags.
    flags: Vec<scene::ObjectFlags>,
    center: DVec3,
    pad: f32,
}

impl std::fmt::Debug for TriangleBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleBvh")
            .field("triangles", &self.tris.len())
            .finish()
    }
}

impl TriangleBvh {
    /// Builds the BVH over every triangle of every object.
    pub fn new(scene: &Scene) -> Self {
        let center = scene.bounds().center();
        let extent = if scene.bounds().is_empty() {
            1.0
        } else {
            scene.bounds().size().max_element().max(1e-30)
        };
        let pad = extent * (1.0 / 65536.0);
        // Exact capacities: grown by doubling, the f64 triangles alone
        // would reserve up to twice their 72 bytes per triangle.
        let total: usize = (0..scene.objects().len())
            .map(|oi| {
                scene
                    .object_mesh(ObjectId::from_slot(oi as u32))
                    .triangles()
                    .len()
            })
            .sum();
        let mut tris = Vec::with_capacity(total);
        let mut ids = Vec::with_capacity(total);
        let mut flags = Vec::with_capacity(total);
        for (oi, o) in scene.objects().iter().enumerate() {
            let id = ObjectId::from_slot(oi as u32);
            let n = scene.object_mesh(id).triangles().len();
            for t in 0..n {
                tris.push(scene.world_triangle(id, t));
                ids.push((id, t as u32));
                flags.push(o.flags);
            }
        }
        // The tree is built over clusters of up to CLUSTER consecutive
        // triangles of one object, then expanded: a quarter of the build
        // scratch and of the nodes where clusters are full (the city's boxes).
        let mut starts = Vec::with_capacity(total.div_ceil(CLUSTER) + scene.objects().len() + 1);
        let mut boxes = Vec::with_capacity(starts.capacity());
        let mut firsts = Vec::with_capacity(scene.objects().len() + 1);
        let mut first = 0u32;
        for oi in 0..scene.objects().len() {
            let n = scene
                .object_mesh(ObjectId::from_slot(oi as u32))
                .triangles()
                .len() as u32;
            firsts.push(first);
            let object = &tris[first as usize..(first + n) as usize];
            push_clusters(object, first, center, pad, &mut starts, &mut boxes);
            first += n;
        }
        starts.push(first);
        firsts.push(first);
        let params = obvhs::BvhBuildParams {
            // Leaves of at most two clusters: eight triangles, as before.
            max_prims_per_leaf: 2,
            ..obvhs::BvhBuildParams::fast_build()
        };
        let mut bvh = scene::bvh_build::build_bvh2(&boxes, params);
        drop(boxes);
        scene::bvh_build::expand_clusters(&mut bvh, &starts);
        TriangleBvh {
            bvh,
            tris,
            ids,
            firsts,
            flags,
            center,
            pad,
        }
    }

    /// Updates triangle positions after objects moved (same scene topology) and
    /// refits the BVH without rebuilding it.
    ///
    /// # Panics
    /// If the scene's triangle count changed since [`TriangleBvh::new`].
    pub fn refit(&mut self, scene: &Scene) {
        let mut k = 0;
        for (oi, o) in scene.objects().iter().enumerate() {
            let id = ObjectId::from_slot(oi as u32);
            for t in 0..scene.object_mesh(id).triangles().len() {
                self.tris[k] = scene.world_triangle(id, t);
                self.flags[k] = o.flags;
                k += 1;
            }
        }
        assert_eq!(
            k,
            self.tris.len(),
            "scene topology changed; rebuild the TriangleBvh"
        );
        for node in 0..self.bvh.nodes.len() {
            let n = self.bvh.nodes[node];
            if n.is_leaf() {
                let mut b = obvhs::aabb::Aabb::empty();
                for p in n.first_index..n.first_index + n.prim_count {
                    let prim = self.bvh.primitive_indices[p as usize] as usize;
                    b = b.union(&tri_box(&self.rel(prim), self.pad));
                }
                self.bvh.nodes[node].set_aabb(b);
            }
        }
        self.bvh.refit_all();
    }

    /// The triangle of primitive `id`, if the scene holds it.
    fn index_of(&self, (object, t): PrimitiveId) -> Option<usize> {
        let o = object.index();
        let (first, end) = (*self.firsts.get(o)?, *self.firsts.get(o + 1)?);
        (t < end - first).then_some((first + t) as usize)
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when the scene has no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Triangle `prim` relative to the centre.
    #[inline]
    fn rel(&self, prim: usize) -> [DVec3; 3] {
        let ([a, b, c], o) = (self.tris[prim], self.center);
        [a - o, b - o, c - o]
    }

    fn ray(&self, origin: DVec3, dir: DVec3, tmax: f64) -> Ray {
        let o = Vec3A::from(origin.as_vec3());
        let d = Vec3A::from(dir.as_vec3());
        let tmax = if tmax.is_finite() {
            (tmax * (1.0 + 1e-6)) as f32 + 4.0 * self.pad
        } else {
            f32::INFINITY
        };
        Ray::new(o, d, 0.0, tmax)
    }

    /// Nearest triangle along a (centre-relative) ray, both faces; ties at equal
    /// distance go to the smaller primitive id.
    fn closest_hit(&self, origin: DVec3, dir: DVec3) -> Option<(f64, usize)> {
        if self.tris.is_empty() {
            return None;
        }
        let mut best: Option<(f64, usize)> = None;
        let mut hit = obvhs::ray::RayHit::none();
        self.bvh
            .ray_traverse(self.ray(origin, dir, f64::INFINITY), &mut hit, |_, i| {
                let prim = self.bvh.primitive_indices[i] as usize;
                if !self.flags[prim].visible {
                    return f32::INFINITY;
                }
                match intersect(&self.rel(prim), origin, dir) {
                    Some(t) if t > 0.0 => {
                        let better = match best {
                            None => true,
                            Some((bt, bp)) => t < bt || (t == bt && self.ids[prim] < self.ids[bp]),
                        };
                        if better {
                            best = Some((t, prim));
                        }
                        // Keep equal-distance candidates reachable: report a slightly larger t.
                        (t * (1.0 + 1e-6)) as f32 + self.pad
                    }
                    _ => f32::INFINITY,
                }
            });
        best
    }

    /// True when some caster (`casters[prim]`: see [`caster_flags`]) blocks
    /// the centre-relative shadow ray.
    fn blocked(&self, ray: &ShadowRay, casters: &[bool]) -> bool {
        let ShadowRay {
            origin,
            dir,
            tmin,
            tmax,
            skip,
        } = *ray;
        !self
            .bvh
            .ray_traverse_miss(self.ray(origin, dir, tmax), |_, i| {
                let prim = self.bvh.primitive_indices[i] as usize;
                // Only casters count: light-facing triangles, or all when two-sided.
                if prim == skip || !casters[prim] {
                    return f32::INFINITY;
                }
                match intersect(&self.rel(prim), origin, dir) {
                    Some(t) if t > tmin && t < tmax => 0.0,
                    _ => f32::INFINITY,
                }
            })
    }
}

/// A shadow ray: centre-relative origin, unit direction, the open interval
/// `(tmin, tmax)` where hits count, and the surface triangle to skip.
#[derive(Clone, Copy)]
struct ShadowRay {
    origin: DVec3,
    dir: DVec3,
    tmin: f64,
    tmax: f64,
    skip: usize,
}

/// Cuts one object's triangles (`tris`, the first of them primitive `first`)
/// into clusters of up to [`CLUSTER`] consecutive triangles and pushes each
/// cluster's first primitive and its box (centre-relative, padded).
///
/// A cluster grows only while its box's half-area stays within
/// [`CLUSTER_SPREAD`] times the sum of its triangles' box half-areas.
/// Consecutive triangles are near each other in most meshes (the city's
/// boxes, scanned meshes), but not in all: a cluster of triangles from
/// opposite ends of a mesh has a box that most shadow rays enter, and its
/// leaf's triangles are tested by all of them (the shared jobs' reference
/// masks took 13 times as long with clusters cut by count alone; the
/// default city's are unchanged).
fn push_clusters(
    tris: &[[DVec3; 3]],
    first: u32,
    center: DVec3,
    pad: f32,
    starts: &mut Vec<u32>,
    boxes: &mut Vec<obvhs::aabb::Aabb>,
) {
    let tri = |k: usize| tri_box(&tris[k].map(|p| p - center), pad);
    let mut k = 0;
    while k < tris.len() {
        starts.push(first + k as u32);
        let mut cluster = tri(k);
        let mut areas = cluster.half_area();
        let end = (k + CLUSTER).min(tris.len());
        k += 1;
        while k < end {
            let next = tri(k);
            let joined = cluster.union(&next);
            if joined.half_area() > CLUSTER_SPREAD * (areas + next.half_area()) {
                break;
            }
            (cluster, areas) = (joined, areas + next.half_area());
            k += 1;
        }
        boxes.push(cluster);
    }
}

fn tri_box(t: &[DVec3; 3], pad: f32) -> obvhs::aabb::Aabb {
    let b = scene::Aabb::from_dpoints(t.iter().copied());
    obvhs::aabb::Aabb::new(
        Vec3A::from(b.min) - Vec3A::splat(pad),
        Vec3A::from(b.max) + Vec3A::splat(pad),
    )
}

/// Per triangle of `bvh`, whether it can block a shadow ray of `light`: its
/// object casts, and it faces the light ([`faces_light`]) or every triangle
/// casts (`two_sided`). Decided once per mask rather than at every hit.
fn caster_flags(bvh: &TriangleBvh, light: &Light, two_sided: bool) -> Result<Vec<bool>> {
    let mut casters = try_filled(bvh.tris.len(), false, "the reference's caster flags")?;
    casters.par_iter_mut().enumerate().for_each(|(k, c)| {
        *c = bvh.flags[k].casts && (two_sided || faces_light(&bvh.tris[k], light));
    });
    Ok(casters)
}

/// Ray–triangle distance in f64 (Möller–Trumbore), both faces, edges inclusive.
#[inline]
fn intersect(tri: &[DVec3; 3], o: DVec3, d: DVec3) -> Option<f64> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - tri[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// Per-class counts of a reference mask plus its ambiguous pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReferenceCounts {
    /// Pixels per class.
    pub classes: ClassCounts,
    /// Lit or shadow pixels whose class flips within ±δ along the eye ray.
    pub ambiguous: u64,
}

/// The reference's result for one view and one light.
#[derive(Clone, Debug)]
pub struct ReferenceMask {
    /// The four-class mask.
    pub mask: Mask,
    /// Per pixel: ambiguous (excluded from comparisons).
    pub ambiguous: Vec<bool>,
    /// Per pixel: the visible primitive, `None` for background.
    pub primitive: Vec<Option<PrimitiveId>>,
    /// Per pixel: cosine between the surface's visible-side normal and the
    /// direction to the light, clamped to `[0, 1]` (for shaded images).
    pub lambert: Vec<f32>,
    /// Counts.
    pub counts: ReferenceCounts,
}

/// Computes the exact shadow mask of `light` seen through `camera` at
/// `width × height` (pixel centres at +0.5, row 0 at the top).
///
/// The visible surface comes from `surface` when given (the eye pass's
/// primitive ids), else from primary rays through the same BVH.
///
/// # Panics
/// If `surface` has a size other than `width × height`, or names a primitive
/// that is not in the scene; when its buffers cannot be allocated (use
/// [`try_reference_mask`] where the viewport comes from a user).
pub fn reference_mask(
    bvh: &TriangleBvh,
    camera: &Camera,
    light: &Light,
    width: u32,
    height: u32,
    options: &ReferenceOptions,
    surface: Option<EyeSurface<'_>>,
) -> ReferenceMask {
    try_reference_mask(bvh, camera, light, width, height, options, surface)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A vector of `n` copies of `value`, or [`Error::OutOfMemory`] naming `what`.
fn try_filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what: what.to_string(),
        bytes: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    })?;
    v.resize(n, value);
    Ok(v)
}

/// [`reference_mask`], with an allocation failure of its per-pixel buffers
/// an [`Error::OutOfMemory`] instead of an abort.
///
/// # Errors
/// [`Error::OutOfMemory`] naming the buffer and its size.
///
/// # Panics
/// If `surface` has a size other than `width × height`, or names a primitive
/// that is not in the scene.
pub fn try_reference_mask(
    bvh: &TriangleBvh,
    camera: &Camera,
    light: &Light,
    width: u32,
    height: u32,
    options: &ReferenceOptions,
    surface: Option<EyeSurface<'_>>,
) -> Result<ReferenceMask> {
    let n = width as usize * height as usize;
    if let Some(s) = &surface {
        assert!(
            s.fits(width, height),
            "surface size differs from the viewport"
        );
    }
    let eye = camera.position - bvh.center;
    let forward = camera.forward();
    let light_rel = match *light {
        Light::Point { position, range } => Light::Point {
            position: position - bvh.center,
            range,
        },
        Light::Spot {
            position,
            direction,
            apex_angle,
            range,
        } => Light::Spot {
            position: position - bvh.center,
            direction,
            apex_angle,
            range,
        },
        Light::Directional { direction } => Light::Directional { direction },
    };
    let rays = camera.rays(width, height);
    // Every per-pixel buffer first, so that running out of memory is an
    // error before any work.
    let mut out: Vec<(PixelClass, bool, Option<PrimitiveId>, f32)> = try_filled(
        n,
        (PixelClass::Background, false, None, 0.0),
        "the reference's pixels",
    )?;
    let mut mask = Mask {
        width,
        height,
        pixels: try_filled(n, PixelClass::Background, "the reference mask")?,
    };
    let mut ambiguous = try_filled(n, false, "the reference's ambiguity flags")?;
    let mut primitive = try_filled(n, None, "the reference's primitive ids")?;
    let mut lambert = try_filled(n, 0.0, "the reference's cosines")?;
    let casters = caster_flags(bvh, light, options.two_sided)?;
    let shadow_rays = ShadowRays {
        bvh,
        casters: &casters,
        eye,
        light,
        light_rel: &light_rel,
        two_sided: options.two_sided,
    };
    out.par_chunks_mut(width.max(1) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let dir = rays.direction(x as f64 + 0.5, y as f64 + 0.5);
                let hit = match &surface {
                    Some(s) => s.primitive(x as u32, y as u32).map(|id| {
                        let k = bvh
                            .index_of(id)
                            .expect("surface names a primitive not in the scene");
                        let t = plane_distance(&bvh.rel(k), eye, dir);
                        (t, k)
                    }),
                    None => bvh.closest_hit(eye, dir),
                };
                let Some((t, k)) = hit else { continue };
                if !t.is_finite() {
                    continue;
                }
                let tri = bvh.rel(k);
                let p = eye + dir * t;
                let depth = (p - eye).dot(forward);
                let delta = (4.0 * options.depth_error * depth).max(depth / (1u64 << 20) as f64);
                // The rasterized surface's distance from `p` along the ray, when given.
                let buffer_error = surface
                    .as_ref()
                    .and_then(|s| s.depth(x as u32, y as u32))
                    .map_or(0.0, |z| {
                        let zb = f64::from(z);
                        // Reversed Z, infinite far plane: z = near / view depth.
                        let db = if zb > 0.0 {
                            camera.near / zb
                        } else {
                            f64::INFINITY
                        };
                        (db - depth).abs() / dir.dot(forward)
                    });
                let window = delta.max(2.0 * buffer_error);
                let classify_at =
                    |q: DVec3, behind_rule: bool| shadow_rays.classify(k, q, delta, behind_rule);
                let c = classify_at(p, true);
                // Probes ask what the class would be were the surface there: only
                // the surface's own triangle and hits within δ are ignored.
                let class_at = |q: DVec3| classify_at(q, false);
                let sideways = |dx: f64, dy: f64| {
                    let (px, py) = (x as f64 + 0.5 + dx, y as f64 + 0.5 + dy);
                    let d = rays.direction(px, py);
                    let t = plane_distance(&bvh.rel(k), eye, d);
                    t.is_finite() && class_at(eye + d * t) != c
                };
                let s = SNAP_PROBE_PX;
                let ambiguous = c.is_compared()
                    && (near_own_prism(&tri, eye, dir, t, window, &light_rel)
                        || class_at(p - dir * window) != c
                        || class_at(p + dir * window) != c
                        || sideways(s, 0.0)
                        || sideways(-s, 0.0)
                        || sideways(0.0, s)
                        || sideways(0.0, -s));
                let nrm = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
                let to_l = light_rel.toward_light(p).normalize_or_zero();
                let side = if nrm.dot(eye - p) >= 0.0 { nrm } else { -nrm };
                *px = (
                    c,
                    ambiguous,
                    Some(bvh.ids[k]),
                    side.dot(to_l).clamp(0.0, 1.0) as f32,
                );
            }
        });
    for (i, (c, a, p, l)) in out.into_iter().enumerate() {
        mask.pixels[i] = c;
        ambiguous[i] = a;
        primitive[i] = p;
        lambert[i] = l;
    }
    let counts = ReferenceCounts {
        classes: mask.counts(),
        ambiguous: ambiguous.iter().filter(|&&a| a).count() as u64,
    };
    Ok(ReferenceMask {
        mask,
        ambiguous,
        primitive,
        lambert,
        counts,
    })
}

/// Whether the eye ray `eye + t·dir` crosses the boundary of the visible
/// triangle's own shadow prism — a plane through one of its edges along the
/// light direction — within `window` of the surface point at `t_surface`.
///
/// There the surface and a side of its own shadow volume (present wherever that
/// edge is a silhouette edge) are within the depth error of each other, and
/// which one the rasterizer puts in front changes the stencil count by one; the
/// reference, which never lets a triangle shadow itself, cannot see it. Away
/// from grazing light the planes meet the surface steeply, so this flags only
/// pixel centres within a hair of an edge; under grazing light (the light
/// nearly in the surface's plane: the terminator) it flags the band where the
/// prism side and the surface are closer than the window.
fn near_own_prism(
    tri: &[DVec3; 3],
    eye: DVec3,
    dir: DVec3,
    t_surface: f64,
    window: f64,
    light_rel: &Light,
) -> bool {
    let p = eye + dir * t_surface;
    let to_light = light_rel.toward_light(p);
    (0..3).any(|i| {
        let (u, v) = (tri[i], tri[(i + 1) % 3]);
        let m = (v - u).cross(to_light);
        let den = m.dot(dir);
        if den == 0.0 || m == DVec3::ZERO {
            return false;
        }
        let t = m.dot(u - eye) / den;
        (t - t_surface).abs() <= window
    })
}

/// Distance along the ray to the triangle's plane (infinite when parallel).
fn plane_distance(tri: &[DVec3; 3], o: DVec3, d: DVec3) -> f64 {
    crate::surface::RayPlane::new(tri, o)
        .hit(d)
        .unwrap_or(f64::INFINITY)
}

/// What every shadow ray of one reference mask shares: the scene, the
/// triangles that can block the light, the eye and the light.
struct ShadowRays<'a> {
    bvh: &'a TriangleBvh,
    /// Per triangle of `bvh`, whether it can block a shadow ray ([`caster_flags`]).
    casters: &'a [bool],
    /// The eye, centre-relative (as the BVH's triangles are).
    eye: DVec3,
    /// The light in world space.
    light: &'a Light,
    /// The light moved by the same offset as `eye`.
    light_rel: &'a Light,
    /// Every triangle casts, not only light-facing ones.
    two_sided: bool,
}

impl ShadowRays<'_> {
    /// Class of surface point `q` (centre-relative) on triangle `k`; `delta` is
    /// the distance a shadow ray starts away from `q`; `behind_rule`: a point
    /// behind the visible side of its triangle is shadowed from where its ray
    /// leaves the triangle's plane.
    fn classify(&self, k: usize, q: DVec3, delta: f64, behind_rule: bool) -> PixelClass {
        let ShadowRays {
            bvh,
            casters,
            eye,
            light,
            light_rel,
            two_sided,
        } = *self;
        let c = bvh.center;
        if is_unlit(&bvh.tris[k], eye + c, light, q + c, two_sided) {
            return PixelClass::Unlit;
        }
        if !bvh.flags[k].receives {
            return PixelClass::Lit;
        }
        let tri = bvh.rel(k);
        let (dir, tmax) = match light_rel.position() {
            Some(l) => {
                let v = l - q;
                let len = v.length();
                if len == 0.0 {
                    return PixelClass::Lit;
                }
                (v / len, len)
            }
            None => (light_rel.toward_light(q).normalize(), f64::INFINITY),
        };
        // Where the shadow ray leaves the surface's plane (when q is behind it).
        let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let side_eye = n.dot(eye - tri[0]).signum();
        let behind = n.dot(q - tri[0]) * side_eye; // < 0: q behind the visible side
        let mut tmin = delta;
        if behind_rule && behind < 0.0 {
            let den = n.dot(dir);
            if den != 0.0 {
                let t_plane = n.dot(tri[0] - q) / den;
                if t_plane > 0.0 {
                    tmin = t_plane + delta;
                }
            }
        }
        if tmin >= tmax {
            return PixelClass::Lit;
        }
        let ray = ShadowRay {
            origin: q,
            dir,
            tmin,
            tmax,
            skip: k,
        };
        if bvh.blocked(&ray, casters) {
            PixelClass::Shadow
        } else {
            PixelClass::Lit
        }
    }
}

#[cfg(test)]
mod tests {
    /// The reference's buffers are allocated fallibly: a failed allocation
    /// is an error naming the buffer, not an abort.
    #[test]
    fn a_failed_allocation_is_an_error() {
        let e = super::try_filled(usize::MAX / 4, 0u64, "the reference's pixels").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("out of memory: the reference's pixels need"),
            "{e}"
        );
        assert_eq!(super::try_filled(2, 1u8, "x").unwrap(), [1, 1]);
    }

    /// An eye surface's primitive ids find their triangles (the object's
    /// first triangle plus the index); ids the scene does not hold find none.
    #[test]
    fn primitive_ids_find_their_triangles() {
        use scene::procedural::analytic;
        use scene::{ObjectId, Scene, SceneGraph, Transform};
        let mut g = SceneGraph::new();
        let ground = g.add_mesh(
            analytic::horizontal_quad("ground", [-5.0, 5.0], [-5.0, 5.0], 0.0, true).unwrap(),
        );
        let cube =
            g.add_mesh(analytic::box_mesh("box", glam::Vec3::ZERO, glam::Vec3::ONE).unwrap());
        g.add_instance("ground", ground, Transform::default());
        g.add_instance("a", cube, Transform::translation(glam::DVec3::Y));
        g.add_instance("b", cube, Transform::translation(glam::DVec3::X * 3.0));
        let scene = Scene::new(g).unwrap();
        let bvh = super::TriangleBvh::new(&scene);
        assert_eq!(bvh.len(), 2 + 12 + 12);
        for (k, &id) in bvh.ids.iter().enumerate() {
            assert_eq!(bvh.index_of(id), Some(k), "{id:?}");
        }
        assert_eq!(bvh.index_of((ObjectId::from_slot(1), 12)), None);
        assert_eq!(bvh.index_of((ObjectId::from_slot(3), 0)), None);
    }

    /// A box's twelve triangles make three full clusters (its faces come in
    /// opposite pairs); consecutive triangles far apart make one cluster
    /// each; every triangle is in exactly one cluster, in order.
    #[test]
    fn clusters_hold_triangles_that_lie_together() {
        use glam::DVec3;
        use scene::procedural::analytic;
        let clusters = |tris: &[[DVec3; 3]]| {
            let (mut starts, mut boxes) = (Vec::new(), Vec::new());
            super::push_clusters(tris, 7, DVec3::ZERO, 1e-4, &mut starts, &mut boxes);
            assert_eq!(starts.len(), boxes.len());
            assert!(starts.windows(2).all(|w| w[0] < w[1]) && starts[0] == 7);
            starts
        };
        let cube = analytic::box_mesh("box", glam::Vec3::ZERO, glam::Vec3::ONE).unwrap();
        let p = |i: u32| cube.positions()[i as usize].as_dvec3();
        let tris: Vec<[DVec3; 3]> = (cube.triangles().iter())
            .map(|t| [p(t[0]), p(t[1]), p(t[2])])
            .collect();
        assert_eq!(clusters(&tris), [7, 11, 15]);
        // Small triangles along a line 100 apart: one cluster each.
        let scattered: Vec<[DVec3; 3]> = (0..8)
            .map(|k| {
                let o = DVec3::X * (100.0 * f64::from(k));
                [o, o + DVec3::X, o + DVec3::Y]
            })
            .collect();
        assert_eq!(clusters(&scattered), (7..15).collect::<Vec<u32>>());
    }
}
