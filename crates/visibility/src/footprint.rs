//! A caster's footprint in a light view: where receivers in its shadow can
//! be marked (`fragment_depths.rs`, "The rule"). Shared by the readers of
//! fragment intervals and of occupied slices.

use glam::DMat4;
use raster::{RECEIVER_EPS_PX, SEGMENT_SLACK_PX};
use scene::Aabb;

/// Footprint of a marked pixel beyond its square, in pixels.
pub(crate) const FOOTPRINT_PX: f64 = RECEIVER_EPS_PX + SEGMENT_SLACK_PX;

/// The inclusive pixel ranges of `b`'s projection widened by a pixel (the
/// receivers' footprints and the query's coverage lie within), the whole
/// target when a corner lies at or behind the centre of projection; `None`
/// when the projection misses the target.
pub(crate) fn pixel_rect(m: &DMat4, b: &Aabb, w: u32, h: u32) -> Option<((u32, u32), (u32, u32))> {
    let whole = Some(((0, w.saturating_sub(1)), (0, h.saturating_sub(1))));
    let (mut x, mut y) = (
        [f64::INFINITY, f64::NEG_INFINITY],
        [f64::INFINITY, f64::NEG_INFINITY],
    );
    for p in b.corners() {
        let c = *m * p.as_dvec3().extend(1.0);
        if !(c.w > 0.0 && c.is_finite()) {
            return whole;
        }
        let px = (c.x / c.w + 1.0) * 0.5 * f64::from(w);
        let py = (1.0 - c.y / c.w) * 0.5 * f64::from(h);
        x = [x[0].min(px), x[1].max(px)];
        y = [y[0].min(py), y[1].max(py)];
    }
    let range = |r: [f64; 2], n: u32| {
        let a = (r[0] - 1.0).floor().max(0.0);
        let b = (r[1] + 1.0).ceil().min(f64::from(n) - 1.0);
        (a <= b).then_some((a as u32, b as u32))
    };
    Some((range(x, w)?, range(y, h)?))
}

/// A light view's pixel coordinates in normalized device coordinates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PixelNdc {
    /// NDC per pixel, per axis (0: x, 1: y).
    pub scale: [f64; 2],
    /// NDC at pixel 0, per axis.
    pub offset: [f64; 2],
}

impl PixelNdc {
    /// The mapping of a `w × h` target (row 0 at the top).
    pub fn new((w, h): (u32, u32)) -> Self {
        PixelNdc {
            scale: [2.0 / f64::from(w), -2.0 / f64::from(h)],
            offset: [-1.0, 1.0],
        }
    }

    /// The NDC along axis `k` (0: x, 1: y) of the edges of the inclusive
    /// pixel range `a..=b`, widened by the footprint.
    pub fn edges(&self, k: usize, (a, b): (u32, u32)) -> [f64; 2] {
        let (p, q) = (
            f64::from(a) - FOOTPRINT_PX,
            f64::from(b) + 1.0 + FOOTPRINT_PX,
        );
        [
            p * self.scale[k] + self.offset[k],
            q * self.scale[k] + self.offset[k],
        ]
    }
}
