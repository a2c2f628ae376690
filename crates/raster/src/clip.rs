//! Homogeneous clipping of a triangle against the near, far and guard-band
//! planes (Sutherland–Hodgman in clip space, [Blinn & Newell 1978]).
//!
//! Planes, as `d(v) ≥ 0` on clip coordinates `v = (x, y, z, w)`:
//! - near `w − z ≥ 0` (depth ≤ 1), far `z ≥ 0` (depth ≥ 0);
//! - guard band `g_x·w ∓ x ≥ 0`, `g_y·w ∓ y ≥ 0` with `g = 1 + 2·GUARD_BAND_PX / size`,
//!   i.e. `w ≥ ε|x|` with `ε = 1/g_x` (and likewise for y): every surviving
//!   vertex projects to within [`crate::GUARD_BAND_PX`] pixels of the viewport.
//!
//! After clipping every vertex has `w ≥ |x|/g_x ≥ 0`, and `w = 0` only for the
//! zero vector, so setup never divides by a clip w that can be 0 (such a
//! polygon is rejected). The intersection of an edge with a plane is computed
//! from the edge's endpoints in a canonical order (lexicographic on the
//! coordinates), so two triangles sharing an edge get bit-identical clipped
//! vertices on it: shared edges stay watertight.

use glam::DVec4;

/// Most vertices a triangle can have after clipping against six planes.
pub const MAX_CLIPPED_VERTICES: usize = 9;

/// A convex polygon in clip space (f64), at most [`MAX_CLIPPED_VERTICES`] vertices.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ClipPolygon {
    pub v: [DVec4; MAX_CLIPPED_VERTICES],
    pub len: usize,
}

/// The six clip planes of a viewport, as coefficient vectors dotted with `(x, y, z, w)`.
pub(crate) fn clip_planes(gx: f64, gy: f64) -> [DVec4; 6] {
    [
        NEAR_PLANE,                     // near: w − z ≥ 0
        DVec4::new(0.0, 0.0, 1.0, 0.0), // far: z ≥ 0
        DVec4::new(-1.0, 0.0, 0.0, gx),
        DVec4::new(1.0, 0.0, 0.0, gx),
        DVec4::new(0.0, -1.0, 0.0, gy),
        DVec4::new(0.0, 1.0, 0.0, gy),
    ]
}

/// Outcome of clipping one triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ClipOutcome {
    /// All vertices inside all planes: the polygon is the triangle.
    Inside,
    /// Some plane cut the triangle.
    Clipped,
    /// Nothing is left.
    Culled,
}

fn key_less(a: DVec4, b: DVec4) -> bool {
    let ka = [a.x, a.y, a.z, a.w];
    let kb = [b.x, b.y, b.z, b.w];
    for i in 0..4 {
        match ka[i].total_cmp(&kb[i]) {
            std::cmp::Ordering::Less => return true,
            std::cmp::Ordering::Greater => return false,
            std::cmp::Ordering::Equal => {}
        }
    }
    false
}

/// The point where segment (a, b) crosses the plane, computed identically for (a, b) and (b, a).
fn intersect(a: DVec4, da: f64, b: DVec4, db: f64) -> DVec4 {
    let (p, dp, q, dq) = if key_less(a, b) {
        (a, da, b, db)
    } else {
        (b, db, a, da)
    };
    let t = dp / (dp - dq);
    p + (q - p) * t
}

/// Clips the triangle `tri` (clip coordinates) against `planes` (at most six, so
/// the polygon fits [`MAX_CLIPPED_VERTICES`]), in order.
pub(crate) fn clip_triangle<const N: usize>(
    tri: [DVec4; 3],
    planes: &[DVec4; N],
) -> (ClipOutcome, ClipPolygon) {
    let mut poly = ClipPolygon {
        v: [DVec4::ZERO; MAX_CLIPPED_VERTICES],
        len: 3,
    };
    poly.v[..3].copy_from_slice(&tri);
    let mut any_out = false;
    for p in planes {
        let d = [p.dot(tri[0]), p.dot(tri[1]), p.dot(tri[2])];
        if d.iter().all(|&d| d < 0.0) {
            return (ClipOutcome::Culled, poly);
        }
        any_out |= d.iter().any(|&d| d < 0.0);
    }
    if !any_out {
        return (ClipOutcome::Inside, poly);
    }
    let mut tmp = [DVec4::ZERO; MAX_CLIPPED_VERTICES];
    for p in planes {
        let n = poly.len;
        // Each vertex's distance once; a plane that keeps every vertex keeps
        // the polygon as it is (the loop below would copy it unchanged).
        let mut d = [0.0f64; MAX_CLIPPED_VERTICES];
        let mut all_in = true;
        for (d, v) in d.iter_mut().zip(&poly.v[..n]) {
            *d = p.dot(*v);
            all_in &= *d >= 0.0;
        }
        if all_in {
            continue;
        }
        let mut m = 0;
        for i in 0..n {
            let j = if i + 1 == n { 0 } else { i + 1 };
            let (a, b, da, db) = (poly.v[i], poly.v[j], d[i], d[j]);
            if da >= 0.0 {
                tmp[m] = a;
                m += 1;
            }
            if (da >= 0.0) != (db >= 0.0) && m < MAX_CLIPPED_VERTICES {
                tmp[m] = intersect(a, da, b, db);
                m += 1;
            }
        }
        poly.v[..m].copy_from_slice(&tmp[..m]);
        poly.len = m;
        if m < 3 {
            return (ClipOutcome::Culled, poly);
        }
    }
    (ClipOutcome::Clipped, poly)
}

/// The near plane `w − z ≥ 0`, the first of [`clip_planes`].
pub(crate) const NEAR_PLANE: DVec4 = DVec4::new(0.0, 0.0, -1.0, 1.0);

/// The segment `(exit, entry)` that clipping the triangle `tri` against the near
/// plane creates, oriented by the triangle's winding: walking `tri[0] → tri[1] →
/// tri[2]`, `exit` is where the boundary leaves the kept side (`w − z ≥ 0`) and
/// `entry` where it comes back, so the clipped polygon runs `… exit, entry …`.
/// `None` when the near plane does not cut the triangle (all vertices kept, or none).
///
/// The points are bit-identical to the vertices [`clip_triangle`] creates on the
/// near plane (it clips against the near plane first, with the same test and the
/// same canonical-order intersection), and two triangles sharing an edge get the
/// same point on it: one triangle's entry is its neighbour's exit.
pub(crate) fn near_segment(tri: [DVec4; 3]) -> Option<(DVec4, DVec4)> {
    let d = tri.map(|v| NEAR_PLANE.dot(v));
    let (mut exit, mut entry) = (None, None);
    for i in 0..3 {
        let j = (i + 1) % 3;
        match (d[i] >= 0.0, d[j] >= 0.0) {
            (true, false) => exit = Some(intersect(tri[i], d[i], tri[j], d[j])),
            (false, true) => entry = Some(intersect(tri[i], d[i], tri[j], d[j])),
            _ => {}
        }
    }
    Some((exit?, entry?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inside_triangle_is_untouched() {
        let planes = clip_planes(2.0, 2.0);
        let t = [
            DVec4::new(0.0, 0.0, 0.5, 1.0),
            DVec4::new(0.5, 0.0, 0.5, 1.0),
            DVec4::new(0.0, 0.5, 0.5, 1.0),
        ];
        let (o, p) = clip_triangle(t, &planes);
        assert_eq!(o, ClipOutcome::Inside);
        assert_eq!(p.len, 3);
    }

    #[test]
    fn near_crossing_keeps_positive_w_and_depth_at_most_one() {
        let planes = clip_planes(2.0, 2.0);
        // One vertex behind the eye (w < 0), one a point at infinity (z = 0).
        let t = [
            DVec4::new(0.0, 0.0, 0.5, -1.0),
            DVec4::new(0.5, 0.0, 0.5, 2.0),
            DVec4::new(0.3, 0.2, 0.0, 1.0),
        ];
        let (o, p) = clip_triangle(t, &planes);
        assert_eq!(o, ClipOutcome::Clipped);
        for v in &p.v[..p.len] {
            assert!(v.w > 0.0);
            assert!(v.z <= v.w * (1.0 + 1e-15));
            assert!(v.x.abs() <= 2.0 * v.w * (1.0 + 1e-15));
        }
    }

    #[test]
    fn shared_edge_clips_identically() {
        let planes = clip_planes(2.0, 2.0);
        let a = DVec4::new(0.1, 0.3, 0.5, -0.7);
        let b = DVec4::new(0.4, -0.2, 0.5, 3.1);
        let c = DVec4::new(-0.4, 0.2, 0.5, 2.1);
        let d = DVec4::new(0.9, 0.9, 0.5, 1.3);
        let (_, p1) = clip_triangle([a, b, c], &planes);
        let (_, p2) = clip_triangle([b, a, d], &planes);
        let near = |p: &ClipPolygon| -> Vec<DVec4> {
            p.v[..p.len]
                .iter()
                .copied()
                .filter(|v| (v.w - v.z).abs() < 1e-12)
                .collect()
        };
        let (n1, n2) = (near(&p1), near(&p2));
        let x1 = n1.iter().filter(|v| n2.contains(v)).count();
        assert_eq!(x1, 1);
    }

    #[test]
    fn near_segments_match_clipped_vertices_and_chain() {
        let planes = clip_planes(2.0, 2.0);
        assert_eq!(planes[0], NEAR_PLANE);
        let a = DVec4::new(0.1, 0.3, 0.5, -0.7);
        let b = DVec4::new(0.4, -0.2, 0.5, 3.1);
        let c = DVec4::new(-0.4, 0.2, 0.5, 2.1);
        let d = DVec4::new(0.9, 0.9, 0.5, 1.3);
        // a is behind the near plane, b, c, d in front.
        let (x1, n1) = near_segment([a, b, c]).unwrap();
        let (x2, n2) = near_segment([b, a, d]).unwrap();
        // [a, b, c] enters on a–b and leaves on c–a; [b, a, d] leaves on b–a.
        assert_eq!(n1, x2);
        assert_ne!(x1, n2);
        let (_, p1) = clip_triangle([a, b, c], &planes);
        let on = &p1.v[..p1.len];
        let i = on.iter().position(|v| *v == x1).unwrap();
        assert_eq!(on[(i + 1) % p1.len], n1);
        assert!(near_segment([b, c, d]).is_none());
        assert!(near_segment([a, a * 2.0, a * 3.0]).is_none());
    }
}
