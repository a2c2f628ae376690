//! Stencil pass: zpass / zfail counting against brute-force references, 8-bit
//! wrapping, background pixels, infinite volumes.

use glam::{DMat4, DVec3, DVec4, Mat4, Vec3, Vec4};
use raster::*;

/// Reversed-Z infinite perspective as in the scene crate: clip = (x·f/a, y·f, near, −z).
fn perspective(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
    let f = 1.0 / (0.5 * fov_y).tan();
    Mat4::from_cols(
        Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        Vec4::new(0.0, f, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 0.0, -1.0),
        Vec4::new(0.0, 0.0, near, 0.0),
    )
}

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
    s.draw_volume(eye, m, &buf, &range, &mut st).unwrap();
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
    assert_eq!(st8, stw);
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
        small.draw_volume(&eye, m, &buf, &range, &mut st),
        Err(Error::SizeMismatch { .. })
    ));
    let mut s = StencilTarget::new(W, H, StencilBits::Wide).unwrap();
    assert_eq!(s.bits(), StencilBits::Wide);
    range.index_count += 3;
    assert!(matches!(
        s.draw_volume(&eye, m, &buf, &range, &mut st),
        Err(Error::IndexOutOfRange { .. })
    ));
    let mut bad = buf.clone();
    bad.indices[4] = 99;
    range.index_count -= 3;
    assert!(matches!(
        s.draw_volume(&eye, m, &bad, &range, &mut st),
        Err(Error::IndexOutOfRange {
            triangle: 1,
            index: 99,
            ..
        })
    ));
    assert_eq!(st, StencilStats::default());
    s.draw_volume(&eye, m, &buf, &range, &mut st).unwrap();
    assert!(st.stencil_updates == 0 && st.pixels_processed > 0 && st.triangles == 2);
    s.clear();
    assert!((0..H).all(|y| (0..W).all(|x| !s.nonzero(x, y))));
}
