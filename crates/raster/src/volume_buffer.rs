//! The shadow-volume buffer: the seam between volume construction (filled by
//! `shadowgen`) and the stencil pass (this crate, or a GPU host), DESIGN.md
//! "Seams for host renderers".
//!
//! Positions are homogeneous and stay in each caster's local space: finite
//! vertices are the caster's own f32 vertices with `w = 1` (bit-identical to
//! what the eye pass draws, so a light cap has the depth of the surface it
//! caps), extruded vertices are points at infinity with `w = 0` (or, for a
//! finitely extruded volume of a ranged light, finite points with `w = 1`). Every range
//! carries the `world_from_local` its vertices are drawn with through the one
//! transform path (`clip_from_local`).
//!
//! Winding: every volume triangle is counter-clockwise seen from *outside* the
//! volume once its vertices are mapped to world space by the range's
//! `world_from_local` (mirrored instances are already accounted for), so a
//! front-facing volume triangle is an entry into the volume for the eye.

use glam::DMat4;
use std::ops::Range;

/// Stencil counting rule of one volume range [EK "Zpass vs Zfail", Steiner §3.2.1].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum VolumeMethod {
    /// Count volume faces in front of the visible surface; sides only (no caps
    /// needed). Only correct when the volume misses the near rectangle.
    #[default]
    ZPass,
    /// Count volume faces behind the visible surface; needs the closed volume
    /// (light cap, sides and, for point lights, the dark cap).
    ZFail,
    /// zpass on the near-clipped closed volume with the near-plane cross-section
    /// filled by winding number; needs the closed volume, whose caps the range names.
    ZpPlus,
}

/// One caster's (and segment's) volume inside a [`VolumeBuffer`].
///
/// Growth rule: fields are only added (the clamping fields to come), never
/// renamed or removed within a major version; hosts read it, only shadowgen
/// builds it.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeRange {
    /// The caster's object id (scene's `ObjectId`, its `to_bits`).
    pub object: u64,
    /// Segment of the caster's volume; 0 until clamping produces segments.
    pub segment: u32,
    /// The transform the range's local-space positions are drawn with (f64,
    /// composed into `clip_from_local` by the one transform path).
    pub world_from_local: DMat4,
    /// Counting rule for this range.
    pub method: VolumeMethod,
    /// First vertex of the range in [`VolumeBuffer::positions`].
    pub first_vertex: u32,
    /// Number of vertices the range owns (`first_vertex..first_vertex + vertex_count`);
    /// its indices name only these.
    pub vertex_count: u32,
    /// First entry of the range in [`VolumeBuffer::indices`] (a multiple of 3).
    pub first_index: u32,
    /// Number of index entries (3 per triangle): light cap, dark cap, sides, in that order.
    pub index_count: u32,
    /// Absolute range in [`VolumeBuffer::indices`] of the light cap (the
    /// caster's light-facing triangles, finite vertices); empty for zpass.
    pub light_cap: Range<u32>,
    /// Absolute range in [`VolumeBuffer::indices`] of the dark cap (the light
    /// cap projected to infinity, reversed, or to the finite extrusion distance
    /// of a ranged light); empty for an infinitely extruded zpass volume and
    /// for directional lights (their extrusion meets in one point at infinity).
    /// A finitely extruded volume always has its dark cap, zpass included.
    pub dark_cap: Range<u32>,
    /// Depth-bounds test, reversed Z (`depth_near ≥ depth_far`): a pixel whose
    /// stored surface depth lies outside `[depth_far, depth_near]` has its surface
    /// point outside the volume (within the scene bounds), so the volume cannot
    /// change its stencil and may skip it. 1.0 when unbounded (the near plane).
    pub depth_near: f32,
    /// Farthest depth of the depth-bounds test; 0.0 when unbounded (infinity).
    pub depth_far: f32,
    /// Scissor rectangle `[x0, y0, x1, y1)` in pixels, row 0 at the top: pixels
    /// outside it have their surface point outside the volume and may be
    /// skipped; never inverted, empty (`x0 = x1`) when no visible surface can
    /// be inside. [`VolumeRange::FULL_SCISSOR`] when unbounded (the consumer
    /// clamps it to its viewport).
    pub scissor: [u32; 4],
    /// Band `[x0, y0, x1, y1)` in pixels, row 0 at the top: the only pixels
    /// the range may be drawn at, whatever the stencil tests. A caster's
    /// volume drawn once per eye-slice band its receivers occupy counts,
    /// inside each band, exactly as the whole volume does, and nothing
    /// outside them (`shadowgen`'s `bands.rs`); a consumer must apply it as
    /// a scissor. [`VolumeRange::FULL_SCISSOR`] when unbanded.
    pub band: [u32; 4],
    /// Clamped volumes [Steiner §4.4.3]: the segment's bounding planes in
    /// world space as `[a, b, c, d]`, `a·x + b·y + c·z + d = 0`, `(a, b, c)`
    /// a unit normal towards greater light depth. The near plane is `None` for
    /// segment 0 (it starts at the caster's own light cap), the far plane
    /// `None` for a volume that extrudes to infinity (or to the finite
    /// extrusion distance). `[None, None]` for an unclamped volume.
    pub planes: [Option<[f64; 4]>; 2],
}

impl VolumeRange {
    /// The scissor rectangle that covers any viewport.
    pub const FULL_SCISSOR: [u32; 4] = [0, 0, u32::MAX, u32::MAX];

    /// Index range of the whole volume in [`VolumeBuffer::indices`].
    pub fn indices(&self) -> Range<usize> {
        self.first_index as usize..(self.first_index + self.index_count) as usize
    }

    /// Number of triangles of the volume.
    pub fn triangle_count(&self) -> usize {
        self.index_count as usize / 3
    }
}

/// Shadow-volume geometry for one light and frame, as a GPU host could draw it.
///
/// Callers own and reuse it: [`VolumeBuffer::clear`] keeps the allocations.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeBuffer {
    /// Homogeneous local-space positions `[x, y, z, w]`, `w ∈ {0, 1}`.
    pub positions: Vec<[f32; 4]>,
    /// Triangle list, three absolute indices into [`VolumeBuffer::positions`] each.
    pub indices: Vec<u32>,
    /// One range per caster and segment, in the order they were built.
    pub ranges: Vec<VolumeRange>,
}

/// Reserves `v` at twice its length when less than a quarter of its capacity
/// is free (see [`VolumeBuffer::reserve_headroom`]).
pub(crate) fn headroom<T>(v: &mut Vec<T>) {
    if 4 * v.len() > 3 * v.capacity() {
        v.reserve(v.len());
    }
}

impl VolumeBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Empties the buffer, keeping its allocations.
    pub fn clear(&mut self) {
        self.positions.clear();
        self.indices.clear();
        self.ranges.clear();
    }

    /// Keeps a quarter of every list's capacity free, reserving twice its
    /// length when less is: called after each frame's build, the next frames
    /// (which draw about as many volumes) fill the buffer without allocating
    /// until one needs a third more than any frame before.
    pub fn reserve_headroom(&mut self) {
        headroom(&mut self.positions);
        headroom(&mut self.indices);
        headroom(&mut self.ranges);
    }

    /// Total number of volume triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The triangle `t` (absolute) as three homogeneous positions.
    ///
    /// # Panics
    /// If `t` is out of range.
    pub fn triangle(&self, t: usize) -> [[f32; 4]; 3] {
        std::array::from_fn(|k| self.positions[self.indices[3 * t + k] as usize])
    }

    /// Checks the buffer's internal consistency: every range's indices lie within
    /// its own vertices, caps lie within the range, counts are multiples of 3,
    /// depth bounds are ordered and scissors not inverted. Returns a message
    /// naming the first violation.
    ///
    /// # Errors
    /// A description of the first inconsistency found.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !self.indices.len().is_multiple_of(3) {
            return Err("index count is not a multiple of 3".into());
        }
        for (i, r) in self.ranges.iter().enumerate() {
            let idx = r.indices();
            if idx.end > self.indices.len() || r.index_count % 3 != 0 || r.first_index % 3 != 0 {
                return Err(format!("range {i}: bad index range {idx:?}"));
            }
            let verts = r.first_vertex..r.first_vertex + r.vertex_count;
            if verts.end as usize > self.positions.len() {
                return Err(format!("range {i}: bad vertex range {verts:?}"));
            }
            if let Some(bad) = self.indices[idx.clone()]
                .iter()
                .find(|v| !verts.contains(v))
            {
                return Err(format!("range {i}: index {bad} outside {verts:?}"));
            }
            for (name, cap) in [("light_cap", &r.light_cap), ("dark_cap", &r.dark_cap)] {
                let inside = cap.start as usize >= idx.start && cap.end as usize <= idx.end;
                if cap.start > cap.end || !inside || (cap.end - cap.start) % 3 != 0 {
                    return Err(format!("range {i}: {name} {cap:?} outside {idx:?}"));
                }
            }
            if r.depth_near < r.depth_far || !(0.0..=1.0).contains(&r.depth_far) {
                return Err(format!("range {i}: inverted depth bounds"));
            }
            if r.scissor[0] > r.scissor[2] || r.scissor[1] > r.scissor[3] {
                return Err(format!("range {i}: inverted scissor"));
            }
            if r.band[0] > r.band[2] || r.band[1] > r.band[3] {
                return Err(format!("range {i}: inverted band"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_buffer_is_consistent() {
        let mut b = VolumeBuffer::new();
        assert_eq!(b.triangle_count(), 0);
        assert!(b.check().is_ok());
        b.positions.push([0.0, 0.0, 0.0, 1.0]);
        b.indices.extend([0, 0, 0]);
        b.ranges.push(VolumeRange {
            object: 0,
            segment: 0,
            world_from_local: DMat4::IDENTITY,
            method: VolumeMethod::ZFail,
            first_vertex: 0,
            vertex_count: 1,
            first_index: 0,
            index_count: 3,
            light_cap: 0..3,
            dark_cap: 3..3,
            depth_near: 1.0,
            depth_far: 0.0,
            scissor: VolumeRange::FULL_SCISSOR,
            band: VolumeRange::FULL_SCISSOR,
            planes: [None, None],
        });
        assert!(b.check().is_ok());
        b.ranges[0].dark_cap = 3..6;
        assert!(b.check().is_err());
        b.clear();
        assert!(b.ranges.is_empty());
    }
}
