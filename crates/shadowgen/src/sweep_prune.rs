//! Sweep-and-prune over rectangles on a light view's image plane [Cohen et al.
//! 1995, "I-COLLIDE"; Steiner §4.4.1]: the overlapping pairs of a set of boxes
//! that changes little from frame to frame, in O(n + k) per frame, where k is
//! the number of endpoint swaps.
//!
//! Each axis keeps its box endpoints in one list sorted by value. A frame
//! refreshes the values and re-sorts the lists by insertion sort, which costs
//! one swap per pair of endpoints whose order changed. A pair of boxes starts
//! or stops overlapping on an axis exactly when one box's minimum and the
//! other's maximum swap, so the swaps name every pair whose status may have
//! changed. The thesis toggles two per-pair flags; here the swapped pairs are
//! collected and rechecked on the final rectangles, which needs no per-pair
//! storage for pairs that overlap on one axis only (in a city seen from a
//! light, most boxes share a column or a row with hundreds of others).
//!
//! When a light moves, every box moves and insertion sort degrades towards
//! O(n²). The sort therefore runs with a swap budget ([`SweepPrune::budget`],
//! a multiple of n): past it, the frame sorts from scratch and sweeps all
//! pairs once, and the next frame does so at once if at least half as many
//! boxes moved. The rule reads counters only, so a frame's result and its
//! counters never depend on timing.
//!
//! # Exactness
//! Rectangles are closed: touching boxes overlap, as in [`ImageRect::overlaps`].
//! Endpoint keys order values by `f32` comparison, a minimum before a maximum
//! of equal value, then by id, so "a's minimum precedes b's maximum" is exactly
//! `a.min <= b.max`. NaN bounds widen to ±∞ (a box of unknown extent overlaps
//! everything), and −0 is read as +0.

use crate::bounds::corner;
use crate::{Error, Result};
use glam::DMat4;
use scene::Aabb;
use serde::Serialize;

/// A closed axis-aligned rectangle `[min.0, max.0] × [min.1, max.1]` on a
/// light view's image plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageRect {
    /// Lower corner (x, y).
    pub min: [f32; 2],
    /// Upper corner (x, y).
    pub max: [f32; 2],
}

impl ImageRect {
    /// The rectangle that covers the whole plane.
    pub const EVERYWHERE: ImageRect = ImageRect {
        min: [f32::NEG_INFINITY; 2],
        max: [f32::INFINITY; 2],
    };

    /// The screen rectangle of world box `b` in a light view: the bounds of
    /// its corners' normalized device x and y under `clip_from_world`
    /// (column vectors). A box with a corner at or behind the light's plane
    /// (clip w ≤ 0) has no bounded image and gets [`Self::EVERYWHERE`]; an
    /// empty box gets its centre's point.
    pub fn of_box(clip_from_world: &DMat4, b: &Aabb) -> ImageRect {
        let (lo, hi) = if b.is_empty() {
            let c = b.min.lerp(b.max, 0.5);
            (c, c)
        } else {
            (b.min, b.max)
        };
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let mut r = ImageRect {
            min: [f32::INFINITY; 2],
            max: [f32::NEG_INFINITY; 2],
        };
        for k in 0..8 {
            let p = corner(lo, hi, k);
            let c = *clip_from_world * p.extend(1.0);
            if c.w.is_nan() || c.w <= 0.0 {
                return ImageRect::EVERYWHERE;
            }
            for axis in 0..2 {
                let v = (c[axis] / c.w) as f32;
                r.min[axis] = r.min[axis].min(v);
                r.max[axis] = r.max[axis].max(v);
            }
        }
        r
    }

    /// True when the closed rectangles share a point (after [`Self::sanitized`]).
    pub fn overlaps(&self, other: &ImageRect) -> bool {
        let (a, b) = (self.sanitized(), other.sanitized());
        (0..2).all(|k| a.min[k] <= b.max[k] && b.min[k] <= a.max[k])
    }

    /// The rectangle as the sweep reads it: NaN bounds widened to ±∞, −0 as
    /// +0, and inverted bounds (min > max) swapped.
    pub fn sanitized(&self) -> ImageRect {
        let clean = |v: f32, nan: f32| if v.is_nan() { nan } else { v + 0.0 };
        let mut r = *self;
        for k in 0..2 {
            let (lo, hi) = (
                clean(self.min[k], f32::NEG_INFINITY),
                clean(self.max[k], f32::INFINITY),
            );
            (r.min[k], r.max[k]) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        }
        r
    }
}

/// Counters of one [`SweepPrune::update`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SapStats {
    /// Boxes present after the update.
    pub boxes: u32,
    /// Overlapping pairs after the update.
    pub pairs: u64,
    /// Endpoint swaps of the insertion sorts (up to the budget).
    pub swaps: u64,
    /// Boxes that appeared.
    pub inserted: u32,
    /// Boxes that disappeared.
    pub removed: u32,
    /// Boxes present before and after whose rectangle changed.
    pub moved: u32,
    /// Whether the swap budget ran out and the frame sorted from scratch.
    pub rebuilt: bool,
}

/// Largest box id: ids and the endpoint kind share the low 32 bits of a key.
pub const MAX_BOX_ID: u32 = ID_MASK;

const ID_MASK: u32 = (1 << 31) - 1;
const MAX_BIT: u64 = 1 << 31;

/// After a rebuild, every this many consecutive rebuilds the incremental sort
/// is tried again ([`SweepPrune::update`]).
const RETRY_EVERY: u32 = 8;

/// The default swap budget per box ([`SweepPrune::budget`]).
pub const DEFAULT_SWAPS_PER_BOX: u32 = 32;

/// Incremental sweep-and-prune state for one light view: the boxes, their
/// endpoints sorted per axis, and the overlapping pairs as neighbour lists.
///
/// Boxes are named by dense ids (object ids). [`Self::update`] takes the whole
/// set each frame as `rects[id]`, `None` for a box not in the set; the state
/// works out which boxes appeared, moved or disappeared.
#[derive(Clone, Debug)]
pub struct SweepPrune {
    rects: Vec<Option<ImageRect>>,
    axes: [Vec<u64>; 2],
    neighbours: Vec<Vec<u32>>,
    pairs: u64,
    swaps_per_box: u32,
    candidates: Vec<u64>,
    inserted: Vec<u32>,
    /// The moved-box count of the previous update if it rebuilt.
    last_rebuilt: Option<u32>,
    /// Consecutive updates that rebuilt.
    rebuilds: u32,
    /// [`SweepPrune::merge`]'s and [`SweepPrune::rebuild`]'s lists, kept so
    /// that boxes appearing again (a periodic motion) allocate nothing.
    scratch: MergeScratch,
}

/// The lists of one merge or rebuild.
#[derive(Clone, Debug, Default)]
struct MergeScratch {
    new: Vec<u64>,
    merged: Vec<u64>,
    open_old: Vec<u32>,
    open_new: Vec<u32>,
    found: Vec<(u32, u32)>,
}

impl Default for SweepPrune {
    fn default() -> Self {
        SweepPrune {
            rects: Vec::new(),
            axes: [Vec::new(), Vec::new()],
            neighbours: Vec::new(),
            pairs: 0,
            swaps_per_box: DEFAULT_SWAPS_PER_BOX,
            candidates: Vec::new(),
            inserted: Vec::new(),
            last_rebuilt: None,
            rebuilds: 0,
            scratch: MergeScratch::default(),
        }
    }
}

impl SweepPrune {
    /// An empty state.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the swap budget to `swaps_per_box` times the number of boxes:
    /// an insertion sort past it stops and the frame sorts from scratch.
    /// 0 sorts every frame from scratch.
    pub fn budget(mut self, swaps_per_box: u32) -> Self {
        self.swaps_per_box = swaps_per_box;
        self
    }

    /// Forgets every box (the view's frame changed).
    pub fn clear(&mut self) {
        self.rects.clear();
        self.axes.iter_mut().for_each(Vec::clear);
        self.neighbours.clear();
        self.pairs = 0;
        self.last_rebuilt = None;
        self.rebuilds = 0;
    }

    /// Number of overlapping pairs.
    pub fn pair_count(&self) -> u64 {
        self.pairs
    }

    /// The boxes overlapping box `id` (none when `id` is absent), in no
    /// particular order.
    pub fn neighbours(&self, id: u32) -> &[u32] {
        self.neighbours.get(id as usize).map_or(&[], Vec::as_slice)
    }

    /// Every overlapping pair once, as `(a, b)` with `a < b`.
    pub fn pairs(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (self.neighbours.iter().enumerate()).flat_map(|(a, n)| {
            let a = a as u32;
            n.iter().filter(move |&&b| a < b).map(move |&b| (a, b))
        })
    }

    /// The current rectangle of box `id`, sanitized.
    pub fn rect(&self, id: u32) -> Option<ImageRect> {
        self.rects.get(id as usize).copied().flatten()
    }

    /// Brings the state to the box set `rects` (`rects[id]`, `None` where
    /// box `id` is absent; ids past the end are absent) and returns the
    /// update's counters.
    ///
    /// # Errors
    /// [`Error::TooManyBoxes`] when `rects` is longer than [`MAX_BOX_ID`] + 1;
    /// the state is then unchanged.
    pub fn update(&mut self, rects: &[Option<ImageRect>]) -> Result<SapStats> {
        if rects.len() > MAX_BOX_ID as usize + 1 {
            return Err(Error::TooManyBoxes { boxes: rects.len() });
        }
        let n = rects.len().max(self.rects.len());
        self.rects.resize(n, None);
        self.neighbours.resize_with(n, Vec::new);
        let mut stats = SapStats::default();
        self.inserted.clear();
        // Disappeared boxes leave the lists and their pairs; appeared ones
        // wait for the merge below; moved ones take their new rectangle.
        let mut any_removed = false;
        for id in 0..n {
            let new = rects.get(id).copied().flatten().map(|r| r.sanitized());
            match (self.rects[id], new) {
                (Some(_), None) => {
                    self.remove_pairs(id as u32);
                    any_removed = true;
                    stats.removed += 1;
                }
                (None, Some(_)) => {
                    self.inserted.push(id as u32);
                    stats.inserted += 1;
                }
                (Some(old), Some(r)) if old != r => stats.moved += 1,
                _ => {}
            }
            self.rects[id] = new;
        }
        let inserted = std::mem::take(&mut self.inserted);
        if any_removed {
            // Appeared boxes are not listed yet, so presence is the test.
            let rects = &self.rects;
            for axis in &mut self.axes {
                axis.retain(|k| rects[(*k as u32 & ID_MASK) as usize].is_some());
            }
        }
        self.candidates.clear();
        let old_boxes = self.axes[0].len() as u64 / 2;
        let budget = old_boxes * u64::from(self.swaps_per_box);
        // A frame after a rebuild with at least half as many moved boxes
        // rebuilds at once rather than spend the budget first (a moving
        // light), except every [`RETRY_EVERY`]th one, which tries the sort
        // again in case the motion slowed.
        let again = !self.rebuilds.is_multiple_of(RETRY_EVERY)
            && self
                .last_rebuilt
                .is_some_and(|m| stats.moved >= m.div_ceil(2));
        let sorted = stats.moved == 0 || (!again && self.resort(budget, &mut stats.swaps));
        if sorted {
            self.recheck_candidates();
            self.merge(&inserted);
        } else {
            stats.rebuilt = true;
            self.rebuild();
        }
        self.inserted = inserted;
        self.last_rebuilt = stats.rebuilt.then_some(stats.moved);
        self.rebuilds = if stats.rebuilt { self.rebuilds + 1 } else { 0 };
        stats.boxes = self.axes[0].len() as u32 / 2;
        stats.pairs = self.pairs;
        Ok(stats)
    }

    /// Refreshes every endpoint's value and insertion-sorts both axes,
    /// collecting min/max swaps of different boxes in `candidates`. False
    /// when the swaps exceed `budget` (the lists are then partly sorted).
    fn resort(&mut self, budget: u64, swaps: &mut u64) -> bool {
        for (axis, list) in self.axes.iter_mut().enumerate() {
            for k in list.iter_mut() {
                let id = *k as u32 & ID_MASK;
                let r = self.rects[id as usize].expect("listed boxes are present");
                *k = key(r, axis, *k & MAX_BIT != 0, id);
            }
            for i in 1..list.len() {
                let k = list[i];
                let mut j = i;
                while j > 0 && list[j - 1] > k {
                    let q = list[j - 1];
                    // A minimum passing a maximum: the pair's overlap on this
                    // axis flipped. Most such pairs stay apart on the other
                    // axis and were no pair before: only the rest are rechecked.
                    if (q ^ k) & MAX_BIT != 0 {
                        let (a, b) = (q as u32 & ID_MASK, k as u32 & ID_MASK);
                        let (ra, rb) = (&self.rects[a as usize], &self.rects[b as usize]);
                        let apart = matches!((ra, rb), (Some(ra), Some(rb)) if !overlaps(ra, rb));
                        if !apart || self.neighbours[a as usize].contains(&b) {
                            self.candidates.push(pair_key(a, b));
                        }
                    }
                    list[j] = q;
                    j -= 1;
                    *swaps += 1;
                    if *swaps > budget {
                        return false;
                    }
                }
                list[j] = k;
            }
        }
        true
    }

    /// Decides every swapped pair on its final rectangles.
    fn recheck_candidates(&mut self) {
        let mut candidates = std::mem::take(&mut self.candidates);
        candidates.sort_unstable();
        candidates.dedup();
        for &c in &candidates {
            let (a, b) = ((c >> 32) as u32, c as u32);
            let (ra, rb) = (self.rects[a as usize], self.rects[b as usize]);
            let now = matches!((ra, rb), (Some(ra), Some(rb)) if overlaps(&ra, &rb));
            let was = self.neighbours[a as usize].contains(&b);
            if now && !was {
                self.add_pair(a, b);
            } else if was && !now {
                self.unlink(a, b);
                self.unlink(b, a);
                self.pairs -= 1;
            }
        }
        self.candidates = candidates;
    }

    /// Merges the endpoints of the appeared boxes `ids` (ascending) into the
    /// sorted lists and adds their pairs, found by one sweep along x.
    fn merge(&mut self, ids: &[u32]) {
        if ids.is_empty() {
            return;
        }
        let mut s = std::mem::take(&mut self.scratch);
        for (axis, list) in self.axes.iter_mut().enumerate() {
            s.new.clear();
            s.new.extend(ids.iter().flat_map(|&id| {
                let r = self.rects[id as usize].expect("appeared boxes are present");
                [key(r, axis, false, id), key(r, axis, true, id)]
            }));
            s.new.sort_unstable();
            merge_sorted(list, &s.new, &mut s.merged);
            std::mem::swap(list, &mut s.merged);
        }
        // Sweep x: a pair with an appeared box is found where the later
        // minimum meets the earlier box still open.
        let is_new = |id: u32| ids.binary_search(&id).is_ok();
        let (open_old, open_new, found) = (&mut s.open_old, &mut s.open_new, &mut s.found);
        open_old.clear();
        open_new.clear();
        found.clear();
        for &k in &self.axes[0] {
            let id = k as u32 & ID_MASK;
            let fresh = is_new(id);
            let open = if fresh {
                &mut *open_new
            } else {
                &mut *open_old
            };
            if k & MAX_BIT != 0 {
                let at = open.iter().position(|&o| o == id).expect("opened before");
                open.swap_remove(at);
                continue;
            }
            let r = self.rects[id as usize].expect("listed boxes are present");
            let others = open_new
                .iter()
                .chain(if fresh { &open_old[..] } else { &[] });
            for &o in others {
                let ro = self.rects[o as usize].expect("open boxes are present");
                if overlaps_y(&r, &ro) {
                    found.push((o, id));
                }
            }
            if fresh {
                open_new.push(id);
            } else {
                open_old.push(id);
            }
        }
        for &(a, b) in found.iter() {
            self.add_pair(a, b);
        }
        self.scratch = s;
    }

    /// Sorts every axis from scratch and sweeps all pairs once.
    fn rebuild(&mut self) {
        self.neighbours.iter_mut().for_each(Vec::clear);
        self.pairs = 0;
        for (axis, list) in self.axes.iter_mut().enumerate() {
            list.clear();
            for (id, r) in self.rects.iter().enumerate() {
                if let Some(r) = r {
                    let id = id as u32;
                    list.extend([key(*r, axis, false, id), key(*r, axis, true, id)]);
                }
            }
            list.sort_unstable();
        }
        let mut s = std::mem::take(&mut self.scratch);
        s.found.clear();
        sweep_x(&self.axes[0], &self.rects, |a, b| s.found.push((a, b)));
        for &(a, b) in &s.found {
            self.add_pair(a, b);
        }
        self.scratch = s;
    }

    fn add_pair(&mut self, a: u32, b: u32) {
        self.neighbours[a as usize].push(b);
        self.neighbours[b as usize].push(a);
        self.pairs += 1;
    }

    fn unlink(&mut self, a: u32, b: u32) {
        let list = &mut self.neighbours[a as usize];
        if let Some(at) = list.iter().position(|&x| x == b) {
            list.swap_remove(at);
        }
    }

    fn remove_pairs(&mut self, id: u32) {
        let mut list = std::mem::take(&mut self.neighbours[id as usize]);
        for &b in &list {
            self.unlink(b, id);
        }
        self.pairs -= list.len() as u64;
        // Keep the allocation for when the box comes back.
        list.clear();
        self.neighbours[id as usize] = list;
    }
}

/// The overlapping pairs of `rects` (`None` entries absent), sorted from
/// scratch and swept once along x: the frame-independent baseline of
/// [`SweepPrune`], O(n log n + pairs on x). Pairs come as `(a, b)`, `a < b`,
/// sorted.
pub fn sweep_pairs(rects: &[Option<ImageRect>]) -> Vec<(u32, u32)> {
    let rects: Vec<Option<ImageRect>> = rects.iter().map(|r| r.map(|r| r.sanitized())).collect();
    let mut xs: Vec<u64> = (rects.iter().enumerate())
        .filter_map(|(id, r)| r.map(|r| (id as u32, r)))
        .flat_map(|(id, r)| [key(r, 0, false, id), key(r, 0, true, id)])
        .collect();
    xs.sort_unstable();
    let mut out = Vec::new();
    sweep_x(&xs, &rects, |a, b| out.push((a.min(b), a.max(b))));
    out.sort_unstable();
    out
}

/// Calls `found(earlier, later)` for every pair that overlaps on both axes,
/// given `xs`, the sorted x endpoints of the present boxes of `rects`.
fn sweep_x(xs: &[u64], rects: &[Option<ImageRect>], mut found: impl FnMut(u32, u32)) {
    // The boxes open at the sweep line with their y interval, and where each
    // box sits in that list (for O(1) removal).
    let mut open: Vec<(u32, [f32; 2])> = Vec::new();
    let mut slot = vec![u32::MAX; rects.len()];
    for &k in xs {
        let id = k as u32 & ID_MASK;
        if k & MAX_BIT != 0 {
            let at = slot[id as usize] as usize;
            open.swap_remove(at);
            if let Some(&(moved, _)) = open.get(at) {
                slot[moved as usize] = at as u32;
            }
            continue;
        }
        let r = rects[id as usize].expect("swept boxes are present");
        for &(o, [lo, hi]) in &open {
            if r.min[1] <= hi && lo <= r.max[1] {
                found(o, id);
            }
        }
        slot[id as usize] = open.len() as u32;
        open.push((id, [r.min[1], r.max[1]]));
    }
}

/// Overlap of two sanitized rectangles.
fn overlaps(a: &ImageRect, b: &ImageRect) -> bool {
    a.min[0] <= b.max[0] && b.min[0] <= a.max[0] && overlaps_y(a, b)
}

fn overlaps_y(a: &ImageRect, b: &ImageRect) -> bool {
    a.min[1] <= b.max[1] && b.min[1] <= a.max[1]
}

/// The sort key of one endpoint of sanitized `r`: the value's bits mapped to
/// an order-preserving u32, then the kind (minimum 0, maximum 1), then the id.
fn key(r: ImageRect, axis: usize, max: bool, id: u32) -> u64 {
    let v = if max { r.max[axis] } else { r.min[axis] };
    let bits = v.to_bits();
    let ordered = if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    };
    (u64::from(ordered) << 32) | if max { MAX_BIT } else { 0 } | u64::from(id)
}

/// One key per unordered pair: the smaller id high.
fn pair_key(a: u32, b: u32) -> u64 {
    (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
}

/// The union of two sorted lists, sorted, into `out` (cleared first).
fn merge_sorted(a: &[u64], b: &[u64], out: &mut Vec<u64>) {
    out.clear();
    out.reserve(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i] <= b[j] {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: f32, x1: f32, y0: f32, y1: f32) -> Option<ImageRect> {
        Some(ImageRect {
            min: [x0, y0],
            max: [x1, y1],
        })
    }

    fn sorted_pairs(s: &SweepPrune) -> Vec<(u32, u32)> {
        let mut p: Vec<_> = s.pairs().collect();
        p.sort_unstable();
        p
    }

    #[test]
    fn boxes_project_to_their_corner_bounds_or_everywhere() {
        // A 90° view down −z: clip (x, y, 0, −z), columns listed.
        let clip_from_world = DMat4::from_cols_array_2d(&[
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, -1.0],
            [0.0, 0.0, 0.0, 0.0],
        ]);
        let b = Aabb {
            min: glam::Vec3::new(-1.0, -1.0, -4.0),
            max: glam::Vec3::new(1.0, 1.5, -2.0),
        };
        let r = ImageRect::of_box(&clip_from_world, &b);
        // The near face (z = −2) bounds the image.
        assert_eq!(
            r,
            ImageRect {
                min: [-0.5, -0.5],
                max: [0.5, 0.75]
            }
        );
        let behind = Aabb {
            min: glam::Vec3::new(-1.0, -1.0, -1.0),
            max: glam::Vec3::new(1.0, 1.0, 1.0),
        };
        assert_eq!(
            ImageRect::of_box(&clip_from_world, &behind),
            ImageRect::EVERYWHERE
        );
    }

    #[test]
    fn keys_order_values_then_min_before_max() {
        let r = ImageRect {
            min: [-1.0, 0.0],
            max: [2.0, 0.0],
        };
        assert!(key(r, 0, false, 5) < key(r, 0, true, 0));
        assert!(
            key(r, 1, false, 9) < key(r, 1, true, 0),
            "min before max at equal value"
        );
        let neg = ImageRect::EVERYWHERE;
        assert!(key(neg, 0, false, 0) < key(r, 0, false, 0));
        assert!(key(r, 0, true, 0) < key(neg, 0, true, 0));
    }

    #[test]
    fn touching_boxes_overlap_and_swaps_track_motion() {
        let mut s = SweepPrune::new();
        let st = s
            .update(&[
                rect(0.0, 1.0, 0.0, 1.0),
                rect(1.0, 2.0, 0.0, 1.0),
                rect(3.0, 4.0, 0.0, 1.0),
            ])
            .unwrap();
        assert_eq!((st.boxes, st.pairs, st.inserted), (3, 1, 3));
        assert_eq!(sorted_pairs(&s), [(0, 1)]);
        // Box 2 slides left over box 1 and off box 0's edge.
        let st = s
            .update(&[
                rect(0.0, 1.0, 0.0, 1.0),
                rect(1.0, 2.0, 0.0, 1.0),
                rect(1.5, 2.5, 0.0, 1.0),
            ])
            .unwrap();
        assert_eq!((st.moved, st.rebuilt), (1, false));
        assert!(st.swaps > 0);
        assert_eq!(sorted_pairs(&s), [(0, 1), (1, 2)]);
        // Box 1 leaves; box 0 moves up, away from everything.
        let st = s
            .update(&[rect(0.0, 1.0, 5.0, 6.0), None, rect(1.5, 2.5, 0.0, 1.0)])
            .unwrap();
        assert_eq!((st.removed, st.pairs, st.boxes), (1, 0, 2));
        assert_eq!(s.neighbours(1), &[] as &[u32]);
    }

    #[test]
    fn a_zero_budget_rebuilds_with_the_same_pairs() {
        let frames = [
            vec![rect(0.0, 2.0, 0.0, 2.0), rect(1.0, 3.0, 1.0, 3.0), None],
            vec![
                rect(2.5, 4.0, 0.0, 2.0),
                rect(1.0, 3.0, 1.0, 3.0),
                rect(0.0, 1.0, 0.0, 9.0),
            ],
        ];
        let (mut a, mut b) = (SweepPrune::new(), SweepPrune::new().budget(0));
        for f in &frames {
            a.update(f).unwrap();
            let st = b.update(f).unwrap();
            assert_eq!(sorted_pairs(&a), sorted_pairs(&b));
            assert_eq!(sorted_pairs(&a), sweep_pairs(f));
            assert_eq!(st.rebuilt, st.moved > 0);
        }
    }

    #[test]
    fn nan_bounds_overlap_everything_and_negative_zero_is_zero() {
        let nan = ImageRect {
            min: [f32::NAN, 0.0],
            max: [f32::NAN, 1.0],
        };
        assert!(nan.overlaps(&ImageRect {
            min: [1e30, 0.5],
            max: [1e30, 0.5]
        }));
        let mut s = SweepPrune::new();
        s.update(&[
            Some(nan),
            rect(1e30, 1e30, 0.5, 0.5),
            rect(-0.0, -0.0, 0.0, 0.0),
            rect(0.0, 0.0, 0.0, 0.0),
        ])
        .unwrap();
        assert_eq!(sorted_pairs(&s), [(0, 1), (0, 2), (0, 3), (2, 3)]);
    }
}
