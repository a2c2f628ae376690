//! The light pass's receivers [Steiner §4.3.1; Bittner et al. 2011]: the
//! eye's visible surface points, pushed away from the light, relative to the
//! light views' origin, sent to the views that can hold them.
//!
//! Conservative marking works on *segments*: the visible pixels of one eye
//! row on one triangle lie on a line (the row's pixel-centre rays span a
//! plane through the eye; it meets the triangle's plane in a line), in
//! order. A run of such points, cut into pieces of [`PIECE_STEPS`] steps,
//! is marked as the segment between each piece's ends
//! ([`raster::ReceiverTarget::mark_segments_within`]): every pixel a point
//! would mark, at a depth no nearer, with two projections per piece instead
//! of one per point. The push away from the light is a homothety about the
//! light (or a translation, for a directional light), so pushed points stay
//! on their pushed segment. Point-sampled (aggressive) marking keeps one
//! projection per point.
//!
//! Cube faces: a point, or a segment, goes only to the faces whose cone
//! (the directions in which the face's axis dominates, widened by the
//! marking's reach at the face's resolution) it meets; a face's fitted
//! window lies inside its full 90° face, so what is left out could mark
//! nothing there.

use crate::light_view::{LightView, LightViewKind};
use crate::view_setup::Sampling;
use glam::{DVec3, Vec4};
#[cfg(feature = "parallel")]
use rayon::prelude::*;
use scene::Light;

/// Relative push of a receiver point away from the light before marking.
pub const RECEIVER_PUSH: f64 = 1.0 / 1_048_576.0;

/// Steps per receiver segment: a run of joined points is marked in pieces
/// of this many steps (longer pieces save projections but give their
/// pixels the piece's farthest depth).
pub const PIECE_STEPS: usize = 8;

/// The eye's visible surface points, as the light pass takes them.
#[derive(Clone, Debug, Default)]
pub struct ReceiverPoints {
    /// World points (NaN where the eye sees background), in any order that
    /// keeps each run of joined points consecutive (row-major).
    pub points: Vec<DVec3>,
    /// Per point: true when it continues the run of the point before it —
    /// both on one line, the points between them on the segment joining
    /// them (same eye row, same triangle plane). Empty: no point is joined.
    pub joined: Vec<bool>,
}

impl ReceiverPoints {
    /// Points each marked on their own.
    pub fn from_points(points: Vec<DVec3>) -> Self {
        ReceiverPoints {
            points,
            joined: Vec::new(),
        }
    }

    fn joined(&self, i: usize) -> bool {
        self.joined.get(i).copied().unwrap_or(false)
    }
}

/// What one view marks.
pub(crate) enum Marks<'a> {
    Points(&'a [Vec4]),
    Segments(&'a [(Vec4, Vec4)]),
}

/// The receivers prepared for one light's views (buffers reused from frame
/// to frame).
#[derive(Debug, Default)]
pub(crate) struct Prepared {
    local: Vec<Vec4>,
    /// Pieces as (first, last) point indices.
    pieces: Vec<(u32, u32)>,
    segments: Vec<(Vec4, Vec4)>,
    face_points: [Vec<Vec4>; 6],
    face_segments: [Vec<(Vec4, Vec4)>; 6],
    segmented: bool,
    cube: bool,
}

impl Prepared {
    /// Pushes `r`'s points away from `light` (by [`RECEIVER_PUSH`] when
    /// conservative; `diameter` scales a directional light's push), makes
    /// them relative to `origin`, and sends them to `views`.
    pub fn prepare(
        &mut self,
        r: &ReceiverPoints,
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
        if self.segmented {
            // Only the pieces' ends are placed: two per piece, not one per point.
            self.cut_pieces(r);
            let n = self.pieces.len();
            self.segments.resize(n, (Vec4::NAN, Vec4::NAN));
            let piece = |(&(a, b), s): (&(u32, u32), &mut (Vec4, Vec4))| {
                *s = (place(r.points[a as usize]), place(r.points[b as usize]));
            };
            #[cfg(feature = "parallel")]
            self.pieces
                .par_iter()
                .zip(self.segments.par_iter_mut())
                .with_min_len(1024)
                .for_each(piece);
            #[cfg(not(feature = "parallel"))]
            self.pieces
                .iter()
                .zip(self.segments.iter_mut())
                .for_each(piece);
        } else {
            let n = r.points.len();
            self.local.resize(n, Vec4::NAN);
            // (NaN points, the eye's background pixels, stay NaN: marking skips them.)
            let point = |(&p, l): (&DVec3, &mut Vec4)| *l = place(p);
            #[cfg(feature = "parallel")]
            r.points
                .par_iter()
                .zip(self.local.par_iter_mut())
                .with_min_len(4096)
                .for_each(point);
            #[cfg(not(feature = "parallel"))]
            r.points.iter().zip(self.local.iter_mut()).for_each(point);
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
        match (view.kind, self.cube, self.segmented) {
            (LightViewKind::CubeFace(k), true, true) => {
                Marks::Segments(&self.face_segments[k as usize])
            }
            (LightViewKind::CubeFace(k), true, false) => {
                Marks::Points(&self.face_points[k as usize])
            }
            (_, _, true) => Marks::Segments(&self.segments),
            (_, _, false) => Marks::Points(&self.local),
        }
    }

    /// Cuts the runs of joined points into pieces of at most
    /// [`PIECE_STEPS`] steps; a lone point is a piece of its own.
    fn cut_pieces(&mut self, r: &ReceiverPoints) {
        self.pieces.clear();
        let n = r.points.len();
        let mut i = 0;
        while i < n {
            if r.points[i].x.is_nan() {
                i += 1;
                continue;
            }
            let mut end = i;
            while end + 1 < n && r.joined(end + 1) {
                end += 1;
            }
            let mut a = i;
            loop {
                let b = (a + PIECE_STEPS).min(end);
                self.pieces.push((a as u32, b as u32));
                if b == end {
                    break;
                }
                a = b;
            }
            i = end + 1;
        }
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
        for f in &mut self.face_segments {
            f.clear();
        }
        if self.segmented {
            for s in &self.segments {
                let (da, db) = (s.0.truncate().as_dvec3(), s.1.truncate().as_dvec3());
                if let (Some(ka), Some(kb)) = (clear_face(da, slack), clear_face(db, slack)) {
                    if ka == kb {
                        self.face_segments[ka].push(*s);
                        continue;
                    }
                }
                for (k, f) in self.face_segments.iter_mut().enumerate() {
                    if segment_meets_face(da, db, k, slack) {
                        f.push(*s);
                    }
                }
            }
        } else {
            for q in &self.local {
                let d = q.truncate().as_dvec3();
                for (k, f) in self.face_points.iter_mut().enumerate() {
                    if segment_meets_face(d, d, k, slack) {
                        f.push(*q);
                    }
                }
            }
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

    /// Pieces cover every joined run end to end with at most PIECE_STEPS
    /// steps, lone points alone, background skipped.
    #[test]
    fn runs_are_cut_into_pieces() {
        let nan = DVec3::NAN;
        let p = DVec3::ONE;
        // Runs: [0..=11] (12 points), [12], background 13, [14..=15].
        let mut points = vec![p; 16];
        points[13] = nan;
        let mut joined = vec![true; 16];
        for i in [0, 12, 13, 14] {
            joined[i] = false;
        }
        let r = ReceiverPoints { points, joined };
        let mut pr = Prepared::default();
        pr.cut_pieces(&r);
        assert_eq!(pr.pieces, vec![(0, 8), (8, 11), (12, 12), (14, 15)]);
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
