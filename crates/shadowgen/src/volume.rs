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
//! Not yet here: finite extrusion for ranged point lights (every volume extrudes
//! to infinity).

use crate::Silhouette;
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
    },
    /// Directional light: unit travel direction in local space.
    Directional(DVec3),
}

impl LocalLight {
    /// The light relative to a caster placed by `world_from_local` (f64).
    pub fn new(light: &Light, world_from_local: &DMat4) -> Self {
        let local_from_world = world_from_local.inverse();
        match *light {
            Light::Point { position, .. } | Light::Spot { position, .. } => LocalLight::Point {
                position,
                local_from_world,
            },
            Light::Directional { direction } => {
                LocalLight::Directional(local_from_world.transform_vector3(direction).normalize())
            }
        }
    }
}

/// Counts of one appended volume.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VolumeCounts {
    /// Side triangles (2 per quad, 1 per directional-light side).
    pub side_triangles: usize,
    /// Light-cap plus dark-cap triangles.
    pub cap_triangles: usize,
}

/// Reusable scratch for [`append_volume`]: vertex remapping tables.
#[derive(Clone, Debug, Default)]
pub struct VolumeScratch {
    finite: Vec<u32>,
    infinite: Vec<u32>,
}

const UNSET: u32 = u32::MAX;

/// Appends the volume of one caster to `out` as one range (segment 0, full
/// scissor and depth bounds).
///
/// `positions` are the caster mesh's welded local positions, `silhouette` its
/// silhouette for the light, `world_from_local` its transform. Caps are emitted
/// for [`VolumeMethod::ZFail`] and [`VolumeMethod::ZpPlus`] (the dark cap only
/// for positional lights); [`VolumeMethod::ZPass`] gets sides only.
#[allow(clippy::too_many_arguments)]
pub fn append_volume(
    out: &mut VolumeBuffer,
    scratch: &mut VolumeScratch,
    object: u32,
    positions: &[Vec3],
    world_from_local: &DMat4,
    silhouette: &Silhouette,
    light: &LocalLight,
    method: VolumeMethod,
) -> VolumeCounts {
    let first_vertex = out.positions.len() as u32;
    let first_index = out.indices.len() as u32;
    scratch.finite.clear();
    scratch.finite.resize(positions.len(), UNSET);
    scratch.infinite.clear();
    scratch.infinite.resize(positions.len(), UNSET);
    let mut emit = Emitter {
        out,
        scratch,
        positions,
        world_from_local,
        light,
        directional_slot: UNSET,
    };
    let caps = method != VolumeMethod::ZPass;
    let mut counts = VolumeCounts::default();
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
    if caps && matches!(light, LocalLight::Point { .. }) {
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
        object,
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
    });
    counts
}

struct Emitter<'a> {
    out: &'a mut VolumeBuffer,
    scratch: &'a mut VolumeScratch,
    positions: &'a [Vec3],
    world_from_local: &'a DMat4,
    light: &'a LocalLight,
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

    /// The vertex extruded to infinity, `w = 0`.
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
                let d = local_from_world
                    .transform_vector3(world - position)
                    .normalize_or_zero()
                    .as_vec3();
                debug_assert!(d != Vec3::ZERO, "a casting vertex coincides with the light");
                let s = self.push([d.x, d.y, d.z, 0.0]);
                self.scratch.infinite[v as usize] = s;
                s
            }
        }
    }
}
