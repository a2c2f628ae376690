//! Coverage modes: which pixels a triangle covers and which depth it has there.
//!
//! - Standard: the pixel centre `(x + ½, y + ½)` lies in the triangle (top-left rule).
//! - Outer-conservative: the closed pixel square meets the closed triangle
//!   (separating axes: the three edge normals and the two axes, exact in integers).
//! - Inner-conservative: the closed pixel square lies inside the closed triangle.
//!
//! In the conservative modes the depth is a bound over pixel ∩ triangle:
//! [`DepthPick::Nearest`] gives a depth at least as near as every point of it
//! (min of the plane's maximum over the pixel square and the largest vertex
//! depth), [`DepthPick::Farthest`] at least as far; both widened by the
//! evaluation error and rounded outward to f32. A clipped triangle is
//! rasterized as a fan, and these definitions hold per fan triangle.

use crate::edge::Tri;
use crate::setup::SUBPIXEL;

/// Which depth a conservative coverage mode writes or tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DepthPick {
    /// A bound at least as near as the nearest point of pixel ∩ triangle.
    Nearest,
    /// A bound at least as far as the farthest point of pixel ∩ triangle.
    Farthest,
}

/// How pixels are covered (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Coverage {
    /// Pixel centres, top-left rule; depth interpolated at the centre.
    #[default]
    Standard,
    /// The closed pixel square meets the closed triangle.
    Outer(DepthPick),
    /// The closed pixel square lies inside the closed triangle.
    Inner(DepthPick),
}

/// Per-edge constants so that a pixel is covered iff `E_i(centre) + off[i] ≥ 0` for all i.
#[inline]
pub(crate) fn edge_offsets(tri: &Tri, cov: Coverage) -> [i64; 3] {
    let half = SUBPIXEL / 2;
    tri.e.map(|e| match cov {
        Coverage::Standard => -(i64::from(!e.top_left)),
        Coverage::Outer(_) => (e.a.abs() + e.b.abs()) * half,
        Coverage::Inner(_) => -(e.a.abs() + e.b.abs()) * half,
    })
}

/// ⌊a / SUBPIXEL⌋ (SUBPIXEL = 2⁸: an arithmetic shift).
#[inline(always)]
fn floor_div(a: i64, b: i64) -> i64 {
    debug_assert_eq!(b, SUBPIXEL);
    a >> 8
}

/// ⌈a / SUBPIXEL⌉.
#[inline(always)]
fn ceil_div(a: i64, b: i64) -> i64 {
    debug_assert_eq!(b, SUBPIXEL);
    -((-a) >> 8)
}

/// An inclusive pixel rectangle `[x0, x1] × [y0, y1]` (rows down from the
/// top): what a triangle can cover, a tile, a scissor window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Rect {
    pub x0: i64,
    pub x1: i64,
    pub y0: i64,
    pub y1: i64,
}

impl Rect {
    /// The unbounded rectangle (no clipping).
    pub const ALL: Rect = Rect {
        x0: i64::MIN,
        x1: i64::MAX,
        y0: i64::MIN,
        y1: i64::MAX,
    };

    /// The common part of `self` and `o` (empty when [`Rect::is_empty`]).
    #[inline(always)]
    pub fn intersect(self, o: Rect) -> Rect {
        Rect {
            x0: self.x0.max(o.x0),
            x1: self.x1.min(o.x1),
            y0: self.y0.max(o.y0),
            y1: self.y1.min(o.y1),
        }
    }

    /// No pixel inside.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.x0 > self.x1 || self.y0 > self.y1
    }
}

/// The pixels that can be covered, clamped to the `width × height` target;
/// `None` when empty.
#[inline(always)]
pub(crate) fn pixel_bounds(tri: &Tri, cov: Coverage, width: u32, height: u32) -> Option<Rect> {
    let s = SUBPIXEL;
    let (x0, x1, y0, y1) = match cov {
        Coverage::Outer(_) => (
            ceil_div(tri.xmin - s, s),
            floor_div(tri.xmax, s),
            ceil_div(tri.ymin - s, s),
            floor_div(tri.ymax, s),
        ),
        _ => (
            ceil_div(tri.xmin - s / 2, s),
            floor_div(tri.xmax - s / 2, s),
            ceil_div(tri.ymin - s / 2, s),
            floor_div(tri.ymax - s / 2, s),
        ),
    };
    let (x0, y0) = (x0.max(0), y0.max(0));
    let (x1, y1) = (x1.min(width as i64 - 1), y1.min(height as i64 - 1));
    (x0 <= x1 && y0 <= y1).then_some(Rect { x0, x1, y0, y1 })
}

/// Rounds up to the next f32 at or above `x` (`f32::next_up` done by the bits,
/// without branches on the value: it runs per triangle and per pixel).
#[inline(always)]
pub(crate) fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    let b = f.to_bits();
    let up = if f > 0.0 {
        b + 1
    } else if f == 0.0 {
        1
    } else {
        b - 1
    };
    if (f as f64) < x {
        f32::from_bits(up)
    } else {
        f
    }
}

/// Rounds down to the next f32 at or below `x` (see [`f32_up`]).
#[inline(always)]
pub(crate) fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    let b = f.to_bits();
    let down = if f > 0.0 {
        b - 1
    } else if f == 0.0 {
        0x8000_0001
    } else {
        b + 1
    };
    if (f as f64) > x {
        f32::from_bits(down)
    } else {
        f
    }
}

/// Relative error allowance of the f64 plane evaluation (generous: 8 ulps).
pub(crate) const PLANE_EPS: f64 = 8.0 * f64::EPSILON;

/// Depth written or tested at a covered pixel with raw edge values `e` (the
/// definition the traversal's vectorized rows reproduce bit for bit).
#[cfg(test)]
pub(crate) fn pixel_depth(tri: &Tri, cov: Coverage, e: [i64; 3]) -> f32 {
    match cov {
        Coverage::Standard => tri.depth(e[0], e[1], e[2]) as f32,
        Coverage::Outer(p) | Coverage::Inner(p) => {
            let zc = tri.depth(e[0], e[1], e[2]);
            let half = 0.5 * (tri.dzdx.abs() + tri.dzdy.abs()) * (1.0 + PLANE_EPS);
            let slack = PLANE_EPS * tri.depth_scale(e[0], e[1], e[2]);
            match p {
                DepthPick::Nearest => f32_up((zc + half + slack).min(tri.zhi)),
                DepthPick::Farthest => f32_down((zc - half - slack).max(tri.zlo)),
            }
        }
    }
}

/// Bounds `(lo, hi)` on every depth [`pixel_depth`] can produce at pixel centres whose
/// raw edge values are convex combinations of `corners`.
#[inline(always)]
pub(crate) fn depth_range(tri: &Tri, cov: Coverage, corners: &[[i64; 3]; 4]) -> (f32, f32) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut scale: f64 = 0.0;
    for c in corners {
        let z = tri.depth(c[0], c[1], c[2]);
        lo = lo.min(z);
        hi = hi.max(z);
        scale = scale.max(tri.depth_scale(c[0], c[1], c[2]));
    }
    let slack = 2.0 * PLANE_EPS * scale;
    let mut lo = lo - slack;
    let mut hi = hi + slack;
    if cov != Coverage::Standard {
        let half = 0.5 * (tri.dzdx.abs() + tri.dzdy.abs()) * (1.0 + PLANE_EPS);
        lo -= half;
        hi += half;
    }
    (f32_down(lo.max(tri.zlo)), f32_up(hi.min(tri.zhi)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The branch-free roundings equal rounding by `f32::next_up` /
    /// `f32::next_down` everywhere: signed zeros, subnormals, exact values,
    /// overflow to infinity and NaN included.
    #[test]
    fn branch_free_roundings_match_next_up_and_down() {
        let up = |x: f64| {
            let f = x as f32;
            if (f as f64) < x {
                f.next_up()
            } else {
                f
            }
        };
        let down = |x: f64| {
            let f = x as f32;
            if (f as f64) > x {
                f.next_down()
            } else {
                f
            }
        };
        let mut v = vec![
            0.0,
            -0.0,
            1e-45,
            -1e-45,
            1e-300,
            -1e-300,
            0.5,
            1.0,
            -1.0,
            0.1,
            1e39,
            -1e39,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut x = 0.123_456_789f64;
        for _ in 0..10_000 {
            x = (x * 7919.0 + 0.377).fract();
            v.extend([x, -x, x * 1e-40, x * 3e5]);
        }
        for x in v {
            assert_eq!(f32_up(x).to_bits(), up(x).to_bits(), "{x:e}");
            assert_eq!(f32_down(x).to_bits(), down(x).to_bits(), "{x:e}");
        }
    }

    #[test]
    fn outward_rounding() {
        let x = 0.1f64;
        assert!(f32_up(x) as f64 >= x && f32_down(x) as f64 <= x);
        assert_eq!(f32_up(0.5), 0.5);
        assert_eq!(f32_down(0.5), 0.5);
    }
}

#[cfg(test)]
mod div_tests {
    use super::*;

    #[test]
    fn shifts_are_floor_and_ceil() {
        for a in -1000i64..1000 {
            assert_eq!(floor_div(a, SUBPIXEL), a.div_euclid(SUBPIXEL));
            assert_eq!(ceil_div(a, SUBPIXEL), -(-a).div_euclid(SUBPIXEL));
        }
    }
}
