//! Exact checks of shadow volumes in world space, shared by the shadowgen
//! tests and the volume fuzz target: signed crossings of a segment with a
//! volume's triangles (homogeneous, `w = 0` vertices included), the casting
//! triangles that block a point from the light (the reference's definition
//! of the shadow), and the open edges of a range.

use glam::{DMat4, DVec3, DVec4};
use raster::{VolumeBuffer, VolumeRange};
use scene::{Light, ObjectId, Scene};
use std::collections::HashMap;

/// Vertex `p` of `range` (local `[x, y, z, w]`) in world space.
pub fn world(range: &VolumeRange, p: [f32; 4]) -> DVec4 {
    range.world_from_local * DVec4::new(p[0] as f64, p[1] as f64, p[2] as f64, p[3] as f64)
}

/// The determinant of the four rows: positive when the fourth lies behind the
/// triangle of the first three (for `w = 0` rows too, by multilinearity).
pub fn det4(rows: [DVec4; 4]) -> f64 {
    DMat4::from_cols(rows[0], rows[1], rows[2], rows[3]).determinant()
}

/// The sign of [`det4`], or `None` when it is too close to 0 to trust
/// (relative to the sizes of its rows).
pub fn sign4(rows: [DVec4; 4]) -> Option<i32> {
    let d = det4(rows);
    let scale: f64 = rows.iter().map(|r| r.length()).product();
    if d.abs() <= 1e-7 * scale {
        None
    } else {
        Some(if d > 0.0 { 1 } else { -1 })
    }
}

/// Signed crossing of segment `p → q` (homogeneous, `w ≥ 0`) with triangle
/// `(a, b, c)`: +1 when it passes from the front to the back side, −1 the other
/// way, 0 when it misses. `None` when nearly degenerate.
pub fn crossing(p: DVec4, q: DVec4, tri: [DVec4; 3]) -> Option<i32> {
    // Translate so that the finite point p is the origin (a projective map with
    // determinant 1: signs are kept, and far-from-origin scenes keep precision).
    let o = p.truncate();
    let m = |x: DVec4| (x.truncate() - o * x.w).extend(x.w);
    let (p, q, [a, b, c]) = (m(p), m(q), tri.map(m));
    let sp = sign4([a, b, c, p])?;
    let sq = sign4([a, b, c, q])?;
    if sp == sq {
        return Some(0);
    }
    let e = [
        sign4([p, q, a, b])?,
        sign4([p, q, b, c])?,
        sign4([p, q, c, a])?,
    ];
    Some(if e[0] == e[1] && e[1] == e[2] { sq } else { 0 })
}

/// Reference: how many casting triangles of `object` block the segment from
/// `p` to the light (`None` when one is nearly degenerate).
pub fn blockers(s: &Scene, object: ObjectId, p: DVec3, l: &Light, two_sided: bool) -> Option<i32> {
    let lh = l.homogeneous();
    let mut n = 0;
    for t in 0..s.object_mesh(object).triangles().len() {
        let w = s.world_triangle(object, t);
        let casts =
            scene::faces_light(&w, l) || (two_sided && scene::faces_light(&[w[0], w[2], w[1]], l));
        if casts {
            n += crossing(p.extend(1.0), lh, w.map(|v| v.extend(1.0)))?.abs();
        }
    }
    Some(n)
}

/// Signed crossings of the segment `e → q` with every triangle of range `r`;
/// `None` when one is too close to degenerate to trust.
pub fn range_crossings(buf: &VolumeBuffer, r: &VolumeRange, e: DVec3, q: DVec3) -> Option<i32> {
    let mut count = 0;
    for t in r.indices().step_by(3) {
        let tri = buf.triangle(t / 3).map(|p| world(r, p));
        count += crossing(e.extend(1.0), q.extend(1.0), tri)?;
    }
    Some(count)
}

/// Signed crossings of `e → q` with every range of `buf`.
pub fn buffer_crossings(buf: &VolumeBuffer, e: DVec3, q: DVec3) -> Option<i32> {
    buf.ranges
        .iter()
        .try_fold(0, |n, r| Some(n + range_crossings(buf, r, e, q)?))
}

/// The open edges of range `r`: per directed edge (bitwise positions, the
/// smaller first) the number of times it is used one way minus the other;
/// empty for a closed surface.
pub fn boundary(buf: &VolumeBuffer, r: &VolumeRange) -> HashMap<([u32; 4], [u32; 4]), i32> {
    let key = |i: u32| buf.positions[i as usize].map(f32::to_bits);
    let mut m: HashMap<([u32; 4], [u32; 4]), i32> = HashMap::new();
    for t in r.indices().step_by(3) {
        let tri = [buf.indices[t], buf.indices[t + 1], buf.indices[t + 2]];
        for k in 0..3 {
            let (a, b) = (key(tri[k]), key(tri[(k + 1) % 3]));
            if a == b {
                continue;
            }
            if a < b {
                *m.entry((a, b)).or_insert(0) += 1;
            } else {
                *m.entry((b, a)).or_insert(0) -= 1;
            }
        }
    }
    m.retain(|_, v| *v != 0);
    m
}
