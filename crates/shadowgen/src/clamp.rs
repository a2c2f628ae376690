//! Continuous clamping for one light [Steiner §4.4.1, Lloyd et al.]: which
//! receivers may lie in each caster's shadow (sweep-and-prune on the light's
//! image plane, kept across frames), and the occupied depth intervals that
//! follow, as a [`ClampPlan`] for [`crate::build_clamped_volumes`].
//!
//! # Image planes
//! A receiver point in caster C's shadow lies on a light ray through C, so
//! in any projection from the light the two share an image point. The image
//! planes are fixed by the light alone, so the sweep state stays valid while
//! the light is static, whatever the camera does:
//! - a directional light: the orthographic plane across its direction;
//! - a point or spot light: the six cube faces around it (+X, −X, +Y, −Y, +Z,
//!   −Z). A box takes part in a face when it may meet the face's pyramid; its
//!   rectangle is its corners' projection cut to the face's square, or the
//!   whole square when the face's plane through the light cuts the box. A
//!   shadow ray lies in some face's pyramid, and there both boxes' rectangles
//!   hold its image point, so the pairs of all faces together miss none.
//!
//! A caster the light is on or in ([`SegmentAxis::new`] refuses it) stays
//! unclamped.

use crate::bounds::{corner, round_down, round_up};
use crate::{occupied_intervals, ClampPlan, GapArea, GapCost, Result, SegmentAxis, SweepPrune};
use crate::{EyeSlices, ImageRect, SapStats};
use glam::DVec3;
use scene::{Aabb, Light, ObjectId, Scene};

/// Counters of one [`LightClamp::plan`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ClampStats {
    /// Overlapping pairs over the image planes (a pair seen in two cube
    /// faces counts twice).
    pub sap_pairs: u64,
    /// Endpoint swaps of the sweeps.
    pub sap_swaps: u64,
    /// Whether the sweeps were skipped (light, receivers and every
    /// object's bounds unchanged since the last plan).
    pub cached: bool,
    /// Casters whose raw intervals came from an earlier plan.
    pub cached_casters: u32,
    /// Sweeps that sorted from scratch.
    pub sap_rebuilds: u32,
    /// Casters the plan clamps.
    pub clamped: u32,
    /// Occupied intervals over the clamped casters (segments before widening).
    pub intervals: u64,
}

/// The per-light state of continuous clamping: one [`SweepPrune`] per image
/// plane, and the light it was built for. Keep one per light across frames.
#[derive(Clone, Debug, Default)]
pub struct LightClamp {
    light: Option<Light>,
    planes: Vec<SweepPrune>,
    rects: Vec<Option<ImageRect>>,
    /// Per object: the stamp of the last caster whose receivers it was
    /// counted for; `stamp` is the last one handed out.
    seen: Vec<u32>,
    stamp: u32,
    depths: Vec<[f64; 2]>,
    intervals: Vec<[f64; 2]>,
    /// What the sweeps last saw, to skip them while nothing moved.
    key: Option<CacheKey>,
    /// Per caster slot: its axis and raw occupied intervals (no gap merged:
    /// the cost model's areas depend on the view), valid while `key` holds
    /// (`None`: not found yet). Forgotten entries keep their lists'
    /// allocations.
    raw: Vec<(Option<SegmentAxis>, Vec<[f64; 2]>)>,
    /// This frame's casters that are not receivers, sorted (swapped into
    /// the key when it changes).
    other_casters: Vec<ObjectId>,
    /// Per object: a caster of this frame (the sweeps' scratch).
    is_caster: Vec<bool>,
}

/// What the sweeps and the raw intervals depend on: the light, the receiver
/// set, the casters that are not receivers (the swept boxes are the
/// receivers and the casters: a caster that receives is swept anyway, so a
/// changing caster set among receivers, as the PSC of a culled frame, keeps
/// the cache) and every object's world bounds.
#[derive(Clone, Debug, PartialEq)]
struct CacheKey {
    light: Light,
    receives: Vec<bool>,
    other_casters: Vec<ObjectId>,
    bounds: Vec<Aabb>,
}

/// What [`LightClamp::plan`] reads.
pub struct ClampInput<'a> {
    /// The scene (world bounds of every object).
    pub scene: &'a Scene,
    /// The light.
    pub light: &'a Light,
    /// The casters to clamp.
    pub casters: &'a [ObjectId],
    /// Per object id: whether it receives (the receiver model's set).
    pub receives: &'a [bool],
    /// The gap cost model; `None` keeps every gap open.
    pub cost: Option<&'a dyn GapModel>,
}

/// Per caster, the depths along its [`SegmentAxis`] where receivers may lie
/// in its shadow, found by the caller: the fragment receivers of the light
/// pass [Steiner Fig. 4.16] (`visibility::FragmentDepths`).
pub trait ReceiverDepths {
    /// `caster`'s receiver depth intervals along `SegmentAxis::new(light,
    /// bounds)`, or `None` when the caller has none for it (it stays
    /// unclamped).
    fn depths(&self, caster: ObjectId) -> Option<&[[f64; 2]]>;
}

/// What the gap cost model [Steiner eqs. 4.2–4.3] needs from the renderer.
pub trait GapModel {
    /// The cost constants and vertex counts of `caster`'s segments.
    fn cost(&self, caster: ObjectId) -> GapCost;
    /// An estimate of the pixels the volume of the caster bounded by `bounds`
    /// covers between depths `near` and `far` along `axis`.
    fn area(&self, bounds: &Aabb, axis: &SegmentAxis, near: f64, far: f64) -> f64;
}

impl LightClamp {
    /// An empty state.
    pub fn new() -> Self {
        Self::default()
    }

    /// Fills `plan` (cleared first) with the occupied intervals of every
    /// caster of `input` that has an axis, from the receivers whose image
    /// rectangles overlap it in some image plane.
    ///
    /// # Errors
    /// [`crate::Error::TooManyBoxes`] past [`crate::MAX_BOX_ID`] objects.
    pub fn plan(&mut self, input: &ClampInput<'_>, plan: &mut ClampPlan) -> Result<ClampStats> {
        plan.clear();
        let ClampInput {
            scene,
            light,
            casters,
            receives,
            cost,
        } = *input;
        let objects = scene.objects();
        let receiving = |c: &ObjectId| receives.get(c.index()).copied().unwrap_or(false);
        let mut other_casters = std::mem::take(&mut self.other_casters);
        other_casters.clear();
        other_casters.extend(casters.iter().copied().filter(|c| !receiving(c)));
        other_casters.sort_unstable();
        let same_geometry = self.key.as_ref().is_some_and(|k| {
            k.light == *light
                && k.receives.len() == receives.len()
                && k.bounds.len() == objects.len()
                && k.bounds
                    .iter()
                    .zip(objects)
                    .all(|(b, o)| *b == o.world_bounds)
        });
        let unchanged = same_geometry
            && self
                .key
                .as_ref()
                .is_some_and(|k| k.receives == receives && k.other_casters == other_casters);
        let mut stats = ClampStats {
            cached: unchanged,
            ..ClampStats::default()
        };
        if !unchanged {
            // With the light and every box where they were, only the casters
            // that pair with an object whose receiver flag or part in the
            // sweeps changed (before or after the sweep) see other receivers:
            // they and those objects lose their raw intervals. Anything else
            // (a light or a box moved) drops them all.
            let changed = match (&self.key, same_geometry) {
                (Some(k), true) => changed_objects(k, receives, &other_casters),
                _ => Vec::new(),
            };
            self.forget_pairs_of(&changed);
            self.sweep(input, &mut stats)?;
            if same_geometry {
                self.forget_pairs_of(&changed);
            } else {
                self.raw.iter_mut().for_each(|r| r.0 = None);
            }
            // The key, updated in place (its lists keep their allocations).
            let key = self.key.get_or_insert_with(|| CacheKey {
                light: *light,
                receives: Vec::new(),
                other_casters: Vec::new(),
                bounds: Vec::new(),
            });
            key.light = *light;
            key.receives.clear();
            key.receives.extend_from_slice(receives);
            std::mem::swap(&mut key.other_casters, &mut other_casters);
            key.bounds.clear();
            key.bounds.extend(objects.iter().map(|o| o.world_bounds));
        }
        self.other_casters = other_casters;
        if self.raw.len() < objects.len() {
            self.raw.resize_with(objects.len(), Default::default);
        }
        for &c in casters {
            let Some(bounds) = objects.get(c.index()).map(|o| o.world_bounds) else {
                continue;
            };
            if self.raw[c.index()].0.is_some() {
                stats.cached_casters += 1;
            } else {
                let Some(axis) = SegmentAxis::new(light, &bounds) else {
                    continue;
                };
                let mut raw = std::mem::take(&mut self.raw[c.index()].1);
                self.raw_intervals(input, c, &axis, &bounds, &mut raw);
                self.raw[c.index()] = (Some(axis), raw);
            }
            let (Some(axis), raw) = &self.raw[c.index()] else {
                continue;
            };
            let [first, rest @ ..] = raw.as_slice() else {
                continue;
            };
            // The gap model, every frame (its areas are the view's).
            let model = cost.map(|m| (m.cost(c), m));
            let area = |a: f64, b: f64| model.map_or(0.0, |(_, m)| m.area(&bounds, axis, a, b));
            let area: GapArea<'_> = &area;
            occupied_intervals(
                *first,
                rest.iter().copied(),
                model.as_ref().map(|(m, _)| (m, area)),
                &mut self.intervals,
            );
            stats.clamped += 1;
            stats.intervals += self.intervals.len() as u64;
            plan.set(c, *axis, &self.intervals);
        }
        Ok(stats)
    }

    /// [`LightClamp::plan`] with the receivers' depths given per caster by
    /// `depths` instead of found from receiver objects: no sweep, nothing
    /// cached (fragment receivers change with the view). A caster with an
    /// axis and an entry in `depths` is clamped to the occupied intervals of
    /// its own depths and those entries ([`crate::occupied_intervals`], with
    /// `input.cost`); any other stays unclamped. `input.receives` is not
    /// read.
    pub fn plan_from_depths(
        &mut self,
        input: &ClampInput<'_>,
        depths: &dyn ReceiverDepths,
        plan: &mut ClampPlan,
    ) -> ClampStats {
        plan.clear();
        let mut stats = ClampStats::default();
        for (c, bounds, found) in with_depths(input, depths) {
            let Some(axis) = SegmentAxis::new(input.light, &bounds) else {
                continue;
            };
            let model = input.cost.map(|m| (m.cost(c), m));
            let area = |a: f64, b: f64| model.map_or(0.0, |(_, m)| m.area(&bounds, &axis, a, b));
            let area: GapArea<'_> = &area;
            occupied_intervals(
                axis.box_depths(&bounds),
                found.iter().copied(),
                model.as_ref().map(|(m, _)| (m, area)),
                &mut self.intervals,
            );
            stats.clamped += 1;
            stats.intervals += self.intervals.len() as u64;
            plan.set(c, axis, &self.intervals);
        }
        stats
    }

    /// Discrete clamping [Steiner §4.4.2, Listing 4.3]: fills `plan`
    /// (cleared first) with `slices` and, per caster of `input` that lies in
    /// front of the eye and has an entry in `depths` (its receivers' `g`
    /// ranges, see [`EyeSlices`]), the slices its receivers occupy and the
    /// slices of its own box, merged where they touch. Every gap is kept: a
    /// segment's caps are edge-on and cost no fill. From the first interval
    /// end some ray of the caster's box does not reach, its segment
    /// extrudes to infinity (from the last plane every ray reaches, `+∞`
    /// far end); a caster whose first interval is such stays unclamped, as
    /// does any other. `input.receives` and `input.cost` are not read.
    pub fn plan_sliced(
        &mut self,
        input: &ClampInput<'_>,
        slices: &EyeSlices,
        depths: &dyn ReceiverDepths,
        plan: &mut ClampPlan,
    ) -> ClampStats {
        plan.clear();
        let mut stats = ClampStats::default();
        for (c, bounds, found) in with_depths(input, depths) {
            // Oriented so that g grows along the caster's rays; `depths`
            // counts in the base orientation.
            let Some(slices) = slices.for_caster(&bounds) else {
                continue;
            };
            let oriented = |r: [f64; 2]| {
                let r = if slices.flip() {
                    slices.from_other(r)
                } else {
                    r
                };
                slices.widened(r)
            };
            let own = slices.box_range(&bounds);
            let first = match slices.widened(own) {
                Some([_, hi]) => [own[0], hi.max(own[1])],
                None => own,
            };
            occupied_intervals(
                first,
                found.iter().filter_map(|&r| oriented(r)),
                None,
                &mut self.intervals,
            );
            let iv = &mut self.intervals;
            if let Some(k) = iv
                .iter()
                .position(|&[_, b]| !slices.box_reaches(&bounds, b))
            {
                // The segment from the last plane every ray reaches goes on
                // to infinity.
                let j = if k > 0 && slices.box_reaches(&bounds, iv[k][0]) {
                    k
                } else {
                    k.saturating_sub(1)
                };
                if j == 0 {
                    continue;
                }
                iv.truncate(j + 1);
                iv[j][1] = f64::INFINITY;
            }
            stats.clamped += 1;
            stats.intervals += iv.len() as u64;
            plan.set_sliced(c, slices, iv);
        }
        stats
    }

    /// Drops the raw intervals of `objects` and of every box the sweeps
    /// pair them with.
    fn forget_pairs_of(&mut self, objects: &[u32]) {
        let raw = &mut self.raw;
        let mut forget = |k: u32| {
            if let Some(r) = raw.get_mut(k as usize) {
                r.0 = None;
            }
        };
        for &d in objects {
            forget(d);
            for sap in &self.planes {
                for &c in sap.neighbours(d) {
                    forget(c);
                }
            }
        }
    }

    /// Caster `c`'s raw occupied intervals along `axis` from the receivers
    /// the sweeps pair it with (each counted once: a fresh stamp marks them).
    fn raw_intervals(
        &mut self,
        input: &ClampInput<'_>,
        c: ObjectId,
        axis: &SegmentAxis,
        bounds: &Aabb,
        raw: &mut Vec<[f64; 2]>,
    ) {
        let objects = input.scene.objects();
        self.seen.resize(objects.len(), 0);
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.seen.iter_mut().for_each(|s| *s = 0);
            self.stamp = 1;
        }
        let stamp = self.stamp;
        self.depths.clear();
        for sap in &self.planes {
            for &r in sap.neighbours(c.slot()) {
                let seen = &mut self.seen[r as usize];
                if *seen != stamp && input.receives.get(r as usize).copied().unwrap_or(false) {
                    *seen = stamp;
                    self.depths
                        .push(axis.box_depths(&objects[r as usize].world_bounds));
                }
            }
        }
        occupied_intervals(
            axis.box_depths(bounds),
            self.depths.iter().copied(),
            None,
            raw,
        );
    }

    /// The sweeps on every image plane.
    fn sweep(&mut self, input: &ClampInput<'_>, stats: &mut ClampStats) -> Result<()> {
        let ClampInput {
            scene,
            light,
            casters,
            receives,
            ..
        } = *input;
        let n = scene.objects().len();
        if self.light.as_ref() != Some(light) {
            // A moved light moves every box: keep the states (the sweeps
            // handle motion); a different kind of light needs other planes.
            let same_kind = self
                .light
                .as_ref()
                .is_some_and(|l| l.position().is_some() == light.position().is_some());
            if !same_kind {
                self.planes.clear();
            }
            self.light = Some(*light);
        }
        let faces = if light.position().is_some() { 6 } else { 1 };
        self.planes.resize_with(faces, SweepPrune::new);
        let objects = scene.objects();
        let is_caster = &mut self.is_caster;
        is_caster.clear();
        is_caster.resize(n, false);
        for c in casters {
            if let Some(f) = is_caster.get_mut(c.index()) {
                *f = true;
            }
        }
        for (face, sap) in self.planes.iter_mut().enumerate() {
            self.rects.clear();
            self.rects.extend((0..n).map(|k| {
                let part = is_caster[k] || receives.get(k).copied().unwrap_or(false);
                part.then(|| face_rect(light, face, &objects[k].world_bounds))
                    .flatten()
            }));
            let s: SapStats = sap.update(&self.rects)?;
            stats.sap_pairs += s.pairs;
            stats.sap_swaps += s.swaps;
            stats.sap_rebuilds += u32::from(s.rebuilt);
        }
        Ok(())
    }
}

/// The casters of `input` that `depths` has an entry for, with their world
/// bounds and that entry.
fn with_depths<'a>(
    input: &'a ClampInput<'_>,
    depths: &'a dyn ReceiverDepths,
) -> impl Iterator<Item = (ObjectId, Aabb, &'a [[f64; 2]])> + 'a {
    let objects = input.scene.objects();
    (input.casters.iter()).filter_map(move |&c| {
        let bounds = objects.get(c.index())?.world_bounds;
        Some((c, bounds, depths.depths(c)?))
    })
}

/// The objects whose receiver flag or part in the sweeps (receiving, or a
/// caster that does not receive) differs between `key` and the new sets.
fn changed_objects(key: &CacheKey, receives: &[bool], other_casters: &[ObjectId]) -> Vec<u32> {
    let n = receives.len();
    let mark = |ids: &[ObjectId]| {
        let mut v = vec![false; n];
        for id in ids {
            if let Some(f) = v.get_mut(id.index()) {
                *f = true;
            }
        }
        v
    };
    let (was_other, is_other) = (mark(&key.other_casters), mark(other_casters));
    (0..n)
        .filter(|&k| {
            key.receives[k] != receives[k]
                || (key.receives[k] || was_other[k]) != (receives[k] || is_other[k])
        })
        .map(|k| k as u32)
        .collect()
}

/// The cube face frames: view axis, then the image plane's two axes.
const FACES: [[DVec3; 3]; 6] = [
    [DVec3::X, DVec3::NEG_Z, DVec3::NEG_Y],
    [DVec3::NEG_X, DVec3::Z, DVec3::NEG_Y],
    [DVec3::Y, DVec3::X, DVec3::Z],
    [DVec3::NEG_Y, DVec3::X, DVec3::NEG_Z],
    [DVec3::Z, DVec3::X, DVec3::NEG_Y],
    [DVec3::NEG_Z, DVec3::NEG_X, DVec3::NEG_Y],
];

/// Box `b`'s rectangle on image plane `face` of `light` (module docs), or
/// `None` when it cannot meet the face.
fn face_rect(light: &Light, face: usize, b: &Aabb) -> Option<ImageRect> {
    if b.is_empty() {
        return None;
    }
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    match *light {
        Light::Directional { direction } => {
            let d = direction.normalize();
            let u = d.any_orthonormal_vector();
            let v = d.cross(u);
            let mut r = ImageRect {
                min: [f32::INFINITY; 2],
                max: [f32::NEG_INFINITY; 2],
            };
            for k in 0..8 {
                let p = corner(lo, hi, k);
                widen(&mut r, [u.dot(p), v.dot(p)]);
            }
            Some(r)
        }
        Light::Point { position, .. } | Light::Spot { position, .. } => {
            let [axis, u, v] = FACES[face];
            let c: [[f64; 3]; 8] = std::array::from_fn(|k| {
                let p = corner(lo, hi, k) - position;
                [axis.dot(p), u.dot(p), v.dot(p)]
            });
            // Outside one of the pyramid's planes (w ≤ 0, |s| ≤ w, |t| ≤ w).
            let outside = |f: &dyn Fn(&[f64; 3]) -> bool| c.iter().all(f);
            if outside(&|p| p[0] <= 0.0)
                || outside(&|p| p[1] > p[0])
                || outside(&|p| -p[1] > p[0])
                || outside(&|p| p[2] > p[0])
                || outside(&|p| -p[2] > p[0])
            {
                return None;
            }
            let square = ImageRect {
                min: [-1.0; 2],
                max: [1.0; 2],
            };
            if c.iter().any(|p| p[0] <= 0.0) {
                return Some(square);
            }
            let mut r = ImageRect {
                min: [f32::INFINITY; 2],
                max: [f32::NEG_INFINITY; 2],
            };
            for p in &c {
                widen(&mut r, [p[1] / p[0], p[2] / p[0]]);
            }
            for k in 0..2 {
                r.min[k] = r.min[k].clamp(-1.0, 1.0);
                r.max[k] = r.max[k].clamp(-1.0, 1.0);
            }
            Some(r)
        }
    }
}

/// Grows `r` to hold `p`, rounding outward to f32.
fn widen(r: &mut ImageRect, p: [f64; 2]) {
    for (k, v) in p.into_iter().enumerate() {
        r.min[k] = r.min[k].min(round_down(v));
        r.max[k] = r.max[k].max(round_up(v));
    }
}
