//! Tests of the box-city loader (`citysc 1`): counts and exact geometry of the
//! benchmark cities, cameras, light and paths, and errors naming the line.

use glam::{DVec3, Vec3};
use scene::load::box_city::{load_box_city, load_box_city_str};
use scene::load::{load_path, Loaded};
use scene::procedural::analytic::{box_corners, box_triangles};
use scene::{CameraPath, Error, Light, ObjectId, Scene};
use std::path::{Path, PathBuf};

fn bench(name: &str) -> Option<PathBuf> {
    Some(testkit::shared_data()?.join("bench").join(name))
}

fn path<'a>(l: &'a Loaded, name: &str) -> &'a CameraPath {
    &l.paths.iter().find(|(n, _)| n == name).expect("path").1
}

fn box_lines(text: &str) -> Vec<[f64; 6]> {
    let mut lines = text.lines().skip_while(|l| !l.starts_with("boxes"));
    lines.next();
    lines
        .take_while(|l| *l != "end")
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|s| s.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4], v[5]]
        })
        .collect()
}

#[test]
fn box_city_4096_counts_geometry_cameras_and_paths() {
    let Some(file) = bench("city_4096.txt") else {
        return;
    };
    let loaded = load_box_city(&file).unwrap();
    assert_eq!(
        loaded.lights,
        vec![(
            "light".to_string(),
            Light::Point {
                position: DVec3::new(704.0, 640.0, 576.0),
                range: None
            }
        )]
    );
    let names: Vec<&str> = loaded.cameras.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["street", "bird"]);
    let street = loaded.cameras[0].1;
    assert_eq!(street.eye, DVec3::new(640.0, 1.70000005, 960.0));
    assert_eq!(street.target, DVec3::new(640.0, 1.70000005, 0.0));
    assert_eq!((street.fov_y_deg, street.near), (60.0, 0.5));
    let bird = loaded.cameras[1].1;
    assert_eq!(bird.eye, DVec3::new(640.0, 640.0, 1536.0));
    assert_eq!(bird.near, 5.0);
    assert!(
        loaded.graph.warnings().is_empty(),
        "{:?}",
        loaded.graph.warnings()
    );

    let text = std::fs::read_to_string(&file).unwrap();
    let boxes = box_lines(&text);
    let scene = Scene::new(loaded.graph.clone()).unwrap();
    let c = scene.counts();
    println!("city_4096: {c:?}, bounds {:?}", scene.bounds());
    assert_eq!(c.objects, 4097);
    assert_eq!(c.triangles, 4096 * 12 + 2);
    assert_eq!(c.topology.boundary_edges, 4, "only the ground is open");
    assert_eq!(
        c.topology.inconsistent_edges + c.topology.degenerate_triangles,
        0
    );

    // Boxes 0, 1 and the last in world space are exactly their lines' numbers,
    // triangle by triangle in the README's order.
    for k in [0, 1, 4095] {
        let b = boxes[k];
        let (min, max) = (
            Vec3::new(b[0] as f32, b[1] as f32, b[2] as f32),
            Vec3::new(b[3] as f32, b[4] as f32, b[5] as f32),
        );
        let corners = box_corners(min, max);
        let o = scene.object(ObjectId::from_slot(k as u32));
        assert_eq!(o.world_bounds.min, min);
        assert_eq!(o.world_bounds.max, max);
        for (t, tri) in box_triangles().iter().enumerate() {
            let want = tri.map(|i| corners[i as usize].as_dvec3());
            assert_eq!(
                scene.world_triangle(ObjectId::from_slot(k as u32), t),
                want,
                "box {k} triangle {t}"
            );
        }
    }
    assert_eq!(boxes[0], [4.25, 0.0, 5.25, 14.75, 44.75, 12.0]);
    // The ground: last object, 2 triangles facing up.
    let g = ObjectId::from_slot(4096);
    for t in 0..2 {
        let [a, b, c] = scene.world_triangle(g, t);
        let n = (b - a).cross(c - a);
        assert!(n.y > 0.0 && n.x == 0.0 && n.z == 0.0);
    }
    assert_eq!(
        scene.object(g).world_bounds.min,
        Vec3::new(-1280.0, 0.0, -1280.0)
    );
    assert_eq!(
        scene.object(g).world_bounds.max,
        Vec3::new(2560.0, 0.0, 2560.0)
    );

    // Paths: street dollies 1 m/frame toward −z; bird orbits the boxes' centre at 1°/frame.
    let s = path(&loaded, "street");
    for f in [0u32, 1, 10, 99] {
        let p = s.at(f).unwrap();
        assert_eq!(p.eye, street.eye - DVec3::new(0.0, 0.0, f as f64));
        assert_eq!(p.target, street.target - DVec3::new(0.0, 0.0, f as f64));
        assert!(p.camera(4.0 / 3.0).is_ok());
    }
    let lo = boxes
        .iter()
        .fold(DVec3::INFINITY, |m, b| m.min(DVec3::new(b[0], b[1], b[2])));
    let hi = boxes.iter().fold(DVec3::NEG_INFINITY, |m, b| {
        m.max(DVec3::new(b[3], b[4], b[5]))
    });
    let centre = DVec3::new(0.5 * (lo.x + hi.x), 0.0, 0.5 * (lo.z + hi.z));
    let CameraPath::Orbit {
        center,
        deg_per_frame,
        ..
    } = *path(&loaded, "bird")
    else {
        panic!("bird is not an orbit")
    };
    assert_eq!((center, deg_per_frame), (centre, 1.0));
    let b = path(&loaded, "bird");
    let r0 = bird.eye - centre;
    for f in [1u32, 45, 90, 360] {
        let p = b.at(f).unwrap();
        let r = p.eye - centre;
        assert!((r.y - r0.y).abs() < 1e-9);
        let angle = (r0.x * r.z - r0.z * r.x)
            .atan2(r0.x * r.x + r0.z * r.z)
            .to_degrees();
        // Counter-clockwise seen from above is a negative angle in (x, z).
        let want = -(f as f64 % 360.0);
        let diff = (angle - want + 540.0).rem_euclid(360.0) - 180.0;
        assert!(diff.abs() < 1e-6, "frame {f}: turned {angle}°");
        assert!((r.length() - r0.length()).abs() < 1e-9);
        assert!(p.camera(4.0 / 3.0).is_ok());
    }

    // load_path dispatches .txt to this loader.
    assert_eq!(
        Scene::new(load_path(&file).unwrap().graph)
            .unwrap()
            .counts()
            .objects,
        4097
    );
}

#[test]
fn box_city_16384_counts() {
    let Some(file) = bench("city_16384.txt") else {
        return;
    };
    let loaded = load_box_city(&file).unwrap();
    let scene = Scene::new(loaded.graph).unwrap();
    let c = scene.counts();
    println!("city_16384: {c:?}, bounds {:?}", scene.bounds());
    assert_eq!(c.objects, 16385);
    assert_eq!(c.triangles, 16384 * 12 + 2);
    assert_eq!(
        loaded.lights[0].1.position(),
        Some(DVec3::new(1408.0, 1280.0, 1152.0))
    );
    assert_eq!(loaded.paths.len(), 2);
}

#[test]
fn box_city_truncations_are_errors_not_panics() {
    let Some(file) = bench("city_4096.txt") else {
        return;
    };
    let bytes = std::fs::read(&file).unwrap();
    let n = bytes.len();
    let mut cuts: Vec<usize> = vec![
        0,
        1,
        5,
        9,
        10,
        40,
        200,
        1000,
        3000,
        3001,
        3002,
        n / 2,
        n - 10,
        n - 5,
        n - 4,
        n - 3,
        n - 2,
    ];
    cuts.extend((1..40).map(|i| i * n / 40 + i));
    for cut in cuts.into_iter().filter(|&c| c < n) {
        let text = String::from_utf8_lossy(&bytes[..cut]);
        match load_box_city_str(&text, &file) {
            Err(Error::Load {
                file: f, element, ..
            }) => {
                assert_eq!(f, file);
                assert!(element.starts_with("line "), "cut {cut}: {element}");
            }
            Err(e) => panic!("cut {cut}: unexpected error kind {e}"),
            Ok(_) => panic!("cut {cut}: truncated file loaded"),
        }
    }
    // Only the final newline missing: still complete.
    assert!(load_box_city_str(std::str::from_utf8(&bytes[..n - 1]).unwrap(), &file).is_ok());
    let trimmed = std::str::from_utf8(&bytes).unwrap().trim_end();
    assert!(load_box_city_str(trimmed, &file).is_ok());
}

const SMALL: &str = "citysc 1
# a comment
seed 7
grid 2 pitch 20 street 8
ground -10 0 -10 50 0 50
light 13 40 5.25
camera street 800 600 eye 10 1.7 30 target 10 1.7 0 up 0 1 0 fovy 60 near 0.5 far inf eps 1e-6
view street 800 600 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1
camera street 1280 1024 eye 99 1.7 30 target 10 1.7 0 up 0 1 0 fovy 60 near 0.5 far inf eps 1e-6
camera bird 800 600 eye 20 40 60 target 20 0 20 up 0 1 0 fovy 60 near 5 far inf eps 1e-6
boxes 2
0 0 0 4 10 4
30 0 20 40 5.5 28
end
";

fn small_err(text: &str) -> (String, String) {
    match load_box_city_str(text, Path::new("small.txt")) {
        Err(Error::Load {
            file,
            element,
            message,
        }) => {
            assert_eq!(file, PathBuf::from("small.txt"));
            (element, message)
        }
        Err(e) => panic!("unexpected error kind: {e}"),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}

#[test]
fn box_city_small_file_loads() {
    let l = load_box_city_str(SMALL, Path::new("small.txt")).unwrap();
    assert_eq!(l.cameras.len(), 2);
    assert_eq!(l.cameras[0].1.eye.x, 10.0, "first camera of a name wins");
    let CameraPath::Orbit { center, .. } = *path(&l, "bird") else {
        panic!()
    };
    assert_eq!(center, DVec3::new(20.0, 0.0, 14.0));
    let s = Scene::new(l.graph).unwrap();
    assert_eq!((s.counts().objects, s.counts().triangles), (3, 26));
    assert_eq!(s.bounds().min, Vec3::new(-10.0, 0.0, -10.0));
    assert_eq!(s.bounds().max, Vec3::new(50.0, 10.0, 50.0));
}

#[test]
fn box_city_malformed_input_names_the_line() {
    let cases: [(&str, &str, &str, &str); 13] = [
        ("bad header", "citysc 1", "citysx 1", "line 1"),
        ("bad version", "citysc 1", "citysc 2", "line 1"),
        ("box count too high", "boxes 2", "boxes 3", "line 14"),
        ("box count too low", "boxes 2", "boxes 1", "line 13"),
        (
            "non-numeric box field",
            "30 0 20 40 5.5 28",
            "30 0 20 4o 5.5 28",
            "line 13",
        ),
        ("NaN in a box", "0 0 0 4 10 4", "0 0 NaN 4 10 4", "line 12"),
        ("infinite box", "0 0 0 4 10 4", "0 0 0 4 inf 4", "line 12"),
        (
            "min above max",
            "30 0 20 40 5.5 28",
            "30 0 29 40 5.5 28",
            "line 13",
        ),
        ("flat box", "0 0 0 4 10 4", "0 0 0 4 0 4", "line 12"),
        ("short box line", "0 0 0 4 10 4", "0 0 0 4 10", "line 12"),
        (
            "non-numeric light",
            "light 13 40 5.25",
            "light 13 forty 5.25",
            "line 6",
        ),
        (
            "camera eye = target",
            "eye 20 40 60 target",
            "eye 20 0 20 target",
            "line 10",
        ),
        ("unknown keyword", "seed 7", "sede 7", "line 3"),
    ];
    for (what, from, to, line) in cases {
        assert!(SMALL.contains(from), "{what}");
        let (element, message) = small_err(&SMALL.replacen(from, to, 1));
        assert_eq!(element, line, "{what}: {message}");
        println!("{what}: {element}: {message}");
    }
    let (element, message) = small_err(SMALL.trim_end().strip_suffix("end").unwrap());
    assert_eq!(element, "line 13");
    assert!(message.contains("end"), "{message}");
    let (element, _) = small_err(&format!("{SMALL}0 0 0 1 1 1\n"));
    assert_eq!(element, "line 15");
    let (element, _) = small_err("");
    assert_eq!(element, "line 1");
    let (element, _) = small_err(&SMALL.replace("boxes 2", "boxes 99999999999999999999999"));
    assert_eq!(element, "line 11");
    let (element, _) = small_err(&SMALL.replace("boxes 2", "boxes 1000000"));
    assert_eq!(element, "line 11");
    let (element, _) =
        small_err(&SMALL.replace("ground -10 0 -10 50 0 50", "ground -10 0 -10 50 1 50"));
    assert_eq!(element, "line 5");
}

#[test]
fn box_city_unreadable_or_binary_files_are_errors() {
    let missing = Path::new("/nonexistent/city.txt");
    assert!(matches!(load_box_city(missing), Err(Error::Io { .. })));
    let dir = testkit::scratch_dir("box-city");
    let file = dir.join("binary.txt");
    std::fs::write(&file, b"citysc 1\nseed 7\n\xff\xfe\n").unwrap();
    let result = load_box_city(&file);
    drop(dir);
    match result {
        Err(Error::Load {
            element, message, ..
        }) => {
            assert_eq!(element, "line 3");
            assert!(message.contains("UTF-8"));
        }
        other => panic!("expected a UTF-8 error, got {other:?}"),
    }
}
