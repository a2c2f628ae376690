//! End-to-end tests of the `shadowcull` binary: `run`, `compare` and `inspect`.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_shadowcull"))
}

/// A fresh scratch directory for one test, removed when dropped.
fn tmp_dir(name: &str) -> testkit::ScratchDir {
    testkit::scratch_dir(&format!("cli-{name}"))
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
    let Some(data) = testkit::shared_data() else {
        return;
    };
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
    let Some(data) = testkit::shared_data() else {
        return;
    };
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
    let Some(data) = testkit::shared_data() else {
        return;
    };
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
    // On Linux, the peak resident set: at least the job's output buffers,
    // and no more than the estimate the run was admitted with.
    let estimate = summary["memory_estimate_bytes"].as_u64().unwrap();
    if cfg!(target_os = "linux") {
        let rss = summary["peak_rss_bytes"].as_u64().unwrap();
        assert!(rss > 1 << 20 && rss <= estimate, "{summary}");
    }
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
            (name: "bf", pipeline: (culling: none)),
            (name: "db", pipeline: (stencil: db, scissor: true)),
            (name: "zfail", pipeline: (method: zfail)),
            (name: "zpass", pipeline: (method: zpass)),
            (name: "h", pipeline: (stencil: h, full_shadow: false, tile: 4)),
            (name: "hybrid", pipeline: (stencil: hybrid, map_size: 512)),
            (name: "chcpp", pipeline: (stencil: h, culling: chcpp, coverage: conservative,
                light_resolution: 256, query_threshold: 0,
                chcpp: (batch: 50, revisit: 5, seed: 1))),
            (name: "clamp", pipeline: (stencil: h, culling: none, clamping: continuous,
                count_fill: true)),
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
    assert_eq!(lines.len(), 1 + 8, "{csv}");
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
    // Clamping with fill accounting on `h`: bf's own fill without clamping,
    // and the fill with it; bf counts its own.
    assert_eq!(rows[7][idx("clamping")], "continuous");
    assert_eq!(get(7, "mismatch_off_boundary"), 0.0);
    assert!(get(7, "segments") > 0.0);
    assert_eq!(get(7, "bf_fill_unclamped"), get(0, "pixels_processed"));
    assert!(get(7, "bf_fill_clamped") > 0.0);
    assert_eq!(get(0, "bf_fill_unclamped"), get(0, "pixels_processed"));
    assert_eq!(get(0, "bf_fill_clamped"), 0.0);
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
        svg.contains("<svg") && svg.contains("zfail") && svg.contains("Pareto front"),
        "labelled plot"
    );
    // The Pareto front of time against off-boundary mismatch: the fastest of
    // the closest variants is on it, and nothing on it is beaten.
    let point = |r: usize| (get(r, "frame_ms"), get(r, "mismatch_off_boundary"));
    let beats = |a: (f64, f64), b: (f64, f64)| a.0 <= b.0 && a.1 <= b.1 && a != b;
    let closest = (0..rows.len())
        .min_by(|&a, &b| {
            point(a)
                .1
                .total_cmp(&point(b).1)
                .then(point(a).0.total_cmp(&point(b).0))
        })
        .unwrap();
    assert_eq!(get(closest, "pareto"), 1.0, "{csv}");
    for r in 0..rows.len() {
        let on = get(r, "pareto");
        assert!(on == 0.0 || on == 1.0, "{csv}");
        let beaten = (0..rows.len()).any(|q| beats(point(q), point(r)));
        assert_eq!(on == 1.0, !beaten, "row {r}: {csv}");
    }
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

/// A 12-frame job with coherent culling, whose history-dependent columns
/// (queries, PSR, PSC) differ between a single run and a cold-started shard.
const SHARD_JOB: &str = r#"(
    version: 1,
    scene: City((blocks_x: 3, blocks_z: 3)),
    resolution: (80, 60),
    camera: Path("street"),
    frames: 12,
    lights: [AboveScene(1.5), Sun(elevation_deg: 35.0, azimuth_deg: 30.0)],
    outputs: (masks: true, shaded: true, tile_image: true),
    pipeline: (stencil: h, culling: chcpp),
)"#;

/// `run --preset gpu_host` replaces the job's `pipeline` section: no CPU
/// stencil and no reference, so no mask or shaded image, whatever the
/// job's outputs ask; a bad preset name is a usage error naming the names.
#[test]
fn run_preset_gpu_host_replaces_the_pipeline_section() {
    let dir = tmp_dir("preset");
    let job = dir.join("job.ron");
    std::fs::write(&job, SMALL_JOB.replace("frames: 3,", "frames: 2,")).unwrap();
    let out = dir.join("out");
    run_ok(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--preset"),
        OsStr::new("gpu_host"),
        OsStr::new("--out"),
        out.as_os_str(),
    ]);
    let csv = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 2, "{csv}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["frame_ms_median"].as_f64().unwrap() > 0.0,
        "{summary}"
    );
    let cols: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    let cell = |name: &str| row[cols.iter().position(|c| *c == name).unwrap()];
    assert_eq!(cell("stencil_ms").parse::<f64>().unwrap(), 0.0, "{csv}");
    assert_eq!(cell("reference_ms").parse::<f64>().unwrap(), 0.0, "{csv}");
    let images = std::fs::read_dir(out.join("frames")).map_or(0, |d| d.count());
    assert_eq!(images, 0, "no mask, no reference: no images");
    let o = bin()
        .args(["run", "--preset", "gpu", "--frames", "1"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("gpu_host"));
}

/// Runs `shadowcull` with `args`, asserting success.
fn run_ok<S: AsRef<std::ffi::OsStr> + std::fmt::Debug>(args: &[S]) {
    let o = bin().args(args).output().unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Runs `shadowcull` with `args`, expecting exit status 1; returns stderr.
fn run_err<S: AsRef<std::ffi::OsStr> + std::fmt::Debug>(args: &[S]) -> String {
    let o = bin().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    err
}

/// Runs `shadowcull` with `args`, expecting exit status 1 and one `error:`
/// line on stderr (after `run`'s progress line); returns that line.
fn fails<S: AsRef<std::ffi::OsStr> + std::fmt::Debug>(args: &[S]) -> String {
    let o = bin().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error: ")).collect();
    assert_eq!(errors.len(), 1, "one error line: {err}");
    errors[0].to_string()
}

/// `stats.csv` as (header, rows of fields).
fn stats(dir: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("stats.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

/// The columns of `a` and `b` (same header) whose values differ in some row.
fn differing_columns(a: &Path, b: &Path) -> Vec<String> {
    let ((ha, ra), (hb, rb)) = (stats(a), stats(b));
    assert_eq!(ha, hb);
    assert_eq!(ra.len(), rb.len(), "{} vs {}", a.display(), b.display());
    (0..ha.len())
        .filter(|&c| ra.iter().zip(&rb).any(|(x, y)| x[c] != y[c]))
        .map(|c| ha[c].clone())
        .collect()
}

/// The names of `dir/frames` whose bytes differ from `other/frames`' (the
/// two must hold the same names).
fn differing_images(a: &Path, b: &Path) -> Vec<String> {
    let names = |d: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(d.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    };
    let (na, nb) = (names(a), names(b));
    assert_eq!(na, nb, "{} vs {}", a.display(), b.display());
    assert!(!na.is_empty());
    na.into_iter()
        .filter(|n| {
            std::fs::read(a.join("frames").join(n)).unwrap()
                != std::fs::read(b.join("frames").join(n)).unwrap()
        })
        .collect()
}

/// The equality contract of sharded jobs: merged shards give the single
/// run's masks and mask-derived columns byte for byte, whatever the split;
/// with keyframes on the shard boundaries, every column but the times; and
/// a missing, overlapping or foreign shard is an error naming its directory.
#[test]
fn sharded_runs_merge_into_the_single_run() {
    let dir = tmp_dir("shards");
    let job = dir.join("job.ron");
    std::fs::write(&job, SHARD_JOB).unwrap();
    let d = |name: &str| dir.join(name);
    let run = |out: &Path, extra: &[&str]| {
        let mut args: Vec<&std::ffi::OsStr> =
            vec!["run".as_ref(), job.as_ref(), "--out".as_ref(), out.as_ref()];
        args.extend(extra.iter().map(std::ffi::OsStr::new));
        run_ok(&args);
    };
    let merge = |out: &Path, shards: &[PathBuf]| {
        let mut args = vec!["merge".into(), out.as_os_str().to_owned()];
        args.extend(shards.iter().map(|s| s.as_os_str().to_owned()));
        args
    };
    let sharded = |tag: &str, n: u32, extra: &[&str]| {
        let dirs: Vec<PathBuf> = (0..n).map(|i| d(&format!("{tag}_{i}of{n}"))).collect();
        for (i, s) in dirs.iter().enumerate() {
            let shard = format!("{i}/{n}");
            let mut args = vec!["--shard", shard.as_str()];
            args.extend_from_slice(extra);
            run(s, &args);
        }
        let out = d(&format!("{tag}_merged{n}"));
        run_ok(&merge(&out, &dirs));
        (out, dirs)
    };
    // Mask-derived columns: identical under any split.
    let mask_columns = shadowcull::stats::FrameRow::MASK_COLUMNS;
    let single = d("single");
    run(&single, &[]);
    let mut history_differs = false;
    for n in [1, 2, 3] {
        let (merged, dirs) = sharded("plain", n, &[]);
        let columns = differing_columns(&single, &merged);
        for c in &columns {
            assert!(!mask_columns.contains(&c.as_str()), "N = {n}: {c} differs");
        }
        history_differs |= columns.iter().any(|c| !c.ends_with("_ms"));
        for name in differing_images(&single, &merged) {
            assert!(name.ends_with("_tiles.png"), "N = {n}: {name} differs");
        }
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(merged.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(summary["frames"], 12);
        assert_eq!(summary["shards"].as_array().unwrap().len(), n as usize);
        if cfg!(target_os = "linux") {
            assert!(summary["peak_rss_bytes"].as_u64().unwrap() > 1 << 20);
        }
        let manifest: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dirs[n as usize - 1].join("shard.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(manifest["count"], n);
        assert_eq!(manifest["frames"][1], 12);
        assert!(manifest["job_hash"]
            .as_str()
            .unwrap()
            .starts_with("fnv1a64:"));
    }
    assert!(
        history_differs,
        "cold-started shards should query differently from the single run"
    );

    // Keyframes every 4 frames, shard boundaries at 4 and 8: identical in
    // every column but the times, and in every image.
    let single_k = d("single_k");
    run(&single_k, &["--keyframe", "4"]);
    let (merged_k, dirs_k) = sharded("key", 3, &["--keyframe", "4"]);
    let columns = differing_columns(&single_k, &merged_k);
    assert!(
        columns.iter().all(|c| c.ends_with("_ms")),
        "with keyframes only times may differ: {columns:?}"
    );
    assert_eq!(differing_images(&single_k, &merged_k), Vec::<String>::new());
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dirs_k[1].join("shard.json")).unwrap())
            .unwrap();
    assert_eq!(
        m["warmup_frames"], 0,
        "a block starting on a keyframe needs no warm-up"
    );
    assert_eq!(m["keyframe"], 4);

    // Errors name the directory.
    let plain = |i: u32, n: u32| d(&format!("plain_{i}of{n}"));
    let e = run_err(&merge(&d("bad1"), &[plain(0, 3), plain(2, 3)]));
    assert!(
        e.contains("shard 1/3 is missing") && e.contains("bad1"),
        "{e}"
    );
    let e = run_err(&merge(&d("bad2"), &[plain(0, 2), plain(1, 2), plain(1, 2)]));
    assert!(e.contains("overlaps") && e.contains("plain_1of2"), "{e}");
    let e = run_err(&merge(&d("bad3"), &[plain(0, 2), dirs_k[1].clone()]));
    assert!(e.contains("another job") && e.contains("key_1of3"), "{e}");
    let e = run_err(&merge(&plain(0, 1), &[plain(0, 1)]));
    assert!(e.contains("one of the shards"), "{e}");
    let e = run_err(&merge(&d("bad4"), std::slice::from_ref(&single)));
    assert!(
        e.contains("no readable shard.json") && e.contains("single"),
        "{e}"
    );
    // A job edited between shards is foreign.
    let other = dir.join("other.ron");
    std::fs::write(&other, SHARD_JOB.replace("frames: 12", "frames: 12 ")).unwrap();
    let foreign = d("foreign_1of2");
    run_ok(&[
        "run".as_ref(),
        other.as_os_str(),
        "--out".as_ref(),
        foreign.as_os_str(),
        "--shard".as_ref(),
        "1/2".as_ref(),
    ] as &[&std::ffi::OsStr]);
    let e = run_err(&merge(&d("bad5"), &[plain(0, 2), foreign]));
    assert!(e.contains("job_hash") && e.contains("foreign_1of2"), "{e}");
    // A bad shard is a usage error that says what is wanted.
    let o = bin()
        .args([
            "run".as_ref(),
            job.as_os_str(),
            "--shard".as_ref(),
            "3/3".as_ref(),
        ] as [&std::ffi::OsStr; 4])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        e.contains("3/3") && e.contains("below the shard count"),
        "{e}"
    );
}

/// One writer per output directory: while a run holds the lock, a second
/// run into the same `--out` fails at once with a message naming it; a run
/// first removes what an earlier run owns there (so an interrupted rerun
/// leaves no stale `summary.json`) and nothing else; a killed run leaves no
/// stale lock.
#[test]
fn one_writer_per_output_directory() {
    use std::time::{Duration, Instant};
    let dir = tmp_dir("lock");
    let long = dir.join("long.ron");
    std::fs::write(&long, SMALL_JOB.replace("frames: 3", "frames: 100000")).unwrap();
    let short = dir.join("short.ron");
    std::fs::write(&short, SMALL_JOB).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("frames")).unwrap();
    std::fs::write(out.join("summary.json"), "an earlier run's").unwrap();
    std::fs::write(out.join("shard.json"), "an earlier run's").unwrap();
    std::fs::write(out.join("frames/77777_0_mask.png"), "an earlier run's").unwrap();
    std::fs::write(out.join("keep.txt"), "the user's").unwrap();
    let mut first = bin()
        .arg("run")
        .arg(&long)
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Once the first run has written a row, it holds the lock.
    let deadline = Instant::now() + Duration::from_secs(120);
    while std::fs::read_to_string(out.join("stats.csv")).map_or(true, |t| t.lines().count() < 2) {
        assert!(Instant::now() < deadline, "the first run wrote no row");
        std::thread::sleep(Duration::from_millis(50));
    }
    for stale in ["summary.json", "shard.json", "frames/77777_0_mask.png"] {
        assert!(!out.join(stale).exists(), "{stale} is an earlier run's");
    }
    assert!(out.join("keep.txt").exists(), "other files are left alone");
    let started = Instant::now();
    let o = bin()
        .arg("run")
        .arg(&short)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let last = e.trim_end().lines().last().unwrap_or_default();
    assert!(
        last.starts_with("error: ")
            && last.contains("another shadowcull run is writing")
            && last.contains(&*out.to_string_lossy()),
        "{e}"
    );
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "it fails at once"
    );
    // Interrupted: no summary beside the partial stats.csv, and no stale lock.
    first.kill().unwrap();
    first.wait().unwrap();
    assert!(!out.join("summary.json").exists());
    run_ok(&[
        "run".as_ref(),
        short.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ] as &[&std::ffi::OsStr]);
    let (header, rows) = stats(&out);
    assert_eq!(rows.len(), 3 * 2, "frames × lights");
    assert!(rows.iter().all(|r| r.len() == header.len()), "whole rows");
    assert!(out.join("summary.json").exists() && out.join("keep.txt").exists());
}

/// A reader that stops reading (`shadowcull inspect --objects … | head -1`)
/// ends the output normally: exit 0, nothing on stderr.
#[test]
fn a_closed_stdout_is_a_normal_end() {
    use std::io::{BufRead, BufReader};
    let dir = tmp_dir("pipe");
    let obj = dir.join("many.obj");
    let mut text = String::new();
    for i in 0..3000 {
        let x = i as f32 * 2.0;
        text.push_str(&format!(
            "o object_with_a_long_name_{i}\nv {x} 0 0\nv {} 0 0\nv {x} 1 0\nf {} {} {}\n",
            x + 1.0,
            3 * i + 1,
            3 * i + 2,
            3 * i + 3
        ));
    }
    std::fs::write(&obj, text).unwrap();
    let mut child = bin()
        .arg("inspect")
        .arg(&obj)
        .arg("--objects")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("many.obj"), "{first}");
    // The reader is gone; the rest (over 200 KB) meets a closed pipe.
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.is_empty(), "{err}");
}

/// `--frames 0` is refused as a job's `frames: 0` is, by `run` and `compare`,
/// naming the field (it once exited 0 with no rows).
#[test]
fn zero_frames_is_an_error_everywhere() {
    let out = tmp_dir("zero_frames");
    let job = out.join("zero.ron");
    std::fs::write(&job, "(scene: City((blocks_x: 1, blocks_z: 1)), frames: 0)").unwrap();
    let e = fails(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("a").as_os_str(),
    ]);
    assert!(e.contains("frames"), "{e}");
    for cmd in ["run", "compare"] {
        let e = fails(&[
            OsStr::new(cmd),
            OsStr::new("data/jobs/default_city.ron"),
            OsStr::new("--out"),
            out.join(cmd).as_os_str(),
            OsStr::new("--frames"),
            OsStr::new("0"),
        ]);
        assert!(e.contains("frames: must be at least 1"), "{cmd}: {e}");
        assert!(!out.join(cmd).join("stats.csv").exists());
    }
}

/// Input files: only regular files within `--max-input-size` are read; a
/// FIFO as the job once blocked forever.
#[test]
fn inputs_are_regular_files_within_the_size_limit() {
    let out = tmp_dir("input_limits");
    let job = Path::new("data/jobs/default_city.ron");
    let len = std::fs::metadata(job).unwrap().len();
    let e = fails(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("a").as_os_str(),
        OsStr::new("--max-input-size"),
        OsStr::new("100"),
    ]);
    assert!(
        e.contains(&format!("{len} bytes")) && e.contains("limit of 100 bytes"),
        "{e}"
    );
    let fifo = out.join("job.ron");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let e = fails(&[
            OsStr::new("run"),
            fifo.as_os_str(),
            OsStr::new("--out"),
            out.join("b").as_os_str(),
        ]);
        assert!(e.contains("a FIFO"), "{e}");
        let scene = out.join("scene.obj");
        assert!(Command::new("mkfifo")
            .arg(&scene)
            .status()
            .unwrap()
            .success());
        let e = fails(&[OsStr::new("inspect"), scene.as_os_str()]);
        assert!(e.contains("scene.obj") && e.contains("a FIFO"), "{e}");
    } else {
        eprintln!("note: no mkfifo here; the FIFO case is skipped");
    }
    let o = bin()
        .args(["inspect", "--max-input-size", "12T", "x.obj"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "a bad size is a usage error");
}

/// A scene that holds no geometry is named as such, with the loader's
/// reason, not blamed on the camera ("the scene is empty; give a camera").
#[test]
fn a_scene_without_geometry_is_named() {
    let out = tmp_dir("no_geometry");
    let passwd = out.join("passwd.obj");
    std::fs::write(
        &passwd,
        "root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1::/:/bin/sh\n",
    )
    .unwrap();
    for (scene, said) in [
        (format!("Obj({:?})", passwd), "no OBJ statement"),
        ("Group([])".to_string(), "an empty Group([])"),
    ] {
        let job = out.join("job.ron");
        std::fs::write(&job, format!("(scene: {scene})")).unwrap();
        let e = fails(&[
            OsStr::new("run"),
            job.as_os_str(),
            OsStr::new("--out"),
            out.join("o").as_os_str(),
        ]);
        assert!(
            e.contains("scene: ") && e.contains("holds no geometry") && e.contains(said),
            "{e}"
        );
    }
}

/// The loaders' warnings (here a dropped polyline) reach stderr, not only
/// `summary.json`.
#[test]
fn run_prints_the_loaders_warnings() {
    let out = tmp_dir("load_warnings");
    let obj = out.join("tent.obj");
    std::fs::write(
        &obj,
        "v -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\nv 0 1 0\nf 1 2 3 4\nf 1 2 5\nf 2 3 5\nl 1 5\n",
    )
    .unwrap();
    let job = out.join("job.ron");
    std::fs::write(
        &job,
        format!("(scene: Obj({obj:?}), frames: 1, resolution: (32, 24))"),
    )
    .unwrap();
    let o = bin()
        .args([OsStr::new("run"), job.as_os_str(), OsStr::new("--out")])
        .arg(out.join("o"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.lines()
            .any(|l| l.starts_with("shadowcull: warning: ") && l.contains("dropped 1 `l`")),
        "{err}"
    );
}

/// Jobs that cannot fit are refused before anything big is allocated, naming
/// the fields that drive the estimate: a 16384² viewport with the reference
/// (it once aborted at 13.6 GB), a billion frames, a city bounded by its
/// parameters; and `--max-memory` lowers the limit.
#[test]
fn jobs_that_cannot_fit_are_refused_up_front() {
    let out = tmp_dir("max_memory");
    let job = out.join("job.ron");
    for (text, field) in [
        ("(scene: City((blocks_x: 2, blocks_z: 2)), resolution: (16384, 16384))", "`resolution`"),
        ("(scene: City((blocks_x: 2, blocks_z: 2)), frames: 1000000000)", "`frames`"),
        (
            "(scene: City((blocks_x: 1024, blocks_z: 512, lots_per_side: 4, trees_per_block: 8, tree_segments: 256, tree_rings: 256)))",
            "`scene`",
        ),
    ] {
        std::fs::write(&job, text).unwrap();
        let e = fails(&[OsStr::new("run"), job.as_os_str(), OsStr::new("--out"), out.join("o").as_os_str()]);
        assert!(e.contains("max_memory: ") && e.contains(field), "{text}: {e}");
    }
    std::fs::write(
        &job,
        "(scene: City((blocks_x: 2, blocks_z: 2)), resolution: (320, 240), frames: 1)",
    )
    .unwrap();
    run_ok(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("ok").as_os_str(),
    ]);
    let e = fails(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("small").as_os_str(),
        OsStr::new("--max-memory"),
        OsStr::new("64M"),
    ]);
    assert!(e.contains("more than the limit of 64 MiB"), "{e}");
    // A refused rerun leaves the earlier run's results in place.
    assert!(out.join("ok").join("stats.csv").exists());
    let e = fails(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("ok").as_os_str(),
        OsStr::new("--max-memory"),
        OsStr::new("64M"),
    ]);
    assert!(e.contains("max_memory"), "{e}");
    assert!(
        out.join("ok").join("stats.csv").exists(),
        "a refused run deleted the results"
    );
    // A shard keeps only its block's rows: a billion-frame job in 10-frame
    // shards runs.
    std::fs::write(
        &job,
        "(scene: City((blocks_x: 1, blocks_z: 1)), resolution: (32, 24), frames: 1000000000, outputs: (masks: false))",
    )
    .unwrap();
    run_ok(&[
        OsStr::new("run"),
        job.as_os_str(),
        OsStr::new("--out"),
        out.join("shard").as_os_str(),
        OsStr::new("--shard"),
        OsStr::new("0/100000000"),
    ]);
    // Ten frames, two lights (the city's own).
    let rows = stats(&out.join("shard")).1;
    assert_eq!(rows.len(), 20);
    assert!(rows.iter().all(|r| r[0].parse::<u32>().unwrap() < 10));
}

/// `merge` reads only regular files: a FIFO in a shard directory is an
/// error naming it, not a hang.
#[test]
fn merge_refuses_a_fifo_in_a_shard() {
    let out = tmp_dir("merge_fifo");
    let job = out.join("job.ron");
    std::fs::write(
        &job,
        "(scene: City((blocks_x: 1, blocks_z: 1)), resolution: (32, 24), frames: 4)",
    )
    .unwrap();
    let dirs: Vec<PathBuf> = (0..2).map(|i| out.join(format!("s{i}"))).collect();
    for (i, d) in dirs.iter().enumerate() {
        run_ok(&[
            OsStr::new("run"),
            job.as_os_str(),
            OsStr::new("--out"),
            d.as_os_str(),
            OsStr::new("--shard"),
            OsStr::new(&format!("{i}/2")),
        ]);
    }
    let csv = dirs[1].join("stats.csv");
    std::fs::remove_file(&csv).unwrap();
    if !Command::new("mkfifo")
        .arg(&csv)
        .status()
        .is_ok_and(|s| s.success())
    {
        eprintln!("note: no mkfifo here; skipped");
        return;
    }
    let e = fails(&[
        OsStr::new("merge"),
        out.join("merged").as_os_str(),
        dirs[0].as_os_str(),
        dirs[1].as_os_str(),
    ]);
    assert!(e.contains("stats.csv") && e.contains("a FIFO"), "{e}");
}

/// `calibrate` prints clamping's two cost constants as RON fields that a job's
/// `pipeline` takes as they are; clamping with them keeps the job exact.
#[test]
fn calibrate_prints_costs_a_job_takes() {
    let dir = tmp_dir("calibrate");
    let job = dir.join("job.ron");
    // Enough pixels that the per-pixel time stands out of the noise.
    let measurable = SMALL_JOB.replace("resolution: (64, 48)", "resolution: (320, 240)");
    assert_ne!(measurable, SMALL_JOB);
    std::fs::write(&job, &measurable).unwrap();
    let o = bin()
        .arg("calibrate")
        .arg(&job)
        .args(["--reps", "3"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fields = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = fields.lines().collect();
    assert_eq!(lines.len(), 2, "{fields}");
    for (line, key) in lines
        .iter()
        .zip(["clamp_vertex_cost: ", "clamp_pixel_cost: "])
    {
        let v: f64 = line
            .strip_prefix(key)
            .and_then(|r| r.strip_suffix(','))
            .unwrap_or_else(|| panic!("{line}"))
            .parse()
            .unwrap();
        assert!(v.is_finite() && v > 0.0, "{line}");
    }
    // Pasted into the job's pipeline, with clamping on: a valid, exact job.
    let text = measurable.replace(
        "outputs: (masks: true, shaded: true),",
        &format!(
            "outputs: (masks: true, shaded: true),\n    pipeline: (clamping: continuous, {}),",
            fields.replace('\n', " ")
        ),
    );
    assert_ne!(text, measurable);
    std::fs::write(&job, &text).unwrap();
    let out = dir.join("out");
    let o = bin()
        .arg("run")
        .arg(&job)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    let cols: Vec<&str> = stats.lines().next().unwrap().split(',').collect();
    let off = cols
        .iter()
        .position(|c| *c == "mismatch_off_boundary")
        .unwrap();
    let segments = cols.iter().position(|c| *c == "segments").unwrap();
    let rows: Vec<Vec<&str>> = stats
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert!(rows.iter().all(|r| r[off] == "0"), "{stats}");
    assert!(rows.iter().any(|r| r[segments] != "0"), "{stats}");
}
