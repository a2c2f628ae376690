//! Discrete clamping's occupancy test [Steiner §4.4.2, Listing 4.3; Lloyd et
//! al., CC shadow volumes]: per caster, the eye slices that hold a receiver
//! in its shadow (discrete clamping's slices, and the bands every caster's
//! volume is drawn in under continuous clamping).
//!
//! Listing 4.3 marks each caster's shadow in the light's view once, then
//! counts, per slice, the receivers drawn there. Here the light pass has
//! already marked the eye's visible surface in each light view (with the
//! nearest and farthest depth per light pixel), and a receiver in the
//! caster's shadow lies within the footprint of the caster's projected box
//! (`fragment_depths.rs`, "The rule"). Over each marked tile there, and
//! where a tile spans more than a few slices ([`WHOLE_TILE_DIVISOR`]) over
//! each marked pixel, the slice
//! coordinate `g` of the receivers is bounded at the corners of the
//! region's box (a ratio of affine functions of the light view's x, y and
//! z, with a positive denominator: its extremes lie at corners), the nearer
//! corners also taken where the receivers were before their push away from
//! the light. Every slice the bound meets is occupied. A tile whose slices
//! are all occupied already is skipped: most are.
//!
//! With outer-conservative marks (`coverage: conservative`) every receiver
//! point lies in the boxes read, so a slice with a shadowed sample is
//! occupied: the mask does not change. With point-sampled marks (`coverage:
//! point`) a receiver between samples may be missed: aggressive.

use crate::footprint::{pixel_rect, PixelNdc};
use crate::receivers::RECEIVER_PUSH;
use glam::{DMat4, DVec4};
use raster::ReceiverTarget;
use scene::{Aabb, Light};

/// Discrete clamping's slice coordinate as the light pass reads it:
/// `g(p) = num·(p, 1) / den·(p, 1)` for world points `p`, defined where
/// `den·(p, 1) > 0` (in front of the eye), and the slice boundaries.
#[derive(Clone, Copy, Debug)]
pub struct SliceRatio<'a> {
    /// Numerator, world homogeneous.
    pub num: DVec4,
    /// Denominator, world homogeneous.
    pub den: DVec4,
    /// Slice boundaries, ascending: slice `i` is `edges[i]..edges[i + 1]`;
    /// at most 65 (64 slices).
    pub edges: &'a [f64],
}

/// Most slices a [`SliceRatio`] may have.
pub const MAX_SLICES: usize = 64;

/// A marked tile whose `g` range meets at most `max(1, slices / 16)`
/// slices marks them all; a wider one is read pixel by pixel. At 64 slices
/// (the bands) a tile of four slices is marked whole: on the city bird view
/// that reads about half as long, and the street view's banded fill grows
/// by 1.4 %.
const WHOLE_TILE_DIVISOR: usize = 16;

/// `g` over one light view's clip space: for corner `c = (x, y, z, 1)` in
/// NDC, `num·c / den·c` as marked (`pushed`) and with the push undone
/// (`unpushed`), and `w·c` the world point's w.
struct ClipRatio {
    pushed: [DVec4; 2],
    unpushed: [DVec4; 2],
    w: DVec4,
    /// The view's pixels in NDC.
    pixels: PixelNdc,
}

impl ClipRatio {
    fn new(
        r: &SliceRatio<'_>,
        world_from_clip: &DMat4,
        light: &Light,
        diameter: f64,
        size: (u32, u32),
    ) -> Self {
        // Undoing twice the push is linear on homogeneous points: a
        // positional light scales towards it, a directional one shifts.
        let mu = 2.0 * RECEIVER_PUSH;
        let unpush = match *light {
            Light::Directional { direction } => {
                let s = -direction.normalize_or_zero() * (mu * diameter);
                DMat4::from_cols(DVec4::X, DVec4::Y, DVec4::Z, s.extend(1.0))
            }
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                let l = position * mu;
                DMat4::from_cols(DVec4::X, DVec4::Y, DVec4::Z, l.extend(1.0 + mu))
            }
        };
        let t = world_from_clip.transpose();
        let u = (unpush * *world_from_clip).transpose();
        ClipRatio {
            pushed: [t * r.num, t * r.den],
            unpushed: [u * r.num, u * r.den],
            w: t * DVec4::W,
            pixels: PixelNdc::new(size),
        }
    }

    /// The `g` range over the inclusive pixel rectangle `xs × ys` widened by
    /// the footprint, for receivers between depths `far` and `near`;
    /// unbounded where a corner is not in front of the eye or the light.
    fn range(&self, xs: (u32, u32), ys: (u32, u32), far: f32, near: f32) -> [f64; 2] {
        const ALL: [f64; 2] = [f64::NEG_INFINITY, f64::INFINITY];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for cx in self.pixels.edges(0, xs) {
            for cy in self.pixels.edges(1, ys) {
                for cz in [f64::from(far), f64::from(near)] {
                    let c = DVec4::new(cx, cy, cz, 1.0);
                    // NaN fails too.
                    if self.w.dot(c).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                        return ALL;
                    }
                    for [n, d] in [self.pushed, self.unpushed] {
                        let (n, d) = (n.dot(c), d.dot(c));
                        let g = n / d;
                        if !(d > 0.0 && g.is_finite()) {
                            return ALL;
                        }
                        lo = lo.min(g);
                        hi = hi.max(g);
                    }
                }
            }
        }
        [lo, hi]
    }
}

/// The bits of the slices `[lo, hi]` meets, of `edges`.
fn slice_bits(edges: &[f64], [lo, hi]: [f64; 2]) -> u64 {
    let n = edges.len() - 1;
    if hi < edges[0] || lo > edges[n] {
        return 0;
    }
    // Slice i = [edges[i], edges[i + 1]); the last one closed.
    let first = edges[1..n].partition_point(|&e| e <= lo);
    let last = edges[1..n].partition_point(|&e| e <= hi);
    let bits = |k: usize| if k >= 64 { u64::MAX } else { (1u64 << k) - 1 };
    bits(last + 1) & !bits(first)
}

/// Appends to `out` the occupied slices of the caster with world bounds
/// `bounds`, as `(id, [edges[i], edges[j + 1]])` per run `i..=j` of them,
/// read from `marks` in the view whose `world_from_clip` and
/// `clip_from_world` are given (module docs). Returns the marked pixels
/// read one by one.
#[allow(clippy::too_many_arguments)]
pub(crate) fn read_caster(
    r: &SliceRatio<'_>,
    id: u32,
    bounds: &Aabb,
    light: &Light,
    diameter: f64,
    (clip_from_world, world_from_clip): (&DMat4, &DMat4),
    marks: &ReceiverTarget,
    out: &mut Vec<(u32, [f64; 2])>,
) -> u64 {
    let n = r.edges.len().saturating_sub(1);
    if n == 0 || n > MAX_SLICES {
        return 0;
    }
    let size = marks.size();
    let Some((xs, ys)) = pixel_rect(clip_from_world, bounds, size.0, size.1) else {
        return 0;
    };
    let ratio = ClipRatio::new(r, world_from_clip, light, diameter, size);
    let full = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
    let whole = (n / WHOLE_TILE_DIVISOR).max(1) as u32;
    let (mut occupied, mut pixels) = (0u64, 0u64);
    marks.for_each_tile_in(xs, ys, |t| {
        if occupied == full {
            return;
        }
        let bits = slice_bits(r.edges, ratio.range(t.x, t.y, t.far, t.near));
        if bits & !occupied == 0 {
            return;
        }
        if bits.count_ones() <= whole {
            occupied |= bits;
            return;
        }
        t.for_each_marked(|x, y, far, near| {
            pixels += 1;
            occupied |= slice_bits(r.edges, ratio.range((x, x), (y, y), far, near));
        });
    });
    // Runs of occupied slices.
    let mut i = 0;
    while i < n {
        if occupied >> i & 1 == 0 {
            i += 1;
            continue;
        }
        let mut j = i;
        while j + 1 < n && occupied >> (j + 1) & 1 == 1 {
            j += 1;
        }
        out.push((id, [r.edges[i], r.edges[j + 1]]));
        i = j + 1;
    }
    pixels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_of_ranges() {
        let e = [0.0, 10.0, 20.0, 30.0];
        assert_eq!(slice_bits(&e, [1.0, 2.0]), 0b001);
        assert_eq!(slice_bits(&e, [5.0, 10.0]), 0b011);
        assert_eq!(slice_bits(&e, [-5.0, 35.0]), 0b111);
        assert_eq!(slice_bits(&e, [35.0, 40.0]), 0);
        assert_eq!(slice_bits(&e, [f64::NEG_INFINITY, f64::INFINITY]), 0b111);
        assert_eq!(slice_bits(&e, [29.0, 30.0]), 0b100);
    }
}
