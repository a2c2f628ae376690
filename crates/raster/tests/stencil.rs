//! Stencil pass: zpass / zfail counting against brute-force references, 8-bit
//! wrapping, background pixels, infinite volumes; per-volume scissor and depth
//! bounds against the untested pass; zp+ against zfail and legal zpass.

use crate::perspective;
use glam::{DMat4, DVec3, DVec4, Mat4, Vec3, Vec4};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use raster::*;

const W: u32 = 64;
const H: u32 = 48;

/// Right-handed look-at view (the camera looks down −z) composed with the projection.
fn camera(eye: Vec3, target: Vec3) -> Mat4 {
    let f = (target - eye).normalize();
    let s = f.cross(Vec3::Y).normalize();
    let u = s.cross(f);
    let view = Mat4::from_cols(
        Vec4::new(s.x, u.x, -f.x, 0.0),
        Vec4::new(s.y, u.y, -f.y, 0.0),
        Vec4::new(s.z, u.z, -f.z, 0.0),
        Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    );
    perspective(1.0, W as f32 / H as f32, 0.1) * view
}

/// A volume buffer holding one range over all of `positions` / `tris`.
fn volume(
    positions: &[Vec4],
    tris: &[[u32; 3]],
    method: VolumeMethod,
) -> (VolumeBuffer, VolumeRange) {
    let mut buf = VolumeBuffer::new();
    buf.positions.extend(positions.iter().map(|p| p.to_array()));
    buf.indices.extend(tris.iter().flatten());
    let range = VolumeRange {
        object: 0,
        segment: 0,
        world_from_local: DMat4::IDENTITY,
        method,
        first_vertex: 0,
        vertex_count: positions.len() as u32,
        first_index: 0,
        index_count: buf.indices.len() as u32,
        light_cap: 0..0,
        dark_cap: 0..0,
        depth_near: 1.0,
        depth_far: 0.0,
        scissor: VolumeRange::FULL_SCISSOR,
        band: VolumeRange::FULL_SCISSOR,
        planes: [None, None],
    };
    buf.ranges.push(range.clone());
    assert_eq!(buf.check(), Ok(()));
    (buf, range)
}

fn stencil_of(
    eye: &DepthTarget,
    m: Mat4,
    positions: &[Vec4],
    tris: &[[u32; 3]],
    method: VolumeMethod,
    bits: StencilBits,
) -> (StencilTarget, StencilStats) {
    let (buf, range) = volume(positions, tris, method);
    let mut s = StencilTarget::new(W, H, bits).unwrap();
    let mut st = StencilStats::default();
    s.draw_volume(eye, m, &buf, &range, StencilTests::default(), &mut st)
        .unwrap();
    (s, st)
}

/// A quad through `c` spanned by `u`, `v` (±1 each), as two triangles.
fn quad(c: Vec3, u: Vec3, v: Vec3) -> ([Vec4; 4], [[u32; 3]; 2]) {
    let p = [c - u - v, c + u - v, c + u + v, c - u + v].map(|p| p.extend(1.0));
    (p, [[0, 1, 2], [0, 2, 3]])
}

fn depth_of(m: Mat4, meshes: &[(&[Vec4], &[[u32; 3]])]) -> DepthTarget {
    let mut eye = DepthTarget::new(W, H, TileSize::T8, false).unwrap();
    for (k, (p, t)) in meshes.iter().enumerate() {
        let item = DrawItem {
            clip_from_local: m,
            positions: p,
            triangles: t,
            object: k as u32,
            cull: raster::CullMode::None,
        };
        eye.draw(&item, Coverage::Standard).unwrap();
    }
    eye
}

/// World point of the ray through pixel `(x, y)`'s centre and the plane `n·p = d`.
fn surface_point(m: Mat4, eye: DVec3, x: u32, y: u32, n: DVec3, d: f64) -> DVec3 {
    let inv = m.as_dmat4().inverse();
    let ndc = DVec4::new(
        2.0 * (x as f64 + 0.5) / W as f64 - 1.0,
        1.0 - 2.0 * (y as f64 + 0.5) / H as f64,
        0.5,
        1.0,
    );
    let q = inv * ndc;
    let q = q.truncate() / q.w;
    let dir = q - eye;
    let t = (d - n.dot(eye)) / n.dot(dir);
    eye + dir * t
}

#[test]
fn box_volumes_are_wound_front_facing_from_outside() {
    // AABB_TRIANGLES are CCW seen from outside; the +Z face seen from +Z is Front,
    // the −Z face Back (the Facing convention, CCW in NDC).
    let m = camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO);
    let c = aabb_corners(Vec3::splat(-1.0), Vec3::splat(1.0));
    let f = |t: [u32; 3]| facing(t.map(|i| m * c[i as usize]));
    assert_eq!(f(AABB_TRIANGLES[10]), Some(Facing::Front));
    assert_eq!(f(AABB_TRIANGLES[11]), Some(Facing::Front));
    assert_eq!(f(AABB_TRIANGLES[8]), Some(Facing::Back));
    assert_eq!(f(AABB_TRIANGLES[9]), Some(Facing::Back));
}

#[test]
fn closed_box_counts_surface_points_inside() {
    let (bmin, bmax) = (Vec3::new(-1.0, -0.8, -1.2), Vec3::new(1.2, 1.0, 0.9));
    let corners = aabb_corners(bmin, bmax);
    let inside = |p: DVec3, eps: f64| {
        let (lo, hi) = (bmin.as_dvec3(), bmax.as_dvec3());
        (0..3).all(|i| p[i] > lo[i] + eps && p[i] < hi[i] - eps)
    };
    // Planes n·p = d: behind, in front of, and through the box (tilted).
    let planes = [
        (DVec3::Z, -3.0),
        (DVec3::Z, 2.0),
        (DVec3::new(0.3, 0.2, 1.0).normalize(), 0.1),
        (DVec3::new(-0.5, 1.0, 0.4).normalize(), -0.2),
        (DVec3::new(1.0, -0.1, 0.2).normalize(), 0.3),
    ];
    // (eye, target, eye inside the box): zpass is only checked with the eye outside.
    let eyes = [
        (Vec3::new(0.7, 1.1, 6.0), Vec3::new(0.1, 0.0, 0.0), false),
        (Vec3::new(-4.0, 3.0, 4.5), Vec3::new(0.1, 0.0, 0.0), false),
        (Vec3::new(0.2, 0.1, 0.3), Vec3::new(1.0, -0.7, -3.0), true),
    ];
    let mut checked_inside = 0;
    for &(eye_pos, target, eye_inside) in &eyes {
        let m = camera(eye_pos, target);
        for &(n, d) in &planes {
            // The plane as a big quad (centre n·d).
            let nf = n.as_vec3();
            let u = nf.any_orthonormal_vector() * 40.0;
            let v = nf.cross(u);
            let (qp, qt) = quad(nf * d as f32, u, v);
            let eye = depth_of(m, &[(&qp, &qt)]);
            for method in [
                VolumeMethod::ZFail,
                VolumeMethod::ZPass,
                VolumeMethod::ZpPlus,
            ] {
                if eye_inside && method == VolumeMethod::ZPass {
                    continue;
                }
                let (s, st) = stencil_of(
                    &eye,
                    m,
                    &corners,
                    &AABB_TRIANGLES,
                    method,
                    StencilBits::Wide,
                );
                assert_eq!(st.triangles, 12);
                for y in 0..H {
                    for x in 0..W {
                        let got = s.value(x, y);
                        if eye.depth_at(x, y).is_none() {
                            assert_eq!(got, 0);
                            continue;
                        }
                        let p = surface_point(m, eye_pos.as_dvec3(), x, y, n, d);
                        let eps = 1e-2;
                        if inside(p, -eps) && !inside(p, eps) {
                            continue; // within eps of a face
                        }
                        let want = i32::from(inside(p, eps));
                        checked_inside += want;
                        assert_eq!(
                            got, want,
                            "{method:?} eye {eye_pos} plane {n} {d} pixel ({x}, {y}) point {p}"
                        );
                    }
                }
            }
        }
    }
    assert!(checked_inside > 100, "{checked_inside}");
}

#[test]
fn eight_bit_counters_wrap_at_256() {
    let m = camera(Vec3::new(0.5, 0.8, 6.0), Vec3::ZERO);
    let corners = aabb_corners(Vec3::splat(-1.0), Vec3::splat(1.0));
    let tris: Vec<[u32; 3]> = (0..256).flat_map(|_| AABB_TRIANGLES).collect();
    let (qp, qt) = quad(Vec3::ZERO, Vec3::X * 30.0, Vec3::Y * 30.0);
    let eye = depth_of(m, &[(&qp, &qt)]);
    let (s8, st8) = stencil_of(
        &eye,
        m,
        &corners,
        &tris,
        VolumeMethod::ZFail,
        StencilBits::Eight,
    );
    let (sw, stw) = stencil_of(
        &eye,
        m,
        &corners,
        &tris,
        VolumeMethod::ZFail,
        StencilBits::Wide,
    );
    // Same work; only the modeled bytes differ (1-byte against 4-byte counters).
    let work = |s: &StencilStats| {
        (
            s.pixels_processed,
            s.stencil_updates,
            s.triangles,
            s.pixels_touched,
        )
    };
    assert_eq!(work(&st8), work(&stw));
    assert!(st8.pixel_bytes < stw.pixel_bytes);
    assert_eq!(st8.triangles, 256 * 12);
    let (one, _) = stencil_of(
        &eye,
        m,
        &corners,
        &AABB_TRIANGLES,
        VolumeMethod::ZFail,
        StencilBits::Eight,
    );
    let mut shadowed = 0;
    for y in 0..H {
        for x in 0..W {
            assert_eq!(s8.value(x, y), 0, "pixel ({x}, {y})");
            assert_eq!(sw.value(x, y), 256 * one.value(x, y));
            shadowed += u32::from(one.value(x, y) == 1);
        }
    }
    assert!(shadowed > 50, "{shadowed}");
}

#[test]
fn background_pixels_are_never_touched() {
    let m = camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO);
    // A small surface far behind, and a front-facing triangle in front covering more.
    let (qp, qt) = quad(Vec3::new(0.0, 0.0, -5.0), Vec3::X * 2.0, Vec3::Y * 1.5);
    let eye = depth_of(m, &[(&qp, &qt)]);
    let tri = [
        Vec4::new(-3.0, -2.0, 0.0, 1.0),
        Vec4::new(3.0, -2.0, 0.0, 1.0),
        Vec4::new(0.0, 2.5, 0.0, 1.0),
    ];
    let cover = depth_of(m, &[(&tri, &[[0, 1, 2]])]);
    for method in [VolumeMethod::ZPass, VolumeMethod::ZFail] {
        for bits in [StencilBits::Eight, StencilBits::Wide] {
            let (s, st) = stencil_of(&eye, m, &tri, &[[0, 1, 2]], method, bits);
            let (mut covered_bg, mut covered_fg) = (0, 0);
            for y in 0..H {
                for x in 0..W {
                    let covered = cover.depth_at(x, y).is_some();
                    if eye.depth_at(x, y).is_none() {
                        assert_eq!(s.value(x, y), 0);
                        covered_bg += u32::from(covered);
                    } else {
                        covered_fg += u64::from(covered);
                        // zpass: the front face in front of the surface enters (+1);
                        // zfail: it passes, so nothing changes.
                        let want = i32::from(covered && method == VolumeMethod::ZPass);
                        assert_eq!(s.value(x, y), want, "{method:?} ({x}, {y})");
                    }
                }
            }
            assert!(covered_bg > 100 && covered_fg > 100);
            assert_eq!(st.pixels_processed, covered_fg);
            let updates = if method == VolumeMethod::ZPass {
                covered_fg
            } else {
                0
            };
            assert_eq!(st.stencil_updates, updates);
            assert_eq!(st.triangles, 1);
        }
    }
}

/// Orients every triangle of a convex volume outward (CCW seen from outside),
/// using finite stand-ins `p + 10·d` for the points at infinity `(d, 0)`.
fn orient_outward(pos: &[Vec4], tris: &mut [[u32; 3]], interior: DVec3) {
    for t in tris.iter_mut() {
        let q = t.map(|i| {
            let p = pos[i as usize].as_dvec4();
            if p.w == 0.0 {
                // Direction away from the light; its base is the matching finite vertex.
                let base = pos[i as usize - 4].as_dvec4().truncate();
                base + p.truncate() * 10.0
            } else {
                p.truncate()
            }
        });
        let n = (q[1] - q[0]).cross(q[2] - q[0]);
        if n.dot(q[0] - interior) < 0.0 {
            t.swap(1, 2);
        }
    }
}

#[test]
fn infinite_volume_zpass_equals_zfail_outside() {
    let light = Vec3::new(0.3, 5.0, -0.2);
    // Occluder quad at y = 2, its four corners; extruded corners are points at infinity.
    let quad_pts = [
        Vec3::new(-1.0, 2.0, -1.0),
        Vec3::new(1.0, 2.0, -1.0),
        Vec3::new(1.2, 2.0, 0.8),
        Vec3::new(-0.9, 2.0, 1.1),
    ];
    let mut pos: Vec<Vec4> = quad_pts.iter().map(|p| p.extend(1.0)).collect();
    pos.extend(quad_pts.iter().map(|p| (*p - light).extend(0.0)));
    let cap = [[0u32, 1, 2], [0, 2, 3]];
    let mut tris: Vec<[u32; 3]> = cap.to_vec();
    tris.extend([[4, 5, 6], [4, 6, 7]]);
    for i in 0..4u32 {
        let j = (i + 1) % 4;
        tris.extend([[i, j, j + 4], [i, j + 4, i + 4]]);
    }
    let c = quad_pts.iter().copied().sum::<Vec3>().as_dvec3() / 4.0;
    let interior = c + (c - light.as_dvec3()) * 0.5;
    orient_outward(&pos, &mut tris, interior);
    // The eye pass draws the occluder with the light cap's own triangles (so the cap
    // is coplanar with the surface it caps: equal depth fails) and a ground plane.
    let cap_tris = [tris[0], tris[1]];
    let (gp, gt) = quad(Vec3::ZERO, Vec3::X * 40.0, Vec3::Z * 40.0);
    for eye_pos in [Vec3::new(6.0, 8.0, 10.0), Vec3::new(-3.0, 4.0, 7.0)] {
        let m = camera(eye_pos, Vec3::new(0.0, 0.5, 0.0));
        let eye = depth_of(m, &[(&pos[..4], &cap_tris), (&gp, &gt)]);
        let (zp, _) = stencil_of(&eye, m, &pos, &tris, VolumeMethod::ZPass, StencilBits::Wide);
        let (zf, _) = stencil_of(&eye, m, &pos, &tris, VolumeMethod::ZFail, StencilBits::Wide);
        let occluder = depth_of(m, &[(&pos[..4], &cap_tris)]);
        // Signed distance of the 2D point (x, z) to the quad's edges (CCW or CW), > 0 inside.
        let quad_margin = |qx: f64, qz: f64| {
            let q2 = quad_pts.map(|p| (p.x as f64, p.z as f64));
            let mut d = f64::INFINITY;
            let mut sign = 0.0;
            for i in 0..4 {
                let (a, b) = (q2[i], q2[(i + 1) % 4]);
                let (ex, ez) = (b.0 - a.0, b.1 - a.1);
                let cr = (ex * (qz - a.1) - ez * (qx - a.0)) / (ex * ex + ez * ez).sqrt();
                if sign == 0.0 {
                    sign = if cr >= 0.0 { 1.0 } else { -1.0 };
                }
                d = d.min(cr * sign);
                if cr * sign < 0.0 {
                    return -1.0;
                }
            }
            d
        };
        let (mut shadow, mut lit_cap, mut checked) = (0, 0, 0);
        for y in 0..H {
            for x in 0..W {
                assert_eq!(zp.value(x, y), zf.value(x, y), "pixel ({x}, {y})");
                assert!((0..=1).contains(&zf.value(x, y)));
                shadow += u32::from(zf.nonzero(x, y));
                if occluder.depth_at(x, y).is_some()
                    && occluder.depth_at(x, y) == eye.depth_at(x, y)
                {
                    // The occluder's own top: its light cap has equal depth, which fails.
                    assert_eq!(zf.value(x, y), 0, "occluder pixel ({x}, {y})");
                    lit_cap += 1;
                } else if eye.depth_at(x, y).is_some() {
                    // Ground: shadowed iff the segment to the light crosses the quad.
                    let p = surface_point(m, eye_pos.as_dvec3(), x, y, DVec3::Y, 0.0);
                    let l = light.as_dvec3();
                    let q = p + (l - p) * (2.0 / l.y);
                    let margin = quad_margin(q.x, q.z);
                    if margin.abs() > 0.02 {
                        assert_eq!(zf.value(x, y), i32::from(margin > 0.0), "ground ({x}, {y})");
                        checked += 1;
                    }
                }
            }
        }
        assert!(lit_cap > 20, "{lit_cap}");
        assert!(checked > W * H / 2, "{checked}");
        assert!(shadow > 20 && shadow < W * H / 2, "{shadow}");
    }
}

#[test]
fn errors_are_found_before_drawing() {
    let m = camera(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO);
    let (qp, qt) = quad(Vec3::ZERO, Vec3::X * 30.0, Vec3::Y * 30.0);
    let eye = depth_of(m, &[(&qp, &qt)]);
    let (buf, mut range) = volume(&qp, &qt, VolumeMethod::ZPass);
    let mut st = StencilStats::default();
    assert!(matches!(
        StencilTarget::new(0, 4, StencilBits::Eight),
        Err(Error::InvalidSize { .. })
    ));
    let mut small = StencilTarget::new(W - 1, H, StencilBits::Eight).unwrap();
    assert!(matches!(
        small.draw_volume(&eye, m, &buf, &range, StencilTests::default(), &mut st),
        Err(Error::SizeMismatch { .. })
    ));
    let mut s = StencilTarget::new(W, H, StencilBits::Wide).unwrap();
    assert_eq!(s.bits(), StencilBits::Wide);
    range.index_count += 3;
    assert!(matches!(
        s.draw_volume(&eye, m, &buf, &range, StencilTests::default(), &mut st),
        Err(Error::IndexOutOfRange { .. })
    ));
    let mut bad = buf.clone();
    bad.indices[4] = 99;
    range.index_count -= 3;
    assert!(matches!(
        s.draw_volume(&eye, m, &bad, &range, StencilTests::default(), &mut st),
        Err(Error::IndexOutOfRange {
            triangle: 1,
            index: 99,
            ..
        })
    ));
    assert_eq!(st, StencilStats::default());
    s.draw_volume(&eye, m, &buf, &range, StencilTests::default(), &mut st)
        .unwrap();
    assert!(st.stencil_updates == 0 && st.pixels_processed > 0 && st.triangles == 2);
    s.clear();
    assert!((0..H).all(|y| (0..W).all(|x| !s.nonzero(x, y))));
}

// ---------------------------------------------------------------------------
// Random closed volumes, scissor / depth bounds, zp+.

/// `det[P0 P1 P2 X]` of homogeneous points: positive when `(P0, P1, P2)` is
/// counter-clockwise seen from the side away from the finite point `X` (valid for
/// points at infinity too, as the limit of far finite points).
fn det4(p: [Vec4; 3], x: DVec3) -> f64 {
    DMat4::from_cols(
        p[0].as_dvec4(),
        p[1].as_dvec4(),
        p[2].as_dvec4(),
        x.extend(1.0),
    )
    .determinant()
}

/// Orients every triangle of a convex volume outward from `interior`; `None` when a
/// triangle is (nearly) coplanar with it.
fn orient_homogeneous(pos: &[Vec4], tris: &mut [[u32; 3]], interior: DVec3) -> Option<()> {
    for t in tris.iter_mut() {
        let d = det4(t.map(|i| pos[i as usize]), interior);
        if d.abs() < 1e-6 {
            return None;
        }
        if d < 0.0 {
            t.swap(1, 2);
        }
    }
    Some(())
}

/// A convex closed volume.
#[derive(Clone, Debug)]
enum Shape {
    Box {
        c: [f32; 3],
        h: [f32; 3],
    },
    Tet([[f32; 3]; 4]),
    /// An occluder triangle extruded away from a point light (light cap, dark cap
    /// at infinity, sides).
    PointLight {
        tri: [[f32; 3]; 3],
        light: [f32; 3],
    },
    /// An occluder triangle extruded along a direction (light cap, sides meeting in
    /// one point at infinity).
    Directional {
        tri: [[f32; 3]; 3],
        dir: [f32; 3],
    },
}

/// A volume's positions and outward triangles, plus the occluder triangle (drawn
/// in the eye pass, so its light cap has the surface's own depth) if any.
struct Closed {
    pos: Vec<Vec4>,
    tris: Vec<[u32; 3]>,
    occluder: Option<[Vec4; 3]>,
}

fn closed_volume(shape: &Shape) -> Option<Closed> {
    let v = Vec3::from_array;
    let (pos, mut tris, interior, occluder) = match shape {
        Shape::Box { c, h } => {
            let (c, h) = (v(*c), v(*h));
            let pos = aabb_corners(c - h, c + h).to_vec();
            (pos, AABB_TRIANGLES.to_vec(), c.as_dvec3(), None)
        }
        Shape::Tet(p) => {
            let pos: Vec<Vec4> = p.iter().map(|p| v(*p).extend(1.0)).collect();
            let c = p.iter().map(|p| v(*p).as_dvec3()).sum::<DVec3>() / 4.0;
            (
                pos,
                vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]],
                c,
                None,
            )
        }
        Shape::PointLight { tri, light } => {
            let l = v(*light);
            let p = tri.map(v);
            let mut pos: Vec<Vec4> = p.iter().map(|p| p.extend(1.0)).collect();
            pos.extend(p.iter().map(|p| (*p - l).extend(0.0)));
            let mut tris = vec![[0, 1, 2], [3, 4, 5]];
            for i in 0..3u32 {
                let j = (i + 1) % 3;
                tris.extend([[i, j, j + 3], [i, j + 3, i + 3]]);
            }
            let c = p.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / 3.0;
            let interior = c + (c - l.as_dvec3()) * 0.5;
            let occ = [pos[0], pos[1], pos[2]];
            (pos, tris, interior, Some(occ))
        }
        Shape::Directional { tri, dir } => {
            let d = v(*dir);
            let p = tri.map(v);
            let mut pos: Vec<Vec4> = p.iter().map(|p| p.extend(1.0)).collect();
            pos.push(d.extend(0.0));
            let tris = vec![[0, 1, 2], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
            let c = p.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / 3.0;
            let interior = c + d.as_dvec3() * 0.5;
            let occ = [pos[0], pos[1], pos[2]];
            (pos, tris, interior, Some(occ))
        }
    };
    orient_homogeneous(&pos, &mut tris, interior)?;
    Some(Closed {
        pos,
        tris,
        occluder,
    })
}

/// A random scene: a camera near the origin looking roughly down −z, volumes
/// around it (often cut by the near plane, sometimes around the eye), receiver
/// planes at least 0.5 from the eye (stored depths stay below 1).
#[derive(Clone, Debug)]
struct SceneSpec {
    eye: [f32; 3],
    look: [f32; 2],
    shapes: Vec<Shape>,
    /// (normal, distance from the eye).
    receivers: Vec<([f32; 3], f32)>,
}

fn shape_strategy() -> impl Strategy<Value = Shape> {
    let pt = || [-2.0f32..2.0, -2.0f32..2.0, -3.0f32..1.0];
    prop_oneof![
        (
            [-1.5f32..1.5, -1.5f32..1.5, -2.5f32..1.0],
            [0.05f32..1.5, 0.05f32..1.5, 0.05f32..1.5]
        )
            .prop_map(|(c, h)| Shape::Box { c, h }),
        [pt(), pt(), pt(), pt()].prop_map(Shape::Tet),
        ([pt(), pt(), pt()], pt()).prop_map(|(tri, light)| Shape::PointLight { tri, light }),
        (
            [pt(), pt(), pt()],
            [-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0]
        )
            .prop_map(|(tri, dir)| Shape::Directional { tri, dir }),
    ]
}

fn scene_strategy() -> impl Strategy<Value = SceneSpec> {
    (
        [-0.3f32..0.3, -0.3f32..0.3, -0.3f32..0.3],
        [-0.6f32..0.6, -0.6f32..0.6],
        prop::collection::vec(shape_strategy(), 1..4),
        prop::collection::vec(
            ([-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0], 0.5f32..4.0),
            1..3,
        ),
    )
        .prop_map(|(eye, look, shapes, receivers)| SceneSpec {
            eye,
            look,
            shapes,
            receivers,
        })
}

struct Built {
    m: Mat4,
    eye: DepthTarget,
    volumes: Vec<Closed>,
}

fn build_scene(sc: &SceneSpec) -> Built {
    let e = Vec3::from_array(sc.eye);
    let m = camera(e, e + Vec3::new(sc.look[0], sc.look[1], -1.0));
    let volumes: Vec<Closed> = sc.shapes.iter().filter_map(closed_volume).collect();
    let mut quads = Vec::new();
    for (n, dist) in &sc.receivers {
        let n = Vec3::from_array(*n);
        if n.length() < 0.1 {
            continue;
        }
        let n = n.normalize();
        let (u, v) = n.any_orthonormal_pair();
        quads.push(quad(e + n * *dist, u * 60.0, v * 60.0));
    }
    let mut meshes: Vec<(&[Vec4], &[[u32; 3]])> =
        quads.iter().map(|(p, t)| (&p[..], &t[..])).collect();
    let occ_tri = [[0u32, 1, 2]];
    for v in &volumes {
        if let Some(o) = &v.occluder {
            meshes.push((&o[..], &occ_tri[..]));
        }
    }
    let eye = depth_of(m, &meshes);
    Built { m, eye, volumes }
}

/// Whether every vertex lies strictly on the kept side of the near plane (`w > z`)
/// with positive clip w: the volume misses the near plane, zpass is legal, and
/// projecting the vertices bounds the volume's image.
fn in_front(m: Mat4, pos: &[Vec4]) -> bool {
    pos.iter().all(|p| {
        let c = (m * *p).as_dvec4();
        c.w > 0.0 && c.w - c.z > 0.0
    })
}

/// Conservative scissor and depth bounds of a volume: projected vertices when every
/// vertex has clip w > 0 (a point at infinity then projects to its vanishing
/// point), widened by 2 pixels and 1e-5 relative; unbounded otherwise.
fn conservative_bounds(m: Mat4, pos: &[Vec4]) -> ([u32; 4], f32, f32) {
    let clip: Vec<DVec4> = pos.iter().map(|p| (m * *p).as_dvec4()).collect();
    if clip.iter().any(|c| c.w <= 0.0) {
        return (VolumeRange::FULL_SCISSOR, 1.0, 0.0);
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    let (mut zlo, mut zhi) = (f64::MAX, f64::MIN);
    for c in &clip {
        let x = (c.x / c.w + 1.0) * 0.5 * W as f64;
        let y = (1.0 - c.y / c.w) * 0.5 * H as f64;
        let z = c.z / c.w;
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        (zlo, zhi) = (zlo.min(z), zhi.max(z));
    }
    let px = |v: f64, lim: u32| v.clamp(0.0, f64::from(lim)) as u32;
    let scissor = [
        px((x0 - 2.0).floor(), W),
        px((y0 - 2.0).floor(), H),
        px((x1 + 2.0).ceil(), W),
        px((y1 + 2.0).ceil(), H),
    ];
    let near = (zhi * (1.0 + 1e-5)).min(1.0) as f32;
    let far = (zlo * (1.0 - 1e-5)).max(0.0) as f32;
    (scissor, near.next_up().min(1.0), far.next_down().max(0.0))
}

fn draw_one(
    b: &Built,
    v: &Closed,
    method: VolumeMethod,
    bounds: Option<([u32; 4], f32, f32)>,
    tests: StencilTests,
) -> (StencilTarget, StencilStats) {
    let (buf, mut range) = volume(&v.pos, &v.tris, method);
    if let Some((scissor, near, far)) = bounds {
        range.scissor = scissor;
        range.depth_near = near;
        range.depth_far = far;
    }
    let mut s = StencilTarget::new(W, H, StencilBits::Wide).unwrap();
    let mut st = StencilStats::default();
    s.draw_volume(&b.eye, b.m, &buf, &range, tests, &mut st)
        .unwrap();
    (s, st)
}

/// Pixels where `a` and `b` differ, skipping pixels whose stored depth is exactly 1
/// (a surface on the near plane, where the near cap's strict test fails).
fn differing(b: &Built, a: &StencilTarget, c: &StencilTarget) -> Vec<(u32, u32, i32, i32)> {
    let mut out = Vec::new();
    for y in 0..H {
        for x in 0..W {
            if b.eye.depth_at(x, y) == Some(1.0) {
                continue;
            }
            if a.value(x, y) != c.value(x, y) {
                out.push((x, y, a.value(x, y), c.value(x, y)));
            }
        }
    }
    out
}

/// What a zp+ check saw, to show the tests are not vacuous.
#[derive(Default, Debug)]
struct ZpSeen {
    volumes: u32,
    /// Volumes the near plane cuts, where the near cap changed some pixel.
    cap_matters: u32,
    /// Volumes with a non-zero count somewhere.
    shadowing: u32,
    zpass_checked: u32,
}

/// zp+ == zfail pixel for pixel, and zpass == zfail where zpass is legal, per volume.
fn check_zp_plus(sc: &SceneSpec, seen: &mut ZpSeen) -> std::result::Result<(), TestCaseError> {
    let b = build_scene(sc);
    for (k, v) in b.volumes.iter().enumerate() {
        let none = StencilTests::default();
        let (zf, _) = draw_one(&b, v, VolumeMethod::ZFail, None, none);
        let (zp, _) = draw_one(&b, v, VolumeMethod::ZpPlus, None, none);
        let (zpass, _) = draw_one(&b, v, VolumeMethod::ZPass, None, none);
        let diff = differing(&b, &zp, &zf);
        prop_assert!(
            diff.is_empty(),
            "volume {k}: zp+ != zfail at {} pixels, first (x, y, zp+, zfail) {:?}",
            diff.len(),
            &diff[..diff.len().min(8)]
        );
        seen.volumes += 1;
        seen.shadowing += u32::from((0..H).any(|y| (0..W).any(|x| zf.nonzero(x, y))));
        if in_front(b.m, &v.pos) {
            let diff = differing(&b, &zpass, &zf);
            prop_assert!(
                diff.is_empty(),
                "volume {k}: legal zpass != zfail at {:?}",
                &diff[..diff.len().min(8)]
            );
            seen.zpass_checked += 1;
        } else {
            seen.cap_matters += u32::from(!differing(&b, &zpass, &zp).is_empty());
        }
    }
    Ok(())
}

/// With conservative bounds, scissor and depth-bounds tests (each and both) leave the
/// stencil bit for bit unchanged and never process more pixels.
fn check_bounds(sc: &SceneSpec) -> std::result::Result<u64, TestCaseError> {
    let b = build_scene(sc);
    let mut saved = 0;
    for (k, v) in b.volumes.iter().enumerate() {
        let bounds = conservative_bounds(b.m, &v.pos);
        let legal_zpass = in_front(b.m, &v.pos);
        for method in [
            VolumeMethod::ZFail,
            VolumeMethod::ZpPlus,
            VolumeMethod::ZPass,
        ] {
            if method == VolumeMethod::ZPass && !legal_zpass {
                continue;
            }
            let (s0, st0) = draw_one(&b, v, method, Some(bounds), StencilTests::default());
            prop_assert_eq!(st0.pixels_touched, s0.touched_pixels());
            for (scissor, depth_bounds) in [(true, false), (false, true), (true, true)] {
                let tests = StencilTests {
                    scissor,
                    depth_bounds,
                };
                let (s1, st1) = draw_one(&b, v, method, Some(bounds), tests);
                for y in 0..H {
                    for x in 0..W {
                        prop_assert_eq!(
                            s1.value(x, y),
                            s0.value(x, y),
                            "volume {} {:?} {:?} bounds {:?} pixel ({}, {})",
                            k,
                            method,
                            tests,
                            bounds,
                            x,
                            y
                        );
                        // Only pixels the untested pass touched can be touched.
                        prop_assert!(!s1.touched(x, y) || s0.touched(x, y));
                    }
                }
                prop_assert!(st1.pixels_processed <= st0.pixels_processed);
                prop_assert_eq!(st1.triangles, st0.triangles);
                prop_assert_eq!(st1.pixels_touched, s1.touched_pixels());
                if scissor && depth_bounds {
                    saved += st0.pixels_processed - st1.pixels_processed;
                }
            }
        }
    }
    Ok(saved)
}

proptest! {
    #![proptest_config(testkit::proptest_config(200))]

    #[test]
    fn zp_plus_equals_zfail_and_legal_zpass(sc in scene_strategy()) {
        check_zp_plus(&sc, &mut ZpSeen::default())?;
    }

    #[test]
    fn conservative_scissor_and_depth_bounds_keep_the_stencil(sc in scene_strategy()) {
        check_bounds(&sc)?;
    }
}

/// The random scenes above are not vacuous: over a fixed sample, the near plane
/// cuts many volumes where the near cap matters, many volumes shadow something,
/// zpass is checked often, and the tests save work.
#[test]
fn random_scenes_exercise_the_near_cap_and_the_bounds() {
    let mut runner = TestRunner::deterministic();
    let strategy = scene_strategy();
    let mut seen = ZpSeen::default();
    let mut saved = 0;
    for _ in 0..150 {
        let sc = strategy.new_tree(&mut runner).unwrap().current();
        check_zp_plus(&sc, &mut seen).unwrap();
        saved += check_bounds(&sc).unwrap();
    }
    assert!(seen.volumes > 200, "{seen:?}");
    assert!(seen.cap_matters > 20, "{seen:?}");
    assert!(seen.shadowing > 100, "{seen:?}");
    assert!(seen.zpass_checked > 20, "{seen:?}");
    assert!(saved > 10_000, "{saved}");
}

#[test]
fn orientation_rule_matches_box_winding() {
    let c = aabb_corners(Vec3::splat(-1.0), Vec3::new(2.0, 1.0, 0.5));
    let mut tris = AABB_TRIANGLES.to_vec();
    orient_homogeneous(&c, &mut tris, DVec3::new(0.5, 0.0, -0.2)).unwrap();
    assert_eq!(tris, AABB_TRIANGLES.to_vec());
}

/// The eye inside a box: zpass alone misses the box everywhere, the near cap puts
/// every pixel's count back, and zp+ equals zfail.
#[test]
fn zp_plus_with_the_eye_inside_a_box() {
    let sc = SceneSpec {
        eye: [0.1, -0.05, 0.0],
        look: [0.1, 0.05],
        shapes: vec![Shape::Box {
            c: [0.2, 0.1, -0.5],
            h: [1.0, 0.8, 1.2],
        }],
        receivers: vec![([0.1, 0.2, -1.0], 1.0), ([0.0, -1.0, 0.1], 0.6)],
    };
    let b = build_scene(&sc);
    let v = &b.volumes[0];
    let none = StencilTests::default();
    let (zf, _) = draw_one(&b, v, VolumeMethod::ZFail, None, none);
    let (zp, stp) = draw_one(&b, v, VolumeMethod::ZpPlus, None, none);
    let (zpass, _) = draw_one(&b, v, VolumeMethod::ZPass, None, none);
    assert!(differing(&b, &zp, &zf).is_empty());
    let (mut inside, mut wrong_zpass) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            inside += u32::from(zf.value(x, y) == 1);
            wrong_zpass += u32::from(zpass.value(x, y) != zf.value(x, y));
        }
    }
    assert!(inside > W * H / 4, "{inside}");
    assert!(wrong_zpass > W * H / 4, "{wrong_zpass}");
    // The near cap updates every non-background pixel it covers: all of them here.
    assert_eq!(stp.pixels_touched, zp.touched_pixels());
    assert!(zp.touched_pixels() >= u64::from(inside));
}

/// An occluder triangle whose extrusion from a point light has a vertex with clip
/// w = 0 on the near plane (direction perpendicular to the view direction), and a
/// volume the near plane cuts: zp+ still equals zfail pixel for pixel.
#[test]
fn zp_plus_with_an_extruded_vertex_at_clip_w_zero_on_the_near_plane() {
    // Camera at the origin looking down −z: clip w = −z_eye exactly.
    let sc_eye = [0.0f32, 0.0, 0.0];
    let light = [0.0f32, 0.0, -1.0];
    let tri = [[0.5f32, 0.0, -1.0], [-0.2, 0.4, -1.3], [-0.2, -0.4, -0.6]];
    let sc = SceneSpec {
        eye: sc_eye,
        look: [0.0, 0.0],
        shapes: vec![Shape::PointLight { tri, light }],
        receivers: vec![([0.0, 0.0, -1.0], 3.0), ([0.3, -1.0, -0.2], 0.8)],
    };
    let b = build_scene(&sc);
    let v = &b.volumes[0];
    // Vertex 3 is p0 − light = (0.5, 0, 0, 0): clip (x, y, 0, 0), on the near plane.
    let c = b.m * v.pos[3];
    assert_eq!((c.z, c.w), (0.0, 0.0), "{c}");
    assert!(c.x != 0.0);
    // The near plane cuts the volume (vertex 5 heads toward the eye and past it).
    assert!(!in_front(b.m, &v.pos));
    let none = StencilTests::default();
    let (zf, _) = draw_one(&b, v, VolumeMethod::ZFail, None, none);
    let (zp, _) = draw_one(&b, v, VolumeMethod::ZpPlus, None, none);
    let (zpass, _) = draw_one(&b, v, VolumeMethod::ZPass, None, none);
    let diff = differing(&b, &zp, &zf);
    assert!(diff.is_empty(), "{:?}", &diff[..diff.len().min(8)]);
    let count = |s: &StencilTarget| {
        (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .filter(|&(x, y)| s.nonzero(x, y))
            .count()
    };
    assert!(count(&zf) > 50, "{}", count(&zf));
    // The cap matters: zpass alone is wrong somewhere.
    assert!(!differing(&b, &zpass, &zf).is_empty());
    // Also with a directional light parallel to the near plane: every extruded
    // point at infinity is on it.
    let sc = SceneSpec {
        shapes: vec![Shape::Directional {
            tri,
            dir: [1.0, 0.3, 0.0],
        }],
        ..sc
    };
    let b = build_scene(&sc);
    let v = &b.volumes[0];
    assert_eq!((b.m * v.pos[3]).w, 0.0);
    let (zf, _) = draw_one(&b, v, VolumeMethod::ZFail, None, none);
    let (zp, _) = draw_one(&b, v, VolumeMethod::ZpPlus, None, none);
    let diff = differing(&b, &zp, &zf);
    assert!(diff.is_empty(), "{:?}", &diff[..diff.len().min(8)]);
    assert!(count(&zf) > 50, "{}", count(&zf));
}

/// Scissor and depth bounds on a fixed scene: conservative bounds keep the stencil
/// and save work; a too-tight scissor or too-tight depth bounds change it; touched
/// pixels are counted per draw and reset by `clear`.
#[test]
fn scissor_and_depth_bounds_save_work_and_too_tight_bounds_show() {
    let occluder = [[0.7f32, 1.0, -2.0], [2.0, 0.9, -2.4], [1.2, 1.2, -3.2]];
    let dir = [-0.2f32, -1.0, -0.3];
    let sc = SceneSpec {
        eye: [0.0, 0.8, 0.5],
        look: [0.05, -0.35],
        shapes: vec![
            Shape::Box {
                c: [0.3, -0.2, -3.0],
                h: [0.6, 0.5, 0.7],
            },
            Shape::Tet([
                [-1.2, 0.4, -2.0],
                [-0.4, 0.9, -3.5],
                [-1.5, -0.8, -3.2],
                [-0.3, -0.6, -2.6],
            ]),
            Shape::Directional { tri: occluder, dir },
        ],
        // A floor at y = −0.2 through the box and the tetrahedron, a far wall.
        receivers: vec![([0.0, -1.0, 0.0], 1.0), ([0.0, 0.0, -1.0], 8.5)],
    };
    let b = build_scene(&sc);
    assert_eq!(b.volumes.len(), 3);
    // The infinite volume: visible surface points inside it are on the occluder or
    // on the floor in its shadow (it only meets the far wall below the floor), so
    // the image of those bounds it.
    let infinite_bounds = {
        let (d, y) = (Vec3::from_array(dir), -0.2f32);
        let mut pts: Vec<Vec4> = occluder.map(|p| Vec3::from_array(p).extend(1.0)).to_vec();
        pts.extend(occluder.map(|p| {
            let p = Vec3::from_array(p);
            (p + d * ((y - p.y) / d.y)).extend(1.0)
        }));
        let (scissor, _, _) = conservative_bounds(b.m, &pts);
        let (_, near, far) = conservative_bounds(b.m, &b.volumes[2].pos);
        (scissor, near, far)
    };
    let both = StencilTests {
        scissor: true,
        depth_bounds: true,
    };
    let (mut processed_all, mut processed_tested) = (0, 0);
    let mut total = StencilTarget::new(W, H, StencilBits::Eight).unwrap();
    let mut total_stats = StencilStats::default();
    for (k, v) in b.volumes.iter().enumerate() {
        assert!(in_front(b.m, &v.pos));
        let bounds = if k == 2 {
            infinite_bounds
        } else {
            conservative_bounds(b.m, &v.pos)
        };
        assert!(bounds.0 != VolumeRange::FULL_SCISSOR && bounds.1 < 1.0);
        for method in [
            VolumeMethod::ZPass,
            VolumeMethod::ZFail,
            VolumeMethod::ZpPlus,
        ] {
            let (s0, st0) = draw_one(&b, v, method, Some(bounds), StencilTests::default());
            let (s1, st1) = draw_one(&b, v, method, Some(bounds), both);
            let shadowed = (0..H)
                .flat_map(|y| (0..W).map(move |x| (x, y)))
                .filter(|&(x, y)| s0.nonzero(x, y))
                .count();
            assert!(shadowed > 20, "{k} {method:?} {shadowed}");
            assert!(differing(&b, &s0, &s1).is_empty(), "{method:?}");
            assert!(
                st1.pixels_processed < st0.pixels_processed,
                "{k} {method:?} {st0:?} {st1:?}"
            );
            processed_all += st0.pixels_processed;
            processed_tested += st1.pixels_processed;
            if k == 2 {
                // The scissor alone saves work on the infinite volume.
                let scissor = StencilTests {
                    scissor: true,
                    depth_bounds: false,
                };
                let (s4, st4) = draw_one(&b, v, method, Some(bounds), scissor);
                assert!(differing(&b, &s0, &s4).is_empty(), "{method:?}");
                assert!(
                    st4.pixels_processed * 4 < st0.pixels_processed * 3,
                    "{method:?} {st0:?} {st4:?}"
                );
            }
            assert_eq!(
                st1.stencil_updates,
                st1.stencil_updates.min(st0.stencil_updates)
            );
            // Too tight: a scissor ending in the middle of the shadowed pixels, or
            // depth bounds that end just before the farthest shadowed pixel.
            let shadow: Vec<(u32, u32)> = (0..H)
                .flat_map(|y| (0..W).map(move |x| (x, y)))
                .filter(|&(x, y)| s0.nonzero(x, y))
                .collect();
            let sx0 = shadow.iter().map(|p| p.0).min().unwrap();
            let sx1 = shadow.iter().map(|p| p.0).max().unwrap();
            let mid = (sx0 + sx1).div_ceil(2);
            let [x0, y0, _, y1] = bounds.0;
            let tight = ([x0, y0, mid, y1], bounds.1, bounds.2);
            let (s2, _) = draw_one(&b, v, method, Some(tight), both);
            assert!(
                !differing(&b, &s0, &s2).is_empty(),
                "{k} {method:?} tight scissor"
            );
            for y in 0..H {
                for x in mid..W {
                    assert!(!s2.touched(x, y));
                }
            }
            let farthest = shadow
                .iter()
                .map(|&(x, y)| b.eye.depth_at(x, y).unwrap())
                .fold(f32::INFINITY, f32::min);
            let squeezed = (bounds.0, bounds.1, farthest.next_up());
            let (s3, _) = draw_one(&b, v, method, Some(squeezed), both);
            assert!(
                !differing(&b, &s0, &s3).is_empty(),
                "{k} {method:?} tight depth"
            );
        }
        let (buf, mut range) = volume(&v.pos, &v.tris, VolumeMethod::ZFail);
        (range.scissor, range.depth_near, range.depth_far) = bounds;
        total
            .draw_volume(&b.eye, b.m, &buf, &range, both, &mut total_stats)
            .unwrap();
    }
    assert!(
        processed_tested * 3 < processed_all * 2,
        "{processed_tested} {processed_all}"
    );
    // Touched pixels: distinct pixels updated since the clear, summed over draws.
    let touched = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| total.touched(x, y))
        .count() as u64;
    assert_eq!(total.touched_pixels(), touched);
    assert_eq!(total_stats.pixels_touched, touched);
    assert!(touched > 40 && touched <= total_stats.stencil_updates);
    assert!((0..H).all(|y| (0..W).all(|x| total.touched(x, y) || !total.nonzero(x, y))));
    total.clear();
    assert_eq!(total.touched_pixels(), 0);
    assert!((0..H).all(|y| (0..W).all(|x| !total.touched(x, y))));
}

/// All `volumes` in one buffer, one range each with `method`, with conservative
/// scissor and depth bounds.
fn all_volumes(b: &Built, method: VolumeMethod) -> VolumeBuffer {
    let mut buf = VolumeBuffer::new();
    for (k, v) in b.volumes.iter().enumerate() {
        let (one, mut range) = volume(&v.pos, &v.tris, method);
        let (scissor, near, far) = conservative_bounds(b.m, &v.pos);
        range.object = k as u64;
        range.first_vertex = buf.positions.len() as u32;
        range.first_index = buf.indices.len() as u32;
        range.scissor = scissor;
        range.depth_near = near;
        range.depth_far = far;
        buf.indices
            .extend(one.indices.iter().map(|i| i + range.first_vertex));
        buf.positions.extend(one.positions);
        buf.ranges.push(range);
    }
    buf
}

/// What the hierarchical checks saw, to show they are not vacuous.
#[derive(Default, Debug)]
struct HSeen {
    draws: u32,
    boundary: u64,
    shadow: u64,
    lit: u64,
    fs_differences: u64,
    saved: u64,
}

/// The hierarchical stencil against brute force on the same depth buffer, volumes
/// and tests ([`testkit::hierarchical_matches_brute_force`], tiles 4, 8 and 16),
/// for every volume method and with scissor and depth bounds off and on: wide
/// and 8-bit counters without the FS bit give the same value at every written
/// pixel; with the FS bit the mask differs only where some volume's own count
/// is negative (or, 8-bit, the wide count wraps).
fn check_hierarchical(sc: &SceneSpec, seen: &mut HSeen) -> std::result::Result<(), TestCaseError> {
    let b = build_scene(sc);
    if b.volumes.is_empty() {
        return Ok(());
    }
    // zpass is checked even where it is illegal: the hierarchy must reproduce the
    // brute-force count, right or wrong.
    for method in [
        VolumeMethod::ZFail,
        VolumeMethod::ZpPlus,
        VolumeMethod::ZPass,
    ] {
        let buf = all_volumes(&b, method);
        let ranges: Vec<(Mat4, &VolumeRange)> = buf.ranges.iter().map(|r| (b.m, r)).collect();
        for tests in [
            StencilTests::default(),
            StencilTests {
                scissor: true,
                depth_bounds: true,
            },
        ] {
            let tiles = [TileSize::T4, TileSize::T8, TileSize::T16];
            let c = testkit::hierarchical_matches_brute_force(&b.eye, &ranges, &buf, tests, &tiles)
                .map_err(|e| TestCaseError::fail(format!("{method:?} {tests:?}: {e}")))?;
            seen.draws += c.draws;
            seen.boundary += c.boundary_tiles;
            seen.shadow += c.shadow_tiles;
            seen.lit += c.lit_tiles;
            seen.saved += c.saved_fragments;
            seen.fs_differences += c.fs_wide_differences;
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(testkit::proptest_config(100))]

    #[test]
    fn hierarchical_equals_brute_force(sc in scene_strategy()) {
        check_hierarchical(&sc, &mut HSeen::default())?;
    }
}

/// The hierarchical checks see boundary, shadow and lit tiles and save per-pixel work.
#[test]
fn hierarchical_checks_are_not_vacuous() {
    let mut runner = TestRunner::deterministic();
    let strategy = scene_strategy();
    let mut seen = HSeen::default();
    for _ in 0..60 {
        let sc = strategy.new_tree(&mut runner).unwrap().current();
        check_hierarchical(&sc, &mut seen).unwrap();
    }
    eprintln!("{seen:?}");
    assert!(
        seen.boundary > 1000 && seen.shadow > 100 && seen.lit > 100,
        "{seen:?}"
    );
    assert!(seen.saved > 10_000, "{seen:?}");
}

/// A range's band applies whatever the tests: drawn in a band of rows, a
/// volume counts as the whole volume inside it and nothing outside, with
/// the scissor and depth-bounds tests off or on; two bands that tile the
/// image count as the whole volume, and one band processes fewer fragments
/// and scans fewer tiles (`StencilStats::tiles_scanned`).
#[test]
fn bands_cut_the_pixels_whatever_the_tests() {
    let sc = SceneSpec {
        eye: [0.0, 0.8, 0.5],
        look: [0.05, -0.35],
        shapes: vec![Shape::Box {
            c: [0.3, -0.2, -3.0],
            h: [0.6, 0.5, 0.7],
        }],
        receivers: vec![([0.0, -1.0, 0.0], 1.0), ([0.0, 0.0, -1.0], 8.5)],
    };
    let b = build_scene(&sc);
    let v = &b.volumes[0];
    let mut shadowed = 0;
    for tests in [
        StencilTests::default(),
        StencilTests {
            scissor: true,
            depth_bounds: true,
        },
    ] {
        for method in [VolumeMethod::ZPass, VolumeMethod::ZFail] {
            let (buf, range) = volume(&v.pos, &v.tris, method);
            let draw = |bands: &[[u32; 4]]| {
                let mut s = StencilTarget::new(W, H, StencilBits::Wide).unwrap();
                let mut st = StencilStats::default();
                for &band in bands {
                    let r = VolumeRange {
                        band,
                        ..range.clone()
                    };
                    s.draw_volume(&b.eye, b.m, &buf, &r, tests, &mut st)
                        .unwrap();
                }
                (s, (st.pixels_processed, st.tiles_scanned))
            };
            let (whole, whole_px) = draw(&[VolumeRange::FULL_SCISSOR]);
            // Split at the middle of the shadowed rows.
            let rows: Vec<u32> = (0..H)
                .filter(|&y| (0..W).any(|x| whole.nonzero(x, y)))
                .collect();
            let split = rows[rows.len() / 2];
            let (top, top_px) = draw(&[[0, 0, u32::MAX, split]]);
            let (tiled, tiled_px) = draw(&[[0, 0, u32::MAX, split], [0, split, W, H]]);
            for y in 0..H {
                for x in 0..W {
                    let want = if y < split { whole.value(x, y) } else { 0 };
                    assert_eq!(top.value(x, y), want, "{method:?} ({x}, {y})");
                    assert_eq!(tiled.value(x, y), whole.value(x, y));
                    shadowed += usize::from(whole.nonzero(x, y) && y >= split);
                }
            }
            // The fill scans tiles and fragments only inside the band.
            // (A band edge inside a tile row scans that row's tiles twice.)
            assert_eq!(tiled_px.0, whole_px.0);
            assert!(tiled_px.1 >= whole_px.1);
            assert!(top_px.0 < whole_px.0 && top_px.1 < whole_px.1);
        }
    }
    // The volume's shadow reaches below the split: the cut is not vacuous.
    assert!(shadowed > 0);
}
