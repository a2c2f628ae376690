//! The light pass's receivers [Steiner §4.3.1; Bittner et al. 2011]: the
//! eye's visible surface points, pushed away from the light, relative to the
//! light views' origin, sent to the views that can hold them.
//!
//! Conservative marking works on *segments*: the visible pixels of one eye
//! row on one triangle lie on a line (the row's pixel-centre rays span a
//! plane through the eye; it meets the triangle's plane in a line), in
//! order. The producer keeps only such a run's two ends, and the run is
//! marked as the segment between them
//! ([`raster::ReceiverTarget::mark_segments_within`]): every pixel a point
//! would mark, each at the depths of the part of the segment there, so no
//! nearer than its points, with two projections per run instead of one per
//! point. The push away from the light is a homothety about the light (or
//! a translation, for a directional light), so pushed points stay on their
//! pushed segment. Point-sampled (aggressive) marking keeps one projection
//! per point.
//!
//! Cube faces: a point, or a segment, goes only to the faces whose cone
//! (the directions in which the face's axis dominates, widened by the
//! marking's reach at the face's resolution) it meets; a face's fitted
//! window lies inside its full 90° face, so what is left out could mark
//! nothing there.

use crate::light_view::{LightView, LightViewKind};
use crate::view_setup::Sampling;
use glam::{DVec3, Mat4, Vec4};
#[cfg(feature = "parallel")]
use rayon::prelude::*;
use scene::Light;

/// Relative push of a receiver point away from the light before marking.
pub const RECEIVER_PUSH: f64 = 1.0 / 1_048_576.0;

/// The eye's visible surface points, as the light pass takes them.
#[derive(Clone, Debug, Default)]
pub struct ReceiverPoints {
    /// World points, in any order that keeps each joined point right after
    /// the one it is joined to (NaN points are skipped).
    pub points: Vec<DVec3>,
    /// Per point: true when it and the point before it end one piece, marked
    /// (conservatively) as the segment between them: the surface the eye
    /// sees between them lies on that segment (same eye row, same triangle
    /// plane). Point-sampled marking ignores it. Empty: no point is joined.
    pub joined: Vec<bool>,
    /// Per point: the lights that may leave it out, as a mask of the bits
    /// light passes are given ([`crate::PassInput::skip_receivers`]): the
    /// producer's proof that those lights never read a shadow there (the
    /// pipeline sets a light's bit on the points of surfaces that face away
    /// from it). Points joined to each other must have one mask (the
    /// pipeline gives every point of a run one). Empty: every light takes
    /// every point.
    pub skip: Vec<u32>,
    /// Receiver polygons: pieces of surface on which visible receiver
    /// points may lie anywhere (a coarse eye pass knows no more), each
    /// marked as a whole ([`raster::ReceiverTarget::mark_polygons_within`]).
    pub polygons: ReceiverPolygons,
}

/// Convex, planar polygons of world points, each a piece of receiving
/// surface ([`ReceiverPoints::polygons`]).
#[derive(Clone, Debug, Default)]
pub struct ReceiverPolygons {
    /// Every polygon's vertices, one polygon after the other, in order
    /// around it.
    pub vertices: Vec<DVec3>,
    /// Per polygon, the end of its vertices in `vertices` (it starts at the
    /// end of the one before).
    pub ends: Vec<u32>,
    /// Per polygon, the lights that may leave it out, as
    /// [`ReceiverPoints::skip`]. Empty: every light takes every polygon.
    pub skip: Vec<u32>,
}

impl ReceiverPolygons {
    /// Forgets every polygon (the buffers stay).
    pub fn clear(&mut self) {
        self.vertices.clear();
        self.ends.clear();
        self.skip.clear();
    }

    /// Appends polygon `vertices`, which lights of bits `skip` may leave out.
    pub fn push(&mut self, vertices: impl IntoIterator<Item = DVec3>, skip: u32) {
        self.vertices.extend(vertices);
        self.ends.push(self.vertices.len() as u32);
        self.skip.push(skip);
    }

    /// The number of polygons.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }
}

impl ReceiverPoints {
    /// Points each marked on their own.
    pub fn from_points(points: Vec<DVec3>) -> Self {
        ReceiverPoints {
            points,
            joined: Vec::new(),
            skip: Vec::new(),
            polygons: ReceiverPolygons::default(),
        }
    }

    fn joined(&self, i: usize) -> bool {
        self.joined.get(i).copied().unwrap_or(false)
    }

    /// Whether a light of bits `skip` takes point `i`: it is a point (not
    /// NaN) that the light may not leave out.
    fn takes(&self, i: usize, skip: u32) -> bool {
        !self.points[i].x.is_nan() && self.skip.get(i).is_none_or(|&s| s & skip == 0)
    }
}

/// What one view marks: points or segments, and polygons.
pub(crate) struct Marks<'a> {
    /// The points or segments.
    pub lines: LineMarks<'a>,
    /// Polygons `(start, end)` of `vertices`: all of them, or those listed
    /// in `only`.
    pub polygons: PolygonMarks<'a>,
}

/// The points or segments one view marks.
pub(crate) enum LineMarks<'a> {
    /// Points, each on its own.
    Points(&'a [Vec4]),
    /// Pieces `(first, last)` of `points`, each marked as the segment
    /// between its ends: all of them, or those listed in `only`.
    Segments {
        points: &'a [Vec4],
        pieces: &'a [(u32, u32)],
        only: Option<&'a [u32]>,
    },
}

/// The polygons one view marks.
#[derive(Clone, Copy)]
pub(crate) struct PolygonMarks<'a> {
    pub vertices: &'a [Vec4],
    pub ranges: &'a [(u32, u32)],
    pub only: Option<&'a [u32]>,
}

impl PolygonMarks<'_> {
    fn len(&self) -> usize {
        self.only.map_or(self.ranges.len(), <[u32]>::len)
    }

    /// Marks polygons `range` (of `only`, or of every polygon) in `t`.
    fn mark(
        &self,
        t: &mut raster::ReceiverTarget,
        clip_from_local: Mat4,
        range: std::ops::Range<usize>,
        eps_px: f64,
    ) {
        let poly = |&(a, b): &(u32, u32)| &self.vertices[a as usize..b as usize];
        match self.only {
            Some(ix) => t.mark_polygons_within(
                clip_from_local,
                ix[range].iter().map(|&i| poly(&self.ranges[i as usize])),
                eps_px,
            ),
            None => {
                t.mark_polygons_within(clip_from_local, self.ranges[range].iter().map(poly), eps_px)
            }
        };
    }
}

/// Segments from which a view's marking is split between two threads.
#[cfg(feature = "parallel")]
const SPLIT_SEGMENTS: usize = 1 << 15;

impl Marks<'_> {
    /// How many points, pieces and polygons this view marks.
    pub fn len(&self) -> usize {
        let lines = match self.lines {
            LineMarks::Points(p) => p.len(),
            LineMarks::Segments { pieces, only, .. } => only.map_or(pieces.len(), <[u32]>::len),
        };
        lines + self.polygons.len()
    }

    /// Marks these receivers in `target` (local points, clip
    /// `clip_from_local · p`) within `eps_px`. With many segments or
    /// polygons, a pool of more than one thread and a `spare` target (made
    /// like `target` when missing or unlike it), half of them are marked in
    /// the spare on another thread and absorbed
    /// ([`raster::ReceiverTarget::absorb`]): the same marks, as marks are
    /// minima and maxima. A street view's receivers crowd one cube face,
    /// whose marking was the light pass's longest single-threaded step.
    pub fn mark(
        &self,
        target: &mut raster::ReceiverTarget,
        clip_from_local: Mat4,
        eps_px: f64,
        spare: Option<&mut Option<raster::ReceiverTarget>>,
    ) {
        let polygons = self.polygons;
        let (points, pieces, only) = match self.lines {
            LineMarks::Points(p) => (p, &[][..], None),
            LineMarks::Segments {
                points,
                pieces,
                only,
            } => (points, pieces, only),
        };
        let segmented = matches!(self.lines, LineMarks::Segments { .. });
        let segment = |&(a, b): &(u32, u32)| (points[a as usize], points[b as usize]);
        let count = only.map_or(pieces.len(), <[u32]>::len);
        // Marks segments `range` (of `only`, or of every piece) in `t`.
        let mark = |t: &mut raster::ReceiverTarget, range: std::ops::Range<usize>| match only {
            Some(ix) => t.mark_segments_within(
                clip_from_local,
                ix[range].iter().map(|&i| segment(&pieces[i as usize])),
                eps_px,
            ),
            None => {
                t.mark_segments_within(clip_from_local, pieces[range].iter().map(segment), eps_px)
            }
        };
        let polys = polygons.len();
        #[cfg(feature = "parallel")]
        if let Some(spare) = spare {
            if segmented && count + polys >= SPLIT_SEGMENTS && rayon::current_num_threads() > 1 {
                let other = match spare {
                    Some(s)
                        if s.size() == target.size()
                            && s.tracks_nearest() == target.tracks_nearest() =>
                    {
                        s
                    }
                    _ => spare.insert(target.unmarked_like()),
                };
                let (half, half_polys) = (count / 2, polys / 2);
                rayon::join(
                    || {
                        mark(target, 0..half);
                        polygons.mark(target, clip_from_local, 0..half_polys, eps_px);
                    },
                    || {
                        mark(other, half..count);
                        polygons.mark(other, clip_from_local, half_polys..polys, eps_px);
                    },
                );
                target.absorb(other).expect("a spare made like the target");
                return;
            }
        }
        #[cfg(not(feature = "parallel"))]
        let _ = spare;
        if segmented {
            mark(target, 0..count);
        } else {
            target.mark_points_within(clip_from_local, points, eps_px);
        }
        polygons.mark(target, clip_from_local, 0..polys, eps_px);
    }
}

/// The receivers prepared for one light's views (buffers reused from frame
/// to frame).
#[derive(Debug, Default)]
pub(crate) struct Prepared {
    /// Every point, pushed and relative to the views' origin.
    local: Vec<Vec4>,
    /// Segmented: the pieces as (first, last) indices into `local`.
    pieces: Vec<(u32, u32)>,
    /// Point-sampled, per cube face: the points that can mark it.
    face_points: [Vec<Vec4>; 6],
    /// Segmented, per cube face: the indices of the pieces that can mark it.
    face_pieces: [Vec<u32>; 6],
    /// Every polygon's vertices, pushed and relative to the views' origin.
    polygon_local: Vec<Vec4>,
    /// The polygons the light takes, as (start, end) into `polygon_local`.
    polygons: Vec<(u32, u32)>,
    /// Per cube face: the indices of the polygons that can mark it.
    face_polygons: [Vec<u32>; 6],
    segmented: bool,
    cube: bool,
}

impl Prepared {
    /// Pushes the points of `parts` away from `light` (by
    /// [`RECEIVER_PUSH`] when conservative; `diameter` scales a directional
    /// light's push), makes them relative to `origin`, and sends them to
    /// `views`; points the light may leave out (`skip`,
    /// [`ReceiverPoints::skip`]) become NaN, which no piece holds and
    /// marking skips.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare(
        &mut self,
        parts: &[ReceiverPoints],
        skip: u32,
        light: &Light,
        origin: DVec3,
        diameter: f64,
        sampling: Sampling,
        views: &[LightView],
    ) {
        let push = match sampling {
            Sampling::Conservative => RECEIVER_PUSH,
            Sampling::Point => 0.0,
        };
        let step = match light.position() {
            Some(_) => DVec3::ZERO,
            None => light.toward_light(origin).normalize_or_zero() * (push * diameter),
        };
        let place = |p: DVec3| {
            let q = match light.position() {
                Some(c) => c + (p - c) * (1.0 + push),
                None => p - step,
            };
            (q - origin).as_vec3().extend(1.0)
        };
        self.segmented = sampling == Sampling::Conservative;
        self.pieces.clear();
        let n = parts.iter().map(|r| r.points.len()).sum();
        self.local.resize(n, Vec4::NAN);
        let mut rest = &mut self.local[..];
        let mut offset = 0;
        for r in parts {
            if self.segmented {
                cut_pieces(r, skip, offset, &mut self.pieces);
            }
            let (local, tail) = rest.split_at_mut(r.points.len());
            // (NaN points stay NaN: marking skips them, and no piece holds one.)
            let point = |(i, l): (usize, &mut Vec4)| {
                *l = if r.takes(i, skip) {
                    place(r.points[i])
                } else {
                    Vec4::NAN
                }
            };
            #[cfg(feature = "parallel")]
            local
                .par_iter_mut()
                .enumerate()
                .with_min_len(4096)
                .for_each(point);
            #[cfg(not(feature = "parallel"))]
            local.iter_mut().enumerate().for_each(point);
            rest = tail;
            offset += r.points.len() as u32;
        }
        self.polygon_local.clear();
        self.polygons.clear();
        for r in parts {
            let p = &r.polygons;
            let mut start = 0;
            for (k, &end) in p.ends.iter().enumerate() {
                let taken = p.skip.get(k).is_none_or(|&s| s & skip == 0);
                let vertices = &p.vertices[start as usize..end as usize];
                start = end;
                if !taken || vertices.is_empty() {
                    continue;
                }
                let first = self.polygon_local.len() as u32;
                self.polygon_local
                    .extend(vertices.iter().map(|&v| place(v)));
                self.polygons.push((first, self.polygon_local.len() as u32));
            }
        }
        let cube_res = views
            .iter()
            .filter(|v| matches!(v.kind, LightViewKind::CubeFace(_)))
            .map(|v| v.resolution)
            .min();
        self.cube = false;
        if let (Some(res), Some(_)) = (cube_res, light.position()) {
            self.cube = true;
            let eps = match sampling {
                Sampling::Conservative => raster::RECEIVER_EPS_PX,
                Sampling::Point => 0.0,
            };
            // The marking's reach beyond a face's edge: its footprint and
            // the two-pixel margin its clip keeps.
            let slack = 1.0 + 2.0 * (2.0 + eps) / f64::from(res) + 1e-9;
            self.bin_faces(slack);
        }
    }

    /// The receivers `view` marks.
    pub fn for_view(&self, view: &LightView) -> Marks<'_> {
        let face = match (view.kind, self.cube) {
            (LightViewKind::CubeFace(k), true) => Some(k as usize),
            _ => None,
        };
        let lines = match (face, self.segmented) {
            (face, true) => LineMarks::Segments {
                points: &self.local,
                pieces: &self.pieces,
                only: face.map(|k| &self.face_pieces[k][..]),
            },
            (Some(k), false) => LineMarks::Points(&self.face_points[k]),
            (None, false) => LineMarks::Points(&self.local),
        };
        let polygons = PolygonMarks {
            vertices: &self.polygon_local,
            ranges: &self.polygons,
            only: face.map(|k| &self.face_polygons[k][..]),
        };
        Marks { lines, polygons }
    }

    /// How many points, pieces and polygons `view` marks
    /// ([`Prepared::for_view`]).
    pub fn count_for(&self, view: &LightView) -> usize {
        self.for_view(view).len()
    }

    /// Sends every point or piece to the cube faces whose widened cone it
    /// meets, by its light-relative coordinates (a positional light is the
    /// views' origin). They are f32: the rounding (2⁻²⁴ relative) moves a
    /// point across a widened cone's boundary only within 2⁻²⁴ of it, and
    /// that boundary lies `slack` beyond the face — the marking's footprint
    /// plus the two pixels its clip keeps — so such a point marks no pixel of
    /// the face either way (at most 16384 · 2⁻²⁴ ≈ 0.001 px nearer).
    fn bin_faces(&mut self, slack: f64) {
        for f in &mut self.face_points {
            f.clear();
        }
        for f in &mut self.face_pieces {
            f.clear();
        }
        // A polygon with every vertex clear of one face lies in that face's
        // cone (convex, as the pieces' test says): it goes there alone; any
        // other, to every face (a few along the cube's edges).
        for f in &mut self.face_polygons {
            f.clear();
        }
        for (i, &(a, b)) in self.polygons.iter().enumerate() {
            let vertices = &self.polygon_local[a as usize..b as usize];
            let face = |v: &Vec4| clear_face(v.truncate().as_dvec3(), slack);
            let first = face(&vertices[0]);
            match first.filter(|_| vertices[1..].iter().all(|v| face(v) == first)) {
                Some(k) => self.face_polygons[k].push(i as u32),
                None => self.face_polygons.iter_mut().for_each(|f| f.push(i as u32)),
            }
        }
        if self.segmented {
            let at = |i: u32| self.local[i as usize].truncate().as_dvec3();
            for (i, &(a, b)) in self.pieces.iter().enumerate() {
                let (da, db) = (at(a), at(b));
                if let (Some(ka), Some(kb)) = (clear_face(da, slack), clear_face(db, slack)) {
                    if ka == kb {
                        self.face_pieces[ka].push(i as u32);
                        continue;
                    }
                }
                for (k, f) in self.face_pieces.iter_mut().enumerate() {
                    if segment_meets_face(da, db, k, slack) {
                        f.push(i as u32);
                    }
                }
            }
        } else {
            for q in &self.local {
                let d = q.truncate().as_dvec3();
                // A point clear of one face meets no other (as a piece
                // with both ends clear of it): one test, not six.
                if let Some(k) = clear_face(d, slack) {
                    self.face_points[k].push(*q);
                    continue;
                }
                for (k, f) in self.face_points.iter_mut().enumerate() {
                    if segment_meets_face(d, d, k, slack) {
                        f.push(*q);
                    }
                }
            }
        }
    }
}

/// Appends `r`'s pieces (indices offset by `offset`) to `pieces`: each
/// joined point with the one before it, and every point joined to neither
/// neighbour on its own; of the points a light of bits `skip` takes.
fn cut_pieces(r: &ReceiverPoints, skip: u32, offset: u32, pieces: &mut Vec<(u32, u32)>) {
    let valid = |i: usize| r.takes(i, skip);
    let n = r.points.len();
    for i in (0..n).filter(|&i| valid(i)) {
        let at = offset + i as u32;
        if i > 0 && r.joined(i) && valid(i - 1) {
            pieces.push((at - 1, at));
        } else if !(i + 1 < n && r.joined(i + 1) && valid(i + 1)) {
            pieces.push((at, at));
        }
    }
}

/// The one face whose cone holds `d` with room to spare: its axis `f`
/// strictly dominates, `|d_f| > slack·|d_o|` for both other axes. That set
/// is convex (per sign of `d_f`) and meets no other face's widened cone, so
/// a segment with both ends clear of the same face meets that face only.
fn clear_face(d: DVec3, slack: f64) -> Option<usize> {
    let a = d.abs();
    let f = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let clear = (0..3).all(|o| o == f || a[f] > slack * a[o]);
    (clear && a[f] > 0.0).then_some(2 * f + usize::from(d[f] < 0.0))
}

/// Whether the segment of directions `a b` (from the light) meets cube face
/// `k`'s cone (axis `k / 2`, positive for even `k`): `σ·d_axis·slack ≥ |d_o|`
/// for both other axes — a convex cone, so a segment clip decides.
fn segment_meets_face(a: DVec3, b: DVec3, k: usize, slack: f64) -> bool {
    let axis = k / 2;
    let sign = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for o in (0..3).filter(|&o| o != axis) {
        for so in [1.0, -1.0] {
            // Inside: sign·d_axis·slack − so·d_o ≥ 0.
            let f = |d: DVec3| sign * d[axis] * slack - so * d[o];
            let (f0, f1) = (f(a), f(b));
            if f0.is_nan() || f1.is_nan() || (f0 < 0.0 && f1 < 0.0) {
                return false;
            }
            if f0 < 0.0 {
                t0 = t0.max(f0 / (f0 - f1));
            } else if f1 < 0.0 {
                t1 = t1.min(f0 / (f0 - f1));
            }
        }
    }
    t0 <= t1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Joined points pair with the point before them, lone points stand
    /// alone, NaN points are skipped (and join nothing); pieces are appended
    /// at the part's offset.
    #[test]
    fn joined_points_make_pieces() {
        let nan = DVec3::NAN;
        let p = DVec3::ONE;
        // Runs: [0 (joined to nothing), 1, 2], [3], NaN 4, [5 (joined to the NaN), 6].
        let points = vec![p, p, p, p, nan, p, p];
        let joined = vec![true, true, true, false, true, true, true];
        // The run [1, 2] left out by lights of bit 1 (not by those of bit 2).
        let skip = vec![0, 1, 1, 0, 0, 0, 0];
        let r = ReceiverPoints {
            points,
            joined,
            skip,
            polygons: ReceiverPolygons::default(),
        };
        let mut pieces = vec![(0, 0)];
        cut_pieces(&r, 0, 10, &mut pieces);
        assert_eq!(pieces, vec![(0, 0), (10, 11), (11, 12), (13, 13), (15, 16)]);
        for other in [2, 4] {
            let mut again = vec![(0, 0)];
            cut_pieces(&r, other, 10, &mut again);
            assert_eq!(again, pieces);
        }
        pieces.truncate(1);
        cut_pieces(&r, 1 | 4, 10, &mut pieces);
        assert_eq!(pieces, vec![(0, 0), (10, 10), (13, 13), (15, 16)]);
    }

    /// A seeded uniform sampler of [−1, 1) (an LCG: reproducible, no dependency).
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// A segment with both ends clear of one face meets no other face.
    #[test]
    fn clear_faces_exclude_the_others() {
        let mut rnd = uniform(11);
        let slack = 1.01;
        let mut cleared = 0;
        for _ in 0..5000 {
            let a = DVec3::new(rnd(), rnd(), rnd());
            let b = a + DVec3::new(rnd(), rnd(), rnd()) * 0.3;
            // A point clear of a face meets only that face (the point path).
            if let Some(ka) = clear_face(a, slack) {
                for k in 0..6 {
                    assert_eq!(segment_meets_face(a, a, k, slack), k == ka, "{a} {k}");
                }
            }
            if let (Some(ka), Some(kb)) = (clear_face(a, slack), clear_face(b, slack)) {
                if ka == kb {
                    cleared += 1;
                    for k in 0..6 {
                        assert_eq!(segment_meets_face(a, b, k, slack), k == ka, "{a} {b} {k}");
                    }
                }
            }
        }
        assert!(cleared > 1000, "{cleared}");
    }

    /// A segment meets a face's cone exactly when some point on it does.
    #[test]
    fn segment_face_test_matches_sampling() {
        let mut rnd = uniform(7);
        let slack = 1.01;
        let inside = |d: DVec3, k: usize| {
            let axis = k / 2;
            let s = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
            (0..3)
                .filter(|&o| o != axis)
                .all(|o| s * d[axis] * slack >= d[o].abs())
        };
        for _ in 0..2000 {
            let a = DVec3::new(rnd(), rnd(), rnd());
            let b = DVec3::new(rnd(), rnd(), rnd());
            for k in 0..6 {
                let sampled = (0..=200).any(|i| inside(a + (b - a) * (i as f64 / 200.0), k));
                if sampled {
                    assert!(segment_meets_face(a, b, k, slack), "{a} {b} face {k}");
                }
            }
        }
    }
}
