//! End-to-end tests of the `shadowcull` binary: `run`, `compare` and `inspect`.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_shadowcull"))
}

fn shared_data() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if p.is_dir() {
        Some(p)
    } else {
        println!("note: {} is absent; skipping", p.display());
        None
    }
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("shadowcull-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn inspect_json(path: &Path) -> serde_json::Value {
    let out = bin()
        .arg("inspect")
        .arg(path)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn inspect_reports_the_done_when_counts() {
    let Some(data) = shared_data() else { return };
    let engine = inspect_json(&data.join("scenes/engine_2cylinder/2CylinderEngine.glb"));
    assert_eq!(engine["triangles"], 121_496, "every instance counted");
    for key in [
        "objects",
        "meshes",
        "triangles",
        "vertices",
        "bounds",
        "boundary_edges",
        "non_manifold_edges",
        "inconsistent_edges",
        "degenerate_triangles",
        "warnings",
    ] {
        assert!(engine.get(key).is_some(), "missing key {key}");
    }
    assert!(engine["bounds"]["min"].is_array() && engine["bounds"]["max"].is_array());
    assert!(engine["warnings"].is_array());
    let city = inspect_json(&data.join("scenes/procedural_city/city.obj"));
    assert_eq!(city["objects"], 498);
}

#[test]
fn inspect_errors_exit_1_with_one_line_naming_the_file() {
    let dir = tmp_dir("inspect-errors");
    let cases: Vec<(PathBuf, &str)> = vec![
        (dir.join("missing.obj"), "missing.obj"),
        (dir.join("bad.gltf"), "bad.gltf"),
        (dir.join("scene.xyz"), "scene.xyz"),
    ];
    std::fs::write(dir.join("bad.gltf"), b"{ not json").unwrap();
    std::fs::write(dir.join("scene.xyz"), b"hello").unwrap();
    for (path, name) in cases {
        let out = bin()
            .arg("inspect")
            .arg(&path)
            .arg("--json")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{name}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        assert!(err.contains(name), "names the file: {err}");
        assert!(
            !err.contains("panicked") && !err.contains("backtrace"),
            "{err}"
        );
    }
}

#[test]
fn inspect_missing_bin_names_both_files() {
    let Some(data) = shared_data() else { return };
    let p = data.join("edge_gltf/assimp/glTF2/MissingBin/BoxTextured.gltf");
    let out = bin().arg("inspect").arg(&p).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("BoxTextured.gltf") && err.contains(".bin"),
        "{err}"
    );
}

#[test]
fn inspect_never_panics_on_the_edge_corpus() {
    let Some(data) = shared_data() else { return };
    let mut files = Vec::new();
    let mut stack = vec![data.join("edge_gltf"), data.join("edge_obj")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("gltf" | "glb" | "obj")
            ) {
                files.push(p);
            }
        }
    }
    files.sort();
    assert!(files.len() > 300, "corpus has {} files", files.len());
    let mut bad = Vec::new();
    for f in &files {
        let t = std::time::Instant::now();
        let out = bin().arg("inspect").arg(f).arg("--json").output().unwrap();
        let code = out.status.code();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        if !(code == Some(0) || code == Some(1))
            || err.contains("panicked")
            || err.contains("internal error")
        {
            bad.push(format!("{}: status {code:?}: {err}", f.display()));
        }
        if code == Some(1) && !err.contains(f.file_name().unwrap().to_str().unwrap()) {
            bad.push(format!(
                "{}: error does not name the file: {err}",
                f.display()
            ));
        }
        if t.elapsed().as_secs_f64() > 5.0 {
            bad.push(format!("{}: took {:?}", f.display(), t.elapsed()));
        }
    }
    assert!(
        bad.is_empty(),
        "{} of {} files misbehaved:\n{}",
        bad.len(),
        files.len(),
        bad.join("\n")
    );
}

const SMALL_JOB: &str = r#"(
    version: 1,
    scene: City((blocks_x: 2, blocks_z: 2)),
    resolution: (64, 48),
    camera: Path("bird"),
    frames: 3,
    lights: [AboveScene(1.5), Sun(elevation_deg: 35.0, azimuth_deg: 30.0)],
    outputs: (masks: true, shaded: true),
)"#;

#[test]
fn run_writes_stats_summary_and_images() {
    let dir = tmp_dir("run");
    let job = dir.join("job.ron");
    std::fs::write(
        &job,
        SMALL_JOB.replace(
            "outputs: (masks: true, shaded: true),",
            "outputs: (masks: true, shaded: true, tile_image: true),\n    pipeline: (stencil: h),",
        ),
    )
    .unwrap();
    let out = dir.join("out/nested");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "other file").unwrap();
    let o = bin()
        .arg("run")
        .arg(&job)
        .arg("--out")
        .arg(&out)
        .arg("--frames")
        .arg("2")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("keep.txt").exists(), "other files are left alone");
    let csv = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 1 + 2 * 2, "header + frames × lights:\n{csv}");
    assert!(lines[0].starts_with("frame,light,"));
    assert!(
        lines[0].contains("reference_ms") && lines[0].contains(",lit,shadow,unlit,background,")
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 2);
    // Whole-frame time: the wall time of `Pipeline::frame`, all lights.
    let (median, mean) = (
        summary["frame_ms_median"].as_f64().unwrap(),
        summary["frame_ms_mean"].as_f64().unwrap(),
    );
    assert!(median > 0.0 && mean > 0.0, "{summary}");
    for f in [
        "0_0_mask.png",
        "0_1_mask.png",
        "1_0_shaded.png",
        "1_1_shaded.png",
        "0_0_tiles.png",
        "1_1_tiles.png",
    ] {
        assert!(out.join("frames").join(f).exists(), "{f}");
    }
    assert!(
        !out.join("frames/2_0_mask.png").exists(),
        "--frames 2 stops after two frames"
    );
    // Rows add up to the image size.
    let cols: Vec<&str> = lines[0].split(',').collect();
    let idx = |name: &str| cols.iter().position(|c| *c == name).unwrap();
    for row in &lines[1..] {
        let v: Vec<&str> = row.split(',').collect();
        let sum: u64 = ["lit", "shadow", "unlit", "background"]
            .iter()
            .map(|c| v[idx(c)].parse::<u64>().unwrap())
            .sum();
        assert_eq!(sum, 64 * 48);
        // Each light's row repeats its frame's whole-frame time, which holds
        // the eye pass and this light's stages.
        let get = |c: &str| v[idx(c)].parse::<f64>().unwrap();
        assert!(get("pipeline_frame_ms") >= get("eye_ms"), "{row}");
        // The pipeline ran and matched the reference (ambiguous pixels aside).
        let num = |c: &str| v[idx(c)].parse::<f64>().unwrap();
        assert!(num("volume_triangles") > 0.0 && num("pixels_processed") > 0.0);
        assert!(num("compared_pixels") > 0.0);
        assert_eq!(num("mismatch_off_boundary"), 0.0, "{row}");
        assert!(
            num("mismatch_pixels") <= (64.0 * 48.0 * 1e-4f64).ceil(),
            "{row}"
        );
        assert_eq!(num("shadowed_pixels") > 0.0, num("shadow") > 0.0, "{row}");
    }
    for key in [
        "mismatch_pixels",
        "ambiguous_pixels",
        "shadowed_pixels",
        "pixels_processed",
    ] {
        assert!(cols.contains(&key), "stats.csv column {key}");
    }
}

#[test]
fn compare_writes_one_row_per_variant_and_a_plot() {
    let dir = tmp_dir("compare");
    let job = dir.join("job.ron");
    let text = SMALL_JOB.replace(
        "outputs: (masks: true, shaded: true),",
        r#"pipelines: [
            (name: "bf"),
            (name: "db", pipeline: (stencil: db, scissor: true)),
            (name: "zfail", pipeline: (method: zfail)),
            (name: "zpass", pipeline: (method: zpass)),
            (name: "h", pipeline: (stencil: h, full_shadow: false, tile: 4)),
            (name: "hybrid", pipeline: (stencil: hybrid, map_size: 512)),
            (name: "chcpp", pipeline: (stencil: h, culling: chcpp, coverage: conservative,
                light_resolution: 256, query_threshold: 0,
                chcpp: (batch: 50, revisit: 5, seed: 1))),
        ],"#,
    );
    std::fs::write(&job, text).unwrap();
    let out = dir.join("out");
    let o = bin()
        .arg("compare")
        .arg(&job)
        .arg("--out")
        .arg(&out)
        .args(["--frames", "1"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("compare.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 1 + 7, "{csv}");
    let cols: Vec<&str> = lines[0].split(',').collect();
    let idx = |name: &str| cols.iter().position(|c| *c == name).unwrap();
    let rows: Vec<Vec<&str>> = lines[1..].iter().map(|l| l.split(',').collect()).collect();
    let get = |r: usize, c: &str| rows[r][idx(c)].parse::<f64>().unwrap();
    assert_eq!(rows[0][0], "bf");
    for r in 0..3 {
        assert_eq!(get(r, "mismatch_off_boundary"), 0.0, "{}", lines[r + 1]);
        assert_eq!(get(r, "rows"), 2.0);
    }
    // Same masks, less per-pixel work with scissor and depth bounds.
    assert_eq!(get(0, "shadowed_pixels"), get(1, "shadowed_pixels"));
    assert!(get(1, "pixels_processed") <= get(0, "pixels_processed"));
    // The hierarchical stencil without FS: brute force's mask, fewer pixels.
    assert_eq!(get(4, "shadowed_pixels"), get(0, "shadowed_pixels"));
    assert_eq!(get(4, "mismatch_pixels"), get(0, "mismatch_pixels"));
    assert!(get(4, "pixels_processed") < get(0, "pixels_processed"));
    assert!(get(4, "tile_tests") > 0.0 && get(4, "bandwidth_bytes") > 0.0);
    // The hybrid runs volumes only at its silhouette pixels.
    assert!(get(5, "silhouette_pixels") > 0.0);
    assert!(get(5, "pixels_processed") < get(0, "pixels_processed"));
    // Conservative CHC++ culling: brute force's mask, fewer casters, its
    // settings and counters reported.
    assert_eq!(get(6, "shadowed_pixels"), get(0, "shadowed_pixels"));
    assert_eq!(get(6, "mismatch_pixels"), get(0, "mismatch_pixels"));
    assert!(get(6, "queries") > 0.0 && get(6, "psc") <= get(0, "psc"));
    assert_eq!(rows[6][idx("culling")], "chcpp");
    assert_eq!(rows[6][idx("coverage")], "conservative");
    assert_eq!(rows[6][idx("chcpp")], "50/5/1");
    assert_eq!(get(6, "light_resolution"), 256.0);
    assert_eq!(rows[0][idx("culling")], "none");
    for c in [
        "frame_ms",
        "stencil_ms",
        "pixels_processed",
        "ambiguous_pixels",
    ] {
        assert!(cols.contains(&c), "{c}");
    }
    let svg = std::fs::read_to_string(out.join("compare.svg")).unwrap();
    assert!(
        svg.contains("<svg") && svg.contains("zfail"),
        "labelled plot"
    );
    // A bad variant names itself.
    std::fs::write(
        &job,
        SMALL_JOB.replace(
            "outputs: (masks: true, shaded: true),",
            r#"pipelines: [(name: "x", pipeline: (stencil: hier))],"#,
        ),
    )
    .unwrap();
    let o = bin()
        .arg("compare")
        .arg(&job)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("job.ron") && err.contains("hier"), "{err}");
}

#[test]
fn run_log_format_json_prints_one_event_per_row() {
    let dir = tmp_dir("json");
    let job = dir.join("job.ron");
    std::fs::write(&job, SMALL_JOB).unwrap();
    let o = bin()
        .args(["run", "--log-format", "json", "--frames", "1", "--out"])
        .arg(dir.join("out"))
        .arg(&job)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let events: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .filter(|v: &serde_json::Value| v["target"] == "shadowcull::frame")
        .collect();
    assert_eq!(events.len(), 2);
    for key in shadowcull::stats::FrameRow::COLUMNS {
        assert!(
            events[0].get(*key).is_some(),
            "event lacks {key}: {}",
            events[0]
        );
    }
}

#[test]
fn run_reports_job_errors_with_line_and_column() {
    let dir = tmp_dir("badjob");
    let job = dir.join("bad.ron");
    std::fs::write(&job, "(\n  scene: City(()),\n  lightz: [],\n)").unwrap();
    let o = bin()
        .arg("run")
        .arg(&job)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bad.ron:3:") && err.contains("lightz"),
        "{err}"
    );
}
