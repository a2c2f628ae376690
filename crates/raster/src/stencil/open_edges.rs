//! Open edges of a volume's rasterized surface, and the boundary rule for them
//! [Aila04 §3.2.1; the zpass rule of this project's hierarchical-stencil issue].
//!
//! Stage 1 gives a tile one count, taken at a sample pixel, when no piece of the
//! volume crosses the tile's box. Why one sample stands for every pixel: the
//! count at a pixel centre is the signed coverage of the *counted* pieces (those
//! in front of the tile for zpass and zp+, behind it for zfail), a 2-chain on
//! the screen. Between two pixel centres of the tile it changes only where the
//! boundary of that chain separates them. An edge shared by two counted pieces
//! cancels (snapped, watertight edge functions with the top-left rule). An edge
//! shared by a counted piece and an uncounted one cannot pass through the tile:
//! both planes take the same depth on it, which would have to be in front of
//! the box and behind it at once. So the count is the same at every pixel centre
//! unless the tile meets an *open* edge, one that no other piece of the volume
//! shares:
//!
//! - the caster-side edges of a zpass volume (its side surface is open where it
//!   meets the caster: the silhouette edges);
//! - edges the near plane cut (zpass and zfail volumes; zp+ closes them with
//!   its near-cap fans);
//! - edges left alone when a neighbouring piece vanished: a piece whose snapped
//!   area is zero, a triangle seen exactly edge-on, a vertex that could not be
//!   projected. (Guard-band cuts are open too but lie far outside the target.)
//!
//! They are found exactly, as the directed snapped edges (with their depths) of
//! the volume's drawn pieces that no opposite edge cancels. The rule for an open
//! edge of a zpass or zp+ volume: every tile it crosses is a boundary tile if,
//! within the tile, the edge reaches in front of the tile box's far depth
//! (`zmin`, reversed Z); a piece in front of the box that ends at the edge must
//! have the edge's depth there, so an edge wholly behind `zmin` borders no
//! counted piece in that tile. For zfail, symmetrically, the edge must reach
//! behind the box's near depth `zmax`. The test is on the snapped segment with
//! the tile widened by one sub-pixel step and depths widened by `2⁻²⁰`
//! relative, beyond the f32 rounding of the classification.

use crate::coverage::Rect;
use crate::setup::{SnappedVertex, SUBPIXEL};

/// A directed snapped edge, stored with its endpoints in canonical order and the
/// direction as a sign.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EdgeRec {
    key: (i64, i64, u64, i64, i64, u64),
    sign: i32,
}

fn vkey(v: &SnappedVertex) -> (i64, i64, u64) {
    (v.x, v.y, v.z.to_bits())
}

/// Appends the directed edges `v0 → v1`, `v1 → v2`, `v2 → v0` of a drawn
/// piece whose flag in `keep` is set (a caller leaves out a pair it knows
/// cancels).
pub(crate) fn push_piece_edges(v: [SnappedVertex; 3], keep: [bool; 3], out: &mut Vec<EdgeRec>) {
    for ((a, b), _) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
        .into_iter()
        .zip(keep)
        .filter(|(_, k)| *k)
    {
        let (ka, kb) = (vkey(&a), vkey(&b));
        let (lo, hi, sign) = match ka.cmp(&kb) {
            std::cmp::Ordering::Less => (ka, kb, 1),
            std::cmp::Ordering::Greater => (kb, ka, -1),
            std::cmp::Ordering::Equal => continue,
        };
        out.push(EdgeRec {
            key: (lo.0, lo.1, lo.2, hi.0, hi.1, hi.2),
            sign,
        });
    }
}

/// An open edge on the screen: snapped endpoints with their depths.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Segment {
    ax: f64,
    ay: f64,
    az: f64,
    bx: f64,
    by: f64,
    bz: f64,
    /// Pixel rows the segment can reach (inclusive, unclamped).
    pub y0: i64,
    pub y1: i64,
}

/// Sorts `edges` and appends every edge whose directed copies do not cancel to `out`.
pub(crate) fn open_edges(edges: &mut [EdgeRec], out: &mut Vec<Segment>) {
    edges.sort_unstable_by_key(|e| e.key);
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        let mut net = 0;
        while j < edges.len() && edges[j].key == edges[i].key {
            net += edges[j].sign;
            j += 1;
        }
        if net != 0 {
            let k = edges[i].key;
            let s = SUBPIXEL as f64;
            let (ay, by) = (k.1 as f64, k.4 as f64);
            out.push(Segment {
                ax: k.0 as f64,
                ay,
                az: f64::from_bits(k.2),
                bx: k.3 as f64,
                by,
                bz: f64::from_bits(k.5),
                y0: ((ay.min(by) - s) / s).floor() as i64 - 1,
                y1: ((ay.max(by) + s) / s).ceil() as i64 + 1,
            });
        }
        i = j;
    }
}

impl Segment {
    /// Parameter interval `[t0, t1]` of the segment inside the pixel-centre
    /// rectangle `x0..=x1 × y0..=y1` widened by one sub-pixel step; `None` when it
    /// misses.
    fn clip(&self, x0: i64, x1: i64, y0: i64, y1: i64) -> Option<(f64, f64)> {
        let s = SUBPIXEL as f64;
        let c = |p: i64, d: f64| p as f64 * s + 0.5 * s + d;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, d, lo, hi) in [
            (self.ax, self.bx - self.ax, c(x0, -1.0), c(x1, 1.0)),
            (self.ay, self.by - self.ay, c(y0, -1.0), c(y1, 1.0)),
        ] {
            if d == 0.0 {
                if p < lo || p > hi {
                    return None;
                }
                continue;
            }
            let (ta, tb) = ((lo - p) / d, (hi - p) / d);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        // A little slack for the divisions' rounding.
        (t0 <= t1 + 1e-12).then_some((t0 - 1e-12, t1 + 1e-12))
    }

    /// Pixel columns the segment can reach on the rows `ya..=yb` (inclusive,
    /// widened by a pixel each side); `None` when it misses those rows.
    pub fn columns(&self, ya: i64, yb: i64) -> Option<(i64, i64)> {
        let (t0, t1) = self.clip(i64::MIN / 1024, i64::MAX / 1024, ya, yb)?;
        let s = SUBPIXEL as f64;
        let xa = self.ax + (self.bx - self.ax) * t0.clamp(0.0, 1.0);
        let xb = self.ax + (self.bx - self.ax) * t1.clamp(0.0, 1.0);
        let col = |x: f64| ((x - 0.5 * s) / s).floor() as i64;
        Some((col(xa.min(xb)) - 1, col(xa.max(xb)) + 2))
    }

    /// Whether the open edge makes the tile with pixel-centre rectangle
    /// `rect = (x0, x1, y0, y1)` and written depths `[zmin, zmax]` a boundary tile,
    /// for a volume counted in front of the surface (`!zfail`) or behind it.
    pub fn marks(&self, rect: Rect, zmin: f32, zmax: f32, zfail: bool) -> bool {
        let Some((t0, t1)) = self.clip(rect.x0, rect.x1, rect.y0, rect.y1) else {
            return false;
        };
        let z = |t: f64| self.az + (self.bz - self.az) * t.clamp(0.0, 1.0);
        let (za, zb) = (z(t0), z(t1));
        let (elo, ehi) = (za.min(zb), za.max(zb));
        let m = (ehi.abs().max(f64::from(zmax).abs())) * (1.0 / 1_048_576.0) + 1e-300;
        if zfail {
            elo - m <= f64::from(zmax)
        } else {
            ehi + m >= f64::from(zmin)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: i64, y: i64, z: f64) -> SnappedVertex {
        SnappedVertex {
            x: x * SUBPIXEL,
            y: y * SUBPIXEL,
            z,
        }
    }

    /// Two triangles sharing an edge leave the four outer edges open; a closed
    /// tetrahedron-like fan leaves none.
    #[test]
    fn shared_edges_cancel() {
        let (a, b, c, d) = (v(0, 0, 0.5), v(10, 0, 0.5), v(0, 10, 0.5), v(10, 10, 0.4));
        let mut e = Vec::new();
        push_piece_edges([a, b, c], [true; 3], &mut e);
        push_piece_edges([c, b, d], [true; 3], &mut e);
        let mut out = Vec::new();
        open_edges(&mut e, &mut out);
        assert_eq!(out.len(), 4);
        // The same surface plus its reverse is closed.
        let mut e = Vec::new();
        push_piece_edges([a, b, c], [true; 3], &mut e);
        push_piece_edges([c, b, d], [true; 3], &mut e);
        push_piece_edges([a, c, b], [true; 3], &mut e);
        push_piece_edges([c, d, b], [true; 3], &mut e);
        out.clear();
        open_edges(&mut e, &mut out);
        assert!(out.is_empty());
        // Screen edges at another depth do not cancel: only the shared a–c does.
        let mut e = Vec::new();
        push_piece_edges([a, b, c], [true; 3], &mut e);
        push_piece_edges([a, c, v(10, 0, 0.25)], [true; 3], &mut e);
        out.clear();
        open_edges(&mut e, &mut out);
        assert_eq!(out.len(), 4);
    }

    #[test]
    fn marks_follow_the_depth_rule() {
        let mut e = Vec::new();
        // A horizontal edge through row 4 from x = 0 to 40 at depth 0.5.
        push_piece_edges(
            [v(0, 4, 0.5), v(40, 4, 0.5), v(20, 30, 0.5)],
            [true; 3],
            &mut e,
        );
        let mut out = Vec::new();
        open_edges(&mut e, &mut out);
        let seg = out
            .iter()
            .find(|s| s.ay == s.by && s.ay == (4 * SUBPIXEL) as f64)
            .unwrap();
        let tile = Rect {
            x0: 0,
            x1: 7,
            y0: 0,
            y1: 7,
        };
        // zpass: the edge is in front of zmin = 0.3 → boundary; behind zmin = 0.6 → not.
        assert!(seg.marks(tile, 0.3, 0.4, false));
        assert!(!seg.marks(tile, 0.6, 0.7, false));
        // zfail: behind zmax = 0.6 → boundary; in front of zmax = 0.4 → not.
        assert!(seg.marks(tile, 0.5, 0.6, true));
        assert!(!seg.marks(tile, 0.3, 0.4, true));
        // A tile the edge misses.
        assert!(!seg.marks(
            Rect {
                x0: 0,
                x1: 7,
                y0: 16,
                y1: 23
            },
            0.0,
            1.0,
            false
        ));
        assert_eq!(
            seg.columns(0, 7).map(|(a, b)| a <= 0 && b >= 40),
            Some(true)
        );
        assert!(seg.columns(16, 23).is_none());
    }
}
