//! Occupied depth intervals of a caster's shadow volume [Steiner §4.4.1,
//! Listing 4.2; Lloyd et al., CC shadow volumes]: the depths along the light's
//! view where a receiver may stand in the caster's shadow. Segments are built
//! only over these intervals (`segments.rs`, §4.4.3).
//!
//! Depth is the light view's distance along its axis (clip w of a perspective
//! view, the view-space distance of an orthographic one), constant on the
//! planes that bound the segments.
//!
//! # The rule, and where it departs from Listing 4.2
//! A receiver R may lie in caster C's shadow when their image-plane
//! rectangles overlap ([`crate::SweepPrune`]) and R's far depth is at least
//! C's near depth: the text's rule. R then occupies `[max(R.near, C.near),
//! R.far]`, cut at C's near depth because no shadow of C lies nearer the
//! light than C. Listing 4.2 instead skips every receiver whose near depth
//! is below C's ("encountered" casters only), which drops a wall that stands
//! beside C and reaches behind it; that would lose shadow, so here the cut
//! replaces the skip. C's own interval is always occupied (self-shadowing).
//!
//! Occupied intervals are merged in increasing near depth with the listing's
//! three cases: contained (nothing to do), overlapping (extend the last
//! interval's far end), disjoint (a new interval, unless the gap is cheaper to
//! fill than to bridge with another segment; see [`GapCost`]).

/// The cost model that decides whether a gap between two occupied intervals
/// becomes a break between segments [Steiner eqs. 4.2–4.3]: a new segment
/// costs `V = (2C + 2S)·v` (its two caps, C cap vertices each, and its sides
/// along the S silhouette vertices), filling the gap costs `R = A·r` for A
/// pixels of gap. The gap stays open when `V < R`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GapCost {
    /// Cost per volume vertex, v.
    pub per_vertex: f64,
    /// Cost per pixel of stencil fill, r.
    pub per_pixel: f64,
    /// Cap vertices of one segment cap, C.
    pub cap_vertices: u32,
    /// Silhouette vertices of the caster, S.
    pub silhouette_vertices: u32,
}

impl GapCost {
    /// True when a gap of `area` pixels is worth a new segment (`V < R`).
    pub fn keeps_gap(&self, area: f64) -> bool {
        let v = f64::from(2 * self.cap_vertices.saturating_add(self.silhouette_vertices));
        v * self.per_vertex < area * self.per_pixel
    }
}

/// Estimates the pixels a caster's volume covers between two depths.
pub type GapArea<'a> = &'a dyn Fn(f64, f64) -> f64;

/// The occupied intervals of caster depth `caster` given the depth
/// intervals of the receivers whose rectangles overlap it, sorted, disjoint
/// and merged where touching, written to `out` (cleared first).
///
/// `gap_area(near, far)` estimates the pixels the volume covers between two
/// depths; a gap whose fill costs less than a new segment is closed
/// ([`GapCost::keeps_gap`]). With `cost = None` every gap stays open.
/// Non-finite or inverted depths are read conservatively: NaN bounds widen to
/// ±∞, inverted ones swap.
pub fn occupied_intervals(
    caster: [f64; 2],
    receivers: impl IntoIterator<Item = [f64; 2]>,
    cost: Option<(&GapCost, GapArea<'_>)>,
    out: &mut Vec<[f64; 2]>,
) {
    out.clear();
    let c = sanitized(caster);
    out.push(c);
    out.extend(
        (receivers.into_iter().map(sanitized))
            .filter(|r| r[1] >= c[0])
            .map(|r| [r[0].max(c[0]), r[1]]),
    );
    out.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]));
    let mut kept = 0;
    for k in 1..out.len() {
        let next = out[k];
        let last = &mut out[kept];
        if next[0] <= last[1] {
            // Cases 1 and 2: contained or overlapping.
            last[1] = last[1].max(next[1]);
        } else if cost.is_some_and(|(m, area)| !m.keeps_gap(area(last[1], next[0]))) {
            // Case 3, but the gap is cheaper to fill.
            last[1] = next[1];
        } else {
            kept += 1;
            out[kept] = next;
        }
    }
    out.truncate(kept + 1);
}

fn sanitized([lo, hi]: [f64; 2]) -> [f64; 2] {
    let lo = if lo.is_nan() { f64::NEG_INFINITY } else { lo };
    let hi = if hi.is_nan() { f64::INFINITY } else { hi };
    if lo <= hi {
        [lo, hi]
    } else {
        [hi, lo]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn intervals(c: [f64; 2], r: &[[f64; 2]]) -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        occupied_intervals(c, r.iter().copied(), None, &mut out);
        out
    }

    #[test]
    fn the_three_cases_and_the_cut_at_the_caster() {
        // Contained, overlapping, disjoint; a receiver wholly nearer the
        // light is dropped; one reaching behind the caster is cut at it.
        let out = intervals(
            [10.0, 12.0],
            &[
                [10.5, 11.0],
                [11.5, 14.0],
                [20.0, 21.0],
                [1.0, 5.0],
                [2.0, 30.5],
            ],
        );
        assert_eq!(out, [[10.0, 30.5]]);
        let out = intervals(
            [10.0, 12.0],
            &[[10.5, 11.0], [11.5, 14.0], [20.0, 21.0], [1.0, 5.0]],
        );
        assert_eq!(out, [[10.0, 14.0], [20.0, 21.0]]);
    }

    #[test]
    fn the_cost_model_closes_cheap_gaps() {
        let m = GapCost {
            per_vertex: 1.0,
            per_pixel: 1.0,
            cap_vertices: 10,
            silhouette_vertices: 15,
        };
        // V = 50: a gap of 40 pixels is filled, one of 60 kept.
        let area = |a: f64, b: f64| (b - a) * 10.0;
        let mut out = Vec::new();
        occupied_intervals(
            [0.0, 1.0],
            [[5.0, 6.0], [12.0, 13.0]],
            Some((&m, &area)),
            &mut out,
        );
        assert_eq!(out, [[0.0, 6.0], [12.0, 13.0]]);
        assert!(m.keeps_gap(50.5) && !m.keeps_gap(50.0));
    }

    proptest! {
        /// Every receiver depth behind the caster's near depth lies in an
        /// interval; intervals are sorted, disjoint, start at the caster and
        /// end at the farthest receiver or the caster; merging gaps only
        /// grows the covered set.
        #[test]
        fn intervals_cover_every_shadowed_receiver_depth(
            c in (0.0f64..100.0, 0.0f64..20.0),
            rs in prop::collection::vec((0.0f64..150.0, 0.0f64..20.0, 0.0f64..=1.0), 0..20),
            per_pixel in 0.0f64..2.0,
        ) {
            let caster = [c.0, c.0 + c.1];
            let recv: Vec<[f64; 2]> = rs.iter().map(|&(a, l, _)| [a, a + l]).collect();
            let open = intervals(caster, &recv);
            let m = GapCost { per_vertex: 1.0, per_pixel, cap_vertices: 4, silhouette_vertices: 8 };
            let area = |a: f64, b: f64| (b - a) * 3.0;
            let mut merged = Vec::new();
            occupied_intervals(caster, recv.iter().copied(), Some((&m, &area)), &mut merged);
            for out in [&open, &merged] {
                prop_assert_eq!(out[0][0], caster[0]);
                prop_assert!(out.windows(2).all(|w| w[0][1] < w[1][0] && w[0][0] <= w[0][1]));
                let far = recv.iter().filter(|r| r[1] >= caster[0]).fold(caster[1], |f, r| f.max(r[1]));
                prop_assert_eq!(out.last().unwrap()[1], far);
                let inside = |z: f64| out.iter().any(|i| i[0] <= z && z <= i[1]);
                for (r, &(_, _, t)) in recv.iter().zip(&rs) {
                    let z = (r[0] + (r[1] - r[0]) * t).clamp(r[0], r[1]);
                    if z >= caster[0] {
                        prop_assert!(inside(z), "depth {} of {:?} outside {:?}", z, r, out);
                    }
                }
            }
            // Merging only closes gaps: every open interval is inside a merged one.
            for i in &open {
                prop_assert!(merged.iter().any(|m| m[0] <= i[0] && i[1] <= m[1]));
            }
        }
    }
}
