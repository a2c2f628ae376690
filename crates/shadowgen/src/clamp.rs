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

use crate::{occupied_intervals, ClampPlan, GapArea, GapCost, Result, SegmentAxis, SweepPrune};
use crate::{ImageRect, SapStats};
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
    /// Per object: the last caster whose receivers it was counted for (+1).
    seen: Vec<u32>,
    depths: Vec<[f64; 2]>,
    intervals: Vec<[f64; 2]>,
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
        let mut is_caster = vec![false; n];
        for c in casters {
            if let Some(f) = is_caster.get_mut(c.0 as usize) {
                *f = true;
            }
        }
        let mut stats = ClampStats::default();
        let objects = scene.objects();
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
        self.seen.clear();
        self.seen.resize(n, 0);
        for (k, &c) in casters.iter().enumerate() {
            let Some(bounds) = objects.get(c.0 as usize).map(|o| o.world_bounds) else {
                continue;
            };
            let Some(axis) = SegmentAxis::new(light, &bounds) else {
                continue;
            };
            let stamp = k as u32 + 1;
            self.depths.clear();
            for sap in &self.planes {
                for &r in sap.neighbours(c.0) {
                    let seen = &mut self.seen[r as usize];
                    if *seen != stamp && receives.get(r as usize).copied().unwrap_or(false) {
                        *seen = stamp;
                        self.depths
                            .push(axis.box_depths(&objects[r as usize].world_bounds));
                    }
                }
            }
            let caster_depths = axis.box_depths(&bounds);
            let model = cost.map(|m| (m.cost(c), m));
            let area = |a: f64, b: f64| model.map_or(0.0, |(_, m)| m.area(&bounds, &axis, a, b));
            let area: GapArea<'_> = &area;
            occupied_intervals(
                caster_depths,
                self.depths.iter().copied(),
                model.as_ref().map(|(m, _)| (m, area)),
                &mut self.intervals,
            );
            stats.clamped += 1;
            stats.intervals += self.intervals.len() as u64;
            plan.set(c, axis, &self.intervals);
        }
        Ok(stats)
    }
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
    let corner =
        |k: usize| DVec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo);
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
                let p = corner(k);
                widen(&mut r, [u.dot(p), v.dot(p)]);
            }
            Some(r)
        }
        Light::Point { position, .. } | Light::Spot { position, .. } => {
            let [axis, u, v] = FACES[face];
            let c: [[f64; 3]; 8] = std::array::from_fn(|k| {
                let p = corner(k) - position;
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
        let f = v as f32;
        let (down, up) = if f64::from(f) > v {
            (f.next_down(), f)
        } else if f64::from(f) < v {
            (f, f.next_up())
        } else {
            (f, f)
        };
        r.min[k] = r.min[k].min(down);
        r.max[k] = r.max[k].max(up);
    }
}
