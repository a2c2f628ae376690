//! Software prefetch of the depth tiles the next box queries will read.
//!
//! A 1080p depth target is 8 MB, and boxes sorted front to back land all over the
//! screen, so the first depth load of nearly every box query missed the caches:
//! in the bird's-eye benchmark that one stall was about a quarter of the query
//! time. [`crate::DepthTarget::query_aabbs`] looks a few boxes ahead, projects
//! two opposite corners and asks for the depth tiles between them and their
//! bounds. A hint only: nothing depends on it but timing. (The same for draws
//! measured no gain: a draw's loads are fewer per instruction.)

use crate::layout::{Layout, TileBounds};
use glam::{Mat4, Vec4};

/// Boxes looked ahead: enough to cover a memory latency with the work of the
/// queries in between.
pub(crate) const AHEAD: usize = 8;

/// Asks for the cache line holding `*p`.
#[inline(always)]
fn line<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: SSE is part of the x86_64 baseline, and a prefetch has no
        // architectural effect: it never faults and reads nothing the program sees
        // (the address comes from a reference anyway).
        unsafe { _mm_prefetch::<_MM_HINT_T0>((p as *const T).cast::<i8>()) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Pixel of the projection of local point `p`, when it lies in front of the eye
/// and inside the target.
#[inline(always)]
fn pixel(m: &Mat4, p: Vec4, l: &Layout) -> Option<(u32, u32)> {
    let c = *m * p;
    if c.w.is_nan() || c.w <= 0.0 {
        return None;
    }
    let x = (c.x / c.w + 1.0) * 0.5 * l.width as f32;
    let y = (1.0 - c.y / c.w) * 0.5 * l.height as f32;
    (x >= 0.0 && y >= 0.0 && x < l.width as f32 && y < l.height as f32)
        .then_some((x as u32, y as u32))
}

/// Tiles prefetched per item, at most, per axis.
const MAX_TILES: u32 = 3;

/// Prefetches the depth tiles (up to four lines each) and tile bounds of the
/// screen rectangle spanned by the projections of local points `a` and `b` (a
/// box's opposite corners), at most [`MAX_TILES`] per axis; nothing when either
/// does not project into the target.
#[inline(always)]
pub(crate) fn span(
    m: &Mat4,
    (a, b): (Vec4, Vec4),
    l: &Layout,
    depth: &[f32],
    tiles: &[TileBounds],
) {
    let (Some(pa), Some(pb)) = (pixel(m, a, l), pixel(m, b, l)) else {
        return;
    };
    let s = l.shift;
    let (tx0, ty0) = (pa.0.min(pb.0) >> s, pa.1.min(pb.1) >> s);
    let (tx1, ty1) = (
        (pa.0.max(pb.0) >> s).min(tx0 + MAX_TILES - 1),
        (pa.1.max(pb.1) >> s).min(ty0 + MAX_TILES - 1),
    );
    for ty in ty0..ty1 + 1 {
        for tx in tx0..tx1 + 1 {
            let t = l.tile_index(tx, ty);
            if let Some(b) = tiles.get(t) {
                line(b);
            }
            let base = t << (2 * s);
            for k in (0..l.tile_pixels().min(64)).step_by(16) {
                if let Some(d) = depth.get(base + k) {
                    line(d);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_map_to_their_pixel_or_to_nothing() {
        let l = Layout {
            width: 64,
            height: 48,
            tiles_x: 8,
            tiles_y: 6,
            shift: 3,
        };
        // Reversed-Z perspective with an infinite far plane (DESIGN.md).
        let f = 1.0 / 0.5f32.tan();
        let m = Mat4::from_cols(
            Vec4::new(f * 48.0 / 64.0, 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.5, 0.0),
        );
        // Straight ahead: the centre pixel.
        assert_eq!(
            pixel(&m, Vec4::new(0.0, 0.0, -5.0, 1.0), &l),
            Some((32, 24))
        );
        // Behind the eye, far outside the view, at infinity sideways, NaN: nothing.
        for p in [
            Vec4::new(0.0, 0.0, 5.0, 1.0),
            Vec4::new(100.0, 0.0, -5.0, 1.0),
            Vec4::new(1.0, 0.0, 0.0, 0.0),
            Vec4::new(f32::NAN, 0.0, -5.0, 1.0),
        ] {
            assert_eq!(pixel(&m, p, &l), None, "{p}");
        }
        // A span over the whole view and one off it touch only valid tiles.
        let depth = vec![0f32; 64 * 48];
        let tiles = vec![
            TileBounds {
                zmin: 0.0,
                zmax: 0.0,
                background: 64
            };
            48
        ];
        let ends = (
            Vec4::new(-9.0, -9.0, -5.0, 1.0),
            Vec4::new(9.0, 9.0, -5.0, 1.0),
        );
        span(&m, ends, &l, &depth, &tiles);
        span(
            &m,
            (ends.0, Vec4::new(0.0, 0.0, 5.0, 1.0)),
            &l,
            &depth,
            &tiles,
        );
    }
}
