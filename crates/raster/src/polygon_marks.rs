//! Receiver polygons [Steiner §4.3.1]: where the eye pass runs at a coarse
//! culling resolution, a visible receiver point is known only to lie on a
//! piece of a receiving triangle (the triangle within a coarse pixel's
//! frustum), not at one place. That piece is a convex polygon, and it marks
//! every light pixel any of its points would mark
//! ([`ReceiverTarget::mark_points_within`]), at depths no tighter than
//! theirs.
//!
//! A polygon is clipped to the target's region in homogeneous coordinates
//! (as segments are), projected, and marked row by row: in each row's band
//! widened by the footprint (plus [`SEGMENT_SLACK_PX`]), the polygon's part
//! is convex, so its x extent and its depths (z/w is affine over a plane's
//! image) are those of its edges clipped to the band. Every pixel of the
//! row's widened x extent is marked with the part's farthest and nearest
//! depths, tightened to the polygon's depth plane over the pixel's
//! widened square where the plane is well conditioned.

use crate::band_extent::band_extent;
use crate::depth_plane::DepthPlane;
use crate::receiver_target::{floor, Projector, ReceiverTarget, SEGMENT_SLACK_PX};
use glam::{DVec4, Mat4, Vec4};

/// The most vertices a receiver polygon is marked with in one piece; a
/// longer one is marked as its fan of triangles.
pub const MAX_POLYGON_VERTICES: usize = 8;

/// Room for a polygon clipped by the four region planes: each clip of an
/// n-gon keeps at most 1.5 n vertices, so 8 grow to at most 41.
const CLIPPED: usize = 48;

impl ReceiverTarget {
    /// Marks receiver polygons: for each convex polygon (local points,
    /// clip `clip_from_local · p`, at most [`MAX_POLYGON_VERTICES`] in one
    /// piece), every pixel whose closed square, widened by `eps_px` (plus
    /// [`SEGMENT_SLACK_PX`]) on each side, meets the projected polygon,
    /// with the farthest (and, with [`ReceiverTarget::set_track_nearest`],
    /// the nearest) depth of the polygon's part in the pixel's widened
    /// row: a superset of what [`ReceiverTarget::mark_points_within`] marks
    /// for any points of the polygon, at depths no nearer. A polygon with a
    /// non-finite vertex marks nothing (as a NaN point); one reaching the
    /// centre of projection marks every pixel. Returns the number of pixels
    /// marked (counting repeats).
    pub fn mark_polygons_within<'p>(
        &mut self,
        clip_from_local: Mat4,
        polygons: impl IntoIterator<Item = &'p [Vec4]>,
        eps_px: f64,
    ) -> u64 {
        let pr = Projector::new(self.layout, clip_from_local, eps_px);
        let mut n = 0;
        for poly in polygons {
            if poly.len() <= MAX_POLYGON_VERTICES {
                n += self.mark_polygon(&pr, poly);
            } else {
                for i in 1..poly.len() - 1 {
                    n += self.mark_polygon(&pr, &[poly[0], poly[i], poly[i + 1]]);
                }
            }
        }
        n
    }

    /// Marks one polygon's pixels; returns how many.
    fn mark_polygon(&mut self, pr: &Projector, poly: &[Vec4]) -> u64 {
        let mut a = [DVec4::ZERO; CLIPPED];
        let mut n = 0;
        for p in poly {
            let c = (pr.m * *p).as_dvec4();
            if !c.is_finite() {
                return 0;
            }
            a[n] = c;
            n += 1;
        }
        if n == 0 {
            return 0;
        }
        let mut b = [DVec4::ZERO; CLIPPED];
        for (sx, sy, m) in pr.planes() {
            // Inside: m·w − (sx·x + sy·y) ≥ 0.
            let f = |c: DVec4| m * c.w - (sx * c.x + sy * c.y);
            let inside = a[..n].iter().filter(|c| f(**c) >= 0.0).count();
            if inside == n {
                continue;
            }
            if inside == 0 {
                return 0;
            }
            let mut k = 0;
            for i in 0..n {
                let (c0, c1) = (a[i], a[(i + 1) % n]);
                let (f0, f1) = (f(c0), f(c1));
                if f0 >= 0.0 && k < CLIPPED {
                    b[k] = c0;
                    k += 1;
                }
                if (f0 >= 0.0) != (f1 >= 0.0) && k < CLIPPED {
                    b[k] = c0 + (c1 - c0) * (f0 / (f0 - f1));
                    k += 1;
                }
            }
            std::mem::swap(&mut a, &mut b);
            n = k;
        }
        // Inside the region |x| ≤ mx·w, |y| ≤ my·w, w ≥ 0: a vertex at
        // w = 0 is the centre of projection, whose neighbourhood projects
        // anywhere at depths no farther than the polygon's others.
        let mut v = [(0.0f64, 0.0f64, 0.0f64); CLIPPED];
        let (mut far, mut apex) = (f64::INFINITY, false);
        for (c, v) in a[..n].iter().zip(&mut v) {
            *v = pr.project_clip(*c);
            if c.w > 0.0 && v.0.is_finite() && v.1.is_finite() && v.2.is_finite() {
                far = far.min(v.2);
            } else {
                apex = true;
            }
        }
        if apex {
            if !far.is_finite() {
                return 0;
            }
            for i in 0..self.depth.len() {
                self.mark_pixel(i, far as f32, f32::INFINITY);
            }
            return self.depth.len() as u64;
        }
        self.mark_projected(pr, &v[..n])
    }

    /// Marks a projected convex polygon (pixel coordinates and depth per
    /// vertex) row by row; returns how many pixels.
    fn mark_projected(&mut self, pr: &Projector, v: &[(f64, f64, f64)]) -> u64 {
        let e = pr.eps + SEGMENT_SLACK_PX;
        let (ylo, yhi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.1), hi.max(p.1))
            });
        let y0 = (-floor(1.0 + e - ylo)).max(0.0);
        let y1 = floor(yhi + e).min(pr.h - 1.0);
        if y0 > y1 {
            return 0;
        }
        let l = self.layout;
        let plane = DepthPlane::fit(v);
        let mut marked = 0;
        for y in y0 as u32..=y1 as u32 {
            let Some(((xlo, xhi), (zlo, zhi))) =
                band_extent(v, (f64::from(y) - e, f64::from(y) + 1.0 + e))
            else {
                continue;
            };
            let x0 = (-floor(1.0 + e - xlo)).max(0.0);
            let x1 = floor(xhi + e).min(pr.w - 1.0);
            if x0.is_nan() || x1.is_nan() || x0 > x1 {
                continue;
            }
            match plane {
                // The plane's extremes over each widened square, within the
                // row's: a large polygon marks each pixel as tightly as its
                // pieces would.
                Some((p, err)) => {
                    let yf = f64::from(y);
                    let ys = (yf - e, yf + 1.0 + e);
                    for x in x0 as u32..=x1 as u32 {
                        let xf = f64::from(x);
                        let xs = (xf - e, xf + 1.0 + e);
                        let far = zlo.max(p.least(xs, ys) - err);
                        let near = zhi.min(p.greatest(xs, ys) + err);
                        self.mark_pixel(l.pixel_index(x, y), far as f32, near as f32);
                    }
                }
                None => {
                    let (far, near) = (zlo as f32, zhi as f32);
                    for x in x0 as u32..=x1 as u32 {
                        self.mark_pixel(l.pixel_index(x, y), far, near);
                    }
                }
            }
            marked += (x1 - x0) as u64 + 1;
        }
        marked
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DepthTarget, TileSize};
    use proptest::prelude::*;

    fn target(w: u32, h: u32) -> ReceiverTarget {
        let t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        let mut r = ReceiverTarget::for_target(&t);
        r.set_track_nearest(true);
        r
    }

    /// A light-like projection: reversed-Z perspective looking down −z.
    fn projection() -> Mat4 {
        Mat4::from_cols(
            Vec4::new(1.2, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.3, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        )
    }

    /// `(x, y)`'s marks in `a` lie within `b`'s: marked there too, no
    /// nearer at the farthest, no farther at the nearest.
    fn assert_within(points: &ReceiverTarget, polygon: &ReceiverTarget) -> usize {
        let (w, h) = points.size();
        let mut n = 0;
        for y in 0..h {
            for x in 0..w {
                let Some(far) = points.at(x, y) else { continue };
                n += 1;
                let pf = polygon.at(x, y);
                assert!(pf.is_some_and(|p| p <= far), "({x}, {y}): {pf:?} vs {far}");
                let (pn, qn) = (points.nearest_at(x, y), polygon.nearest_at(x, y));
                assert!(
                    qn.unwrap() >= pn.unwrap(),
                    "({x}, {y}): near {qn:?} vs {pn:?}"
                );
            }
        }
        n
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Every point of a polygon (sampled by convex combinations of its
        /// vertices) marks only pixels the polygon marks, at depths the
        /// polygon's marks contain; with a perspective, some vertices
        /// behind the centre of projection or off the target.
        #[test]
        fn polygons_mark_what_their_points_mark(
            verts in prop::collection::vec(
                (-3.0f32..3.0, -3.0f32..3.0, -4.0f32..0.5), 3..=8),
            weights in prop::collection::vec(prop::collection::vec(0.0f32..1.0, 8), 64),
            eps in prop_oneof![Just(0.0), Just(crate::RECEIVER_EPS_PX)],
        ) {
            // A convex polygon: the vertices' fan around their centroid,
            // kept as a triangle fan of the first vertex when planar
            // points are wanted: take the triangle (0, 1, 2)'s plane and
            // project the rest onto it.
            let p: Vec<Vec4> = verts.iter().map(|v| Vec4::new(v.0, v.1, v.2, 1.0)).collect();
            let (o, u, w) = (p[0].truncate(), p[1].truncate() - p[0].truncate(), p[2].truncate() - p[0].truncate());
            prop_assume!(u.cross(w).length() > 1e-3);
            // Vertices in the plane (o, u, w), ordered by angle: convex.
            let mut planar: Vec<(f32, Vec4)> = (0..verts.len()).map(|k| {
                let a = k as f32 / verts.len() as f32 * std::f32::consts::TAU;
                let r = 0.5 + 0.5 * (verts[k].0.abs() / 3.0);
                (a, (o + u * (r * a.cos()) + w * (r * a.sin())).extend(1.0))
            }).collect();
            planar.sort_by(|a, b| a.0.total_cmp(&b.0));
            let poly: Vec<Vec4> = planar.iter().map(|x| x.1).collect();
            let m = projection();
            let mut by_points = target(41, 37);
            let mut by_polygon = target(41, 37);
            by_polygon.mark_polygons_within(m, [&poly[..]], eps);
            let samples: Vec<Vec4> = weights.iter().map(|wt| {
                let s: f32 = wt[..poly.len()].iter().sum::<f32>().max(1e-6);
                poly.iter().zip(wt).map(|(v, k)| *v * (*k / s)).sum::<Vec4>()
            }).chain(poly.iter().copied()).collect();
            by_points.mark_points_within(m, &samples, eps);
            assert_within(&by_points, &by_polygon);
        }
    }

    /// A polygon marks no more than its widened bounds, and a triangle
    /// marks what its points do at the tightness of its rows.
    #[test]
    fn a_polygon_marks_its_rows_only() {
        let mut t = target(32, 32);
        // NDC square (−0.5, −0.5)–(0.5, 0.5) at depth 0.25: pixels 8–23.
        let q = [
            Vec4::new(-0.5, -0.5, 0.25, 1.0),
            Vec4::new(0.5, -0.5, 0.25, 1.0),
            Vec4::new(0.5, 0.5, 0.25, 1.0),
            Vec4::new(-0.5, 0.5, 0.25, 1.0),
        ];
        let n = t.mark_polygons_within(Mat4::IDENTITY, [&q[..]], 0.0);
        // Closed squares meeting [8, 24]²: pixels 7..=24 per axis.
        assert_eq!(n, 18 * 18);
        for y in 0..32 {
            for x in 0..32 {
                let inside = (7..=24).contains(&x) && (7..=24).contains(&y);
                assert_eq!(t.at(x, y), inside.then_some(0.25), "({x}, {y})");
            }
        }
        // Off the target, or with a NaN vertex: nothing.
        let mut u = target(32, 32);
        let off = q.map(|v| v + Vec4::new(3.0, 0.0, 0.0, 0.0));
        assert_eq!(u.mark_polygons_within(Mat4::IDENTITY, [&off[..]], 0.0), 0);
        let mut nan = q;
        nan[2].x = f32::NAN;
        assert_eq!(u.mark_polygons_within(Mat4::IDENTITY, [&nan[..]], 0.0), 0);
        assert_eq!(u.marked_rows(), None);
    }

    /// A polygon through the centre of projection marks every pixel, at
    /// its other vertices' farthest depth.
    #[test]
    fn a_polygon_through_the_light_marks_everywhere() {
        let mut t = target(16, 16);
        let m = projection();
        let poly = [
            Vec4::new(0.0, 0.0, 0.0, 1.0),
            Vec4::new(0.1, 0.0, -2.0, 1.0),
            Vec4::new(-0.1, 0.1, -3.0, 1.0),
        ];
        let n = t.mark_polygons_within(m, [&poly[..]], 0.0);
        assert_eq!(n, t.depth.len() as u64);
        let far = (m * poly[2]).z / (m * poly[2]).w;
        assert!((t.at(5, 5).unwrap() - far).abs() < 1e-6, "{:?}", t.at(5, 5));
    }
}
