//! Tests of the OBJ loader: counts and topology of the shared scenes and
//! meshes, every edge-case file of `edge_obj/` (no panics, named errors,
//! specific outcomes), and small in-memory files for each guarded tobj quirk.

use glam::DVec3;
use scene::load::obj::{load_obj, load_obj_bytes, load_obj_dir};
use scene::{Error, Scene, SceneCounts, SceneGraph};
use std::path::{Path, PathBuf};

fn data(rel: &str) -> Option<PathBuf> {
    Some(testkit::shared_data()?.join(rel))
}

fn scene(graph: SceneGraph) -> Scene {
    Scene::new(graph).expect("flattening a loaded OBJ")
}

fn counts(graph: SceneGraph) -> SceneCounts {
    scene(graph).counts()
}

fn load_str(text: &str) -> scene::Result<SceneGraph> {
    load_obj_bytes(text.as_bytes(), Path::new("mem/test.obj"))
}

/// Twice the vector area of a triangle.
fn tri_normal(t: [glam::Vec3; 3]) -> DVec3 {
    let [a, b, c] = t.map(|p| p.as_dvec3());
    (b - a).cross(c - a)
}

fn total_area(graph: &SceneGraph) -> f64 {
    graph
        .meshes()
        .iter()
        .flat_map(|m| {
            (0..m.triangles().len()).map(move |t| tri_normal(m.triangle(t)).length() / 2.0)
        })
        .sum()
}

fn assert_load_error_at(result: scene::Result<SceneGraph>, file: &str, line: usize) -> String {
    match result {
        Err(e @ Error::Load { .. }) => {
            let text = e.to_string();
            assert!(text.contains(file), "error does not name {file}: {text}");
            assert!(
                text.contains(&format!("line {line}:")),
                "error does not name line {line}: {text}"
            );
            text
        }
        other => panic!("expected a load error at line {line}, got {other:?}"),
    }
}

// ---------------------------------------------------------------- scenes

#[test]
fn procedural_city_has_498_objects_and_the_readme_triangles() {
    let Some(file) = data("scenes/procedural_city/city.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
    let names: Vec<String> = graph.nodes().iter().map(|n| n.name.clone()).collect();
    let s = scene(graph);
    let c = s.counts();
    println!("city.obj: {c:?}, bounds {:?}", s.bounds());
    // 498 `g` groups; tobj splits them further at its 1,486 `usemtl` lines,
    // which the loader never passes on (and would merge back).
    assert_eq!(c.objects, 498);
    assert_eq!(c.meshes, 498);
    // README: 7,148 = 700 triangles + 2 × 3,224 quads, fanned. Checked in
    // Python (vertices welded by f32 value per group): 83 quads are zero-area
    // roofs written as `a b b a` — their 166 triangles are dropped as
    // degenerate, without a warning — and 2 quads (lines 33052–33053) repeat
    // their last corner, so they are triangles: the CDT makes 1 triangle of
    // each where the fan makes 2, one degenerate. 7,148 − 166 − 2 = 6,980
    // with f32 world positions. The loader recentres the buildings (near
    // 1e7, where f32 spacing is 1) from the file's f64 values, which keeps 2
    // more: triangles 13 and 15 of `b_54e7512f`, whose corners at
    // y = 9,857,572.46 and 9,857,571.53 are one point in f32 world coordinates.
    assert_eq!(c.drawn_triangles, 6_982);
    assert_eq!(c.triangles, 6_982 + 166, "as loaded, degenerate included");
    assert_eq!(c.topology.degenerate_triangles, 166);
    // Same script, edges counted per group as `Mesh` does: a polygon soup
    // with many faces wound against their neighbours.
    let t = c.topology;
    assert_eq!(
        (t.boundary_edges, t.non_manifold_edges, t.inconsistent_edges),
        (614, 0, 2_462)
    );
    let mut distinct = names.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 498, "group names are distinct");
    // Bounds of the used vertices, measured with Python over the v lines (as f32).
    let b = s.bounds();
    let (min, max) = (b.min.as_dvec3(), b.max.as_dvec3());
    let want_min = DVec3::new(-16.0, -16.0, -0.05f32 as f64);
    let want_max = DVec3::new(258_370.593_75, 9_857_740.0, 142.31f32 as f64);
    for (got, want) in [(min, want_min), (max, want_max)] {
        assert!(
            (got - want).abs().max_element() <= 1e-6 * want.abs().max_element(),
            "bounds {b:?}"
        );
    }
}

#[test]
fn cornell_box_directory_has_8_objects_and_15906_triangles() {
    let Some(dir) = data("scenes/cornell_box_multifile") else {
        return;
    };
    let graph = load_obj_dir(&dir).unwrap();
    let names: Vec<String> = graph.nodes().iter().map(|n| n.name.clone()).collect();
    let c = counts(graph);
    println!("cornell_box_multifile: {c:?}, objects {names:?}");
    assert_eq!(c.objects, 8);
    assert_eq!(c.drawn_triangles + c.topology.degenerate_triangles, 15_906);
    assert_eq!(c.triangles, 15_906);
    // Files in name order: cbox_back, cbox_ceiling, ..., glass_sphere last.
    assert_eq!(names.len(), 8);
    assert!(names[0].to_lowercase().contains("back"), "{names:?}");
    assert!(names[7].to_lowercase().contains("sphere"), "{names:?}");
}

// ---------------------------------------------------------------- meshes

/// One row of `../shared/data/README.md` (meshes table) plus the topology the
/// loader must report after welding.
struct MeshCase {
    name: &'static str,
    readme_triangles: usize,
    boundary: usize,
    non_manifold: usize,
    inconsistent: usize,
}

// Closed meshes: README and welding agree (0/0/0). The open meshes were
// re-counted with a Python script over the raw files (vertices welded by f32
// value, faces triangulated, degenerate triangles dropped, edges counted as
// `Mesh` does):
// - stanford-bunny, alligator, woody: welding changes nothing; README's
//   223 / 433 / 119 boundary edges stand.
// - teapot: README counts 1,036 boundary edges by index, but its 4 patches
//   repeat seam vertices at identical coordinates; welded, 160 remain.
// - suzanne: README (by index, fan) has 42 boundary edges, 1 non-manifold
//   edge and 2 directed edges occurring twice (`Mesh` counts that as 1
//   inconsistent undirected edge). The fin is not in the file's polygons:
//   faces 143 and 144 (`f 71 197 139 138`, `f 71 138 139 198`) are two
//   non-planar quads folded onto each other along the mid-plane, and the
//   diagonal 71–139 is shared by all four of their triangles. The CDT keeps
//   that diagonal — it is the Delaunay one in each quad's best-fit plane
//   (checked in Python: same Newell projection, incircle test −2.9e−6) — so
//   the count stands; welding merges 2 duplicate vertices and changes no edge.
const MESHES: &[MeshCase] = &[
    MeshCase {
        name: "stanford-bunny",
        readme_triangles: 69_451,
        boundary: 223,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "suzanne",
        readme_triangles: 968,
        boundary: 42,
        non_manifold: 1,
        inconsistent: 1,
    },
    MeshCase {
        name: "teapot",
        readme_triangles: 6_320,
        boundary: 160,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "spot",
        readme_triangles: 5_856,
        boundary: 0,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "cow",
        readme_triangles: 5_804,
        boundary: 0,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "fandisk",
        readme_triangles: 12_946,
        boundary: 0,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "rocker-arm",
        readme_triangles: 20_088,
        boundary: 0,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "cheburashka",
        readme_triangles: 13_334,
        boundary: 0,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "alligator",
        readme_triangles: 5_981,
        boundary: 433,
        non_manifold: 0,
        inconsistent: 0,
    },
    MeshCase {
        name: "woody",
        readme_triangles: 1_267,
        boundary: 119,
        non_manifold: 0,
        inconsistent: 0,
    },
];

#[test]
fn classic_meshes_match_readme_counts_and_topology() {
    let Some(dir) = data("meshes") else { return };
    for case in MESHES {
        let file = dir.join(format!("{}.obj", case.name));
        let graph = load_obj(&file).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            graph.warnings().is_empty(),
            "{}: {:?}",
            case.name,
            graph.warnings()
        );
        assert_eq!(
            graph.nodes()[0].name,
            case.name,
            "object named after the file stem"
        );
        let c = counts(graph);
        println!("{}: {c:?}", case.name);
        assert_eq!(c.objects, 1, "{}", case.name);
        assert_eq!(
            c.drawn_triangles + c.topology.degenerate_triangles,
            case.readme_triangles,
            "{}: triangles + degenerate",
            case.name
        );
        let t = c.topology;
        assert_eq!(
            (t.boundary_edges, t.non_manifold_edges, t.inconsistent_edges),
            (case.boundary, case.non_manifold, case.inconsistent),
            "{}: boundary / non-manifold / inconsistent",
            case.name
        );
    }
}

// ---------------------------------------------------------------- edge_obj

fn obj_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            obj_files(&path, out);
        } else if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
        {
            out.push(path);
        }
    }
}

#[test]
fn every_edge_case_file_loads_or_errors_by_name_without_panicking() {
    let Some(root) = data("edge_obj") else { return };
    let mut files = Vec::new();
    obj_files(&root, &mut files);
    files.sort();
    assert!(files.len() >= 70, "found only {} files", files.len());
    let mut panicked = Vec::new();
    let (mut loaded, mut failed) = (0, 0);
    for file in &files {
        let result = std::panic::catch_unwind(|| load_obj(file).and_then(Scene::new));
        let name = file.file_name().unwrap().to_string_lossy().to_string();
        match result {
            Err(_) => panicked.push(file.display().to_string()),
            Ok(Ok(s)) => {
                loaded += 1;
                let c = s.counts();
                println!(
                    "{name}: {} objects, {} triangles, warnings {:?}",
                    c.objects,
                    c.triangles,
                    s.warnings()
                );
                for w in s.warnings() {
                    assert!(w.contains(&name), "warning without the file name: {w}");
                }
            }
            Ok(Err(e)) => {
                failed += 1;
                assert!(
                    e.to_string().contains(&name),
                    "error without the file name: {e}"
                );
                println!("{name}: {e}");
            }
        }
    }
    println!(
        "edge_obj: {} files, {loaded} loaded, {failed} errors",
        files.len()
    );
    assert!(panicked.is_empty(), "panicked on: {panicked:#?}");
}

fn edge(rel: &str) -> Option<PathBuf> {
    data(&format!("edge_obj/{rel}"))
}

#[test]
fn empty_file_loads_as_an_empty_scene_with_a_warning() {
    // Choice: an empty file is a valid OBJ with nothing in it.
    let Some(file) = edge("assimp/invalid/empty.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(graph
        .warnings()
        .iter()
        .any(|w| w.contains("empty.obj") && w.contains("no faces")));
    assert_eq!(counts(graph).objects, 0);
}

#[test]
fn malformed_files_name_the_bad_line() {
    let Some(file) = edge("assimp/invalid/malformed.obj") else {
        return;
    };
    // `f 4 12 2 1` with 8 vertices.
    let msg = assert_load_error_at(load_obj(&file), "malformed.obj", 23);
    assert!(msg.contains("12"), "{msg}");
    // malformed2.obj has an empty `f` (dropped with a warning) and otherwise loads.
    let Some(file) = edge("assimp/invalid/malformed2.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(graph
        .warnings()
        .iter()
        .any(|w| w.contains("fewer than 3 corners") && w.contains("line 23")));
    assert_eq!(counts(graph).triangles, 10);
}

#[test]
fn non_finite_and_zero_indices_are_errors_naming_the_line() {
    let Some(file) = edge("tinyobjloader/test-nan.obj") else {
        return;
    };
    assert_load_error_at(load_obj(&file), "test-nan.obj", 12); // `v nan -nan nan`
    let Some(file) = edge("tinyobjloader/issue-140-zero-face-idx.obj") else {
        return;
    };
    let msg = assert_load_error_at(load_obj(&file), "issue-140-zero-face-idx.obj", 16);
    assert!(msg.contains("index 0"), "{msg}");
    let Some(file) = edge("tinyobjloader/invalid-relative-vertex-index.obj") else {
        return;
    };
    assert_load_error_at(load_obj(&file), "invalid-relative-vertex-index.obj", 1);
}

#[test]
fn points_and_polylines_load_with_no_triangles_and_a_warning() {
    for rel in [
        "assimp/OBJ/point_cloud.obj",
        "assimp/OBJ/testpoints.obj",
        "assimp/OBJ/testline.obj",
    ] {
        let Some(file) = edge(rel) else { return };
        let graph = load_obj(&file).unwrap();
        let name = file.file_name().unwrap().to_string_lossy().to_string();
        assert!(!graph.warnings().is_empty(), "{name}: no warning");
        assert!(graph.warnings().iter().all(|w| w.contains(&name)));
        assert_eq!(counts(graph).triangles, 0, "{name}");
    }
    // testmixed.obj: 6 `l`, 6 `p` and 6 quad faces.
    let Some(file) = edge("assimp/OBJ/testmixed.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(
        graph
            .warnings()
            .iter()
            .any(|w| w.contains("6 `l`") && w.contains("6 `p`")),
        "{:?}",
        graph.warnings()
    );
    assert_eq!(counts(graph).triangles, 12);
}

#[test]
fn utf16_big_endian_box_has_12_triangles() {
    let Some(file) = edge("assimp/OBJ/box_UTF16BE.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
    let c = counts(graph);
    assert_eq!((c.triangles, c.topology.boundary_edges), (12, 0));
}

#[test]
fn long_face_round_one_quad_gives_a_closed_box() {
    // The first face runs round quad 1 2 3 4 118 times; a fan makes 466 degenerate triangles.
    let Some(file) = edge("assimp/OBJ/box_longline.obj") else {
        return;
    };
    let c = counts(load_obj(&file).unwrap());
    assert_eq!(c.triangles, 12);
    assert_eq!(c.topology.degenerate_triangles, 0);
    // Closed, but that face is wound `1 2 3 4` where box.obj has `4 3 2 1`:
    // its 4 edges are traversed twice in the same direction.
    let t = c.topology;
    assert_eq!(
        (t.boundary_edges, t.non_manifold_edges, t.inconsistent_edges),
        (0, 0, 4)
    );
}

#[test]
fn regr_3429812_has_a_non_manifold_edge() {
    let Some(file) = edge("assimp/OBJ/regr_3429812.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    // Three groups over the same 4 vertices: `rectangle` and two triangles on it.
    assert_eq!(graph.nodes().len(), 3);
    let mut all = scene::SceneGraph::new();
    let mut tris = Vec::new();
    let mut positions = Vec::new();
    for m in graph.meshes() {
        for t in 0..m.triangles().len() {
            let base = positions.len() as u32;
            positions.extend(m.triangle(t));
            tris.push([base, base + 1, base + 2]);
        }
    }
    // Welded into one mesh, the shared diagonal 4–2 is used by 4 triangles.
    all.add_mesh(scene::Mesh::new("all", &positions, &tris).unwrap());
    let merged = &all.meshes()[0];
    assert!(
        merged.topology().non_manifold_edges >= 1,
        "{:?}",
        merged.topology()
    );
    // Per object, the loader keeps the groups apart; the scene sums them.
    let c = counts(graph);
    assert_eq!((c.objects, c.triangles), (3, 4));
}

#[test]
fn spider_and_regr01_have_one_object_per_group() {
    // Counted in Python: spider.obj has 19 `g` lines, all with faces; regr01.obj
    // has 111 `o`/`g` lines of which 55 have faces.
    let Some(file) = edge("assimp/OBJ/spider.obj") else {
        return;
    };
    assert_eq!(counts(load_obj(&file).unwrap()).objects, 19);
    let Some(file) = edge("assimp/OBJ/regr01.obj") else {
        return;
    };
    assert_eq!(counts(load_obj(&file).unwrap()).objects, 55);
}

#[test]
fn concave_66_gon_is_triangulated_by_area_not_by_fan() {
    let Some(file) = edge("assimp/OBJ/concave_polygon.obj") else {
        return;
    };
    let graph = load_obj(&file).unwrap();
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
    // The polygon from the raw file: its Newell vector area.
    let text = std::fs::read_to_string(&file).unwrap();
    let verts: Vec<DVec3> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
        })
        .collect();
    let face: Vec<usize> = text
        .lines()
        .find_map(|l| l.strip_prefix("f "))
        .unwrap()
        .split_whitespace()
        .map(|t| t.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
        .collect();
    assert_eq!(face.len(), 66);
    let p: Vec<DVec3> = face.iter().map(|&i| verts[i]).collect();
    let normal: DVec3 = (0..66).map(|i| p[i].cross(p[(i + 1) % 66])).sum();
    let area = normal.length() / 2.0;
    let fan: f64 = (1..65)
        .map(|i| (p[i] - p[0]).cross(p[i + 1] - p[0]).length() / 2.0)
        .sum();
    println!(
        "concave_polygon: area {area}, fan {fan} ({:.1}x)",
        fan / area
    );
    assert!(
        fan > 10.0 * area,
        "the fan is the wrong answer this test guards against"
    );

    let mesh = &graph.meshes()[0];
    assert_eq!(mesh.triangles().len(), 64);
    let got = total_area(&graph);
    assert!(
        (got - area).abs() <= 1e-4 * area,
        "area {got} vs polygon {area}"
    );
    for t in 0..64 {
        assert!(
            tri_normal(mesh.triangle(t)).dot(normal) > 0.0,
            "triangle {t} flipped"
        );
    }
}

// ---------------------------------------------------------------- in memory

const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

#[test]
fn negative_indices_are_relative_to_the_vertices_so_far() {
    let text = format!("{SQUARE}f -4 -3 -2 -1\nv 5 5 5\nf -5 -4 -1\n");
    let graph = load_str(&text).unwrap();
    let m = &graph.meshes()[0];
    assert_eq!(m.triangles().len(), 3);
    // The last triangle is (0,0,0) (1,0,0) (5,5,5).
    let last = m.triangle(2);
    assert_eq!(last[2], glam::Vec3::splat(5.0));
    assert_eq!(total_area(&graph) - 1.0, tri_normal(last).length() / 2.0);
}

#[test]
fn faces_before_any_group_take_the_file_stem_and_groups_split_objects() {
    let text = format!("{SQUARE}f 1 2 3\ng roof\nf 1 3 4\no wall\ng\nf 2 3 4\ng roof\nf 1 2 4\n");
    let graph = load_str(&text).unwrap();
    let names: Vec<&str> = graph.nodes().iter().map(|n| n.name.as_str()).collect();
    // A bare `g` is the default group, named after the file stem too.
    assert_eq!(names, ["test", "roof", "test", "roof"]);
    assert_eq!(
        graph.meshes().iter().map(|m| m.name()).collect::<Vec<_>>(),
        names
    );
}

#[test]
fn consecutive_groups_of_one_name_are_one_object() {
    let text =
        format!("{SQUARE}g a\nusemtl red\nf 1 2 3\nusemtl blue\nf 1 3 4\ng b\ng a\nf 1 2 4\n");
    let graph = load_str(&text).unwrap();
    assert_eq!(graph.nodes().len(), 1);
    assert_eq!(graph.meshes()[0].triangles().len(), 3);
}

#[test]
fn byte_order_marks_and_encodings() {
    let body = format!("{SQUARE}f 1 2 3 4\n");
    // UTF-8 BOM: tobj alone would drop the first line (and lose vertex 1).
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(body.as_bytes());
    let g = load_obj_bytes(&bytes, Path::new("bom.obj")).unwrap();
    assert!(g.warnings().is_empty(), "{:?}", g.warnings());
    assert_eq!(total_area(&g), 1.0);
    // UTF-16 LE and BE with BOMs.
    for be in [false, true] {
        let mut bytes = if be {
            vec![0xFE, 0xFF]
        } else {
            vec![0xFF, 0xFE]
        };
        for u in body.encode_utf16() {
            bytes.extend(if be { u.to_be_bytes() } else { u.to_le_bytes() });
        }
        let g = load_obj_bytes(&bytes, Path::new("utf16.obj")).unwrap();
        assert_eq!(total_area(&g), 1.0, "big endian: {be}");
    }
    // A stray Latin-1 byte in a group name: decoded lossily, with a warning.
    let mut bytes = b"g caf\xE9\n".to_vec();
    bytes.extend(body.as_bytes());
    let g = load_obj_bytes(&bytes, Path::new("latin1.obj")).unwrap();
    assert_eq!(g.nodes()[0].name, "caf\u{FFFD}");
    assert!(g.warnings()[0].contains("latin1.obj"));
}

#[test]
fn concave_l_shaped_hexagon_has_four_triangles_of_exact_area() {
    let text = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 1 2 3 4 5 6\n";
    let graph = load_str(text).unwrap();
    let m = &graph.meshes()[0];
    assert_eq!(m.triangles().len(), 4);
    assert_eq!(total_area(&graph), 3.0);
    for t in 0..4 {
        assert!(
            tri_normal(m.triangle(t)).z > 0.0,
            "counter-clockwise face, triangle {t}"
        );
    }
    // No triangle covers the missing corner square (1..2, 1..2).
    for t in 0..4 {
        let c = m.triangle(t).iter().sum::<glam::Vec3>() / 3.0;
        assert!(!(c.x > 1.0 && c.y > 1.0), "triangle {t} outside the L");
    }
}

#[test]
fn clockwise_face_keeps_clockwise_winding() {
    let text = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 6 5 4 3 2 1\n";
    let graph = load_str(text).unwrap();
    let m = &graph.meshes()[0];
    assert_eq!(m.triangles().len(), 4);
    for t in 0..4 {
        assert!(
            tri_normal(m.triangle(t)).z < 0.0,
            "clockwise face, triangle {t}"
        );
    }
    // A clockwise triangle stays as written too.
    let g = load_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 3 2\n").unwrap();
    assert!(tri_normal(g.meshes()[0].triangle(0)).z < 0.0);
}

#[test]
fn bad_coordinates_are_errors_naming_the_line() {
    for (v, what) in [
        ("1.#INF 0 0", "1.#INF"),
        ("nan 0 0", "nan"),
        ("0 inf 0", "inf"),
        ("0 1e39 0", "1e39"),
        ("0 x 0", "x"),
        ("0 0", "2"),
    ] {
        let text = format!("# header\nv 0 0 0\nv {v}\n");
        let msg = assert_load_error_at(load_str(&text), "test.obj", 3);
        println!("{v}: {msg}");
        let _ = what;
    }
    // w = 0 divides by zero.
    assert_load_error_at(load_str("v 1 2 3 0\n"), "test.obj", 1);
    // A homogeneous w is divided out; vertex colors are ignored.
    let g = load_str("v 2 0 0 2\nv 0 1 0 1 0.5 0.5\nv 0 0 0 0.5 0.5 0.5\nf 1 2 3\n").unwrap();
    assert_eq!(total_area(&g), 0.5);
}

#[test]
fn bad_face_indices_are_errors_naming_the_line() {
    let cases = [
        ("f 1 2 0", "index 0"),
        ("f 1 2 5", "out of range"),
        ("f 1 2 -5", "out of range"),
        ("f 1 2 x", "cannot parse"),
        ("f 1 2 3/", ""),
    ];
    for (f, needle) in cases {
        let text = format!("{SQUARE}\n{f}\n");
        let result = load_str(&text);
        if f == "f 1 2 3/" {
            assert!(
                result.is_ok(),
                "`3/` is vertex 3 with an empty texture slot"
            );
            continue;
        }
        let msg = assert_load_error_at(result, "test.obj", 6);
        assert!(msg.contains(needle), "{f}: {msg}");
    }
    // An index that refers to a vertex defined only later is out of range too.
    assert_load_error_at(
        load_str("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n"),
        "test.obj",
        3,
    );
}

#[test]
fn out_of_range_texture_and_normal_indices_are_ignored() {
    // tobj (debug) panics on these; only positions matter here.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/9/9 2/-7/-7 3//42\n";
    let g = load_str(text).unwrap();
    assert_eq!(total_area(&g), 0.5);
}

#[test]
fn continuation_lines_comments_and_crlf() {
    let text = "v 0 0 0 # origin\r\nv 1 \\\r\n 0 0\r\nv 0 1 0\r\nf 1 \\\n2 \\\n3\r\n# done\r\nv 9 9 9\r\nf 1 2 x\r\n";
    // Lines 2–3 and 5–7 are one logical line each; the bad face is physical line 10.
    assert_load_error_at(load_str(text), "test.obj", 10);
    let ok = &text[..text.find("# done").unwrap()];
    let g = load_str(ok).unwrap();
    assert_eq!(total_area(&g), 0.5);
}

#[test]
fn polylines_points_and_short_faces_are_dropped_with_one_warning_each() {
    let text = format!("{SQUARE}l 1 2 3\nl 3 4\np 1\np 2 3\nf 1 2\nf 1 2 3 4\n");
    let g = load_str(&text).unwrap();
    let w = g.warnings();
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(
        w[0].contains("2 `l`") && w[0].contains("2 `p`") && w[0].contains("line 5"),
        "{w:?}"
    );
    assert!(
        w[1].contains("1 faces with fewer than 3") && w[1].contains("line 9"),
        "{w:?}"
    );
    assert_eq!(total_area(&g), 1.0);
}

#[test]
fn self_intersecting_face_falls_back_with_a_warning() {
    let text = "v 0 0 0\nv 2 2 0\nv 2 0 0\nv 0 3 0\nf 1 2 3 4\n";
    let g = load_str(text).unwrap();
    assert_eq!(g.meshes()[0].triangles().len(), 2);
    assert!(
        g.warnings()
            .iter()
            .any(|w| w.contains("line 5") && w.contains("ear-clipped")),
        "{:?}",
        g.warnings()
    );
}

#[test]
fn directory_loads_obj_files_case_insensitively_in_name_order() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("obj_dir_test");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    std::fs::write(dir.join("b.OBJ"), format!("o second\n{tri}")).unwrap();
    std::fs::write(dir.join("a.obj"), format!("o first\n{tri}o first_2\n{tri}")).unwrap();
    std::fs::write(dir.join("c.mtl"), "newmtl x\n").unwrap();
    let g = load_obj_dir(&dir).unwrap();
    let names: Vec<&str> = g.nodes().iter().map(|n| n.name.as_str()).collect();
    assert_eq!(names, ["first", "first_2", "second"]);
    // A file error names the file.
    std::fs::write(dir.join("c.obj"), "f 1 2 3\n").unwrap();
    let msg = load_obj_dir(&dir).unwrap_err().to_string();
    assert!(msg.contains("c.obj") && msg.contains("line 1"), "{msg}");
    // A directory without .obj files is an error naming it.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    assert!(load_obj_dir(&empty)
        .unwrap_err()
        .to_string()
        .contains("empty"));
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let err = load_obj(Path::new("/nonexistent/nothing.obj")).unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert!(err.to_string().contains("nothing.obj"));
}

// ---------------------------------------------------------------- recentring

/// A 4 × 2 × 3 box (walls, 10 triangles) and a separate roof group on it,
/// near (2.57e5, 9.857e6, 10) like city.obj's buildings, where an f32 has a
/// spacing of 1 (y) and 1/64 (x). Every coordinate is a multiple of 1/8, so
/// the f64 values, the f64 centre and the small f32 local coordinates are
/// all exact: world positions must come back bit for bit.
const FAR_X: f64 = 257_000.125;
const FAR_Y: f64 = 9_857_000.375;
const FAR_Z: f64 = 10.5;

fn far_box_obj() -> (String, Vec<DVec3>) {
    let mut corners = Vec::new();
    for k in 0..8 {
        let d = DVec3::new(
            if k & 1 == 0 { 0.0 } else { 4.0 },
            if k & 2 == 0 { 0.0 } else { 2.25 },
            if k & 4 == 0 { 0.0 } else { 3.0 },
        );
        corners.push(DVec3::new(FAR_X, FAR_Y, FAR_Z) + d);
    }
    let mut text = String::from("g walls\n");
    for c in &corners {
        text += &format!("v {} {} {}\n", c.x, c.y, c.z);
    }
    // Four walls and the floor (outward, counter-clockwise), then the roof
    // (z = max) as its own group sharing the top corners.
    text += "f 1 3 4 2\nf 1 2 6 5\nf 2 4 8 6\nf 4 3 7 8\nf 3 1 5 7\n";
    text += "g roof\nf 5 6 8 7\n";
    (text, corners)
}

fn write_temp(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("obj_recentre_test");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn far_off_obj_is_recentred_and_round_trips_world_positions() {
    let (text, corners) = far_box_obj();
    let file = write_temp("far_box.obj", &text);
    let graph = load_obj(&file).unwrap();
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
    assert_eq!(graph.nodes().len(), 2);
    let centre = DVec3::new(FAR_X + 2.0, FAR_Y + 1.125, FAR_Z + 1.5);
    for node in graph.nodes() {
        // The translation is in the node, in f64, and is the f64 centre of
        // the walls and roof together (they touch, so they share it).
        let m = node.transform.matrix();
        assert_eq!(m, glam::DMat4::from_translation(centre), "{}", node.name);
        // Local vertices are centred and small.
        let mesh = &graph.meshes()[node.meshes[0].index()];
        for p in mesh.positions() {
            assert!(
                p.abs().cmple(glam::Vec3::new(2.0, 1.125, 1.5)).all(),
                "{}: local vertex {p} is not centred",
                node.name
            );
        }
        let b = mesh.bounds();
        assert!(
            b.center().abs().max_element() <= 1.5,
            "{}: local bounds {b:?}",
            node.name
        );
    }
    // World positions (f64, the one transform path) are the file's exactly,
    // and every file corner is some vertex: nothing was merged by f32
    // rounding at 1e7 (2.25 and 0.375 apart in y would be 0 or 1 there).
    let s = scene(graph);
    let mut seen = Vec::new();
    for (o, obj) in s.objects().iter().enumerate() {
        let mesh = s.object_mesh(scene::ObjectId::from_slot(o as u32));
        for p in mesh.positions() {
            let w = scene::transform::world_point(&obj.world_from_local, *p);
            assert!(corners.contains(&w), "world {w} is not a file corner");
            seen.push(w.to_array().map(f64::to_bits));
        }
    }
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen.len(), 8);
    // Walls and roof share their top corners bit for bit in local space.
    let walls = &s.graph().meshes()[0];
    let roof = &s.graph().meshes()[1];
    for p in roof.positions() {
        assert!(walls.positions().contains(p), "roof corner {p}");
    }
    // World bounds still hold the box.
    let b = s.bounds();
    assert!(b.min.as_dvec3().cmple(corners[0]).all());
    assert!(b.max.as_dvec3().cmpge(corners[7]).all());
}

#[test]
fn far_off_obj_keeps_world_positions_within_f32_of_the_small_local_values() {
    // Values that are not exact in binary: the world position is the f64
    // value of the file up to the f32 rounding of the *local* coordinate
    // (a few metres: about 2.4e-7), not of the world one (spacing 1 at 1e7).
    let text = "v 257318.945 9857572.46 27.9\nv 257318.945 9857571.53 27.9\n\
                v 257320.955 9857574.00 25.28\nv 257316.935 9857574.00 25.28\n\
                f 1 2 3\nf 1 4 2\n";
    let want = [
        DVec3::new(257318.945, 9857572.46, 27.9),
        DVec3::new(257318.945, 9857571.53, 27.9),
        DVec3::new(257320.955, 9857574.00, 25.28),
        DVec3::new(257316.935, 9857574.00, 25.28),
    ];
    let graph = load_obj(&write_temp("far_roof.obj", text)).unwrap();
    let s = scene(graph);
    let id = scene::ObjectId::from_slot(0);
    assert_eq!(s.object_mesh(id).triangles().len(), 2, "none degenerate");
    let got: Vec<DVec3> = (0..2).flat_map(|t| s.world_triangle(id, t)).collect();
    for w in want {
        let err = got
            .iter()
            .map(|g| (*g - w).abs().max_element())
            .fold(f64::INFINITY, f64::min);
        assert!(err <= 3.0 * 2f64.powi(-24), "{w}: off by {err}");
    }
}

#[test]
fn obj_near_its_origin_is_not_moved() {
    // Centre 0.5 away, radius 0.5: kept bit for bit with an identity transform.
    let g = load_str("v 0.1 0.2 0.3\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(g.nodes()[0].transform, scene::Transform::default());
    assert!(g.meshes()[0]
        .positions()
        .contains(&glam::Vec3::new(0.1, 0.2, 0.3)));
    // Far groups in one file are moved; near ones are not.
    let g = load_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1e6 0 0\nv 1000001 0 0\nv 1e6 1 0\ng near\nf 1 2 3\ng far\nf 4 5 6\n").unwrap();
    assert_eq!(g.nodes()[0].transform, scene::Transform::default());
    assert_eq!(
        g.nodes()[1].transform.matrix().w_axis.truncate(),
        DVec3::new(1e6 + 0.5, 0.5, 0.0)
    );
}

// ---------------------------------------------------------------- fuzzing

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    fn number() -> impl Strategy<Value = String> {
        prop_oneof![
            6 => (-8i32..8).prop_map(|i| i.to_string()),
            3 => (-100.0f32..100.0).prop_map(|x| x.to_string()),
            1 => prop::sample::select(vec!["nan", "-inf", "1e39", "-0", "1.#INF", ".5", "5.", "1e-45", "x"])
                .prop_map(str::to_string),
        ]
    }

    fn corner() -> impl Strategy<Value = String> {
        (
            (-12i64..12),
            prop::sample::select(vec!["", "/", "/1", "/-9", "//3", "/2/99"]),
        )
            .prop_map(|(i, rest)| format!("{i}{rest}"))
    }

    fn line() -> impl Strategy<Value = String> {
        prop_oneof![
            5 => prop::collection::vec(number(), 0..6).prop_map(|v| format!("v {}", v.join(" "))),
            5 => prop::collection::vec(corner(), 0..9).prop_map(|c| format!("f {}", c.join(" "))),
            1 => prop::sample::select(vec![
                "g", "g a", "o b", "g a # comment", "l 1 2 3", "p 1 -1", "vt 0 0", "vn 0 0 1",
                "usemtl", "mtllib missing.mtl", "s off", "# f 1 2 3", "f 1 2 \\", "", "  \t",
                "\u{FEFF}v 1 2 3", "curv 0 1 1 2",
            ])
            .prop_map(str::to_string),
        ]
    }

    proptest! {
        #![proptest_config(testkit::proptest_config(512))]

        /// Random OBJ-like text: loads (and flattens) or fails with an error
        /// naming the file and a line that exists; never panics.
        #[test]
        fn obj_like_text_never_panics(lines in prop::collection::vec(line(), 0..40), crlf in any::<bool>()) {
            let text = lines.join(if crlf { "\r\n" } else { "\n" });
            match load_obj_bytes(text.as_bytes(), Path::new("fuzz.obj")) {
                Ok(graph) => {
                    let s = Scene::new(graph).unwrap();
                    for w in s.warnings() {
                        prop_assert!(w.contains("fuzz.obj"));
                    }
                }
                Err(Error::Load { file, element, .. }) => {
                    prop_assert_eq!(file, PathBuf::from("fuzz.obj"));
                    let n: usize = element.strip_prefix("line ").and_then(|n| n.parse().ok()).unwrap_or(0);
                    prop_assert!(n >= 1 && n <= lines.len(), "element {}", element);
                }
                Err(e) => prop_assert!(false, "unexpected error {}", e),
            }
        }

        /// Arbitrary bytes never panic.
        #[test]
        fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
            let _ = load_obj_bytes(&bytes, Path::new("bytes.obj")).map(Scene::new);
        }
    }
}
