//! Segmented shadow volumes [Steiner §4.4.3, Listing 4.4, A.4]: a caster's
//! volume cut to the depth intervals where receivers may be
//! ([`crate::occupied_intervals`]), one closed volume per interval.
//!
//! # Geometry
//! Depth is measured along a [`SegmentAxis`]: for a point or spot light, the
//! distance from the light along the unit axis from the light towards the
//! caster; for a directional light, the distance along its travel direction.
//! The planes of constant depth bound the segments. A casting (light-cap)
//! vertex `v` projects onto the plane of depth `P` along its light ray:
//! `l + (v − l)·P/depth(v)` for a point light (all caster vertices have
//! positive depth: [`SegmentAxis::new`] refuses a caster the light's plane
//! cuts), `v + d·(P − depth(v))` for a directional one.
//!
//! Each casting triangle's shadow is the prism of light rays beyond it; the
//! unclamped volume is their sum [EK]. Between two planes beyond the caster,
//! the prism is bounded by the triangle projected onto each plane and by the
//! planes through the light and each edge, so segment `k ≥ 1` over `[a, b]`
//! is: near cap (the light cap projected onto `a`, light-facing winding), far
//! cap (projected onto `b`, reversed), and per silhouette edge `p → q` the
//! side quad `(q_a, p_a, p_b, q_b)`: the unclamped side quad's plane, cut.
//! Segment 0 starts at the caster and keeps the real light cap, as an
//! unclamped volume does; its far cap closes it (zpass included, as with
//! finite extrusion). Inside its slab a segment counts exactly as the
//! unclamped volume does; outside every slab it counts nothing.
//!
//! # Margins
//! Interval ends come from receiver bounds, and a receiver's face can lie
//! exactly on one. A cap there would meet the surface within the rounding of
//! f32 vertices and eye depths, so each interval is widened by
//! `2⁻¹⁰·(|P| + size)` at both ends (`size` the caster's bounding diagonal)
//! before segments are built, and intervals that then overlap are merged.

use crate::bounds::{corner, round_down, round_up};
use crate::volume::CasterGeometry;
use crate::EyeSlices;
use glam::{DMat4, DVec3};
use raster::{VolumeBuffer, VolumeMethod, VolumeRange};
use scene::{Aabb, Light, ObjectId};

/// The depth axis of one caster's segments, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentAxis {
    /// Depth 0: the light's position (point and spot lights) or the caster's
    /// centre (directional lights).
    pub origin: DVec3,
    /// Unit direction of increasing depth.
    pub axis: DVec3,
    /// Whether projection goes through `origin` (a positional light) or along
    /// `axis` (a directional one).
    pub positional: bool,
    /// The caster's bounding diagonal, for the margins.
    pub size: f64,
}

/// Relative margin of the segment planes (module docs, "Margins").
pub const SEGMENT_MARGIN: f64 = 1.0 / 1024.0;

impl SegmentAxis {
    /// The axis for a caster with world bounds `caster`: `None` when the
    /// caster cannot be segmented (a positional light on or inside the
    /// caster's box, or within `SEGMENT_MARGIN` of its plane, or non-finite
    /// geometry).
    pub fn new(light: &Light, caster: &Aabb) -> Option<SegmentAxis> {
        if caster.is_empty() {
            return None;
        }
        let (lo, hi) = (caster.min.as_dvec3(), caster.max.as_dvec3());
        let centre = (lo + hi) * 0.5;
        let size = (hi - lo).length();
        let s = match *light {
            Light::Directional { direction } => SegmentAxis {
                origin: centre,
                axis: direction.normalize(),
                positional: false,
                size,
            },
            Light::Point { position, .. } | Light::Spot { position, .. } => SegmentAxis {
                origin: position,
                axis: (centre - position).normalize(),
                positional: true,
                size,
            },
        };
        if !(s.axis.is_finite() && s.origin.is_finite() && size.is_finite()) {
            return None;
        }
        let [near, _] = s.box_depths(caster);
        (!s.positional || near > SEGMENT_MARGIN * size).then_some(s)
    }

    /// Depth of world point `p`.
    pub fn depth(&self, p: DVec3) -> f64 {
        self.axis.dot(p - self.origin)
    }

    /// The depth interval of world box `b` (its corners' extremes).
    pub fn box_depths(&self, b: &Aabb) -> [f64; 2] {
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        // The axis's sign per coordinate picks the nearest and farthest corner.
        let near = DVec3::select(self.axis.cmpge(DVec3::ZERO), lo, hi);
        let far = DVec3::select(self.axis.cmpge(DVec3::ZERO), hi, lo);
        [self.depth(near), self.depth(far)]
    }

    /// World point `v` moved along its light ray to depth `plane`.
    pub fn project(&self, v: DVec3, plane: f64) -> DVec3 {
        if self.positional {
            self.origin + (v - self.origin) * (plane / self.depth(v))
        } else {
            v + self.axis * (plane - self.depth(v))
        }
    }

    /// The world bounds of the segment between `near` (`None`: the caster's
    /// own bounds `caster`) and depth `far`: the caster's corners projected
    /// onto both planes. For a positional light every caster corner has
    /// positive depth ([`Self::new`]), so the projections bound the light's
    /// rays through the caster between the planes.
    pub fn segment_bounds(&self, caster: &Aabb, near: Option<f64>, far: f64) -> Aabb {
        let (lo, hi) = (caster.min.as_dvec3(), caster.max.as_dvec3());
        let mut b = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let mut add = |p: DVec3| b = (b.0.min(p), b.1.max(p));
        for k in 0..8 {
            let c = corner(lo, hi, k);
            match near {
                None => add(c),
                Some(n) => add(self.project(c, n)),
            }
            add(self.project(c, far));
        }
        // f32 bounds rounded outward.
        Aabb {
            min: b.0.to_array().map(round_down).into(),
            max: b.1.to_array().map(round_up).into(),
        }
    }

    /// The world plane `(n, d)` (`n·x + d = 0`, `n` pointing to greater
    /// depth) of depth `plane`.
    pub fn plane(&self, plane: f64) -> [f64; 4] {
        let d = -(self.axis.dot(self.origin) + plane);
        [self.axis.x, self.axis.y, self.axis.z, d]
    }

    /// `intervals` (sorted, disjoint; the first starting at the caster)
    /// widened by the margins and merged where they then meet.
    pub fn widened(&self, intervals: &[[f64; 2]], out: &mut Vec<[f64; 2]>) {
        out.clear();
        let pad = |p: f64| SEGMENT_MARGIN * (p.abs() + self.size);
        for (k, &[a, b]) in intervals.iter().enumerate() {
            // Segment 0 starts at the caster itself: no plane there.
            let a = if k == 0 { a } else { a - pad(a) };
            let b = b + pad(b);
            match out.last_mut() {
                Some(last) if a <= last[1] => last[1] = last[1].max(b),
                _ => out.push([a, b]),
            }
        }
    }
}

/// Where each caster's volume is clamped [Steiner §4.4]: its depth axis and
/// its occupied intervals, widened by the margins (continuous clamping), or
/// its eye slices and occupied slices (discrete clamping). Casters without
/// an entry are built unclamped. Filled per light and frame by the clamping
/// stage, read by [`crate::build_clamped_volumes`].
#[derive(Clone, Debug, Default)]
pub struct ClampPlan {
    /// Per caster slot: how it is cut (`None`: unclamped) and its
    /// intervals. Cleared entries keep their lists' allocations, so a
    /// steady frame's plan allocates nothing.
    entries: Vec<(Option<Frame>, Vec<[f64; 2]>)>,
    /// The slots with an entry.
    set: Vec<u32>,
    widened: Vec<[f64; 2]>,
}

/// What an entry's intervals are measured along.
#[derive(Clone, Copy, Debug)]
enum Frame {
    Axis(SegmentAxis),
    Eye(EyeSlices),
}

/// How one caster's segments are cut: planes of constant depth along an
/// axis, or the eye's slicing planes.
#[derive(Clone, Copy, Debug)]
pub(crate) enum SegmentFrame<'a> {
    Axis(&'a SegmentAxis),
    Eye(&'a EyeSlices),
}

impl SegmentFrame<'_> {
    fn project(&self, v: DVec3, plane: f64) -> DVec3 {
        match self {
            SegmentFrame::Axis(a) => a.project(v, plane),
            SegmentFrame::Eye(e) => e.project(v, plane),
        }
    }

    fn plane(&self, plane: f64) -> [f64; 4] {
        match self {
            SegmentFrame::Axis(a) => a.plane(plane),
            SegmentFrame::Eye(e) => e.plane(plane),
        }
    }
}

impl ClampPlan {
    /// An empty plan: every caster unclamped.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets every entry.
    pub fn clear(&mut self) {
        for &slot in &self.set {
            self.entries[slot as usize].0 = None;
        }
        self.set.clear();
    }

    /// `caster`'s entry, made when missing, to be filled as `frame`.
    fn entry(&mut self, caster: ObjectId, frame: Frame) -> &mut Vec<[f64; 2]> {
        let slot = caster.index();
        if self.entries.len() <= slot {
            self.entries.resize_with(slot + 1, Default::default);
        }
        let e = &mut self.entries[slot];
        if e.0.is_none() {
            self.set.push(caster.slot());
        }
        e.0 = Some(frame);
        &mut e.1
    }

    /// Removes `caster`'s entry.
    fn unset(&mut self, caster: ObjectId) {
        if let Some(e) = self.entries.get_mut(caster.index()) {
            if e.0.take().is_some() {
                self.set.retain(|&s| s != caster.slot());
            }
        }
    }

    fn entry_of(&self, caster: ObjectId) -> Option<(&Frame, &[[f64; 2]])> {
        match self.entries.get(caster.index())? {
            (Some(f), i) => Some((f, i.as_slice())),
            (None, _) => None,
        }
    }

    /// Clamps `caster` along `axis` to `intervals` (sorted and disjoint, the
    /// first starting at or before the caster's nearest depth; see
    /// [`crate::occupied_intervals`]), widened by the margins. An empty list
    /// removes the entry.
    pub fn set(&mut self, caster: ObjectId, axis: SegmentAxis, intervals: &[[f64; 2]]) {
        if intervals.is_empty() {
            self.unset(caster);
            return;
        }
        let mut widened = std::mem::take(&mut self.widened);
        axis.widened(intervals, &mut widened);
        self.entry(caster, Frame::Axis(axis)).clone_from(&widened);
        self.widened = widened;
    }

    /// Clamps `caster` to `intervals` of `slices`' `g` (oriented for the
    /// caster, [`EyeSlices::for_caster`]; sorted and disjoint, the first
    /// starting at or before the caster's least `g`, every other end a
    /// plane every ray of the caster reaches; the last may end at `+∞`:
    /// that segment extrudes to infinity). No margins: the boundaries are
    /// edge-on for the eye. An empty list removes the entry.
    pub fn set_sliced(&mut self, caster: ObjectId, slices: EyeSlices, intervals: &[[f64; 2]]) {
        if intervals.is_empty() {
            self.unset(caster);
            return;
        }
        let e = self.entry(caster, Frame::Eye(slices));
        e.clear();
        e.extend_from_slice(intervals);
    }

    /// The axis and widened intervals of `caster`, if continuous clamping
    /// clamps it.
    pub fn get(&self, caster: ObjectId) -> Option<(&SegmentAxis, &[[f64; 2]])> {
        match self.entry_of(caster)? {
            (Frame::Axis(a), i) => Some((a, i)),
            _ => None,
        }
    }

    /// The oriented slices and intervals of `caster`, if discrete clamping
    /// clamps it.
    pub fn get_sliced(&self, caster: ObjectId) -> Option<(&EyeSlices, &[[f64; 2]])> {
        match self.entry_of(caster)? {
            (Frame::Eye(e), i) => Some((e, i)),
            _ => None,
        }
    }

    /// How `caster` is cut and where, if it is clamped.
    pub(crate) fn frame(&self, caster: ObjectId) -> Option<(SegmentFrame<'_>, &[[f64; 2]])> {
        let (f, i) = self.entry_of(caster)?;
        let f = match f {
            Frame::Axis(a) => SegmentFrame::Axis(a),
            Frame::Eye(e) => SegmentFrame::Eye(e),
        };
        Some((f, i))
    }

    /// Number of clamped casters.
    pub fn len(&self) -> usize {
        self.set.len()
    }

    /// True when no caster is clamped.
    pub fn is_empty(&self) -> bool {
        self.set.is_empty()
    }
}

/// Counts of [`append_segments`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SegmentCounts {
    /// Segments appended (ranges).
    pub segments: usize,
    /// Triangles appended.
    pub triangles: usize,
}

/// Reusable scratch of [`append_segments`]: per mesh vertex, its slot on the
/// current plane.
#[derive(Clone, Debug, Default)]
pub struct SegmentScratch {
    near: Vec<u32>,
    far: Vec<u32>,
}

const UNSET: u32 = u32::MAX;

/// Appends `caster`'s segments over `intervals` (after
/// [`SegmentAxis::widened`] or from discrete clamping; `g` values of
/// `frame`, sorted and disjoint, the first starting at or before the
/// caster's least `g`; the last may end at `+∞`) to `out`, one range per
/// interval numbered `0..k` in [`VolumeRange::segment`], each with its
/// planes and the method `method(segment, near, far)` chooses.
///
/// A segment ending at `+∞` (beyond a plane some light ray never reaches)
/// extrudes to infinity from its near cap as an unclamped volume does
/// (`volume.rs`): sides to `w = 0`, and for a positional light a dark cap
/// unless the method is zpass.
pub(crate) fn append_segments(
    out: &mut VolumeBuffer,
    scratch: &mut SegmentScratch,
    caster: CasterGeometry<'_>,
    frame: SegmentFrame<'_>,
    light: &Light,
    intervals: &[[f64; 2]],
    mut method: impl FnMut(u32, f64, f64) -> VolumeMethod,
) -> SegmentCounts {
    let CasterGeometry {
        object,
        positions,
        world_from_local,
        silhouette,
    } = caster;
    let local_from_world = world_from_local.inverse();
    let world = |v: u32| scene::transform::world_point(world_from_local, positions[v as usize]);
    // Extrusion to infinity: the local direction of each vertex's light ray.
    let to_infinity = |v: u32| -> [f32; 4] {
        let d = match *light {
            Light::Directional { direction } => direction,
            Light::Point { position, .. } | Light::Spot { position, .. } => world(v) - position,
        };
        let d = local_from_world.transform_vector3(d).as_vec3();
        [d.x, d.y, d.z, 0.0]
    };
    let mut counts = SegmentCounts::default();
    for (k, &[near, far]) in intervals.iter().enumerate() {
        let k = k as u32;
        let method = method(k, near, far);
        let infinite = far == f64::INFINITY;
        let first_vertex = out.positions.len() as u32;
        let first_index = out.indices.len() as u32;
        for table in [&mut scratch.near, &mut scratch.far] {
            table.clear();
            table.resize(positions.len(), UNSET);
        }
        // Segment 0's near end is the caster (the light cap itself).
        let near_plane = (k > 0).then_some(near);
        let slot = |out: &mut VolumeBuffer, table: &mut Vec<u32>, v: u32, plane: Option<f64>| {
            let s = &mut table[v as usize];
            if *s == UNSET {
                let p = match plane {
                    None => positions[v as usize],
                    Some(p) => to_local(&local_from_world, frame.project(world(v), p)),
                };
                out.positions.push([p.x, p.y, p.z, 1.0]);
                *s = out.positions.len() as u32 - 1;
            }
            *s
        };
        // A directional light's rays meet in one point at infinity: one
        // vertex for all, so that the sides close on it.
        let mut directional_slot = UNSET;
        let mut far_slot = |out: &mut VolumeBuffer, table: &mut Vec<u32>, v: u32| {
            if !infinite {
                return slot(out, table, v, Some(far));
            }
            let s = match light {
                Light::Directional { .. } => &mut directional_slot,
                _ => &mut table[v as usize],
            };
            if *s == UNSET {
                out.positions.push(to_infinity(v));
                *s = out.positions.len() as u32 - 1;
            }
            *s
        };
        let light_start = out.indices.len() as u32;
        if k > 0 || method != VolumeMethod::ZPass {
            for c in &silhouette.caps {
                let t = c.map(|v| slot(out, &mut scratch.near, v, near_plane));
                out.indices.extend_from_slice(&t);
            }
        }
        let light_cap = light_start..out.indices.len() as u32;
        let dark = !infinite || (light.position().is_some() && method != VolumeMethod::ZPass);
        if dark {
            for c in &silhouette.caps {
                let [a, b, c] = c.map(|v| far_slot(out, &mut scratch.far, v));
                out.indices.extend_from_slice(&[a, c, b]);
            }
        }
        let dark_cap = light_cap.end..out.indices.len() as u32;
        for e in &silhouette.edges {
            let (a, b) = (
                slot(out, &mut scratch.near, e.from, near_plane),
                slot(out, &mut scratch.near, e.to, near_plane),
            );
            let (af, bf) = (
                far_slot(out, &mut scratch.far, e.from),
                far_slot(out, &mut scratch.far, e.to),
            );
            for _ in 0..e.multiplicity {
                if infinite && light.position().is_none() {
                    // One point at infinity: the side is a triangle.
                    out.indices.extend_from_slice(&[b, a, af]);
                } else {
                    out.indices.extend_from_slice(&[b, a, af, b, af, bf]);
                }
            }
        }
        let index_count = out.indices.len() as u32 - first_index;
        counts.segments += 1;
        counts.triangles += index_count as usize / 3;
        out.ranges.push(VolumeRange {
            object: object.into(),
            segment: k,
            world_from_local: *world_from_local,
            method,
            first_vertex,
            vertex_count: out.positions.len() as u32 - first_vertex,
            first_index,
            index_count,
            light_cap,
            dark_cap,
            depth_near: 1.0,
            depth_far: 0.0,
            scissor: VolumeRange::FULL_SCISSOR,
            band: VolumeRange::FULL_SCISSOR,
            planes: [
                near_plane.map(|p| frame.plane(p)),
                (!infinite).then(|| frame.plane(far)),
            ],
        });
    }
    counts
}

fn to_local(local_from_world: &DMat4, p: DVec3) -> glam::Vec3 {
    local_from_world.transform_point3(p).as_vec3()
}
