//! Fixed-point edge functions with the top-left fill rule [Pineda 1988;
//! D3D10 rasterization rules].
//!
//! Vertices are snapped to 1/256 pixel ([`crate::setup`]); an edge `a → b`
//! has the exact integer edge function
//! `E(p) = (b.x − a.x)(p.y − a.y) − (b.y − a.y)(p.x − a.x)` (i64; every
//! value stays below 2^53, so it is also exact in f64). The triangle is
//! oriented so that `E ≥ 0` inside. A pixel centre on an edge belongs to
//! the triangle only when the edge is a top or left edge (inward normal
//! `(A, B)` with `A > 0`, or `A = 0` and `B > 0`, screen y down). Two
//! triangles sharing an edge see exactly negated functions and exactly one of
//! them owns the edge, so no pixel centre is covered twice or missed.

use crate::setup::{SnappedVertex, SUBPIXEL};

/// One edge function `E(p) = a·(p.x − ox) + b·(p.y − oy)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edge {
    pub a: i64,
    pub b: i64,
    pub ox: i64,
    pub oy: i64,
    pub top_left: bool,
}

impl Edge {
    fn new(from: SnappedVertex, to: SnappedVertex) -> Edge {
        let a = -(to.y - from.y);
        let b = to.x - from.x;
        Edge {
            a,
            b,
            ox: from.x,
            oy: from.y,
            top_left: a > 0 || (a == 0 && b > 0),
        }
    }

    /// The exact edge function at the fixed-point point `(px, py)`.
    #[inline(always)]
    pub fn eval(&self, px: i64, py: i64) -> i64 {
        self.a * (px - self.ox) + self.b * (py - self.oy)
    }

    /// The edge function at the centre of pixel `(x, y)`.
    #[inline(always)]
    pub fn at_pixel(&self, x: i64, y: i64) -> i64 {
        self.eval(x * SUBPIXEL + SUBPIXEL / 2, y * SUBPIXEL + SUBPIXEL / 2)
    }
}

/// A set-up triangle of a fan: oriented edge functions and depth interpolation.
///
/// Edge `i` is opposite vertex `i`, so `E_i / area` is vertex `i`'s barycentric weight.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tri {
    pub e: [Edge; 3],
    /// Vertex depths, `z[i]` at vertex `i`.
    pub z: [f64; 3],
    pub inv_area: f64,
    /// Smallest and largest vertex depth.
    pub zlo: f64,
    pub zhi: f64,
    /// Depth gradient per pixel in x and y.
    pub dzdx: f64,
    pub dzdy: f64,
    /// Fixed-point bounding box (inclusive).
    pub xmin: i64,
    pub xmax: i64,
    pub ymin: i64,
    pub ymax: i64,
}

impl Tri {
    /// Sets up `(v0, v1, v2)`; `None` when the snapped area is zero.
    #[inline(always)]
    pub fn new(v0: SnappedVertex, v1: SnappedVertex, v2: SnappedVertex) -> Option<Tri> {
        let area = (v1.x - v0.x) * (v2.y - v0.y) - (v1.y - v0.y) * (v2.x - v0.x);
        if area == 0 {
            return None;
        }
        let (v1, v2) = if area > 0 { (v1, v2) } else { (v2, v1) };
        let area = area.abs();
        let e = [Edge::new(v1, v2), Edge::new(v2, v0), Edge::new(v0, v1)];
        let z = [v0.z, v1.z, v2.z];
        let inv_area = 1.0 / area as f64;
        let s = SUBPIXEL as f64;
        let dzdx =
            (e[0].a as f64 * z[0] + e[1].a as f64 * z[1] + e[2].a as f64 * z[2]) * s * inv_area;
        let dzdy =
            (e[0].b as f64 * z[0] + e[1].b as f64 * z[1] + e[2].b as f64 * z[2]) * s * inv_area;
        Some(Tri {
            e,
            z,
            inv_area,
            zlo: z[0].min(z[1]).min(z[2]),
            zhi: z[0].max(z[1]).max(z[2]),
            dzdx,
            dzdy,
            xmin: v0.x.min(v1.x).min(v2.x),
            xmax: v0.x.max(v1.x).max(v2.x),
            ymin: v0.y.min(v1.y).min(v2.y),
            ymax: v0.y.max(v1.y).max(v2.y),
        })
    }

    /// Plane depth from the three raw edge values at a point: `Σ E_i·z_i / area`.
    /// Inside the triangle all terms are non-negative, so the f64 result has a
    /// relative error below 5·2⁻⁵³.
    #[inline(always)]
    pub fn depth(&self, e0: i64, e1: i64, e2: i64) -> f64 {
        (e0 as f64 * self.z[0] + e1 as f64 * self.z[1] + e2 as f64 * self.z[2]) * self.inv_area
    }

    /// `Σ |E_i|·z_i / area`: the scale of the rounding error of [`Tri::depth`] at a point.
    #[inline(always)]
    pub fn depth_scale(&self, e0: i64, e1: i64, e2: i64) -> f64 {
        (e0.unsigned_abs() as f64 * self.z[0]
            + e1.unsigned_abs() as f64 * self.z[1]
            + e2.unsigned_abs() as f64 * self.z[2])
            * self.inv_area
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: i64, y: i64) -> SnappedVertex {
        SnappedVertex { x, y, z: 0.5 }
    }

    #[test]
    fn shared_edges_negate_and_one_owns() {
        let (a, b) = (v(10, 700), v(900, 33));
        let e1 = Edge::new(a, b);
        let e2 = Edge::new(b, a);
        for (px, py) in [(0, 0), (450, 366), (1000, -5)] {
            assert_eq!(e1.eval(px, py), -e2.eval(px, py));
        }
        assert_ne!(e1.top_left, e2.top_left);
    }

    #[test]
    fn barycentric_depth_is_one_at_vertices() {
        let t = Tri::new(
            SnappedVertex { x: 0, y: 0, z: 1.0 },
            SnappedVertex {
                x: 2560,
                y: 0,
                z: 0.5,
            },
            SnappedVertex {
                x: 0,
                y: 2560,
                z: 0.25,
            },
        )
        .unwrap();
        let at = |x: i64, y: i64| {
            let e = t.e.map(|e| e.eval(x, y));
            t.depth(e[0], e[1], e[2])
        };
        assert!((at(0, 0) - 1.0).abs() < 1e-15);
        assert!((at(2560, 0) - 0.5).abs() < 1e-15);
        assert!((at(0, 2560) - 0.25).abs() < 1e-15);
        assert!((t.dzdx - (-0.5 / 10.0)).abs() < 1e-15);
    }
}
