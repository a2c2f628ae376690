//! Stage 1 of the hierarchical stencil [Aila04 §3.2.1, App. A]: where a set-up
//! volume triangle piece lies relative to a tile's 3D box, decided so that the
//! per-pixel test of stage 2 can never disagree.
//!
//! A piece's fragment depth at pixel `p` is `fl32(((E_0·z_0 + E_1·z_1) + E_2·z_2)·inv)`
//! (`stencil_run.rs`): the plane `P(p) = Σ E_i(p)·z_i / area` through the piece's
//! snapped vertices, evaluated in f64 with exact integer `E_i`, then rounded to
//! f32. Over a rectangle of pixel centres `P` is affine, so its range is
//! `P(centre) ± (|∂P/∂x|·half_width + |∂P/∂y|·half_height)`.
//!
//! Error bound. With `M = z_0 + g_x·(|dx| + hw) + g_y·(|dy| + hh)`, where
//! `(dx, dy)` is the rectangle's centre relative to vertex 0 (pixels), `hw, hh`
//! its half extents, and `g_x = Σ|a_i|·z_i·256/area` (likewise `g_y` with `b_i`):
//! `M` bounds `Σ|E_i(p)|·z_i/area` over the rectangle (at vertex 0 the `E_i` are
//! `(area, 0, 0)`, and each `|E_i|` grows by at most `|a_i|·256` per pixel in x).
//! The per-pixel f64 evaluation errs by at most `6·2⁻⁵³` of that sum (no
//! cancellation bound is needed: the error is relative to the sum of the terms'
//! magnitudes), and this module's own estimate of the range (gradients with
//! relative error `5·2⁻⁵³` of `g`, three more roundings) by at most `2⁻⁴⁸·M`.
//! The bounds are widened by `2⁻⁴⁶·M`, four times the sum, so every computed
//! f64 fragment depth in the rectangle lies in `[lo, hi]`; rounding to f32 to
//! nearest is monotone, so every f32 fragment depth lies in
//! `[fl32(lo), fl32(hi)]`. Then, against a tile whose written depths lie in
//! `[zmin, zmax]`:
//!
//! - `fl32(lo) > zmax`: every fragment is strictly nearer than every written
//!   pixel, so the strict test passes everywhere ("in front");
//! - `fl32(hi) ≤ zmin`: it fails everywhere ("behind");
//! - otherwise the piece may meet the tile's box: a boundary tile.
//!
//! Vertex depths are `z/w` of post-clip vertices clamped to `[0, 1]`: no vertex
//! at clip `w = 0` reaches here (the guard-band planes clipped it), and triangles
//! crossing the near plane arrive as their near-clipped pieces.

use crate::coverage::{edge_offsets, Coverage, Rect};
use crate::edge::Tri;
use crate::setup::SUBPIXEL;

/// A piece's depth plane, anchored at its vertex 0, with the error scale.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PiecePlane {
    x0: f64,
    y0: f64,
    z0: f64,
    dzdx: f64,
    dzdy: f64,
    gx: f64,
    gy: f64,
    /// Edge offsets of standard coverage (top-left rule).
    off: [i64; 3],
}

/// `2⁻⁴⁶`: the widening of the depth range per unit of the error scale `M`.
const WIDEN: f64 = 1.0 / 70_368_744_177_664.0;

/// Slack of [`PiecePlane::side_clipped`]'s clip rectangle, in pixels: far
/// above the f64 rounding of the clipped vertices (about 2⁻³⁰ pixel at the
/// largest snapped coordinates).
const CLIP_SLACK: f64 = 1.0 / 65536.0;

/// Where a piece lies relative to a tile's box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    /// Strictly nearer than every written pixel of the tile at every pixel centre.
    Front,
    /// Not strictly nearer than any written pixel of the tile anywhere.
    Behind,
    /// Neither: the tile is a boundary tile for the piece's volume.
    Crossing,
}

impl PiecePlane {
    pub fn new(tri: &Tri) -> Self {
        let s = SUBPIXEL as f64;
        let v0 = &tri.e[2]; // edge v0 → v1 starts at vertex 0
        let scale = |f: fn(&crate::edge::Edge) -> i64| {
            (0..3)
                .map(|i| f(&tri.e[i]).unsigned_abs() as f64 * tri.z[i])
                .sum::<f64>()
                * s
                * tri.inv_area
        };
        PiecePlane {
            x0: v0.ox as f64 / s,
            y0: v0.oy as f64 / s,
            z0: tri.z[0],
            dzdx: tri.dzdx,
            dzdy: tri.dzdy,
            gx: scale(|e| e.a),
            gy: scale(|e| e.b),
            off: edge_offsets(tri, Coverage::Standard),
        }
    }

    /// Bounds `(lo, hi)` of every f32 fragment depth the rasterizer computes for
    /// the piece at the pixel centres `x0..=x1 × y0..=y1` (inclusive pixels).
    #[inline(always)]
    pub fn depth_bounds(&self, x0: i64, x1: i64, y0: i64, y1: i64) -> (f32, f32) {
        let (hw, hh) = (0.5 * (x1 - x0) as f64, 0.5 * (y1 - y0) as f64);
        let (dx, dy) = (
            0.5 * (x0 + x1) as f64 + 0.5 - self.x0,
            0.5 * (y0 + y1) as f64 + 0.5 - self.y0,
        );
        let mid = self.z0 + self.dzdx * dx + self.dzdy * dy;
        let ext = self.dzdx.abs() * hw + self.dzdy.abs() * hh;
        let m = WIDEN * (self.z0 + self.gx * (dx.abs() + hw) + self.gy * (dy.abs() + hh));
        (((mid - ext) - m) as f32, ((mid + ext) + m) as f32)
    }

    /// [`Side`] of the piece over the pixel rectangle, against written depths in
    /// `[zmin, zmax]`.
    #[inline(always)]
    pub fn side(&self, rect: Rect, zmin: f32, zmax: f32) -> Side {
        let (lo, hi) = self.depth_bounds(rect.x0, rect.x1, rect.y0, rect.y1);
        if lo > zmax {
            Side::Front
        } else if hi <= zmin {
            Side::Behind
        } else {
            Side::Crossing
        }
    }

    /// [`PiecePlane::side`] refined for a piece the plane test found
    /// [`Side::Crossing`]: the depth range over the piece's triangle clipped to
    /// the rectangle of pixel centres (not over the whole rectangle), which for
    /// the long, steep slivers of shadow volumes is far smaller. `None` when the
    /// triangle misses the rectangle: it covers none of its pixel centres and
    /// none of its edges passes through it.
    ///
    /// The clip runs in f64 on the snapped vertices (pixel units) against the
    /// rectangle widened by [`CLIP_SLACK`] pixels, so the computed polygon
    /// contains the true one despite rounding; the bounds add the plane's change
    /// over that slack to the widening of [`PiecePlane::depth_bounds`].
    pub fn side_clipped(&self, tri: &Tri, rect: Rect, zmin: f32, zmax: f32) -> Option<Side> {
        let s = SUBPIXEL as f64;
        let mut poly = [(0.0f64, 0.0f64); 9];
        let mut n = 3;
        // Tri's vertices: edge i starts at vertex i + 1 (see `Tri::new`).
        for (k, i) in [2usize, 0, 1].iter().enumerate() {
            poly[k] = (tri.e[*i].ox as f64 / s, tri.e[*i].oy as f64 / s);
        }
        let lim = [
            rect.x0 as f64 + 0.5 - CLIP_SLACK,
            rect.x1 as f64 + 0.5 + CLIP_SLACK,
            rect.y0 as f64 + 0.5 - CLIP_SLACK,
            rect.y1 as f64 + 0.5 + CLIP_SLACK,
        ];
        // Keep the side where `sign·(coord − bound) ≥ 0` for each of the 4 sides.
        for (axis, bound, sign) in [
            (0, lim[0], 1.0),
            (0, lim[1], -1.0),
            (1, lim[2], 1.0),
            (1, lim[3], -1.0),
        ] {
            let mut out = [(0.0f64, 0.0f64); 9];
            let mut m = 0;
            let d = |p: (f64, f64)| sign * (if axis == 0 { p.0 } else { p.1 } - bound);
            for k in 0..n {
                let (a, b) = (poly[k], poly[(k + 1) % n]);
                let (da, db) = (d(a), d(b));
                if da >= 0.0 {
                    out[m] = a;
                    m += 1;
                }
                if (da >= 0.0) != (db >= 0.0) {
                    let t = da / (da - db);
                    out[m] = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
                    m += 1;
                }
            }
            if m == 0 {
                return None;
            }
            poly = out;
            n = m;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in &poly[..n] {
            // Inside the widened rectangle by construction, up to rounding.
            let (x, y) = (x.clamp(lim[0], lim[1]), y.clamp(lim[2], lim[3]));
            let z = self.z0 + self.dzdx * (x - self.x0) + self.dzdy * (y - self.y0);
            lo = lo.min(z);
            hi = hi.max(z);
        }
        let (hw, hh) = (
            0.5 * (rect.x1 - rect.x0) as f64,
            0.5 * (rect.y1 - rect.y0) as f64,
        );
        let (dx, dy) = (
            0.5 * (rect.x0 + rect.x1) as f64 + 0.5 - self.x0,
            0.5 * (rect.y0 + rect.y1) as f64 + 0.5 - self.y0,
        );
        let m = WIDEN
            * (self.z0
                + self.gx * (dx.abs() + hw + 1.0)
                + self.gy * (dy.abs() + hh + 1.0)
                + self.dzdx.abs() * (2.0 * hw + 2.0)
                + self.dzdy.abs() * (2.0 * hh + 2.0))
            + (self.dzdx.abs() + self.dzdy.abs()) * 2.0 * CLIP_SLACK;
        let (lo, hi) = ((lo - m) as f32, (hi + m) as f32);
        Some(if lo > zmax {
            Side::Front
        } else if hi <= zmin {
            Side::Behind
        } else {
            Side::Crossing
        })
    }

    /// Whether standard coverage (top-left rule) includes pixel `(x, y)`'s centre.
    #[inline(always)]
    pub fn covers(&self, tri: &Tri, x: i64, y: i64) -> bool {
        (0..3).all(|i| tri.e[i].at_pixel(x, y) + self.off[i] >= 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::SnappedVertex;
    use proptest::prelude::*;

    fn rasterized_depth(tri: &Tri, x: i64, y: i64) -> f32 {
        let e = tri.e.map(|e| e.at_pixel(x, y) as f64);
        (((e[0] * tri.z[0] + e[1] * tri.z[1]) + e[2] * tri.z[2]) * tri.inv_area) as f32
    }

    proptest! {
        /// Every covered pixel's rasterized f32 depth lies within the bounds of any
        /// rectangle containing it, for slivers and steep planes too.
        #[test]
        fn bounds_contain_every_fragment(
            v in prop::array::uniform3((-4000i64..6000, -4000i64..6000, 0.0f64..=1.0)),
            rect in (0i64..16, 0i64..16, 1i64..12, 1i64..12),
        ) {
            let [a, b, c] = v.map(|(x, y, z)| SnappedVertex { x, y, z });
            let Some(tri) = Tri::new(a, b, c) else { return Ok(()); };
            let plane = PiecePlane::new(&tri);
            let (x0, y0) = (rect.0, rect.1);
            let (x1, y1) = (x0 + rect.2, y0 + rect.3);
            let (lo, hi) = plane.depth_bounds(x0, x1, y0, y1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    // Covered or not: the bound holds for the plane everywhere.
                    let z = rasterized_depth(&tri, x, y);
                    prop_assert!(lo <= z && z <= hi, "{lo} ≤ {z} ≤ {hi} at ({x}, {y})");
                }
            }
        }
    }

    proptest! {
        /// The clipped bounds contain every covered pixel's fragment depth in the
        /// rectangle, and a missed rectangle has no covered pixel.
        #[test]
        fn clipped_bounds_contain_every_covered_fragment(
            v in prop::array::uniform3((-4000i64..6000, -4000i64..6000, 0.0f64..=1.0)),
            rect in (0i64..16, 0i64..16, 0i64..12, 0i64..12),
        ) {
            let [a, b, c] = v.map(|(x, y, z)| SnappedVertex { x, y, z });
            let Some(tri) = Tri::new(a, b, c) else { return Ok(()); };
            let plane = PiecePlane::new(&tri);
            let r = Rect {
                x0: rect.0,
                x1: rect.0 + rect.2,
                y0: rect.1,
                y1: rect.1 + rect.3,
            };
            let covered: Vec<f32> = (r.y0..=r.y1)
                .flat_map(|y| (r.x0..=r.x1).map(move |x| (x, y)))
                .filter(|&(x, y)| plane.covers(&tri, x, y))
                .map(|(x, y)| rasterized_depth(&tri, x, y))
                .collect();
            match plane.side_clipped(&tri, r, 0.0, 1.0) {
                None => prop_assert!(covered.is_empty()),
                Some(_) => {
                    for &z in &covered {
                        // Against a box holding exactly z on either side.
                        prop_assert_ne!(plane.side_clipped(&tri, r, z, z), Some(Side::Front));
                        prop_assert_ne!(plane.side_clipped(&tri, r, z.next_down(), z.next_down()), Some(Side::Behind));
                        prop_assert_ne!(plane.side_clipped(&tri, r, z.next_up(), z.next_up()), Some(Side::Front));
                    }
                }
            }
        }
    }

    /// The widening stays far below one f32 step at the scale of the depths.
    #[test]
    fn bounds_are_tight_on_a_plain_triangle() {
        let v = |x: i64, y: i64, z: f64| SnappedVertex {
            x: x * 256,
            y: y * 256,
            z,
        };
        let tri = Tri::new(v(0, 0, 0.5), v(64, 0, 0.5), v(0, 64, 0.25)).unwrap();
        let plane = PiecePlane::new(&tri);
        let (lo, hi) = plane.depth_bounds(0, 7, 0, 7);
        let exact_lo = 0.5 - 0.25 * 7.5 / 64.0;
        let exact_hi = 0.5 - 0.25 * 0.5 / 64.0;
        assert!(
            (f64::from(lo) - exact_lo).abs() < 1e-7,
            "{lo} vs {exact_lo}"
        );
        assert!(
            (f64::from(hi) - exact_hi).abs() < 1e-7,
            "{hi} vs {exact_hi}"
        );
        assert_eq!(
            plane.side(
                Rect {
                    x0: 0,
                    x1: 7,
                    y0: 0,
                    y1: 7
                },
                0.6,
                0.7
            ),
            Side::Behind
        );
        assert_eq!(
            plane.side(
                Rect {
                    x0: 0,
                    x1: 7,
                    y0: 0,
                    y1: 7
                },
                0.1,
                0.2
            ),
            Side::Front
        );
        assert_eq!(
            plane.side(
                Rect {
                    x0: 0,
                    x1: 7,
                    y0: 0,
                    y1: 7
                },
                0.48,
                0.6
            ),
            Side::Crossing
        );
    }
}
