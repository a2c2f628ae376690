//! Integration tests of shadowgen: silhouette laws (proptest), volume winding,
//! extrusion and closedness, method choice through `build_volumes`, errors.

use glam::{DMat4, DQuat, DVec3, DVec4, Vec3};
use proptest::prelude::*;
use raster::{VolumeBuffer, VolumeMethod, VolumeRange};
use scene::{Camera, Light, Mesh, ObjectId, Scene, SceneGraph, Transform};
use shadowgen::{
    build_volumes, silhouette, BuildOptions, Error, MethodChoice, Silhouette, SilhouetteCache,
};
use std::collections::HashMap;
use testkit::volume_checks::{
    blockers, boundary, buffer_crossings, crossing, det4, range_crossings, world,
};

// ---------------------------------------------------------------- meshes

fn unit_box() -> Mesh {
    scene::procedural::analytic::box_mesh("unit box", Vec3::ZERO, Vec3::ONE).unwrap()
}

/// A closed, consistently wound, star-shaped (generally non-convex) sphere.
fn star_sphere(radii: &[f32], lat: usize, lon: usize) -> Mesh {
    let mut pos = vec![Vec3::Y * radii[0]];
    let mut k = 1;
    for i in 1..lat {
        let th = std::f32::consts::PI * i as f32 / lat as f32;
        for j in 0..lon {
            let ph = std::f32::consts::TAU * j as f32 / lon as f32;
            let d = Vec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin());
            pos.push(d * radii[k % radii.len()]);
            k += 1;
        }
    }
    pos.push(Vec3::NEG_Y * radii[k % radii.len()]);
    let bottom = pos.len() as u32 - 1;
    let ring = |i: usize, j: usize| (1 + (i - 1) * lon + j % lon) as u32;
    let mut tris = Vec::new();
    for j in 0..lon {
        tris.push([0, ring(1, j), ring(1, j + 1)]);
        tris.push([bottom, ring(lat - 1, j + 1), ring(lat - 1, j)]);
    }
    for i in 1..lat - 1 {
        for j in 0..lon {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            tris.push([a, c, d]);
            tris.push([a, d, b]);
        }
    }
    Mesh::new("star", &pos, &tris).unwrap()
}

fn scene_with(mesh: Mesh, world_from_local: DMat4) -> Scene {
    let mut g = SceneGraph::new();
    let m = g.add_mesh(mesh);
    g.add_instance("o", m, Transform::Matrix(world_from_local));
    Scene::new(g).unwrap()
}

fn point(p: DVec3) -> Light {
    Light::Point {
        position: p,
        range: None,
    }
}

fn camera() -> Camera {
    Camera::look_at(
        DVec3::new(0.0, 2.0, 20.0),
        DVec3::ZERO,
        DVec3::Y,
        1.0,
        1.0,
        0.1,
    )
    .unwrap()
}

/// Per vertex, out-degree minus in-degree counted with multiplicity.
fn imbalance(s: &Silhouette) -> HashMap<u32, i64> {
    let mut m = HashMap::new();
    for e in &s.edges {
        *m.entry(e.from).or_insert(0) += e.multiplicity as i64;
        *m.entry(e.to).or_insert(0) -= e.multiplicity as i64;
    }
    m.retain(|_, v| *v != 0);
    m
}

// ---------------------------------------------------------------- strategies

fn transform() -> impl Strategy<Value = DMat4> {
    (
        prop::array::uniform4(-1.0f64..1.0),
        prop::array::uniform3(0.3f64..3.0),
        prop::array::uniform3(any::<bool>()),
        prop::array::uniform3(-10.0f64..10.0),
    )
        .prop_filter_map("zero quaternion", |(q, s, neg, t)| {
            let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
            (q.length() > 0.1).then(|| {
                let s = DVec3::new(
                    if neg[0] { -s[0] } else { s[0] },
                    if neg[1] { -s[1] } else { s[1] },
                    if neg[2] { -s[2] } else { s[2] },
                );
                DMat4::from_scale_rotation_translation(s, q.normalize(), DVec3::from(t))
            })
        })
}

fn light() -> impl Strategy<Value = Light> {
    prop_oneof![
        prop::array::uniform3(-40.0f64..40.0).prop_map(|p| point(DVec3::from(p))),
        prop::array::uniform3(-1.0f64..1.0)
            .prop_filter("zero direction", |d| DVec3::from(*d).length() > 0.05)
            .prop_map(|d| Light::Directional {
                direction: DVec3::from(d)
            }),
    ]
}

// ---------------------------------------------------------------- silhouettes

proptest! {
    #![proptest_config(testkit::proptest_config(96))]

    /// Closed consistently wound meshes: silhouette edges have multiplicity 1
    /// and form closed loops (equal in- and out-degree at every vertex).
    #[test]
    fn closed_mesh_silhouettes_form_loops(
        radii in prop::collection::vec(0.5f32..1.5, 7..40),
        lat in 3usize..8,
        lon in 3usize..9,
        w in transform(),
        l in light(),
        use_box in any::<bool>(),
        two_sided in any::<bool>(),
    ) {
        let mesh = if use_box { unit_box() } else { star_sphere(&radii, lat, lon) };
        let s = scene_with(mesh, w);
        let mut out = Silhouette::default();
        silhouette(&s, ObjectId::from_slot(0), &l, two_sided, &mut out);
        prop_assert!(imbalance(&out).is_empty());
        if !two_sided {
            prop_assert!(out.edges.iter().all(|e| e.multiplicity == 1));
        } else {
            // Two-sided on a closed mesh: front and flipped back faces cancel
            // along each edge or double up, never more than 2.
            prop_assert!(out.edges.iter().all(|e| e.multiplicity <= 2));
        }
    }

    /// Any triangle soup (open, non-manifold, mixed winding): the counters
    /// balance at every vertex.
    #[test]
    fn any_mesh_counters_balance(
        pts in prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), 4..10),
        tris in prop::collection::vec(prop::array::uniform3(0u32..10), 1..30),
        w in transform(),
        l in light(),
        two_sided in any::<bool>(),
    ) {
        let n = pts.len() as u32;
        let pos: Vec<Vec3> = pts.into_iter().map(Vec3::from).collect();
        let tris: Vec<[u32; 3]> = tris.into_iter().map(|t| t.map(|i| i % n)).collect();
        let Ok(mesh) = Mesh::new("soup", &pos, &tris) else { return Ok(()); };
        if mesh.triangles().is_empty() { return Ok(()); }
        let s = scene_with(mesh, w);
        let mut out = Silhouette::default();
        silhouette(&s, ObjectId::from_slot(0), &l, two_sided, &mut out);
        prop_assert!(imbalance(&out).is_empty(), "{:?}", out.edges);
    }

    /// Every volume triangle of a box faces outward relative to the box centre
    /// (in world space, mirrored transforms included); zfail volumes are closed
    /// surfaces; extruded vertices have w = 0 exactly.
    #[test]
    fn box_volumes_are_outward_and_closed(w in transform(), l in light(), method in 0usize..3) {
        let s = scene_with(unit_box(), w);
        let centre = w.transform_point3(DVec3::splat(0.5));
        if let Some(p) = l.position() {
            // Keep the light clearly outside the box.
            let local = w.inverse().transform_point3(p);
            prop_assume!(local.cmplt(DVec3::splat(-0.2)).any() || local.cmpgt(DVec3::splat(1.2)).any());
        }
        let choice = [MethodChoice::ZPass, MethodChoice::ZFail, MethodChoice::ZpPlus][method];
        let buf = build(&s, &l, choice);
        check_outward(&buf, centre);
        check_extrusion(&s, &buf, &l);
        if choice != MethodChoice::ZPass {
            prop_assert!(boundary(&buf, &buf.ranges[0]).is_empty());
        }
    }
}

fn build(s: &Scene, l: &Light, choice: MethodChoice) -> VolumeBuffer {
    let mut buf = VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    let ids: Vec<ObjectId> = (0..s.objects().len() as u32)
        .map(ObjectId::from_slot)
        .collect();
    let opts = BuildOptions {
        method: choice,
        two_sided: false,
        viewport: None,
        ..Default::default()
    };
    let st = build_volumes(&mut buf, s, &camera(), l, &ids, opts, &mut cache).unwrap();
    buf.check().unwrap();
    assert_eq!(st.volume_triangles, buf.triangle_count());
    buf
}

/// Object 0's unclamped zfail volume for `l`.
fn zfail_volumes(s: &Scene, l: &Light, two_sided: bool) -> VolumeBuffer {
    let mut buf = VolumeBuffer::new();
    let opts = BuildOptions {
        method: MethodChoice::ZFail,
        two_sided,
        viewport: None,
        ..Default::default()
    };
    let casters = [ObjectId::from_slot(0)];
    build_volumes(
        &mut buf,
        s,
        &camera(),
        l,
        &casters,
        opts,
        &mut SilhouetteCache::new(),
    )
    .unwrap();
    buf
}

/// `det[A, B, C, X] > 0` ⇔ X lies behind the triangle (A, B, C) — for w = 0
/// vertices too, by multilinearity (the limit of far finite points).
fn check_outward(buf: &VolumeBuffer, interior: DVec3) {
    // Sanity of the sign convention on a finite triangle with normal +z.
    let t = [
        DVec4::new(0.0, 0.0, 0.0, 1.0),
        DVec4::new(1.0, 0.0, 0.0, 1.0),
        DVec4::new(0.0, 1.0, 0.0, 1.0),
    ];
    assert!(det4([t[0], t[1], t[2], DVec4::new(0.1, 0.1, -1.0, 1.0)]) > 0.0);
    let x = interior.extend(1.0);
    for r in &buf.ranges {
        for t in r.indices().step_by(3) {
            let [a, b, c] = buf.triangle(t / 3).map(|p| world(r, p));
            let d = det4([a, b, c, x]);
            let scale = a.length() * b.length() * c.length() * x.length();
            assert!(d > -1e-9 * scale, "triangle {} faces inward: {d}", t / 3);
        }
    }
}

fn check_extrusion(s: &Scene, buf: &VolumeBuffer, l: &Light) {
    for r in &buf.ranges {
        let verts = r.first_vertex as usize..(r.first_vertex + r.vertex_count) as usize;
        let mesh = s.object_mesh(ObjectId::from_bits(r.object));
        let mut infinite = Vec::new();
        for p in &buf.positions[verts] {
            if p[3] == 1.0 {
                let v = Vec3::new(p[0], p[1], p[2]);
                assert!(
                    mesh.positions().contains(&v),
                    "finite vertex not a mesh vertex"
                );
            } else {
                assert_eq!(p[3].to_bits(), 0.0f32.to_bits(), "w is exactly +0");
                infinite.push(world(r, *p).truncate());
            }
        }
        if let Light::Directional { direction } = *l {
            assert!(infinite.len() <= 1);
            for d in infinite {
                assert!(d.normalize().dot(direction.normalize()) > 1.0 - 1e-6);
            }
        }
    }
}

/// Directed edges of a range's triangles (by position value) that have no
/// reverse partner: empty for a closed surface.

// ---------------------------------------------------------------- volumes

#[test]
fn unit_box_under_a_point_light() {
    let s = scene_with(unit_box(), DMat4::IDENTITY);
    // Corner-on: three faces lit, a hexagonal silhouette.
    let l = point(DVec3::new(5.0, 6.0, 7.0));
    let mut sil = Silhouette::default();
    silhouette(&s, ObjectId::from_slot(0), &l, false, &mut sil);
    let k = sil.edge_count();
    assert_eq!(k, 6);
    assert_eq!(sil.caps.len(), 6);
    let zpass = build(&s, &l, MethodChoice::ZPass);
    assert_eq!(
        zpass.triangle_count(),
        2 * k,
        "one quad (2 triangles) per silhouette edge"
    );
    assert!(zpass.ranges[0].light_cap.is_empty() && zpass.ranges[0].dark_cap.is_empty());
    let zfail = build(&s, &l, MethodChoice::ZFail);
    let r = &zfail.ranges[0];
    assert_eq!(r.method, VolumeMethod::ZFail);
    assert_eq!(r.light_cap.len(), 3 * 6);
    assert_eq!(r.dark_cap.len(), 3 * 6);
    assert_eq!(zfail.triangle_count(), 2 * k + 12);
    // 6 silhouette vertices + 1 cap-only corner, each finite and extruded.
    assert_eq!(r.vertex_count, 14);
    assert!(boundary(&zfail, r).is_empty());
    check_outward(&zfail, DVec3::splat(0.5));
    // Face-on: one face lit, four silhouette edges.
    let l = point(DVec3::new(0.5, 0.5, 9.0));
    silhouette(&s, ObjectId::from_slot(0), &l, false, &mut sil);
    assert_eq!(sil.edge_count(), 4);
    assert_eq!(build(&s, &l, MethodChoice::ZPass).triangle_count(), 8);
}

#[test]
fn directional_sides_meet_in_one_point_at_infinity() {
    let s = scene_with(
        unit_box(),
        DMat4::from_translation(DVec3::new(3.0, 1.0, -2.0)),
    );
    let sun = Light::Directional {
        direction: DVec3::new(-0.3, -1.0, -0.2),
    };
    let buf = build(&s, &sun, MethodChoice::ZFail);
    let r = &buf.ranges[0];
    assert!(r.dark_cap.is_empty());
    let infinite: Vec<usize> = (r.first_vertex..r.first_vertex + r.vertex_count)
        .map(|i| i as usize)
        .filter(|&i| buf.positions[i][3] == 0.0)
        .collect();
    assert_eq!(infinite.len(), 1);
    let sides = r.light_cap.end as usize..r.indices().end;
    assert_eq!(sides.len() / 3, 6, "one triangle per silhouette edge");
    for t in sides.step_by(3) {
        assert_eq!(buf.indices[t + 2] as usize, infinite[0]);
    }
    assert!(boundary(&buf, r).is_empty(), "light cap + fan is closed");
    check_outward(&buf, DVec3::new(3.5, 1.5, -1.5));
}

#[test]
fn mirrored_box_keeps_outward_winding() {
    for scale in [
        DVec3::new(-1.0, 1.0, 1.0),
        DVec3::new(-2.0, -1.0, 1.5),
        DVec3::new(-1.0, -1.0, -1.0),
    ] {
        let w = DMat4::from_scale(scale);
        let s = scene_with(unit_box(), w);
        let centre = w.transform_point3(DVec3::splat(0.5));
        for l in [
            point(DVec3::new(5.0, 6.0, 7.0)),
            Light::Directional {
                direction: DVec3::new(0.2, -1.0, 0.3),
            },
        ] {
            let buf = build(&s, &l, MethodChoice::ZFail);
            check_outward(&buf, centre);
            assert!(boundary(&buf, &buf.ranges[0]).is_empty());
        }
    }
}

#[test]
fn open_and_non_manifold_volumes_are_closed() {
    // Open quad plus a fin: the zfail volume is still a closed surface.
    let p = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::Y,
        Vec3::new(0.5, 0.0, 1.0),
        Vec3::new(0.5, 0.0, -1.0),
    ];
    let m = Mesh::new("fin", &p, &[[0, 1, 2], [0, 2, 3], [0, 1, 4], [1, 0, 5]]).unwrap();
    let s = scene_with(m, DMat4::IDENTITY);
    for l in [
        point(DVec3::new(0.3, -2.0, 5.0)),
        point(DVec3::new(0.3, 2.0, -5.0)),
    ] {
        for two_sided in [false, true] {
            let buf = zfail_volumes(&s, &l, two_sided);
            assert!(boundary(&buf, &buf.ranges[0]).is_empty());
        }
    }
}

// ---------------------------------------------------------------- build_volumes

#[test]
fn auto_chooses_zfail_when_the_camera_is_in_shadow() {
    let mut g = SceneGraph::new();
    let m = g.add_mesh(unit_box());
    // Between the eye (0, 2, 20) and the light above it.
    g.add_instance(
        "over",
        m,
        Transform::translation(DVec3::new(-0.5, 6.0, 19.5)),
    );
    // Far off to the side.
    g.add_instance(
        "far",
        m,
        Transform::translation(DVec3::new(-30.0, 0.0, -30.0)),
    );
    let s = Scene::new(g).unwrap();
    let l = point(DVec3::new(0.0, 12.0, 20.0));
    let mut buf = VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    let ids = [ObjectId::from_slot(0), ObjectId::from_slot(1)];
    let st = build_volumes(
        &mut buf,
        &s,
        &camera(),
        &l,
        &ids,
        BuildOptions::default(),
        &mut cache,
    )
    .unwrap();
    assert_eq!(buf.ranges[0].method, VolumeMethod::ZFail);
    assert_eq!(buf.ranges[1].method, VolumeMethod::ZPass);
    assert_eq!((st.zpass, st.zfail, st.zpplus), (1, 1, 0));
    assert_eq!(st.cache_misses, 2);
    assert_eq!(st.silhouette_edges, 4 + 6);
    buf.check().unwrap();
    // Second frame: everything from the cache, same buffer.
    let before = buf.clone();
    let st = build_volumes(
        &mut buf,
        &s,
        &camera(),
        &l,
        &ids,
        BuildOptions::default(),
        &mut cache,
    )
    .unwrap();
    assert_eq!((st.cache_hits, st.cache_misses), (2, 0));
    assert_eq!(before, buf);
    // Forced zp+ names both caps.
    let opts = BuildOptions {
        method: MethodChoice::ZpPlus,
        two_sided: false,
        viewport: None,
        ..Default::default()
    };
    build_volumes(&mut buf, &s, &camera(), &l, &ids, opts, &mut cache).unwrap();
    for r in &buf.ranges {
        assert_eq!(r.method, VolumeMethod::ZpPlus);
        assert!(!r.light_cap.is_empty() && !r.dark_cap.is_empty());
        assert_eq!((r.depth_near, r.depth_far), (1.0, 0.0));
        assert_eq!(r.scissor, VolumeRange::FULL_SCISSOR);
    }
}

#[test]
fn bad_lights_and_ids_are_errors() {
    let s = scene_with(unit_box(), DMat4::IDENTITY);
    let mut buf = VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    let bad = [
        point(DVec3::new(f64::NAN, 0.0, 0.0)),
        Light::Directional {
            direction: DVec3::ZERO,
        },
        Light::Directional {
            direction: DVec3::new(0.0, f64::NAN, 0.0),
        },
        Light::Spot {
            position: DVec3::Y * 5.0,
            direction: DVec3::NEG_Y,
            apex_angle: std::f64::consts::PI,
            range: None,
        },
    ];
    for l in bad {
        let e = build_volumes(
            &mut buf,
            &s,
            &camera(),
            &l,
            &[ObjectId::from_slot(0)],
            BuildOptions::default(),
            &mut cache,
        );
        assert!(matches!(e, Err(Error::Light(_))), "{l:?}");
    }
    let e = build_volumes(
        &mut buf,
        &s,
        &camera(),
        &point(DVec3::Y * 5.0),
        &[ObjectId::from_slot(3)],
        BuildOptions::default(),
        &mut cache,
    );
    assert!(matches!(e, Err(Error::UnknownObject { id: 3, .. })));
}

#[test]
fn light_inside_a_closed_object_casts_nothing_one_sided() {
    let s = scene_with(unit_box(), DMat4::IDENTITY);
    let l = point(DVec3::splat(0.5));
    let buf = build(&s, &l, MethodChoice::ZFail);
    assert_eq!(buf.triangle_count(), 0);
    let mut buf = VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    let opts = BuildOptions {
        method: MethodChoice::ZFail,
        two_sided: true,
        viewport: None,
        ..Default::default()
    };
    build_volumes(
        &mut buf,
        &s,
        &camera(),
        &l,
        &[ObjectId::from_slot(0)],
        opts,
        &mut cache,
    )
    .unwrap();
    // Two-sided: every face casts (flipped), caps cover the whole box, no sides.
    let r = &buf.ranges[0];
    assert_eq!(r.light_cap.len() / 3, 12);
    assert_eq!(buf.triangle_count(), 24);
    assert!(boundary(&buf, r).is_empty());
}

// ---------------------------------------------------------------- volumes = reference

proptest! {
    #![proptest_config(testkit::proptest_config(512))]

    /// The closed volume's signed crossings along a segment e → q equal the
    /// change in the number of casting triangles between each end and the
    /// light: the volume is exactly the union of the casting triangles' shadows
    /// (the reference's definition), for any mesh, transform and light.
    #[test]
    fn volume_crossings_match_the_reference(
        pts in prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), 4..9),
        tris in prop::collection::vec(prop::array::uniform3(0u32..9), 1..14),
        radii in prop::collection::vec(0.5f32..1.5, 7..20),
        soup in any::<bool>(),
        w in transform(),
        l in light(),
        scale_exp in -3i32..=3,
        offset in prop_oneof![Just(0.0), Just(1e5), Just(1e6)],
        e in prop::array::uniform3(-2.0f64..2.0),
        q in prop::array::uniform3(-2.0f64..2.0),
        te in 0.3f64..3.0,
        tq in 0.3f64..3.0,
        two_sided in any::<bool>(),
    ) {
        let mesh = if soup {
            let n = pts.len() as u32;
            let pos: Vec<Vec3> = pts.into_iter().map(Vec3::from).collect();
            let tris: Vec<[u32; 3]> = tris.into_iter().map(|t| t.map(|i| i % n)).collect();
            match Mesh::new("soup", &pos, &tris) {
                Ok(m) if !m.triangles().is_empty() => m,
                _ => return Ok(()),
            }
        } else {
            star_sphere(&radii, 4, 5)
        };
        // The whole scene (caster and light) scaled by 10^k and offset in x and z.
        let k = 10f64.powi(scale_exp);
        let outer = DMat4::from_translation(DVec3::new(offset, 0.0, offset)) * DMat4::from_scale(DVec3::splat(k));
        let w = outer * w;
        let l = match l {
            Light::Directional { .. } => l,
            _ => point(outer.transform_point3(l.position().unwrap())),
        };
        let s = scene_with(mesh, w);
        // Points near the caster, slid along the light's rays: often in shadow.
        let slide = |p: [f64; 3], t: f64| {
            let p = w.transform_point3(DVec3::from(p));
            match l {
                Light::Directional { direction } => p + direction * (3.0 * t * k),
                _ => {
                    let lp = l.position().unwrap();
                    lp + (p - lp) * t
                }
            }
        };
        let (e, q) = (slide(e, te), slide(q, tq));
        let mut buf = VolumeBuffer::new();
        let mut cache = SilhouetteCache::new();
        let opts = BuildOptions { method: MethodChoice::ZFail, two_sided, viewport: None, ..Default::default() };
        build_volumes(&mut buf, &s, &camera(), &l, &[ObjectId::from_slot(0)], opts, &mut cache).unwrap();
        let r = &buf.ranges[0];
        let mut count = 0;
        for t in r.indices().step_by(3) {
            let tri = buf.triangle(t / 3).map(|p| world(r, p));
            let Some(c) = crossing(e.extend(1.0), q.extend(1.0), tri) else { return Ok(()); };
            count += c;
        }
        let (Some(bq), Some(be)) = (blockers(&s, ObjectId::from_slot(0), q, &l, two_sided), blockers(&s, ObjectId::from_slot(0), e, &l, two_sided)) else {
            return Ok(());
        };
        prop_assert_eq!(count, bq - be);
    }
}

proptest! {
    #![proptest_config(testkit::proptest_config(512))]

    /// zpass is only chosen when no point of the near rectangle lies in the
    /// caster's shadow (sampled on a grid over the rectangle, both sides of
    /// every triangle casting).
    #[test]
    fn zpass_only_when_the_near_rectangle_is_lit(
        w in transform(),
        l in light(),
        eye in prop::array::uniform3(-4.0f64..4.0),
        target in prop::array::uniform3(-4.0f64..4.0),
        near in 0.05f64..2.0,
        fov in 0.3f64..2.5,
    ) {
        let s = scene_with(unit_box(), w);
        let centre = w.transform_point3(DVec3::splat(0.5));
        let eye = centre + DVec3::from(eye);
        let Ok(cam) = Camera::look_at(eye, centre + DVec3::from(target), DVec3::Y, fov, 1.3, near) else {
            return Ok(());
        };
        let bounds = s.object(ObjectId::from_slot(0)).world_bounds;
        if !shadowgen::zpass_is_safe(&cam, &l, &bounds) {
            return Ok(());
        }
        let c = cam.frustum().near_corners;
        for i in 0..=8 {
            for j in 0..=8 {
                let (u, v) = (i as f64 / 8.0, j as f64 / 8.0);
                let r = c[0] + (c[1] - c[0]) * u + (c[3] - c[0]) * v;
                if let Some(n) = blockers(&s, ObjectId::from_slot(0), r, &l, true) {
                    prop_assert_eq!(n, 0, "near point {:?} is in shadow", r);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(testkit::proptest_config(2048))]

    /// Every point in a caster's shadow, inside the scene bounds and in front
    /// of the near plane, projects into the volume's scissor rectangle and
    /// depth bounds — for point lights with or without range, directional
    /// lights, and spot lights (often narrow cones aimed near the caster, so
    /// that some shadowed points lie outside the cone: those are unlit and
    /// need not be inside).
    #[test]
    fn shadowed_points_lie_within_scissor_and_depth_bounds(
        w in transform(),
        l in light(),
        eye in prop::array::uniform3(-12.0f64..12.0),
        near in 0.05f64..2.0,
        range in prop::option::of(1.0f64..30.0),
        spot in prop::option::weighted(0.6, (
            prop::array::uniform3(-10.0f64..10.0),
            prop::array::uniform3(-0.4f64..0.4),
            prop_oneof![0.02f64..0.5, 0.5f64..3.0],
        )),
        pts in prop::collection::vec((prop::array::uniform3(-0.2f64..1.2), 0.3f64..8.0), 16),
    ) {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(unit_box());
        g.add_instance("caster", m, Transform::Matrix(w));
        let ground = DMat4::from_scale_rotation_translation(
            DVec3::new(30.0, 1.0, 30.0), DQuat::IDENTITY, DVec3::new(-15.0, -12.0, -15.0));
        g.add_instance("ground", m, Transform::Matrix(ground));
        let s = Scene::new(g).unwrap();
        let centre = w.transform_point3(DVec3::splat(0.5));
        let l = match (l, spot) {
            (Light::Point { position, .. }, None) => Light::Point { position, range },
            (Light::Point { .. }, Some((offset, tilt, apex_angle))) => {
                // Nearer than the point lights, so that many shadowed points
                // fall inside the scene bounds.
                let position = centre + DVec3::from(offset);
                let direction = (centre - position).normalize_or_zero() + DVec3::from(tilt);
                if direction.length() < 1e-3 {
                    return Ok(());
                }
                Light::Spot { position, direction, apex_angle, range }
            }
            _ => l,
        };
        let Ok(cam) = Camera::look_at(centre + DVec3::from(eye), centre, DVec3::Y, 1.0, 1.3, near) else {
            return Ok(());
        };
        let (wd, ht) = (80u32, 60u32);
        let b = shadowgen::volume_bounds(&cam, (wd, ht), &l, &s.object(ObjectId::from_slot(0)).world_bounds, &s.bounds());
        prop_assert!(b.scissor[0] <= b.scissor[2] && b.scissor[1] <= b.scissor[3]);
        prop_assert!(b.depth_near >= b.depth_far);
        let sb = s.bounds();
        let clip = cam.clip_from_eye_relative();
        for (p, t) in pts {
            let p = w.transform_point3(DVec3::from(p));
            let q = match l {
                Light::Directional { direction } => p + direction * (3.0 * t),
                _ => {
                    let lp = l.position().unwrap();
                    lp + (p - lp) * t
                }
            };
            if !sb.contains(q.as_vec3())
                || !l.reaches(q)
                || blockers(&s, ObjectId::from_slot(0), q, &l, true).unwrap_or(0) == 0
            {
                continue;
            }
            let c = clip * (q - cam.position).extend(1.0);
            if c.w < near {
                continue;
            }
            let (x, y) = ((c.x / c.w + 1.0) * 0.5 * wd as f64, (1.0 - c.y / c.w) * 0.5 * ht as f64);
            let z = (c.z / c.w) as f32;
            if x >= 0.0 && x < wd as f64 && y >= 0.0 && y < ht as f64 {
                prop_assert!(x >= b.scissor[0] as f64 && x < b.scissor[2] as f64, "x {} {:?}", x, b);
                prop_assert!(y >= b.scissor[1] as f64 && y < b.scissor[3] as f64, "y {} {:?}", y, b);
            }
            prop_assert!(z <= b.depth_near && z >= b.depth_far, "z {} {:?}", z, b);
        }
    }
}

// ---------------------------------------------------------------- finite extrusion

fn build_opts(s: &Scene, l: &Light, opts: BuildOptions) -> (VolumeBuffer, shadowgen::VolumeStats) {
    let mut buf = VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    let ids: Vec<ObjectId> = (0..s.objects().len() as u32)
        .map(ObjectId::from_slot)
        .collect();
    let st = build_volumes(&mut buf, s, &camera(), l, &ids, opts, &mut cache).unwrap();
    buf.check().unwrap();
    assert_eq!(st.volume_triangles, buf.triangle_count());
    (buf, st)
}

fn finite_opts(method: MethodChoice) -> BuildOptions {
    BuildOptions {
        method,
        finite_extrusion: true,
        ..Default::default()
    }
}

#[test]
fn ranged_point_light_extrudes_to_the_stated_distance() {
    // A quad scaled by 2 (local ±1 → world ±2) and moved: D is in world units.
    let w =
        DMat4::from_translation(DVec3::new(3.0, 0.0, -1.0)) * DMat4::from_scale(DVec3::splat(2.0));
    let quad =
        scene::procedural::analytic::horizontal_quad("q", [-1.0, 1.0], [-1.0, 1.0], 0.0, true)
            .unwrap();
    let s = scene_with(quad, w);
    let lp = DVec3::new(3.0, 10.0, -1.0);
    let l = Light::Point {
        position: lp,
        range: Some(25.0),
    };
    // Corners at (±2, −10, ±2) from the light: the widest angle of a cap
    // triangle is its diagonal, cos α = 92 / 108.
    let d = 25.0 * 108.0 / 92.0;
    for choice in [
        MethodChoice::ZPass,
        MethodChoice::ZFail,
        MethodChoice::ZpPlus,
    ] {
        let (buf, st) = build_opts(&s, &l, finite_opts(choice));
        assert_eq!(st.finite_volumes, 1);
        let r = &buf.ranges[0];
        assert_eq!(
            r.dark_cap.len(),
            3 * 2,
            "{choice:?}: the dark cap is always there"
        );
        assert_eq!(r.light_cap.is_empty(), choice == MethodChoice::ZPass);
        let mut far = 0;
        for p in &buf.positions[r.first_vertex as usize..(r.first_vertex + r.vertex_count) as usize]
        {
            assert_eq!(p[3], 1.0, "finite extrusion: every vertex is finite");
            let x = world(r, *p).truncate();
            if (x.y).abs() > 1e-6 {
                far += 1;
                let dist = (x - lp).length();
                assert!((dist - d).abs() < 1e-5 * d, "{dist} vs {d}");
                // On the ray from the light through a corner (±2, 0, ±2) around (3, 0, −1).
                let at_ground = lp + (x - lp) * (10.0 / (lp.y - x.y));
                let c = at_ground - DVec3::new(3.0, 0.0, -1.0);
                assert!(
                    (c.x.abs() - 2.0).abs() < 1e-5 && (c.z.abs() - 2.0).abs() < 1e-5,
                    "{c}"
                );
            }
        }
        assert_eq!(far, 4);
        if choice != MethodChoice::ZPass {
            assert!(boundary(&buf, r).is_empty());
        }
        // Below the quad within range: in shadow; beyond D: outside the volume.
        let above = DVec3::new(3.2, 5.0, -1.1);
        let inside = DVec3::new(3.5, -12.0, -0.5);
        let beyond = DVec3::new(3.5, -40.0, -0.5);
        if choice != MethodChoice::ZPass {
            assert_eq!(range_crossings(&buf, r, above, inside), Some(1));
            assert_eq!(range_crossings(&buf, r, above, beyond), Some(0));
        }
    }
    // The light nearly in the quad's plane: the diagonal spans more than 90°,
    // so the volume extrudes to infinity (no dark cap for zpass).
    let low = Light::Point {
        position: DVec3::new(3.0, 0.5, -1.0),
        range: Some(25.0),
    };
    let (buf, st) = build_opts(&s, &low, finite_opts(MethodChoice::ZPass));
    assert_eq!(st.finite_volumes, 0);
    assert!(buf.ranges[0].dark_cap.is_empty());
    assert!(buf.positions.iter().any(|p| p[3] == 0.0));
    // Without a range, or without the option: infinite as before.
    let (_, st) = build_opts(&s, &point(lp), finite_opts(MethodChoice::ZFail));
    assert_eq!(st.finite_volumes, 0);
    let (buf, st) = build_opts(&s, &l, BuildOptions::default());
    assert_eq!(st.finite_volumes, 0);
    assert!(
        buf.ranges[0].dark_cap.is_empty(),
        "zpass (Auto) without the option"
    );
    // A caster beyond the range: D comes from the farthest vertex.
    let short = Light::Point {
        position: lp,
        range: Some(1.0),
    };
    let (buf, st) = build_opts(&s, &short, finite_opts(MethodChoice::ZFail));
    assert_eq!(st.finite_volumes, 1);
    let r = &buf.ranges[0];
    let far = 108f64.sqrt() * (1.0 + 2f64.powi(-10));
    for p in &buf.positions[r.first_vertex as usize..(r.first_vertex + r.vertex_count) as usize] {
        let x = world(r, *p).truncate();
        if x.y.abs() > 1e-6 {
            assert!(((x - lp).length() - far).abs() < 1e-5 * far);
        }
    }
    assert!(boundary(&buf, r).is_empty());
}

fn ranged_light() -> impl Strategy<Value = (DVec3, Option<(DVec3, f64)>)> {
    (
        prop::array::uniform3(-40.0f64..40.0),
        prop::option::of((
            prop::array::uniform3(-1.0f64..1.0)
                .prop_filter("zero direction", |d| DVec3::from(*d).length() > 0.05),
            0.2f64..3.0,
        )),
    )
        .prop_map(|(p, spot)| (DVec3::from(p), spot.map(|(d, a)| (DVec3::from(d), a))))
}

proptest! {
    #![proptest_config(testkit::proptest_config(512))]

    /// Finite extrusion changes nothing within range: for any mesh, transform,
    /// ranged point or spot light and method, the finite volume's signed
    /// crossings along a segment between two points within range equal the
    /// infinite volume's; closed methods give closed finite volumes.
    #[test]
    fn finite_volumes_count_as_infinite_ones_within_range(
        pts in prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), 4..9),
        tris in prop::collection::vec(prop::array::uniform3(0u32..9), 1..14),
        radii in prop::collection::vec(0.5f32..1.5, 7..20),
        soup in any::<bool>(),
        w in transform(),
        (lp, spot) in ranged_light(),
        offset in prop_oneof![Just(0.0), Just(1e5)],
        e in prop::array::uniform3(-2.0f64..2.0),
        q in prop::array::uniform3(-2.0f64..2.0),
        te in 0.3f64..3.0,
        tq in 0.3f64..3.0,
        slack in prop_oneof![Just(1.0), 1.0f64..1.3],
        method in 0usize..3,
        two_sided in any::<bool>(),
    ) {
        let mesh = if soup {
            let n = pts.len() as u32;
            let pos: Vec<Vec3> = pts.into_iter().map(Vec3::from).collect();
            let tris: Vec<[u32; 3]> = tris.into_iter().map(|t| t.map(|i| i % n)).collect();
            match Mesh::new("soup", &pos, &tris) {
                Ok(m) if !m.triangles().is_empty() => m,
                _ => return Ok(()),
            }
        } else {
            star_sphere(&radii, 4, 5)
        };
        let shift = DVec3::new(offset, 0.0, offset);
        let w = DMat4::from_translation(shift) * w;
        let lp = lp + shift;
        let s = scene_with(mesh, w);
        // Points near the caster, slid along the light's rays: often in shadow.
        let slide = |p: [f64; 3], t: f64| lp + (w.transform_point3(DVec3::from(p)) - lp) * t;
        let (e, q) = (slide(e, te), slide(q, tq));
        let range = Some((e - lp).length().max((q - lp).length()) * slack);
        let l = match spot {
            None => Light::Point { position: lp, range },
            Some((direction, apex_angle)) => Light::Spot { position: lp, direction, apex_angle, range },
        };
        let choice = [MethodChoice::ZPass, MethodChoice::ZFail, MethodChoice::ZpPlus][method];
        let infinite = BuildOptions { method: choice, two_sided, ..Default::default() };
        let finite = BuildOptions { finite_extrusion: true, ..infinite };
        let (bi, _) = build_opts(&s, &l, infinite);
        let (bf, st) = build_opts(&s, &l, finite);
        let rf = &bf.ranges[0];
        if st.finite_volumes == 1 {
            prop_assert!(!rf.dark_cap.is_empty() || rf.light_cap.is_empty());
            prop_assert!(bf.positions.iter().all(|p| p[3] == 1.0));
        }
        if choice != MethodChoice::ZPass {
            prop_assert!(boundary(&bf, rf).is_empty(), "finite volume not closed");
        }
        let (Some(ci), Some(cf)) = (
            range_crossings(&bi, &bi.ranges[0], e, q),
            range_crossings(&bf, rf, e, q),
        ) else {
            return Ok(());
        };
        prop_assert_eq!(ci, cf);
    }
}

// ---------------------------------------------------------------- segmented volumes

proptest! {
    #![proptest_config(testkit::proptest_config(384))]

    /// Continuous clamping [Steiner §4.4.3]: inside a segment's slab the
    /// segments count as the unclamped volume does, in a gap between slabs
    /// (and beyond the last) they count nothing, so every segment lies inside
    /// the unclamped volume and every shadowed point of an occupied interval
    /// lies in a segment. Any mesh, transform, light and intervals; zfail,
    /// so that every range is closed.
    #[test]
    fn segments_count_as_the_unclamped_volume_within_their_slabs(
        radii in prop::collection::vec(0.5f32..1.5, 7..20),
        w in transform(),
        l in light(),
        gaps in prop::collection::vec((0.05f64..1.0, 0.05f64..1.0), 0..4),
        first in 0.0f64..1.0,
        q in prop::array::uniform3(-0.4f64..0.4),
        which in 0usize..6,
        frac in 0.0f64..1.0,
    ) {
        let s = scene_with(star_sphere(&radii, 4, 5), w);
        let bounds = s.object(ObjectId::from_slot(0)).world_bounds;
        let Some(axis) = shadowgen::SegmentAxis::new(&l, &bounds) else { return Ok(()) };
        // Intervals in units of the caster's depth extent beyond its far end.
        let [c0, c1] = axis.box_depths(&bounds);
        let unit = (c1 - c0).max(1e-3);
        let mut intervals = vec![[c0, c1 + first * unit]];
        for (gap, len) in &gaps {
            let a = intervals.last().unwrap()[1] + gap * unit;
            intervals.push([a, a + len * unit]);
        }
        let mut plan = shadowgen::ClampPlan::new();
        plan.set(ObjectId::from_slot(0), axis, &intervals);
        let opts = BuildOptions { method: MethodChoice::ZFail, ..Default::default() };
        let (mut unclamped, mut clamped) = (VolumeBuffer::new(), VolumeBuffer::new());
        let mut cache = SilhouetteCache::new();
        build_volumes(&mut unclamped, &s, &camera(), &l, &[ObjectId::from_slot(0)], opts, &mut cache).unwrap();
        let cam = camera();
        let request = shadowgen::VolumeRequest {
            scene: &s, camera: &cam, light: &l, casters: &[ObjectId::from_slot(0)], options: opts,
        };
        let st = shadowgen::build_clamped_volumes(&mut clamped, &request, &mut cache, &plan).unwrap();
        clamped.check().unwrap();
        let widened = plan.get(ObjectId::from_slot(0)).unwrap().1.to_vec();
        prop_assert_eq!(st.segments, widened.len());
        prop_assert_eq!(st.volume_triangles, clamped.triangle_count());
        for (k, r) in clamped.ranges.iter().enumerate() {
            prop_assert_eq!(r.segment as usize, k);
            prop_assert!(boundary(&clamped, r).is_empty(), "segment {} is not closed", k);
        }
        // e: nearer the light than the caster, outside every volume.
        let e = match l {
            Light::Directional { direction } => axis.origin - direction.normalize() * (2.0 * axis.size + 1.0),
            _ => axis.origin + axis.axis * (0.5 * c0),
        };
        // q: a point inside the caster (its radii are at least 0.5), so
        // usually in its shadow once moved along its light ray to a depth in
        // an interval (`which` < their count) or in a gap or beyond them.
        let p = w.transform_point3(DVec3::from(q));
        let target = match widened.get(which) {
            Some(i) => i[0] + frac * (i[1] - i[0]),
            None => {
                let last = widened.len() - 1;
                let k = which % widened.len();
                let (a, b) = if k == last {
                    (widened[last][1], widened[last][1] + 2.0 * unit)
                } else {
                    (widened[k][1], widened[k + 1][0])
                };
                a + frac * (b - a)
            }
        };
        if axis.depth(p) >= target || (axis.positional && axis.depth(p) <= 0.0) {
            return Ok(());
        }
        let q = axis.project(p, target);
        let d = axis.depth(q);
        // Points within rounding of a plane decide nothing.
        let tol = 1e-6 * (d.abs() + axis.size);
        if widened.iter().any(|i| (d - i[0]).abs() < tol || (d - i[1]).abs() < tol) {
            return Ok(());
        }
        let (Some(u), Some(c)) = (buffer_crossings(&unclamped, e, q), buffer_crossings(&clamped, e, q)) else {
            return Ok(());
        };
        if widened.iter().any(|i| i[0] < d && d < i[1]) {
            prop_assert_eq!(c, u, "depth {} in {:?}", d, widened);
        } else if d > c1 {
            prop_assert_eq!(c, 0, "depth {} outside {:?}", d, widened);
        }
    }
}

proptest! {
    #![proptest_config(testkit::proptest_config(384))]

    /// Discrete clamping [Steiner §4.4.2]: a caster's segments between the
    /// eye's slicing planes count as the unclamped volume does inside its
    /// occupied slices and nothing beyond the last (unless it extrudes to
    /// infinity); each range is closed. Any mesh, transform, light, slice
    /// count and occupied slices; zfail, so that every range is closed.
    #[test]
    fn sliced_segments_count_as_the_unclamped_volume_within_their_slices(
        radii in prop::collection::vec(0.5f32..1.5, 7..20),
        w in transform(),
        l in light(),
        n in 1u32..24,
        occupied in any::<u32>(),
        q in prop::array::uniform3(-0.4f64..0.4),
        pick in 0usize..8,
        frac in 0.0f64..1.0,
    ) {
        struct Found(Vec<[f64; 2]>);
        impl shadowgen::ReceiverDepths for Found {
            fn depths(&self, _: ObjectId) -> Option<&[[f64; 2]]> {
                Some(&self.0)
            }
        }
        let s = scene_with(star_sphere(&radii, 4, 5), w);
        let bounds = s.object(ObjectId::from_slot(0)).world_bounds;
        let cam = camera();
        let base = shadowgen::EyeSlices::new(&cam, (64, 48), &l, n).unwrap();
        let Some(axis) = shadowgen::SegmentAxis::new(&l, &bounds) else { return Ok(()) };
        // Occupied slices in the base orientation, as the light pass gives them.
        let found = Found(
            (0..n)
                .filter(|i| occupied >> (i % 32) & 1 == 1)
                .map(|i| [base.edge(i), base.edge(i + 1)])
                .collect(),
        );
        let input = shadowgen::ClampInput {
            scene: &s, light: &l, casters: &[ObjectId::from_slot(0)], receives: &[true], cost: None,
        };
        let mut plan = shadowgen::ClampPlan::new();
        shadowgen::LightClamp::new().plan_sliced(&input, &base, &found, &mut plan);
        let Some((slices, intervals)) = plan.get_sliced(ObjectId::from_slot(0)) else { return Ok(()) };
        let (slices, intervals) = (*slices, intervals.to_vec());
        prop_assert!(intervals.windows(2).all(|w| w[0][1] < w[1][0]));
        prop_assert!(intervals[..intervals.len() - 1].iter().all(|i| i[1].is_finite()));
        let opts = BuildOptions { method: MethodChoice::ZFail, ..Default::default() };
        let (mut unclamped, mut clamped) = (VolumeBuffer::new(), VolumeBuffer::new());
        let mut cache = SilhouetteCache::new();
        build_volumes(&mut unclamped, &s, &cam, &l, &[ObjectId::from_slot(0)], opts, &mut cache).unwrap();
        let request = shadowgen::VolumeRequest {
            scene: &s, camera: &cam, light: &l, casters: &[ObjectId::from_slot(0)], options: opts,
        };
        let st = shadowgen::build_clamped_volumes(&mut clamped, &request, &mut cache, &plan).unwrap();
        clamped.check().unwrap();
        prop_assert_eq!(st.segments, intervals.len());
        for (k, r) in clamped.ranges.iter().enumerate() {
            prop_assert_eq!(r.segment as usize, k);
            prop_assert!(boundary(&clamped, r).is_empty(), "segment {} is not closed", k);
        }
        // e: nearer the light than the caster, outside every volume.
        let [c0, _] = axis.box_depths(&bounds);
        let e = match l {
            Light::Directional { direction } => axis.origin - direction.normalize() * (2.0 * axis.size + 1.0),
            _ => axis.origin + axis.axis * (0.5 * c0),
        };
        // A point inside the caster moved along its light ray to a g in an
        // interval (`pick` < their count) or past the last.
        let p = w.transform_point3(DVec3::from(q));
        let last = intervals.len() - 1;
        let target = match intervals.get(pick % (intervals.len() + 1)) {
            Some(i) if i[1].is_finite() => i[0] + frac * (i[1] - i[0]),
            Some(i) => i[0] + frac * 100.0,
            None if intervals[last][1].is_finite() => intervals[last][1] + frac * 100.0,
            None => return Ok(()),
        };
        if !(slices.depth(p) < target && slices.reaches(p, target)) {
            return Ok(());
        }
        let q = slices.project(p, target);
        let g = slices.depth(q);
        // Points within rounding of a plane decide nothing.
        let tol = 1e-6 * (1.0 + g.abs());
        if intervals.iter().any(|i| (g - i[0]).abs() < tol || (g - i[1]).abs() < tol) {
            return Ok(());
        }
        let (Some(u), Some(c)) = (buffer_crossings(&unclamped, e, q), buffer_crossings(&clamped, e, q)) else {
            return Ok(());
        };
        if intervals.iter().any(|i| i[0] < g && g < i[1]) {
            prop_assert_eq!(c, u, "g {} in {:?}", g, intervals);
        } else if g > intervals[last][1] {
            prop_assert_eq!(c, 0, "g {} beyond {:?}", g, intervals);
        }
    }
}

/// Discrete clamping where the caster's rays never reach the lowest slices
/// (a light behind and above the eye, rays running down towards the
/// horizon): the plan ends in a segment that extrudes to infinity, which
/// is closed and counts as the unclamped volume along a ray through it.
#[test]
fn sliced_segments_extrude_to_infinity_past_the_rays_reach() {
    struct Found(Vec<[f64; 2]>);
    impl shadowgen::ReceiverDepths for Found {
        fn depths(&self, _: ObjectId) -> Option<&[[f64; 2]]> {
            Some(&self.0)
        }
    }
    let s = scene_with(
        unit_box(),
        DMat4::from_translation(DVec3::new(-0.5, 3.0, -0.5)),
    );
    let cam = camera();
    let l = point(DVec3::new(0.0, 10.0, 40.0));
    let base = shadowgen::EyeSlices::new(&cam, (64, 48), &l, 8).unwrap();
    assert!(base.rows());
    let input = shadowgen::ClampInput {
        scene: &s,
        light: &l,
        casters: &[ObjectId::from_slot(0)],
        receives: &[true],
        cost: None,
    };
    let opts = BuildOptions {
        method: MethodChoice::ZFail,
        ..Default::default()
    };
    let (mut unclamped, mut clamped) = (VolumeBuffer::new(), VolumeBuffer::new());
    let mut cache = SilhouetteCache::new();
    build_volumes(
        &mut unclamped,
        &s,
        &cam,
        &l,
        &[ObjectId::from_slot(0)],
        opts,
        &mut cache,
    )
    .unwrap();
    let request = shadowgen::VolumeRequest {
        scene: &s,
        camera: &cam,
        light: &l,
        casters: &[ObjectId::from_slot(0)],
        options: opts,
    };
    let (mut tails, mut checked) = (0, 0);
    // One occupied slice at a time.
    for i in 0..8 {
        let found = Found(vec![[base.edge(i), base.edge(i + 1)]]);
        let mut plan = shadowgen::ClampPlan::new();
        shadowgen::LightClamp::new().plan_sliced(&input, &base, &found, &mut plan);
        let Some((slices, intervals)) = plan.get_sliced(ObjectId::from_slot(0)) else {
            continue;
        };
        let (slices, intervals) = (*slices, intervals.to_vec());
        shadowgen::build_clamped_volumes(&mut clamped, &request, &mut cache, &plan).unwrap();
        clamped.check().unwrap();
        let tail = intervals.last().unwrap()[1] == f64::INFINITY;
        tails += usize::from(tail);
        let last = clamped.ranges.last().unwrap();
        assert_eq!(last.planes[1].is_none(), tail);
        for r in &clamped.ranges {
            assert!(
                boundary(&clamped, r).is_empty(),
                "slice {i}: segment {} is not closed",
                r.segment
            );
        }
        // Points along the light ray through the box's centre, out to far
        // beyond it: in the box's shadow at every distance.
        let (lp, c) = (l.position().unwrap(), DVec3::new(0.0, 3.5, 0.0));
        let e = lp + (c - lp) * 0.5;
        for t in [1.5, 2.0, 3.0, 10.0, 100.0, 1000.0] {
            let q = lp + (c - lp) * t;
            let g = slices.depth(q);
            if !intervals.iter().any(|r| r[0] + 1e-6 < g && g < r[1] - 1e-6) {
                continue;
            }
            let (Some(u), Some(k)) = (
                buffer_crossings(&unclamped, e, q),
                buffer_crossings(&clamped, e, q),
            ) else {
                continue;
            };
            assert_eq!(k, u, "slice {i}, t {t}, g {g}, {intervals:?}");
            assert_ne!(u, 0);
            checked += 1;
        }
    }
    assert!(
        tails >= 1 && checked >= 3,
        "{tails} tails, {checked} points checked"
    );
}

/// Clamping's plan for a row of boxes under a point light: a caster's
/// intervals cover the boxes behind it; the plan is reused (no sweep) while
/// nothing moves and recomputed when a box moves or the receivers change.
#[test]
fn clamp_plans_are_reused_until_something_moves() {
    let build = |offset: f64| {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(unit_box());
        // Boxes along −y below the light at x = 0, 0, 0 (one straight
        // under the other) and one off to the side.
        for (k, p) in [(0.0, -2.0), (0.0, -6.0 - offset), (0.0, -12.0), (9.0, -6.0)]
            .iter()
            .enumerate()
        {
            let t = DMat4::from_translation(DVec3::new(p.0, p.1, 0.0));
            g.add_instance(&format!("b{k}"), m, Transform::Matrix(t));
        }
        Scene::new(g).unwrap()
    };
    let l = point(DVec3::new(0.0, 5.0, 0.0));
    let casters = [ObjectId::from_slot(0)];
    let receives = [true; 4];
    let mut clamp = shadowgen::LightClamp::new();
    let mut plan = shadowgen::ClampPlan::new();
    let s = build(0.0);
    let input = shadowgen::ClampInput {
        scene: &s,
        light: &l,
        casters: &casters,
        receives: &receives,
        cost: None,
    };
    let first = clamp.plan(&input, &mut plan).unwrap();
    assert!(!first.cached && first.sap_pairs > 0);
    let (axis, intervals) = plan.get(ObjectId::from_slot(0)).unwrap();
    let intervals = intervals.to_vec();
    // The caster itself and the two boxes below it: three intervals (the
    // side box is not in its shadow).
    assert_eq!(intervals.len(), 3, "{intervals:?}");
    let depth = |y: f64| axis.depth(DVec3::new(0.0, y, 0.0));
    for y in [-2.0, -6.0, -12.0] {
        assert!(
            intervals
                .iter()
                .any(|i| i[0] <= depth(y) && depth(y) <= i[1]),
            "{y}"
        );
    }
    assert!(!intervals
        .iter()
        .any(|i| i[0] <= depth(-9.0) && depth(-9.0) <= i[1]));
    let again = clamp.plan(&input, &mut plan).unwrap();
    assert!(again.cached && again.sap_pairs == 0);
    assert_eq!(plan.get(ObjectId::from_slot(0)).unwrap().1, &intervals[..]);
    // The side box stops receiving: swept again, but the caster does not
    // pair with it and keeps its intervals; the lowest box stops: the
    // caster's intervals are recomputed without it.
    let mut fewer = receives;
    for (dropped, kept, segments) in [(3, 1, intervals.len()), (2, 0, 2)] {
        fewer[dropped] = false;
        let st = clamp
            .plan(
                &shadowgen::ClampInput {
                    receives: &fewer,
                    ..input
                },
                &mut plan,
            )
            .unwrap();
        assert!(
            !st.cached && st.cached_casters == kept,
            "box {dropped}: {st:?}"
        );
        let now = plan.get(ObjectId::from_slot(0)).unwrap().1;
        assert_eq!(now.len(), segments);
        assert!(
            kept == 0 || now == &intervals[..],
            "kept intervals unchanged"
        );
    }
    clamp.plan(&input, &mut plan).unwrap();
    assert_eq!(plan.get(ObjectId::from_slot(0)).unwrap().1, &intervals[..]);
    // A box moves: recomputed, and the interval follows it.
    let moved = build(1.0);
    let input = shadowgen::ClampInput {
        scene: &moved,
        ..input
    };
    let after = clamp.plan(&input, &mut plan).unwrap();
    assert!(!after.cached);
    let (axis, now) = plan.get(ObjectId::from_slot(0)).unwrap();
    let d = axis.depth(DVec3::new(0.0, -7.0, 0.0));
    assert!(now.iter().any(|i| i[0] <= d && d <= i[1]) && now != &intervals[..]);
    // Fewer receivers: recomputed; the caster alone keeps its own interval.
    let none = [true, false, false, false];
    let alone = clamp
        .plan(
            &shadowgen::ClampInput {
                receives: &none,
                ..input
            },
            &mut plan,
        )
        .unwrap();
    assert!(!alone.cached);
    assert_eq!(plan.get(ObjectId::from_slot(0)).unwrap().1.len(), 1);
}

proptest! {
    #![proptest_config(testkit::proptest_config(96))]

    /// Receiver and caster sets that change while nothing moves (a culled
    /// view's PSR and PSC): the kept state forgets only the casters paired
    /// with a changed object, and its plan equals a fresh state's at every
    /// step.
    #[test]
    fn clamp_plans_follow_changing_sets_like_fresh_ones(
        pos in prop::collection::vec((-8.0f64..8.0, -9.0f64..0.0, -8.0f64..8.0), 4..20),
        sun in any::<bool>(),
        start in prop::collection::vec((any::<bool>(), any::<bool>()), 20),
        steps in prop::collection::vec(prop::collection::vec((0usize..20, any::<bool>()), 1..4), 1..6),
    ) {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(unit_box());
        for (k, p) in pos.iter().enumerate() {
            let t = DMat4::from_translation(DVec3::new(p.0, p.1, p.2));
            g.add_instance(&format!("b{k}"), m, Transform::Matrix(t));
        }
        let s = Scene::new(g).unwrap();
        let n = pos.len();
        let l = if sun {
            Light::Directional { direction: DVec3::new(0.3, -1.0, 0.2) }
        } else {
            point(DVec3::new(0.5, 6.0, -0.5))
        };
        let (mut receives, mut casts): (Vec<bool>, Vec<bool>) = start[..n].iter().copied().unzip();
        let mut kept = shadowgen::LightClamp::new();
        let (mut plan, mut fresh_plan) = (shadowgen::ClampPlan::new(), shadowgen::ClampPlan::new());
        for (k, flips) in std::iter::once(&Vec::new()).chain(&steps).enumerate() {
            for &(i, which) in flips {
                let f = if which { &mut receives } else { &mut casts };
                f[i % n] = !f[i % n];
            }
            let casters: Vec<ObjectId> = (0..n as u32).filter(|&i| casts[i as usize]).map(ObjectId::from_slot).collect();
            let input = shadowgen::ClampInput {
                scene: &s,
                light: &l,
                casters: &casters,
                receives: &receives,
                cost: None,
            };
            kept.plan(&input, &mut plan).unwrap();
            shadowgen::LightClamp::new().plan(&input, &mut fresh_plan).unwrap();
            prop_assert_eq!(plan.len(), fresh_plan.len());
            for c in &casters {
                prop_assert_eq!(plan.get(*c).map(|p| p.1), fresh_plan.get(*c).map(|p| p.1),
                    "step {} caster {}", k, c.slot());
            }
        }
    }
}

/// Found by the `volumes` fuzz target (fuzz/HOURS.md findings 4 and 5): soups
/// with a vertex 10³⁶–10³⁸ out beside vertices near 10⁻², under a sun. The
/// f64 facing sign, once taken at the far vertex, lost the normal's largest
/// component, so a triangle's shadow volume was built inside out and the
/// zfail crossings disagreed with the reference's blockers. The facing rule
/// is exact now.
#[test]
fn huge_coordinate_soups_count_their_blockers() {
    struct Case {
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        scale: f64,
        offset: f64,
        direction: DVec3,
        two_sided: bool,
        e: DVec3,
        q: DVec3,
    }
    let cases = [
        Case {
            positions: vec![
                Vec3::new(-7.9697937e31, 0.0, 1.305771e36),
                Vec3::new(1.375, 0.03125, 0.0),
                Vec3::new(-0.3999635, 1.4088781e36, 0.0),
                Vec3::new(3.84375, 3.84375, 0.0),
                Vec3::new(9.196e-41, -3.7110975e-27, -0.28125),
            ],
            triangles: vec![
                [1, 4, 0],
                [3, 0, 2],
                [3, 3, 3],
                [0, 3, 2],
                [2, 1, 2],
                [2, 3, 0],
                [4, 0, 0],
            ],
            scale: 0.001,
            offset: 0.0,
            direction: DVec3::splat(-1.0),
            two_sided: true,
            e: DVec3::new(
                0.0003464988186095855,
                -0.001539882504347613,
                0.00046008697760859365,
            ),
            q: DVec3::new(
                -0.004703410562431061,
                -0.004765484263506822,
                -0.004809216620262753,
            ),
        },
        Case {
            positions: vec![
                Vec3::new(-0.03125, -2.96875, -0.03125),
                Vec3::new(-0.03125, -1.7279962e38, -2.1532974e38),
                Vec3::new(-2.96875, -0.53125, 6.2862357e-30),
                Vec3::new(3.65625, 0.03125, 0.09375),
                Vec3::new(0.0, 0.03125, 2.3509548e-38),
                Vec3::new(0.09375, 0.25, -3.5),
                Vec3::new(3.375, 1.90625, -3.0625),
                Vec3::new(-3.0625, -3.0625, -0.03125),
                Vec3::new(2.3509886e-38, -0.03125, 1.03125),
                Vec3::new(-0.28125, 2.3509754e-38, 0.0),
                Vec3::new(0.4375, 3.65625, -0.03125),
            ],
            triangles: vec![
                [0, 2, 5],
                [0, 1, 0],
                [3, 2, 0],
                [2, 1, 0],
                [3, 6, 7],
                [10, 1, 0],
                [10, 8, 7],
                [10, 2, 5],
                [0, 0, 6],
                [4, 6, 0],
                [10, 10, 0],
                [0, 0, 10],
                [0, 10, 6],
                [4, 0, 10],
                [8, 10, 10],
                [10, 10, 10],
            ],
            scale: 1.0,
            offset: 1000.0,
            direction: DVec3::new(
                -0.49871061264972916,
                -0.9184557869840543,
                -0.6403143358510719,
            ),
            two_sided: false,
            e: DVec3::new(999.8730174145991, 999.5670305006744, 998.5346453654586),
            q: DVec3::new(998.6338017283246, 998.325586997203, 998.5298235145392),
        },
    ];
    for (k, c) in cases.into_iter().enumerate() {
        let mesh = Mesh::new("soup", &c.positions, &c.triangles).unwrap();
        let w = DMat4::from_translation(DVec3::splat(c.offset))
            * DMat4::from_scale(DVec3::splat(c.scale));
        let s = scene_with(mesh, w);
        let l = Light::Directional {
            direction: c.direction,
        };
        let buf = zfail_volumes(&s, &l, c.two_sided);
        for r in &buf.ranges {
            assert!(boundary(&buf, r).is_empty(), "case {k}: an open volume");
        }
        let count = buffer_crossings(&buf, c.e, c.q).expect("decidable crossings");
        let bq =
            blockers(&s, ObjectId::from_slot(0), c.q, &l, c.two_sided).expect("decidable blockers");
        let be =
            blockers(&s, ObjectId::from_slot(0), c.e, &l, c.two_sided).expect("decidable blockers");
        assert_eq!(count, bq - be, "case {k}: crossings against blockers");
    }
}
