//! Shadow-volume construction for one caster [EK "Shadow Volume Extrusion",
//! Steiner §4.1].
//!
//! Side quads from the silhouette edges, the light cap (the casting triangles)
//! and the dark cap (the same projected to infinity, reversed) where the method
//! needs caps. Extrusion is to infinity with `w = 0`: for a point or spot light
//! each vertex `v` goes to `(v − l, 0)` in local space (the direction from the
//! light through the vertex); for a directional light every vertex goes to the
//! one point at infinity `(d, 0)`, `d` the light's travel direction in local
//! space, so sides are triangles and there is no dark cap.
//!
//! Winding: outward-facing, as in [EK] — every triangle is counter-clockwise
//! seen from outside the volume in world space. The light cap keeps the casting
//! triangles' light-facing winding; a silhouette edge `a → b` (the way the
//! casting triangles traverse it) gives the side quad `(b, a, a∞, b∞)`.
//!
//! # Finite extrusion (ranged point and spot lights)
//!
//! With [`LocalLight::Point`]`{ finite_range: Some(R), .. }` (from
//! [`LocalLight::finite`], the option `BuildOptions::finite_extrusion`) a
//! volume may stop at distance `D` from the light instead of going to
//! infinity: every extruded vertex is the finite point
//! `l + D·(v − l)/|v − l|` (`w = 1`), with
//!
//! `D = max(R / cos α, (1 + 2⁻¹⁰)·max_v |v − l|)`,
//!
//! `α` the largest angle between the light directions `u_i = (v_i − l)/|v_i − l|`
//! of two vertices of one casting (light-cap) triangle and the maximum over
//! the cap vertices; all in world space and world units (the range is a world
//! distance; transforms may scale), the extruded world point then mapped to
//! local space. One `D` per caster, so neighbouring triangles share their
//! extruded vertices and the volume stays closed. A caster with
//! `cos α ≤ 0` (`α ≥ 90°`) extrudes to infinity as without the option. A
//! finitely extruded volume always has its dark cap (the far triangles
//! `l + D·u_i`, reversed), zpass included: a finite segment can now leave the
//! volume through it.
//!
//! Why `D` suffices: take a casting triangle `T` with vertices `v_i` and its far
//! triangle `F` with vertices `l + D·u_i`. Every ray from `l` through `T` has
//! direction `Σ μ_i u_i` (`μ_i ≥ 0`, `Σ μ_i = 1`) and meets `F` at
//! `l + D·Σ μ_i u_i`, at distance `D·|Σ μ_i u_i|` from the light, and
//! `|Σ μ_i u_i|² = Σ_ij μ_i μ_j (u_i·u_j) ≥ cos α · (Σ μ_i)² = cos α` since
//! every `u_i·u_j ≥ cos α > 0`. So `F` lies at distance at least
//! `D·√cos α ≥ D·cos α ≥ R` along every such ray (the bound is per ray, not
//! the distance of `F`'s plane: for an obtuse `T` that plane can come much
//! nearer). `F` also lies beyond `T` on every ray: along direction `x` the two
//! planes are met at parameters `1/(a_T·x)` and `1/(a_F·x)`, and
//! `a_T·x > a_F·x` holds at the three `u_i` (`|v_i − l| < D`), hence, being
//! linear, on their whole cone. The truncated prism between `T` and `F`
//! (its sides are planar: `v_i, v_j, l` span them) therefore holds exactly the
//! points of `T`'s infinite shadow within distance `R` of the light, plus
//! some beyond `R`; the caster's finite volume is the sum of these prisms as
//! the infinite one is of the infinite shadows, so for every point within
//! range the two count alike (and every point beyond the range is unlit
//! whatever the stencil says). The `2⁻¹⁰` keeps the far cap clear of the
//! caster after rounding to f32; the f32 rounding of the far vertices
//! themselves (relative 2⁻²⁴ of their local coordinates) is not covered when
//! `cos α` is within that of 1, i.e. for points within that distance of the
//! range sphere.

use crate::silhouette::Silhouette;
use glam::{DMat4, DVec3, Vec3};
use raster::{VolumeBuffer, VolumeMethod, VolumeRange};
use scene::Light;

/// The light as seen from one caster's local space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LocalLight {
    /// Point or spot light: world position, and `local_from_world` to map
    /// extrusion directions into local space.
    Point {
        /// World position of the light.
        position: DVec3,
        /// Inverse of the caster's `world_from_local`.
        local_from_world: DMat4,
        /// `Some(R)`: extrude finitely for a light of range `R` (world units)
        /// where the caster allows it (see the module docs); `None`: to infinity.
        finite_range: Option<f64>,
    },
    /// Directional light: unit travel direction in local space.
    Directional(DVec3),
}

impl LocalLight {
    /// The light relative to a caster placed by `world_from_local` (f64);
    /// volumes extrude to infinity.
    pub fn new(light: &Light, world_from_local: &DMat4) -> Self {
        let local_from_world = world_from_local.inverse();
        match *light {
            Light::Point { position, .. } | Light::Spot { position, .. } => LocalLight::Point {
                position,
                local_from_world,
                finite_range: None,
            },
            Light::Directional { direction } => {
                LocalLight::Directional(local_from_world.transform_vector3(direction).normalize())
            }
        }
    }

    /// As [`LocalLight::new`], but a point or spot light with a range extrudes
    /// finitely where the caster allows it (module docs, "Finite extrusion").
    /// Lights without a range and directional lights are as with `new`.
    pub fn finite(light: &Light, world_from_local: &DMat4) -> Self {
        let mut l = Self::new(light, world_from_local);
        if let (
            LocalLight::Point { finite_range, .. },
            Light::Point { range, .. } | Light::Spot { range, .. },
        ) = (&mut l, light)
        {
            *finite_range = *range;
        }
        l
    }
}

/// The finite extrusion distance `D` of a caster (module docs, "Finite
/// extrusion"): `None` when it must extrude to infinity (no cap, `α ≥ 90°`, or
/// `D` not finite). `dir(v)` is the world-space vector `v − l` of mesh vertex `v`.
fn extrusion_distance(
    caps: &[[u32; 3]],
    range: f64,
    mut dir: impl FnMut(u32) -> DVec3,
) -> Option<f64> {
    let mut cos_min = f64::INFINITY;
    let mut far = 0.0f64;
    for c in caps {
        let d = c.map(&mut dir);
        let len = d.map(DVec3::length);
        far = far.max(len[0]).max(len[1]).max(len[2]);
        let u = [d[0] / len[0], d[1] / len[1], d[2] / len[2]];
        cos_min = cos_min
            .min(u[0].dot(u[1]))
            .min(u[1].dot(u[2]))
            .min(u[2].dot(u[0]));
    }
    // NaN (a vertex at the light) fails this test too.
    if cos_min.is_nan() || cos_min <= 0.0 {
        return None;
    }
    let d = (range / cos_min).max((1.0 + 2f64.powi(-10)) * far);
    d.is_finite().then_some(d)
}

/// Counts of one appended volume.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VolumeCounts {
    /// Side triangles (2 per quad, 1 per directional-light side).
    pub side_triangles: usize,
    /// Light-cap plus dark-cap triangles.
    pub cap_triangles: usize,
    /// The volume was extruded finitely (module docs, "Finite extrusion").
    pub finite: bool,
}

/// Reusable scratch for [`append_volume`]: vertex remapping tables.
#[derive(Clone, Debug, Default)]
pub struct VolumeScratch {
    finite: Vec<u32>,
    infinite: Vec<u32>,
}

/// One share of the parallel volume build (`build.rs`): its buffer and
/// scratch, kept between frames.
#[derive(Clone, Debug, Default)]
#[cfg_attr(not(feature = "parallel"), allow(dead_code))]
pub(crate) struct BuildPart {
    pub buffer: VolumeBuffer,
    pub scratch: VolumeScratch,
}

/// How extruded vertices are placed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Extrusion {
    /// Directions `w = 0`.
    Infinite,
    /// Finite points at this world distance from the light.
    Finite(f64),
}

const UNSET: u32 = u32::MAX;

/// One caster as [`append_volume`] reads it.
#[derive(Clone, Copy)]
pub struct CasterGeometry<'a> {
    /// The caster's object id (the range's `object`).
    pub object: u32,
    /// The caster mesh's welded local positions.
    pub positions: &'a [Vec3],
    /// The caster's transform.
    pub world_from_local: &'a DMat4,
    /// The caster's silhouette for the light.
    pub silhouette: &'a Silhouette,
}

/// Appends the volume of one caster to `out` as one range (segment 0, full
/// scissor and depth bounds).
///
/// Caps are emitted for [`VolumeMethod::ZFail`] and [`VolumeMethod::ZpPlus`]
/// (the dark cap only for positional lights); [`VolumeMethod::ZPass`] gets
/// sides only — plus the dark cap when the volume is extruded finitely (a
/// `light` from [`LocalLight::finite`]; module docs, "Finite extrusion").
pub fn append_volume(
    out: &mut VolumeBuffer,
    scratch: &mut VolumeScratch,
    caster: CasterGeometry<'_>,
    light: &LocalLight,
    method: VolumeMethod,
) -> VolumeCounts {
    let CasterGeometry {
        object,
        positions,
        world_from_local,
        silhouette,
    } = caster;
    let first_vertex = out.positions.len() as u32;
    let first_index = out.indices.len() as u32;
    scratch.finite.clear();
    scratch.finite.resize(positions.len(), UNSET);
    scratch.infinite.clear();
    scratch.infinite.resize(positions.len(), UNSET);
    let extrusion = match *light {
        LocalLight::Point {
            position,
            finite_range: Some(range),
            ..
        } => extrusion_distance(&silhouette.caps, range, |v| {
            scene::transform::world_point(world_from_local, positions[v as usize]) - position
        })
        .map_or(Extrusion::Infinite, Extrusion::Finite),
        _ => Extrusion::Infinite,
    };
    let mut emit = Emitter {
        out,
        scratch,
        positions,
        world_from_local,
        light,
        extrusion,
        directional_slot: UNSET,
    };
    let caps = method != VolumeMethod::ZPass;
    let mut counts = VolumeCounts {
        finite: extrusion != Extrusion::Infinite,
        ..VolumeCounts::default()
    };
    let light_start = emit.out.indices.len() as u32;
    if caps {
        for c in &silhouette.caps {
            let t = c.map(|v| emit.finite(v));
            emit.out.indices.extend_from_slice(&t);
        }
        counts.cap_triangles += silhouette.caps.len();
    }
    let light_cap = light_start..emit.out.indices.len() as u32;
    let dark_start = emit.out.indices.len() as u32;
    if (caps || counts.finite) && matches!(light, LocalLight::Point { .. }) {
        for c in &silhouette.caps {
            let [a, b, c] = c.map(|v| emit.infinite(v));
            emit.out.indices.extend_from_slice(&[a, c, b]);
        }
        counts.cap_triangles += silhouette.caps.len();
    }
    let dark_cap = dark_start..emit.out.indices.len() as u32;
    for e in &silhouette.edges {
        let (a, b) = (emit.finite(e.from), emit.finite(e.to));
        let (ai, bi) = (emit.infinite(e.from), emit.infinite(e.to));
        for _ in 0..e.multiplicity {
            if matches!(light, LocalLight::Directional(_)) {
                emit.out.indices.extend_from_slice(&[b, a, ai]);
                counts.side_triangles += 1;
            } else {
                emit.out.indices.extend_from_slice(&[b, a, ai, b, ai, bi]);
                counts.side_triangles += 2;
            }
        }
    }
    let out = emit.out;
    out.ranges.push(VolumeRange {
        object: object.into(),
        segment: 0,
        world_from_local: *world_from_local,
        method,
        first_vertex,
        vertex_count: out.positions.len() as u32 - first_vertex,
        first_index,
        index_count: out.indices.len() as u32 - first_index,
        light_cap,
        dark_cap,
        depth_near: 1.0,
        depth_far: 0.0,
        scissor: VolumeRange::FULL_SCISSOR,
        band: VolumeRange::FULL_SCISSOR,
        planes: [None, None],
    });
    counts
}

struct Emitter<'a> {
    out: &'a mut VolumeBuffer,
    scratch: &'a mut VolumeScratch,
    positions: &'a [Vec3],
    world_from_local: &'a DMat4,
    light: &'a LocalLight,
    extrusion: Extrusion,
    directional_slot: u32,
}

impl Emitter<'_> {
    fn push(&mut self, p: [f32; 4]) -> u32 {
        self.out.positions.push(p);
        self.out.positions.len() as u32 - 1
    }

    /// The vertex itself, `w = 1` (the eye pass's own f32 vertex).
    fn finite(&mut self, v: u32) -> u32 {
        let slot = self.scratch.finite[v as usize];
        if slot != UNSET {
            return slot;
        }
        let p = self.positions[v as usize];
        let s = self.push([p.x, p.y, p.z, 1.0]);
        self.scratch.finite[v as usize] = s;
        s
    }

    /// The vertex extruded: to infinity (`w = 0`), or with a finite
    /// extrusion to the point at distance `D` from the light (`w = 1`).
    fn infinite(&mut self, v: u32) -> u32 {
        match *self.light {
            LocalLight::Directional(d) => {
                if self.directional_slot == UNSET {
                    let d = d.as_vec3();
                    self.directional_slot = self.push([d.x, d.y, d.z, 0.0]);
                }
                self.directional_slot
            }
            LocalLight::Point {
                position,
                local_from_world,
                ..
            } => {
                let slot = self.scratch.infinite[v as usize];
                if slot != UNSET {
                    return slot;
                }
                // Direction light → vertex formed in world space from the same
                // f64 world point the facing rule used, then mapped to local space.
                let world = scene::transform::world_point(
                    self.world_from_local,
                    self.positions[v as usize],
                );
                if let Extrusion::Finite(dist) = self.extrusion {
                    let u = (world - position).normalize_or_zero();
                    let p = local_from_world
                        .transform_point3(position + u * dist)
                        .as_vec3();
                    let s = self.push([p.x, p.y, p.z, 1.0]);
                    self.scratch.infinite[v as usize] = s;
                    return s;
                }
                let d = local_from_world
                    .transform_vector3(world - position)
                    .normalize_or_zero()
                    .as_vec3();
                // A casting vertex at the light is reachable only through
                // rounding of degenerate (hostile) transforms: it extrudes to
                // the zero vector, which clipping drops.
                let s = self.push([d.x, d.y, d.z, 0.0]);
                self.scratch.infinite[v as usize] = s;
                s
            }
        }
    }
}
