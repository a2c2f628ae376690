//! The meshes the procedural city ([`super::city`]) is built from: stepped
//! buildings (one closed mesh per building, tiers joined by rings instead of
//! overlapping boxes, so silhouettes [AW §2.4] see a clean manifold) and the
//! two shared prop meshes, the tree and the lamp post. Winding:
//! counter-clockwise seen from outside; every mesh here is closed.

use super::analytic::{box_corners, box_triangles, BOX_FACES};
use crate::{Mesh, Result};
use glam::Vec3;

/// Tree: crown centre height, crown radii (horizontal, vertical), trunk radius
/// and height, metres, before the per-instance scale.
pub(super) const CROWN_Y: f32 = 5.0;
pub(super) const CROWN_RX: f32 = 2.0;
pub(super) const CROWN_RY: f32 = 3.0;
pub(super) const TRUNK_R: f32 = 0.2;
pub(super) const TRUNK_TOP: f32 = 3.0;
/// Height of a lamp post's pole, metres.
pub(super) const LAMP_HEIGHT: f32 = 6.0;

/// One tier of a building in quarter metres, local to the footprint corner:
/// `x`, `z` ranges and the height of its top.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tier {
    pub(super) x: [i32; 2],
    pub(super) z: [i32; 2],
    pub(super) top: i32,
}

pub(super) fn quarter(v: i32) -> f32 {
    v as f32 * 0.25
}

pub(super) fn push_quad(pos: &mut Vec<Vec3>, tris: &mut Vec<[u32; 3]>, q: [Vec3; 4]) {
    let b = pos.len() as u32;
    pos.extend(q);
    tris.push([b, b + 1, b + 2]);
    tris.push([b, b + 2, b + 3]);
}

/// A building: tiers stacked bottom to top, each strictly inside the one
/// below, joined by an up-facing ring; on top a flat roof or, with `apex`, a
/// hip roof rising to that height over the top tier's centre. One closed,
/// consistently wound mesh: bottom quad, 4 side quads per tier, 4 ring
/// trapezoids per step, and a top quad or 4 roof triangles. Faces follow the
/// box order of [`BOX_FACES`].
pub(super) fn building_mesh(name: String, tiers: &[Tier], apex: Option<i32>) -> Result<Mesh> {
    let mut pos = Vec::with_capacity(8 * tiers.len() + 4);
    let mut tris = Vec::with_capacity(8 * tiers.len() + 4);
    let mut bottom = 0;
    for (k, t) in tiers.iter().enumerate() {
        let c = box_corners(
            Vec3::new(quarter(t.x[0]), quarter(bottom), quarter(t.z[0])),
            Vec3::new(quarter(t.x[1]), quarter(t.top), quarter(t.z[1])),
        );
        for (f, face) in BOX_FACES.iter().enumerate() {
            // −Y only for the lowest tier; +Y is replaced by a ring or roof.
            if (f == 2 && k == 0) || (f != 2 && f != 3) {
                push_quad(&mut pos, &mut tris, face.map(|i| c[i as usize]));
            }
        }
        // The top outline, counter-clockwise seen from above (the +Y face's order).
        let ring = [c[2], c[6], c[7], c[3]];
        if let Some(next) = tiers.get(k + 1) {
            let inner = box_corners(
                Vec3::new(quarter(next.x[0]), quarter(t.top), quarter(next.z[0])),
                Vec3::new(quarter(next.x[1]), quarter(t.top), quarter(next.z[1])),
            );
            let inner = [inner[0], inner[4], inner[5], inner[1]];
            for e in 0..4 {
                let n = (e + 1) % 4;
                push_quad(&mut pos, &mut tris, [ring[e], ring[n], inner[n], inner[e]]);
            }
        } else if let Some(apex) = apex {
            let top = Vec3::new(
                0.5 * (quarter(t.x[0]) + quarter(t.x[1])),
                quarter(apex),
                0.5 * (quarter(t.z[0]) + quarter(t.z[1])),
            );
            for e in 0..4 {
                let b = pos.len() as u32;
                pos.extend([ring[e], ring[(e + 1) % 4], top]);
                tris.push([b, b + 1, b + 2]);
            }
        } else {
            push_quad(&mut pos, &mut tris, ring);
        }
        bottom = t.top;
    }
    Mesh::new(name, &pos, &tris)
}

/// A closed `n`-gon prism around the y axis from `y0` to `y1` (sides, top and
/// bottom caps), appended to `pos`/`tris`.
pub(super) fn push_prism(
    pos: &mut Vec<Vec3>,
    tris: &mut Vec<[u32; 3]>,
    n: u32,
    r: f32,
    y0: f32,
    y1: f32,
) {
    let b = pos.len() as u32;
    for i in 0..n {
        let a = std::f32::consts::TAU * i as f32 / n as f32;
        pos.push(Vec3::new(r * a.cos(), y0, r * a.sin()));
        pos.push(Vec3::new(r * a.cos(), y1, r * a.sin()));
    }
    let lo = |i: u32| b + 2 * (i % n);
    let hi = |i: u32| b + 2 * (i % n) + 1;
    for i in 0..n {
        tris.push([lo(i), hi(i), hi(i + 1)]);
        tris.push([lo(i), hi(i + 1), lo(i + 1)]);
    }
    for i in 1..n - 1 {
        tris.push([hi(0), hi(i + 1), hi(i)]);
        tris.push([lo(0), lo(i), lo(i + 1)]);
    }
}

/// The shared tree: an octagonal trunk (0 to 3 m, radius 0.2 m, 28
/// triangles) reaching into a faceted ellipsoid crown (centre 5 m, radii 2 m
/// across and 3 m up, `2·segments·(rings − 1)` triangles). Two closed shells
/// in one mesh; the tree stands on y = 0 at the origin.
pub(super) fn tree_mesh(segments: u32, rings: u32) -> Result<Mesh> {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    push_prism(&mut pos, &mut tris, 8, TRUNK_R, 0.0, TRUNK_TOP);
    let b = pos.len() as u32;
    pos.push(Vec3::new(0.0, CROWN_Y + CROWN_RY, 0.0));
    for j in 1..rings {
        let phi = std::f32::consts::PI * j as f32 / rings as f32;
        for i in 0..segments {
            let theta = std::f32::consts::TAU * i as f32 / segments as f32;
            pos.push(Vec3::new(
                CROWN_RX * phi.sin() * theta.cos(),
                CROWN_Y + CROWN_RY * phi.cos(),
                CROWN_RX * phi.sin() * theta.sin(),
            ));
        }
    }
    pos.push(Vec3::new(0.0, CROWN_Y - CROWN_RY, 0.0));
    let bottom = pos.len() as u32 - 1;
    let v = |j: u32, i: u32| b + 1 + (j - 1) * segments + i % segments;
    for i in 0..segments {
        tris.push([b, v(1, i + 1), v(1, i)]);
        for j in 1..rings - 1 {
            tris.push([v(j, i), v(j, i + 1), v(j + 1, i + 1)]);
            tris.push([v(j, i), v(j + 1, i + 1), v(j + 1, i)]);
        }
        tris.push([v(rings - 1, i), v(rings - 1, i + 1), bottom]);
    }
    Mesh::new("tree", &pos, &tris)
}

/// The shared lamp post: a hexagonal pole (6 m, radius 0.09 m), an arm along
/// +x at 5.7–5.82 m reaching 1.5 m out, and a lamp head hanging from its end;
/// three interpenetrating closed shells, 44 triangles.
pub(super) fn lamp_mesh() -> Result<Mesh> {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    push_prism(&mut pos, &mut tris, 6, 0.09, 0.0, LAMP_HEIGHT);
    for (min, max) in [
        (Vec3::new(0.0, 5.7, -0.05), Vec3::new(1.5, 5.82, 0.05)),
        (Vec3::new(1.15, 5.5, -0.18), Vec3::new(1.55, 5.78, 0.18)),
    ] {
        let b = pos.len() as u32;
        pos.extend(box_corners(min, max));
        tris.extend(box_triangles().map(|t| t.map(|i| b + i)));
    }
    Mesh::new("lamp post", &pos, &tris)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::Topology;

    /// Signed volume (positive for a closed mesh wound outward).
    pub(in crate::procedural) fn signed_volume(m: &Mesh) -> f64 {
        (0..m.triangles().len())
            .map(|t| {
                let [a, b, c] = m.triangle(t).map(|p| p.as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Closed, manifold, consistently wound outward, nothing degenerate.
    pub(in crate::procedural) fn assert_closed(m: &Mesh) {
        assert_eq!(m.topology(), Topology::default(), "mesh {}", m.name());
        assert!(signed_volume(m) > 0.0, "mesh {} is inside out", m.name());
    }

    #[test]
    fn building_shapes_are_closed() {
        let base = Tier {
            x: [0, 40],
            z: [0, 32],
            top: 100,
        };
        let flat = building_mesh("flat".into(), &[base], None).unwrap();
        assert_eq!(flat.triangles().len(), 12);
        assert_closed(&flat);
        assert!((signed_volume(&flat) - 10.0 * 8.0 * 25.0).abs() < 1e-9);
        let hip = building_mesh("hip".into(), &[Tier { top: 80, ..base }], Some(100)).unwrap();
        assert_eq!(hip.triangles().len(), 14);
        assert_closed(&hip);
        assert_eq!(hip.bounds().max.y, 25.0);
        let tiers = [
            Tier { top: 40, ..base },
            Tier {
                x: [4, 36],
                z: [3, 30],
                top: 70,
            },
            Tier {
                x: [8, 30],
                z: [6, 20],
                top: 100,
            },
        ];
        let tower = building_mesh("tower".into(), &tiers, None).unwrap();
        assert_eq!(tower.triangles().len(), 44);
        assert_closed(&tower);
        let want = 10.0 * 8.0 * 10.0 + 8.0 * 6.75 * 7.5 + 5.5 * 3.5 * 7.5;
        assert!((signed_volume(&tower) - want).abs() < 1e-9);
    }

    #[test]
    fn tree_and_lamp_are_closed() {
        let tree = tree_mesh(16, 10).unwrap();
        assert_eq!(tree.triangles().len(), 316);
        assert_closed(&tree);
        assert_eq!(tree.bounds().max.y, CROWN_Y + CROWN_RY);
        assert_eq!(tree.bounds().min.y, 0.0);
        let small = tree_mesh(3, 2).unwrap();
        assert_eq!(small.triangles().len(), 2 * 3 + 28);
        assert_closed(&small);
        let lamp = lamp_mesh().unwrap();
        assert_eq!(lamp.triangles().len(), 44);
        assert_closed(&lamp);
        assert_eq!(lamp.bounds().max.y, LAMP_HEIGHT);
    }
}
