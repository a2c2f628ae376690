//! Silhouettes and shadow volumes on arbitrary triangle soups (positions,
//! indices, transform, light and method from the fuzzer's bytes; broken
//! meshes included), unclamped and cut into segments over arbitrary depth
//! intervals. Checked, as the shadowgen tests state them:
//! - no panic; a bad input is an error;
//! - every zfail range, and every segment, is a closed surface (no open edge);
//! - along a segment slid along the light's rays, the zfail volume's signed
//!   crossings equal the change in the number of casting triangles that
//!   block each end from the light (the reference's definition of the
//!   shadow), whenever no triangle is too close to degenerate to tell.

use crate::Bytes;
use glam::{DMat4, DVec3, Vec3};
use shadowcull::scene::{Camera, Light, Mesh, ObjectId, Scene, SceneGraph, Transform};
use shadowcull::shadowgen::{
    build_clamped_volumes, build_volumes, BuildOptions, ClampPlan, MethodChoice, SegmentAxis,
    SilhouetteCache, VolumeRequest,
};
use testkit::volume_checks::{blockers, boundary, range_crossings};

/// Mostly in [−4, 4) in steps of 1/32; one in sixteen any bit pattern.
fn coordinate(b: &mut Bytes) -> f32 {
    match b.u8() % 16 {
        0 => b.any_f32(),
        _ => b.small(1.0 / 32.0),
    }
}

/// A point of the cube [−1, 1]³.
fn point(b: &mut Bytes) -> DVec3 {
    DVec3::new(b.unit(), b.unit(), b.unit()) * 2.0 - 1.0
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let mut b = Bytes(data);
    let n = 3 + usize::from(b.u8() % 10);
    let positions: Vec<Vec3> = (0..n)
        .map(|_| Vec3::new(coordinate(&mut b), coordinate(&mut b), coordinate(&mut b)))
        .collect();
    let count = 1 + usize::from(b.u8() % 16);
    let tris: Vec<[u32; 3]> = (0..count)
        .map(|_| [0; 3].map(|_| u32::from(b.u8()) % n as u32))
        .collect();
    let Ok(mesh) = Mesh::new("soup", &positions, &tris) else {
        return;
    };
    if mesh.triangles().is_empty() {
        return;
    }
    let scale = 10f64.powi(i32::from(b.u8() % 7) - 3);
    let offset = [0.0, 1e3, 1e6][usize::from(b.u8() % 3)];
    let w = DMat4::from_translation(DVec3::splat(offset)) * DMat4::from_scale(DVec3::splat(scale));
    let mut g = SceneGraph::new();
    let m = g.add_mesh(mesh);
    g.add_instance("soup", m, Transform::Matrix(w));
    let Ok(s) = Scene::new(g) else {
        return;
    };
    let at = |p: DVec3| w.transform_point3(p);
    let light = match b.u8() % 3 {
        0 => Light::Directional {
            direction: point(&mut b),
        },
        1 => Light::Point {
            position: at(point(&mut b) * 4.0),
            range: None,
        },
        _ => Light::Spot {
            position: at(point(&mut b) * 4.0),
            direction: point(&mut b),
            apex_angle: 0.1 + 3.0 * b.unit(),
            range: None,
        },
    };
    if light.validate().is_err() {
        return;
    }
    let two_sided = b.u8() % 2 == 0;
    let Ok(camera) = Camera::look_at(
        at(DVec3::new(0.3, 2.0, 9.0)),
        at(DVec3::ZERO),
        DVec3::Y,
        1.0,
        1.0,
        0.1 * scale,
    ) else {
        return;
    };
    let casters = [ObjectId::from_slot(0)];
    let mut buf = shadowcull::raster::VolumeBuffer::new();
    let mut cache = SilhouetteCache::new();
    for method in [
        MethodChoice::Auto,
        MethodChoice::ZPass,
        MethodChoice::ZpPlus,
    ] {
        let opts = BuildOptions {
            method,
            two_sided,
            viewport: Some((32, 24)),
            ..Default::default()
        };
        let _ = build_volumes(&mut buf, &s, &camera, &light, &casters, opts, &mut cache);
    }
    let opts = BuildOptions {
        method: MethodChoice::ZFail,
        two_sided,
        viewport: None,
        ..Default::default()
    };
    if build_volumes(&mut buf, &s, &camera, &light, &casters, opts, &mut cache).is_err() {
        return;
    }
    for r in &buf.ranges {
        assert!(boundary(&buf, r).is_empty(), "an open zfail volume");
    }
    // Ends near the soup, slid along the light's rays: often in shadow.
    let slide = |p: DVec3, t: f64| match light.position() {
        None => p + light.toward_light(p).normalize() * (-3.0 * t * scale),
        Some(lp) => lp + (p - lp) * t,
    };
    for _ in 0..4 {
        let (e, te, q, tq) = (
            point(&mut b),
            0.3 + 3.0 * b.unit(),
            point(&mut b),
            0.3 + 3.0 * b.unit(),
        );
        let (e, q) = (slide(at(e), te), slide(at(q), tq));
        let Some(count) = buf
            .ranges
            .iter()
            .try_fold(0, |n, r| Some(n + range_crossings(&buf, r, e, q)?))
        else {
            continue;
        };
        let (Some(bq), Some(be)) = (
            blockers(&s, ObjectId::from_slot(0), q, &light, two_sided),
            blockers(&s, ObjectId::from_slot(0), e, &light, two_sided),
        ) else {
            continue;
        };
        assert_eq!(
            count,
            bq - be,
            "crossings of {e} -> {q}: blockers {be} -> {bq}; {light:?}, two-sided {two_sided}, \
             scale {scale}, offset {offset}, positions {positions:?}, triangles {tris:?}, \
             ranges {:?}",
            buf.ranges
                .iter()
                .map(|r| (r.method, r.index_count))
                .collect::<Vec<_>>()
        );
    }
    // Segments over arbitrary sorted depth intervals: each closed.
    let bounds = s.object(ObjectId::from_slot(0)).world_bounds;
    let Some(axis) = SegmentAxis::new(&light, &bounds) else {
        return;
    };
    let [c0, c1] = axis.box_depths(&bounds);
    let unit = (c1 - c0).max(1e-6 * scale);
    let mut intervals = vec![[c0, c1 + b.unit() * unit]];
    for _ in 0..b.u8() % 4 {
        let a = intervals.last().map_or(c1, |i| i[1]) + (0.01 + b.unit()) * unit;
        intervals.push([a, a + (0.01 + b.unit()) * unit]);
    }
    let mut plan = ClampPlan::new();
    plan.set(ObjectId::from_slot(0), axis, &intervals);
    let request = VolumeRequest {
        scene: &s,
        light: &light,
        camera: &camera,
        casters: &casters,
        options: opts,
    };
    if build_clamped_volumes(&mut buf, &request, &mut cache, &plan).is_ok() {
        for r in &buf.ranges {
            assert!(
                boundary(&buf, r).is_empty(),
                "an open segment {}",
                r.segment
            );
        }
    }
}
