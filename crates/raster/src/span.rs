//! Exact covered span of each pixel row of a triangle, from its edge functions.
//!
//! Along a row every edge function is affine in x with integer slope
//! `a·SUBPIXEL`, so the pixels whose centres pass `E_i + off_i ≥ 0` for all
//! three edges form one interval: loops that walk it do work proportional to
//! the covered pixels, not to the bounding box (shadow-volume sides are long
//! slivers that cover a small part of their box).
//!
//! Edge values at pixel centres are integers below 2⁵³ (`edge.rs`), so they
//! and every product and sum formed here are exact in f64. Each edge's bound
//! on x is estimated without a division per row — the real-valued crossing
//! moves by a constant per row — and then corrected with exact tests, so the
//! span is exactly the set of pixels the per-pixel test accepts
//! (watertightness is unchanged).

use crate::edge::Tri;
use crate::setup::SUBPIXEL;

/// Row-by-row covered spans of one triangle within the columns `lo..=hi`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpanWalker {
    /// `E_i + off_i` at pixel `(lo, y0)`.
    v0: [f64; 3],
    /// Change of `E_i` per row.
    dy: [f64; 3],
    /// Change of `E_i` per pixel along x (`a·SUBPIXEL`).
    dx: [f64; 3],
    /// `−v0 / dx`: the real crossing of the edge at row `y0`, in pixels from `lo`.
    c0: [f64; 3],
    /// Change of the crossing per row.
    cy: [f64; 3],
    off: [f64; 3],
    lo: i64,
    hi: i64,
    y0: i64,
}

impl SpanWalker {
    /// Prepares the spans of `tri` with per-edge offsets `off` (the coverage
    /// rule) over the columns `lo..=hi`, rows from `y0`.
    #[inline(always)]
    pub fn new(tri: &Tri, off: &[i64; 3], lo: i64, hi: i64, y0: i64) -> Self {
        let v0 = [0, 1, 2].map(|i| (tri.e[i].at_pixel(lo, y0) + off[i]) as f64);
        let dy = tri.e.map(|e| (e.b * SUBPIXEL) as f64);
        let dx = tri.e.map(|e| (e.a * SUBPIXEL) as f64);
        let c0 = [0, 1, 2].map(|i| if dx[i] != 0.0 { -v0[i] / dx[i] } else { 0.0 });
        let cy = [0, 1, 2].map(|i| if dx[i] != 0.0 { -dy[i] / dx[i] } else { 0.0 });
        SpanWalker {
            v0,
            dy,
            dx,
            c0,
            cy,
            off: off.map(|o| o as f64),
            lo,
            hi,
            y0,
        }
    }

    /// The covered pixels `(a, b)` of row `y` (`a ≤ b`), with the raw edge
    /// values `E_i` (no offsets) at pixel `a`; `None` when the row is empty.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // four parallel per-edge arrays
    pub fn span(&self, y: i64) -> Option<(i64, i64, [f64; 3])> {
        let r = (y - self.y0) as f64;
        let n = (self.hi - self.lo) as f64;
        let (mut k0, mut k1) = (0.0f64, n);
        let mut v = [0.0; 3];
        for i in 0..3 {
            v[i] = self.v0[i] + self.dy[i] * r;
            let (vi, s) = (v[i], self.dx[i]);
            // Pixel k (from lo) passes iff vi + s·k ≥ 0.
            let pass = |k: f64| vi + s * k >= 0.0;
            if s == 0.0 {
                if vi < 0.0 {
                    return None;
                }
                continue;
            }
            // Estimate of the crossing (within one pixel, or clamped to just
            // outside the row; truncation, as `floor`/`ceil` are library calls
            // without SSE4.1), then the exact first/last passing pixel.
            let mut k = (self.c0[i] + self.cy[i] * r).clamp(-2.0, n + 2.0) as i64 as f64;
            if s > 0.0 {
                if vi < 0.0 {
                    while k <= n && !pass(k) {
                        k += 1.0;
                    }
                    while k > 0.0 && pass(k - 1.0) {
                        k -= 1.0;
                    }
                    k0 = k0.max(k);
                }
            } else {
                if vi < 0.0 {
                    return None;
                }
                while k >= 0.0 && !pass(k) {
                    k -= 1.0;
                }
                while k < n && pass(k + 1.0) {
                    k += 1.0;
                }
                k1 = k1.min(k);
            }
        }
        if k0 > k1 {
            return None;
        }
        let e = [0, 1, 2].map(|i| v[i] - self.off[i] + self.dx[i] * k0);
        Some((self.lo + k0 as i64, self.lo + k1 as i64, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coverage::{edge_offsets, Coverage, DepthPick};
    use crate::setup::SnappedVertex;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn span_is_exactly_the_covered_pixels(
            p in prop::array::uniform6(-30000i64..300000),
            shrink in 1i64..200,
            y in 0i64..100,
            cov in 0usize..2,
        ) {
            let v = |i: usize| SnappedVertex { x: p[2 * i] / shrink, y: p[2 * i + 1] / (4 * shrink), z: 0.5 };
            let Some(tri) = Tri::new(v(0), v(1), v(2)) else { return Ok(()) };
            let cov = [Coverage::Standard, Coverage::Outer(DepthPick::Nearest)][cov];
            let off = edge_offsets(&tri, cov);
            let (lo, hi) = (-5i64, 130i64);
            let brute: Vec<i64> = (lo..=hi)
                .filter(|&x| tri.e.iter().zip(&off).all(|(e, o)| e.at_pixel(x, y) + o >= 0))
                .collect();
            let w = SpanWalker::new(&tri, &off, lo, hi, -3);
            match w.span(y) {
                None => prop_assert!(brute.is_empty()),
                Some((a, b, e)) => {
                    prop_assert_eq!(brute, (a..=b).collect::<Vec<_>>());
                    for (ei, edge) in e.iter().zip(&tri.e) {
                        prop_assert_eq!(*ei, edge.at_pixel(a, y) as f64);
                    }
                }
            }
        }
    }
}
