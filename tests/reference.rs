//! End-to-end tests of the ray-cast reference on analytic scenes.

use crate::common::scene_of;
use glam::{DMat4, DVec3, Vec3};
use scene::procedural::analytic;
use scene::{Camera, Light, Mesh, ObjectId, Scene, Transform};
use shadowcull::mask::{compare, PixelClass};
use shadowcull::reference::{
    reference_mask, EyeSurface, ReferenceMask, ReferenceOptions, TriangleBvh,
};

/// A closed box, CCW outward, 12 triangles.
fn box_mesh(min: Vec3, max: Vec3) -> Mesh {
    analytic::box_mesh("box", min, max).unwrap()
}

/// A horizontal quad at height `y`, half-size `h`, facing up or down.
fn quad(y: f32, h: f32, up: bool) -> Mesh {
    analytic::horizontal_quad("quad", [-h, h], [-h, h], y, up).unwrap()
}

/// The view of [`test_scene`] most tests use.
fn test_camera() -> Camera {
    let eye = DVec3::new(2.0, 9.0, 12.0);
    Camera::look_at(
        eye,
        DVec3::ZERO,
        DVec3::Y,
        50f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap()
}

/// A 60° camera at `eye` looking at the origin.
fn view_from(eye: DVec3) -> Camera {
    Camera::look_at(
        eye,
        DVec3::ZERO,
        DVec3::Y,
        60f64.to_radians(),
        4.0 / 3.0,
        0.1,
    )
    .unwrap()
}

/// A point light up and to the side of [`test_scene`].
fn test_lamp() -> Light {
    let position = DVec3::new(-4.0, 8.0, 3.0);
    Light::Point {
        position,
        range: None,
    }
}

/// The reference with default options.
fn mask(bvh: &TriangleBvh, cam: &Camera, light: &Light, w: u32, h: u32) -> ReferenceMask {
    reference_mask(bvh, cam, light, w, h, &ReferenceOptions::default(), None)
}

fn top_down(center: DVec3, height: f64, fov_deg: f64) -> Camera {
    Camera::look_at(
        center + DVec3::Y * height,
        center,
        DVec3::NEG_Z,
        fov_deg.to_radians(),
        1.0,
        height * 0.01,
    )
    .unwrap()
}

/// Area of the convex hull of 2D points (monotone chain + shoelace).
fn hull_area(mut pts: Vec<(f64, f64)>) -> f64 {
    pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut h: Vec<(f64, f64)> = Vec::new();
    for pass in 0..2 {
        let start = h.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    let n = h.len();
    (0..n)
        .map(|i| h[i].0 * h[(i + 1) % n].1 - h[(i + 1) % n].0 * h[i].1)
        .sum::<f64>()
        .abs()
        * 0.5
}

#[test]
fn box_shadow_area_matches_the_analytic_projection() {
    // Unit box whose bottom is 1 above the ground plane y = 0; point light to the
    // side so the whole shadow is visible from straight above.
    let light_pos = DVec3::new(-6.0, 5.0, 0.0);
    let s = scene_of(
        vec![
            quad(0.0, 20.0, true),
            box_mesh(Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 2.0, 0.5)),
        ],
        Transform::default(),
    );
    let bvh = TriangleBvh::new(&s);
    // Analytic shadow: convex hull of the 8 corners projected from the light onto y = 0.
    let mut pts = Vec::new();
    for &x in &[-0.5, 0.5] {
        for &y in &[1.0, 2.0] {
            for &z in &[-0.5, 0.5] {
                let p = DVec3::new(x, y, z);
                let t = light_pos.y / (light_pos.y - p.y);
                let q = light_pos + (p - light_pos) * t;
                pts.push((q.x, q.z));
            }
        }
    }
    let expected = hull_area(pts);
    let (h, fov, res) = (1000.0, 0.35f64, 400u32);
    let cam = top_down(DVec3::new(2.85, 0.0, 0.0), h, fov);
    let light = Light::Point {
        position: light_pos,
        range: None,
    };
    let r = reference_mask(
        &bvh,
        &cam,
        &light,
        res,
        res,
        &ReferenceOptions::default(),
        None,
    );
    let pixel = 2.0 * h * (0.5 * fov.to_radians()).tan() / res as f64;
    let area = r.counts.classes.shadow as f64 * pixel * pixel;
    let rel = (area - expected).abs() / expected;
    println!(
        "shadow area {area:.4} m² vs analytic {expected:.4} m² ({:.3}%)",
        rel * 100.0
    );
    assert!(
        rel < 0.01,
        "shadow area {area:.4} vs analytic {expected:.4} ({:.3}%)",
        rel * 100.0
    );
    assert!(
        r.counts.classes.shadow > 5000,
        "resolution too low to measure 1%"
    );
}

/// Six hundred copies of one box in one place: the triangle BVH chains
/// them (600 coinciding triangles per face), far deeper than obvhs' fixed
/// traversal stacks (96 and 192; `scene::bvh_build` sizes the stack). The
/// mask equals one box's.
#[test]
fn coinciding_copies_cast_like_one() {
    let cam = test_camera();
    let light = test_lamp();
    let caster = || box_mesh(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0));
    let one = scene_of(vec![quad(0.0, 10.0, true), caster()], Transform::default());
    let mut meshes = vec![quad(0.0, 10.0, true)];
    meshes.extend((0..600).map(|_| caster()));
    let many = scene_of(meshes, Transform::default());
    let a = mask(&TriangleBvh::new(&one), &cam, &light, 160, 120);
    let b = mask(&TriangleBvh::new(&many), &cam, &light, 160, 120);
    assert!(a.counts.classes.shadow > 100, "{:?}", a.counts);
    // (Ambiguity differs: the copies tie at every visible pixel of the box.)
    assert!(a.mask == b.mask);
    assert_eq!(a.counts.classes, b.counts.classes);
}

#[test]
fn open_quad_casts_only_when_it_faces_the_light() {
    let light = Light::Point {
        position: DVec3::new(0.0, 6.0, 0.0),
        range: None,
    };
    let cam = view_from(DVec3::new(0.0, 8.0, 8.0));
    let opts = ReferenceOptions::default();
    let two = ReferenceOptions {
        two_sided: true,
        ..opts
    };
    for up in [true, false] {
        let s = scene_of(
            vec![quad(0.0, 10.0, true), quad(2.0, 1.0, up)],
            Transform::default(),
        );
        let bvh = TriangleBvh::new(&s);
        let r = reference_mask(&bvh, &cam, &light, 160, 120, &opts, None);
        if up {
            assert!(
                r.counts.classes.shadow > 100,
                "an up-facing quad must cast: {:?}",
                r.counts
            );
        } else {
            assert_eq!(
                r.counts.classes.shadow, 0,
                "a quad facing away casts nothing"
            );
        }
        let r2 = reference_mask(&bvh, &cam, &light, 160, 120, &two, None);
        assert!(
            r2.counts.classes.shadow > 100,
            "two-sided: every triangle casts"
        );
    }
}

#[test]
fn light_inside_a_closed_box_casts_nothing_by_default_and_everything_two_sided() {
    let light = Light::Point {
        position: DVec3::new(0.0, 1.5, 0.0),
        range: None,
    };
    let s = scene_of(
        vec![
            quad(0.0, 10.0, true),
            box_mesh(Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 2.0, 0.5)),
        ],
        Transform::default(),
    );
    let bvh = TriangleBvh::new(&s);
    let cam = view_from(DVec3::new(0.0, 6.0, 9.0));
    let r = mask(&bvh, &cam, &light, 160, 120);
    assert_eq!(r.counts.classes.shadow, 0);
    assert!(r.counts.classes.lit > 1000);
    assert!(
        r.counts.classes.unlit > 0,
        "the box's outside faces the light's back"
    );
    let r = reference_mask(
        &bvh,
        &cam,
        &light,
        160,
        120,
        &ReferenceOptions {
            two_sided: true,
            ..Default::default()
        },
        None,
    );
    assert_eq!(r.counts.classes.lit, 0, "{:?}", r.counts);
    assert!(r.counts.classes.shadow > 1000);
}

/// A small shadowed scene: ground, a box, a floating quad; camera and lights.
fn test_scene(root: Transform) -> Scene {
    scene_of(
        vec![
            quad(0.0, 10.0, true),
            box_mesh(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 3.0, 1.0)),
            box_mesh(Vec3::new(2.0, 1.0, 2.0), Vec3::new(3.0, 1.5, 4.0)),
        ],
        root,
    )
}

#[test]
fn masks_do_not_depend_on_offset_or_scale() {
    let base_cam = (DVec3::new(2.0, 9.0, 12.0), DVec3::new(0.0, 0.5, 0.0));
    let lights = [
        test_lamp(),
        Light::Directional {
            direction: DVec3::new(0.4, -1.0, -0.3),
        },
    ];
    let mask_for = |offset: DVec3, scale: f64, light: &Light| {
        let root = Transform::Matrix(
            DMat4::from_translation(offset) * DMat4::from_scale(DVec3::splat(scale)),
        );
        let s = test_scene(root);
        let bvh = TriangleBvh::new(&s);
        let at = |p: DVec3| offset + p * scale;
        let cam = Camera::look_at(
            at(base_cam.0),
            at(base_cam.1),
            DVec3::Y,
            50f64.to_radians(),
            4.0 / 3.0,
            0.05 * scale,
        )
        .unwrap();
        let l = match *light {
            Light::Point { position, range } => Light::Point {
                position: at(position),
                range,
            },
            other => other,
        };
        mask(&bvh, &cam, &l, 200, 150)
    };
    for light in &lights {
        let base = mask_for(DVec3::ZERO, 1.0, light);
        assert!(base.counts.classes.shadow > 200, "{:?}", base.counts);
        for (offset, scale) in [
            (DVec3::new(1e5, -3e4, 1e5), 1.0),
            (DVec3::new(1e6, 1e6, -1e6), 1.0),
            (DVec3::ZERO, 1e-3),
            (DVec3::ZERO, 1e3),
            (DVec3::splat(1e6), 1e3),
        ] {
            let other = mask_for(offset, scale, light);
            let c = compare(&base.mask, &base.ambiguous, &other.mask);
            assert!(
                c.mismatches * 2000 <= c.compared,
                "offset {offset} scale {scale}: {} of {} pixels differ",
                c.mismatches,
                c.compared
            );
        }
    }
}

#[test]
fn deterministic_across_thread_counts() {
    let s = test_scene(Transform::default());
    let bvh = TriangleBvh::new(&s);
    let cam = test_camera();
    let light = test_lamp();
    let a = mask(&bvh, &cam, &light, 200, 150);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one.install(|| mask(&bvh, &cam, &light, 200, 150));
    assert_eq!(a.mask, b.mask);
    assert_eq!(a.ambiguous, b.ambiguous);
    assert_eq!(a.primitive, b.primitive);
}

#[test]
fn given_eye_surface_gives_the_same_mask() {
    let s = test_scene(Transform::default());
    let bvh = TriangleBvh::new(&s);
    let cam = test_camera();
    let light = Light::Directional {
        direction: DVec3::new(0.4, -1.0, -0.3),
    };
    let a = mask(&bvh, &cam, &light, 200, 150);
    let b = reference_mask(
        &bvh,
        &cam,
        &light,
        200,
        150,
        &ReferenceOptions::default(),
        Some(EyeSurface::from_rows(200, &a.primitive, None)),
    );
    let c = compare(&a.mask, &a.ambiguous, &b.mask);
    assert_eq!(c.mismatches, 0);
    assert_eq!(a.mask.counts(), b.mask.counts());
}

#[test]
fn refit_after_moving_matches_a_rebuild() {
    let mut s = test_scene(Transform::default());
    let mut bvh = TriangleBvh::new(&s);
    let cam = test_camera();
    let light = test_lamp();
    let before = mask(&bvh, &cam, &light, 160, 120);
    s.set_object_transform(
        ObjectId::from_slot(1),
        DMat4::from_translation(DVec3::new(3.0, 0.0, -2.0)),
    )
    .unwrap();
    bvh.refit(&s);
    let refit = mask(&bvh, &cam, &light, 160, 120);
    let rebuilt = reference_mask(
        &TriangleBvh::new(&s),
        &cam,
        &light,
        160,
        120,
        &ReferenceOptions::default(),
        None,
    );
    assert_eq!(refit.mask, rebuilt.mask);
    assert_ne!(
        before.mask, refit.mask,
        "moving the box must move its shadow"
    );
}

#[test]
fn spot_cone_and_range_make_pixels_unlit() {
    let s = test_scene(Transform::default());
    let bvh = TriangleBvh::new(&s);
    let cam = Camera::look_at(
        DVec3::new(0.0, 14.0, 14.0),
        DVec3::ZERO,
        DVec3::Y,
        60f64.to_radians(),
        1.0,
        0.05,
    )
    .unwrap();
    let spot = Light::Spot {
        position: DVec3::new(0.0, 8.0, 0.0),
        direction: DVec3::NEG_Y,
        apex_angle: 40f64.to_radians(),
        range: None,
    };
    let r = mask(&bvh, &cam, &spot, 120, 120);
    // Ground outside the cone's footprint (radius 8·tan 20° ≈ 2.9) is unlit.
    assert!(
        r.counts.classes.unlit > r.counts.classes.lit,
        "{:?}",
        r.counts
    );
    for (i, c) in r.mask.pixels.iter().enumerate() {
        if *c == PixelClass::Lit {
            let (obj, _) = r.primitive[i].unwrap();
            assert!(obj.slot() <= 2);
        }
    }
}

#[test]
fn coplanar_casters_do_not_shadow_their_plane() {
    // A light-facing quad lying exactly on the ground: no shadow acne either way.
    let s = scene_of(
        vec![quad(0.0, 10.0, true), quad(0.0, 2.0, true)],
        Transform::default(),
    );
    let bvh = TriangleBvh::new(&s);
    let cam = view_from(DVec3::new(0.0, 6.0, 8.0));
    let light = Light::Point {
        position: DVec3::new(1.0, 5.0, 0.0),
        range: None,
    };
    let r = mask(&bvh, &cam, &light, 160, 120);
    assert_eq!(r.counts.classes.shadow, 0, "{:?}", r.counts);
    assert!(r.counts.classes.lit > 5000);
}

#[test]
fn ambiguous_pixels_lie_on_shadow_boundaries_under_grazing_light() {
    let s = test_scene(Transform::default());
    let bvh = TriangleBvh::new(&s);
    let cam = test_camera();
    // The sun 0.5° above the horizon: long shadows, grazing incidence on the ground.
    let e = 0.5f64.to_radians();
    let light = Light::Directional {
        direction: -DVec3::new(e.cos() * 0.6, e.sin(), e.cos() * 0.8),
    };
    let r = mask(&bvh, &cam, &light, 200, 150);
    assert!(r.counts.classes.shadow > 300, "{:?}", r.counts);
    let (w, h) = (200i64, 150i64);
    for (i, &a) in r.ambiguous.iter().enumerate() {
        if !a {
            continue;
        }
        let (x, y) = (i as i64 % w, i as i64 / w);
        let c = r.mask.pixels[i];
        let near_boundary = (-2..=2).any(|dy| {
            (-2..=2).any(|dx| {
                let (nx, ny) = (x + dx, y + dy);
                nx >= 0 && ny >= 0 && nx < w && ny < h && r.mask.pixels[(ny * w + nx) as usize] != c
            })
        });
        assert!(
            near_boundary,
            "ambiguous pixel ({x}, {y}) is far from any class boundary"
        );
    }
    println!("grazing sun: {:?}", r.counts);
}

#[test]
fn a_point_exactly_on_a_shadow_boundary_is_ambiguous() {
    // The light lies in the plane x = 1 of the box's +X face, so the shadow
    // boundary on the ground is the line x = 1. The centre pixel of an odd-sized
    // image looks exactly at (1, 0, 0), obliquely: moving ±δ along its eye ray
    // crosses the boundary, so the pixel must be ambiguous (and excluded).
    let s = scene_of(
        vec![
            quad(0.0, 10.0, true),
            box_mesh(Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, 2.0, 1.0)),
        ],
        Transform::default(),
    );
    let bvh = TriangleBvh::new(&s);
    let light = Light::Point {
        position: DVec3::new(1.0, 5.0, 0.0),
        range: None,
    };
    let cam = Camera::look_at(
        DVec3::new(5.0, 4.0, 0.5),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::Y,
        40f64.to_radians(),
        101.0 / 75.0,
        0.05,
    )
    .unwrap();
    let r = mask(&bvh, &cam, &light, 101, 75);
    let centre = 37 * 101 + 50;
    assert!(
        r.ambiguous[centre],
        "centre pixel must be ambiguous: {:?}",
        r.counts
    );
    assert!(
        r.counts.classes.shadow > 100 && r.counts.classes.lit > 100,
        "{:?}",
        r.counts
    );
    // Its neighbours across the boundary are decided and differ.
    let left = r.mask.pixels[centre - 2];
    let right = r.mask.pixels[centre + 2];
    assert_ne!(left, right, "the boundary runs through the centre column");
    let c = compare(&r.mask, &r.ambiguous, &r.mask);
    assert_eq!(c.ambiguous, r.counts.ambiguous);
}
