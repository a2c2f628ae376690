//! Tests of the glTF 2.0 loader: real scenes from the shared corpus (counts
//! checked by hand against the files' JSON), every file of the edge-case
//! corpus (no panics, clear errors), and small glTF files built here.

use glam::{DMat4, DQuat, DVec3, Vec3};
use scene::load::gltf::{load_gltf, load_gltf_slice};
use scene::{Error, ObjectId, Scene, SceneGraph, Transform};
use serde_json::{json, Value};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

// ---------------------------------------------------------------- helpers

fn edge(rel: &str) -> Option<PathBuf> {
    Some(testkit::shared_data()?.join("edge_gltf").join(rel))
}

fn assimp(rel: &str) -> Option<PathBuf> {
    edge(&format!("assimp/glTF2/{rel}"))
}

fn scene_of(path: &Path) -> Scene {
    let graph = load_gltf(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Scene::new(graph).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn load_err(path: &Path) -> Error {
    match load_gltf(path) {
        Ok(_) => panic!("{} loaded, but should fail", path.display()),
        Err(e) => e,
    }
}

/// A `resolve` that knows no external files.
fn no_files(uri: &str) -> std::io::Result<Vec<u8>> {
    Err(std::io::Error::new(
        std::io::ErrorKind::NotFound,
        uri.to_string(),
    ))
}

fn from_json(v: &Value) -> scene::Result<SceneGraph> {
    let bytes = serde_json::to_vec(v).expect("serializable");
    load_gltf_slice(&bytes, Path::new("test.gltf"), &mut no_files)
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | u32::from(b) << (16 - 8 * i));
        for i in 0..4 {
            if i <= c.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bytes))
}

fn f32_bytes(points: &[[f32; 3]]) -> Vec<u8> {
    points
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect()
}

/// A unit quad in the xy plane (CCW seen from +z) as 4 positions.
const QUAD: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
];

/// One buffer (a data URI) holding `positions` then `indices`, one mesh with
/// one primitive, and the given nodes (scene 0 = node 0 unless `scenes` given).
fn quad_doc(indices: Option<(&[u8], u32, usize)>, nodes: Value) -> Value {
    let mut data = f32_bytes(&QUAD);
    let pos_len = data.len();
    let mut accessors = vec![json!({
        "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0]
    })];
    let mut views = vec![json!({"buffer": 0, "byteLength": pos_len})];
    // Non-indexed, the 4 vertices are a fan: the quad's 2 triangles.
    let mut primitive = json!({"attributes": {"POSITION": 0}, "mode": 6});
    if let Some((bytes, component_type, count)) = indices {
        views.push(json!({"buffer": 0, "byteOffset": pos_len, "byteLength": bytes.len()}));
        accessors.push(json!({"bufferView": 1, "componentType": component_type, "count": count, "type": "SCALAR"}));
        primitive["indices"] = json!(1);
        primitive["mode"] = json!(4);
        data.extend_from_slice(bytes);
    }
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"name": "quad", "primitives": [primitive]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": data.len(), "uri": data_uri(&data)}]
    })
}

fn normal(t: &[DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

// ---------------------------------------------------------- real scenes

/// A real scene and what a hand check of its JSON found.
struct Expected {
    rel: &'static str,
    /// Σ over mesh nodes of the mesh's primitive count.
    objects: usize,
    /// Scene meshes = glTF primitives.
    meshes: usize,
    /// Triangles over all instances, as stored in the file.
    raw_triangles: usize,
    /// Of those, triangles with two equal indices or positions (or zero
    /// area), which `Mesh::new` drops, counted per instance.
    degenerate_instances: usize,
    /// The same, counted once per distinct primitive.
    degenerate_meshes: usize,
    min: [f32; 3],
    max: [f32; 3],
}

/// Expected counts, checked by hand with short Python walks over each file
/// (default scene, node tree, accessor data, accumulated node transforms):
/// 2CylinderEngine: 82 nodes, 67 mesh nodes, 29 meshes with 34 primitives,
/// 115 (node, primitive) objects, 121,496 triangles of which 11,160 are
/// degenerate (10,413 per mesh repeat an index), leaving 110,336;
/// room: 17 mesh nodes with one primitive each, 63,720 triangles, none degenerate;
/// subpass_scene_opaque: 70 mesh nodes, 12 meshes with 16 primitives, 87
/// objects, 23,388 triangles of which 4,168 are degenerate, leaving 19,220.
const REAL_SCENES: [Expected; 3] = [
    Expected {
        rel: "scenes/engine_2cylinder/2CylinderEngine.glb",
        objects: 115,
        meshes: 34,
        raw_triangles: 121_496,
        degenerate_instances: 11_160,
        degenerate_meshes: 10_419,
        min: [-371.692, -180.972, -140.0],
        max: [371.692, 92.042, 128.0],
    },
    Expected {
        rel: "scenes/occlusion_room/room.glb",
        objects: 17,
        meshes: 17,
        raw_triangles: 63_720,
        degenerate_instances: 0,
        degenerate_meshes: 0,
        min: [-5.0, 0.0, -5.0],
        max: [5.0, 5.0, 5.0],
    },
    Expected {
        rel: "scenes/subpass_scene/subpass_scene_opaque.gltf",
        objects: 87,
        meshes: 16,
        raw_triangles: 23_388,
        degenerate_instances: 4_168,
        degenerate_meshes: 4_100,
        min: [-11.0, -9.714, -11.0],
        max: [11.0, 0.486, 11.0],
    },
];

#[test]
fn gltf_real_scenes_have_the_expected_counts() {
    let Some(data) = testkit::shared_data() else {
        return;
    };
    for x in REAL_SCENES {
        let rel = x.rel;
        let scene = scene_of(&data.join(rel));
        let c = scene.counts();
        assert_eq!(c.objects, x.objects, "{rel}");
        assert_eq!(c.meshes, x.meshes, "{rel}");
        // Every triangle of the file is either kept or dropped as degenerate.
        let dropped: usize = scene
            .objects()
            .iter()
            .map(|o| {
                scene.graph().meshes()[o.mesh.index()]
                    .topology()
                    .degenerate_triangles
            })
            .sum();
        assert_eq!(dropped, x.degenerate_instances, "{rel}");
        assert_eq!(
            c.topology.degenerate_triangles, x.degenerate_meshes,
            "{rel}"
        );
        assert_eq!(
            c.drawn_triangles,
            x.raw_triangles - x.degenerate_instances,
            "{rel}"
        );
        assert_eq!(
            c.triangles, x.raw_triangles,
            "{rel}: as loaded, every instance"
        );
        // Tight world bounds of all triangles match the hand computation; the
        // scene bounds (a union of transformed boxes) contain them.
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (id, o) in scene.objects().iter().enumerate() {
            let n = scene.graph().meshes()[o.mesh.index()].triangles().len();
            for t in 0..n {
                for p in scene.world_triangle(ObjectId::from_slot(id as u32), t) {
                    (lo, hi) = (lo.min(p), hi.max(p));
                }
            }
        }
        let tol = 1e-3 * Vec3::from(x.max).abs().max_element().max(1.0) as f64;
        let (min, max) = (Vec3::from(x.min).as_dvec3(), Vec3::from(x.max).as_dvec3());
        assert!((lo - min).abs().max_element() < tol, "{rel}: {lo} vs {min}");
        assert!((hi - max).abs().max_element() < tol, "{rel}: {hi} vs {max}");
        let b = scene.bounds();
        assert!(b.min.is_finite() && b.max.is_finite(), "{rel}: {b:?}");
        assert!(
            b.min.as_dvec3().cmple(lo).all() && b.max.as_dvec3().cmpge(hi).all(),
            "{rel}: {b:?}"
        );
    }
}

#[test]
fn gltf_engine_instances_share_meshes() {
    let Some(data) = testkit::shared_data() else {
        return;
    };
    let graph = load_gltf(&data.join("scenes/engine_2cylinder/2CylinderEngine.glb")).unwrap();
    assert_eq!(graph.nodes().len(), 82);
    let mesh_nodes = graph
        .nodes()
        .iter()
        .filter(|n| !n.meshes.is_empty())
        .count();
    assert_eq!(mesh_nodes, 67);
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
}

// ------------------------------------------------------------- the corpus

fn corpus_files(root: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut dirs = vec![root.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = entry.path();
            if p.is_dir() {
                dirs.push(p);
            } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

/// Every .gltf/.glb of the edge corpus: no panic, each loads or fails with an
/// error naming the file, and each finishes well under a second.
#[test]
fn gltf_edge_corpus_never_panics_and_errors_name_the_file() {
    let Some(root) = edge("") else {
        return;
    };
    let files = corpus_files(&root);
    assert!(files.len() > 400, "only {} files", files.len());
    let mut panicked = Vec::new();
    let mut unnamed = Vec::new();
    let mut slow = Vec::new();
    let (mut loaded, mut failed) = (0, 0);
    for file in &files {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let start = Instant::now();
        let result = catch_unwind(AssertUnwindSafe(|| load_gltf(file).and_then(Scene::new)));
        let elapsed = start.elapsed();
        match result {
            Err(_) => panicked.push(file.display().to_string()),
            Ok(Ok(scene)) => {
                loaded += 1;
                let c = scene.counts();
                println!(
                    "ok   {}: {} objects, {} triangles, {} warnings",
                    file.display(),
                    c.objects,
                    c.triangles,
                    scene.warnings().len()
                );
                for w in scene.warnings() {
                    println!("       warning: {w}");
                }
            }
            Ok(Err(e)) => {
                failed += 1;
                println!("err  {e}");
                if !e.to_string().contains(&name) {
                    unnamed.push(format!("{}: {e}", file.display()));
                }
            }
        }
        if elapsed > Duration::from_millis(500) {
            slow.push(format!("{} took {elapsed:?}", file.display()));
        }
    }
    println!(
        "{} files: {loaded} loaded, {failed} failed cleanly",
        files.len()
    );
    assert!(panicked.is_empty(), "panicked on:\n{}", panicked.join("\n"));
    assert!(
        unnamed.is_empty(),
        "errors that do not name the file:\n{}",
        unnamed.join("\n")
    );
    assert!(slow.is_empty(), "too slow:\n{}", slow.join("\n"));
}

#[test]
fn gltf_node_cycles_are_errors() {
    for path in [
        assimp("RecursiveNodes/RecursiveNodes.gltf"),
        edge("gltf-validator/base/data/node/node_loop_scene.gltf"),
        edge("gltf-validator/base/data/node/node_loop.gltf"),
    ] {
        let Some(path) = path else {
            return;
        };
        let e = load_err(&path);
        assert!(e.to_string().contains("cycle"), "{e}");
    }
}

#[test]
fn gltf_second_parent_is_a_warning_not_a_loop() {
    let Some(path) = edge("gltf-validator/base/data/node/node_parent_override.gltf") else {
        return;
    };
    let graph = load_gltf(&path).unwrap();
    assert!(
        graph
            .warnings()
            .iter()
            .any(|w| w.contains("only one parent")),
        "{:?}",
        graph.warnings()
    );
    Scene::new(graph).unwrap();
}

#[test]
fn gltf_missing_bin_is_an_io_error_naming_both_files() {
    let Some(path) = assimp("MissingBin/BoxTextured.gltf") else {
        return;
    };
    match load_err(&path) {
        Error::Io {
            path: bin,
            referenced_from,
            ..
        } => {
            assert_eq!(
                bin.extension().and_then(|e| e.to_str()),
                Some("bin"),
                "{}",
                bin.display()
            );
            assert_eq!(bin.parent(), path.parent());
            assert_eq!(referenced_from.as_deref(), Some(path.as_path()));
        }
        e => panic!("expected an Io error, got {e}"),
    }
}

#[test]
fn gltf_draco_is_an_error_naming_the_extension() {
    let Some(path) = assimp("draco/2CylinderEngine.gltf") else {
        return;
    };
    let e = load_err(&path).to_string();
    assert!(
        e.contains("KHR_draco_mesh_compression") && e.contains("2CylinderEngine.gltf"),
        "{e}"
    );
}

#[test]
fn gltf_1_0_files_are_rejected_clearly() {
    let Some(root) = edge("assimp/glTF") else {
        return;
    };
    let files = corpus_files(&root);
    assert_eq!(files.len(), 7);
    for file in files {
        let e = load_err(&file).to_string();
        assert!(e.contains("1.0") && e.contains("not supported"), "{e}");
    }
}

#[test]
fn gltf_unknown_required_material_extension_is_a_warning() {
    let Some(path) = assimp("BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf") else {
        return;
    };
    let graph = load_gltf(&path).unwrap();
    assert!(
        graph
            .warnings()
            .iter()
            .any(|w| w.contains("KHR_technique_webgl")),
        "{:?}",
        graph.warnings()
    );
    assert_eq!(Scene::new(graph).unwrap().counts().triangles, 12);
}

#[test]
fn gltf_bad_indices_and_positions_are_errors() {
    for (rel, needle) in [
        ("IndexOutOfRange/IndexOutOfRange.gltf", "vertices"),
        ("IndexOutOfRange/AllIndicesOutOfRange.gltf", "vertices"),
        (
            "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
            "not finite",
        ),
    ] {
        let Some(path) = assimp(rel) else {
            return;
        };
        let e = load_err(&path);
        assert!(matches!(e, Error::Load { .. }), "{e}");
        let e = e.to_string();
        assert!(e.contains(needle) && e.contains("accessor"), "{e}");
    }
}

#[test]
fn gltf_unresolved_positions_does_not_panic() {
    let Some(path) = edge("gltf-validator/base/data/mesh/unresolved_positions.gltf") else {
        return;
    };
    let graph = load_gltf(&path);
    // The mesh is not in any scene; either way nothing panics.
    if let Err(e) = graph {
        assert!(e.to_string().contains("unresolved_positions.gltf"), "{e}");
    }
}

/// Mesh_PrimitiveMode_NN: points and lines are skipped with a warning; every
/// triangle mode gives the quad's 2 triangles (4 vertices as strip or fan,
/// 6 as a list or 6 indices), all facing the same way.
#[test]
fn gltf_primitive_modes() {
    let Some(dir) = assimp("glTF-Asset-Generator/Mesh_PrimitiveMode") else {
        return;
    };
    for k in 0..16 {
        let path = dir.join(format!("Mesh_PrimitiveMode_{k:02}.gltf"));
        let graph = load_gltf(&path).unwrap_or_else(|e| panic!("{e}"));
        let lines_or_points = matches!(k, 0..=3 | 7..=10);
        let warned = graph
            .warnings()
            .iter()
            .any(|w| w.contains("mesh 0 primitive 0") && w.contains("skipped"));
        assert_eq!(warned, lines_or_points, "{k}: {:?}", graph.warnings());
        let scene = Scene::new(graph).unwrap();
        let expected = if lines_or_points { 0 } else { 2 };
        assert_eq!(
            scene.counts().triangles,
            expected,
            "Mesh_PrimitiveMode_{k:02}"
        );
        if expected > 0 {
            let n0 = normal(&scene.world_triangle(ObjectId::from_slot(0), 0));
            let n1 = normal(&scene.world_triangle(ObjectId::from_slot(0), 1));
            assert!(n0.dot(n1) > 0.0, "{k}: {n0} vs {n1}");
        }
    }
}

#[test]
fn gltf_lying_glb_headers_fail_fast() {
    for rel in [
        "glb/zero_length.glb",
        "glb/invalid_version.glb",
        "glb/length_mismatch.glb",
        "glb/chunk_too_big.glb",
    ] {
        let Some(path) = edge(&format!("gltf-validator/base/data/{rel}")) else {
            return;
        };
        let start = Instant::now();
        let e = load_err(&path).to_string();
        assert!(start.elapsed() < Duration::from_millis(100), "{rel}");
        assert!(e.contains("GLB"), "{e}");
    }
}

#[test]
fn gltf_files_without_nodes_or_scenes() {
    let Some(dir) = assimp("TestNoRootNode") else {
        return;
    };
    for f in ["NoScene.gltf", "SceneWithoutNodes.gltf"] {
        let graph = load_gltf(&dir.join(f)).unwrap();
        assert!(graph.roots().is_empty() && graph.meshes().is_empty(), "{f}");
    }
}

// -------------------------------------------------- hand-written files

#[test]
fn gltf_trs_and_matrix_give_the_same_world_transform() {
    let rotation = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
    let (t, s) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(2.0, 0.5, 1.0));
    let m = DMat4::from_scale_rotation_translation(s, rotation, t);
    let doc = quad_doc(
        None,
        json!([
            {"name": "root", "children": [1, 2]},
            {"name": "trs", "mesh": 0, "translation": t.to_array(), "rotation": rotation.to_array(), "scale": s.to_array()},
            {"name": "matrix", "mesh": 0, "matrix": m.to_cols_array()}
        ]),
    );
    let graph = from_json(&doc).unwrap();
    assert!(graph.warnings().is_empty(), "{:?}", graph.warnings());
    assert_eq!(graph.nodes()[0].transform.matrix(), DMat4::IDENTITY);
    match graph.nodes()[1].transform {
        Transform::Trs {
            translation,
            rotation: r,
            scale,
        } => {
            assert_eq!(translation, t);
            assert_eq!(scale, s);
            assert!(r.abs_diff_eq(rotation, 1e-15));
        }
        other => panic!("expected TRS, got {other:?}"),
    }
    assert_eq!(graph.nodes()[2].transform, Transform::Matrix(m));
    let scene = Scene::new(graph).unwrap();
    assert_eq!(scene.counts().objects, 2);
    let (a, b) = (
        scene.object(ObjectId::from_slot(0)),
        scene.object(ObjectId::from_slot(1)),
    );
    assert!(a.world_from_local.abs_diff_eq(b.world_from_local, 1e-12));
    assert!(a.world_from_local.abs_diff_eq(m, 1e-12));
}

#[test]
fn gltf_mirrored_node_keeps_world_facing() {
    let doc = quad_doc(None, json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]));
    let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
    assert_eq!(scene.counts().triangles, 2);
    let o = scene.object(ObjectId::from_slot(0));
    assert!(o.mirrored);
    // The quad is CCW seen from +z; its mirror image still faces +z.
    for t in 0..2 {
        assert!(normal(&scene.world_triangle(ObjectId::from_slot(0), t)).z > 0.0);
    }
    assert_eq!(o.world_bounds.min.x, -1.0);
}

#[test]
fn gltf_u8_u16_u32_indices() {
    let idx = [0u32, 1, 2, 0, 2, 3];
    let u8s: Vec<u8> = idx.iter().map(|&i| i as u8).collect();
    let u16s: Vec<u8> = idx.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect();
    let u32s: Vec<u8> = idx.iter().flat_map(|&i| i.to_le_bytes()).collect();
    for (bytes, ct) in [(&u8s, 5121), (&u16s, 5123), (&u32s, 5125)] {
        let doc = quad_doc(Some((bytes, ct, 6)), json!([{"mesh": 0}]));
        let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
        assert_eq!(scene.counts().triangles, 2, "componentType {ct}");
        assert_eq!(scene.counts().vertices, 4, "componentType {ct}");
        assert!(normal(&scene.world_triangle(ObjectId::from_slot(0), 0)).z > 0.0);
    }
    // Float and signed indices are errors naming the accessor.
    let floats: Vec<u8> = idx.iter().flat_map(|&i| (i as f32).to_le_bytes()).collect();
    for (bytes, ct) in [(&floats, 5126), (&u16s, 5122)] {
        let e = from_json(&quad_doc(Some((bytes, ct, 6)), json!([{"mesh": 0}]))).unwrap_err();
        assert!(e.to_string().contains("accessor 1"), "{e}");
    }
}

#[test]
fn gltf_non_indexed_primitive_and_index_out_of_range() {
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
    assert_eq!(scene.counts().triangles, 2);
    assert!(scene.warnings().is_empty());
    // 4 vertices as a list: one triangle, one vertex left over (with a warning).
    doc["meshes"][0]["primitives"][0]["mode"] = json!(4);
    let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
    assert_eq!(scene.counts().triangles, 1);
    assert!(scene.warnings().iter().any(|w| w.contains("multiple of 3")));
    let doc = quad_doc(Some((&[0, 1, 4], 5121, 3)), json!([{"mesh": 0}]));
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(
        e.contains("test.gltf") && e.contains("mesh 0 primitive 0") && e.contains("is 4"),
        "{e}"
    );
}

#[test]
fn gltf_truncated_data_names_the_accessor_or_buffer_view() {
    // The accessor claims more elements than its view holds.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["accessors"][0]["count"] = json!(5);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(
        e.contains("accessor 0") && e.contains("bufferView 0"),
        "{e}"
    );
    // A huge count must not allocate: it fails the same way, at once.
    doc["accessors"][0]["count"] = json!(u64::MAX / 2);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("accessor 0"), "{e}");
    // The view runs past the end of its buffer.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["bufferViews"][0]["byteLength"] = json!(60);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("bufferView 0") && e.contains("buffer 0"), "{e}");
    // The buffer's data is shorter than its byteLength.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["buffers"][0]["byteLength"] = json!(1000);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("buffer 0") && e.contains("1000"), "{e}");
    // A stride smaller than the element.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["bufferViews"][0]["byteStride"] = json!(8);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("byteStride"), "{e}");
    // Wrong accessor type for POSITION.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["accessors"][0]["type"] = json!("VEC2");
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("accessor 0") && e.contains("VEC3"), "{e}");
    // A dangling POSITION accessor (the gltf crate panics here).
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(
        e.contains("mesh 0 primitive 0") && e.contains("accessor 7"),
        "{e}"
    );
    // An index beyond u32 is not truncated onto a valid accessor.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(1u64 << 32);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("mesh 0 primitive 0"), "{e}");
}

#[test]
fn gltf_sparse_positions() {
    // Base quad, with vertex 2 moved to (2, 2, 0) by a sparse substitution.
    let mut data = f32_bytes(&QUAD);
    let base = data.len();
    data.extend_from_slice(&[2, 0, 0, 0]); // u8 index 2, padded
    data.extend(f32_bytes(&[[2.0, 2.0, 0.0]]));
    let idx = [0u8, 1, 2, 0, 2, 3];
    let idx_at = data.len();
    data.extend_from_slice(&idx);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "sparse": {"count": 1,
                        "indices": {"bufferView": 1, "componentType": 5121},
                        "values": {"bufferView": 1, "byteOffset": 4}}},
            {"bufferView": 2, "componentType": 5121, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": base},
            {"buffer": 0, "byteOffset": base, "byteLength": 16},
            {"buffer": 0, "byteOffset": idx_at, "byteLength": 6}
        ],
        "buffers": [{"byteLength": data.len(), "uri": data_uri(&data)}]
    });
    let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
    assert_eq!(scene.bounds().max, Vec3::new(2.0, 2.0, 0.0));
    assert_eq!(scene.counts().triangles, 2);
}

#[test]
fn gltf_quantized_positions_need_the_extension() {
    let q: Vec<u8> = [
        [0u16, 0, 0],
        [65535, 0, 0],
        [65535, 65535, 0],
        [0, 65535, 0],
    ]
    .iter()
    .flatten()
    .flat_map(|c| c.to_le_bytes())
    .collect();
    let doc = |used: bool| {
        let mut d = json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 6}]}],
            "accessors": [{"bufferView": 0, "componentType": 5123, "normalized": true, "count": 4, "type": "VEC3"}],
            "bufferViews": [{"buffer": 0, "byteLength": 24}],
            "buffers": [{"byteLength": q.len(), "uri": data_uri(&q)}]
        });
        if used {
            d["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
            d["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
        }
        d
    };
    let scene = Scene::new(from_json(&doc(true)).unwrap()).unwrap();
    assert_eq!(scene.counts().triangles, 2);
    assert_eq!(scene.bounds().max, Vec3::new(1.0, 1.0, 0.0));
    let e = from_json(&doc(false)).unwrap_err().to_string();
    assert!(
        e.contains("KHR_mesh_quantization") && e.contains("accessor 0"),
        "{e}"
    );
}

#[test]
fn gltf_glb_container_and_lying_lengths() {
    let positions = f32_bytes(&QUAD);
    let json = serde_json::to_vec(&json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 5}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": 48}],
        "buffers": [{"byteLength": 48}]
    }))
    .unwrap();
    let glb = |json: &[u8], bin: &[u8]| {
        let mut json = json.to_vec();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out
    };
    let load = |bytes: &[u8]| load_gltf_slice(bytes, Path::new("t.glb"), &mut no_files);
    let good = glb(&json, &positions);
    let scene = Scene::new(load(&good).unwrap()).unwrap();
    // A strip of 4: the quad's 2 triangles (0,1,2) and (1,3,2).
    assert_eq!(scene.counts().triangles, 2);

    let mut lying = good.clone();
    lying[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(load(&lying).unwrap_err().to_string().contains("GLB header"));
    let mut lying = good.clone();
    lying[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(load(&lying)
        .unwrap_err()
        .to_string()
        .contains("GLB chunk 0"));
    // A BIN chunk shorter than the buffer's byteLength.
    let short = glb(&json, &positions[..40]);
    let e = load(&short).unwrap_err().to_string();
    assert!(e.contains("buffer 0"), "{e}");
    // Truncated anywhere: an error, never a panic.
    for cut in 0..good.len() {
        assert!(load(&good[..cut]).is_err(), "cut at {cut}");
    }
}

#[test]
fn gltf_external_buffers_are_resolved_percent_decoded() {
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["accessors"][0]["count"] = json!(3);
    doc["buffers"][0]["uri"] = json!("my%20quad.bin");
    let bytes = serde_json::to_vec(&doc).unwrap();
    let mut asked = Vec::new();
    let mut resolve = |uri: &str| {
        asked.push(uri.to_string());
        Ok(f32_bytes(&QUAD))
    };
    let graph = load_gltf_slice(&bytes, Path::new("dir/scene.gltf"), &mut resolve).unwrap();
    assert_eq!(asked, ["my quad.bin"]);
    assert_eq!(Scene::new(graph).unwrap().counts().triangles, 1);
    // A failing resolve is an Io error naming the buffer file and the glTF file.
    match load_gltf_slice(&bytes, Path::new("dir/scene.gltf"), &mut no_files) {
        Err(Error::Io {
            path,
            referenced_from,
            ..
        }) => {
            assert_eq!(path, Path::new("dir/my quad.bin"));
            assert_eq!(
                referenced_from.as_deref(),
                Some(Path::new("dir/scene.gltf"))
            );
        }
        other => panic!("expected an Io error, got {other:?}"),
    }
}

#[test]
fn gltf_scene_selection_and_extensions() {
    // No scenes: every root node, with a warning.
    let mut doc = quad_doc(
        None,
        json!([{"mesh": 0, "children": [1]}, {"mesh": 0}, {"mesh": 0}]),
    );
    doc.as_object_mut().unwrap().remove("scenes");
    doc.as_object_mut().unwrap().remove("scene");
    let graph = from_json(&doc).unwrap();
    assert_eq!(graph.roots().len(), 2);
    assert!(graph.warnings().iter().any(|w| w.contains("no scenes")));
    assert_eq!(Scene::new(graph).unwrap().counts().objects, 3);
    // No nodes at all: an empty graph.
    let graph = from_json(&json!({"asset": {"version": "2.0"}})).unwrap();
    assert!(graph.nodes().is_empty() && graph.roots().is_empty());
    // A required material extension is a warning, a required unknown mesh extension an error.
    let mut doc = quad_doc(None, json!([{"mesh": 0}]));
    doc["extensionsRequired"] = json!(["KHR_materials_foo"]);
    let graph = from_json(&doc).unwrap();
    assert!(graph
        .warnings()
        .iter()
        .any(|w| w.contains("KHR_materials_foo")));
    doc["extensionsRequired"] = json!(["ACME_mesh_magic"]);
    doc["meshes"][0]["extensions"] = json!({"ACME_mesh_magic": {}});
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("ACME_mesh_magic") && e.contains("mesh 0"), "{e}");
    doc["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("EXT_meshopt_compression"), "{e}");
    // Version checks.
    let e = from_json(&json!({"asset": {"version": "1.0"}}))
        .unwrap_err()
        .to_string();
    assert!(e.contains("glTF 1.0"), "{e}");
    let e = from_json(&json!({"asset": {"version": "3.0"}}))
        .unwrap_err()
        .to_string();
    assert!(e.contains("3.0"), "{e}");
}

#[test]
fn gltf_hidden_nodes_and_deep_chains() {
    // KHR_node_visibility hides a subtree.
    let doc = quad_doc(
        None,
        json!([{"mesh": 0, "children": [1]}, {"mesh": 0, "extensions": {"KHR_node_visibility": {"visible": false}}, "children": [2]}, {"mesh": 0}]),
    );
    let scene = Scene::new(from_json(&doc).unwrap()).unwrap();
    assert_eq!(scene.counts().objects, 1);
    // A chain deeper than MAX_NODE_DEPTH is an error naming the file, not a stack overflow.
    let n = scene::MAX_NODE_DEPTH + 10;
    let nodes: Vec<Value> = (0..n)
        .map(|i| {
            if i + 1 < n {
                json!({"children": [i + 1]})
            } else {
                json!({"mesh": 0})
            }
        })
        .collect();
    let doc = quad_doc(None, Value::Array(nodes));
    let e = from_json(&doc).unwrap_err().to_string();
    assert!(e.contains("test.gltf") && e.contains("deeper"), "{e}");
}
