//! Discrete clamping's slicing planes [Steiner §4.4.2, Fig. 4.17, Listing
//! 4.3; Lloyd et al., CC shadow volumes]: a pencil of planes through the eye
//! that cuts the image into strips of (almost) equal width, each plane facing
//! the light.
//!
//! # Geometry
//! Every plane holds the eye, so the eye sees each one edge-on: a segment's
//! caps on them cover no pixel, and every eye ray lies in one slice. The
//! planes are the image's pixel rows (or columns): the slice coordinate `g`
//! of a point `p` is its image row (or column) in pixels, `num·q / den·q`
//! with `q = p − eye` and `den·q` the view distance, oriented so that `g`
//! grows along every light ray that reaches the view. Both are linear in
//! `q`, so `g = t` is the plane `(num − t·den)·q = 0` through the eye.
//!
//! Along a light ray `g` is a ratio of two affine functions of the ray
//! parameter, monotone wherever the ray is in front of the eye; whether it
//! grows or shrinks depends only on the ray's side of the plane through the
//! eye, the light and the strips' direction (the pencil's plane through the
//! light, `K = 0` below). A caster wholly on one side has every ray run the
//! same way: its `g` is oriented to grow along them (counted from the top
//! or from the bottom; [`EyeSlices::for_caster`]). A caster that plane cuts
//! stays unclamped. When the light's image lies off the screen (Steiner's
//! setting, "especially useful for point light sources that lie outside
//! the view frustum") the plane misses the view and every caster that can
//! shadow it lies on one side; with the light on the screen the plane cuts
//! the view along the light's row (or column), and only the casters it
//! cuts are lost. Rows or columns: whichever line through the light's image
//! lies farther from the screen's centre.

//! # Why the mask does not change
//! A segment between planes `g = a` and `g = b` is the caster's volume cut
//! to the slice: every ray of the volume enters it at `a` and leaves it at
//! `b`. An eye ray through a pixel centre with `a < g < b` lies wholly in
//! the slice, so along it the segment and the unclamped volume hold the
//! same points, and the stencil counts them alike; an eye ray outside every
//! interval meets no segment. So a caster's segments must cover the slices
//! of the pixels whose surface lies in its shadow, and nothing more. The
//! boundaries lie on pixel edges, half a pixel from any centre, so rounding
//! the segments' vertices to f32 moves no boundary across a centre.
//!
//! # Where the projection holds
//! A casting vertex `v` moves along its light ray to the plane `g = t` when
//! `g(v) ≤ t` and the ray reaches that plane in front of the eye; a ray
//! whose `g` tends to a limit below `t` (a ray leaving the view towards
//! the horizon) never does. The points whose rays reach a plane form a
//! convex set (the hull of the light and the plane's half in front of the
//! eye; for a directional light, that half swept back along the
//! direction), so a caster's box corners decide it for the whole caster.
//! A caster whose box is not wholly in front of the eye stays unclamped.

use glam::{DVec3, DVec4};
use scene::{Aabb, Camera, Light};

/// The slicing pencil of one eye, viewport and light (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeSlices {
    eye: DVec3,
    /// `g(p) = num·(p − eye) / den·(p − eye)`, in pixels.
    num: DVec3,
    den: DVec3,
    /// The light, eye-relative and homogeneous (`w = 0`: directional, the
    /// direction towards the light).
    light: DVec4,
    /// Pixels across the strips (the viewport's height for rows).
    extent: u32,
    /// Number of slices.
    count: u32,
    /// Rows (strips across the height) or columns.
    rows: bool,
    /// `g` counts pixels from the bottom (rows) or right (columns) instead
    /// of from the top or left.
    flip: bool,
}

impl EyeSlices {
    /// The pencil of `count` slices for `camera` over a `width × height`
    /// viewport and `light`, in its base orientation (`g` counts rows from
    /// the top or columns from the left; [`Self::for_caster`] orients it):
    /// rows or columns, whichever line through the light's image lies
    /// farther from the screen's centre, in pixels. `None` when `count` or
    /// the viewport is 0 or the values are not finite.
    pub fn new(
        camera: &Camera,
        (width, height): (u32, u32),
        light: &Light,
        count: u32,
    ) -> Option<Self> {
        if count == 0 || width == 0 || height == 0 {
            return None;
        }
        let m = camera.clip_from_eye_relative();
        let light = match *light {
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                (position - camera.position).extend(1.0)
            }
            Light::Directional { direction } => (-direction).extend(0.0),
        };
        // Clip x and y of the light (column 3 holds only z's near term).
        let row = |k: usize| m.row(k).truncate();
        let at = |k: usize| row(k).dot(light.truncate()).abs();
        let rows = at(1) * f64::from(height) >= at(0) * f64::from(width);
        // pixel = half·(1 + down·ndc): rows count down from the top (NDC y
        // up), columns right.
        let (extent, k, down) = if rows {
            (height, 1, -1.0)
        } else {
            (width, 0, 1.0)
        };
        let half = 0.5 * f64::from(extent);
        let s = EyeSlices {
            eye: camera.position,
            num: row(k) * (down * half) + row(3) * half,
            den: row(3),
            light,
            extent,
            count,
            rows,
            flip: false,
        };
        (s.num.is_finite() && s.den.is_finite() && s.light.is_finite()).then_some(s)
    }

    /// The pencil oriented for a caster with world bounds `b`: `g` grows
    /// along its light rays (module docs). `None` when a corner of `b` is
    /// not in front of the eye, or `b` meets the plane through the eye, the
    /// light and the strips' direction (its rays run both ways).
    pub fn for_caster(&self, b: &Aabb) -> Option<EyeSlices> {
        if !self.in_front(b) {
            return None;
        }
        let l = self.light.truncate();
        let (nl, dl) = (self.num.dot(l), self.den.dot(l));
        let (mut pos, mut neg) = (true, true);
        for c in b.corners() {
            // K = den(L)·num(q) − num(L)·den(q): the sign of g's growth
            // along the ray through q (eye-relative, homogeneous light).
            let q = c.as_dvec3() - self.eye;
            let (nq, dq) = (self.num.dot(q), self.den.dot(q));
            let k = dl * nq - nl * dq;
            let scale = (dl * nq).abs() + (nl * dq).abs();
            pos &= k > 1e-9 * scale;
            neg &= k < -1e-9 * scale;
        }
        match (pos, neg) {
            (true, _) => Some(*self),
            (_, true) => Some(self.flipped()),
            _ => None,
        }
    }

    /// The other orientation: `g' = extent − g`.
    fn flipped(&self) -> EyeSlices {
        EyeSlices {
            num: self.den * f64::from(self.extent) - self.num,
            flip: !self.flip,
            ..*self
        }
    }

    /// True when `g` counts from the bottom or right.
    pub fn flip(&self) -> bool {
        self.flip
    }

    /// `[lo, hi]` of the other orientation in this one's `g`.
    pub fn from_other(&self, [lo, hi]: [f64; 2]) -> [f64; 2] {
        let e = f64::from(self.extent);
        [e - hi, e - lo]
    }

    /// Number of slices.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Pixels across the strips.
    pub fn extent(&self) -> u32 {
        self.extent
    }

    /// True for strips of rows, false for columns.
    pub fn rows(&self) -> bool {
        self.rows
    }

    /// `g` as `num·(p, 1) / den·(p, 1)` for world points `p` (homogeneous
    /// rows): the pixel coordinate that grows along the light rays.
    pub fn world_ratio(&self) -> (DVec4, DVec4) {
        let h = |v: DVec3| v.extend(-v.dot(self.eye));
        (h(self.num), h(self.den))
    }

    /// `g` of world point `p` (meaningful in front of the eye).
    pub fn depth(&self, p: DVec3) -> f64 {
        let q = p - self.eye;
        self.num.dot(q) / self.den.dot(q)
    }

    /// `g` of slice boundary `i` (`0..=count`, ascending): a pixel edge,
    /// `i·extent / count` rounded to the nearest in the base orientation.
    pub fn edge(&self, i: u32) -> f64 {
        let base = |i: u32| {
            let (i, e, n) = (u64::from(i), u64::from(self.extent), u64::from(self.count));
            ((2 * i * e + n) / (2 * n)) as f64
        };
        if self.flip {
            f64::from(self.extent) - base(self.count - i.min(self.count))
        } else {
            base(i)
        }
    }

    /// The slice holding `g` (clamped to the screen).
    pub fn slice_of(&self, g: f64) -> u32 {
        let n = self.count;
        if g.is_nan() || g <= 0.0 {
            return 0;
        }
        let mut i = ((g * f64::from(n) / f64::from(self.extent)) as u32).min(n - 1);
        while i + 1 < n && self.edge(i + 1) <= g {
            i += 1;
        }
        while i > 0 && self.edge(i) > g {
            i -= 1;
        }
        i
    }

    /// `[lo, hi]` (cut to the screen) widened outward to the nearest slice
    /// boundaries: the greatest at or below `lo`, the least at or above
    /// `hi`. `None` when it misses the screen.
    pub fn widened(&self, [lo, hi]: [f64; 2]) -> Option<[f64; 2]> {
        let top = f64::from(self.extent);
        if !(hi >= 0.0 && lo <= top) {
            return None;
        }
        let (lo, hi) = (lo.max(0.0), hi.min(top));
        let a = self.edge(self.slice_of(lo));
        let mut j = self.slice_of(hi);
        if self.edge(j) < hi {
            j += 1;
        }
        Some([a, self.edge(j)])
    }

    /// True when every corner of `b` lies in front of the eye, where `g` is
    /// defined.
    pub fn in_front(&self, b: &Aabb) -> bool {
        !b.is_empty()
            && b.corners().iter().all(|c| {
                let q = c.as_dvec3() - self.eye;
                self.den.dot(q) > 1e-9 * q.length()
            })
    }

    /// The `g` range of box `b`'s corners (its extremes: `g` is a ratio of
    /// affine functions, positive denominator, over the box).
    pub fn box_range(&self, b: &Aabb) -> [f64; 2] {
        b.corners()
            .iter()
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], c| {
                let g = self.depth(c.as_dvec3());
                [lo.min(g), hi.max(g)]
            })
    }

    /// The plane `g = t` as an eye-relative normal (`n·(p − eye) = 0`).
    fn normal(&self, t: f64) -> DVec3 {
        self.num - self.den * t
    }

    /// True when `v`'s light ray, from `v` on, reaches the plane `g = t` in
    /// front of the eye (module docs, "Where the projection holds").
    pub fn reaches(&self, v: DVec3, t: f64) -> bool {
        let n = self.normal(t);
        let q = v - self.eye;
        // The ray from v: q + λ·d, with n·q ≤ 0 at v (g(v) ≤ t).
        let d = self.ray_direction(q);
        let (at_v, slope) = (n.dot(q), n.dot(d));
        if !(at_v <= 1e-12 * n.length() * q.length() && slope > 0.0) {
            return false;
        }
        let hit = q + d * (-at_v / slope).max(0.0);
        self.den.dot(hit) > 0.0 && hit.is_finite()
    }

    /// Eye-relative direction of the light ray through eye-relative `q`.
    fn ray_direction(&self, q: DVec3) -> DVec3 {
        if self.light.w == 0.0 {
            -self.light.truncate()
        } else {
            q - self.light.truncate()
        }
    }

    /// World point `v` moved along its light ray to the plane `g = t`
    /// (where [`Self::reaches`] holds).
    pub fn project(&self, v: DVec3, t: f64) -> DVec3 {
        let n = self.normal(t);
        let q = v - self.eye;
        let d = self.ray_direction(q);
        self.eye + q + d * (-n.dot(q) / n.dot(d))
    }

    /// True when the light ray of every corner of `b` reaches `g = t`.
    pub fn box_reaches(&self, b: &Aabb, t: f64) -> bool {
        b.corners().iter().all(|c| self.reaches(c.as_dvec3(), t))
    }

    /// The world plane `(n, d)` (`n·x + d = 0`, `n` a unit normal towards
    /// greater `g`) of `g = t`.
    pub fn plane(&self, t: f64) -> [f64; 4] {
        let n = self.normal(t);
        let n = n / n.length();
        [n.x, n.y, n.z, -n.dot(self.eye)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn camera() -> Camera {
        Camera::look_at(
            DVec3::new(0.0, 1.7, 0.0),
            DVec3::new(0.0, 1.0, -20.0),
            DVec3::Y,
            1.0,
            4.0 / 3.0,
            0.1,
        )
        .unwrap()
    }

    #[test]
    fn a_light_above_slices_rows_and_orients_by_side() {
        let cam = camera();
        let above = Light::Point {
            position: DVec3::new(5.0, 60.0, -10.0),
            range: None,
        };
        let s = EyeSlices::new(&cam, (800, 600), &above, 10).unwrap();
        assert!(s.rows());
        assert_eq!((s.edge(0), s.edge(10), s.edge(3)), (0.0, 600.0, 180.0));
        let b = |y: f32| Aabb {
            min: glam::Vec3::new(-1.0, y, -20.0),
            max: glam::Vec3::new(1.0, y + 2.0, -18.0),
        };
        // Below the light's plane its rays run down the image (g from the
        // top); a box above it, between eye and light, runs up.
        let low = s.for_caster(&b(0.0)).unwrap();
        assert!(!low.flip());
        let ahead = Light::Point {
            position: DVec3::new(0.0, 1.5, -30.0),
            range: None,
        };
        let s = EyeSlices::new(&cam, (800, 600), &ahead, 10).unwrap();
        let (lo, hi) = (s.for_caster(&b(-1.0)), s.for_caster(&b(4.0)));
        assert_ne!(lo.unwrap().flip(), hi.unwrap().flip());
        // A box the light's plane cuts, or behind the eye, is refused.
        assert!(s.for_caster(&b(0.5)).is_none());
        let behind = Aabb {
            min: glam::Vec3::new(-1.0, 0.0, 1.0),
            max: glam::Vec3::new(1.0, 1.0, 2.0),
        };
        assert!(s.for_caster(&behind).is_none());
        let flipped = s.for_caster(&b(4.0)).unwrap();
        let e: Vec<f64> = (0..=10).map(|i| flipped.edge(i)).collect();
        assert!(e.windows(2).all(|w| w[0] < w[1]) && e[0] == 0.0 && e[10] == 600.0);
    }

    proptest! {
        /// `g` grows along every light ray through the view, oriented per
        /// caster: for a point of the view frustum and a point nearer the
        /// light on its ray (a tiny caster there), the nearer one has the
        /// smaller `g`, and `g` is the pixel's row or column from one side;
        /// projections land on their plane where the ray reaches it.
        #[test]
        fn g_grows_along_light_rays_and_projections_land(
            l in (-50.0f64..50.0, -20.0f64..80.0, -60.0f64..20.0),
            directional in any::<bool>(),
            px in 0.0f64..800.0, py in 0.0f64..600.0, dist in 1.0f64..200.0,
            back in 0.05f64..0.95,
            n in 1u32..40,
        ) {
            let cam = camera();
            let light = if directional {
                Light::Directional { direction: -DVec3::new(l.0, l.1, l.2).normalize() }
            } else {
                Light::Point { position: DVec3::new(l.0, l.1, l.2), range: None }
            };
            let base = EyeSlices::new(&cam, (800, 600), &light, n).unwrap();
            let p = cam.position + cam.ray_direction(px, py, 800, 600) * dist;
            let toward = light.toward_light(p);
            let nearer = if directional { p + toward * (back * 5.0) } else { p + toward * back };
            let tiny = Aabb {
                min: (nearer - 1e-4).as_vec3(),
                max: (nearer + 1e-4).as_vec3(),
            };
            let Some(s) = base.for_caster(&tiny) else { return Ok(()) };
            let g = s.depth(p);
            let pixel = if s.rows() { py } else { px };
            let from = if s.flip() { f64::from(s.extent()) - pixel } else { pixel };
            prop_assert!((g - from).abs() < 1e-6, "g {} pixel {} flip {}", g, pixel, s.flip());
            prop_assert!(s.depth(nearer) <= g + 1e-9, "{} > {}", s.depth(nearer), g);
            if s.reaches(nearer, g) {
                let hit = s.project(nearer, g);
                prop_assert!((s.depth(hit) - g).abs() < 1e-6 * (1.0 + g.abs()));
                prop_assert!((hit - p).length() < 1e-6 * (1.0 + dist));
            }
            let i = s.slice_of(g);
            prop_assert!(i < n);
            prop_assert!(s.edge(i) <= g.max(0.0) && (g < s.edge(i + 1) || i + 1 == n));
        }
    }
}
