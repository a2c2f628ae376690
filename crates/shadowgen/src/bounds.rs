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
//! relative factor `1 ± BOUNDS_MARGIN · DEPTH_ERROR` (raster's ε_z). Spot cones
//! are not used yet.

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
        return nothing;
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
            return nothing;
        }
    }
    // Eye-relative from here on (precision far from the origin).
    let eye = camera.position;
    let (lo, hi) = (lo - eye, hi - eye);
    let (blo, bhi) = (blo - eye, bhi - eye);
    let r = (0..8)
        .map(|i| corner(lo, hi, i).length())
        .fold(0.0, f64::max);
    let m = BOUNDS_MARGIN * DEPTH_ERROR * r;
    let (lo, hi) = (lo - DVec3::splat(m), hi + DVec3::splat(m));
    // Early outs: the box wholly behind the near plane or outside a side plane
    // of the view frustum (side planes pass through the eye: d = 0 here).
    let frustum = camera.frustum();
    let outside = |n: DVec3, d: f64| {
        let far = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
        n.dot(far) + d < 0.0
    };
    if outside(camera.forward(), -camera.near)
        || frustum.planes[..4]
            .iter()
            .any(|p| outside(p.normal, m * p.normal.length()))
    {
        return nothing;
    }

    // Half-spaces n·x + d ≥ 0 holding the swept set H, each pushed out by m.
    let mut planes = [(DVec3::ZERO, 0.0f64); 19];
    let mut np = 0;
    let mut add = |n: DVec3, d: f64| {
        if n != DVec3::ZERO && n.is_finite() && d.is_finite() {
            planes[np] = (n, d + m * n.length());
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
            let side = bc.map(|c| n.dot(c - a));
            if side.iter().all(|&v| v >= 0.0) {
                add(n, -n.dot(a));
            } else if side.iter().all(|&v| v <= 0.0) {
                add(-n, n.dot(a));
            }
        }
    }
    // The near plane: view distance ≥ near.
    let fwd = camera.forward();
    let near = camera.near;
    planes[np] = (fwd, -near);
    np += 1;
    // Drop half-spaces that hold the whole box; a box wholly outside one is empty.
    let mut kept = 0;
    for i in 0..np {
        let (n, d) = planes[i];
        let near_corner = DVec3::select(n.cmpge(DVec3::ZERO), lo, hi);
        if n.dot(near_corner) + d >= 0.0 {
            continue;
        }
        if outside(n, d) {
            return nothing;
        }
        planes[kept] = planes[i];
        kept += 1;
    }
    let planes = &planes[..kept];

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
    let clip = camera.clip_from_eye_relative();
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let (mut wmin, mut wmax) = (f64::MAX, f64::MIN);
    let mut any = false;
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
            let p = clip * x.extend(1.0);
            let pw = p.w.max(near);
            let (px, py) = (p.x / pw, p.y / pw);
            xmin = xmin.min(px);
            xmax = xmax.max(px);
            ymin = ymin.min(py);
            ymax = ymax.max(py);
            wmin = wmin.min(pw);
            wmax = wmax.max(pw);
            any = true;
        }
    }
    if !any {
        return nothing;
    }
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
    let dn = (near / wmin * (1.0 + k)).min(1.0);
    let df = (near / wmax * (1.0 - k)).max(0.0);
    let depth_near = round_up(dn).min(1.0);
    let depth_far = round_down(df).max(0.0);
    VolumeBounds {
        scissor: [x0, y0, x1.max(x0), y1.max(y0)],
        depth_near,
        depth_far: depth_far.min(depth_near),
    }
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

/// A convex polygon of at most 32 vertices: 4 plus one per clipping plane
/// (at most 6 + 19 − 1 of them).
struct Poly {
    v: [DVec3; 32],
    n: usize,
}

impl Default for Poly {
    fn default() -> Self {
        Poly {
            v: [DVec3::ZERO; 32],
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

fn corner(lo: DVec3, hi: DVec3, i: usize) -> DVec3 {
    DVec3::new(
        if i & 1 != 0 { hi.x } else { lo.x },
        if i & 2 != 0 { hi.y } else { lo.y },
        if i & 4 != 0 { hi.z } else { lo.z },
    )
}

fn round_up(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v {
        f.next_up()
    } else {
        f
    }
}

fn round_down(v: f64) -> f32 {
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
