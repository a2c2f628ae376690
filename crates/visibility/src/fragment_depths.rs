//! Fragment receivers for clamping [Steiner §4.4.1, Fig. 4.16; Lloyd et al.,
//! CC shadow volumes]: per caster, the depths along its clamping axis where
//! the eye's visible surface may lie in its shadow, read from the light
//! views' receiver targets instead of from receiver objects' bounds.
//!
//! # The rule
//! A receiver point r in caster C's shadow lies on a light ray through C. In
//! a light view that marked r (every point lies in the view holding it), r
//! projects where that ray's point of C does, so r's marks lie within the
//! footprint margin of C's projected box. Each marked light pixel there
//! holds the farthest and the nearest receiver depth over it
//! ([`raster::ReceiverTarget::set_track_nearest`]); the receivers of that
//! pixel lie in the region between those depths over the pixel's square
//! widened by the footprint. Depth along C's axis is a ratio of two affine
//! functions of the view's (x, y, z), so over that box its extremes are at
//! the eight corners: they bound the pixel's receivers along the axis. Cut
//! at C's nearest depth (no shadow of C lies nearer the light) and merged
//! where they overlap, these ranges are C's fragment intervals in this
//! view; the union over the light's views is C's set.
//!
//! # Margins
//! Conservative receivers are pushed away from the light by
//! [`crate::RECEIVER_PUSH`] before they are marked, which keeps the farthest
//! depth beyond the true one but the nearest not: each range's near end is
//! pulled back by twice the push (scaled towards the light for a positional
//! light, shifted along the direction for a directional one). A corner at or
//! behind the centre of projection, or any non-finite value, makes the range
//! unbounded. The segments' own margins (`shadowgen`'s `SEGMENT_MARGIN`)
//! come on top.

use crate::footprint::{pixel_rect, PixelNdc};
use crate::light_view::LightView;
use crate::receivers::RECEIVER_PUSH;
use crate::slice_occupancy::SliceRatio;
use glam::{DMat4, DVec3, DVec4};
use raster::{ReceiverTarget, TileMarks};
use scene::{Aabb, Light, ObjectId, Scene};

/// A caster's clamping axis: depth of world point `p` is `axis·(p − origin)`
/// (`axis` a unit vector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthAxis {
    /// Depth 0.
    pub origin: DVec3,
    /// Unit direction of increasing depth.
    pub axis: DVec3,
}

/// Gives the clamping axis of a caster with world bounds `bounds` under a
/// light, or `None` for a caster that is not clamped.
pub type AxisFn = dyn Fn(&Light, &Aabb) -> Option<DepthAxis> + Sync;

/// What the light pass reads fragment receivers along: either or both.
#[derive(Clone, Copy, Default)]
pub struct FragmentSource<'a> {
    /// Continuous clamping: each caster's depth intervals along its axis
    /// ([`LightPassResult::fragments`](crate::LightPassResult::fragments)).
    pub axes: Option<&'a AxisFn>,
    /// Each caster's occupied eye slices (`slice_occupancy.rs`), as
    /// intervals between slice boundaries: discrete clamping's slices, and
    /// the bands a caster's volume is drawn in
    /// ([`LightPassResult::slices`](crate::LightPassResult::slices)).
    pub slices: Option<SliceRatio<'a>>,
}

/// Per caster, its fragment intervals along its [`DepthAxis`]: sorted,
/// disjoint depth intervals, the union over one light's views. A caster
/// without an entry has no axis or was found in no view.
#[derive(Clone, Debug, Default)]
pub struct FragmentDepths {
    /// Casters with an entry, ascending.
    ids: Vec<u32>,
    /// `intervals[starts[k]..starts[k + 1]]` are `ids[k]`'s.
    starts: Vec<u32>,
    intervals: Vec<[f64; 2]>,
    /// The per-view ranges while they are gathered.
    gather: Vec<(u32, [f64; 2])>,
    /// Marked light pixels read one by one (a narrow tile read whole counts
    /// none), summed over casters and views.
    pub pixels: u64,
}

impl FragmentDepths {
    /// The fragment intervals of `caster`, `None` without an entry.
    pub fn get(&self, caster: ObjectId) -> Option<&[[f64; 2]]> {
        let k = self.ids.binary_search(&caster.slot()).ok()?;
        Some(&self.intervals[self.starts[k] as usize..self.starts[k + 1] as usize])
    }

    /// Casters with an entry.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when no caster has an entry.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// Forgets every entry (keeping the buffers).
    pub fn clear(&mut self) {
        self.ids.clear();
        self.starts.clear();
        self.intervals.clear();
        self.pixels = 0;
    }

    /// Sets the entries from per-view lists of `(caster, interval)` (each
    /// caster's intervals of one view sorted and disjoint): per caster, the
    /// union of its views' intervals, merged where they overlap.
    pub(crate) fn gather<'a>(&mut self, views: impl IntoIterator<Item = &'a [(u32, [f64; 2])]>) {
        self.ids.clear();
        self.starts.clear();
        self.intervals.clear();
        let mut all = std::mem::take(&mut self.gather);
        all.clear();
        for v in views {
            all.extend_from_slice(v);
        }
        all.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1[0].total_cmp(&b.1[0])));
        for &(id, r) in &all {
            if self.ids.last() != Some(&id) {
                self.ids.push(id);
                self.starts.push(self.intervals.len() as u32);
                self.intervals.push(r);
                continue;
            }
            let last = self.intervals.last_mut().expect("an entry has an interval");
            if r[0] <= last[1] {
                last[1] = last[1].max(r[1]);
            } else {
                self.intervals.push(r);
            }
        }
        self.starts.push(self.intervals.len() as u32);
        self.gather = all;
    }
}

/// What one view's fragment intervals are read from.
pub(crate) struct ViewFragments<'a> {
    pub scene: &'a Scene,
    pub light: &'a Light,
    pub source: FragmentSource<'a>,
    /// The scene's diameter (a directional light's push).
    pub diameter: f64,
}

/// One view's per-caster intervals, `(caster id, interval)`: along the
/// casters' axes and in the eye slices.
#[derive(Debug, Default)]
pub(crate) struct ViewIntervals {
    pub axes: Intervals,
    pub slices: Intervals,
    /// Marked light pixels read one by one, per kind.
    pub pixels: [u64; 2],
}

impl ViewIntervals {
    pub fn clear(&mut self) {
        self.axes.clear();
        self.slices.clear();
        self.pixels = [0, 0];
    }

    fn append(&mut self, other: &ViewIntervals) {
        self.axes.extend_from_slice(&other.axes);
        self.slices.extend_from_slice(&other.slices);
        self.pixels[0] += other.pixels[0];
        self.pixels[1] += other.pixels[1];
    }
}

impl ViewFragments<'_> {
    /// Appends to `out` the fragment intervals of each of `casters` (those
    /// that cast, and for the axes have one) in `view`, whose receivers
    /// `marks` holds with nearest depths; `ranges` is scratch. Many casters
    /// are read in parallel, in chunks whose lists are joined in order: the
    /// result is the sequential one.
    pub fn read(
        &self,
        view: &LightView,
        marks: &ReceiverTarget,
        casters: &[ObjectId],
        out: &mut ViewIntervals,
        ranges: &mut Vec<[f64; 2]>,
    ) {
        let world_from_clip = view.clip_from_world.inverse();
        let read = |id, out: &mut ViewIntervals, ranges: &mut Vec<_>| {
            self.caster(id, view, &world_from_clip, marks, out, ranges)
        };
        #[cfg(feature = "parallel")]
        if casters.len() >= 2 * PARALLEL_CHUNK && rayon::current_num_threads() > 1 {
            use rayon::prelude::*;
            let parts: Vec<ViewIntervals> = casters
                .par_chunks(PARALLEL_CHUNK)
                .map(|chunk| {
                    let (mut out, mut ranges) = (ViewIntervals::default(), Vec::new());
                    for &id in chunk {
                        read(id, &mut out, &mut ranges);
                    }
                    out
                })
                .collect();
            for part in &parts {
                out.append(part);
            }
            return;
        }
        for &id in casters {
            read(id, out, ranges);
        }
    }

    /// Appends caster `id`'s fragment intervals in `view` to `out`
    /// ([`ViewFragments::read`]).
    fn caster(
        &self,
        id: ObjectId,
        view: &LightView,
        world_from_clip: &DMat4,
        marks: &ReceiverTarget,
        out: &mut ViewIntervals,
        ranges: &mut Vec<[f64; 2]>,
    ) {
        let o = self.scene.object(id);
        if !o.flags.casts {
            return;
        }
        let bounds = o.world_bounds;
        if let Some(r) = &self.source.slices {
            let m = (&view.clip_from_world, world_from_clip);
            out.pixels[1] += crate::slice_occupancy::read_caster(
                r,
                id.slot(),
                &bounds,
                self.light,
                self.diameter,
                m,
                marks,
                &mut out.slices,
            );
        }
        if let Some(axes) = self.source.axes {
            out.pixels[0] += self.axis_caster(
                id,
                axes,
                bounds,
                view,
                world_from_clip,
                marks,
                &mut out.axes,
                ranges,
            );
        }
    }

    /// Appends caster `id`'s intervals along its axis in `view` to `out`;
    /// returns the pixels read one by one.
    #[allow(clippy::too_many_arguments)]
    fn axis_caster(
        &self,
        id: ObjectId,
        axes: &AxisFn,
        bounds: Aabb,
        view: &LightView,
        world_from_clip: &DMat4,
        marks: &ReceiverTarget,
        out: &mut Intervals,
        ranges: &mut Vec<[f64; 2]>,
    ) -> u64 {
        let Some(axis) = axes(self.light, &bounds) else {
            return 0;
        };
        let size = marks.size();
        let Some((xs, ys)) = pixel_rect(&view.clip_from_world, &bounds, size.0, size.1) else {
            return 0;
        };
        let near = box_near(&axis, &bounds);
        let depth = AxisDepth::new(world_from_clip, &axis, self.light, self.diameter, size);
        let narrow = f64::from(bounds.size().length()) * TILE_SPREAD;
        let mut pixels = 0;
        ranges.clear();
        // Neighbouring pixels' ranges mostly overlap: a range that meets
        // the last one kept grows it, so the sort below sees few.
        let mut keep = |[lo, hi]: [f64; 2]| {
            if hi < near {
                return;
            }
            let r = [lo.max(near), hi];
            match ranges.last_mut() {
                Some(last) if r[0] <= last[1] && last[0] <= r[1] => {
                    *last = [last[0].min(r[0]), last[1].max(r[1])];
                }
                _ => ranges.push(r),
            }
        };
        marks.for_each_tile_in(xs, ys, |t| {
            let whole = depth.range(t.x, t.y, t.far, t.near);
            if whole[1] < near {
                return;
            }
            if whole[1] - whole[0] <= narrow {
                keep(whole);
                return;
            }
            pixels += depth.pixel_ranges(t, &mut keep);
        });
        ranges.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]));
        let first = out.len();
        for &r in ranges.iter() {
            match out[first..].last_mut() {
                Some((_, last)) if r[0] <= last[1] => last[1] = last[1].max(r[1]),
                _ => out.push((id.slot(), r)),
            }
        }
        pixels
    }
}

/// Per caster, its intervals in one view: `(caster id, interval)`.
type Intervals = Vec<(u32, [f64; 2])>;

/// Casters per parallel task of [`ViewFragments::read`].
#[cfg(feature = "parallel")]
const PARALLEL_CHUNK: usize = 32;

/// A tile of marks whose depth range along a caster's axis spans at most
/// this fraction of the caster's bounding diagonal is read as one range
/// (its pixels' ranges lie within it); a wider one pixel by pixel, so that
/// gaps between receivers at different depths (a roof and the street
/// below) stay open.
pub const TILE_SPREAD: f64 = 1.0 / 16.0;

/// The depth of `b`'s nearest corner along `axis`.
fn box_near(axis: &DepthAxis, b: &Aabb) -> f64 {
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let p = DVec3::select(axis.axis.cmpge(DVec3::ZERO), lo, hi);
    axis.axis.dot(p - axis.origin)
}

/// Depth along one caster's axis as a function of a light view's pixel
/// coordinates `(px, py)` and depth `z`: `num·c / den·c` for the normalized
/// device coordinates `c = (x, y, z, 1)`.
struct AxisDepth {
    num: DVec4,
    den: DVec4,
    /// The view's pixels in NDC.
    pixels: PixelNdc,
    /// `den` does not depend on x and y (a perspective or orthographic
    /// view): the depth is affine in them at each z.
    affine_xy: bool,
    /// Positional light: the light's depth on the axis (the push scales
    /// depths towards it); directional: `None`.
    light_depth: Option<f64>,
    /// Directional light: the push along the axis.
    shift: f64,
}

impl AxisDepth {
    fn new(
        world_from_clip: &DMat4,
        axis: &DepthAxis,
        light: &Light,
        diameter: f64,
        size: (u32, u32),
    ) -> Self {
        let t = world_from_clip.transpose();
        let a = axis.axis;
        // depth = a·(p − o) with p = (I c).xyz / (I c).w.
        let num = t * a.extend(-a.dot(axis.origin));
        let den = t * DVec4::W;
        // x and y terms below 1e-12 of the rest change the depth by less
        // than that: far inside the margins.
        let affine_xy = den.x.abs().max(den.y.abs()) <= 1e-12 * (den.z.abs() + den.w.abs());
        let light_depth = light.position().map(|l| a.dot(l - axis.origin));
        AxisDepth {
            num,
            den,
            pixels: PixelNdc::new(size),
            affine_xy,
            light_depth,
            shift: if light_depth.is_some() {
                0.0
            } else {
                2.0 * RECEIVER_PUSH * diameter
            },
        }
    }

    /// Calls `f` with the depth range of every marked pixel of `t`, as
    /// [`AxisDepth::range`] gives it for the pixel alone; returns how many.
    fn pixel_ranges(&self, t: &TileMarks<'_>, mut f: impl FnMut([f64; 2])) -> u64 {
        let mut n = 0;
        if !self.affine_xy {
            t.for_each_marked(|x, y, far, near| {
                n += 1;
                f(self.range((x, x), (y, y), far, near));
            });
            return n;
        }
        // The x and y terms of the corners `range` picks, at the tile's
        // first pixel and per pixel step: the pick does not change along a
        // row or column (the sign of num's coefficient decides it).
        let (x0, y0) = (t.x.0, t.y.0);
        let [lo0, hi0] = self.xy_terms((x0, x0), (y0, y0));
        let scale = self.pixels.scale;
        let (sx, sy) = (self.num.x * scale[0], self.num.y * scale[1]);
        t.for_each_marked(|x, y, far, near| {
            n += 1;
            let step = sx * f64::from(x - x0) + sy * f64::from(y - y0);
            f(self.finish(lo0 + step, hi0 + step, far, near));
        });
        n
    }

    /// `num.w` plus the x and y terms of the corners of the inclusive pixel
    /// rectangle where the depth (affine in x and y) is least and greatest.
    fn xy_terms(&self, xs: (u32, u32), ys: (u32, u32)) -> [f64; 2] {
        let pick = |c: f64, r: [f64; 2]| {
            let (p, q) = (c * r[0], c * r[1]);
            [p.min(q), p.max(q)]
        };
        let (x, y) = (
            pick(self.num.x, self.pixels.edges(0, xs)),
            pick(self.num.y, self.pixels.edges(1, ys)),
        );
        [self.num.w + x[0] + y[0], self.num.w + x[1] + y[1]]
    }

    /// The range from the least and greatest x, y terms (affine case), over
    /// depths `far` to `near`, with the push's margin.
    #[inline(always)]
    fn finish(&self, base_lo: f64, base_hi: f64, far: f32, near: f32) -> [f64; 2] {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for z in [f64::from(far), f64::from(near)] {
            let d = self.den.z * z + self.den.w;
            let inv = 1.0 / d;
            let (a, b) = (
                (base_lo + self.num.z * z) * inv,
                (base_hi + self.num.z * z) * inv,
            );
            if !(d > 0.0 && a.is_finite() && b.is_finite()) {
                return [f64::NEG_INFINITY, f64::INFINITY];
            }
            lo = lo.min(a);
            hi = hi.max(b);
        }
        self.pulled([lo, hi])
    }

    /// `r` with its near end pulled back by the push (module docs, "Margins").
    fn pulled(&self, [lo, hi]: [f64; 2]) -> [f64; 2] {
        let lo = match self.light_depth {
            // Unpushed: l + (p − l)/(1 + push), so depths scale towards the
            // light's.
            Some(dl) if lo > dl => dl + (lo - dl) / (1.0 + 2.0 * RECEIVER_PUSH),
            Some(_) => lo,
            None => lo - self.shift,
        };
        [lo, hi]
    }

    /// The depth range along the axis of the receivers over the inclusive
    /// pixel rectangle `xs × ys` whose depths lie between `far` and `near`
    /// (module docs, "The rule" and "Margins").
    fn range(&self, xs: (u32, u32), ys: (u32, u32), far: f32, near: f32) -> [f64; 2] {
        if self.affine_xy {
            // At each z the depth is affine in x and y: its extremes over
            // the square are at the corners the signs of num pick; along z
            // it is monotone (a ratio of affine functions).
            let [lo, hi] = self.xy_terms(xs, ys);
            return self.finish(lo, hi, far, near);
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for cx in self.pixels.edges(0, xs) {
            for cy in self.pixels.edges(1, ys) {
                for cz in [f64::from(far), f64::from(near)] {
                    let c = DVec4::new(cx, cy, cz, 1.0);
                    let (n, d) = (self.num.dot(c), self.den.dot(c));
                    let v = n / d;
                    if !(d > 0.0 && v.is_finite()) {
                        return [f64::NEG_INFINITY, f64::INFINITY];
                    }
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
        self.pulled([lo, hi])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        /// A pixel's range holds the axis depth of every point over it: the
        /// points of the pixel's square, widened by the footprint, between
        /// its farthest and nearest depth, in a perspective view (reversed
        /// Z, infinite far plane; sheared as fitted views are) and an
        /// orthographic one, for any axis — on the affine path and on the
        /// general one (a view whose depth depends on x).
        #[test]
        fn pixel_ranges_hold_the_points_over_the_pixel(
            pixel in (0u32..64, 0u32..64),
            depths in (0.01f32..1.0, 0.01f32..1.0),
            axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
            origin in (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0),
            kind in 0usize..3,
            shear in -0.5f64..0.5,
            samples in proptest::collection::vec((-0.02f64..1.02, -0.02f64..1.02, 0.0f64..1.0), 1..12),
        ) {
            let a = DVec3::new(axis.0, axis.1, axis.2);
            proptest::prop_assume!(a.length() > 0.1);
            let axis = DepthAxis { origin: DVec3::new(origin.0, origin.1, origin.2), axis: a.normalize() };
            // From (0.5, 8, 0.5) looking down −y (view −z).
            let view = DMat4::from_rotation_x(std::f64::consts::FRAC_PI_2)
                * DMat4::from_translation(DVec3::new(-0.5, -8.0, -0.5));
            // Reversed Z: depth n/(−z), infinite far plane; orthographic:
            // depth 1 at z = 0, 0 at z = −20.
            let perspective = DMat4::from_cols(
                DVec4::new(1.5, 0.0, 0.0, 0.0),
                DVec4::new(0.0, 1.5, 0.0, 0.0),
                DVec4::new(0.0, 0.0, 0.0, -1.0),
                DVec4::new(0.0, 0.0, 0.5, 0.0),
            );
            let proj = match kind {
                0 => perspective,
                1 => DMat4::from_cols(
                    DVec4::new(0.1, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, 0.1, 0.0, 0.0),
                    DVec4::new(0.0, 0.0, 0.05, 0.0),
                    DVec4::new(0.0, 0.0, 1.0, 1.0),
                ),
                // Depth, so the inverse's w, depends on x: the general path.
                _ => {
                    let mut m = perspective;
                    m.x_axis.z = 0.05;
                    m
                }
            };
            let shear = DMat4::from_cols_array(&[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, shear, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
            let clip_from_world = shear * proj * view;
            let world_from_clip = clip_from_world.inverse();
            let light = match kind {
                1 => Light::Directional { direction: DVec3::NEG_Y },
                _ => Light::Point { position: DVec3::new(0.5, 8.0, 0.5), range: None },
            };
            let d = AxisDepth::new(&world_from_clip, &axis, &light, 30.0, (64, 64));
            proptest::prop_assert_eq!(d.affine_xy, kind != 2);
            let (far, near) = (depths.0.min(depths.1), depths.0.max(depths.1));
            let (x, y) = pixel;
            let [lo, hi] = d.range((x, x), (y, y), far, near);
            let e = crate::footprint::FOOTPRINT_PX;
            for (sx, sy, sz) in samples {
                let px = f64::from(x) - e + sx * (1.0 + 2.0 * e);
                let py = f64::from(y) - e + sy * (1.0 + 2.0 * e);
                let z = f64::from(far) + sz * f64::from(near - far);
                let c = DVec4::new(px / 32.0 - 1.0, 1.0 - py / 32.0, z, 1.0);
                let h = world_from_clip * c;
                let p = h.truncate() / h.w;
                let depth = axis.axis.dot(p - axis.origin);
                let tol = 1e-9 * (depth.abs() + 1.0);
                proptest::prop_assert!(lo <= depth + tol && depth <= hi + tol, "{} not in [{}, {}]", depth, lo, hi);
            }
        }
    }

    /// Gathering unions each caster's per-view intervals, merging overlaps
    /// and keeping gaps.
    #[test]
    fn gathered_intervals_are_the_union_over_views() {
        let mut f = FragmentDepths::default();
        let a = [(3, [1.0, 2.0]), (3, [5.0, 6.0]), (7, [0.0, 1.0])];
        let b = [(3, [1.5, 3.0]), (4, [2.0, 2.5]), (3, [7.0, 8.0])];
        f.gather([&a[..], &b[..]]);
        assert_eq!(f.len(), 3);
        assert_eq!(
            f.get(ObjectId::from_slot(3)),
            Some(&[[1.0, 3.0], [5.0, 6.0], [7.0, 8.0]][..])
        );
        assert_eq!(f.get(ObjectId::from_slot(4)), Some(&[[2.0, 2.5]][..]));
        assert_eq!(f.get(ObjectId::from_slot(7)), Some(&[[0.0, 1.0]][..]));
        assert_eq!(f.get(ObjectId::from_slot(5)), None);
        f.gather(std::iter::empty());
        assert!(f.is_empty());
    }
}
