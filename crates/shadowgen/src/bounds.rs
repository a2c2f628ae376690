//! Per-volume scissor rectangle and depth bounds [EK "Exploit Bounds",
//! "Computing Depth Bounds"].
//!
//! Only surface points inside a volume change its stencil contribution, every
//! surface lies in the scene bounds S, and surfaces beyond a light's range are
//! unlit whatever the stencil says; so a volume may skip every pixel whose
//! surface point is outside `V ∩ S ∩ range box`. V lies in the set H swept by
//! the caster box B away from the light (point light: `{l + t(p − l) : p ∈ B,
//! t ≥ 1}`; directional: `B + t·d, t ≥ 0`). We start from the box of H ∩ S ∩
//! range box (H's per-axis extent is B's, unbounded where the rays head), clip
//! its six faces (Sutherland–Hodgman, f64, eye-relative) by half-spaces that
//! hold H — behind each box face the light faces, and each plane through the
//! light (or along d) and a box edge with all of B on one side — and by the
//! near plane, and project the clipped faces' vertices (all with clip
//! w ≥ near > 0). The rectangle and depth range of those vertices bound the
//! visible part of the clipped polyhedron ⊇ V ∩ S exactly.
//!
//! Widening (stated bounds, no guesses): the box and every half-space grow by
//! `BOUNDS_MARGIN · DEPTH_ERROR · R` (R the largest distance from the eye to a
//! corner of the box) to cover the f32 rounding of the volume vertices and of
//! `clip_from_local`; the rectangle by one pixel on every side; depths by the
//! relative factor `1 ± BOUNDS_MARGIN · DEPTH_ERROR` (raster's ε_z).
//!
//! Spot lights: surfaces outside the cone are unlit too, so the box is also
//! cut to the exact box of the cone's spherical sector when the spot has a
//! range, and the half-spaces include the eight side planes of the regular
//! octagonal pyramid around the cone (apex at the light, each plane tangent to
//! the cone): conservative, as every other cut.

pub(crate) use crate::swept_vertices::corner;
use crate::swept_vertices::{for_each_vertex, Sweep};
use glam::DVec3;
use raster::DEPTH_ERROR;
use scene::{Aabb, Camera, Light};

/// Multiple of `raster::DEPTH_ERROR` the bounds are widened by.
pub const BOUNDS_MARGIN: f64 = 64.0;

/// Scissor `[x0, y0, x1, y1)` (pixels, row 0 at the top) and reversed-Z depth
/// bounds `(depth_near ≥ depth_far)` of a volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeBounds {
    /// Pixel rectangle, never inverted; empty (`x0 = x1`) when nothing is visible.
    pub scissor: [u32; 4],
    /// Nearest depth (largest reversed-Z value), ≤ 1.
    pub depth_near: f32,
    /// Farthest depth (smallest reversed-Z value), ≥ 0.
    pub depth_far: f32,
}

/// The scissor and depth bounds of the volume of a caster with world bounds
/// `caster` for `light`, restricted to the scene bounds `scene_bounds`, seen by
/// `camera` in a `width × height` viewport.
pub fn volume_bounds(
    camera: &Camera,
    viewport: (u32, u32),
    light: &Light,
    caster: &Aabb,
    scene_bounds: &Aabb,
) -> VolumeBounds {
    BoundsView::new(camera).volume_bounds(viewport, light, caster, scene_bounds)
}

/// What [`volume_bounds`] reads of the camera, derived once for many
/// volumes of one view (a frame's): the eye, near distance and forward axis,
/// the frustum's side plane normals and the eye-relative clip transform.
#[derive(Clone, Copy, Debug)]
pub struct BoundsView {
    eye: DVec3,
    near: f64,
    forward: DVec3,
    sides: [DVec3; 4],
    clip: glam::DMat4,
}

impl BoundsView {
    /// The view of `camera`.
    pub fn new(camera: &Camera) -> Self {
        let frustum = camera.frustum();
        BoundsView {
            eye: camera.position,
            near: camera.near,
            forward: camera.forward(),
            sides: std::array::from_fn(|i| frustum.planes[i].normal),
            clip: camera.clip_from_eye_relative(),
        }
    }

    /// [`volume_bounds`] for this view.
    pub fn volume_bounds(
        &self,
        (width, height): (u32, u32),
        light: &Light,
        caster: &Aabb,
        scene_bounds: &Aabb,
    ) -> VolumeBounds {
        let nothing = VolumeBounds {
            scissor: [0, 0, 0, 0],
            depth_near: 1.0,
            depth_far: 1.0,
        };
        if caster.is_empty() || scene_bounds.is_empty() {
            return nothing;
        }
        let (blo, bhi) = (caster.min.as_dvec3(), caster.max.as_dvec3());
        let Some((lo, hi, cone)) = swept_box(light, (blo, bhi), scene_bounds) else {
            return nothing;
        };
        // Eye-relative from here on (precision far from the origin).
        let eye = self.eye;
        let (lo, hi) = (lo - eye, hi - eye);
        let (blo, bhi) = (blo - eye, bhi - eye);
        let r = (0..8)
            .map(|i| corner(lo, hi, i).length())
            .fold(0.0, f64::max);
        let m = BOUNDS_MARGIN * DEPTH_ERROR * r;
        let (lo, hi) = (lo - DVec3::splat(m), hi + DVec3::splat(m));
        // Early outs: the box wholly behind the near plane or outside a side plane
        // of the view frustum (side planes pass through the eye: d = 0 here).
        let outside = |n: DVec3, d: f64| {
            let far = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
            n.dot(far) + d < 0.0
        };
        if outside(self.forward, -self.near)
            || self.sides.iter().any(|&n| outside(n, m * n.length()))
        {
            return nothing;
        }

        // The fast path: P's vertices from the sweep's structure, when a point
        // light lies outside the grown caster box, or the light is directional,
        // and P lies in front of the near plane; else the general clipper.
        let bm = (blo - DVec3::splat(m), bhi + DVec3::splat(m));
        let ranges = swept_ranges(self, light, eye, bm, cone.is_some(), (lo, hi))
            .or_else(|| clipped_ranges(self, light, eye, (blo, bhi), cone, m, (lo, hi)));
        let Some((xs, ys, ws)) = ranges.flatten() else {
            return nothing;
        };
        let ([xmin, xmax], [ymin, ymax], [wmin, wmax]) = (xs, ys, ws);
        let (w, h) = (width as f64, height as f64);
        let px = |x: f64| (x + 1.0) * 0.5 * w;
        let py = |y: f64| (1.0 - y) * 0.5 * h;
        let clamp = |v: f64, max: f64| v.clamp(0.0, max) as u32;
        let x0 = clamp((px(xmin)).floor() - 1.0, w);
        let x1 = clamp((px(xmax)).ceil() + 1.0, w);
        let y0 = clamp((py(ymax)).floor() - 1.0, h);
        let y1 = clamp((py(ymin)).ceil() + 1.0, h);
        let k = BOUNDS_MARGIN * DEPTH_ERROR;
        // Depth = near / w (reversed Z), rounded outward to f32.
        let dn = (self.near / wmin * (1.0 + k)).min(1.0);
        let df = (self.near / wmax * (1.0 - k)).max(0.0);
        let depth_near = round_up(dn).min(1.0);
        let depth_far = round_down(df).max(0.0);
        VolumeBounds {
            scissor: [x0, y0, x1.max(x0), y1.max(y0)],
            depth_near,
            depth_far: depth_far.min(depth_near),
        }
    }
}

/// The ranges of x/w, y/w (NDC) and w over `P = S ∩ H(B⊕m)` from its
/// vertices ([`crate::swept_vertices`]), `bm` the eye-relative caster box
/// grown by the margin m and `(lo, hi)` the grown box S. `None` when this
/// path does not apply: a spot light's cone, a point light inside `bm`, or
/// P reaching behind the near plane. `Some(None)` when P is empty.
///
/// Conservative as the general path: the rounded volume lies within m of
/// H(B), and `H(B) ⊕ cube(m) ⊆ H(B ⊕ cube(m))` (a point `l + t(p − l) + c`,
/// `t ≥ 1`, is `l + t(p + c/t − l)`; a translation commutes with the sweep).
fn swept_ranges(
    view: &BoundsView,
    light: &Light,
    eye: DVec3,
    bm: (DVec3, DVec3),
    has_cone: bool,
    (lo, hi): (DVec3, DVec3),
) -> Option<Option<Ranges>> {
    let sweep = match *light {
        _ if has_cone => return None,
        Light::Point { position, .. } | Light::Spot { position, .. } => {
            let l = position - eye;
            if l.cmpge(bm.0).all() && l.cmple(bm.1).all() {
                return None;
            }
            Sweep::From(l)
        }
        Light::Directional { direction } => Sweep::Along(direction),
    };
    let mut planes = [(DVec3::ZERO, 0.0f64); MAX_PLANES];
    let np = swept_half_spaces(light, eye, bm, None, 0.0, &mut planes);
    let mut acc = RangeAcc::new(view);
    let mut behind = false;
    for_each_vertex(sweep, bm, (lo, hi), &planes[..np], |x| {
        behind |= !acc.add(x);
    });
    (!behind).then(|| acc.ranges())
}

/// The ranges of [`swept_ranges`] by the general clipper: the box `(lo, hi)`
/// clipped by H(B)'s half-spaces pushed out by m, a spot light's cone and the
/// near plane (`None` when empty).
fn clipped_ranges(
    view: &BoundsView,
    light: &Light,
    eye: DVec3,
    (blo, bhi): (DVec3, DVec3),
    cone: Option<Cone>,
    m: f64,
    (lo, hi): (DVec3, DVec3),
) -> Option<Option<Ranges>> {
    // Half-spaces n·x + d ≥ 0 holding the swept set H, each pushed out by m,
    // then the near plane: view distance ≥ near.
    let mut planes = [(DVec3::ZERO, 0.0f64); MAX_PLANES];
    let mut np = swept_half_spaces(light, eye, (blo, bhi), cone, m, &mut planes);
    planes[np] = (view.forward, -view.near);
    np += 1;
    // Drop half-spaces that hold the whole box; a box wholly outside one is empty.
    let mut kept = 0;
    for i in 0..np {
        let (n, d) = planes[i];
        let near_corner = DVec3::select(n.cmpge(DVec3::ZERO), lo, hi);
        if n.dot(near_corner) + d >= 0.0 {
            continue;
        }
        let far_corner = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
        if n.dot(far_corner) + d < 0.0 {
            return Some(None);
        }
        planes[kept] = planes[i];
        kept += 1;
    }
    Some(project_polyhedron(view, (lo, hi), &planes[..kept]))
}

/// Ranges of x/w, y/w (NDC) and w.
type Ranges = ([f64; 2], [f64; 2], [f64; 2]);

/// Accumulates [`Ranges`] over eye-relative points.
struct RangeAcc {
    clip: glam::DMat4,
    near: f64,
    x: [f64; 2],
    y: [f64; 2],
    w: [f64; 2],
    any: bool,
}

impl RangeAcc {
    fn new(view: &BoundsView) -> Self {
        RangeAcc {
            clip: view.clip,
            near: view.near,
            x: [f64::MAX, f64::MIN],
            y: [f64::MAX, f64::MIN],
            w: [f64::MAX, f64::MIN],
            any: false,
        }
    }

    /// Adds `p` (its w raised to the near distance); whether it lay at or
    /// beyond the near plane.
    fn add(&mut self, p: DVec3) -> bool {
        let c = self.clip * p.extend(1.0);
        let w = c.w.max(self.near);
        let inv = 1.0 / w;
        let (x, y) = (c.x * inv, c.y * inv);
        self.x = [self.x[0].min(x), self.x[1].max(x)];
        self.y = [self.y[0].min(y), self.y[1].max(y)];
        self.w = [self.w[0].min(w), self.w[1].max(w)];
        self.any = true;
        c.w >= self.near
    }

    fn ranges(&self) -> Option<Ranges> {
        self.any.then_some((self.x, self.y, self.w))
    }
}

/// A spot light's cone: apex, unit axis, half angle.
type Cone = (DVec3, DVec3, f64);

/// The world box of the swept set H of the caster box `(blo, bhi)`: per axis
/// from the box to infinity where some light ray through it heads, clamped
/// to the scene bounds, the light's range and a spot light's cone (which is
/// returned too); `None` when empty.
fn swept_box(
    light: &Light,
    (blo, bhi): (DVec3, DVec3),
    scene_bounds: &Aabb,
) -> Option<(DVec3, DVec3, Option<Cone>)> {
    // Per axis: does some light ray through B head toward + / −?
    let (up, down) = match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => {
            (bhi.cmpgt(position), blo.cmplt(position))
        }
        Light::Directional { direction } => {
            (direction.cmpgt(DVec3::ZERO), direction.cmplt(DVec3::ZERO))
        }
    };
    let hlo = DVec3::select(down, DVec3::NEG_INFINITY, blo);
    let hhi = DVec3::select(up, DVec3::INFINITY, bhi);
    let mut lo = hlo.max(scene_bounds.min.as_dvec3());
    let mut hi = hhi.min(scene_bounds.max.as_dvec3());
    if lo.cmpgt(hi).any() {
        return None;
    }
    // The light's range: surfaces beyond it are unlit whatever the stencil says.
    if let Light::Point {
        position,
        range: Some(r),
    }
    | Light::Spot {
        position,
        range: Some(r),
        ..
    } = *light
    {
        lo = lo.max(position - DVec3::splat(r));
        hi = hi.min(position + DVec3::splat(r));
        if lo.cmpgt(hi).any() {
            return None;
        }
    }
    // A spot light's cone within its range: surfaces outside it are unlit too.
    // The box of the spherical sector {l + t·w : angle(w, a) ≤ θ, 0 ≤ t ≤ R}
    // is exact per axis: max w·e over the cone is 1 when e is within θ of the
    // axis, else cos(φ − θ) with φ = angle(a, e); the apex bounds the rest.
    let cone = match *light {
        Light::Spot {
            position,
            direction,
            apex_angle,
            range,
        } => {
            let axis = direction.normalize();
            let half = 0.5 * apex_angle;
            if let Some(r) = range {
                let reach = |c: f64| {
                    let phi = c.clamp(-1.0, 1.0).acos();
                    r * if phi <= half {
                        1.0
                    } else {
                        (phi - half).cos().max(0.0)
                    }
                };
                for k in 0..3 {
                    hi[k] = hi[k].min(position[k] + reach(axis[k]));
                    lo[k] = lo[k].max(position[k] - reach(-axis[k]));
                }
                if lo.cmpgt(hi).any() {
                    return None;
                }
            }
            Some((position, axis, half))
        }
        _ => None,
    };
    Some((lo, hi, cone))
}

/// Writes into `planes` the half-spaces `n·x + d ≥ 0` (eye-relative, each
/// pushed out by `m`) that hold the swept set of the eye-relative caster box
/// `(blo, bhi)`: behind every box face that faces the light, through the light
/// and every box edge with the whole box on one side, and a spot light's cone
/// pyramid. Returns how many.
fn swept_half_spaces(
    light: &Light,
    eye: DVec3,
    (blo, bhi): (DVec3, DVec3),
    cone: Option<Cone>,
    m: f64,
    planes: &mut [(DVec3, f64); MAX_PLANES],
) -> usize {
    let mut np = 0;
    let mut add = |n: DVec3, d: f64| {
        if n != DVec3::ZERO && n.is_finite() && d.is_finite() {
            planes[np] = (n, if m == 0.0 { d } else { d + m * n.length() });
            np += 1;
        }
    };
    let toward_light = |p: DVec3| match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => position - eye - p,
        Light::Directional { direction } => -direction,
    };
    let bc: [DVec3; 8] = std::array::from_fn(|i| corner(blo, bhi, i));
    // Behind every box face that faces the light (rays leave B through it).
    for axis in 0..3 {
        for (coord, sign) in [(bhi[axis], 1.0), (blo[axis], -1.0)] {
            let mut n = DVec3::ZERO;
            n[axis] = sign;
            let p = DVec3::select(
                glam::BVec3::new(axis == 0, axis == 1, axis == 2),
                DVec3::splat(coord),
                bc[0],
            );
            if n.dot(toward_light(p)) > 0.0 {
                add(-n, sign * coord);
            }
        }
    }
    // Planes through the light and a box edge with the whole box on one side.
    for i in 0..8usize {
        for axis in 0..3 {
            let j = i | (1 << axis);
            if j == i {
                continue;
            }
            let (a, b) = (bc[i], bc[j]);
            let n = (b - a).cross(toward_light(a));
            // The box's least and greatest n·(c − a) are at the corners
            // picked per axis by n's signs.
            let pos = n.cmpge(DVec3::ZERO);
            if n.dot(DVec3::select(pos, blo, bhi) - a) >= 0.0 {
                add(n, -n.dot(a));
            } else if n.dot(DVec3::select(pos, bhi, blo) - a) <= 0.0 {
                add(-n, n.dot(a));
            }
        }
    }
    // A spot light's cone: the regular octagonal pyramid around it, apex at
    // the light, each side plane tangent to the cone along one generator
    // (inside normal a·sin θ − s·cos θ, s ⟂ a a unit vector): it holds the cone.
    if let Some((position, axis, half)) = cone {
        let s0 = axis.any_orthonormal_vector();
        let s1 = axis.cross(s0);
        let apex = position - eye;
        for k in 0..CONE_PLANES {
            let t = std::f64::consts::TAU * k as f64 / CONE_PLANES as f64;
            let s = s0 * t.cos() + s1 * t.sin();
            let n = axis * half.sin() - s * half.cos();
            add(n, -n.dot(apex));
        }
    }
    np
}

/// Projects the box `(lo, hi)` (eye-relative) clipped by `planes` with
/// `camera`: the ranges of x/w, y/w (NDC) and w over its vertices (w at least
/// the near distance), `None` when the clipped polyhedron is empty.
fn project_polyhedron(
    view: &BoundsView,
    (lo, hi): (DVec3, DVec3),
    planes: &[(DVec3, f64)],
) -> Option<Ranges> {
    // The clipped polyhedron's faces lie on the box faces or on the planes:
    // clip the six box faces by every half-space, and for every plane a quad
    // on it covering the box by the box and the other half-spaces. The
    // vertices of all these polygons are the polyhedron's vertices.
    let box_planes = [
        (DVec3::X, -lo.x),
        (DVec3::NEG_X, hi.x),
        (DVec3::Y, -lo.y),
        (DVec3::NEG_Y, hi.y),
        (DVec3::Z, -lo.z),
        (DVec3::NEG_Z, hi.z),
    ];
    let centre = (lo + hi) * 0.5;
    let size = (hi - lo).length();
    let mut acc = RangeAcc::new(view);
    let mut bufs = [Poly::default(), Poly::default()];
    for face in 0..6 + planes.len() {
        let [mut poly, mut next] = bufs.each_mut();
        poly.n = 0;
        if face < 6 {
            for &c in &FACES[face] {
                poly.push(corner(lo, hi, c));
            }
        } else {
            let (n, d) = planes[face - 6];
            let u = n / n.length();
            let p0 = centre - u * (n.dot(centre) + d) / n.length();
            let t1 = u.any_orthonormal_vector() * size;
            let t2 = u.cross(t1);
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                poly.push(p0 + t1 * a + t2 * b);
            }
        }
        let others = box_planes
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != face)
            .map(|(_, p)| p)
            .chain(
                planes
                    .iter()
                    .enumerate()
                    .filter(|&(i, _)| i + 6 != face)
                    .map(|(_, p)| p),
            );
        for &(n, d) in others {
            // Clip only when some vertex is outside (cheap test first).
            if poly.v[..poly.n].iter().all(|x| n.dot(*x) + d >= 0.0) {
                continue;
            }
            poly.clip(n, d, next);
            std::mem::swap(&mut poly, &mut next);
            if poly.n == 0 {
                break;
            }
        }
        for &x in &poly.v[..poly.n] {
            acc.add(x);
        }
    }
    acc.ranges()
}

/// The box faces as corner indices (see [`corner`]).
const FACES: [[usize; 4]; 6] = [
    [0, 2, 6, 4],
    [1, 5, 7, 3],
    [0, 4, 5, 1],
    [2, 3, 7, 6],
    [0, 1, 3, 2],
    [4, 6, 7, 5],
];

/// Side planes of the pyramid that bounds a spot light's cone.
const CONE_PLANES: usize = 8;

/// Half-spaces at most: 6 box faces, 12 light/edge planes, the cone's, near.
const MAX_PLANES: usize = 6 + 12 + CONE_PLANES + 1;

/// Vertices of a clipped face at most: 4 plus one per other clipping plane
/// (6 box planes and `MAX_PLANES`, less the face's own).
const POLY_VERTICES: usize = 4 + 6 + MAX_PLANES - 1;

/// A convex polygon of at most [`POLY_VERTICES`] vertices.
struct Poly {
    v: [DVec3; POLY_VERTICES],
    n: usize,
}

impl Default for Poly {
    fn default() -> Self {
        Poly {
            v: [DVec3::ZERO; POLY_VERTICES],
            n: 0,
        }
    }
}

impl Poly {
    fn push(&mut self, p: DVec3) {
        debug_assert!(self.n < self.v.len(), "4 + one vertex per plane fits");
        if self.n < self.v.len() {
            self.v[self.n] = p;
            self.n += 1;
        }
    }

    /// Sutherland–Hodgman against `n·x + d ≥ 0`, into `out`.
    fn clip(&self, n: DVec3, d: f64, out: &mut Poly) {
        out.n = 0;
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            let (sa, sb) = (n.dot(a) + d, n.dot(b) + d);
            if sa >= 0.0 {
                out.push(a);
            }
            if (sa >= 0.0) != (sb >= 0.0) {
                let t = sa / (sa - sb);
                out.push(a + (b - a) * t);
            }
        }
    }
}

/// `v` rounded to the nearest f32 at or above it.
pub(crate) fn round_up(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v {
        f.next_up()
    } else {
        f
    }
}

/// `v` rounded to the nearest f32 at or below it.
pub(crate) fn round_down(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) > v {
        f.next_down()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn cam() -> Camera {
        Camera::look_at(
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::ZERO,
            DVec3::Y,
            1.0,
            1.0,
            0.5,
        )
        .unwrap()
    }

    #[test]
    fn directional_volume_is_cut_by_the_scene_bounds() {
        let sun = Light::Directional {
            direction: DVec3::NEG_Y,
        };
        let caster = Aabb::new(Vec3::new(-0.5, 2.0, -0.5), Vec3::new(0.5, 3.0, 0.5));
        let scene = Aabb::new(Vec3::splat(-5.0), Vec3::splat(5.0));
        let b = volume_bounds(&cam(), (100, 100), &sun, &caster, &scene);
        // Depth range: view distances 9.5 .. 10.5 (x, z within the caster's).
        assert!(b.depth_near >= (0.5 / 9.5) as f32 && b.depth_near < (0.5 / 9.4) as f32);
        assert!(b.depth_far <= (0.5 / 10.5) as f32 && b.depth_far > (0.5 / 10.6) as f32);
        // The column below the caster reaches y = −5: the scissor spans it.
        assert!(b.scissor[0] > 30 && b.scissor[2] < 70);
        assert!(b.scissor[1] < 50 && b.scissor[3] > 60);
    }

    #[test]
    fn a_narrow_spot_cone_tightens_the_bounds() {
        // A wide caster under a light; the cone covers only its middle.
        let caster = Aabb::new(Vec3::new(-4.0, 1.0, -4.0), Vec3::new(4.0, 1.5, 4.0));
        let scene = Aabb::new(Vec3::new(-20.0, -2.0, -20.0), Vec3::new(20.0, 8.0, 20.0));
        let cam = Camera::look_at(
            DVec3::new(0.0, 12.0, 6.0),
            DVec3::ZERO,
            DVec3::Y,
            1.2,
            1.0,
            0.5,
        )
        .unwrap();
        let position = DVec3::new(0.0, 6.0, 0.0);
        let point = Light::Point {
            position,
            range: None,
        };
        let spot = |range| Light::Spot {
            position,
            direction: DVec3::NEG_Y,
            apex_angle: 20f64.to_radians(),
            range,
        };
        let area = |b: VolumeBounds| (b.scissor[2] - b.scissor[0]) * (b.scissor[3] - b.scissor[1]);
        let p = volume_bounds(&cam, (100, 100), &point, &caster, &scene);
        let s = volume_bounds(&cam, (100, 100), &spot(None), &caster, &scene);
        assert!(area(s) * 4 < area(p), "{s:?} vs {p:?}");
        assert!(s.depth_near <= p.depth_near && s.depth_far >= p.depth_far);
        // Within range 6.5 the sector ends above y = −0.5.
        let r = volume_bounds(&cam, (100, 100), &spot(Some(6.5)), &caster, &scene);
        assert!(
            area(r) <= area(s) && r.depth_far > s.depth_far,
            "{r:?} vs {s:?}"
        );
        // A cone aimed away from the caster: nothing to draw.
        let away = Light::Spot {
            position,
            direction: DVec3::Y,
            apex_angle: 20f64.to_radians(),
            range: None,
        };
        let b = volume_bounds(&cam, (100, 100), &away, &caster, &scene);
        assert_eq!(area(b), 0);
    }

    /// The fast path's ranges are the general clipper's for the same
    /// polyhedron: both unwidened (m = 0), so that any vertex the sweep's
    /// structure leaves out shows. (Each path's widening by m is its own:
    /// a grown box swept, or the swept planes pushed out; both hold the
    /// rounded volume, and the end-to-end test samples it.)
    fn assert_paths_agree(cam: &Camera, light: &Light, caster: &Aabb, scene: &Aabb) {
        let (blo, bhi) = (caster.min.as_dvec3(), caster.max.as_dvec3());
        let Some((lo, hi, cone)) = swept_box(light, (blo, bhi), scene) else {
            return;
        };
        let eye = cam.position;
        let (lo, hi, blo, bhi) = (lo - eye, hi - eye, blo - eye, bhi - eye);
        let view = BoundsView::new(cam);
        let Some(fast) = swept_ranges(&view, light, eye, (blo, bhi), cone.is_some(), (lo, hi))
        else {
            return;
        };
        let general = clipped_ranges(&view, light, eye, (blo, bhi), cone, 0.0, (lo, hi)).unwrap();
        let (Some(f), Some(g)) = (fast, general) else {
            assert_eq!(fast.is_none(), general.is_none(), "{fast:?} vs {general:?}");
            return;
        };
        for (a, b) in [(f.0, g.0), (f.1, g.1), (f.2, g.2)] {
            for k in 0..2 {
                let tol = 1e-9 * (1.0 + a[k].abs());
                assert!((a[k] - b[k]).abs() <= tol, "{f:?} vs {g:?}");
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn the_fast_path_agrees_with_the_general_clipper(
            centre in proptest::array::uniform3(-20.0f64..20.0),
            size in proptest::array::uniform3(0.1f64..6.0),
            light in proptest::array::uniform3(-40.0f64..40.0),
            directional in proptest::bool::ANY,
            eye in proptest::array::uniform3(-30.0f64..30.0),
            near in 0.01f64..1.0,
        ) {
            let (c, h) = (DVec3::from(centre), DVec3::from(size) * 0.5);
            let caster = Aabb::new((c - h).as_vec3(), (c + h).as_vec3());
            let scene = Aabb::new(glam::Vec3::new(-25.0, -3.0, -25.0), glam::Vec3::new(25.0, 25.0, 25.0));
            let light = if directional {
                let d = DVec3::from(light).normalize_or_zero();
                if d == DVec3::ZERO {
                    return Ok(());
                }
                Light::Directional { direction: d }
            } else {
                Light::Point { position: DVec3::from(light), range: None }
            };
            let Ok(cam) = Camera::look_at(DVec3::from(eye), c, DVec3::Y, 1.0, 1.3, near) else {
                return Ok(());
            };
            assert_paths_agree(&cam, &light, &caster, &scene);
        }
    }

    #[test]
    fn volume_behind_the_eye_is_empty_and_straddling_is_clipped() {
        let l = Light::Point {
            position: DVec3::new(0.0, 0.0, 0.0),
            range: None,
        };
        let caster = Aabb::new(Vec3::new(-0.5, -0.5, 11.0), Vec3::new(0.5, 0.5, 12.0));
        let scene = Aabb::new(Vec3::splat(-20.0), Vec3::splat(20.0));
        let b = volume_bounds(&cam(), (64, 64), &l, &caster, &scene);
        assert_eq!(b.scissor[0], b.scissor[2]);
        assert!(b.depth_near >= b.depth_far);
        // A caster straddling the eye plane: clipped at the near plane, full depth.
        let caster = Aabb::new(Vec3::new(-0.5, -0.5, 9.0), Vec3::new(0.5, 0.5, 11.0));
        let b = volume_bounds(&cam(), (64, 64), &l, &caster, &scene);
        assert_eq!(b.depth_near, 1.0);
        assert_eq!(b.scissor, [0, 0, 64, 64]);
    }
}
