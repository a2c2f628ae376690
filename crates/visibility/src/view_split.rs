//! A crowded light view, culled as four quadrants.
//!
//! The views of a light run in parallel, one per thread ([`crate::LightPass`]).
//! A street view's receivers crowd one cube face, and a directional light
//! has one view only: that view's traversal was the light pass's longest
//! single-threaded step (city_16384 street, 1280×1024: one face held 15,238
//! receiver pieces, another one). A view that holds the light's receivers
//! all but alone is therefore culled as its four quadrants: four views of
//! half its side on the same pixel grid, each traversed by its own culler,
//! which the threads share; each quadrant also draws only the rows of its
//! own receivers.
//!
//! Quadrants cost: each marks all of the view's receivers (clipped to it)
//! and traverses the hierarchy again. Where other views hold receivers too,
//! they already give the other threads work, and splitting lost (city
//! street 800×600, point light: one face held 16,231 pieces, two others 111
//! and 83, yet those took 3 and 2 ms; light pass 6.0 → 7.4 ms split). So a
//! view is split only when every other view holds at most
//! 1/[`TRACE`] of its receivers. A quadrant sees the pixels of its quarter of the view
//! exactly as the whole view does (the same sample positions), so the union
//! of the quadrants' casters is the view's: culling stays conservative and
//! the masks do not change. Only the counters move (an object over a
//! quadrant edge is queried and drawn in each quadrant it reaches).
//!
//! The rule reads only receiver counts, never the pool's size: the same
//! scene gives the same casters and counters on any number of threads, and
//! with a host's backends (asked for each quadrant) as with the bundled
//! rasterizer. Views are not split when their depth is kept as the hybrid's
//! shadow maps (read as whole views) or when the pass reads fragment
//! intervals (a caster's are read in the views it was found in).
//!
//! Measured (`shadow_bench … --stencil h --culling chcpp --reps 11`, five
//! interleaved rounds, medians): city_16384 street 1280×1024, point light:
//! light pass 5.11 → 3.19 ms, frame 18.7 → 15.3 ms; city street 800×600,
//! sun: light pass 5.88 → 4.81 ms; city street, point light: not split.
//! PSC and masks: unchanged masks (0 mismatches); PSC may differ by a few
//! casters (city_16384: 78 → 75), both conservative.

use crate::light_view::LightView;
use glam::{DMat4, DVec4};

/// Smallest view side that is split (quadrants of at least 32 pixels).
pub(crate) const MIN_SPLIT_RESOLUTION: u32 = 64;

/// A view is split when every other view of its light holds at most
/// `1/TRACE` of its receivers (a trace: such a view's traversal is short).
pub(crate) const TRACE: usize = 256;

/// The views to cull for the fitted `views`: each view as it is, or, when
/// it holds receivers (`receivers(view)`: the points or pieces it marks)
/// and every other view at most 1/[`TRACE`] as many, and its side is even
/// and at least [`MIN_SPLIT_RESOLUTION`], its four [`quadrants`] in its
/// place.
pub(crate) fn cull_views_into(
    views: &[LightView],
    receivers: impl Fn(&LightView) -> usize,
    out: &mut Vec<LightView>,
) {
    out.clear();
    // The crowded view: the first with the most receivers.
    let crowded = (views.iter().enumerate())
        .map(|(k, v)| (receivers(v), std::cmp::Reverse(k)))
        .max()
        .filter(|&(n, std::cmp::Reverse(k))| {
            let r = views[k].resolution;
            n > 0
                && r.is_multiple_of(2)
                && r >= MIN_SPLIT_RESOLUTION
                && (views.iter().enumerate())
                    .all(|(j, v)| j == k || receivers(v).saturating_mul(TRACE) <= n)
        })
        .map(|(_, std::cmp::Reverse(k))| k);
    for (k, view) in views.iter().enumerate() {
        if Some(k) == crowded {
            out.extend(quadrants(view));
        } else {
            out.push(*view);
        }
    }
}

/// The four quadrants of `view`, each `resolution / 2` pixels on a side:
/// clip `x' = 2x ± w`, `y' = 2y ± w` maps each quarter of the view's clip
/// square onto a whole one, so quadrant pixel `i` of the low half is view
/// pixel `i`, and of the high half view pixel `i + resolution / 2` (the
/// same sample positions). Depth and `w` are the view's.
pub(crate) fn quadrants(view: &LightView) -> [LightView; 4] {
    [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)].map(|(sx, sy)| {
        let s = DMat4::from_cols(
            DVec4::new(2.0, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 2.0, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 1.0, 0.0),
            DVec4::new(sx, sy, 0.0, 1.0),
        );
        LightView {
            clip_from_world: s * view.clip_from_world,
            kind: view.kind,
            resolution: view.resolution / 2,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light_view::LightViewKind;
    use glam::DVec3;
    use proptest::prelude::*;

    fn view(resolution: u32) -> LightView {
        face(resolution, 0)
    }

    fn face(resolution: u32, k: u8) -> LightView {
        // Looking down −z from (0.3, −0.2, 10), focal length 1.5 (clip w = −z).
        let proj = DMat4::from_cols(
            DVec4::new(1.5, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 1.5, 0.0, 0.0),
            DVec4::new(0.0, 0.0, -1.0, -1.0),
            DVec4::new(0.0, 0.0, 1.0, 0.0),
        );
        let look = DMat4::from_translation(DVec3::new(-0.3, 0.2, -10.0));
        LightView {
            clip_from_world: proj * look,
            kind: LightViewKind::CubeFace(k),
            resolution,
        }
    }

    /// Pixel coordinates (continuous) of a clip point in a view of side `r`.
    fn pixel(c: DVec4, r: u32) -> (f64, f64) {
        let r = f64::from(r);
        ((c.x / c.w + 1.0) * 0.5 * r, (c.y / c.w + 1.0) * 0.5 * r)
    }

    proptest! {
        /// A point inside the view lies in exactly the quadrants whose clip
        /// square holds it (one, or more on a shared edge), at the view's
        /// pixel position less the quadrant's offset.
        #[test]
        fn quadrants_keep_the_pixel_grid(
            p in prop::array::uniform3(-6.0f64..6.0),
        ) {
            let v = view(256);
            let q = quadrants(&v);
            let c = v.clip_from_world * DVec3::from_array(p).extend(1.0);
            prop_assume!(v.covers(DVec3::from_array(p), 0.0) && c.w > 1e-3);
            let (px, py) = pixel(c, 256);
            let mut holders = 0;
            for (k, quad) in q.iter().enumerate() {
                let (ox, oy) = (128.0 * (k % 2) as f64, 128.0 * (k / 2) as f64);
                let (qx, qy) = pixel(quad.clip_from_world * DVec3::from_array(p).extend(1.0), 128);
                prop_assert!((qx - (px - ox)).abs() < 1e-6 && (qy - (py - oy)).abs() < 1e-6);
                if quad.covers(DVec3::from_array(p), 1e-12) {
                    holders += 1;
                    prop_assert!((-1e-6..=128.0 + 1e-6).contains(&qx));
                    prop_assert!((-1e-6..=128.0 + 1e-6).contains(&qy));
                }
            }
            prop_assert!(holders >= 1);
        }
    }

    /// Only a view whose receivers the others hold at most a trace of is
    /// split, and only at an even side of at least 64.
    #[test]
    fn only_the_crowded_view_is_split() {
        let views = [face(256, 0), face(256, 1), face(256, 2)];
        let mut out = Vec::new();
        let by_res = |counts: [usize; 3]| {
            move |v: &LightView| match v.kind {
                LightViewKind::CubeFace(k) => counts[k as usize],
                _ => unreachable!("cube faces only"),
            }
        };
        cull_views_into(&views, by_res([1, 512, 2]), &mut out);
        assert_eq!(out.len(), 6);
        assert_eq!(out[0], views[0]);
        assert!(out[1..5].iter().all(|v| v.resolution == 128));
        assert_eq!(out[1..5], quadrants(&views[1]));
        assert_eq!(out[5], views[2]);
        cull_views_into(&views, by_res([0, 512, 3]), &mut out);
        assert_eq!(out, views, "a third view holds more than a trace");
        cull_views_into(&views, by_res([40, 40, 20]), &mut out);
        assert_eq!(out, views);
        cull_views_into(&views, by_res([0, 0, 0]), &mut out);
        assert_eq!(out, views);
        for r in [255, 32] {
            let odd = [view(r)];
            cull_views_into(&odd, |_| 5, &mut out);
            assert_eq!(out, odd);
        }
        let one = [view(64)];
        cull_views_into(&one, |_| 5, &mut out);
        assert_eq!(out.len(), 4);
    }
}
